"""Driver of the derivative engines: a System's taped primal run (:func:`record`), the gradient of a
scalar result by the adjoint (:func:`gradient`), and directional derivatives of the recorded
forces by the tangent model (:func:`tangents`).

A result is described to the engines by its *seeds* (:class:`Seeds`): the partial derivatives
of the result with respect to the forces of the steps it reads. Gradients come back per
System array (:data:`PARAMETERS`: kappa, damping, d0, de, dx0, rsum, fext, inv_mass, v0), shaped
like the System's own arrays; the chain rule to config fields is the caller's
(:mod:`hertzchain.gradients`).

What the derivative means: that of the result the engine computes, on the step sequence it used
(the adaptive step is held fixed, see :mod:`~hertzchain.integrate.derivatives.tape`). A finite difference
with the adaptive step sees small jumps (of the order of the integration error, ~1e-6 relative at
the default accuracy) where a parameter change alters the sequence; with a fixed ``run.dt`` the
two agree to the finite difference's own error.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ...errors import ConfigError, SimulationDiverged
from ...model import System
from . import adjoint as _adjoint
from ..core import kernels
from . import tangent as _tangent
from .adjoint import STATE_U, STATE_V
from ..core.generated import is_generated
from .law_derivatives import law_engines
from ..core.extension import EXT_W
from ..core.layout import PAD, Packed, pack
from .tape import replay_group, tape_forward
from ..drivers.verlet import StepPlan, initialise, refine_peak, step_plan

__all__ = ["PARAMETERS", "Seeds", "Tape", "record", "gradient", "tangents", "CHECKPOINT_BYTES", "state_seed", "replay", "state_after", "replay_groups",
           "STATE_U", "STATE_V", "engine_bytes"]

#: System arrays the engines differentiate, in the order of the kernels' gradient rows (v0 last):
#: then a protected body's mount, its spring ``mount_k`` [N/m], dashpot ``mount_c`` [N s/m] and
#: deflection at rest ``mount_d0`` [m] (scalars, as the System holds them), the elastic-plastic
#: law's yield overlaps ``dyield`` [m] (``System.yield_overlap()``; per contact), and the internal
#: springs ``res_k`` [N/m] and inverse internal masses ``res_inv_mass`` [1/kg] of mass-in-mass beads
#: (per body, 0 where none).
PARAMETERS = ("kappa", "damping", "d0", "de", "dx0", "rsum", "fext", "inv_mass", "v0", "mount_k", "mount_c",
              "mount_d0", "dyield", "res_k", "res_inv_mass")
#: Gradient rows of the kernels: the eight per-slot arrays, the linear k and c, dyield, the internal
#: springs and inverse internal masses.
_ROWS = 13
#: Most memory [bytes] the checkpoints of a reverse sweep may take; past it, checkpoints are kept
#: every few blocks (the replay of a group then stores more steps at once).
CHECKPOINT_BYTES = 256 * 2**20
#: Most memory [bytes] the steps of one replayed group may take.
GROUP_BYTES = 64 * 2**20
#: Most memory [bytes] the reverse sweep's stored steps of one group may take (checked before the
#: run by :mod:`hertzchain.gradients.memory` with :func:`engine_bytes`).
GROUP_LIMIT = 4 * GROUP_BYTES
#: Steps between two checkpoints (at most, at the smallest step the run can take): the replayed
#: states of a group then stay in the caches, and the checkpoints are few (writing one per block,
#: a few steps, made the taped run twice as slow as the engine's: memory traffic).
GROUP_STEPS = 256


@dataclass(frozen=True)
class Seeds:
    """Partials dJ/dF^(s)_j of a scalar result J: ``weight[i]`` on the force of contact
    ``contact[i]`` at step ``step[i]`` (-1: t = 0), sorted by step. A contact number
    :data:`STATE_U` + i (:data:`STATE_V` + i) seeds the position (velocity) of slot i after the
    step instead (:func:`state_seed`): a result that reads the state, as a body's speed."""

    step: np.ndarray
    contact: np.ndarray
    weight: np.ndarray

    @staticmethod
    def build(items: list[tuple[int, int, float]], arrays=None) -> "Seeds":
        """Seeds from (step, contact, weight) triples (any order; zero weights dropped).

        Parameters
        ----------
        items : list of (int, int, float)
            Step (-1 for t = 0), contact number and weight [result unit per N].
        arrays : (array, array, array), optional
            More seeds as three arrays (steps, contacts, weights).

        Returns
        -------
        Seeds
            Sorted by step.
        """
        items = [(int(s), int(c), float(w)) for s, c, w in items if w != 0.0]
        step = np.array([i[0] for i in items], np.int64)
        contact = np.array([i[1] for i in items], np.int64)
        weight = np.array([i[2] for i in items], float)
        if arrays is not None:  # many seeds (one per step of a run) come as arrays
            keep = np.asarray(arrays[2]) != 0.0
            step = np.concatenate([step, np.asarray(arrays[0], np.int64)[keep]])
            contact = np.concatenate([contact, np.asarray(arrays[1], np.int64)[keep]])
            weight = np.concatenate([weight, np.asarray(arrays[2], float)[keep]])
        order = np.lexsort((contact, step))
        return Seeds(step[order], contact[order], weight[order])


