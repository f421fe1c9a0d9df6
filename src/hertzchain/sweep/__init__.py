"""Parameter sweeps and tolerance ensembles, computed in resumable chunks by the batched engine.

A sweep file (TOML) has two tables::

    [base]                      # a normal run config (see hertzchain.config)
    chain = { uniform = { n = 16, diameter_mm = 26.0 }, taper = { n = 8, q = 0.05 } }
    striker = { velocity = 0.2 }
    run = { duration = 2.0e-3, sample_interval = 1e-7 }

    [sweep]
    mode = "grid"               # cartesian product of the lists; or "random"
    parameters = { "striker.velocity" = [0.1, 0.2, 0.4], "chain.taper.q" = [0.02, 0.05] }
    chunk_size = 16             # members per chunk file (the unit of resumption)
    tolerances = { diameter_rel = 0.001, offset_mm = 0.05, seed = 1 }

Parameters are dotted paths into the base config (``chain.taper.q``, ``chain.diameters_mm[3]``).
``zip = [["chain.taper.n", "chain.taper.q"]]`` couples parameters: their lists (of equal
length) are walked together, as one axis of the grid (or one draw in random mode), e.g. bead
count and tapering factor chosen so the last bead keeps its size. ``mode = "random"`` draws ``n`` members with ``seed``; each parameter is then a list to choose
from or a range ``{ low = 0.1, high = 0.4 }`` (options ``log = true``, ``integer = true``).
``tolerances`` perturbs every member with seeded random deviations (manufacturing tolerances:
relative and absolute diameter deviations, per bead or for all, beads of one production lot
correlated, perpendicular offsets, the impact velocity; the statistical model is in
:mod:`hertzchain.sweep.tolerances`). Random draws depend only on (seed, member index): a
member is the same whatever ``n`` or ``chunk_size`` is. ``store = "metrics"`` keeps only each
member's metrics (a few hundred bytes: a million-member ensemble runs out of core, chunk by
chunk) and ``traces = [...]`` the full records of the members named. ``analysis = "dispersion"``
makes a band-gap map instead of runs (:mod:`hertzchain.sweep.gaps`: each member's chain one period
of a periodic chain, its band gaps in ``metrics.csv``).

:func:`run_sweep` writes into ``out_dir``:

- ``sweep.json``: the sweep definition and its hash (a rerun with a different sweep is refused
  unless ``force``);
- ``chunks/chunk_00012.nc``: one file per finished chunk (the batched results stacked along
  ``member`` plus the pulse metrics), written through :mod:`hertzchain.fileio` (unique temporary
  name, fsync, rename), so a killed sweep never leaves a half chunk, and a rerun skips every
  chunk already on disk (resumption); beside it ``chunk_00012.nc.sha256``, the SHA-256 of the
  file, checked before a chunk is skipped: a chunk damaged on disk is computed again;
- ``.sweep.lock``: held (``flock``) while a sweep writes into the folder; a second sweep on the
  same folder is refused (:class:`SweepLocked`) instead of mixing files with the first;
- ``chunks/traces_00012.nc`` (store = "metrics" with ``traces``): the full records of the
  traced members of chunk 12, written before the chunk file;
- ``metrics.csv`` (and ``metrics.parquet`` when pyarrow is installed): one row per member, the
  swept parameter values and the wall-pulse metrics of the paper (Sec. III), SI units:
  ``F_m`` [N], ``T`` [s], ``tau`` [s], ``Q_F`` [N s], ``Q_T`` [N s], with the peak wall force
  and its time, the energies at the end and the largest contact force over yield.

Parallelism is passed in: locally each chunk already uses every core
(a compiled loop per core); with a Dask ``distributed.Client`` (worker processes here or on other
machines), an executor with ``submit``, or anything with ``map``, the chunks are farmed out
(:mod:`hertzchain.parallel`) and written here as they come back.

The package has five parts: :mod:`~hertzchain.sweep.schema` (the sweep file: its tables and
members; the models of a chunk), :mod:`~hertzchain.sweep.tolerances` (the deviations and their
statistical model), :mod:`~hertzchain.sweep.storage` (the output folder: chunk files and their
checksums, the folder lock, ``sweep.json`` and ``metrics.csv``), :mod:`~hertzchain.sweep.runner`
(:func:`run_sweep`: one chunk computed, the chunks mapped over a Dask client or run here) and
:mod:`~hertzchain.sweep.statistics` (the metrics' statistics).
"""

from __future__ import annotations

from .runner import SweepResult, compute_chunk, run_sweep
from .schema import SweepConfig, load_sweep, parse_sweep
from .storage import METRIC_COLUMNS, SweepLocked, SweepMismatch

__all__ = ["SweepConfig", "SweepMismatch", "SweepLocked", "SweepResult", "load_sweep", "parse_sweep", "run_sweep",
           "compute_chunk", "METRIC_COLUMNS"]
