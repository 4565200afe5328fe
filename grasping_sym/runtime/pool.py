"""The runs of a batch that Python drives, one per thread.

A batch of a model with contact modes or with atlases (``runtime.modes``, ``run.run``) runs
each of its runs by ``simulate``'s own code: Python switches modes and charts between the C
loops' segments. Those loops release the GIL, and their watch and its events are each
thread's own (``c/watch.c``), so the runs go side by side on ``threads`` threads, each
writing its own row of the batch's arrays (``each``).
"""
from __future__ import annotations

import threading
from collections.abc import Callable
from concurrent.futures import FIRST_EXCEPTION, ThreadPoolExecutor, wait

from grasping_sym.errors import RunInterruptedError
from grasping_sym.runtime import interrupt

#: s: how often the flag is set again while the runs under way stop (a loop that started just
#: after Ctrl-C cleared it)
RAISE_EVERY = 0.01


def each(n: int, threads: int, run: Callable[[int], None]) -> None:
    """``run(i)`` for ``i`` in ``range(n)``, on ``threads`` threads (one: in order, here).

    A run's exception is the batch's (``run`` records the errors that are a run's own): the
    runs not yet started are dropped, those under way end, and the first exception in the
    runs' order is raised. A Ctrl-C (a ``KeyboardInterrupt`` here, or a run's) stops the runs
    under way too: each run's next loop stops before it starts (``interrupt.batch_member``),
    and the flag the loops read is set again until they have all ended (a loop's start clears
    it, and a run starts many)."""
    if threads <= 1 or n <= 1:
        for i in range(n):
            run(i)
        return
    stop = threading.Event()

    def member(i: int) -> None:
        with interrupt.batch_member(stop):
            run(i)

    pool = ThreadPoolExecutor(max_workers=min(threads, n))
    futures: list = []
    try:
        futures.extend(pool.submit(member, i) for i in range(n))
        wait(futures, return_when=FIRST_EXCEPTION)
        if any(_interrupt(f) for f in futures if f.done()):
            _halt(stop, futures)
        pool.shutdown(wait=True, cancel_futures=True)  # a run's error: the others under way end
    except BaseException:  # a KeyboardInterrupt in this thread (also while the others end)
        _halt(stop, futures)
        pool.shutdown(wait=True, cancel_futures=True)
        raise
    for future in futures:
        if not future.cancelled() and future.exception() is not None:
            raise future.exception()


def _interrupt(future) -> bool:
    exc = None if future.cancelled() else future.exception()
    return isinstance(exc, (KeyboardInterrupt, RunInterruptedError))


def _halt(stop: threading.Event, futures) -> None:
    """Stop the runs under way: none starts another loop, and the flag is set until they end."""
    stop.set()
    for future in futures:
        future.cancel()
    while not all(f.done() for f in futures):
        interrupt.raise_flag()
        wait(futures, timeout=RAISE_EVERY)
