"""Results of a batch: the engine's buffers as RawRuns per member, or as one stacked Dataset.

:func:`_member_runs` gives every member's :class:`~hertzchain.integrate.drivers.verlet.RawRun` (views of
the packed outputs, what :func:`~hertzchain.integrate.drivers.verlet.run_verlet` returns for it alone).
:func:`stack_results` stacks single-run Datasets along a ``member`` dimension; the batched
entry points build the same Dataset without a Dataset per member: :func:`_stack_members` from
every member's :func:`~hertzchain.result.run_fields`, and :func:`_ensemble_dataset` straight
from the (member, ...) buffers of an ensemble with array code.
"""

from __future__ import annotations

import datetime as _dt
import json
from dataclasses import dataclass
from types import SimpleNamespace
from typing import Sequence

import numpy as np
import xarray as xr

from ..errors import ConfigError
from ..model import Model
from ..probes import Probes
from .simulation import warn_members_elastic_limit
from ..integrate.batch.buffers import _Packed, _member_body, _member_forces, _member_velocities
from ..integrate.batch.pack import _EnsembleArrays
from ..integrate.batch.ensemble import Ensemble
from ..integrate.core.kernels import LAW_ELASTOPLASTIC
from ..integrate.drivers.verlet import RawRun


#: The ``engine`` attribute of a batch computed on the CPU, by its integrator.
_ENGINE_CPU = "batched compiled velocity Verlet (members dealt to threads), bit-identical to single runs"
_ENGINE_RKN = ("batched compiled rkn4 (members dealt to threads), bit-identical to single runs with integrator='rkn4' "
               "(max_contact_force: over the run where max_force='run')")

#: Per-member scalar attributes of a single run that become variables along ``member``.
_MEMBER_ATTRS = {
    "dt": ("s", "Verlet time step of the member"),
    "n_steps": ("1", "number of steps of the integrator"),
    "peak_wall_force": ("N", "peak wall force, refined between steps (NaN without a wall)"),
    "peak_wall_time": ("s", "time of the peak wall force (NaN without a wall)"),
    "elastic_limit_exceeded": ("1", "1 when a recorded contact force passed the elastic limit"),
}
#: Per-member attributes of runs with a protected body (NaN for members without one).
_BODY_ATTRS = {
    "peak_body_force": ("N", "largest force the protected body passed to the ground"),
    "peak_body_acceleration": ("m s-2", "largest acceleration of the protected body"),
    "peak_body_energy": ("J", "most energy delivered to the protected body"),
}
#: Per-member attributes of runs under gravity (NaN for members without it): result.dynamic_peak.
_GRAVITY_ATTRS = {
    "static_wall_force": ("N", "force the wall carries at rest (the weights)"),
    "peak_wall_force_dynamic": ("N", "peak wall force minus the static force"),
}


@dataclass
class _Part:
    """One member as the stacker needs it, in plain NumPy (from a Dataset or from ``run_fields``).

    ``data``: data variables in Dataset order, ``(dims, values, attrs)``; ``dims``: every
    dimension but ``time`` in the Dataset's dimension order, ``(coordinate values, attrs)``;
    ``attrs``: the Dataset attributes.
    """

    data: dict[str, tuple[tuple[str, ...], np.ndarray, dict]]
    dims: dict[str, tuple[np.ndarray, dict]]
    attrs: dict


def _part_of_dataset(ds: xr.Dataset) -> _Part:
    """The :class:`_Part` of a single-run Dataset (a dimension without coordinate counts 0, 1, ...)."""
    data: dict[str, tuple[tuple[str, ...], np.ndarray, dict]] = {}
    for name in ds.data_vars:
        var = ds.variables[name]
        data[str(name)] = (tuple(str(d) for d in var.dims), var.values, var.attrs)
    dims: dict[str, tuple[np.ndarray, dict]] = {}
    for d in ds.dims:
        if d != "time":
            coord = ds.variables.get(d)
            dims[str(d)] = (coord.values, coord.attrs) if coord is not None else (np.arange(ds.sizes[d]), {})
    return _Part(data, dims, ds.attrs)


