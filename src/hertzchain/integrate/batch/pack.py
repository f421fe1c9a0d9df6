"""Set-up of a batch: models (or an Ensemble) to the packed batch an engine runs.

Two ways to the same numbers. The array set-up (:func:`_setup_groups`, :func:`_pack_groups`,
:func:`_pack_ensemble`) takes members in groups of one end, contact law kind and Probes
(:class:`~hertzchain.integrate.batch.ensemble.Ensemble` for one bead count,
:class:`~hertzchain.integrate.batch.ragged.Ragged` for several) and computes their System arrays,
step plans and initial state with array code, a few microseconds per member. The member-by-member
set-up (:func:`_setup_members`, :func:`_pack_models`: ``Model.system()``,
:func:`~hertzchain.integrate.drivers.verlet.step_plan`, :func:`~hertzchain.integrate.core.layout.pack` and
:func:`~hertzchain.integrate.drivers.verlet.initialise` per member, as
:func:`~hertzchain.integrate.drivers.verlet.run_verlet` does) takes any law, and is the reference the
array set-up reproduces bit for bit (tests/test_batch_grouped.py, tests/test_ensemble.py).
Both fill one :class:`~hertzchain.integrate.batch.buffers._Packed`, whatever engine runs it.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, NamedTuple, Sequence

import numpy as np
from numba import njit

from ...errors import ConfigError
from ...model import Model, System
from ...probes import Probes
from ..core import kernels
from ..drivers import verlet
from ..core.generated import is_generated
from .buffers import (_NAMES, _STATE, _Packed, _member_body, _member_ext, _member_forces, _member_velocities,
                            _outputs, _slot_sizes)
from .ensemble import Ensemble, layout_key
from ..core.layout import PAD, pack
from .ragged import Ragged, ragged
from .systems import systems
from ..drivers.verlet import (ADAPTIVE_STEPS_PER_RADIAN, MAX_OMEGA_DT, RELAX_EVALUATIONS, StepPlan, horizon_radians,
                     initialise, step_plan)


@dataclass
class _Member:
    """What one member needs besides the shared buffers (mirrors the locals of run_verlet)."""

    system: System
    rec: np.ndarray
    plan: StepPlan
    record_v: bool


def _pack_models(members: list[_Member], interval: float, n_samples: int) -> _Packed:
    """A batch of arbitrary models, member by member (see :func:`_pack_ensemble` for the fast path)."""
    packs = [pack(mb.system) for mb in members]
    # the per-contact state buffers (dmax ...): the elastic-plastic law's, and a generated law's state
    plastic = any(mb.system.law == kernels.LAW_ELASTOPLASTIC or is_generated(mb.system.law) for mb in members)
    pk = _outputs(interval, n_samples, plastic=plastic, n_slots=np.array([w.n_slots for w in packs], dtype=np.int64),
                  nrec=np.array([mb.rec.size for mb in members], dtype=np.int64),
                  rec=np.concatenate([mb.rec for mb in members]).astype(np.int64),
                  nb=np.array([mb.system.n_beads + 1 for mb in members], dtype=np.int64),
                  record_v=np.array([mb.record_v for mb in members], dtype=np.bool_),
                  n_contacts=np.array([mb.system.n_contacts for mb in members], dtype=np.int64),
                  law=np.array([mb.system.law for mb in members], dtype=np.int64),
                  general=np.array([mb.system.general for mb in members], dtype=np.bool_),
                  wall_slot=np.array([w.wall_slot for w in packs], dtype=np.int64),
                  stride=np.array([mb.plan.stride for mb in members], dtype=np.int64),
                  n_sub=np.array([mb.plan.n_sub for mb in members], dtype=np.int64),
                  n_eval=np.array([mb.plan.n_eval for mb in members], dtype=np.int64),
                  c_steps=np.array([mb.plan.c_steps for mb in members], dtype=np.float64),
                  relax=np.array([mb.plan.relax for mb in members], dtype=np.int64),
                  plan_dt=np.array([mb.plan.dt for mb in members], dtype=np.float64),
                  ext_on=np.array([mb.system.extended for mb in members], dtype=np.bool_),
                  body_slot=np.array([w.body_slot for w in packs], dtype=np.int64))
    flat = pk.flat
    for m, w in enumerate(packs):
        s, p = pk.off[m], w.n_slots
        for k in _NAMES + (_STATE if plastic else ()):
            flat[k][s:s + p] = getattr(w, k)
        flat["u"][s:s + p + 1] = w.u
        flat["v"][s:s + p + 1] = w.v
        if w.ext.size:
            _member_ext(pk, m)[:] = w.ext
    # ---- initial state: the very function run_verlet uses, on per-member views
    for m, (mb, w) in enumerate(zip(members, packs)):
        s, p = pk.off[m], w.n_slots
        u, v, g, a = (flat["u"][s:s + p + 1], flat["v"][s:s + p + 1], flat["g"][s:s + p + 1], flat["a"][s:s + p])
        if plastic:  # the state the kernel carries is the batch's buffers, not the pack's copies
            for k in _STATE:
                setattr(w, k, flat[k][s:s + p])
        initialise(mb.system, w, u, v, g, a, mb.rec, _member_forces(pk, m),
                   pk.out_ke[m], pk.out_pe[m], pk.out_ed[m], _member_velocities(pk, m), mb.record_v,
                   pk.fmax[pk.fmax_off[m]:pk.fmax_off[m + 1]], pk.peak[m], pk.acc[m], pk.out_wp[m],
                   ext=_member_ext(pk, m), out_b=_member_body(pk, m))
    return pk


@njit(cache=True)
def _init_kernel(off, n_slots, u, v, a, g, mass, inv_mass, kappa, damping, d0, de, dx0, rsum, fext, law, general,
                 wall_slot, rec, rec_off, out_f, f_off, out_ke, out_pe, out_ed, out_v, v_off, v_rows, nbody,
                 record_v, fmax, fmax_off, peak, acc):
    """:func:`hertzchain.integrate.drivers.verlet.initialise` of every member (same kernel calls, same order)."""
    nk = out_ke.shape[1]
    for m in range(n_slots.shape[0]):
        s = off[m]
        p = n_slots[m]
        uu, vv, gg, aa = u[s:s + p + 1], v[s:s + p + 1], g[s:s + p + 1], a[s:s + p]
        power0 = 0.0
        if general[m]:  # never the elastic-plastic law (set up member by member): no state to pass
            power0 = kernels.forces_general(uu, vv, kappa[s:s + p], damping[s:s + p], d0[s:s + p], de[s:s + p],
                                            dx0[s:s + p], rsum[s:s + p], law[m], gg, fext[:0], fext[:0], fext[:0],
                                            fext[:0])
        else:
            kernels.forces_elastic(uu, kappa[s:s + p], d0[s:s + p], gg)
        kernels.accelerations(gg, fext[s:s + p], inv_mass[s:s + p], aa)
        r0 = rec_off[m]
        nr = rec_off[m + 1] - r0
        f = out_f[f_off[m]:f_off[m + 1]].reshape((nk, nr))
        for j in range(nr):
            f[0, j] = gg[rec[r0 + j] + 1]
        out_ke[m, 0] = kernels.kinetic_energy(vv, mass[s:s + p])
        out_pe[m, 0] = kernels.potential_energy(uu, gg, kappa[s:s + p], d0[s:s + p], de[s:s + p], dx0[s:s + p],
                                                rsum[s:s + p], fext[s:s + p], False)
        out_ed[m, 0] = 0.0
        if record_v[m]:
            for i in range(nbody[m]):
                out_v[v_off[m] + i] = vv[i]
        for j in range(fmax_off[m + 1] - fmax_off[m]):
            fmax[fmax_off[m] + j] = gg[j + 1]
        fw0 = gg[wall_slot[m] + 1]
        peak[m, 0] = fw0
        peak[m, 5] = fw0
        for i in (1, 2, 3, 4, 6, 7):
            peak[m, i] = 0.0
        for i in range(7):
            acc[m, i] = 0.0
        acc[m, 1] = power0
        acc[m, 7] = np.inf


kernels.flush_stale_cache(_init_kernel)


def _step_plans(w: np.ndarray, interval: float, dts: np.ndarray, check,
                steps_per_radian: float | None = None) -> dict[str, np.ndarray]:
    """:func:`hertzchain.integrate.drivers.verlet.step_plan` of every member (``dts``: NaN = adaptive step).

    ``check(i, dt)`` is :func:`hertzchain.integrate.drivers.verlet.check_time_step` on member i: called
    for the members whose user step is not positive or too large for their omega_max, it raises
    the single run's error (the bound is tested here with array code, the message comes from there).
    """
    nmem = w.size
    fixed = ~np.isnan(dts)
    with np.errstate(invalid="ignore"):
        suspect = fixed & ~((dts > 0) & np.isfinite(dts) & (w * dts <= MAX_OMEGA_DT))
    for i in np.flatnonzero(suspect).tolist():
        try:
            check(i, float(dts[i]))
        except ConfigError as exc:
            raise ConfigError(exc.field, f"member {i}: {exc.message}") from None
    stride = np.zeros(nmem, dtype=np.int64)
    plan_dt = np.empty(nmem)
    n_sub = np.ones(nmem, dtype=np.int64)
    n_eval = np.ones(nmem, dtype=np.int64)
    c_steps = np.zeros(nmem)
    relax = np.zeros(nmem, dtype=np.int64)
    # fixed step, shortened to divide the sample interval (verlet._stride)
    sf = np.maximum(1, np.ceil(interval / dts[fixed] - 1e-9)).astype(np.int64)
    stride[fixed] = sf
    plan_dt[fixed] = interval / sf
    still = ~fixed & (w <= 0.0)  # nothing moves: any step is exact
    stride[still] = 1
    plan_dt[still] = interval
    ad = ~fixed & (w > 0.0)
    wa = w[ad]
    c = ADAPTIVE_STEPS_PER_RADIAN if steps_per_radian is None else float(steps_per_radian)
    with np.errstate(divide="ignore"):
        bmax = horizon_radians(c) / wa
    short = interval <= bmax
    ns = np.where(short, 1, np.ceil(interval / bmax - 1e-9)).astype(np.int64)
    ne = np.where(short, np.maximum(1, np.floor(bmax / interval)), 1).astype(np.int64)
    block = interval / ns
    plan_dt[ad] = block / np.ceil(block * c * wa - 1e-9)
    n_sub[ad] = ns
    n_eval[ad] = ne
    c_steps[ad] = c
    relax[ad] = RELAX_EVALUATIONS
    return {"stride": stride, "plan_dt": plan_dt, "n_sub": n_sub, "n_eval": n_eval, "c_steps": c_steps,
            "relax": relax}


def _ensemble_dts(dt, nmem: int) -> np.ndarray:
    """Per-member user steps [s] as floats, NaN where the step is automatic."""
    if dt is None:
        return np.full(nmem, np.nan)
    if isinstance(dt, (int, float)):
        return np.full(nmem, float(dt))
    vals = list(dt)
    if len(vals) != nmem:
        raise ConfigError("run.dt", f"needs one value per member ({nmem}), got {len(vals)}")
    return np.array([np.nan if x is None else x for x in vals], dtype=float)


#: Members whose System arrays are computed at once by :func:`_pack_groups`: ~0.5 MB per
#: array for 30 beads, so the temporaries stay in the caches (one pass over 1e5 members at once
#: was ~4x slower, mostly page faults on fresh 25 MB temporaries).
SETUP_BLOCK = 2048


@dataclass
class _EnsembleArrays:
    """What the results need of one group's System arrays (group member, ...)."""

    bead_mass: np.ndarray    # (M, N) kg
    kappa_slots: np.ndarray  # (M, N + 1): System.kappa of every member (0 in a free end's slot)
    yield_slots: np.ndarray  # (M, N + 1): System.yield_force of every member
    n_contacts: int

    @property
    def kappa(self) -> np.ndarray:
        """(M, n_contacts) Hertz constants of the real contacts [N/m^1.5]."""
        return self.kappa_slots[:, :self.n_contacts]

    @property
    def yield_force(self) -> np.ndarray:
        """(M, n_contacts) elastic limits of the real contacts [N]."""
        return self.yield_slots[:, :self.n_contacts]


