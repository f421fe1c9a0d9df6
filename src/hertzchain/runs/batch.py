"""Batched engine: many independent chains integrated in one compiled call across all cores.

Members may differ in everything (length, diameters, materials, striker, offsets, contact law,
wall, time step); they share the duration and the sample interval, so every member has the same
time axis. The results are *bit for bit* those of :func:`hertzchain.simulate`, because nothing
numerical is re-implemented here:

- each member is packed with :func:`hertzchain.integrate.core.layout.pack` and initialised with the
  same kernel calls, in the same order, as :func:`hertzchain.integrate.drivers.verlet.run_verlet`;
- the padded arrays of all members are concatenated into flat ragged buffers (one offset table);
- one compiled loop per thread (members dealt to threads) hands every member to the very same
  :func:`hertzchain.integrate.core.kernels._verlet_run` on slices of those buffers (slices are views,
  so the kernel writes straight into the outputs). Velocity Verlet has no cross-member coupling
  and no reductions across members, so the thread that runs a member cannot change its result.

This module holds the public entry points and the input checks; each step of a run has a
module of its own, called in this order:

- :mod:`hertzchain.integrate.batch.pack`: set-up, models (or an Ensemble) to the packed batch.
  Members are set up with array code (:class:`~hertzchain.integrate.batch.ensemble.Ensemble`,
  ``_pack_groups``: a few microseconds per member, the same numbers as the member-by-member
  ``_pack_models``), one group of members sharing a layout (number of beads, end, contact law
  kind) and one Probes at a time, all groups into one packed batch and one engine call;
- :mod:`hertzchain.integrate.batch.buffers`: the packed batch itself (flat ragged buffers,
  outputs, trackers), the one thing both engines share;
- the engine call: :mod:`hertzchain.integrate.batch.engine` on the CPU, or
  :mod:`hertzchain.integrate.cuda.launch` on a GPU (``device=``, batches of one group);
- :mod:`hertzchain.runs.batch_results`: the buffers as RawRuns or one stacked Dataset
  (batches of one group straight from the (member, ...) buffers).

Public entry points: :func:`simulate_many` (a list of single-run Datasets, identical to
:func:`~hertzchain.runs.simulation.simulate`'s) and :func:`simulate_batch` (one Dataset stacked along a
``member`` dimension, identical to :func:`stack_results` of :func:`simulate_many`'s but built
straight from the engine's arrays: no Dataset per member, and the output buffers that already
have the stacked layout, such as the (member, time) energies, are used without a copy);
:func:`run_batch` (the engine's raw arrays, one RawRun per member).
"""

from __future__ import annotations

import math
from typing import Any, Callable, Sequence

import numba
import numpy as np
import xarray as xr

from ..checks import (_smaller_radius, preflight_batch, smaller_radii, warn_members_hertz_range,
                      warn_members_pulse_not_reached)
from ..errors import ConfigError
from ..model import Model
from ..probes import Probes
from .simulation import warn_members_elastic_limit
from ..strict import real, run_options
from ..integrate.batch.buffers import release_records  # noqa: F401 (for sweeps: entry points only)
from ..integrate.batch.engine import _engine
from ..integrate.batch.pack import MemberSystem, _ensemble_dts, _pack_ensemble, _setup_groups, _setup_members
from .batch_results import _ensemble_dataset, _member_runs, _stack_members, stack_results
from ..integrate.batch.ensemble import Ensemble, same_layout
from ..integrate.drivers.verlet import RawRun

__all__ = ["simulate_batch", "simulate_many", "run_batch", "stack_results"]


def _as_list(x, n: int, name: str) -> list:
    """Broadcast a scalar/None to ``n`` members, or check a per-member sequence's length."""
    if x is None or isinstance(x, (int, float, Probes)):
        return [x] * n
    x = list(x)
    if len(x) != n:
        raise ConfigError(name, f"needs one value per member ({n}), got {len(x)}")
    return x