def _part_of_fields(f) -> _Part:
    """The :class:`_Part` of a :class:`hertzchain.result.RunFields`, dimensions in the order the
    Dataset of :func:`hertzchain.result.build_dataset` has them (first use by a data variable,
    then by a coordinate)."""
    dims = {}
    for dim_names in [v[0] for v in f.data.values()] + [(c[0],) for c in f.coords.values()]:
        for d in dim_names:
            if d != "time" and d not in dims:
                dims[d] = (f.coords[d][1], f.coords[d][2])
    return _Part(f.data, dims, f.attrs)


def _positions(union: np.ndarray, values: np.ndarray):
    """Where ``values`` sit in the sorted ``union``: a slice when they are one increasing run
    (cheap basic indexing), else the index array."""
    pos = np.searchsorted(union, values)
    if pos.size <= 1 or bool(np.all(np.diff(pos) == 1)):
        start = int(pos[0]) if pos.size else 0
        return slice(start, start + pos.size)
    return pos


def _stack(parts: Sequence[_Part], time, n_time: int, member, ready: dict[str, np.ndarray] | None = None
           ) -> xr.Dataset:
    """The stacked Dataset of :func:`stack_results` (see there) from members in plain NumPy.

    ``time`` is the shared time coordinate (a Variable or a ``(dim, values, attrs)`` tuple) of
    ``n_time`` samples. Members with equal coordinate arrays share the index work, so a batch
    of similar members costs one slice assignment per member and variable. ``ready`` may hold
    variables already in the stacked layout, row i being member i's array (the engine's output
    buffers): one is used as it is, not copied, when every member has the variable with exactly
    the stacked coordinates (so there is nothing to pad); otherwise it is ignored.
    """
    ready = ready or {}
    nmem = len(parts)
    # Union of every dimension's coordinates; identical arrays (the usual case) are merged once.
    distinct: dict[str, dict[tuple, np.ndarray]] = {}
    coord_attrs: dict[str, dict] = {}
    keys = []
    for p in parts:
        pk = {}
        for d, (vals, attrs) in p.dims.items():
            fingerprint = (vals.dtype.str, vals.shape, vals.tobytes())
            pk[d] = fingerprint
            distinct.setdefault(d, {}).setdefault(fingerprint, vals)
            coord_attrs.setdefault(d, dict(attrs))
        keys.append(pk)
    dims = {d: np.unique(np.concatenate([v.ravel() for v in arrays.values()]))
            for d, arrays in distinct.items()}
    where = {d: {key: _positions(dims[d], vals) for key, vals in arrays.items()} for d, arrays in distinct.items()}

    var_names: list[str] = []
    for p in parts:
        var_names += [k for k in p.data if k not in var_names]
    data = {}
    indexers: dict[tuple, tuple] = {}

    def indexer(i: int, var_dims: tuple[str, ...]) -> tuple:
        """Where member i's array of a variable with ``var_dims`` goes in the stacked one (minus member)."""
        ck = (var_dims,) + tuple(keys[i][d] for d in var_dims if d != "time")
        idx = indexers.get(ck)
        if idx is None:
            idx = tuple(slice(None) if d == "time" else where[d][keys[i][d]] for d in var_dims)
            if not all(isinstance(x, slice) for x in idx):
                idx = np.ix_(*(np.arange(n_time) if d == "time" else
                               (np.arange(dims[d].size)[x] if isinstance(x, slice) else x)
                               for d, x in zip(var_dims, idx)))
            indexers[ck] = idx
        return idx

    for name in var_names:
        first_dims, _, first_attrs = next(p.data[name] for p in parts if name in p.data)
        shape = (nmem,) + tuple(n_time if d == "time" else dims[d].size for d in first_dims)
        idxs = [indexer(i, first_dims) if name in p.data else None for i, p in enumerate(parts)]
        full = tuple(slice(None) if d == "time" else slice(0, dims[d].size) for d in first_dims)
        if (name in ready and ready[name].shape == shape
                and all(idx is not None and all(isinstance(x, slice) and x == f for x, f in zip(idx, full))
                        for idx in idxs)):
            out = ready[name]  # every member fills its whole row: nothing to pad, nothing to copy
        else:
            out = np.full(shape, np.nan)
            for i, (p, idx) in enumerate(zip(parts, idxs)):
                if idx is not None:
                    out[i][idx] = p.data[name][1]
        data[name] = xr.Variable(("member",) + tuple(first_dims), out, attrs=dict(first_attrs))

    has_wall = np.array(["wall_force" in p.data for p in parts])
    member_attrs = dict(_MEMBER_ATTRS)
    if any("peak_body_force" in p.attrs for p in parts):
        member_attrs.update(_BODY_ATTRS)
    if any("peak_wall_force_dynamic" in p.attrs for p in parts):
        member_attrs.update(_GRAVITY_ATTRS)
    for key, (units, long_name) in member_attrs.items():
        vals = np.array([p.attrs.get(key, np.nan) for p in parts], dtype=float)
        if key.startswith("peak_wall"):
            vals = np.where(has_wall, vals, np.nan)  # the kernel tracks a kappa = 0 contact: 0 N, not a peak
        data[key] = xr.Variable(("member",), vals, attrs={"units": units, "long_name": long_name})
    n_beads = np.array([p.dims["bead"][0].size for p in parts], dtype=np.int64)
    data["n_beads"] = xr.Variable(("member",), n_beads, attrs={"units": "1", "long_name": "number of beads N"})
    data["n_contacts"] = xr.Variable(
        ("member",), n_beads + has_wall.astype(np.int64),
        attrs={"units": "1", "long_name": "number of real contacts (N + 1 with a wall, N without)"})
    data["has_wall"] = xr.Variable(("member",), has_wall.astype(np.int8),
                                   attrs={"units": "1", "long_name": "1 when the chain ends on a wall"})
    for key, long_name in (("model", "model description (JSON)"), ("config", "input of the member (JSON)")):
        data[key] = xr.Variable(("member",), np.array([p.attrs[key] for p in parts], dtype=object),
                                attrs={"long_name": long_name})

    coords = {"member": ("member", np.arange(nmem) if member is None else np.asarray(member, dtype=np.int64),
                         {"long_name": "member of the batch"}),
              "time": time}
    for d, vals in dims.items():
        coords[d] = (d, vals, coord_attrs[d])
    a0 = parts[0].attrs
    return xr.Dataset(data, coords=coords, attrs=_batch_attrs(a0, nmem))