@dataclass
class Tape:
    """A taped primal run: what :func:`gradient` needs, and the records results are read from.

    Attributes
    ----------
    system : System
        The run's arrays.
    time : numpy.ndarray
        Sample times [s], (K,).
    contacts : numpy.ndarray
        Contacts whose forces are recorded.
    forces : numpy.ndarray
        (K, len(contacts)) recorded forces [N].
    max_force, max_force_sample : numpy.ndarray
        Every contact's largest sampled force [N] and the sample it came from.
    peak : numpy.ndarray
        The wall-peak tracker (``kernels._verlet_run``); ``peak_step`` the step of its maximum.
    peak_wall_force, peak_wall_time : float
        Refined as :func:`hertzchain.integrate.drivers.verlet.refine_peak` does [N, s].
    step_end : numpy.ndarray
        Steps made up to each sample (the forces of sample k are those of step step_end[k] - 1).
    n_steps : int
        Steps of the run.
    """

    system: System
    plan: StepPlan
    packed: Packed
    time: np.ndarray
    contacts: np.ndarray
    forces: np.ndarray
    max_force: np.ndarray
    max_force_sample: np.ndarray
    peak: np.ndarray
    peak_step: int
    peak_wall_force: float
    peak_wall_time: float
    step_end: np.ndarray
    n_steps: int
    ns_log: np.ndarray
    ckpt: np.ndarray
    group: int
    u0: np.ndarray
    v0: np.ndarray
    w0: np.ndarray  # (1, P): the internal masses' positions at t = 0 (mass-in-mass beads; zeros else)

    def sample_step(self, k: int) -> int:
        """Global step whose forces are sample ``k`` (-1 for sample 0, t = 0).

        Parameters
        ----------
        k : int
            Sample number.

        Returns
        -------
        int
            The step.
        """
        return int(self.step_end[k]) - 1


def _samples(duration: float, sample_interval: float) -> int:
    return int(math.floor(duration / sample_interval + 1e-9)) + 1


#: Hand-written laws the derivative engines differentiate (engine codes), both the adjoint and the
#: tangent model; every law run by the generated engines too (:mod:`.law_derivatives`).
LAWS = frozenset({0, 1, 2, 3})
#: Laws whose few-variable sensitivities ``mode="auto"`` gives to the tangent model: the
#: elastic-plastic law (3) goes to the adjoint, whose sweep costs less than the tangent's three
#: reverse-mode partials per contact and step (:func:`tangent.tangent_run`); ``mode="tangent"``
#: takes it too.
TANGENT_LAWS = frozenset({0, 1, 2})


def tangent_covers(law: int) -> bool:
    """Whether ``mode="auto"`` gives few-variable sensitivities of engine code ``law`` to the tangent
    model (forward mode; every law it differentiates, :data:`LAWS`, can be asked for by name)."""
    return law in TANGENT_LAWS or is_generated(law)


def _pstore(system: System, steps: int, n: int) -> np.ndarray:
    """The per-step state a replay stores: the elastic-plastic law's (dmax, dres, kres), a generated
    law's state (one row), or none (a placeholder)."""
    if system.law == kernels.LAW_ELASTOPLASTIC:
        return np.zeros((3, steps, n))
    return np.zeros((1, steps, n)) if is_generated(system.law) else np.zeros((3, 1, 1))


