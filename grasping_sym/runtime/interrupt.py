"""The one owner of SIGINT (Ctrl-C) for every compiled model library of the process.

Each model library carries the driver's ``c/stop.c``: its C loops stop within a step when a
flag is set, and a SIGINT handler sets the flag. With several libraries loaded, several
handlers would chain into each other, and Python's ``signal.signal`` (a user's, or CasADi's
run) silently replaces any of them. So this module binds every library, when it is loaded
(:func:`bind`), to one flag held here and to one owner library's ``gs_sigint_ensure``; every
loop's start calls that, and it puts the owner's handler back in front of SIGINT's
disposition when something replaced it (chaining to what it found: Python's handler still
runs, a user's handler too). A disposition of ``SIG_IGN`` (nohup, a background job) or
``SIG_DFL`` is respected: nothing is installed, and an ignored Ctrl-C stops nothing.
Binding and installing work from any thread.

A run that SIGINT stopped raises :func:`interrupted`'s exception: ``KeyboardInterrupt`` while
Python's own handler is in place, else ``RunInterruptedError`` (the user's handler was called
and returned; the run does not pretend to have finished).
"""
from __future__ import annotations

import ctypes
import functools
import signal
import threading

from grasping_sym.errors import RunInterruptedError

#: The flag every bound library's loops read and the owner's handler sets (1: Ctrl-C seen).
_FLAG = ctypes.c_int(0)
_LOCK = threading.Lock()
_owner: ctypes.CDLL | None = None
_ensure: int | None = None  # the owner's gs_sigint_ensure, as a C function address


def bind(lib: ctypes.CDLL) -> None:
    """Share the process's SIGINT flag and owner with the library ``lib`` just loaded, and
    install the owner's handler (unless SIGINT is ignored or at its default)."""
    global _owner, _ensure
    lib.gs_stop_bind.argtypes = [ctypes.POINTER(ctypes.c_int), ctypes.c_void_p]
    lib.gs_stop_bind.restype = None
    with _LOCK:
        if _owner is None:
            lib.gs_sigint_ensure_status.restype = ctypes.c_int
            _owner = lib
            _ensure = ctypes.cast(lib.gs_sigint_ensure, ctypes.c_void_p).value
        lib.gs_stop_bind(ctypes.byref(_FLAG), _ensure)
    ensure()


def ensure() -> int:
    """Put the owner's handler in front of SIGINT's disposition now: 1 when it is in place,
    0 when the disposition is ``SIG_IGN`` or ``SIG_DFL`` (left alone), -1 on failure; None
    before any library was loaded. The C loops do this themselves at their start."""
    return None if _owner is None else int(_owner.gs_sigint_ensure_status())


def requested() -> bool:
    """True when Ctrl-C was seen since the run started (:func:`run_scope`)."""
    return bool(_FLAG.value)


#: Per thread: how deep in runs it is (``run_scope``), and the batch (``runtime.pool``) it runs
#: for (its stop, set when a Ctrl-C stopped the batch).
_member = threading.local()


def run_scope(fn):
    """``fn`` (``simulate``, ``simulate_many``) as a run: its start clears a Ctrl-C seen before
    it (the outermost run of the thread's), and its loops read the flag before each
    (:func:`in_run`, ``c_loops.stoppable``). A loop's start leaves the flag (``c/stop.c``): a
    Ctrl-C that came between two loops of a run of many (modes, charts, an inputs table's
    knots) while Python ran, under a handler of the user's that raises nothing, or while
    another thread's run was between its loops, was cleared by the next loop's start and lost.
    The outermost run also puts the owner's handler in front of SIGINT at its start
    (:func:`ensure`), as every loop's start does: under a handler of the user's set before the
    call, a Ctrl-C during the run's work before its first loop (a long inputs table's checks)
    reached that handler alone, set no flag, and the run went on to its end."""
    @functools.wraps(fn)
    def run(*args, **kwargs):
        depth = getattr(_member, "depth", 0)
        if not depth:
            _FLAG.value = 0
            ensure()
        _member.depth = depth + 1
        try:
            return fn(*args, **kwargs)
        finally:
            _member.depth = depth
    return run


def in_run() -> bool:
    """True inside a run of this thread (:func:`run_scope`, or a batch's, :class:`batch_member`):
    its loops read the flag; a loop outside any (a library's loop called directly) clears it
    first, as every loop's start did."""
    return getattr(_member, "depth", 0) > 0


class batch_member:
    """Within it, this thread runs for a batch whose ``stop`` (a ``threading.Event``) is set
    when Ctrl-C stopped the batch: a loop this thread starts then stops before it runs
    (:func:`stopped`); and the thread is in a run (:func:`in_run`)."""

    def __init__(self, stop: threading.Event):
        self.stop = stop
        self.depth = 0

    def __enter__(self):
        _member.stop = self.stop
        self.depth = getattr(_member, "depth", 0)
        _member.depth = self.depth + 1
        return self

    def __exit__(self, *exc):
        _member.stop = None
        _member.depth = self.depth
        return False


def stopped() -> bool:
    """True when this thread runs for a batch that Ctrl-C stopped (:class:`batch_member`)."""
    stop = getattr(_member, "stop", None)
    return stop is not None and stop.is_set()


def clear() -> None:
    """Clear the flag (a loop called outside any run, ``c_loops.stoppable``)."""
    _FLAG.value = 0


def raise_flag() -> None:
    """Set the flag the C loops read, as SIGINT's handler does: the loops under way stop at
    their next step (a batch stopping its runs; a loop that started after Ctrl-C cleared it)."""
    _FLAG.value = 1


def interrupted(message: str) -> BaseException:
    """The exception for a run that SIGINT stopped (``message`` says which and where):
    ``KeyboardInterrupt`` while Python's default SIGINT handler is in place, else
    ``RunInterruptedError`` (the process's handler is someone else's: it has run, or runs as
    soon as the main thread executes Python, and decides what Ctrl-C means)."""
    if signal.getsignal(signal.SIGINT) is signal.default_int_handler:
        return KeyboardInterrupt(message)
    return RunInterruptedError(
        f"{message}; the process's SIGINT handler is not Python's default one, so the run "
        "stopped without raising KeyboardInterrupt (your handler was called; call the run "
        "again to continue, or restore signal.default_int_handler for KeyboardInterrupt)")