def _batch_attrs(a0, nmem: int) -> dict:
    """Attributes of a stacked batch, from one member's (or the template's) attributes ``a0``."""
    return {
        "title": "hertzchain batch simulation",
        "hertzchain_version": a0["hertzchain_version"],
        "integrator": a0["integrator"],
        "engine": _ENGINE_RKN if a0["integrator"] == "rkn4" else _ENGINE_CPU,
        "duration": a0["duration"],
        "sample_interval": a0["sample_interval"],
        "n_members": nmem,
        "created_utc": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
        "conventions": a0["conventions"],
    }


def stack_results(datasets: Sequence[xr.Dataset], member: Sequence[int] | None = None) -> xr.Dataset:
    """Stack single-run Datasets (same time axis) along a new ``member`` dimension.

    Dimensions other than ``time`` (``contact``, ``bead``, ``sensor``, ``body``) become the sorted
    union of the members' coordinates; values a member lacks (a shorter chain, no wall) are NaN.
    ``n_beads``, ``n_contacts`` (real contacts: N + 1 with a wall, N without) and ``has_wall``
    say what is real. Per-member attributes (``dt``, ``n_steps``, ``peak_wall_force``,
    ``peak_wall_time``, ``elastic_limit_exceeded``, ``model``, ``config``) become variables along
    ``member``; the shared ones (duration, sample interval, version...) stay attributes.
    :func:`~hertzchain.runs.batch.simulate_batch` builds the same Dataset straight from the engine's arrays.
    """
    if not datasets:
        raise ConfigError("datasets", "nothing to stack")
    time = datasets[0]["time"]
    for i, ds in enumerate(datasets):
        if ds.sizes["time"] != time.size or not np.array_equal(ds["time"].values, time.values):
            raise ConfigError(f"datasets[{i}]", "all members must share one time axis (duration and sample interval)")
    return _stack([_part_of_dataset(ds) for ds in datasets], time.variable, time.size, member)