def _check_inputs(models: Sequence[Model], duration: float, probes, dt) -> tuple[list[Probes], list]:
    """The checks of :func:`hertzchain.simulate`, per member, plus a shared sample interval."""
    if len(models) == 0:
        raise ConfigError("models", "the batch is empty: give at least one model")
    for i, m in enumerate(models):
        if not isinstance(m, Model):
            raise ConfigError(f"models[{i}]", f"must be a hertzchain Model, got {type(m).__name__}")
    real(duration, "run.duration", low=0.0, open_low=True, unit="s")
    plist = [p or Probes() for p in _as_list(probes, len(models), "probes")]
    dts = _as_list(dt, len(models), "run.dt")
    interval = plist[0].sample_interval
    for i, p in enumerate(plist):
        if p.sample_interval != interval:
            raise ConfigError(f"probes[{i}].sample_interval", f"all members must share one sample interval "
                              f"({interval:g} s for member 0, {p.sample_interval:g} s here)")
        if p.sample_interval > duration:
            raise ConfigError("run.sample_interval",
                              f"({p.sample_interval:g} s) is longer than run.duration ({duration:g} s)")
        p.validate(models[i].chain.n_beads, models[i].wall.present)
    return plist, dts


def run_batch(models: Sequence[Model], duration: float, probes: Probes | Sequence[Probes] | None = None, *,
              dt: float | Sequence[float | None] | None = None, progress: Callable[[int, int], None] | None = None,
              n_threads: int | None = None, steps_per_radian: float | None = None, return_systems: bool = False
              ) -> list[RawRun] | tuple[list[RawRun], list]:
    """Integrate every model with the batched compiled Verlet; one :class:`RawRun` per member.

    Parameters are those of :func:`simulate_batch`. The RawRuns are identical to what
    :func:`hertzchain.integrate.drivers.verlet.run_verlet` returns for each member alone. Members of
    the elastic, viscoelastic and dashpot laws are set up with array code, one group of members
    of one layout (number of beads, end, law kind) and one Probes at a time, into one engine
    call; a batch with a size-scaled viscoelastic member is set up member by member. With
    ``return_systems`` also every member's :class:`MemberSystem` (bead count, Hertz constants and
    elastic limits, computed for the run anyway; no ``Model.system()`` per member).
    """
    plist, dts = _check_inputs(models, duration, probes, dt)
    runs, sys_list, _ = _run(models, duration, plist, dts, progress, n_threads, steps_per_radian)
    return (runs, sys_list) if return_systems else runs


def _check_no_positions(plist) -> None:
    if any(p.positions for p in plist):
        raise ConfigError("probes.positions", "batches and sweeps do not record positions; simulate the run "
                          "to animate alone (hertzchain run, hertzchain.simulate)")


def _check_threads(n_threads) -> None:
    most = numba.config.NUMBA_NUM_THREADS  # type: ignore[attr-defined]  # numba sets it at import
    if n_threads is not None and not (isinstance(n_threads, (int, np.integer)) and 1 <= n_threads <= most):
        raise ConfigError("n_threads", f"must be an integer in 1..{most}, got {n_threads!r}")


