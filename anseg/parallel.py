"""How the library runs independent work side by side: one helper, used by every caller.

``run_parallel(calls, workers)`` runs ``function(*args)`` for each call and
yields ``(index, result)`` as each finishes (an exception that a call raised
comes back as the result, so that one failure does not lose the others).
``workers=1`` runs the calls here, in order. More go to one of two backends:

* ``"loky"`` (feature computation): joblib's loky executor. Its workers start
  from a fresh interpreter (forking once torch, numba or OpenMP threads exist
  is unsafe) but do not re-import the caller's ``__main__``, so a script
  without an ``if __name__ == "__main__":`` guard works, as does a notebook.
* ``"dask"`` (trainings: :func:`anseg.study.runner.run_plan`, validation):
  a ``LocalCluster`` of ``workers`` processes, or the running cluster at
  ``scheduler``, so a plan scales to a cluster without a changed line. A lost
  worker costs only its call, which runs again elsewhere; a :class:`GpuCall`
  goes only to workers started with ``--resources GPU=1``.

Every worker computes with one thread (OpenMP, numba, torch): on a small
machine several jobs with several threads each thrash. Inside a Dask worker
:func:`in_worker` is true, and callers that would start a pool of their own
(the feature cache) work in-process: a worker may not start processes.
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager

THREAD_VARIABLES = ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS", "NUMBA_NUM_THREADS")
BACKENDS = ("loky", "dask")
DASK_RETRIES = 2  # a call that raised (not one whose worker died: the scheduler reruns those) is tried this often again


class GpuCall:
    """A function whose calls need a GPU: the Dask backend sends them only to workers with a ``GPU`` resource."""

    def __init__(self, function: Callable):
        self.function = function

    def __call__(self, *args):
        return self.function(*args)


def in_worker() -> bool:
    """Whether this process is a Dask worker (which may not start a process pool)."""
    if "distributed" not in sys.modules:
        return False
    from distributed import get_worker

    try:
        get_worker()
    except ValueError:
        return False
    return True


def _one_thread(function: Callable, args: tuple):
    import torch

    torch.set_num_threads(1)
    return function(*args)


def run_parallel(calls: Sequence[tuple[Callable, tuple]], workers: int = 1, progress: bool = False, desc: str = "jobs",
                 stop_after: float | None = None, backend: str = "loky",
                 scheduler: str | None = None) -> Iterator[tuple[int, object]]:
    """Run ``function(*args)`` for each ``(function, args)``; yield ``(index, result or exception)`` as each finishes.

    ``functions`` must be importable (module level) when they leave this
    process. With ``stop_after`` (seconds), no call starts after that time;
    the calls under way finish, and the ones never started are not yielded.
    ``scheduler`` (Dask backend): a running cluster's address; then
    ``workers`` is not used.
    """
    from anseg.progress import progress as progress_bar

    if workers < 1:
        raise ValueError(f"workers must be at least 1, got {workers}")
    if backend not in BACKENDS:
        raise ValueError(f"backend must be one of {BACKENDS}, got {backend!r}")
    started = time.time()
    bar = progress_bar(total=len(calls), desc=desc, show=progress)
    try:
        if scheduler is None and (workers == 1 or len(calls) <= 1 or in_worker()):
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
        pooled = _on_dask if backend == "dask" else _on_loky
        yield from pooled(calls, min(workers, len(calls)), bar, started, stop_after, scheduler)
    finally:
        bar.close()


def _on_loky(calls, workers: int, bar, started: float, stop_after: float | None, scheduler):
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


@contextmanager
def _main_not_reimported():
    """While active, processes started with ``spawn`` do not run the caller's ``__main__`` again.

    ``spawn`` re-imports the main module by its path in every new process, so
    a script without a main guard would start over in each Dask worker (and
    code read from stdin cannot be found). With no ``__file__`` and an empty
    ``__spec__`` on ``__main__`` there is nothing to re-import; the workers
    need nothing from it (the calls are module-level functions, and Dask
    pickles anything defined in ``__main__`` by value).
    """
    main = sys.modules["__main__"]
    spec, path = getattr(main, "__spec__", None), getattr(main, "__file__", None)
    main.__spec__ = None  # spawn reads the attribute, so it stays, empty
    if path is not None:
        del main.__file__
    try:
        yield
    finally:
        main.__spec__ = spec
        if path is not None:
            main.__file__ = path


def _on_dask(calls, workers: int, bar, started: float, stop_after: float | None, scheduler: str | None):
    with _main_not_reimported():  # for the whole run: the nanny restarts a lost worker with spawn too
        yield from _dask_calls(calls, workers, bar, started, stop_after, scheduler)


def _dask_calls(calls, workers: int, bar, started: float, stop_after: float | None, scheduler: str | None):
    from distributed import Client, LocalCluster, as_completed

    env = {name: "1" for name in THREAD_VARIABLES}
    cluster = None if scheduler else LocalCluster(n_workers=workers, threads_per_worker=1, processes=True, env=env,
                                                  dashboard_address=":0" if _has_bokeh() else None)
    with Client(scheduler or cluster) as client:
        if client.dashboard_link and _has_bokeh():
            print(f"[anseg] Dask dashboard: {client.dashboard_link}", file=sys.stderr, flush=True)
        # as many calls in flight as the cluster has threads, so that stop_after can hold the rest back
        slots = max(1, sum(client.nthreads().values())) if scheduler else workers
        waiting = list(enumerate(calls))[::-1]
        futures = as_completed()
        index_of = {}

        def submit():
            index, (function, args) = waiting.pop()
            resources = {"GPU": 1} if isinstance(function, GpuCall) else None
            future = client.submit(_one_thread, function, args, pure=False, retries=DASK_RETRIES, resources=resources)
            index_of[future.key] = index
            futures.add(future)

        while waiting and len(index_of) < slots:
            submit()
        for future in futures:
            index = index_of.pop(future.key)
            outcome = future.exception() if future.status == "error" else future.result()
            future.release()
            bar.update()
            yield index, outcome
            if waiting and (stop_after is None or time.time() - started < stop_after):
                submit()
    if cluster is not None:
        cluster.close()


def _has_bokeh() -> bool:
    import importlib.util

    return importlib.util.find_spec("bokeh") is not None
