"""The cone-shaped local distance field ``psi`` of a triangle (after Tzionas et al. 2016), with
which the interpenetration energy (Eq. 4, :mod:`retarget_lib.geometry.penetration`) measures how
deep a vertex lies behind a triangle it penetrates.

Units: metres; ``psi`` is a length.
"""

from __future__ import annotations

import torch

Tensor = torch.Tensor

__all__ = [
    "CONE_HEIGHT",
    "RADIUS_SCALE",
    "SIGMA",
    "check_cone",
    "circumcircle",
    "cone_distance_field",
]

#: default cone parameters (:func:`cone_distance_field`): quadratic zone and apex height in metres,
#: base radius in circumradii
SIGMA = 0.01
CONE_HEIGHT = 0.1
RADIUS_SCALE = 1.0


def cone_distance_field(
    points: Tensor,
    triangles: Tensor,
    sigma: float = SIGMA,
    height: float = CONE_HEIGHT,
    radius_scale: float = RADIUS_SCALE,
) -> Tensor:
    """Cone-shaped local distance field ``psi`` of triangles (after Tzionas et al. 2016, IJCV).

    Geometry, for a triangle with circumcentre ``c``, circumradius ``R`` and unit normal ``n``
    (counter-clockwise vertices, pointing out of the body): the cone's axis is the normal line
    through ``c``, its apex lies ``height`` in *front* of the triangle, its surface passes through
    the circle of radius ``radius_scale * R`` around ``c`` in the triangle's plane, and it opens
    *behind* the triangle, into the body — the layout of torch-mesh-isect's
    ``conical_distance_field`` (which uses one ``sigma`` for both lengths). For a point ``p`` at
    depth ``d = -(p - c) . n`` behind the plane and distance ``rho`` from the axis::

        r(d)   = radius_scale * R * (1 + d / height)           cone radius at depth d
        U(d)   = 0 (d <= 0);  d^2 / (2 sigma) (0 < d < sigma);  d - sigma / 2 (d >= sigma)
        psi(p) = U(d) * max(0, 1 - (rho / r(d))^2)

    ``U`` is quadratic near the surface (no jolt when a vertex first crosses) and linear deeper,
    so ``psi`` grows like the penetration depth; the radial factor fades it to zero on the cone's
    surface and is smooth on the axis. Differences from torch-mesh-isect (same idea, not the same
    formula): there the intensity is also positive in front of the triangle
    (``penalize_outside``), the radial factor is ``1 - rho / r``, and the product is squared once
    more before Eq. 4 squares it again; here ``psi`` is a length and ``E_int`` an area.

    Args:
        points: ``(..., 3)`` points (metres).
        triangles: ``(..., 3, 3)`` triangles (vertex, xyz), broadcast against ``points``.
        sigma: metres, width of the quadratic zone of ``U``.
        height: metres, height of the cone's apex in front of the triangle (larger = a cone
            closer to a cylinder).
        radius_scale: the cone's radius in the triangle's plane, in circumradii.

    Returns:
        ``(...)`` ``psi >= 0`` (metres), differentiable in ``points`` and ``triangles``.
    """
    check_cone(sigma, height, radius_scale)
    if points.shape[-1] != 3 or triangles.shape[-2:] != (3, 3):
        raise ValueError(
            f"points must be (..., 3) and triangles (..., 3, 3), got "
            f"{tuple(points.shape)} and {tuple(triangles.shape)}"
        )
    centre, radius, normal = circumcircle(triangles)
    rel = points - centre
    elevation = (rel * normal).sum(-1)
    radial_sq = (rel - elevation.unsqueeze(-1) * normal).square().sum(-1)
    d = (-elevation).clamp(min=0.0)
    intensity = torch.where(d < sigma, d.square() / (2.0 * sigma), d - 0.5 * sigma)
    cone_radius = radius_scale * radius * (1.0 + d / height)
    falloff = (
        1.0 - radial_sq / cone_radius.square().clamp(min=torch.finfo(radius.dtype).tiny)
    ).clamp(min=0.0)
    return intensity * falloff


def check_cone(sigma: float, height: float, radius_scale: float) -> None:
    if min(sigma, height, radius_scale) <= 0:
        raise ValueError(
            f"sigma, height and radius_scale must be positive, got {sigma}, {height}, "
            f"{radius_scale}"
        )


def circumcircle(triangles: Tensor) -> tuple[Tensor, Tensor, Tensor]:
    """Circumcircle and normal of triangles (differentiable).

    Args:
        triangles: ``(..., 3, 3)`` (vertex, xyz), metres.

    Returns:
        Circumcentre ``(..., 3)``, circumradius ``(...)`` and unit normal ``(..., 3)`` (right-hand
        rule on the vertex order).
    """
    a = triangles[..., 0, :]
    e1, e2 = triangles[..., 1, :] - a, triangles[..., 2, :] - a
    m = torch.cross(e1, e2, dim=-1)
    m_sq = m.square().sum(-1, keepdim=True).clamp(min=torch.finfo(m.dtype).tiny)
    offset = (
        e1.square().sum(-1, keepdim=True) * torch.cross(e2, m, dim=-1)
        + e2.square().sum(-1, keepdim=True) * torch.cross(m, e1, dim=-1)
    ) / (2.0 * m_sq)
    return a + offset, offset.norm(dim=-1), m / m_sq.sqrt()
