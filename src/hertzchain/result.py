"""Results as one self-describing :class:`xarray.Dataset`, saved as NetCDF.

Dimensions: ``time`` [s], ``contact`` (0..N, numbered as in docs/conventions.rst), ``sensor`` (bead numbers of
embedded sensors), ``bead`` (1..N) and ``body`` (0 = striker, 1..N). Every variable carries
``units`` and ``long_name``; the full input, the package version, the integrator and the time
step are in the attributes.
"""

from __future__ import annotations

import datetime as _dt
import json
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Final, Hashable

import numpy as np
import xarray as xr

from . import __version__
from .model import Model
from .probes import Probes, sensor_forces

if TYPE_CHECKING:  # the compiled kernels load only when a run is made, not to read a result
    from .integrate.drivers.verlet import RawRun

__all__ = ["build_dataset", "fields_dataset", "run_fields", "RunFields", "save", "load", "to_netcdf_bytes",
           "netcdf_bytes"]

ENGINE: Final = "h5netcdf"
#: The integrators of hertzchain's own (``dt``, ``dt_max`` and ``time_step`` attributes mean steps).
STEPPERS = ("verlet", "rkn4")


#: Units and long name of every variable a run may hold (shared by :func:`build_dataset` and the
#: batched engine's stacked results, which take them from :func:`run_fields`).
VARIABLES: dict[str, tuple[str, str]] = {
    "contact_force": ("N", "contact force F_j between body j and body j+1 (paper eq. 1)"),
    "kinetic_energy": ("J", "kinetic energy of striker and beads (and of a protected body, internal masses)"),
    "potential_energy": ("J", "Hertz potential energy sum (2/5) kappa delta^(5/2) (plus linear springs, minus "
                              "external work)"),
    "dissipated_energy": ("J", "energy dissipated by the contact law (viscous part)"),
    "plastic_work": ("J", "plastic work done in the contacts (elastoplastic law, Thornton 1997)"),
    "diameter": ("m", "bead diameter phi_n"),
    "mass": ("kg", "bead mass rho pi phi^3 / 6"),
    "offset": ("m", "perpendicular offset e_n of the bead centre"),
    "kappa": ("N m-1.5", "Hertz constant kappa_j of the contact"),
    "yield_force": ("N", "elastic limit F_Y of the contact (mean pressure = sigma_Y, paper Sec. II)"),
    "max_contact_force": ("N", "largest sampled force of every contact, stored or not"),
    "max_overlap": ("m", "largest overlap every contact reached (elastoplastic law)"),
    "residual_overlap": ("m", "permanent (residual) overlap of every contact at the end (elastoplastic law)"),
    "wall_force": ("N", "force on the wall sensor (contact N)"),
    "sensor_force": ("N", "force read by the sensor embedded in the bead, (F_{n-1} + F_n)/2"),
    "velocity": ("m s-1", "velocity of body (0 = striker)"),
    "displacement": ("m", "displacement of body (0 = striker) from its place at impact, along the chain"),
    "body_force": ("N", "force the protected body passes to the ground, k x + c v (its mount)"),
    "body_displacement": ("m", "protected body's displacement x: its mount's deflection from its unloaded length"),
    "body_velocity": ("m s-1", "protected body's velocity"),
    "body_acceleration": ("m s-2", "protected body's acceleration"),
    "body_energy": ("J", "energy transmitted to the protected body: work of contact N on it since the impact"),
}

#: The ``conventions`` attribute of every result: where units and numbering are defined.
CONVENTIONS = ("SI units; beads 1..N from the impact end, body 0 = striker, contact j joins body j and "
               "body j+1 (contact N = bead N-wall); defined on the Conventions page of the hertzchain "
               "documentation (docs/conventions.rst in the source)")