def _inner(system: System) -> bool:
    """Whether the model has mass-in-mass beads (internal masses the engines step)."""
    res_k = getattr(system, "res_k", None)
    return res_k is not None and bool(np.any(res_k != 0.0))


def _stores(system: System, steps: int, n: int, velocities: bool = False) -> tuple:
    """What a replay of ``steps`` steps stores (``tape.replay_group``): positions, the velocities
    the forces see (a general model's, or when ``velocities``), step lengths, the law's state, the
    internal masses' positions."""
    vel = velocities or system.general
    return (np.zeros((steps, n)), np.zeros((steps if vel else 1, n)), np.zeros(steps), _pstore(system, steps, n),
            np.zeros((steps if _inner(system) else 1, n)))


def _step_arrays(system: System) -> int:
    """Arrays of P doubles the reverse sweep stores per step (positions; the velocities the forces
    see; the elastic-plastic state, or a generated law's; the internal masses' positions)."""
    if system.law == kernels.LAW_ELASTOPLASTIC:
        return 5 + _inner(system)
    return (3 if is_generated(system.law) else 2 if system.general else 1) + _inner(system)


def check_law(system: System) -> None:
    """Refuse (ConfigError naming the field) a law or model the engines do not differentiate.

    Parameters
    ----------
    system : System
        The model's arrays.
    """
    from ...contact import LAW_CODES

    if is_generated(system.law):  # a registry law: its partials (and its state's), a protected body's mount
        law_engines(system.law, _inner(system), system.extended)
        return
    if system.law not in LAWS:
        name = next((k for k, v in LAW_CODES.items() if v == system.law), str(system.law))
        raise ConfigError("contact.law", f"gradients do not differentiate the '{name}' law yet; they cover "
                          "'elastic', 'viscoelastic', 'viscoelastic_scaled', 'dashpot' and 'elastoplastic'")