def _run(models: Sequence[Model], duration: float, plist: list[Probes], dts: list, progress, n_threads,
         steps_per_radian: float | None = None, engine=None
         ) -> tuple[list[RawRun], list[MemberSystem], dict[str, np.ndarray]]:
    """:func:`run_batch` on checked inputs. Also returns every member's :class:`MemberSystem` and
    the output buffers that are already stacked along ``member`` (row m is RawRun m's array): the
    energies always, ``recorded_force`` (member, time, recorded contact) when every member
    records the same contacts, ``velocity`` when every member records velocities of as many bodies."""
    _check_threads(n_threads)
    interval = plist[0].sample_interval
    nmem = len(models)
    n_samples = int(math.floor(duration / interval + 1e-9)) + 1

    _check_no_positions(plist)
    pk, member_systems = (_setup_groups(models, plist, dts, interval, n_samples, steps_per_radian)
                          or _setup_members(models, plist, dts, interval, n_samples, steps_per_radian))
    if engine is None:
        _engine(pk, progress, n_threads)
    else:
        engine(pk, progress)
    runs = _member_runs(pk)
    # The output buffers seen as (member, time, ...) where every member has the same layout: row m
    # is exactly what RawRun m holds (its arrays are views of these rows).
    stacked = {"kinetic_energy": pk.out_ke, "potential_energy": pk.out_pe, "dissipated_energy": pk.out_ed}
    nrec = int(pk.nrec[0])
    if np.all(pk.nrec == nrec) and np.array_equal(pk.rec.reshape(nmem, nrec), np.broadcast_to(pk.rec[:nrec],
                                                                                              (nmem, nrec))):
        stacked["recorded_force"] = pk.out_f.reshape(nmem, n_samples, nrec)
    if pk.record_v.all() and np.all(pk.nb == pk.nb[0]):
        stacked["velocity"] = pk.out_v.reshape(nmem, n_samples, pk.nb[0])
    return runs, member_systems, stacked


def simulate_many(models: Sequence[Model], duration: float, probes: Probes | Sequence[Probes] | None = None, *,
                  dt: float | Sequence[float | None] | None = None, progress: Callable[[int, int], None] | None = None,
                  n_threads: int | None = None, configs: Sequence[dict | None] | None = None) -> list[xr.Dataset]:
    """Simulate every model in one batched compiled call; one Dataset per member.

    Each Dataset is the one :func:`hertzchain.simulate` (Verlet) returns for that model alone,
    with bit-identical arrays; only the ``created_utc`` attribute may differ.

    Parameters
    ----------
    models
        The members (any mix of chains, strikers, walls and contact laws).
    duration
        Simulated time [s] after impact, shared by all members.
    probes
        One :class:`Probes` for all members or one per member (default: every contact force and
        the energies every 100 ns). All members must share the sample interval [s].
    dt
        Verlet time step [s]: None (each member's automatic step), one value for all, or one per
        member (None entries are automatic).
    progress
        Called as ``progress(done, total)`` in samples between compiled calls.
    n_threads
        Threads of the parallel loop (default: Numba's, i.e. every core).
    configs
        Per-member input stored in each result's ``config`` attribute (as ``simulate(config=)``).

    Returns
    -------
    list of xarray.Dataset
        One result per member, in the order of ``models``.

    Warns
    -----
    ElasticLimitWarning
        Once per batch, naming the members whose recorded contact forces pass the elastic limit.
    """
    from ..result import build_dataset

    duration = real(duration, "run.duration", low=0.0, open_low=True, unit="s")
    plist, dts = _check_inputs(models, duration, probes, dt)
    preflight_batch(models, duration, plist, dts, n_threads=n_threads)  # memory and time, before any set-up
    cfgs = _as_list(configs, len(models), "configs") if configs is not None else [None] * len(models)
    runs, systems, _ = _run(models, duration, plist, dts, progress, n_threads)
    out, flagged = [], []
    for i, (raw, model, p, cfg, system) in enumerate(zip(runs, models, plist, cfgs, systems)):
        ds = build_dataset(raw, model, p, duration=duration, config=cfg, system=system)
        if ds.attrs.get("elastic_limit_exceeded", 1):
            flagged.append((i, ds))
        out.append(ds)
    warn_members_elastic_limit(flagged, len(models))
    return out


