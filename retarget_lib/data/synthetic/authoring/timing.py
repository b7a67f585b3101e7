"""Timing and easing curves of the motion families: minimum-jerk ramps, eased windows,
keyframe interpolation, smooth noise, event times."""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np


def minjerk(u: np.ndarray) -> np.ndarray:
    """Minimum-jerk ease ``10u^3 - 15u^4 + 6u^5`` on ``[0, 1]`` (clipped outside)."""
    u = np.clip(u, 0.0, 1.0)
    return u**3 * (10 - 15 * u + 6 * u * u)


def ramp(t: np.ndarray, t0: float, t1: float) -> np.ndarray:
    """0 before ``t0``, eased to 1 at ``t1``."""
    return minjerk((t - t0) / max(t1 - t0, 1e-6))


def window(
    t: np.ndarray, t0: float, t1: float, rise: float, fall: float | None = None
) -> np.ndarray:
    """Eased to 1 over ``[t0, t0 + rise]``, held, eased back to 0 over ``[t1 - fall, t1]``."""
    fall = rise if fall is None else fall
    return ramp(t, t0, t0 + rise) * (1.0 - ramp(t, t1 - fall, t1))


def keyframes(t: np.ndarray, times: Sequence[float], values: Sequence) -> np.ndarray:
    """Minimum-jerk interpolation through keyframes (zero velocity at every key).

    Args:
        t: ``(T,)`` seconds.
        times: ``K`` increasing key times.
        values: ``K`` key values (scalars or equal-shape arrays).

    Returns:
        ``(T, ...)`` values; held constant before the first and after the last key.
    """
    times = np.asarray(times, dtype=float)
    vals = np.asarray(values, dtype=float)
    k = np.clip(np.searchsorted(times, t, side="right") - 1, 0, len(times) - 2)
    u = minjerk((t - times[k]) / np.maximum(times[k + 1] - times[k], 1e-6))
    u = u.reshape(u.shape + (1,) * (vals.ndim - 1))
    return vals[k] + (vals[k + 1] - vals[k]) * u


def noise(rng: np.random.Generator, t: np.ndarray, amp: float, fmax: float = 0.5) -> np.ndarray:
    """Smooth random signal: three sinusoids below ``fmax`` Hz, peak about ``amp``."""
    f = rng.uniform(0.08, fmax, 3)
    ph = rng.uniform(0, 2 * np.pi, 3)
    w = rng.uniform(0.5, 1.0, 3)
    return amp * (w[:, None] * np.sin(2 * np.pi * f[:, None] * t + ph[:, None])).sum(0) / w.sum()


def event_times(
    rng: np.random.Generator,
    duration: float,
    length: Callable[[], float],
    pause: tuple[float, float],
    start: tuple[float, float] = (0.4, 1.0),
    tail: float = 0.6,
) -> list[tuple[float, float]]:
    """Random ``(start, end)`` times of repeated actions separated by pauses, all inside the clip.

    At least one event is returned (shortened to fit if needed).
    """
    out = []
    t = rng.uniform(*start)
    while True:
        n = length()
        if t + n > duration - tail:
            break
        out.append((t, t + n))
        t += n + rng.uniform(*pause)
    if not out:
        t0 = min(start[0], 0.25 * duration)
        out.append((t0, max(t0 + 0.5, duration - tail)))
    return out


def hermite(
    t: np.ndarray, t0: float, t1: float, y0: float, y1: float, v0: float, v1: float
) -> np.ndarray:
    """Cubic Hermite segment from ``(t0, y0, v0)`` to ``(t1, y1, v1)`` evaluated at ``t``."""
    h = t1 - t0
    u = np.clip((t - t0) / h, 0.0, 1.0)
    return (
        (2 * u**3 - 3 * u**2 + 1) * y0
        + (u**3 - 2 * u**2 + u) * h * v0
        + (-2 * u**3 + 3 * u**2) * y1
        + (u**3 - u**2) * h * v1
    )
