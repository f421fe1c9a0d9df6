"""Band-gap maps: a sweep whose members are analysed by their band structure, not run.

With ``[sweep] analysis = "dispersion"`` every member's chain is one period of a periodic chain
under its ``chain.precompression`` (:func:`hertzchain.dispersion`: the Bloch band structure
linearised about the static force F0), and the sweep's table holds its band gaps instead of
wall-pulse metrics. Sweeping a size, a material or the precompression draws a band-gap map: the
gaps against that parameter (``hertzchain sweep`` draws it, ``gap_map.png``).

:func:`run_gap_sweep` writes into the output folder (folder lock, ``sweep.json`` and ``--force``
as for any sweep, :mod:`hertzchain.sweep.storage`):

- ``metrics.csv``: one row per member, the swept values and :data:`GAP_COLUMNS` (the lowest gap's
  edges, the number of gaps, every gap as JSON), with ``metrics.csv.json`` (units, the sweep);
- ``gaps.nc``: ``gap_low`` and ``gap_high`` [Hz] over ``member`` and ``gap`` (NaN past a
  member's last gap) and ``top`` [Hz], the highest frequency of its top branch.

A band structure takes milliseconds (an eigenproblem of the cell's size per wavenumber), so a
rerun computes every member again rather than resuming chunk by chunk.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Callable

import numpy as np

from ..errors import ConfigError
from .schema import SweepConfig, chunk_members
from .storage import _drop_replaced, _folder_lock, _prepare_out_dir

__all__ = ["run_gap_sweep", "GAP_COLUMNS", "WAVENUMBERS"]

#: Wavenumbers from 0 to pi per member (both included: a dimer's gap edges are at q = pi).
WAVENUMBERS = 201
#: The columns of a band-gap sweep's table: unit and meaning.
GAP_COLUMNS = {
    "gap_count": ("1", "band gaps of the member's periodic chain"),
    "gap_low_Hz": ("Hz", "the lowest gap's lower edge (the top of the branch below it); NaN without a gap"),
    "gap_high_Hz": ("Hz", "the lowest gap's upper edge (the bottom of the branch above it)"),
    "top_Hz": ("Hz", "the highest frequency of the top branch (the chain passes nothing above it)"),
    "gaps_Hz": ("Hz", "every gap [[low, high], ...] from the lowest (JSON)"),
}


def run_gap_sweep(cfg: SweepConfig, out: Path, progress: Callable[[int, int], None] | None = None,
                  force: bool = False):
    """The band gaps of every member of ``cfg`` (module docstring).

    Parameters
    ----------
    cfg : SweepConfig
        A sweep with ``analysis = "dispersion"``; each member's chain is one period, its
        ``chain.precompression`` [N] > 0 the static force.
    out : pathlib.Path
        The output folder.
    progress : callable, optional
        ``progress(done_members, total_members)`` after each chunk of members.
    force : bool
        Replace the results of a different sweep found in ``out``.

    Returns
    -------
    pandas.DataFrame
        One row per member (``member``, ``chunk``, the swept values, :data:`GAP_COLUMNS`), as in
        ``metrics.csv``.
    """
    import pandas as pd
    import xarray as xr

    from ..crystal.dispersion import dispersion
    from ..fileio import atomic_path, json_text, write_bytes, write_text
    from ..interrupts import check

    if cfg.sweep.traces:
        raise ConfigError("sweep.traces", "a band-gap sweep (analysis = 'dispersion') records no traces: leave it out")
    gaps: list[list[list[float]]] = []
    top = np.empty(cfg.n_members)
    chunk_of = np.empty(cfg.n_members, dtype=np.int64)
    built: dict = {}
    with _folder_lock(out):
        _prepare_out_dir(cfg, out, force)
        done = 0
        if progress is not None:
            progress(0, cfg.n_members)
        for index, members in enumerate(cfg.chunks()):
            check()
            models, _ = chunk_members(cfg, members, built)
            for r, i in enumerate(members):
                model = models.model(r) if hasattr(models, "model") else models[r]
                try:
                    ds = dispersion(model.chain, model.precompression, points=WAVENUMBERS)
                except ConfigError as exc:
                    raise ConfigError(exc.field, f"sweep member {i} ({json.dumps(cfg.members[i])}): "
                                      f"{exc.message}") from None
                gaps.append(ds.attrs["gaps"])
                top[i] = float(ds.frequency.values.max())
                chunk_of[i] = index
            done += len(members)
            if progress is not None:
                progress(done, cfg.n_members)
        width = max([len(g) for g in gaps] + [1])
        edges = np.full((cfg.n_members, width, 2), np.nan)
        for i, g in enumerate(gaps):
            if g:
                edges[i, : len(g)] = g
        table: dict = {"member": np.arange(cfg.n_members), "chunk": chunk_of}
        for name in cfg.parameter_names:
            table[name] = [json.dumps(v) if isinstance(v, (list, dict)) else v for v in
                           (cfg.members[m][name] for m in range(cfg.n_members))]
        table.update(gap_count=[len(g) for g in gaps], gap_low_Hz=edges[:, 0, 0], gap_high_Hz=edges[:, 0, 1],
                     top_Hz=top, gaps_Hz=[json.dumps(g) for g in gaps])
        df = pd.DataFrame(table)
        with atomic_path(out / "metrics.csv") as tmp:
            df.to_csv(tmp, index=False)
        columns = {c: {"units": u, "long_name": t} for c, (u, t) in GAP_COLUMNS.items()}
        columns.update({c: {"units": "", "long_name": "swept parameter (config path)"} for c in cfg.parameter_names})
        write_text(out / "metrics.csv.json", json_text({"table": "metrics.csv", "analysis": "dispersion",
                                                        "n_members": cfg.n_members, "columns": columns,
                                                        "definition": cfg.definition()}))
        data = xr.Dataset({"gap_low": (("member", "gap"), edges[:, :, 0], {"units": "Hz", "long_name": "gap's lower edge"}),
                           "gap_high": (("member", "gap"), edges[:, :, 1], {"units": "Hz", "long_name": "gap's upper edge"}),
                           "top": ("member", top, {"units": "Hz", "long_name": "top of the highest branch"})},
                          coords={"member": np.arange(cfg.n_members), "gap": np.arange(width)},
                          attrs={"title": "hertzchain band-gap sweep", "sweep_hash": cfg.hash,
                                 "parameters": json.dumps(cfg.parameter_names)})
        write_bytes(out / "gaps.nc", data.to_netcdf())
        _drop_replaced(out)
    return df
