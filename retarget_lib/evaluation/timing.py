"""Timing helpers of the benchmarks (``retarget bench``): a result row with the reference it is
compared to, a median timer, and the Markdown table."""

from __future__ import annotations

import statistics
import time
from collections.abc import Callable
from dataclasses import dataclass

__all__ = ["BenchRow", "time_it", "format_table"]


@dataclass
class BenchRow:
    """One benchmark line: what was timed, its median seconds, and the reference it is compared
    to."""

    name: str
    seconds: float
    reference: str = ""
    reference_seconds: float | None = None
    target: str = ""

    @property
    def speedup(self) -> float | None:
        return None if self.reference_seconds is None else self.reference_seconds / self.seconds


def time_it(
    fn: Callable[[], object], repeat: int = 7, warmup: int = 2, min_time: float = 0.0
) -> float:
    """Median wall time of ``fn()`` in seconds over ``repeat`` runs after ``warmup`` runs."""
    for _ in range(warmup):
        fn()
    times = []
    t_start = time.perf_counter()
    while len(times) < repeat or time.perf_counter() - t_start < min_time:
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def format_table(rows: list[BenchRow]) -> str:
    """Markdown table of benchmark rows."""
    lines = [
        "| benchmark | median | reference (same run) | speed-up | target |",
        "|---|---|---|---|---|",
    ]
    for r in rows:
        ref = "" if r.reference_seconds is None else f"{r.reference}: {_fmt(r.reference_seconds)}"
        sp = (
            ""
            if r.speedup is None
            else f"{r.speedup:,.0f}x"
            if r.speedup >= 10
            else f"{r.speedup:.1f}x"
            if r.speedup >= 0.1
            else f"1/{1 / r.speedup:,.0f}x"
        )  # slower than its reference
        lines.append(f"| {r.name} | {_fmt(r.seconds)} | {ref} | {sp} | {r.target} |")
    return "\n".join(lines)


def _fmt(s: float) -> str:
    return f"{s * 1e3:.2f} ms" if s < 1 else f"{s:.2f} s"
