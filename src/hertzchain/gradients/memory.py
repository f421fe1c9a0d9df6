"""Memory of a sensitivity, estimated before anything is allocated, and the refusal past what the
machine has.

Every part is linear in the beads, the variables and the samples (issue 38: the set-up's
derivatives were once a dense variables x beads matrix, 0.57 GB at 1,000 beads and 19 GB at
20,000):

- the set-up (:mod:`~hertzchain.gradients.setup`): a few rows of the complex step over every
  array (:data:`~hertzchain.gradients.setup.COLOURS` per list, one per scalar field) while they are
  computed, then each variable's nonzero entries (a bead's diameter moves about ten; a material
  constant every contact) and the Python objects that hold them, measured at ~3.4 kB per variable
  (benchmarks/sensitivity_memory.py);
- the engines (:func:`hertzchain.integrate.derivatives.differentiate.engine_bytes`): the taped run's
  checkpoints, step log and records, and the reverse sweep's replayed group; or, in tangent mode,
  the D tangents;
- the result: a few Python objects per variable;
- ``energy_to_body``: a few numbers per step of the run (the body's state at every step).
"""

from __future__ import annotations

from dataclasses import dataclass, field

from ..errors import ConfigError

__all__ = ["MemoryEstimate", "estimate_memory", "check_memory", "PER_VARIABLE_BYTES"]

#: Bytes per variable beyond its derivative's entries: the set-up's dictionaries and arrays of it
#: (~3.4 kB measured) and the result's rows (gradient, value, unit), rounded up.
PER_VARIABLE_BYTES = 6 * 1024
#: Complex (rows, bodies) arrays alive at once while the set-up is computed (~16 measured).
SETUP_ARRAYS = 24
#: Arrays of the set-up a scalar field (a material constant, the striker's speed) moves, every entry.
SETUP_OUTPUTS = 17
#: Bytes per step of the run that ``energy_to_body`` keeps (the body's state at every step, the
#: trapezoids, four seeds a step and their sorted copies).
ENERGY_BYTES_PER_STEP = 400


@dataclass
class MemoryEstimate:
    """What a sensitivity will take [bytes], by part.

    Attributes
    ----------
    parts : dict
        ``{"setup": ..., "tape": ..., "sweep": ...}`` or with ``"tangent"``; ``"variables"`` the
        per-variable objects.
    fields : dict
        The input to change for each part (what a refusal names).
    group : int
        Of the sweep, the steps of one replayed group [bytes].
    """

    parts: dict[str, int]
    fields: dict[str, str] = field(default_factory=dict)
    group: int = 0

    @property
    def total(self) -> int:
        """All parts [bytes]."""
        return int(sum(self.parts.values()))


def estimate_memory(cfg, system, duration: float, paths: list[str], tangent: bool,
                    objective: str = "peak_wall_force") -> MemoryEstimate:
    """Memory of :func:`hertzchain.sensitivity` for a validated config (see the module docstring).

    Parameters
    ----------
    cfg : RunConfig
        The config.
    system : System
        Its arrays.
    duration : float
        Run length [s].
    paths : list of str
        The variables (expanded).
    tangent : bool
        Tangent mode (one direction per variable) instead of the adjoint.
    objective : str
        The result (``energy_to_body`` keeps a few numbers per step of the run).

    Returns
    -------
    MemoryEstimate
        The parts.
    """
    from ..integrate.derivatives.differentiate import engine_bytes
    from .setup import _plan

    rows_of, masks = _plan(cfg, paths)
    rows = max(rows_of.values(), default=0) + 1
    dense_rows = rows - len(masks)  # scalar fields and the items of rows of their own
    size = system.mass.size + 1
    setup = SETUP_ARRAYS * rows * size * 16 + dense_rows * SETUP_OUTPUTS * size * 16
    engines = engine_bytes(system, duration, cfg.run.sample_interval, dt=cfg.run.dt,
                           steps_per_radian=cfg.run.steps_per_radian, recorded=1,
                           directions=len(paths) if tangent else 0)
    group = engines.pop("group", 0)
    steps = engines.pop("steps")
    parts = {"setup": setup, "variables": PER_VARIABLE_BYTES * len(paths), **engines}
    if objective == "energy_to_body":
        parts["objective"] = ENERGY_BYTES_PER_STEP * steps
    fields = {"setup": "variables", "variables": "variables", "tape": "run.duration", "sweep": "run.duration",
              "tangent": "mode", "objective": "run.duration"}
    return MemoryEstimate(parts, fields, group)


def check_memory(est: MemoryEstimate, available: int | None = None) -> None:
    """Refuse (ConfigError naming the input behind the largest part) a sensitivity that would not
    fit in the memory available (:func:`hertzchain.checks.available_memory`, of which a run may
    plan to use :data:`hertzchain.checks.MEMORY_SHARE`), or whose reverse sweep would store more
    steps at once than :data:`hertzchain.integrate.derivatives.differentiate.GROUP_LIMIT`.

    Parameters
    ----------
    est : MemoryEstimate
        From :func:`estimate_memory`.
    available : int, optional
        Memory available [bytes]; the machine's when None.
    """
    from ..checks import MEMORY_SHARE, available_memory
    from ..integrate.derivatives.differentiate import GROUP_LIMIT

    if est.group > GROUP_LIMIT:
        raise ConfigError("run.sample_interval", f"the reverse sweep would replay {est.group / 2**20:.0f} MiB of steps "
                          f"at once (most: {GROUP_LIMIT / 2**20:.0f} MiB): the run's checkpoints are too far apart "
                          "for this many beads; shorten run.duration or raise run.sample_interval")
    available = available_memory() if available is None else available
    if available is None or est.total <= MEMORY_SHARE * available:
        return
    part = max(est.parts, key=est.parts.get)
    hints = {"variables": "differentiate by fewer variables (--wrt)",
             "tape": "shorten run.duration or raise run.sample_interval",
             "sweep": "shorten run.duration or raise run.sample_interval",
             "tangent": "use the adjoint (mode 'adjoint'), whose memory does not grow with the variables",
             "objective": "energy_to_body keeps every step of the run: shorten run.duration"}
    detail = ", ".join(f"{k} {v / 2**30:.2g} GiB" for k, v in est.parts.items())
    raise ConfigError(est.fields[part], f"the sensitivity would need about {est.total / 2**30:.3g} GiB ({detail}), "
                      f"more than the {available / 2**30:.3g} GiB of memory available; the largest part is the "
                      f"{part}: {hints.get(part, hints['variables'])}")
