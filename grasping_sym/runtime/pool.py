"""The runs of a batch that Python drives, one per thread.

A batch of a model with contact modes or with atlases (``runtime.modes``, ``run.run``) runs
each of its runs by ``simulate``'s own code: Python switches modes and charts between the C
loops' segments. Those loops release the GIL, and their watch and its events are each
thread's own (``c/watch.c``), so the runs go side by side on ``threads`` threads, each
writing its own row of the batch's arrays (``each``).
"""
from __future__ import annotations

from collections.abc import Callable
from concurrent.futures import FIRST_EXCEPTION, ThreadPoolExecutor, wait


def each(n: int, threads: int, run: Callable[[int], None]) -> None:
    """``run(i)`` for ``i`` in ``range(n)``, on ``threads`` threads (one: in order, here).

    A run's exception is the batch's (``run`` records the errors that are a run's own): the
    runs not yet started are dropped, those under way end (Ctrl-C stops their C loops at
    once), and the first exception in the runs' order is raised; so is a ``KeyboardInterrupt``
    that reaches this thread while it waits. Without the drop, a Ctrl-C would stop the runs
    under way and the batch would go on with the others."""
    if threads <= 1 or n <= 1:
        for i in range(n):
            run(i)
        return
    pool = ThreadPoolExecutor(max_workers=min(threads, n))
    futures = [pool.submit(run, i) for i in range(n)]
    try:
        wait(futures, return_when=FIRST_EXCEPTION)
    finally:
        pool.shutdown(wait=True, cancel_futures=True)
    for future in futures:
        if not future.cancelled() and future.exception() is not None:
            raise future.exception()