#: Attributes of every coordinate a run may hold.
COORDINATES: dict[str, dict[str, str]] = {
    "time": {"units": "s", "long_name": "time since impact"},
    "contact": {"long_name": "contact j joins body j and body j+1 (0 = striker-bead 1)"},
    "contact_all": {"long_name": "every contact of the chain (elastic-limit check)"},
    "bead": {"long_name": "bead number from the impact end"},
    "sensor": {"long_name": "bead holding the embedded sensor"},
    "body": {"long_name": "body number (0 = striker)"},
}


@dataclass
class RunFields:
    """Everything :func:`build_dataset` puts in a Dataset, as plain NumPy (no xarray objects).

    ``data`` maps each variable, in Dataset order, to ``(dims, array, attrs)``; ``coords`` maps
    each coordinate to ``(dim, values, attrs)``; ``attrs`` are the Dataset attributes. The
    batched engine stacks many of these into one Dataset without building one per member.
    """

    data: dict[str, tuple[tuple[str, ...], np.ndarray, dict]]
    coords: dict[str, tuple[str, np.ndarray, dict]]
    attrs: dict


def run_fields(raw: RawRun, model: Model, probes: Probes, *, duration: float, config: dict | None = None,
               extra_attrs: dict | None = None, system=None) -> RunFields:
    """Variables, coordinates and attributes of one run (see the module docstring for the layout).

    ``system`` is ``model.system()`` when the caller already has it (it is not free for long chains).
    """
    chain = model.chain
    n = chain.n_beads
    system = system if system is not None else model.system()
    nc = system.n_contacts
    wanted = (raw.contacts if not isinstance(probes.contacts, tuple)  # None (all) or "auto": what was recorded
              else np.array(sorted(set(probes.contacts)), dtype=np.int64))
    if np.array_equal(wanted, raw.contacts):
        forces = raw.contact_force  # every recorded contact is wanted: no copy (it can be 100s of MB)
    else:
        forces = raw.contact_force[:, np.searchsorted(raw.contacts, wanted)]
    arrays = {
        "contact_force": (("time", "contact"), forces),
        "kinetic_energy": (("time",), raw.kinetic_energy),
        "potential_energy": (("time",), raw.potential_energy),
        "dissipated_energy": (("time",), raw.dissipated_energy),
        "diameter": (("bead",), chain.diameters.copy()),
        "mass": (("bead",), chain.masses),
        "offset": (("bead",), np.array(chain.offsets)),
        "kappa": (("contact_all",), system.kappa[:nc]),
        "yield_force": (("contact_all",), system.yield_force[:nc]),
        "max_contact_force": (("contact_all",), raw.max_force),
    }
    if raw.plastic_work is not None:
        arrays["plastic_work"] = (("time",), raw.plastic_work)
        arrays["max_overlap"] = (("contact_all",), raw.max_overlap)
        arrays["residual_overlap"] = (("contact_all",), raw.residual_overlap)
    if model.wall.present:
        arrays["wall_force"] = (("time",), raw.contact_force[:, np.searchsorted(raw.contacts, n)])
    if probes.sensors:
        arrays["sensor_force"] = (("time", "sensor"), sensor_forces(raw.contact_force, raw.contacts, probes.sensors))
    if raw.velocity is not None:
        arrays["velocity"] = (("time", "body"), raw.velocity)
    if raw.displacement is not None:
        arrays["displacement"] = (("time", "body"), raw.displacement)
    if raw.body is not None:
        arrays.update(body_arrays(raw.body, system))
    data = {}
    for name, (dims, values) in arrays.items():
        units, long_name = VARIABLES[name]
        data[name] = (dims, values, {"units": units, "long_name": long_name})

    coord_values = {"time": raw.time, "contact": wanted, "contact_all": np.arange(nc), "bead": np.arange(1, n + 1)}
    if probes.sensors:
        coord_values["sensor"] = np.array(probes.sensors)
    if raw.velocity is not None or raw.displacement is not None:
        coord_values["body"] = np.arange(n + 1)
    coords = {name: (name, values, dict(COORDINATES[name])) for name, values in coord_values.items()}

    ratio = raw.max_force / system.yield_force[:nc]
    over = np.flatnonzero(ratio > 1.0).tolist()
    model_text = model.describe_text()
    attrs = {
        "title": "hertzchain simulation",
        "hertzchain_version": __version__,
        "integrator": raw.integrator,
        # what ran (simulate() passes its choice, hertzchain.engine_choice; a batch runs the Verlet on one
        # thread per member)
        "integrator_used": raw.integrator,
        "threads_used": 1,
        "dt": raw.dt,
        "dt_max": raw.dt_max if raw.integrator in STEPPERS else 0.0,
        "time_step": ("adaptive" if raw.adaptive else "fixed") if raw.integrator in STEPPERS else "solve_ivp",
        "n_steps": raw.n_steps,
        "duration": duration,
        "sample_interval": probes.sample_interval,
        "model": model_text,
        # json.dumps({"model": described}), without encoding the model twice
        "config": json.dumps(config) if config is not None else '{"model": ' + model_text + "}",
        "peak_wall_force": raw.peak_wall_force,
        "peak_wall_time": raw.peak_wall_time,
        "elastic_limit_exceeded": int(bool(over)),
        "elastic_limit_contacts": json.dumps(over),
        "elastic_limit_ratio": float(ratio.max()) if ratio.size else 0.0,
        "created_utc": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
        "conventions": CONVENTIONS,
    }
    if model.gravity > 0 and model.wall.present:
        # the wall contact holds bodies 0..N at rest (System.static_forces()[N], from the model: a
        # batch member's arrays hold no external forces)
        striker = 0.0 if model.striker is None else model.striker.mass
        static = model.precompression + model.gravity * (striker + float(np.sum(model.chain.masses)))
        attrs.update(dynamic_peak(raw.peak_wall_force, static))
    if raw.body is not None:
        attrs.update(body_peaks(arrays["body_force"][1], arrays["body_acceleration"][1], arrays["body_energy"][1]))
    if raw.plastic_work is not None:
        attrs["plastic_work"] = float(raw.plastic_work[-1])
        assert raw.residual_overlap is not None  # recorded with the plastic work (verlet.py)
        attrs["residual_overlap_max"] = float(raw.residual_overlap.max()) if raw.residual_overlap.size else 0.0
    attrs.update(extra_attrs or {})
    return RunFields(data, coords, attrs)


