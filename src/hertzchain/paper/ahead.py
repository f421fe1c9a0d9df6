"""Compile ahead: the engines a cold reproduction needs later, compiled on the second core.

A reproduction in a fresh installation (an empty Numba cache) compiled every engine in its own
process, one after another, as each model kind came up: the calibrated law's engine (the aligned
chains, and the offset beads of Fig. 3a-b, which share its one specialisation), the elastic law's
engine (the wall/chain ratio) and the two-dimensional engine (Fig. 3 with lateral freedom), while
the second core idled. :class:`CompileAhead` forks a process that makes a short run of each kind
the reproduction runs later (its kernels then lie in Numba's on-disk cache) while this one
calibrates and runs the aligned chains; :meth:`CompileAhead.wait` holds the reproduction before its
first run of a kind until the fork has compiled it, so that the run loads the kernels instead of
compiling them a second time. The results are those of a run that compiled its own kernels: the
cache holds the code the same compilation gives.

Numba's cache index is not safe against two processes adding *different* signatures of one
function at the same time (each may give its entry the same data file): the kinds compiled ahead
share no compiled function with the calibrated law's engine, which this process compiles.

Its kernels compiled, the fork also runs the wall/chain ratio (the elastic uniform chain,
:func:`~hertzchain.paper.protocol.run_wall_chain_ratio`) and sends it back
(:meth:`CompileAhead.wall_chain_ratio`): a cold reproduction's second core is otherwise idle
until this process has compiled its own engine, and the run, on the same compiled kernels, gives
the same numbers here or there.

With one usable core, no ``fork``, or Numba's compilation switched off, nothing is forked and every ``wait`` returns at once: each run compiles what it needs, as before.
"""

from __future__ import annotations

import multiprocessing
import warnings
from typing import Callable

from ..chain import Chain, paper_chain
from ..interrupts import forked_worker_init, start_forked
from ..model import Model, Wall
from ..parallel import usable_cores
from ..probes import Probes
from .protocol import Settings, run_wall_chain_ratio

__all__ = ["CompileAhead", "KINDS"]

#: The model kinds compiled ahead, in the order the fork compiles them (neither shares a compiled
#: function with the calibrated law's engine).
KINDS = ("lateral", "elastic")

#: Simulated time of each short run [s]: a few steps, enough to reach every kernel of the run.
_SHORT = 2e-6


def _placeholder_law(settings: Settings):
    """A law of the reproduction's kind for the short runs, not calibrated (a calibration would
    compile the aligned engine a second time, beside this process's): the engines take the law as
    a code and per-contact arrays, so every dissipative law compiles the same specialisation."""
    from ..contact import Dashpot, Elastic

    return Elastic() if settings.elastic else Dashpot(1.0)


def _short_run(settings: Settings, kind: str) -> None:
    """One short run of ``kind`` (:data:`KINDS`) with the reproduction's engine choices and probes."""
    from ..runs.simulation import simulate

    striker = settings.striker()
    chain2 = paper_chain("chain2", settings.material)
    if kind == "lateral":
        from . import fidelity

        fidelity.warm_lateral(settings, _placeholder_law(settings))
        return
    # the wall/chain ratio's (protocol.run_wall_chain_ratio)
    from ..contact import Elastic

    model = Model(Chain.uniform(3, chain2.diameters[0], settings.material), striker, Wall("flat"), Elastic())
    probes = Probes(settings.sample_interval / 4, contacts=(1, 3))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        simulate(model, _SHORT, probes)


def _compiling() -> bool:
    """Whether Numba compiles at all (not under NUMBA_DISABLE_JIT, where nothing is to be gained).
    Its on-disk cache needs no check: the engines' ``cache=True`` functions cannot be defined
    without a usable cache folder."""
    from numba.core import config

    return not getattr(config, "DISABLE_JIT", False)  # (set by Numba from the environment at import)


class CompileAhead:
    """The fork compiling :data:`KINDS` (module docstring); make it before the first calibration.

    Parameters
    ----------
    settings : Settings
        The reproduction's settings (its law's kind, striker, material and sampling).
    kinds : tuple of str
        The kinds to compile ahead (default :data:`KINDS`; the elastic one is left out when the
        reproduction's own law is elastic: this process compiles it first).
    """

    def __init__(self, settings: Settings, kinds: tuple[str, ...] | None = None) -> None:
        self.settings = settings
        self.kinds = tuple(k for k in (kinds or KINDS) if not (k == "elastic" and settings.elastic))
        self._ready: set[str] = set()
        self._ratio: dict | None = None
        self._proc = None
        if not self.kinds or usable_cores() < 2 or "fork" not in multiprocessing.get_all_start_methods() \
                or not _compiling():
            return
        ctx = multiprocessing.get_context("fork")
        self._reader, writer = ctx.Pipe(duplex=False)
        self._proc = ctx.Process(target=self._forked, args=(settings, writer), daemon=True)
        start_forked(self._proc)
        writer.close()

    def _forked(self, settings: Settings, writer) -> None:
        forked_worker_init()
        try:
            for kind in self.kinds:
                try:
                    _short_run(settings, kind)
                except Exception:  # noqa: BLE001 - the reproduction's own run compiles it and reports any error
                    pass
                writer.send(kind)
            if "elastic" in self.kinds:  # (its engine now in the cache: nothing compiled beside this process)
                try:
                    writer.send(("ratio", run_wall_chain_ratio(settings)))
                except Exception:  # noqa: BLE001 - the reproduction runs it itself and reports any error
                    writer.send(("ratio", None))
        finally:
            writer.close()

    def _receive(self, done: Callable[[], bool]) -> None:
        """Read the fork's messages until ``done()`` (or the fork ended)."""
        while self._proc is not None and not done():
            try:
                message = self._reader.recv()
            except EOFError:  # the fork ended (or died): the runs compile what is left
                self.close()
                return
            if isinstance(message, tuple):
                self._ratio = message[1]
                self.close()  # its last message
            else:
                self._ready.add(message)

    def wait(self, kind: str) -> None:
        """Return once ``kind`` is compiled (at once when nothing was forked or the fork ended)."""
        if kind in self.kinds:
            self._receive(lambda: kind in self._ready)

    def wall_chain_ratio(self) -> dict:
        """:func:`~hertzchain.paper.protocol.run_wall_chain_ratio` of the settings: the fork's run
        (module docstring), or this process's where there is none or it failed."""
        if "elastic" in self.kinds:
            self._receive(lambda: self._ratio is not None)
        ratio, self._ratio = self._ratio, None
        return ratio if ratio is not None else run_wall_chain_ratio(self.settings)

    def close(self) -> None:
        """Stop the fork (at the end, or after a failure)."""
        if self._proc is not None:
            if self._proc.is_alive():
                self._proc.terminate()
            self._proc.join()
            self._reader.close()
            self._proc = None