@dataclass
class _Group:
    """Members of one end, law kind and Probes, set up together with array code: member j of
    ``ens`` (one layout, or ragged: any bead counts) is member ``rows[j]`` of the batch (None: the
    batch is this group)."""

    ens: Ensemble | Ragged
    probes: Probes
    rows: np.ndarray | None = None


class MemberSystem(NamedTuple):
    """What a batch's results need of a member's ``Model.system()``, without computing it.

    The batched set-up computes every member's System arrays with array code
    (:func:`hertzchain.integrate.batch.systems.systems`); a member's rows of them are kept here.

    Parameters
    ----------
    n_beads
        Number of beads N.
    has_wall
        Whether the chain ends on a wall.
    kappa
        (N + 1,) Hertz constants of contacts 0..N [N/m^1.5] (paper eq. 1), as ``System.kappa``:
        contact N joins bead N and the wall, 0 for a free end.
    yield_force
        (N + 1,) force at which each contact reaches its elastic limit [N], as
        ``System.yield_force`` (inf where not defined).
    mount_k, mount_c, mount_d0
        A protected body's mount (``System.mount_k`` [N/m], ``mount_c`` [N s/m], ``mount_d0``
        [m]); 0 without one.
    """

    n_beads: int
    has_wall: bool
    kappa: np.ndarray
    yield_force: np.ndarray
    mount_k: float = 0.0
    mount_c: float = 0.0
    mount_d0: float = 0.0

    @property
    def n_contacts(self) -> int:
        """Number of real contacts: N + 1 with a wall, N without."""
        return self.n_beads + (1 if self.has_wall else 0)