def body_arrays(record: np.ndarray, system) -> dict[str, tuple[tuple[str, ...], np.ndarray]]:
    """The protected body's variables from the engine's record (time, 4): its displacement from
    rest u, velocity v, acceleration and the work done on it; x = u + the mount's deflection at
    rest, and the force to the ground k x + c v.

    Parameters
    ----------
    record : numpy.ndarray
        (time, 4) as ``RawRun.body``.
    system : hertzchain.model.System
        The run's arrays (``mount_k``, ``mount_c``, ``mount_d0``).

    Returns
    -------
    dict
        ``{name: (dims, values)}`` of ``body_force``, ``body_displacement``, ``body_velocity``,
        ``body_acceleration`` and ``body_energy``.
    """
    x = system.mount_d0 + record[:, 0]
    v = record[:, 1].copy()
    return {"body_force": (("time",), system.mount_k * x + system.mount_c * v),
            "body_displacement": (("time",), x), "body_velocity": (("time",), v),
            "body_acceleration": (("time",), record[:, 2].copy()), "body_energy": (("time",), record[:, 3].copy())}


def body_peaks(force: np.ndarray, acceleration: np.ndarray, energy: np.ndarray) -> dict[str, float]:
    """Attributes of a run with a protected body: ``peak_body_force`` [N] and
    ``peak_body_acceleration`` [m/s^2] (largest magnitudes over the samples) and
    ``peak_body_energy`` [J] (the most energy the chain had delivered to it at any sample).

    Parameters
    ----------
    force, acceleration, energy : numpy.ndarray
        ``body_force``, ``body_acceleration`` and ``body_energy`` over time.

    Returns
    -------
    dict
        The three attributes.
    """
    return {"peak_body_force": float(np.max(np.abs(force))), "peak_body_acceleration": float(np.max(np.abs(acceleration))),
            "peak_body_energy": float(np.max(energy))}


