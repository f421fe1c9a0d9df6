"""Ctrl-C that is never lost during a long job.

Python turns SIGINT into a ``KeyboardInterrupt`` raised wherever the main thread happens to be
when the signal is handled. During a sweep that is often just after a compiled engine call
returns, when the arrays it freed run their cleanups: inside a weakref callback or a
``__del__``, an exception cannot propagate, so Python prints "Exception ignored in ..." and
drops it, and the sweep runs on (one Ctrl-C in four, measured). :func:`latched` installs a
handler that also *remembers* the interrupt; :func:`check`, called at safe points (between
compiled engine calls, between chunks, while waiting for a cluster), raises it again if it was
swallowed.
"""

from __future__ import annotations

import signal
import threading
from contextlib import contextmanager
from typing import Iterator

__all__ = ["latched", "check", "forked_worker_init"]

_state = {"depth": 0, "pending": False}


def _handler(signum, frame) -> None:
    _state["pending"] = True
    raise KeyboardInterrupt


@contextmanager
def latched() -> Iterator[None]:
    """Remember every Ctrl-C (SIGINT) while the block runs, so that :func:`check` can raise one
    that a weakref callback or ``__del__`` swallowed.

    Only in the main thread, and only when SIGINT has Python's default handler: a program that
    installed its own keeps it. Nested blocks share the outermost one's handler. In another
    thread the block does nothing (signals reach the main thread only) and counts nothing: a
    sweep or design search running in another thread kept the count above 0 (and two of them
    could race on it), so a sweep started meanwhile in the main thread installed no handler and
    swallowed its Ctrl-C.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    install = _state["depth"] == 0 and signal.getsignal(signal.SIGINT) is signal.default_int_handler
    previous = signal.signal(signal.SIGINT, _handler) if install else None
    _state["depth"] += 1
    try:
        yield
    finally:
        _state["depth"] -= 1
        if install:
            signal.signal(signal.SIGINT, previous)
            _state["pending"] = False


def check() -> None:
    """Raise ``KeyboardInterrupt`` when a Ctrl-C arrived inside :func:`latched` since the last
    check (whether or not its first ``KeyboardInterrupt`` was swallowed); cheap, call it often."""
    if _state["pending"]:
        _state["pending"] = False
        raise KeyboardInterrupt


def forked_worker_init() -> None:
    """Initializer of a forked pool's workers (the figures ``reproduce`` draws in parallel).

    A fork inherits the parent's signal handlers: the CLI's SIGTERM handler (raise, as Ctrl-C
    does) then ran in every worker when the pool stopped them with SIGTERM at its end, and each
    printed a traceback under a successful run; a Ctrl-C, sent to the whole process group, did
    the same. The workers take SIGTERM's default (they just stop) and ignore SIGINT (the parent
    handles it and stops the pool). The imports are also frozen out of the garbage collector
    (``gc.freeze``): the workers then leave the parent's pages shared.
    """
    import gc

    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    gc.freeze()
