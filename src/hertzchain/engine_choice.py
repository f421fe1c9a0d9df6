"""``integrator = "auto"`` and ``threads = "auto"``: which engine runs a model on this machine.

The rules (documented in the user guide's "Running" page, tested per model kind in
tests/test_engine_choice.py):

* integrator: the fourth-order ``"rkn4"`` (:mod:`hertzchain.integrate.drivers.rkn`) when it integrates the
  model, i.e. a chain without a protected body or mass-in-mass beads, with the elastic law (aligned:
  its default step control keeps the peak wall force within ~1e-8 of DOP853, better than the
  Verlet's ~1e-6, at a fraction of the steps), or Kuwabara-Kono's or the dashpot, plain or
  size-scaled, or beads offset from the axis (:mod:`hertzchain.integrate.drivers.rkn_damped`: within
  ~4e-7 on the paper's chain 1), a registry law (power, Hunt-Crossley, a user's, with or without
  per-contact state) or the elastic-plastic law (:mod:`hertzchain.integrate.drivers.rkn_laws`: the
  same method and bound with the law's own analytic slopes, every change of a contact's branch
  landed on; tests/test_rkn_laws.py; at n = 3/2 the power law is the elastic law's own engine).
  Otherwise, or when the call sets the Verlet's own accuracy (``steps_per_radian``), a fixed
  step ``dt`` or several threads that ``rkn4`` does not run, the compiled velocity ``"verlet"`` (peak wall force within ~1e-6).
* threads: more than one only where a threaded engine runs the model (the Verlet on a chain of
  beads, every contact law, offsets too; not a protected body nor mass-in-mass beads,
  :mod:`hertzchain.integrate.drivers.threaded`; ``rkn4`` on an aligned elastic chain,
  :mod:`hertzchain.integrate.drivers.rkn_threaded`; its other paths run one thread), the chain is long enough for a per-step barrier to pay
  (:data:`AUTO_THREADS_MIN_BEADS` beads, :data:`BEADS_PER_THREAD` per thread) and cores are free:
  the cores this process may run on (``os.sched_getaffinity``) less the one-minute load average
  beyond this process's own (a barrier that waits for a scheduler slice makes a shared core
  slower than one thread: 0.6x measured at 1e4-1e5 beads). Anything else: one thread.

Nothing here imports a compiled kernel: the choice is made, and refused, before any compilation.
"""

from __future__ import annotations

import os
from dataclasses import dataclass

from .errors import ConfigError
from .parallel import usable_cores
# the refusals' checks: plain Python, no compiled kernel imported
from .integrate.drivers.refusals import INTEGRATORS as NAMED, refuse, why_not

__all__ = ["EngineChoice", "choose_engine", "free_cores", "rkn4_threads_refusal", "INTEGRATORS",
           "AUTO_THREADS_MIN_BEADS", "BEADS_PER_THREAD"]

#: Values of ``run.integrator``: "auto" and the integrators it picks from.
INTEGRATORS = ("auto", *NAMED)
#: ``threads = "auto"`` splits no chain shorter than this (benchmarks/long_chain.py: a barrier per
#: step, ~0.1-1 us, against ~0.7 us of work per 1e3 beads).
AUTO_THREADS_MIN_BEADS = 10_000
#: ... and gives every thread at least this many beads.
BEADS_PER_THREAD = 5_000


@dataclass(frozen=True)
class EngineChoice:
    """The engine a run uses.

    Attributes
    ----------
    integrator : str
        ``"verlet"``, ``"rkn4"``, ``"dop853"`` or ``"rk45"``.
    threads : int
        Threads sharing the chain.
    reason : str
        Why, in a few words (``hertzchain run --verbose`` prints it).
    """

    integrator: str
    threads: int
    reason: str


def free_cores() -> tuple[int, float]:
    """Cores this process may run on and the one-minute load average (0 where unknown).

    Returns
    -------
    (int, float)
        ``len(os.sched_getaffinity(0))`` (``os.cpu_count()`` where not available) and
        ``os.getloadavg()[0]``.
    """
    cores = usable_cores()
    try:
        load = float(os.getloadavg()[0])
    except (AttributeError, OSError):
        load = 0.0
    return cores, load


def rkn4_threads_refusal(system) -> str | None:
    """Why ``rkn4`` runs ``system`` on one thread only (None: it splits it,
    :mod:`hertzchain.integrate.drivers.rkn_threaded`): its threads run aligned elastic chains (the
    power law at n = 3/2 too, the elastic law it is), not its dissipative, offset or law paths.

    Parameters
    ----------
    system : hertzchain.model.System
        The model's arrays.

    Returns
    -------
    str or None
        What the model has that the threaded ``rkn4`` does not run, in a few words.
    """
    from .laws import hertz_equivalent, law_of_code

    spec = law_of_code(system.law)
    if system.extended:
        return "a protected body or mass-in-mass beads"
    if system.misaligned:
        return "beads offset from the axis"
    if not hertz_equivalent(system) and (spec.generated or spec.dissipative or spec.plastic):
        return "a contact law other than the elastic one"
    return None