def dynamic_peak(peak: float, static: float) -> dict[str, float]:
    """Attributes of a run under gravity: ``static_wall_force`` [N], the weight the wall carries at
    rest (the static equilibrium the run starts from), and ``peak_wall_force_dynamic`` [N], the
    peak wall force minus it: what the impact adds (-> 0 as the striker's speed -> 0, while
    ``peak_wall_force`` -> the weight).

    Parameters
    ----------
    peak : float
        The run's ``peak_wall_force`` [N].
    static : float
        The wall contact's static force [N] (``System.static_forces()[N]``).

    Returns
    -------
    dict
        The two attributes.
    """
    return {"static_wall_force": static, "peak_wall_force_dynamic": peak - static}


def build_dataset(raw: RawRun, model: Model, probes: Probes, *, duration: float, config: dict | None = None,
                  extra_attrs: dict | None = None, system=None) -> xr.Dataset:
    """Assemble the result of one run (see the module docstring for the layout; the content is
    :func:`run_fields`).

    ``system`` is ``model.system()`` when the caller already has it (it is not free for long chains).
    """
    return fields_dataset(run_fields(raw, model, probes, duration=duration, config=config,
                                     extra_attrs=extra_attrs, system=system))


def fields_dataset(f: RunFields) -> xr.Dataset:
    """The Dataset of ``f``: the one ``xr.Dataset(data, coords=f.coords, attrs=f.attrs)`` builds.

    Assembled directly (variables, one pandas index per coordinate, sizes): the public
    constructor merges and aligns the variables, which took ~0.5 ms of a ~5 ms ``simulate()``
    (benchmarks/overhead.py) for nothing, since a run's variables are aligned by construction.
    Falls back to the public constructor if xarray's internal ``Dataset._construct_direct`` is
    ever missing; tests/test_overhead.py checks that both give identical Datasets.

    Parameters
    ----------
    f : RunFields
        From :func:`run_fields`.

    Returns
    -------
    xarray.Dataset
        The result.
    """
    try:
        import pandas as pd
        from xarray.core.indexes import Index, PandasIndex

        # NumPy arrays throughout, so the checks of the public constructors can be skipped
        out = {name: xr.Variable(dims, np.asarray(values), attrs=attrs, fastpath=True)
               for name, (dims, values, attrs) in f.data.items()}
        indexes: dict[Hashable, Index] = {}
        for name, (dim, values, attrs) in f.coords.items():
            # the run's own arrays: indexed without a copy, named (so that xarray does not copy the
            # index to name it) and of a known dtype (no cast, no inference: fastpath)
            values = np.asarray(values)
            index = PandasIndex(pd.Index(values, copy=False, name=dim), dim, values.dtype, fastpath=True)
            indexes[name] = index
            variables = index.create_variables()
            variables[name].attrs.update(attrs)
            out.update(variables)
        sizes: dict[Hashable, int] = {}
        for var in out.values():
            sizes.update((d, n) for d, n in zip(var.dims, var.shape) if d not in sizes)
        return xr.Dataset._construct_direct(out, set(f.coords), sizes, dict(f.attrs), indexes)
    except (ImportError, AttributeError, TypeError):  # xarray's internals moved: the public way
        variables = {name: xr.Variable(dims, values, attrs=attrs) for name, (dims, values, attrs) in f.data.items()}
        return xr.Dataset(variables, coords=f.coords, attrs=f.attrs)


