"""Time the stages of a run by wrapping the package functions that implement them (shared by the benchmarks)."""

from __future__ import annotations

import time
from contextlib import contextmanager


@contextmanager
def stage_timers(totals: dict, wrapped: dict):
    """While active, every call of ``wrapped[stage] = (owner, attribute)`` adds its seconds to ``totals[stage]``."""
    originals = []
    for stage, (owner, name) in wrapped.items():
        original = getattr(owner, name)
        originals.append((owner, name, original))

        def timed(*args, _original=original, _stage=stage, **kwargs):
            start = time.perf_counter()
            try:
                return _original(*args, **kwargs)
            finally:
                totals[_stage] += time.perf_counter() - start

        setattr(owner, name, timed)
    try:
        yield
    finally:
        for owner, name, original in originals:
            setattr(owner, name, original)


def print_stages(totals: dict) -> None:
    """A two-column table, slowest stage first and the total last."""
    print(f"{'stage':<26}{'seconds':>10}")
    for stage, seconds in sorted(totals.items(), key=lambda kv: (kv[0] == "total", -kv[1])):
        print(f"{stage:<26}{seconds:>10.3f}")