def simulate_batch(models: Sequence[Model] | Ensemble, duration: float,
                   probes: Probes | Sequence[Probes] | None = None, *,
                   dt: float | Sequence[float | None] | None = None, progress: Callable[[int, int], None] | None = None,
                   n_threads: int | None = None, configs: Sequence[dict | None] | None = None,
                   device: str = "auto", steps_per_radian: float | None = None, integrator: str = "verlet",
                   rtol: float | None = None, max_force: str = "samples") -> xr.Dataset:
    """Simulate many independent chains in one parallel compiled call; results stacked along ``member``.

    Every member's arrays are bit-identical to :func:`hertzchain.simulate` run on it alone (see
    the module docstring for why; on the GPU they agree to ~1e-14 instead, see ``device``).
    Layout: the variables of a single run with a leading ``member`` dimension; ``contact`` /
    ``bead`` / ``sensor`` / ``body`` are the union over the members, NaN where a member has no
    such item (see :func:`stack_results`, which also lists the per-member variables ``dt``,
    ``n_steps``, ``peak_wall_force``, ``peak_wall_time``, ``n_beads``, ``n_contacts``,
    ``has_wall``, ``model``, ``config``). The Dataset is the one ``stack_results(simulate_many(...))``
    gives (but for ``created_utc``), built without a Dataset per member; variables are views of
    the engine's output buffers where the members share a layout (``contact_force`` and
    ``wall_force`` may then share one buffer).

    Members that share a layout (same number of beads, end and contact law kind) and one
    :class:`Probes` are set up with array code (``hertzchain.Ensemble``,
    ~microseconds per member instead of ~0.2 ms); pass an ``Ensemble`` directly to avoid building
    one :class:`Model` per member at all.

    Parameters
    ----------
    models
        The members: chains of any length, diameters, materials, offsets, contact law, wall; or
        an ``hertzchain.Ensemble`` (a base model plus per-member arrays).
    duration
        Simulated time [s] after impact, shared by all members.
    probes
        One :class:`Probes` or one per member; all must share ``sample_interval`` [s].
    dt
        Verlet step [s]: None (each member's own automatic step), one value, or one per member.
    progress
        ``progress(done, total)`` in samples, between compiled calls.
    n_threads
        Threads of the parallel loop (default: every core Numba sees).
    configs
        Per-member input stored in the ``config`` variable.
    device
        ``"cpu"`` (the compiled batched engine), ``"cuda"`` (the numba.cuda engine of
        ``hertzchain.integrate.cuda.launch``: members must share a layout and one Probes; an error
        when no usable GPU is present) or ``"auto"`` (default: the GPU when one is usable and the
        batch has at least ``hertzchain.integrate.cuda.launch.AUTO_MIN_MEMBERS`` members, else the CPU).
    steps_per_radian
        Accuracy of the adaptive step, as ``simulate(steps_per_radian=)`` (``run.steps_per_radian``):
        None for the default ``ADAPTIVE_STEPS_PER_RADIAN``; one value for every member.
    integrator
        ``"verlet"`` (default: every member bit-identical to ``simulate(..., integrator="verlet")``),
        ``"rkn4"`` (the fourth-order engine, :mod:`hertzchain.integrate.batch.rkn`: every member
        bit-identical to ``simulate(..., integrator="rkn4")``; for members with offsets or the
        Kuwabara-Kono or dashpot law, an automatic step and no recorded velocities) or ``"auto"``
        (``"rkn4"`` where it runs every member and ``steps_per_radian`` is not given, else the
        Verlet), on the CPU.
    rtol
        Step tolerance of ``"rkn4"`` (default :data:`hertzchain.integrate.drivers.rkn.RKN_RTOL`, as
        ``simulate``'s).
    max_force
        ``"samples"`` (default): ``max_contact_force`` is the largest sampled force, as in a single
        run; ``"run"``: the largest over the run (step ends and in-step maxima) where the engine is
        ``"rkn4"``, which then interpolates only the recorded contacts at the samples (a metrics-only
        sweep: several times faster at 100 ns samples).

    Returns
    -------
    xarray.Dataset
        The members' results stacked along the leading ``member`` dimension (SI units).

    Warns
    -----
    ElasticLimitWarning
        Once per batch, naming the members whose contact forces pass the elastic limit.
    PulseNotReachedWarning
        Once per batch, naming the members on a wall whose record ended before the pulse reached it.
    """
    from ..integrate.cuda import launch as _cuda

    _cuda.check_device(device)
    duration = real(duration, "run.duration", low=0.0, open_low=True, unit="s")
    # The config's bounds at the API's door (hertzchain.strict): dt=nan, n_threads=10**6 refused.
    # n_threads: the bound of a sweep's sweep.n_threads (sweep/schema.py), whose chunks run here.
    dt, _, steps_per_radian, n_threads = run_options(dt=dt, steps_per_radian=steps_per_radian, threads=n_threads,
                                                     threads_field="n_threads", threads_max=4096)
    if integrator not in ("verlet", "rkn4", "auto"):
        raise ConfigError("integrator", f"must be 'verlet', 'rkn4' or 'auto', got {integrator!r}")
    if max_force not in ("samples", "run"):
        raise ConfigError("max_force", f"must be 'samples' or 'run', got {max_force!r}")
    if integrator == "rkn4" and device == "cuda":
        raise ConfigError("integrator", "the CUDA engine runs the Verlet: use integrator='verlet' or 'auto' with "
                          "device='cuda'")
    if integrator == "auto" and steps_per_radian is not None:
        integrator = "verlet"  # the call set the Verlet's accuracy (as simulate's "auto")
    if rtol is not None:
        rtol = real(rtol, "run.rtol", low=0.0, open_low=True)
    engine_options: dict[str, Any] = {"integrator": integrator, "all_forces": max_force == "samples", "rtol": rtol}
    if device == "cuda" and not isinstance(models, Ensemble):
        _cuda.refuse_mixed_laws([_law_code(m) for m in models])
    ens = None
    if isinstance(models, Ensemble):
        ens = models
    elif isinstance(models, Sequence) and same_layout(models) and _one_probes(probes, len(models)) is not None:
        ens = Ensemble.from_models(models)
    if ens is not None:
        if (one := _one_probes(probes, ens.n_members)) is None:
            raise ConfigError("probes", f"the {ens.n_members} members of an Ensemble share one Probes: give one, "
                              "or a list of equal ones (a list of models takes different Probes)")
        ds = _simulate_ensemble(ens, duration, one, dt, progress, n_threads,
                                configs, device, steps_per_radian, engine_options)
    elif device == "cuda" and _one_layout(models) and _one_probes(probes, len(models)) is not None:
        # beyond the paper's kind (a given striker, cylinders, gravity, a protected body,
        # mass-in-mass beads): set up member by member, run on the GPU
        _cuda.require_gpu()
        ds = _simulate_models(models, duration, probes, dt, progress, n_threads, configs, steps_per_radian,
                              engine=_cuda.run_packed)
        ds.attrs["engine"] = _cuda.ENGINE
    elif device == "cuda":
        _cuda.require_gpu()
        raise ConfigError("device", "the CUDA engine runs batches whose members share one layout (number of "
                          "beads, end, contact law kind) and one Probes; this batch mixes them: split it, or use "
                          "device='cpu'")
    else:
        ds = _simulate_models(models, duration, probes, dt, progress, n_threads, configs, steps_per_radian,
                              engine=lambda pk, progress: _engine(pk, progress, n_threads, **engine_options))
    warn_members_pulse_not_reached(ds)
    return ds


