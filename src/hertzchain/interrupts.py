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

__all__ = ["latched", "check", "forked_worker_init", "held_signals", "forked_pool", "start_forked"]

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
    # forked by forked_pool / start_forked with both signals blocked: one sent meanwhile (a pool
    # stopped at once) is delivered now, to the dispositions just set
    signal.pthread_sigmask(signal.SIG_UNBLOCK, _HELD)
    gc.freeze()


#: The signals blocked while a process forks (:func:`held_signals`).
_HELD = {signal.SIGINT, signal.SIGTERM}


@contextmanager
def held_signals() -> Iterator[None]:
    """SIGINT and SIGTERM blocked in this thread while the block runs (it forks).

    A forked child starts with its parent's Python signal handlers, which run at the child's first
    bytecode, before :func:`forked_worker_init` resets them. A SIGTERM that reaches the child
    there (a pool stopped right after it started: ``redraw`` of a damaged folder) raised the CLI's
    :class:`~hertzchain.cli.main.Terminated` in it, outside multiprocessing's ``try``, so the child
    did not exit: it returned into its parent's code and went on running it (a second copy of a
    test, then a test runner waiting forever for work; its parent waiting forever for it). The
    child inherits the blocked mask and :func:`forked_worker_init` unblocks both signals once
    their dispositions are its own; the parent receives any that arrived meanwhile on leaving the
    block."""
    previous = signal.pthread_sigmask(signal.SIG_BLOCK, _HELD)
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, previous)


def forked_pool(processes: int):
    """A ``multiprocessing`` pool of ``processes`` forked workers, started under
    :func:`held_signals`, each running :func:`forked_worker_init` first."""
    import multiprocessing

    with held_signals():
        return multiprocessing.get_context("fork").Pool(processes, initializer=forked_worker_init)


def start_forked(process) -> None:
    """Start the fork-context ``multiprocessing.Process`` ``process`` under :func:`held_signals`
    (its target must call :func:`forked_worker_init` first)."""
    with held_signals():
        process.start()