def _checkpoints(system: System, plan: StepPlan, n_samples: int, sample_interval: float,
                 n_slots: int) -> tuple[int, int, int, int]:
    """(blocks, rows per checkpoint, blocks per checkpoint, most steps of a block) of a taped run."""
    n_blocks = (n_samples - 1) * plan.n_sub
    # u, v, a (and dmax, dres, kres; or a generated law's state; then the internal masses' w, wv)
    rows = (6 if system.law == kernels.LAW_ELASTOPLASTIC else 4 if is_generated(system.law) else 3) + 2 * _inner(system)
    per_ckpt = rows * n_slots * 8
    ns_max = plan.stride if plan.stride > 0 else math.ceil(sample_interval / plan.n_sub / plan.dt - 1e-9)
    group = max(1, GROUP_STEPS // max(ns_max, 1), math.ceil(n_blocks * per_ckpt / CHECKPOINT_BYTES))
    return n_blocks, rows, group, ns_max


def engine_bytes(system: System, duration: float, sample_interval: float, dt: float | None = None,
                 steps_per_radian: float | None = None, recorded: int = 1, directions: int = 0) -> dict[str, int]:
    """Memory [bytes] the derivative engines will take for a run, before anything is allocated.

    Parameters
    ----------
    system : System
        The model's arrays.
    duration, sample_interval : float
        Run length and sample spacing [s].
    dt, steps_per_radian : float, optional
        As for :func:`record`.
    recorded : int
        Contacts recorded at every sample.
    directions : int
        Tangent directions (0: the adjoint: a taped run and one reverse sweep).

    Returns
    -------
    dict
        ``{"tape": ..., "sweep": ..., "group": ...}`` (the adjoint: checkpoints, step log, records;
        the reverse sweep; of it, the steps of one replayed group, which :func:`gradient` bounds by
        4 GROUP_BYTES; and the most steps the run can take, a count) or ``{"tape": ..., "tangent": ...}``
        (the taped run, the D tangents and their records); every part linear in the bodies, the
        samples and the directions.
    """
    plan = step_plan(system, sample_interval, dt, steps_per_radian)
    n_samples = _samples(duration, sample_interval)
    p = -(-(system.n_moving + 1) // PAD) * PAD  # the padded slots (layout.pack): moving bodies, ghost
    records = n_samples * (recorded + 4) * 8  # forces, times, step ends, scratch
    state = 24 * p * 8  # the packed System, the state, forces, trackers
    # th, v0t, the tangents (and the internal masses', the elastic-plastic state's), their records
    extra = 3 * _inner(system) + 2 * (system.law == kernels.LAW_ELASTOPLASTIC)
    per_dir = (_ROWS + 1 + 7 + extra) * (p + 1) * 8 + n_samples * recorded * 8
    n_blocks, rows, group, ns_max = _checkpoints(system, plan, n_samples, sample_interval, p)
    tape = records + state + max(1, -(-n_blocks // group)) * rows * p * 8 + max(n_blocks, 1) * 8
    if directions:  # sensitivity() tapes the run, then runs the tangents (trace_sensitivity only the latter)
        return {"tape": tape, "tangent": records + state + directions * per_dir, "steps": max(n_blocks, 1) * ns_max}
    per_step = _step_arrays(system)
    group_rows = group * ns_max + 1
    sweep = group_rows * (p + 1) * 8 * (per_step + 1) + (_ROWS + 16) * p * 8
    return {"tape": tape, "sweep": sweep, "group": group_rows * (p + 1) * 8 * per_step,
            "steps": max(n_blocks, 1) * ns_max}


def record(system: System, duration: float, sample_interval: float, dt: float | None = None,
           steps_per_radian: float | None = None, contacts=None) -> Tape:
    """Run ``system`` as :func:`hertzchain.integrate.drivers.verlet.run_verlet` does, keeping the tape.

    Parameters
    ----------
    system : System
        The model's arrays.
    duration, sample_interval : float
        Run length and sample spacing [s].
    dt : float, optional
        Fixed step [s]; adaptive when None.
    steps_per_radian : float, optional
        Accuracy of the adaptive step.
    contacts : sequence of int, optional
        Contacts whose forces are recorded at every sample (the wall contact is always added
        when there is a wall).

    Returns
    -------
    Tape
        Records and checkpoints.
    """
    check_law(system)
    plan = step_plan(system, sample_interval, dt, steps_per_radian)
    n_samples = _samples(duration, sample_interval)
    w = pack(system)
    nc = system.n_contacts
    wanted = sorted(set(int(c) for c in (contacts or ())) | ({system.n_beads} if system.has_wall else set()))
    rec = np.array(wanted or [0], dtype=np.int64)
    u, v = w.u, w.v
    u0, v0 = u.copy(), v.copy()
    w0 = (w.ext[:, EXT_W] if w.ext.shape[0] else np.zeros(w.n_slots)).reshape(1, -1).copy()
    g = np.zeros(w.n_slots + 1)
    a = np.zeros(w.n_slots)
    out_f = np.empty((n_samples, rec.size))
    fmax = np.empty(nc)
    peak = np.empty(8)
    acc = np.zeros(8)
    scratch = np.empty(n_samples)
    initialise(system, w, u, v, g, a, rec, out_f, scratch, scratch, scratch, np.empty((1, 1)), False, fmax, peak, acc,
               np.empty(n_samples), w.ext, np.empty((1, 4)))
    n_blocks, rows, group, _ = _checkpoints(system, plan, n_samples, sample_interval, w.n_slots)
    ckpt = np.empty((max(1, -(-n_blocks // group)), rows, w.n_slots))
    ns_log = np.zeros(max(n_blocks, 1), dtype=np.int64)
    step_end = np.zeros(n_samples, dtype=np.int64)
    fmax_k = np.zeros(nc, dtype=np.int64)
    kstar = np.full(1, -1, dtype=np.int64)
    forward = law_engines(system.law, _inner(system), system.extended)[0] if is_generated(system.law) else tape_forward
    status = forward(u, v, a, g, w.inv_mass, w.kappa, w.damping, w.d0, w.de, w.dx0, w.rsum, w.fext, w.dcap,
                     w.dyield, w.dmax, w.dres, w.kres, system.law, system.general, w.wall_slot, sample_interval,
                     plan.stride, plan.n_sub, plan.n_eval, plan.c_steps, plan.relax, n_samples, rec, out_f, fmax,
                     fmax_k, peak, kstar, acc, ns_log, step_end, ckpt, group, w.ext, w.ext.shape[0] > 0)
    if status != 0:
        raise SimulationDiverged("the integration diverged (non-finite state); check the inputs")
    fpk, t_pk = refine_peak(peak)
    return Tape(system=system, plan=plan, packed=w, time=np.arange(n_samples) * sample_interval, contacts=rec,
                forces=out_f, max_force=fmax, max_force_sample=fmax_k, peak=peak.copy(), peak_step=int(kstar[0]),
                peak_wall_force=fpk, peak_wall_time=t_pk, step_end=step_end, n_steps=int(acc[2]), ns_log=ns_log,
                ckpt=ckpt, group=group, u0=u0, v0=v0, w0=w0)


def state_seed(slot: int, velocity: bool = False) -> int:
    """The contact number of a seed on the position (or velocity) of ``slot`` (body) after a step.

    Parameters
    ----------
    slot : int
        The body (0: striker, N + 1: a protected body).
    velocity : bool
        The velocity instead of the position.

    Returns
    -------
    int
        The number to give :meth:`Seeds.build`.
    """
    return (STATE_V if velocity else STATE_U) + int(slot)


def _check_seeds(tape: Tape, seeds: Seeds) -> None:
    if seeds.step.size and (seeds.step[0] < -1 or seeds.step[-1] >= tape.n_steps):
        raise ValueError(f"seeds address steps {seeds.step[0]}..{seeds.step[-1]}; the run has 0..{tape.n_steps - 1}")
    n = tape.packed.n_slots
    c = seeds.contact % STATE_U  # the slot of a state seed, the contact of a force's
    if c.size and (seeds.contact.min() < 0 or seeds.contact.max() >= STATE_V + n or c.max() >= n):
        raise ValueError("seeds address a contact or body the system does not have")


def state_after(tape: Tape, k: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The state (positions [m], velocities [m/s], accelerations [m/s^2] of every slot) at sample
    ``k``, as the engine had it (run again from the last checkpoint before it).

    Parameters
    ----------
    tape : Tape
        From :func:`record`.
    k : int
        Sample number (> 0).

    Returns
    -------
    (numpy.ndarray, numpy.ndarray, numpy.ndarray)
        u, v, a.
    """
    end = k * tape.plan.n_sub  # blocks up to sample k
    g0 = (end - 1) // tape.group
    u, v, a = _replay(tape, g0 * tape.group, end, None)
    return u, v, a


def _replay(tape: Tape, b0: int, b1: int, stores) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Blocks b0 .. b1 - 1 run again from the checkpoint of b0 (a multiple of the group), storing the
    steps into ``stores`` (``tape.replay_group``; None: into scratch of one step); the state after."""
    w, sy = tape.packed, tape.system
    n = w.n_slots
    if stores is None:
        steps = int(tape.ns_log[b0:b1].max()) * (b1 - b0) if b1 > b0 else 1
        stores = _stores(sy, steps, n)
    block = float(tape.time[1] - tape.time[0]) / tape.plan.n_sub
    u, v, a, g = np.zeros(n + 1), np.zeros(n + 1), np.zeros(n), np.zeros(n + 1)
    dmax, dres, kres = np.zeros(n), np.zeros(n), w.kappa.copy()
    replay = law_engines(sy.law, _inner(sy), sy.extended)[1] if is_generated(sy.law) else replay_group
    replay(tape.ckpt[b0 // tape.group], u, v, a, g, w.inv_mass, w.kappa, w.damping, w.d0, w.de, w.dx0, w.rsum,
           w.fext, sy.law, sy.general, w.wall_slot, tape.ns_log, b0, b1, block, stores, w.dyield, dmax, dres, kres,
           w.ext, w.ext.shape[0] > 0)
    return u, v, a


def replay_groups(tape: Tape, last_step: int):
    """The run again from its start, group of checkpoints by group, up to the group holding step
    ``last_step``: yields (global number of the group's first step, positions after each step
    (steps, slots) [m], the velocities the forces of each step see (steps, slots) [m/s], each
    step's length [s]); memory of one group at a time.

    Parameters
    ----------
    tape : Tape
        From :func:`record` (a general model: dissipation, offsets, a protected body, plasticity,
        whose replays store the velocities).
    last_step : int
        The last step needed.

    Yields
    ------
    tuple
        As above.
    """
    sy = tape.system
    n = tape.packed.n_slots
    n_blocks = (tape.time.size - 1) * tape.plan.n_sub
    first = 0
    for b0 in range(0, n_blocks, tape.group):
        b1 = min(b0 + tape.group, n_blocks)
        steps = int(tape.ns_log[b0:b1].sum())
        stores = _stores(sy, steps, n, velocities=True)
        _replay(tape, b0, b1, stores)
        yield first, stores[0], stores[1], stores[2]
        first += steps
        if first > last_step:
            return


def replay(tape: Tape, first_group: int, last_group: int) -> tuple[int, np.ndarray, np.ndarray]:
    """The positions after every step of groups ``first_group`` .. ``last_group`` (of checkpoints),
    run again from the first's checkpoint with the taped step counts.

    Parameters
    ----------
    tape : Tape
        From :func:`record`.
    first_group, last_group : int
        Groups (inclusive), clipped to the run's.

    Returns
    -------
    (int, numpy.ndarray, numpy.ndarray)
        The global number of the first step, the positions after each step (steps, slots) [m]
        and each step's length [s].
    """
    sy = tape.system
    n = tape.packed.n_slots
    n_blocks = (tape.time.size - 1) * tape.plan.n_sub
    g0 = max(0, first_group)
    b0, b1 = g0 * tape.group, min((last_group + 1) * tape.group, n_blocks)
    first = int(tape.ns_log[:b0].sum())
    steps = int(tape.ns_log[b0:b1].sum())
    stores = _stores(sy, steps, n)
    _replay(tape, b0, b1, stores)
    return first, stores[0], stores[2]


def _unpack(system: System, grad: np.ndarray, v0bar: np.ndarray) -> dict[str, np.ndarray]:
    """Gradient rows of the padded slots -> arrays shaped like the System's (the mount's as scalars)."""
    nc = system.kappa.size
    nbody = system.mass.size
    moving = getattr(system, "n_moving", system.n_beads + 1)  # bodies that move (a protected body too)
    out = {}
    for name, row in zip(PARAMETERS[:8], grad):
        size = nbody if name in ("fext", "inv_mass") else nc
        arr = np.zeros(size)
        m = min(size, row.size)
        arr[:m] = row[:m]
        out[name] = arr
    out["inv_mass"][moving:] = 0.0  # the wall (or ground) ghost has 1/m = 0 for good
    out["fext"][moving:] = 0.0
    v0 = np.zeros(nbody)
    v0[:min(nbody, v0bar.size)] = v0bar[:nbody]
    v0[moving:] = 0.0
    out["v0"] = v0
    mount = system.n_beads + 1  # a protected body's mount: contact N + 1 of the padded slots
    body = bool(getattr(system, "body", False))
    out["mount_k"] = np.array([grad[8, mount] if body else 0.0])
    out["mount_c"] = np.array([grad[9, mount] if body else 0.0])
    out["mount_d0"] = np.array([grad[2, mount] if body else 0.0])
    dy = np.zeros(nc)
    dy[:min(nc, grad.shape[1])] = grad[10, :nc]
    out["dyield"] = dy
    for name, r in (("res_k", 11), ("res_inv_mass", 12)):  # the internal masses of the moving bodies
        arr = np.zeros(nbody)
        m = min(moving, grad.shape[1])
        arr[:m] = grad[r, :m]
        out[name] = arr
    return out


def gradient(tape: Tape, seeds: Seeds, final_dres: np.ndarray | None = None) -> dict[str, np.ndarray]:
    """dJ/d(System arrays) of the scalar result J whose partials are ``seeds`` (one reverse sweep).

    Parameters
    ----------
    tape : Tape
        From :func:`record`.
    seeds : Seeds
        dJ/dF of the forces J reads.
    final_dres : numpy.ndarray, optional
        dJ/d(residual overlap of every contact at the end of the run) [per m], for a result that
        reads the elastic-plastic law's final state (the plastic work).

    Returns
    -------
    dict
        ``{name: array}`` for every name of :data:`PARAMETERS`, shaped like the System's array
        (``v0``: the initial velocities; ``inv_mass``: 1/m [1/kg]). ``d0`` and ``fext`` are zero
        unless the chain is precompressed (an aligned elastic chain without a static load skips
        them: nothing moves them there, and the sweep is faster without).
    """
    _check_seeds(tape, seeds)
    w, sy = tape.packed, tape.system
    n = w.n_slots
    n_blocks = (tape.time.size - 1) * tape.plan.n_sub
    ub, vb, ab = np.zeros(n), np.zeros(n), np.zeros(n)
    grad = np.zeros((_ROWS, n))
    group_steps = np.add.reduceat(tape.ns_log, np.arange(0, max(n_blocks, 1), tape.group)) if n_blocks else np.ones(1)
    max_rows = int(max(1, group_steps.max()))
    per_step = _step_arrays(sy)
    if max_rows * (n + 1) * 8 * per_step > GROUP_LIMIT:
        raise ConfigError("run.dt", f"a group of {max_rows} steps between two checkpoints needs more memory than the "
                          "reverse sweep allows; use a larger run.dt or a shorter run.duration")
    block = float(tape.time[1] - tape.time[0]) / tape.plan.n_sub if tape.time.size > 1 else 0.0
    sb = np.zeros((2, n))  # adjoints of the elastic-plastic state (residual overlap, stiffness) at the end
    if final_dres is not None:
        sb[0, :final_dres.size] = final_dres
    generated = law_engines(sy.law, _inner(sy), sy.extended) if is_generated(sy.law) else None
    if generated is not None and n_blocks:
        generated[3](tape.ckpt, tape.ns_log, tape.group, n_blocks, block, tape.u0, tape.v0, ub, vb, ab, w.inv_mass,
                     w.kappa, w.damping, w.d0, w.de, w.dx0, w.rsum, w.fext, sy.law, sy.general, w.wall_slot, seeds.step,
                     seeds.contact, seeds.weight, grad, max_rows, w.ext, w.dyield, sb, tape.w0)
    elif generated is not None:
        generated[4](tape.u0, tape.v0, ub, vb, ab, w.inv_mass, w.kappa, w.damping, w.d0, w.de, w.dx0, w.rsum, w.fext,
                     seeds.step, seeds.contact, seeds.weight, seeds.step.size, grad, sb[0], w.ext,
                     (tape.w0, np.zeros(n), np.zeros(n), np.zeros(n), _inner(sy)))
    elif n_blocks:
        _adjoint.reverse_sweep_of(sy.law, sy.general)(
            tape.ckpt, tape.ns_log, tape.group, n_blocks, block, tape.u0, tape.v0, ub, vb, ab, w.inv_mass, w.kappa,
            w.damping, w.d0, w.de, w.dx0, w.rsum, w.fext, sy.law, sy.general, w.wall_slot,
            (seeds.step, seeds.contact, seeds.weight, grad, max_rows, w.ext, w.dyield, sb, tape.w0))
    else:
        _adjoint._adjoint_initial(tape.u0, tape.v0, ub, vb, ab, w.inv_mass, w.kappa, w.damping, w.d0, w.de, w.dx0,
                                  w.rsum, w.fext, sy.law, sy.general, seeds.step, seeds.contact, seeds.weight,
                                  seeds.step.size, grad, w.ext, w.dyield, sb,
                                  (tape.w0, np.zeros(n), np.zeros(n), np.zeros(n), _inner(sy)))
    return _unpack(sy, grad, vb)


def _pad_rows(system: System, directions: dict[str, np.ndarray], n_dirs: int, n_slots: int):
    th = np.zeros((_ROWS, n_dirs, n_slots))
    v0t = np.zeros((n_dirs, n_slots))
    moving = getattr(system, "n_moving", system.n_beads + 1)
    mount = system.n_beads + 1
    for name, arr in directions.items():
        arr = np.atleast_2d(np.asarray(arr, dtype=float))
        if name == "v0":
            m = min(arr.shape[1], moving)
            v0t[:, :m] = arr[:, :m]
            continue
        if name in ("dyield", "res_k", "res_inv_mass"):
            m = min(arr.shape[1], n_slots, system.kappa.size if name == "dyield" else moving)
            th[{"dyield": 10, "res_k": 11, "res_inv_mass": 12}[name], :, :m] += arr[:, :m]
            continue
        if name in ("mount_k", "mount_c", "mount_d0"):
            th[{"mount_k": 8, "mount_c": 9, "mount_d0": 2}[name], :, mount] += arr[:, 0]
            continue
        r = PARAMETERS.index(name)
        m = min(arr.shape[1], n_slots, moving if name in ("fext", "inv_mass") else system.kappa.size)
        th[r, :, :m] += arr[:, :m]
    return th, v0t


def tangents(system: System, directions: dict[str, np.ndarray], duration: float, sample_interval: float,
             dt: float | None = None, steps_per_radian: float | None = None, contacts=None,
             seeds: Seeds | None = None, final_dres: np.ndarray | None = None
             ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Directional derivatives of the recorded forces (and of a seeded scalar) by the tangent model.

    Parameters
    ----------
    system : System
        The model's arrays.
    directions : dict
        ``{name: (D, size) array}``: the derivative of System array ``name`` (a name of
        :data:`PARAMETERS`) along each of the D directions (arrays not given: zero).
    duration, sample_interval : float
        Run length and sample spacing [s].
    dt, steps_per_radian : float, optional
        Fixed step [s], or the adaptive step's accuracy.
    contacts : sequence of int, optional
        Contacts recorded (default: the wall contact, or contact 0 without a wall).
    seeds : Seeds, optional
        Partials of a scalar result on the step forces (as for :func:`gradient`).
    final_dres : numpy.ndarray, optional
        As for :func:`gradient`: the partials of the scalar on the elastic-plastic law's residual
        overlaps at the end of the run [per m].

    Returns
    -------
    (numpy.ndarray, numpy.ndarray, numpy.ndarray, numpy.ndarray)
        Contacts recorded (C,), forces (K, C) [N], their derivatives (D, K, C) [N per unit of
        the direction] and the seeded scalar's directional derivatives (D,).
    """
    check_law(system)
    plan = step_plan(system, sample_interval, dt, steps_per_radian)
    n_samples = _samples(duration, sample_interval)
    w = pack(system)
    n = w.n_slots
    n_dirs = max((np.atleast_2d(x).shape[0] for x in directions.values()), default=1)
    th, v0t = _pad_rows(system, directions, n_dirs, n)
    default = [system.n_beads] if system.has_wall else [0]
    rec = np.array(sorted(set(int(c) for c in (contacts if contacts is not None else default))), dtype=np.int64)
    u, v = w.u, w.v
    g = np.zeros(n + 1)
    a = np.zeros(n)
    out_f = np.empty((n_samples, rec.size))
    fmax = np.empty(system.n_contacts)
    peak = np.empty(8)
    acc = np.zeros(8)
    scratch = np.empty(n_samples)
    initialise(system, w, u, v, g, a, rec, out_f, scratch, scratch, scratch, np.empty((1, 1)), False, fmax, peak, acc,
               np.empty(n_samples), w.ext, np.empty((1, 4)))
    out_ft = np.zeros((n_dirs, n_samples, rec.size))
    dj = np.zeros(n_dirs)
    seeds = seeds or Seeds.build([])
    if is_generated(system.law):  # the generated law's tangent run, its state's tangents too
        run = law_engines(system.law, _inner(system), system.extended)[2]
        status = run(u, v, a, g, w.inv_mass, w.kappa, w.damping, w.d0, w.de, w.dx0, w.rsum, w.fext, w.dcap, w.dmax,
                     sample_interval, plan.stride, plan.n_sub, plan.n_eval, plan.c_steps, plan.relax, n_samples, acc, th,
                     v0t, rec, out_f, out_ft, seeds.step, seeds.contact, seeds.weight, dj, w.ext)
    else:
        status = _tangent.tangent_run(u, v, a, g, w.inv_mass, w.kappa, w.damping, w.d0, w.de, w.dx0, w.rsum,
                                      w.fext, w.dcap, system.law, system.general, w.wall_slot, sample_interval,
                                      plan.stride, plan.n_sub, plan.n_eval, plan.c_steps, plan.relax, n_samples, acc,
                                      th, v0t, rec, out_f, out_ft, seeds.step, seeds.contact, seeds.weight, dj, w.ext,
                                      (w.dyield, w.dmax, w.dres, w.kres),
                                      np.zeros(0) if final_dres is None else np.asarray(final_dres, dtype=float))
    if status != 0:
        raise SimulationDiverged("the integration diverged (non-finite state); check the inputs")
    return rec, out_f, out_ft, dj