def _one_layout(models) -> bool:
    """Whether the models share the number of beads and the end (whatever else they are): what the
    CUDA engine needs of a batch set up member by member (it takes every member's law as it is)."""
    keys = {(m.chain.n_beads, m.wall.present) if isinstance(m, Model) else None for m in models}
    return len(keys) == 1 and None not in keys


def _one_probes(probes, n: int) -> Probes | None:
    """The one Probes all ``n`` members use, or None when they differ."""
    if probes is None or isinstance(probes, Probes):
        return probes or Probes()
    plist = list(probes)
    if len(plist) != n or not all(isinstance(p, Probes) for p in plist):
        return None
    first = plist[0] or Probes()
    return first if all((p or Probes()) == first for p in plist) else None


def _simulate_ensemble(ens: Ensemble, duration: float, probes: Probes, dt, progress, n_threads, configs,
                       device: str, steps_per_radian: float | None = None, engine_options=None) -> xr.Dataset:
    """:func:`simulate_batch` of an ensemble: set up, run and stacked with array code
    (``engine_options``: :func:`_engine`'s keywords on the CPU)."""
    from ..integrate.cuda import launch as _cuda

    _check_threads(n_threads)
    nmem = ens.n_members
    real(duration, "run.duration", low=0.0, open_low=True, unit="s")
    if probes.sample_interval > duration:
        raise ConfigError("run.sample_interval",
                          f"({probes.sample_interval:g} s) is longer than run.duration ({duration:g} s)")
    probes.validate(ens.n_beads, ens.has_wall)
    _check_no_positions([probes])
    cfgs = _as_list(configs, nmem, "configs") if configs is not None else None
    dts = _ensemble_dts(dt, nmem)
    interval = probes.sample_interval
    n_samples = int(math.floor(duration / interval + 1e-9)) + 1
    on_gpu = _cuda.use_gpu(device, nmem)  # before the set-up: 'cuda' without a GPU fails at once
    preflight_batch(ens, duration, probes, dts, n_threads=n_threads, steps_per_radian=steps_per_radian, on_gpu=on_gpu)
    pk, arrays = _pack_ensemble(ens, probes, dts, interval, n_samples, steps_per_radian)
    if on_gpu:
        _cuda.run_packed(pk, progress)
    else:
        _engine(pk, progress, n_threads, **(engine_options or {}))
    # checks.check_after_run's Hertz range, for every member at once
    smaller = smaller_radii(ens.striker_diameter, ens.diameters)[:, :arrays.n_contacts]
    warn_members_hertz_range(pk.fmax.reshape(nmem, arrays.n_contacts), arrays.kappa, smaller, stacklevel=4)
    ds = _ensemble_dataset(ens, arrays, pk, probes, duration, cfgs)
    if ds is None:  # member 0's results hold a variable the array path does not know: stack member by member
        ds = _stack_members(_member_runs(pk), [ens.model(i) for i in range(nmem)], [probes] * nmem,
                            cfgs or [None] * nmem, duration, None)
    if on_gpu:
        ds.attrs["engine"] = _cuda.ENGINE
    return ds


