"""A run as an H5MD 1.1 file (https://www.nongnu.org/h5md/h5md.html), the HDF5 layout of particle
trajectories that LAMMPS ``dump h5md`` writes and pyh5md, MDAnalysis and VMD read.

Layout (units in each dataset's ``unit`` attribute, H5MD's notation: ``m``, ``m s-1``, ``N``)::

    h5md/                      version = [1, 1]; author/ (name), creator/ (name, version)
    particles/chain/           the striker (particle 0) and beads 1..N
        box/                   dimension = 3, boundary = [none, none, none]
        position/  step, time, value (T, N+1, 3)      m
        velocity/  step, time, value (T, N+1, 3)      m s-1   (when the run recorded velocities)
        force/     step, time, value (T, N+1, 3)      N       (net contact force; every contact recorded)
        diameter   (N+1,)                             m       (time-independent)
        id         (N+1,)                                     body numbers, 0 = striker
    observables/wall_force/    step, time, value (T,) N (and the energies the run recorded, J)
    parameters/                attributes: the run's model and config (JSON text)

``time`` is the sample's time [s]; ``step`` is the sample's number (the engine's own steps are
adaptive, so a step count would not map to time linearly). Time-dependent elements share one
``step`` and ``time`` (hard links, as H5MD allows).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import xarray as xr

from .. import __version__
from .bodies import particles

__all__ = ["write_h5md", "H5MD_VERSION"]

#: The H5MD version written.
H5MD_VERSION = (1, 1)
#: Energies recorded by a run, written as observables beside the wall force.
_OBSERVABLES = ("wall_force", "kinetic_energy", "potential_energy", "dissipated_energy")


def _text(value: str) -> np.bytes_:
    """A fixed-length ASCII string, the type H5MD readers expect of names and boundaries."""
    return np.bytes_(value.encode("ascii", "replace"))


def _element(group, name: str, value: np.ndarray, unit: str | None, step, time) -> None:
    """A time-dependent H5MD element: ``name/value`` with hard links to the shared step and time."""
    g = group.create_group(name)
    g["step"] = step
    g["time"] = time
    v = g.create_dataset("value", data=value, compression="gzip", compression_opts=4, shuffle=True,
                         chunks=(min(value.shape[0], 256), *value.shape[1:]) if value.ndim > 1 else True)
    if unit is not None:
        v.attrs["unit"] = _text(unit)


def write_h5md(run: xr.Dataset, path: Path) -> list[Path]:
    """Write ``run`` as H5MD 1.1 at ``path`` (atomically: a failed write leaves nothing there).

    Parameters
    ----------
    run : xarray.Dataset
        One run with positions (``probes.positions``); velocities and every contact force are
        written when recorded.
    path : pathlib.Path
        The ``.h5md`` file.

    Returns
    -------
    list of pathlib.Path
        ``[path]``.
    """
    import h5py

    from ..fileio import atomic_path

    p = particles(run)
    with atomic_path(path) as tmp, h5py.File(tmp, "w") as f:
        h5 = f.create_group("h5md")
        h5.attrs["version"] = np.asarray(H5MD_VERSION, dtype=np.int32)
        h5.create_group("author").attrs["name"] = _text("hertzchain developers")
        creator = h5.create_group("creator")
        creator.attrs["name"] = _text("hertzchain")
        creator.attrs["version"] = _text(__version__)
        chain = f.create_group("particles/chain")
        box = chain.create_group("box")
        box.attrs["dimension"] = np.int32(3)
        box.attrs["boundary"] = np.array([b"none"] * 3, dtype="S8")
        step = chain.create_dataset("position/step", data=np.arange(p.time.size, dtype=np.int64))
        time = chain.create_dataset("position/time", data=p.time)
        time.attrs["unit"] = _text("s")
        value = chain["position"].create_dataset("value", data=p.position, compression="gzip", compression_opts=4,
                                                 shuffle=True, chunks=(min(p.time.size, 256), *p.position.shape[1:]))
        value.attrs["unit"] = _text("m")
        if p.velocity is not None:
            _element(chain, "velocity", p.velocity, "m s-1", step, time)
        if p.force is not None:
            _element(chain, "force", p.force, "N", step, time)
        chain.create_dataset("diameter", data=p.diameter).attrs["unit"] = _text("m")
        chain.create_dataset("id", data=p.body.astype(np.int64))
        obs = f.create_group("observables")
        for name in _OBSERVABLES:
            if name in run and run[name].dims == ("time",):
                _element(obs, name, np.asarray(run[name].values, dtype=float), run[name].attrs.get("units"),
                         step, time)
        params = f.create_group("parameters")
        for key in ("model", "config", "conventions"):
            if isinstance(run.attrs.get(key), str):
                params.attrs[key] = run.attrs[key]
    return [path]