def to_netcdf_bytes(ds: xr.Dataset, compress: bool = True, single_precision: bool = False) -> bytes:
    """The NetCDF (HDF5) file of ``ds`` as bytes, built in memory (see :func:`save` for the options).

    Parameters
    ----------
    ds : xarray.Dataset
        A result.
    compress : bool
        gzip the variables of more than 1000 values (lossless).
    single_precision : bool
        Store time-dependent variables as float32.

    Returns
    -------
    bytes
        The file's content.
    """
    encoding = {}
    for name, var in ds.data_vars.items():
        enc = {"compression": "gzip", "compression_opts": 4, "shuffle": True} if compress and var.size > 1000 else {}
        if single_precision and "time" in var.dims:
            enc["dtype"] = "float32"
        if enc:
            encoding[name] = enc
    return bytes(netcdf_bytes(ds, encoding))


def netcdf_bytes(ds: xr.Dataset, encoding: dict) -> memoryview:
    """``ds.to_netcdf`` into memory with ``encoding``, whatever Dask scheduler is active.

    xarray guards a write with a lock of the active Dask scheduler; with a ``distributed.Client``
    as the default that is a lock held by the cluster's scheduler, named after the target, and an
    in-memory target has no name the cluster can know ("Semaphore or Lock ... not known"). The
    file is written here, by this thread, from arrays already in memory: the local synchronous
    scheduler's lock is the right one, wherever this runs (the client, a Dask worker).

    Parameters
    ----------
    ds : xarray.Dataset
        The data, in memory.
    encoding : dict
        Per-variable NetCDF encoding (compression, dtype).

    Returns
    -------
    memoryview
        The file's content (a view of the in-memory file: no copy of a file that may be as large
        as the records).
    """
    try:
        import dask
    except ImportError:  # without Dask (the [cluster] extra) xarray takes no scheduler's lock
        return memoryview(ds.to_netcdf(None, engine=ENGINE, encoding=encoding))
    with dask.config.set(scheduler="synchronous"):
        return memoryview(ds.to_netcdf(None, engine=ENGINE, encoding=encoding))


def save(ds: xr.Dataset, path: str | Path, compress: bool = True, single_precision: bool = False) -> Path:
    """Write a result to NetCDF (HDF5 based, gzip-compressed); parent folders are created.

    ``single_precision`` stores the time-dependent variables as float32 (7 significant digits,
    enough to redraw figures; halves the size); the default keeps every bit. The file is built
    in memory and written with :func:`hertzchain.fileio.write_bytes` (unique temporary file,
    fsync, atomic rename): a full disk or a missing permission is a clean
    :class:`~hertzchain.errors.ConfigError` (HDF5 writing straight to a full disk could crash the
    process), and an existing ``path`` that is not a regular file is refused before any work.

    Parameters
    ----------
    ds : xarray.Dataset
        A result of :func:`simulate` (or :func:`simulate_batch`).
    path : str or pathlib.Path
        The file to write (``.nc``); replaced only once the new file is complete.
    compress : bool
        gzip level 4 with byte shuffling for variables of more than 1000 values.
    single_precision : bool
        Store the time-dependent variables as float32 (7 significant digits); halves the size.

    Returns
    -------
    pathlib.Path
        The path written.
    """
    from .errors import ConfigError
    from .fileio import check_target, write_bytes

    path = Path(path)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ConfigError(str(path), f"cannot create its folder: {exc.strerror}") from None
    check_target(path)
    write_bytes(path, to_netcdf_bytes(ds, compress, single_precision))
    return path


def load(path: str | Path) -> xr.Dataset:
    """Read a result written by :func:`save` (fully loaded, file closed).

    Parameters
    ----------
    path : str or pathlib.Path
        A NetCDF file written by :func:`save` or ``hertzchain run``.

    Returns
    -------
    xarray.Dataset
        The result, with its units [SI] in each variable's ``units`` attribute.
    """
    with xr.open_dataset(path, engine=ENGINE) as ds:
        return ds.load()