def _dts_used(pk: _Packed) -> tuple[np.ndarray, np.ndarray]:
    """:func:`hertzchain.integrate.drivers.verlet._dt_used` of every member: smallest and largest step [s]."""
    if pk.integrator == "rkn4":
        assert pk.rkn_steps is not None  # (the rkn4 engine's step counts)
        return pk.rkn_steps[:, 1].copy(), pk.rkn_steps[:, 2].copy()
    adaptive = pk.stride == 0
    block = pk.interval / pk.n_sub
    with np.errstate(divide="ignore"):
        dt_min = np.where(adaptive & (pk.acc[:, 6] != 0), block / pk.acc[:, 6], pk.plan_dt)
        dt_max = np.where(adaptive & (pk.acc[:, 7] != 0), block / pk.acc[:, 7], pk.plan_dt)
    return dt_min, dt_max


def _steps(pk: _Packed) -> np.ndarray:
    """Steps every member took (a copy)."""
    if pk.integrator == "rkn4":
        assert pk.rkn_steps is not None  # (the rkn4 engine's step counts)
        return pk.rkn_steps[:, 0].copy()
    return pk.acc[:, 2].copy()


def _member_runs(pk: _Packed) -> list[RawRun]:
    """Every member's :class:`RawRun`, views of the packed outputs."""
    time = np.arange(pk.n_samples) * pk.interval
    fpk, tpk = _refine_peaks(pk.peak)
    dt_min, dt_max = _dts_used(pk)
    per_member = zip(fpk.tolist(), tpk.tolist(), dt_min.tolist(), dt_max.tolist(), _steps(pk).tolist(),
                     (pk.stride == 0).tolist(), pk.record_v.tolist(), pk.rec_off.tolist(), pk.fmax_off.tolist())
    runs = []
    for m, (f_peak, t_peak, dt0, dt1, steps, adaptive, record_v, r0, c0) in enumerate(per_member):
        runs.append(RawRun(time=time.copy(), contact_force=_member_forces(pk, m), kinetic_energy=pk.out_ke[m],
                           potential_energy=pk.out_pe[m], dissipated_energy=pk.out_ed[m],
                           velocity=_member_velocities(pk, m) if record_v else None,
                           max_force=pk.fmax[c0:pk.fmax_off[m + 1]], peak_wall_force=f_peak, peak_wall_time=t_peak,
                           dt=dt0, integrator=pk.integrator, n_steps=int(steps), contacts=pk.rec[r0:pk.rec_off[m + 1]],
                           dt_max=dt1, adaptive=adaptive, body=_member_body(pk, m) if pk.body_slot[m] >= 0 else None,
                           **_plastic_fields(pk, m)))
    return runs


def _plastic_fields(pk: _Packed, m: int) -> dict:
    """Member m's elastic-plastic results for its RawRun (plastic work samples, residual and
    largest overlaps at the end, views of the packed buffers), or nothing for another law."""
    if pk.law[m] != LAW_ELASTOPLASTIC:
        return {}
    s, nc = int(pk.off[m]), int(pk.fmax_off[m + 1] - pk.fmax_off[m])
    return {"plastic_work": pk.out_wp[m], "residual_overlap": pk.flat["dres"][s:s + nc],
            "max_overlap": pk.flat["dmax"][s:s + nc]}


def _stack_members(runs, models, plist, cfgs, duration, sys_list, stacked=None) -> xr.Dataset:
    """The stacked Dataset from every member's RawRun (run_fields per member, then :func:`_stack`)."""
    from ..result import run_fields

    parts, time, flagged = [], None, []
    sys_list = sys_list or [None] * len(models)
    for i, (raw, model, p, cfg, system) in enumerate(zip(runs, models, plist, cfgs, sys_list)):
        fields = run_fields(raw, model, p, duration=duration, config=cfg, system=system)
        if time is None:
            time = fields.coords["time"]  # every member has this time axis (shared duration and interval)
        part = _part_of_fields(fields)
        if part.attrs["elastic_limit_exceeded"]:
            # What the elastic-limit message reads of a member's Dataset (building one costs ~0.2 ms).
            flagged.append((i, SimpleNamespace(attrs=part.attrs, max_contact_force=part.data["max_contact_force"][1],
                                               yield_force=part.data["yield_force"][1])))
        parts.append(part)
    warn_members_elastic_limit(flagged, len(models), stacklevel=4)
    ready = _ready(stacked, runs[0], models[0], parts[0]) if stacked else None
    return _stack(parts, time, runs[0].time.size, None, ready=ready)


