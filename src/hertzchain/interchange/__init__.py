"""Exchange formats other tools open: a result as particle trajectories (H5MD), a ParaView time
series (VTK) and a LAMMPS data file with its input script.

- ``*.h5md``: H5MD 1.1 (:mod:`.h5md`), what LAMMPS ``dump h5md`` writes: positions, velocities and
  forces of the striker and every bead over time, with units.
- ``*.pvd``: a ParaView collection of VTK PolyData frames (:mod:`.vtk`), the ``.vtp`` files beside
  it: the bodies as points with their diameters, forces, velocities and displacements.
- ``*.data``: a LAMMPS data file of the striker and the chain at impact, and beside it ``in.NAME``,
  the input script of the run (:mod:`.lammps`): ``pair_style granular`` with ``hertz/material``
  and the materials' E and nu, the wall as ``fix wall/gran``.

The bodies are those of the chain (0 = the striker, 1..N = the beads), along x from the striker's
contact with bead 1 (docs/conventions.rst); positions are the places at rest plus the recorded
displacements.
"""

from __future__ import annotations

from pathlib import Path

import xarray as xr

__all__ = ["FORMATS", "write"]

#: File suffixes written here, and what they are.
FORMATS = {".h5md": "H5MD 1.1 trajectories: positions, velocities, forces",
           ".pvd": "ParaView time series, .vtp frames beside it",
           ".data": "LAMMPS data file, input script in.NAME beside it"}


def write(run: xr.Dataset, path: Path, suffix: str, frames: int | None = None) -> list[Path]:
    """Write one run in the exchange format of ``suffix`` (a key of :data:`FORMATS`).

    Parameters
    ----------
    run : xarray.Dataset
        One run (no ``member`` dimension).
    path : pathlib.Path
        The main file (``.h5md``, ``.pvd`` or ``.data``); its folder exists.
    suffix : str
        Its format.
    frames : int, optional
        ``.pvd`` only: how many frames, evenly spread over the samples (default
        :data:`hertzchain.interchange.vtk.DEFAULT_FRAMES`, at most every sample).

    Returns
    -------
    list of pathlib.Path
        Every file written, the main file first.
    """
    if suffix == ".h5md":
        from .h5md import write_h5md

        return write_h5md(run, path)
    if suffix == ".pvd":
        from .vtk import write_pvd

        return write_pvd(run, path, frames)
    from .lammps import write_lammps

    return write_lammps(run, path)