def _auto_threads(system, integrator: str, cores: int, load: float) -> tuple[int, str]:
    """``threads = "auto"`` (module docstring): the count and why."""
    n = system.n_beads
    if integrator == "rkn4":
        refusal = rkn4_threads_refusal(system)
        if refusal is not None:
            return 1, f"the threaded rkn4 runs aligned elastic chains, not {refusal}"
    elif integrator != "verlet":
        return 1, "the threaded engines run the Verlet and rkn4"
    if system.extended:
        return 1, "the threaded engine runs no protected body or mass-in-mass beads"
    if n < AUTO_THREADS_MIN_BEADS:
        return 1, f"{n} beads < {AUTO_THREADS_MIN_BEADS}"
    # the load counts this process once it runs: what is beyond one is other work on the cores
    free = int(cores - max(0.0, load - 1.0))
    threads = max(1, min(cores, free, n // BEADS_PER_THREAD))
    if threads == 1:
        return 1, f"cores shared ({cores} cores, load {load:.2f})"
    return threads, f"{n} beads, {free} of {cores} cores free (load {load:.2f})"


def choose_engine(system, integrator: str = "auto", threads: int | str = "auto", *,
                  steps_per_radian: float | None = None, dt: float | None = None, cores: int | None = None,
                  load: float | None = None) -> EngineChoice:
    """Resolve ``integrator`` and ``threads`` (either may be ``"auto"``) for ``system``.

    Explicit values are kept (and checked: an integrator that does not run the model is refused
    here, naming ``run.integrator`` or ``run.threads``, before anything compiles).

    Parameters
    ----------
    system : hertzchain.model.System
        The model's arrays.
    integrator : str
        ``"auto"`` or one of :data:`INTEGRATORS`.
    threads : int or "auto"
        Threads sharing the chain.
    steps_per_radian : float or None
        The Verlet's accuracy when the call sets it (then ``"auto"`` picks the Verlet).
    dt : float or None
        A fixed step [s] when the call sets one (then ``"auto"`` picks the Verlet, whose stability
        bound the step was chosen against).
    cores, load : optional
        The machine's free cores and load average (default: :func:`free_cores`; given in tests).

    Returns
    -------
    EngineChoice
        The integrator, the threads and why.
    """
    if integrator not in INTEGRATORS:
        raise ConfigError("run.integrator", f"must be one of {', '.join(repr(i) for i in INTEGRATORS)}, "
                          f"got {integrator!r}")
    if not (threads == "auto" or (isinstance(threads, int) and not isinstance(threads, bool) and threads >= 1)):
        raise ConfigError("run.threads", f"must be 'auto' or a whole number of threads >= 1, got {threads!r}")
    if integrator != "auto":
        refuse(integrator, system)  # suggesting only the integrators that take the model
    if integrator == "auto":
        refusal = why_not("rkn4", system)
        if refusal is not None:
            integrator, why = "verlet", f"verlet: {refusal}"
        elif steps_per_radian is not None:
            integrator, why = "verlet", "verlet: its steps_per_radian is set"
        elif dt is not None:
            integrator, why = "verlet", "verlet: a fixed dt is set"
        elif isinstance(threads, int) and threads > 1 and rkn4_threads_refusal(system) is not None:
            integrator, why = "verlet", "verlet: several threads asked for (rkn4 runs them on aligned elastic chains)"
        else:
            from .laws import law_of_code

            spec = law_of_code(system.law)
            kind = "elastic-plastic" if spec.plastic else "dissipative" if spec.dissipative else "elastic"
            state = " with per-contact state" if spec.state_size else ""
            integrator, why = "rkn4", (f"rkn4: {'offset' if system.misaligned else 'aligned'} {kind} chain"
                                       f"{' (registry law' + state + ')' if spec.generated else ''}")
    else:
        why = f"{integrator}: asked for"
    if isinstance(threads, str):  # "auto" (checked above)
        if cores is None or load is None:
            machine_cores, machine_load = free_cores()
            cores = machine_cores if cores is None else cores
            load = machine_load if load is None else load
        threads, twhy = _auto_threads(system, integrator, cores, load)
    else:
        if threads > 1 and integrator == "rkn4" and rkn4_threads_refusal(system) is not None:
            raise ConfigError("run.threads", f"several threads run the integrator 'rkn4' on aligned elastic chains, "
                              f"not on {rkn4_threads_refusal(system)}; use integrator 'verlet' (every law) or "
                              "run.threads = 1 or 'auto'")
        if threads > 1 and integrator not in ("verlet", "rkn4"):
            raise ConfigError("run.threads", f"several threads run the integrators 'verlet' and 'rkn4', not {integrator!r}")
        if threads > 1 and system.extended:
            what = "a protected body (wall.type = 'body')" if system.body else "mass-in-mass beads (chain.elements)"
            raise ConfigError("run.threads", f"several threads run chains of beads (every contact law, offsets too), "
                              f"not {what}; use run.threads = 1 or 'auto' for this model")
        twhy = "asked for"
    return EngineChoice(integrator=integrator, threads=int(threads), reason=f"{why}; {threads} thread(s): {twhy}")