def _pack_groups(groups: Sequence[_Group], dts: np.ndarray, interval: float, n_samples: int,
                 check: Callable[[int, float], None], steps_per_radian: float | None = None
                 ) -> tuple[_Packed, list[tuple[np.ndarray, np.ndarray, np.ndarray]]]:
    """A batch of members of several layouts with array code: what :func:`_pack_models` builds
    member by member, bit for bit, into one :class:`_Packed` (one initialisation, one engine call).

    A group is an :class:`~hertzchain.integrate.batch.ensemble.Ensemble` (one layout) or a
    :class:`~hertzchain.integrate.batch.ragged.Ragged` (one end and law, any bead counts) and one
    Probes; :func:`~hertzchain.integrate.batch.systems.systems` computes its members' arrays a block at
    a time. ``dts``: every member's user step [s] (NaN: adaptive), in the batch's order;
    ``check(i, dt)``: :func:`hertzchain.integrate.drivers.verlet.check_time_step` of member i (see
    :func:`_step_plans`). Every per-member array of the _Packed is in the batch's order; the
    slots of the flat body/contact buffers are laid out group after group, so that the members of
    an Ensemble (one width) are the rows of a 2-D view of each buffer; a Ragged group's members
    are written through one index of their N_i + 1 real slots. Returns the packed batch and, per
    group, its members' bead masses (M, N), Hertz constants and elastic limits (M, N + 1), padded
    past a ragged member's N_i.
    """
    nmem = dts.size
    n_slots, nrec, nb, n_contacts, wall_slot = (np.empty(nmem, dtype=np.int64) for _ in range(5))
    record_v = np.empty(nmem, dtype=np.bool_)
    index, counts, recs = [], [], []
    for g in groups:
        ens = g.ens
        wall = 1 if ens.has_wall else 0
        rows = np.arange(ens.n_members) if g.rows is None else g.rows
        n_each = getattr(ens, "n_each", None)
        n_each = np.full(rows.size, ens.n_beads, dtype=np.int64) if n_each is None else n_each
        n_slots[rows] = -(-(n_each + 2) // PAD) * PAD  # layout.pack: moving bodies + wall ghost, rounded up
        nb[rows] = n_each + 1
        n_contacts[rows] = n_each + wall
        wall_slot[rows] = n_each
        record_v[rows] = bool(g.probes.velocities)
        distinct, which = np.unique(n_each, return_inverse=True)
        rec = [g.probes.recorded_contacts(n, ens.has_wall).astype(np.int64) for n in distinct.tolist()]
        nrec[rows] = np.array([r.size for r in rec], dtype=np.int64)[which]
        index.append(rows)
        counts.append(n_each)
        recs.append((rec, which))
    if len(groups) == 1 and len(recs[0][0]) == 1 and groups[0].rows is None:
        rec_all, slot_order = np.tile(recs[0][0][0], nmem), None
    else:
        # member i's recorded contacts go to rec_all[rec_off[i]:rec_off[i + 1]], in the batch's order
        rec_off = np.concatenate([[0], np.cumsum(nrec)])
        rec_all = np.empty(int(rec_off[-1]), dtype=np.int64)
        for rows, (rec, which) in zip(index, recs):
            for j, r in enumerate(rec):
                rec_all[rec_off[rows[which == j]][:, None] + np.arange(r.size)] = r
        slot_order = np.concatenate(index)
    zeros_i, zeros_f = np.zeros(nmem, dtype=np.int64), np.zeros(nmem)
    pk = _outputs(interval, n_samples, n_slots=n_slots, nrec=nrec, rec=rec_all, nb=nb, record_v=record_v,
                  n_contacts=n_contacts, slot_order=slot_order, law=np.zeros(nmem, dtype=np.int64),
                  general=np.zeros(nmem, dtype=np.bool_), wall_slot=wall_slot, stride=zeros_i, plan_dt=zeros_f,
                  n_sub=zeros_i, n_eval=zeros_i, c_steps=zeros_f, relax=zeros_i)
    w = np.empty(nmem)
    out = []
    flat = pk.flat
    for g, rows, n_each in zip(groups, index, counts):
        ens = g.ens
        m, n = ens.n_members, ens.n_beads
        is_ragged = hasattr(ens, "n_each")
        first = int(pk.off[rows[0]])
        last = first + m * _slot_sizes(int(n_slots[rows[0]]))  # an Ensemble's slots, one row per member
        kept: list[tuple[np.ndarray, ...]] = []
        for lo in range(0, m, SETUP_BLOCK):
            hi = min(m, lo + SETUP_BLOCK)
            sy = systems(ens, lo, hi)
            # the N + 1 slots of every body array (bodies 0..N) and contact array (contacts 0..N)
            cols = {"mass": sy.mass, "inv_mass": sy.inv_mass, "kappa": sy.kappa, "damping": sy.damping, "d0": sy.d0,
                    "de": sy.de, "dx0": sy.dx0, "rsum": sy.rsum, "fext": sy.fext, "dcap": sy.max_overlap,
                    "u": sy.u0, "v": sy.v0}
            if is_ragged:
                r_idx, c_idx = np.nonzero(np.arange(n + 1) <= n_each[lo:hi, None])
                dst = pk.off[rows[lo:hi]][r_idx] + c_idx
                for k, x in cols.items():
                    flat[k][dst] = x[r_idx, c_idx]
            else:
                for k, x in cols.items():
                    flat[k][first:last].reshape(m, -1)[lo:hi, :n + 1] = x[:, :n + 1]
            at = slice(lo, hi) if g.rows is None else rows[lo:hi]
            pk.law[at] = sy.law
            pk.general[at] = sy.general
            w[at] = sy.max_frequency
            kept.append((sy.bead_mass, sy.kappa, sy.yield_force))
        # one block (a design's group): systems()'s own arrays, nothing copied
        bead_mass, kappa, fy = (parts[0] if len(kept) == 1 else np.concatenate(parts) for parts in zip(*kept))
        out.append((bead_mass, kappa, fy))
    for k, x in _step_plans(w, interval, dts, check, steps_per_radian).items():
        setattr(pk, k, x)
    f = flat
    _init_kernel(pk.off, pk.n_slots, f["u"], f["v"], f["a"], f["g"], f["mass"], f["inv_mass"], f["kappa"],
                 f["damping"], f["d0"], f["de"], f["dx0"], f["rsum"], f["fext"], pk.law, pk.general, pk.wall_slot,
                 pk.rec, pk.rec_off, pk.out_f, pk.f_off, pk.out_ke, pk.out_pe, pk.out_ed, pk.out_v, pk.v_off,
                 pk.v_rows, pk.nb, pk.record_v, pk.fmax, pk.fmax_off, pk.peak, pk.acc)
    return pk, out


def _pack_ensemble(ens: Ensemble, probes: Probes, dts: np.ndarray, interval: float,
                   n_samples: int, steps_per_radian: float | None = None) -> tuple[_Packed, _EnsembleArrays]:
    """The batch of an ensemble with array code: :func:`_pack_groups` of one group."""
    def check(i: int, dt: float) -> None:
        verlet.check_time_step(ens.model(i).system(), dt)

    pk, (arrays,) = _pack_groups([_Group(ens, probes)], dts, interval, n_samples, check, steps_per_radian)
    return pk, _EnsembleArrays(*arrays, n_contacts=ens.n_beads + (1 if ens.has_wall else 0))


def _groups(models: Sequence[Model], plist: Sequence[Probes]) -> list[_Group] | None:
    """The models as groups of one end, law kind and Probes (first appearance order, members in the
    batch's order within each): an Ensemble where they share the bead count, else a Ragged group;
    None when one has a law the array set-up does not compute."""
    rows: dict[tuple, list[int]] = {}
    for i, (model, p) in enumerate(zip(models, plist)):
        key = layout_key(model)
        if key is None:
            return None
        rows.setdefault((key[1:], p), []).append(i)
    groups = []
    for (_, p), r in rows.items():
        members = models if len(rows) == 1 else [models[i] for i in r]
        n0 = members[0].chain.n_beads
        same = all(mdl.chain.n_beads == n0 for mdl in members)
        groups.append(_Group(Ensemble.from_models(members) if same else ragged(members), p,
                             None if len(rows) == 1 else np.array(r, dtype=np.int64)))
    return groups


def _setup_members(models: Sequence[Model], plist: Sequence[Probes], dts: list, interval: float, n_samples: int,
                   steps_per_radian: float | None = None) -> tuple[_Packed, list[MemberSystem]]:
    """The batch set up member by member (``Model.system()``, :func:`step_plan`, :func:`_pack_models`):
    any law; the reference the array set-up (:func:`_setup_groups`) reproduces bit for bit."""
    members: list[_Member] = []
    for model, p, dti in zip(models, plist, dts):
        system = model.system()
        plan = step_plan(system, interval, dti, steps_per_radian)
        rec = p.recorded_contacts(model.chain.n_beads, model.wall.present)
        members.append(_Member(system, rec, plan, bool(p.velocities)))
    return _pack_models(members, interval, n_samples), [
        MemberSystem(mb.system.n_beads, mb.system.has_wall, mb.system.kappa, mb.system.yield_force, mb.system.mount_k,
                     mb.system.mount_c, mb.system.mount_d0) for mb in members]


def _setup_groups(models: Sequence[Model], plist: Sequence[Probes], dts: list, interval: float, n_samples: int,
                  steps_per_radian: float | None = None) -> tuple[_Packed, list[MemberSystem]] | None:
    """The batch set up with array code, one group of one layout and Probes at a time
    (:func:`_pack_groups`); None when a member's law needs the member-by-member set-up."""
    groups = _groups(models, plist)
    if groups is None:
        return None

    def check(i: int, dt: float) -> None:
        verlet.check_time_step(models[i].system(), dt)

    pk, arrays = _pack_groups(groups, _ensemble_dts(dts, len(models)), interval, n_samples, check, steps_per_radian)
    member_systems: list[MemberSystem | None] = [None] * len(models)
    for g, (_, kappa, fy) in zip(groups, arrays):
        wall = g.ens.has_wall
        rows = range(g.ens.n_members) if g.rows is None else g.rows.tolist()
        n_each = getattr(g.ens, "n_each", None)
        if n_each is None:
            n = g.ens.n_beads
            for i, k, f in zip(rows, kappa, fy):  # row views
                member_systems[i] = MemberSystem(n, wall, k, f)
        else:
            for i, n, k, f in zip(rows, n_each.tolist(), kappa, fy):
                member_systems[i] = MemberSystem(n, wall, k[:n + 1], f[:n + 1])
    done = [s for s in member_systems if s is not None]
    assert len(done) == len(models)  # (every member is in one group)
    return pk, done
