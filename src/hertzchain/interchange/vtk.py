"""A run as a ParaView time series: a ``.pvd`` collection and one VTK XML PolyData (``.vtp``) file
per frame beside it (https://docs.vtk.org/en/latest/design_documents/VTKFileFormats.html).

Each frame holds the bodies (0 = the striker, 1..N = the beads) as points, one vertex cell each,
with point data ``diameter`` [m] (ParaView: a Glyph filter of spheres scaled by it draws the
beads), ``force`` [N] (net contact force, a vector along the chain), ``velocity`` [m s-1] and
``displacement`` [m] when recorded, and ``body`` (the body number). The collection gives each
frame its time [s]. Files are written in ASCII, the format every VTK reader accepts; the
``.pvd`` last, so a collection on disk always names complete frames.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import xarray as xr

from ..errors import ConfigError
from .bodies import particles

__all__ = ["write_pvd", "DEFAULT_FRAMES", "MAX_FRAMES"]

#: Frames written unless asked otherwise: enough to follow a pulse along a chain, not one file
#: per sample (a 3 ms run sampled every 100 ns has 30 000).
DEFAULT_FRAMES = 200
#: Most frames (files) one export writes.
MAX_FRAMES = 20000


def _array(name: str | None, values: np.ndarray, dtype: str, components: int = 1) -> str:
    fmt = "%.15g" if dtype.startswith("Float") else "%d"
    text = " ".join(fmt % v for v in np.asarray(values).ravel())
    named = f' Name="{name}"' if name else ""
    comps = f' NumberOfComponents="{components}"' if components > 1 else ""
    return f'        <DataArray type="{dtype}"{named}{comps} format="ascii">{text}</DataArray>\n'


def frame_text(position: np.ndarray, point_data: dict[str, np.ndarray]) -> str:
    """One VTK XML PolyData file: ``position`` (B, 3) as points with a vertex each, and
    ``point_data`` (name -> (B,) or (B, 3) array)."""
    b = position.shape[0]
    vectors = [k for k, v in point_data.items() if v.ndim == 2]
    attrs = ' Scalars="diameter"' + (f' Vectors="{vectors[0]}"' if vectors else "")
    parts = ['<?xml version="1.0"?>\n',
             '<VTKFile type="PolyData" version="1.0" byte_order="LittleEndian" header_type="UInt64">\n',
             "  <PolyData>\n",
             f'    <Piece NumberOfPoints="{b}" NumberOfVerts="{b}" NumberOfLines="0" NumberOfStrips="0" '
             'NumberOfPolys="0">\n',
             f"      <PointData{attrs}>\n"]
    for name, values in point_data.items():
        dtype = "Int64" if np.issubdtype(values.dtype, np.integer) else "Float64"
        parts.append(_array(name, values, dtype, 3 if values.ndim == 2 else 1))
    parts += ["      </PointData>\n", "      <Points>\n", _array("Points", position, "Float64", 3),
              "      </Points>\n", "      <Verts>\n", _array("connectivity", np.arange(b), "Int64"),
              _array("offsets", np.arange(1, b + 1), "Int64"), "      </Verts>\n",
              "    </Piece>\n", "  </PolyData>\n", "</VTKFile>\n"]
    return "".join(parts)


def collection_text(times: np.ndarray, files: list[str]) -> str:
    """The ``.pvd`` collection: each frame file with its time [s]."""
    rows = "".join(f'    <DataSet timestep="{t:.10g}" group="" part="0" file="{name}"/>\n'
                   for t, name in zip(times, files))
    return ('<?xml version="1.0"?>\n<VTKFile type="Collection" version="0.1" byte_order="LittleEndian">\n'
            f"  <Collection>\n{rows}  </Collection>\n</VTKFile>\n")


def frame_samples(n_samples: int, frames: int | None) -> np.ndarray:
    """Sample indices of ``frames`` frames evenly spread over ``n_samples`` (first and last included)."""
    if frames is None:
        frames = DEFAULT_FRAMES
    if isinstance(frames, bool) or not isinstance(frames, (int, np.integer)) or not 1 <= frames <= MAX_FRAMES:
        raise ConfigError("--frames", f"must be a whole number of frames in 1..{MAX_FRAMES}, got {frames!r}")
    k = min(int(frames), n_samples)
    return np.unique(np.round(np.linspace(0, n_samples - 1, k)).astype(int))


def write_pvd(run: xr.Dataset, path: Path, frames: int | None = None) -> list[Path]:
    """Write ``run`` as ``path`` (``NAME.pvd``) and its frames ``NAME_000000.vtp``... beside it.

    Parameters
    ----------
    run : xarray.Dataset
        One run with positions (``probes.positions``).
    path : pathlib.Path
        The ``.pvd`` file.
    frames : int, optional
        Number of frames, evenly spread over the samples (default :data:`DEFAULT_FRAMES`, at most
        one per sample).

    Returns
    -------
    list of pathlib.Path
        The ``.pvd`` then every ``.vtp``.
    """
    from ..fileio import write_text

    p = particles(run)
    index = frame_samples(p.time.size, frames)
    names = [f"{path.stem}_{k:06d}.vtp" for k in range(index.size)]
    written = []
    for name, i in zip(names, index):
        data = {"body": p.body, "diameter": p.diameter}
        if p.force is not None:
            data["force"] = p.force[i]
        if p.velocity is not None:
            data["velocity"] = p.velocity[i]
        data["displacement"] = p.displacement[i]
        write_text(path.with_name(name), frame_text(p.position[i], data))
        written.append(path.with_name(name))
    write_text(path, collection_text(p.time[index], names))
    return [path, *written]
