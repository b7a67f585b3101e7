"""Planted feet (step 2 of :mod:`retarget_lib.data.synthetic.authoring`): footstep plans on the
rest ground, swing paths with lift, toe-off and heel-strike, and the still plants of a standing
clip."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import torch

from ....core.rotations import (
    quat_mul,
    quat_rotate,
)
from .body import SIDES, Rig
from .pose import axis_rotation
from .timing import minjerk


@dataclass
class Plant:
    """A foot flat on the ground over ``[t0, t1]`` at ankle ``xz`` with heading ``yaw`` (radians).

    During the last ``pivot`` seconds the heel lifts (pitch up to ``pivot_deg``) about the planted
    toe.
    """

    t0: float
    t1: float
    xz: np.ndarray
    yaw: float
    pivot: float = 0.0
    pivot_deg: float = 0.0


@dataclass
class Feet:
    ankle: np.ndarray  # (T, 2, 3) ankle targets
    rot: np.ndarray  # (T, 2, 4) global foot rotations
    contacts: np.ndarray  # (T, 4) bool: left ankle, right ankle, left toe, right toe
    knee: np.ndarray  # (T, 2, 3) knee bend (pole) directions: where the toes point


def foot_rot(yaw: np.ndarray, pitch_deg: np.ndarray) -> torch.Tensor:
    """``(N, 4)`` global foot rotation: heading ``yaw`` (rad), then ``pitch`` toe-down (deg)."""
    return quat_mul(
        axis_rotation(1, np.degrees(yaw), len(yaw)), axis_rotation(0, pitch_deg, len(yaw))
    )


def _bump(u: np.ndarray, center: float, half: float) -> np.ndarray:
    """Smooth bump, 1 at ``center``, 0 outside ``center +- half``."""
    return np.sin(np.pi * np.clip((u - center + half) / (2 * half), 0.0, 1.0)) ** 2


def plan_feet(
    rig: Rig,
    t: np.ndarray,
    plants: Sequence[Sequence[Plant]],
    lift: float,
    land_pitch: float = 10.0,
) -> Feet:
    """Ankle targets, foot rotations and contact labels from footstep plans.

    Args:
        rig: the character.
        t: ``(T,)`` seconds.
        plants: per foot (left, right), time-ordered :class:`Plant` s covering the clip
            (the first from ``t = 0``, the last to the end).
        lift: swing foot clearance (metres).
        land_pitch: toe-up pitch just before landing (degrees).
    """
    T = len(t)
    ankle = np.zeros((T, 2, 3))
    yaw = np.zeros((T, 2))
    pitch = np.zeros((T, 2))
    contacts = np.zeros((T, 4), bool)
    for f in (0, 1):
        toe, h = rig.toe[f], rig.ankle_h[f]
        for k, p in enumerate(plants[f]):
            flat = (t >= p.t0) & (t <= p.t1 - p.pivot)
            piv = (t > p.t1 - p.pivot) & (t <= p.t1)
            ankle[flat, f] = (p.xz[0], h, p.xz[1])
            yaw[flat | piv, f] = p.yaw
            contacts[flat, f] = True
            contacts[flat | piv, 2 + f] = True
            if piv.any():
                pitch[piv, f] = p.pivot_deg * minjerk((t[piv] - p.t1 + p.pivot) / p.pivot)
                flat_toe = rotate_vector(foot_rot(np.array([p.yaw]), np.zeros(1)), toe)[0]
                toe_pos = np.array([p.xz[0], h, p.xz[1]]) + flat_toe
                ankle[piv, f] = toe_pos - rotate_vector(foot_rot(yaw[piv, f], pitch[piv, f]), toe)
            if k + 1 < len(plants[f]):
                _swing(rig, t, f, p, plants[f][k + 1], lift, land_pitch, ankle, yaw, pitch)
    rot = foot_rot(yaw.reshape(-1), pitch.reshape(-1)).reshape(T, 2, 4).numpy()
    fwd = np.stack((np.sin(yaw), np.zeros_like(yaw), np.cos(yaw)), -1)
    return Feet(ankle, rot, contacts, fwd)


def rotate_vector(q: torch.Tensor, v: np.ndarray) -> np.ndarray:
    return quat_rotate(q, torch.from_numpy(np.broadcast_to(v, q.shape[:-1] + (3,)).copy())).numpy()


def _swing(
    rig: Rig,
    t: np.ndarray,
    f: int,
    a: Plant,
    b: Plant,
    lift: float,
    land_pitch: float,
    ankle: np.ndarray,
    yaw: np.ndarray,
    pitch: np.ndarray,
) -> None:
    """Fill the swing of foot ``f`` from plant ``a`` to plant ``b`` in place."""
    m = (t > a.t1) & (t < b.t0)
    if not m.any():
        return
    u = (t[m] - a.t1) / (b.t0 - a.t1)
    s = minjerk(u)
    toe = rig.toe[f]
    start_pitch = a.pivot_deg if a.pivot > 0 else 0.0
    start = np.array([a.xz[0], rig.ankle_h[f], a.xz[1]])
    if a.pivot > 0:  # the swing starts where the heel-raised foot left off
        toe_pos = start + rotate_vector(foot_rot(np.array([a.yaw]), np.zeros(1)), toe)[0]
        start = (
            toe_pos - rotate_vector(foot_rot(np.array([a.yaw]), np.array([start_pitch])), toe)[0]
        )
    end = np.array([b.xz[0], rig.ankle_h[f], b.xz[1]])
    dyaw = (b.yaw - a.yaw + np.pi) % (2 * np.pi) - np.pi
    yaw[m, f] = a.yaw + dyaw * s
    pitch[m, f] = start_pitch * (1 - minjerk(u / 0.45)) - land_pitch * _bump(u, 0.8, 0.2)
    pos = start + (end - start) * s[:, None]
    dist = np.linalg.norm(end[[0, 2]] - start[[0, 2]])
    pos[:, 1] += min(lift, 0.5 * lift + dist) * np.sin(np.pi * u**0.8) ** 2  # early peak, soft ends
    ankle[m, f] = pos


def still_plants(rig: Rig, duration: float, width: float, toe_out: float) -> list[list[Plant]]:
    """Both feet planted for the whole clip, ``width`` x the rest stance apart, toes out ``toe_out``
    degrees."""
    return [
        [
            Plant(
                0.0,
                duration + 1.0,
                np.array([sign * width * rig.stance_w, 0.0]),
                sign * np.radians(toe_out),
            )
        ]
        for _, sign in SIDES
    ]


def yaw_xz(yaw: float, xz: np.ndarray) -> np.ndarray:
    """Rotate a horizontal ``(x, z)`` vector by heading ``yaw`` (radians, towards +X)."""
    c, s = np.cos(yaw), np.sin(yaw)
    return np.array([c * xz[0] + s * xz[1], -s * xz[0] + c * xz[1]])