def _simulate_models(models, duration, probes, dt, progress, n_threads, configs,
                     steps_per_radian: float | None = None, engine=None) -> xr.Dataset:
    """:func:`simulate_batch` of arbitrary models (members of different layouts or probes);
    ``engine(pk, progress)`` runs the packed batch instead of the CPU engine when given."""
    # What stack_results(simulate_many(...)) gives, without one Dataset per member: every member's
    # run_fields (the arrays and attributes build_dataset would wrap) go straight into the stack.
    plist, dts = _check_inputs(models, duration, probes, dt)
    preflight_batch(models, duration, plist, dts, n_threads=n_threads, steps_per_radian=steps_per_radian)
    cfgs = _as_list(configs, len(models), "configs") if configs is not None else [None] * len(models)
    runs, sys_list, stacked = _run(models, duration, plist, dts, progress, n_threads, steps_per_radian, engine)
    width = max(sy.n_contacts for sy in sys_list)
    fmax, kappa, smaller = (np.full((len(models), width), np.nan) for _ in range(3))
    for i, (run, model, sy) in enumerate(zip(runs, models, sys_list)):
        nc = sy.n_contacts
        fmax[i, :nc], kappa[i, :nc] = run.max_force[:nc], sy.kappa[:nc]
        smaller[i, :nc] = _smaller_radius(model)[:nc]
    warn_members_hertz_range(fmax, kappa, smaller, stacklevel=4)
    return _stack_members(runs, models, plist, cfgs, duration, sys_list, stacked)


def _law_code(model) -> int:
    """The engine code of a model's law (-1 for something that is not a model with a registered law)."""
    from ..laws import get_law

    name = getattr(getattr(model, "law", None), "name", None)
    return get_law(name).code if isinstance(name, str) else -1
