"""How the library runs independent work side by side: one helper, used by every caller.

``run_parallel(calls, workers)`` runs ``function(*args)`` for each call and
yields ``(index, result)`` as each finishes (an exception that a call raised
comes back as the result, so that one failure does not lose the others).
``workers=1`` runs the calls here, in order; more use a process pool.

The pool is joblib's loky executor (joblib comes with scikit-learn): its
workers start from a fresh interpreter, as with ``spawn`` (forking once
torch, numba or OpenMP threads exist is unsafe), but they do not re-import
the caller's ``__main__``, so a plain script without an ``if __name__ ==
"__main__":`` guard works as well as a notebook. Every worker gets one
thread for OpenMP, numba and torch: on a small machine several jobs with
several threads each thrash.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator, Sequence

THREAD_VARIABLES = ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS", "NUMBA_NUM_THREADS")


def _one_thread(function: Callable, args: tuple):
    import torch

    torch.set_num_threads(1)
    return function(*args)


def run_parallel(calls: Sequence[tuple[Callable, tuple]], workers: int = 1, progress: bool = False, desc: str = "jobs",
                 stop_after: float | None = None) -> Iterator[tuple[int, object]]:
    """Run ``function(*args)`` for each ``(function, args)``; yield ``(index, result or exception)`` as each finishes.

    ``functions`` must be importable (module level) when ``workers > 1``.
    With ``stop_after`` (seconds), no call starts after that time; the calls
    under way finish, and the ones never started are not yielded.
    """
    from tqdm.auto import tqdm

    if workers < 1:
        raise ValueError(f"workers must be at least 1, got {workers}")
    started = time.time()
    bar = tqdm(total=len(calls), desc=desc, disable=not progress)
    try:
        if workers == 1 or len(calls) <= 1:
            for index, (function, args) in enumerate(calls):
                if stop_after is not None and time.time() - started >= stop_after:
                    return
                try:
                    outcome = function(*args)
                except Exception as exc:  # handed to the caller, who decides
                    outcome = exc
                bar.update()
                yield index, outcome
            return
        yield from _pooled(calls, min(workers, len(calls)), bar, started, stop_after)
    finally:
        bar.close()


def _pooled(calls, workers: int, bar, started: float, stop_after: float | None):
    from concurrent.futures import FIRST_COMPLETED, wait

    from joblib.externals.loky import ProcessPoolExecutor

    env = {name: "1" for name in THREAD_VARIABLES}
    waiting = list(enumerate(calls))[::-1]  # pop() takes them in order
    with ProcessPoolExecutor(workers, env=env) as pool:
        running = {}
        while waiting or running:
            while waiting and len(running) < workers and (stop_after is None or time.time() - started < stop_after):
                index, (function, args) = waiting.pop()
                running[pool.submit(_one_thread, function, args)] = index
            if not running:
                return
            done, _ = wait(running, return_when=FIRST_COMPLETED)
            for job in done:
                index = running.pop(job)
                exc = job.exception()
                bar.update()
                yield index, exc if exc is not None else job.result()