def _refine_peaks(peak: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`hertzchain.integrate.drivers.verlet.refine_peak` of every row of ``peak`` (same arithmetic)."""
    fpk, t_pk, fb, fa, h0, h1 = (peak[:, i] for i in (0, 1, 2, 3, 6, 7))
    ok = (t_pk > 0) & (peak[:, 4] == 0.0) & (h0 > 0) & (h1 > 0)
    with np.errstate(divide="ignore", invalid="ignore"):
        s01 = (fpk - fb) / h0
        s12 = (fa - fpk) / h1
        c = (s12 - s01) / (h0 + h1)
        ok &= c < 0.0
        b = s12 - c * h1
        return np.where(ok, fpk - 0.25 * b * b / c, fpk), np.where(ok, t_pk - 0.5 * b / c, t_pk)


#: Variables of a single run that :func:`_ensemble_dataset` knows how to stack.
_KNOWN = {"contact_force", "kinetic_energy", "potential_energy", "dissipated_energy", "diameter", "mass", "offset",
          "kappa", "yield_force", "max_contact_force", "wall_force", "sensor_force", "velocity"}


def _ensemble_dataset(ens: Ensemble, sy: _EnsembleArrays, pk: _Packed, probes: Probes, duration: float,
                      configs) -> xr.Dataset | None:
    """The stacked Dataset of :func:`~hertzchain.runs.batch.simulate_batch` for an ensemble,
    straight from the buffers.

    Same variables, order, coordinates and attributes as :func:`_stack` of every member's
    :func:`hertzchain.result.run_fields` (member 0's is built as the template), with the values
    taken from the (member, ...) buffers by array code. None when member 0's fields hold a
    variable this function does not know (the caller then stacks member by member).
    """
    from ..result import run_fields

    nmem, n = ens.n_members, ens.n_beads
    ns, nc = pk.n_samples, sy.n_contacts
    interval = pk.interval
    fpk, tpk = _refine_peaks(pk.peak)
    adaptive = pk.stride == 0
    dt_min, dt_max = _dts_used(pk)
    rec = pk.rec[:pk.nrec[0]]
    forces = pk.out_f.reshape(nmem, ns, rec.size)
    velocity = pk.out_v.reshape(nmem, ns, n + 1) if probes.velocities else None
    fmax = pk.fmax.reshape(nmem, nc)
    time = np.arange(ns) * interval
    raw0 = RawRun(time=time, contact_force=forces[0], kinetic_energy=pk.out_ke[0], potential_energy=pk.out_pe[0],
                  dissipated_energy=pk.out_ed[0], velocity=None if velocity is None else velocity[0],
                  max_force=fmax[0], peak_wall_force=float(fpk[0]), peak_wall_time=float(tpk[0]), dt=float(dt_min[0]),
                  integrator=pk.integrator, n_steps=int(_steps(pk)[0]), contacts=rec, dt_max=float(dt_max[0]),
                  adaptive=bool(adaptive[0]))
    cfg0 = None if configs is None else configs[0]
    fields0 = run_fields(raw0, ens.model(0), probes, duration=duration, config=cfg0)
    template = _part_of_fields(fields0)
    if not set(template.data) <= _KNOWN:
        return None

    wanted = template.dims["contact"][0]
    cols = np.searchsorted(rec, wanted)
    if cols.size and np.array_equal(cols, np.arange(cols[0], cols[0] + cols.size)):
        cf = forces[:, :, cols[0]:cols[0] + cols.size]
    else:
        cf = forces[:, :, cols]
    values = {"contact_force": cf, "kinetic_energy": pk.out_ke, "potential_energy": pk.out_pe,
              "dissipated_energy": pk.out_ed, "diameter": np.array(ens.diameters, dtype=float),
              "mass": sy.bead_mass, "offset": np.array(ens.offsets, dtype=float), "kappa": sy.kappa,
              "yield_force": sy.yield_force, "max_contact_force": fmax}
    if ens.has_wall:
        values["wall_force"] = forces[:, :, int(np.searchsorted(rec, n))]
    sensors = np.unique(np.array(probes.sensors, dtype=np.int64))
    if sensors.size:
        index = {int(c): i for i, c in enumerate(rec)}
        sf = np.empty((nmem, ns, sensors.size))
        for k, s in enumerate(sensors.tolist()):  # probes.sensor_forces, F_s = (F_{n-1} + F_n) / 2
            left = forces[:, :, index[s - 1]]
            right = forces[:, :, index[s]] if s in index else 0.0
            sf[:, :, k] = 0.5 * (left + right)
        values["sensor_force"] = sf
    if velocity is not None:
        values["velocity"] = velocity

    data = {}
    for name, (dims, _, attrs) in template.data.items():
        data[name] = xr.Variable(("member",) + tuple(dims), values[name], attrs=dict(attrs))
    ratio = fmax / sy.yield_force
    over = ratio > 1.0
    exceeded = over.any(axis=1)
    member_vals = {"dt": dt_min, "n_steps": _steps(pk), "peak_wall_force": fpk, "peak_wall_time": tpk,
                   "elastic_limit_exceeded": exceeded.astype(float)}
    for key, (units, long_name) in _MEMBER_ATTRS.items():
        vals = member_vals[key]
        if key.startswith("peak_wall") and not ens.has_wall:
            vals = np.full(nmem, np.nan)
        data[key] = xr.Variable(("member",), vals, attrs={"units": units, "long_name": long_name})
    data["n_beads"] = xr.Variable(("member",), np.full(nmem, n, dtype=np.int64),
                                  attrs={"units": "1", "long_name": "number of beads N"})
    data["n_contacts"] = xr.Variable(("member",), np.full(nmem, nc, dtype=np.int64), attrs={
        "units": "1", "long_name": "number of real contacts (N + 1 with a wall, N without)"})
    data["has_wall"] = xr.Variable(("member",), np.full(nmem, int(ens.has_wall), dtype=np.int8),
                                   attrs={"units": "1", "long_name": "1 when the chain ends on a wall"})
    described = ens.describe()
    if configs is None:
        config_text = ['{"model": ' + d + "}" for d in described]  # json.dumps({"model": described})
    else:
        config_text = [json.dumps(c if c is not None else {"model": json.loads(d)}) for c, d in zip(configs, described)]
    data["model"] = xr.Variable(("member",), np.array(described, dtype=object),
                                attrs={"long_name": "model description (JSON)"})
    data["config"] = xr.Variable(("member",), np.array(config_text, dtype=object),
                                 attrs={"long_name": "input of the member (JSON)"})

    flagged = []
    for i in np.flatnonzero(exceeded).tolist():
        attrs = {"elastic_limit_exceeded": 1, "elastic_limit_contacts": json.dumps(np.flatnonzero(over[i]).tolist()),
                 "elastic_limit_ratio": float(ratio[i].max())}
        flagged.append((i, SimpleNamespace(attrs=attrs, max_contact_force=fmax[i], yield_force=sy.yield_force[i])))
    warn_members_elastic_limit(flagged, nmem, stacklevel=4)

    coords = {"member": ("member", np.arange(nmem), {"long_name": "member of the batch"}),
              "time": fields0.coords["time"]}
    for d, (vals, attrs) in template.dims.items():
        coords[d] = (d, np.unique(vals), dict(attrs))
    a0 = template.attrs
    return xr.Dataset(data, coords=coords, attrs=_batch_attrs(a0, nmem))


def _ready(stacked: dict[str, np.ndarray], raw: RawRun, model: Model, part: _Part) -> dict[str, np.ndarray]:
    """The engine's buffers as the stacked variables of ``run_fields`` (row m = member m's array),
    assuming every member is laid out as member 0 (``raw``, ``model``, ``part``); :func:`_stack`
    uses one only where that holds. Views where possible, so a uniform batch copies nothing."""
    ready: dict[str, np.ndarray] = {k: stacked[k] for k in ("kinetic_energy", "potential_energy",
                                                            "dissipated_energy", "velocity") if k in stacked}
    forces = stacked.get("recorded_force")
    if forces is not None:
        # the columns run_fields takes from raw.contact_force (= forces[m])
        cols = np.searchsorted(raw.contacts, part.dims["contact"][0])
        if cols.size and np.array_equal(cols, np.arange(cols[0], cols[0] + cols.size)):
            ready["contact_force"] = forces[:, :, cols[0]:cols[0] + cols.size]
        else:
            ready["contact_force"] = forces[:, :, cols]
        if model.wall.present:
            ready["wall_force"] = forces[:, :, np.searchsorted(raw.contacts, model.chain.n_beads)]
    return ready
