"""What the benchmarks share: the kernel pin before NumPy loads, stage timers that wrap the package functions, a
reference revision's checkout, the options of a benchmark that measures in child processes, and this core's
arithmetic peak.

Imported first by the benchmarks that can run another revision's code: it
sets the pinned kernels' variables (``anseg/kernels.py``, read as a file so
that ``anseg`` itself is not imported before a reference checkout is put
first), so this process's NumPy and every child process run them.
"""

from __future__ import annotations

import argparse
import importlib.util
import math
import subprocess
import sys
import tempfile
import time
from contextlib import contextmanager
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
_spec = importlib.util.spec_from_file_location("anseg_kernel_pin", REPO / "anseg" / "kernels.py")
_kernels = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(_kernels)
_kernels.pin_environment()


@contextmanager
def reference_checkout(revision: str | None):
    """A temporary git worktree of ``revision`` (its path), or None without one; removed on leaving."""
    if revision is None:
        yield None
        return
    with tempfile.TemporaryDirectory() as scratch:
        path = str(Path(scratch) / "reference")
        subprocess.run(["git", "-C", str(REPO), "worktree", "add", "--detach", path, revision], check=True, capture_output=True)
        try:
            yield path
        finally:
            subprocess.run(["git", "-C", str(REPO), "worktree", "remove", "--force", path], capture_output=True)


@contextmanager
def kernels_of_children(kernels: str | None):
    """While active, the processes started run ``kernels``: None leaves them the pin, ``native`` (the one other
    choice) gives them each library's own kernels (:func:`anseg.kernels.native_environment`)."""
    import os

    if kernels is None:
        yield
        return
    saved = dict(os.environ)
    os.environ.clear()
    os.environ.update(_kernels.native_environment(saved))
    try:
        yield
    finally:
        os.environ.clear()
        os.environ.update(saved)


def import_from(code: str | None) -> None:
    """Make ``import anseg`` find the checkout at ``code`` (in a fresh process, before anseg is imported)."""
    if code is not None:
        sys.path.insert(0, code)
        if "anseg" in sys.modules:
            raise RuntimeError("anseg was imported before the reference checkout was put first")


@contextmanager
def stage_timers(totals: dict, wrapped: dict, outermost: bool = False):
    """While active, every call of ``wrapped[stage] = (owner, attribute)`` adds its seconds to ``totals[stage]``.

    ``outermost``: a call made while another wrapped call runs is counted in
    that one's stage only, so that the stages add up to no more than the time
    they took (the coarse levels' features, which call the feature code, are
    then theirs, not the features').
    """
    originals = []
    running = []
    for stage, (owner, name) in wrapped.items():
        original = getattr(owner, name)
        originals.append((owner, name, original))

        def timed(*args, _original=original, _stage=stage, **kwargs):
            if outermost and running:
                return _original(*args, **kwargs)
            start = time.perf_counter()
            running.append(_stage)
            try:
                return _original(*args, **kwargs)
            finally:
                running.pop()
                totals[_stage] += time.perf_counter() - start

        setattr(owner, name, timed)
    try:
        yield
    finally:
        for owner, name, original in originals:
            setattr(owner, name, original)


def parse_or_measure(parser: argparse.ArgumentParser, argv, measure) -> argparse.Namespace | None:
    """Adds ``--json`` and the hidden options a child process is started with (``--child``, ``--code``: the
    reference checkout whose code it imports), then parses ``argv``: in a child, runs ``measure(args)`` and
    returns None; in the parent, returns the options."""
    parser.add_argument("--json", type=Path, metavar="FILE", help="also write the figures to FILE")
    parser.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    parser.add_argument("--code", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.child:
        measure(args)
        return None
    return args


def print_stages(totals: dict, reference: dict | None = None, name: str = "reference") -> None:
    """Seconds by stage, slowest first and the total last; beside them a reference's and its time over ours."""
    print(f"{'stage':<26}{'seconds':>10}" + (f"{name:>14}{'ratio':>8}" if reference else ""))
    for stage, seconds in sorted(totals.items(), key=lambda kv: (kv[0] == "total", -kv[1])):
        line = f"{stage:<26}{seconds:>10.3f}"
        if reference and stage in reference:
            line += f"{reference[stage]:>14.3f}{reference[stage] / max(seconds, 1e-9):>7.2f}x"
        print(line)


def peak_gflops(repeat: int = 5, size: int = 2048) -> float:
    """GFLOP/s of one (size x size) @ (size x size) float32 product with torch's threads, the best of ``repeat``."""
    import torch

    a, b = torch.randn(size, size), torch.randn(size, size)
    a @ b  # warm-up, not timed
    best = math.inf
    for _ in range(repeat):
        start = time.perf_counter()
        a @ b
        best = min(best, time.perf_counter() - start)
    return 2 * size**3 / best / 1e9
