"""``hertzchain reproduce``: the paper as one command (runs, data, summary, figures, report)."""

from __future__ import annotations

import json
import math
import multiprocessing
import os
import time
from functools import partial
from pathlib import Path
from typing import Any, Callable, Sequence

import numpy as np

from ..interrupts import forked_pool
from ..parallel import usable_cores
from .. import __version__, theory
from ..result import save as _save
from . import fidelity, protocol
from .ahead import CompileAhead
from .claims import build_claims
from .inputs import SUB_TAGS, check_laws, check_settings, expected_traces
from .protocol import ChainStudy, Settings
from .values import PAPER
from ..laws import is_conservative, spec_of

__all__ = ["reproduce", "redraw", "load_data", "draw", "count_runs", "count_steps", "build_summary",
           "elastic_limit_summary", "FIGURE_NAMES", "SUMMARY_UNITS"]

#: The figures drawn (one progress step each, then one for the report).
FIGURE_NAMES = ("fig1", "fig2", "fig3", "fig4", "fig5", "fig6")
#: Order in which the drawing processes take the figures, the model-variant ones included: the
#: costliest first (measured, PNG + PDF: Fig. 1 1.0 s, Fig. 2 0.9 s, Fig. 5 0.8 s, Fig. 6 0.7 s,
#: Figs. 3 and 3 lateral 0.6 s, Fig. 5 laws 0.5 s, Fig. 4 0.25 s; Fig. 6 before Fig. 5 lets the
#: two processes of --from-data, which draws Figs. 1, 2, 4-6, finish together).
_DRAW_ORDER = ("fig1", "fig2", "fig6", "fig5", "fig3", "fig3_lateral", "fig5_laws", "fig4")

#: Units of the summary.json values (SI), written into the file under ``"units"``.
SUMMARY_UNITS = {
    "peak_force, uniform_peak_force, yield_force, figures.misalignment[].peak_force": "N",
    "duration, time_of_flight, T0, uniform_time_of_flight, figures.*.duration, figures.*.time_of_flight, "
    "figures.wall_tof_shift_s, figures.tof_gain_s, timing (s)": "s",
    "front_momentum, tail_momentum": "N s",
    "v1, local_velocity, speed_check.velocities, fidelity.laws.*.restitution_trend.speeds": "m/s",
    "yield_overlap, figures.misalignment[].offset_m": "m",
    "diameter_mm": "mm",
    "figures.spectra.*_hz": "Hz",
    "q, q_std, Q_*, eps*, *_ratio, max_force_over_yield, *_deviation, offset_fraction, collapse_rms, "
    "*restitution*": "1 (dimensionless)",
    "law.A": "s (Kuwabara-Kono time constant)",
    "law.gamma": "N s/m",
    "fidelity.misalignment.*.tail_oscillation": "N",
    "fidelity.misalignment.*.max_lateral_kinetic_energy, friction_loss, striker_energy": "J",
    "fidelity.misalignment.*.time_of_flight_change_s, fidelity.lateral_cost.seconds": "s",
    "fidelity.tracks.*: groove_radius / spring / slip_velocity / gravity": "m / N/m / m/s / m/s^2",
    "claims[].values": "the unit of the row's quantity",
}

#: Significant digits kept in summary.json: the automatic step keeps peak forces within 1e-6 of
#: a DOP853 reference (README), so digits beyond the sixth are noise (e.g. 26.000000000000004).
SUMMARY_DIGITS = 6


def count_runs(settings: Settings) -> int:
    """Number of simulations a reproduction makes (for the progress bar)."""
    n1 = PAPER["chain1"]["n_beads"] - PAPER["n0"] + 1
    n2 = PAPER["chain2"]["n_beads"] - PAPER["n0"] + 1
    from .fidelity import count_variant_runs

    return n1 + n2 + 6 + 3 + 1 + 10 + count_variant_runs(settings)


def count_steps(settings: Settings, figures: bool = True) -> int:
    """Progress steps of a reproduction: every simulation, then each figure and the report."""
    return count_runs(settings) + (len(FIGURE_NAMES) + 1 if figures else 0)


def _round(x, digits: int = SUMMARY_DIGITS):
    """Round every float of a JSON-like structure to ``digits`` significant digits."""
    if isinstance(x, dict):
        return {k: _round(v, digits) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_round(v, digits) for v in x]
    if isinstance(x, (np.integer,)):
        return int(x)
    if isinstance(x, (float, np.floating)):
        v = float(x)
        if not math.isfinite(v) or v == 0:
            return v if math.isfinite(v) else None
        return round(v, digits - 1 - math.floor(math.log10(abs(v))))
    return x


def elastic_limit_summary(studies: dict, mis: dict, subs: dict) -> dict:
    """The elastic-limit check over every run of a reproduction (paper Sec. II).

    Returns ``{"max_force_over_yield", "runs_past_limit", "runs", "message"}``; ``message`` is
    :func:`hertzchain.runs.simulation.elastic_limit_message` of the worst run (None when no run passes
    the limit).
    """
    from ..runs.simulation import elastic_limit_message

    runs = [(f"{name.replace('chain', 'chain ')} cut after bead {n}: ", ds)
            for name, s in studies.items() for n, ds in sorted(s.wall.items())]
    runs += [(f"Fig. 3, chain 2 with bead {b} offset by {100 * fr:g} %: ", ds) for (b, fr), ds in sorted(mis.items())]
    runs += [(f"Fig. 3c, chain 1 cut after bead 24 ({label}): ", ds) for label, ds in subs.items()]
    ratios = [float(np.max(ds.max_contact_force.values / ds.yield_force.values)) for _, ds in runs]
    worst = int(np.argmax(ratios))
    past = sum(r > 1 for r in ratios)
    msg = elastic_limit_message(runs[worst][1], runs[worst][0]) if past else None
    if msg and past > 1:
        msg += f" ({past} of {len(runs)} runs pass the limit)"
    return {"max_force_over_yield": ratios[worst], "runs_past_limit": past, "runs": len(runs), "message": msg}


def _chain_summary(study: ChainStudy) -> dict:
    def clean(a):
        return [None if not np.isfinite(x) else float(x) for x in np.asarray(a, dtype=float)]

    return {
        "q": study.q, "q_std": study.q_std, "Q_theory": study.Q_theory, "Q_fit": study.Q_fit,
        "Q_fit_err": study.Q_fit_err, "beads": [int(b) for b in study.truncations],
        "diameter_mm": clean(study.chain.diameters[study.truncations - 1] * 1e3),
        "peak_force": clean(study.series("peak_force")), "duration": clean(study.series("duration")),
        "time_of_flight": clean(study.series("time_of_flight")),
        "front_momentum": clean(study.series("front_momentum")), "tail_momentum": clean(study.series("tail_momentum")),
        "eps_measured": study.eps_measured, "eps_measured_err": study.eps_measured_err,
        "v1": study.v1, "T0": study.T0, "local_velocity": clean(study.extras["v_local"]),
        "local_velocity_beads": [int(b) for b in study.extras["v_local_beads"]],
        "uniform_peak_force": clean(study.sensor_series("peak_force")),
        "uniform_time_of_flight": clean(study.sensor_series("time_of_flight")),
        "law": _law_desc(study.law),
    }


def _law_desc(law) -> dict:
    return {"law": law.name, **{p: getattr(law, p) for p in spec_of(law).param_names}}


def build_summary(studies: dict[str, ChainStudy], ratio: dict, speed: dict, settings: Settings,
                  timing: dict) -> dict:
    """summary.json: simulated values beside the paper's (keys fixed by the reproduction issue)."""
    f_y, d_y = theory.yield_limit(settings.material, PAPER["bead_diameter"])
    # eps measured back in the uniform part of both chains (identical beads): their mean.
    eps = float(np.mean([s.eps_measured for s in studies.values()]))
    eps_err = float(np.mean([s.eps_measured_err for s in studies.values()]))
    max_ratio = max(float((ds.max_contact_force / ds.yield_force).max()) for s in studies.values()
                    for ds in s.wall.values())
    return {
        "units": SUMMARY_UNITS,
        "hertzchain_version": __version__,
        "chain1": _chain_summary(studies["chain1"]),
        "chain2": _chain_summary(studies["chain2"]),
        "eps": eps, "eps_err": eps_err,
        "wall_to_chain_force_ratio": float(ratio["force_ratio"]),
        "wall_to_chain_duration_ratio": float(ratio["duration_ratio"]),
        "yield_force": f_y, "yield_overlap": d_y,
        "max_force_over_yield": max_ratio,
        "speed_check": {"velocities": speed["velocities"],
                        "max_peak_norm_deviation": speed["max_peak_norm_deviation"],
                        "max_duration_norm_deviation": speed["max_duration_norm_deviation"]},
        "paper": {
            "chain1": {k: PAPER["chain1"][k] for k in ("q", "q_std", "Q_fit", "Q_fit_err", "Q_theory")},
            "chain2": {k: PAPER["chain2"][k] for k in ("q", "q_std", "Q_fit", "Q_fit_err", "Q_theory")},
            "eps": PAPER["eps"], "wall_to_chain_force_ratio": PAPER["wall_to_chain_force_ratio"],
            "wall_to_chain_duration_ratio": PAPER["wall_to_chain_duration_ratio"],
            "yield_force": PAPER["yield_force"], "yield_overlap": PAPER["yield_overlap"],
        },
        "settings": settings.describe(),
        "timing": timing,
    }




def _trace_writes(out: Path, studies, mis, subs, ratio, lateral) -> list[Callable[[], object]]:
    """A call writing each simulated trace into ``out/data`` (single-precision compressed NetCDF:
    enough to redraw the figures), in the order the reproduction ran them."""
    data = out / "data"
    jobs = [(data / f"{name}_truncated_{n:02d}.nc", ds) for name, study in studies.items() for n, ds in study.wall.items()]
    jobs += [(data / f"fig3_chain2_offset_bead{bead}_e{frac:.2f}.nc", ds) for (bead, frac), ds in mis.items()]
    jobs += [(data / f"fig3c_chain1_24_{SUB_TAGS[label]}.nc", ds) for label, ds in subs.items()]
    jobs.append((data / "uniform16_elastic_wall_chain_ratio.nc", ratio["dataset"]))
    # the figure needs the wall force; the per-body transverse records would add ~2 MB a run
    jobs += [(data / f"fig3_lateral_{label}_bead{b}_e{frac:.2f}.nc", ds.drop_vars(["lateral_displacement", "momentum"]))
             for (label, b, frac), ds in lateral.items()]
    return [partial(_save, ds, path, single_precision=True) for path, ds in jobs]


#: Variables of a trace that the analysis and the figures read (the rest stays on disk).
_TRACE_VARIABLES = ("wall_force", "sensor_force", "diameter", "offset", "max_contact_force", "yield_force")
_H5_INTERNAL = {"DIMENSION_LIST", "REFERENCE_LIST", "CLASS", "NAME", "_Netcdf4Dimid", "_Netcdf4Coordinates",
                "_nc3_strict", "_FillValue", "_NCProperties"}


def _h5_attr(v):
    if isinstance(v, bytes):
        return v.decode("utf-8")
    if isinstance(v, np.ndarray) and v.size == 1 and v.dtype.kind != "O":
        return v[0]  # netCDF stores scalar attributes as 1-element arrays
    return v


def load_trace(path: str | Path, names=_TRACE_VARIABLES):
    """Read the variables ``names`` (and their coordinates) of a result file, straight with h5py.

    The same numbers, units and attributes as ``hertzchain.load(path)[names]``, without opening
    the whole file through xarray (~0.1 s a file, most of ``--from-data``'s time) nor
    decompressing the energies and contact forces the figures do not draw.
    """
    import h5py
    import xarray as xr

    from ..checks import available_memory

    memory = available_memory()
    with h5py.File(path, "r") as f:
        def read(name):
            d = f[name]
            # A received trace: what a variable declares is checked before it is allocated.
            if memory is not None and d.size * d.dtype.itemsize > memory // 2:
                raise ValueError(f"variable {name!r} declares shape {d.shape} of {d.dtype}, more than half the "
                                 f"memory available")
            if d.attrs.get("CLASS") == b"DIMENSION_SCALE":
                dims = (name,)
            else:
                dims = tuple(f[refs[0]].name.lstrip("/") for refs in d.attrs.get("DIMENSION_LIST", []))
            attrs = {k: _h5_attr(v) for k, v in d.attrs.items() if k not in _H5_INTERNAL}
            return xr.Variable(dims, d[()], attrs=attrs)

        data = {n: read(n) for n in names if n in f}
        dims = {d for v in data.values() for d in v.dims}
        coords = {d: read(d) for d in sorted(dims) if d in f}
        attrs = {k: _h5_attr(v) for k, v in f.attrs.items() if k not in _H5_INTERNAL}
    return xr.Dataset(data, coords=coords, attrs=attrs)


def load_data(out_dir: str | Path, settings: Settings):
    """Read back the traces of a reproduction: (studies, misalignment, substitutions, ratio)."""
    return _load_data_checked(out_dir, settings)


def _load_data_checked(out_dir: str | Path, settings: Settings, after_fig3: Callable | None = None,
                       ratio: bool = True):
    """:func:`load_data`, calling ``after_fig3(mis, subs)`` once the Fig. 3 traces are read (they
    are read first, before the chains' traces); ``ratio=False`` leaves the wall/chain ratio run
    unread (None: the figures do not draw it)."""
    from ..errors import ConfigError
    from ..result import load

    data = Path(out_dir) / "data"
    if not data.is_dir():
        raise ConfigError(str(data), "no data folder: run 'hertzchain reproduce' first")
    try:
        return _load_data(data, settings, load, after_fig3, ratio)
    except ConfigError:
        raise
    except (OSError, ValueError, KeyError, AttributeError, IndexError, TypeError, RuntimeError) as exc:
        # A trace that is readable NetCDF but lacks what the protocol needs (damaged, foreign)
        raise ConfigError(str(data), f"holds a damaged or foreign trace ({type(exc).__name__}: {exc}); "
                          "rerun 'hertzchain reproduce' without --from-data") from None


#: The first bytes of every HDF5 file (NetCDF-4, as hertzchain writes its results).
_HDF5_SIGNATURE = b"\x89HDF\r\n\x1a\n"


def _load_data(data: Path, settings: Settings, load, after_fig3: Callable | None = None, with_ratio: bool = True):
    import re

    from ..errors import ConfigError

    def read(p: Path, whole: bool = False):
        """A trace: the variables the figures draw (:func:`load_trace`), or the whole result."""
        if not p.is_file():
            raise ConfigError(str(p), "is missing: rerun 'hertzchain reproduce' without --from-data")
        try:
            return load(p) if whole else load_trace(p)
        except Exception as exc:  # noqa: BLE001 - a damaged HDF5 file raises anything (RuntimeError, OSError, ...)
            raise ConfigError(str(p), f"is damaged or not a hertzchain result ({type(exc).__name__}: {exc})") from None

    chains = {name: sorted(data.glob(f"{name}_truncated_*.nc")) for name in ("chain1", "chain2")}
    mis_files = sorted(data.glob("fig3_chain2_offset_bead*_e*.nc"))

    def numbers(p: Path, pattern: str) -> tuple[str, ...]:
        """The numbers in the name of trace ``p`` (the groups of ``pattern``)."""
        m = re.fullmatch(pattern, p.name)
        if m is None:  # a copy or another file named like a trace ("chain1_truncated_16 (2).nc")
            raise ConfigError(str(p), "is not a trace 'hertzchain reproduce' writes (not named as one); move it "
                              "out of the data folder")
        return m.groups()

    # (named before anything is read, like a foreign file below)
    numbered = {p: numbers(p, r"fig3_chain2_offset_bead(\d+)_e(\d+(?:\.\d+)?)\.nc") for p in mis_files}
    numbered |= {p: numbers(p, r"chain[12]_truncated_(\d+)\.nc") for files in chains.values() for p in files}
    sub_files = {label: data / f"fig3c_chain1_24_{tag}.nc" for label, tag in SUB_TAGS.items()}
    ratio_file = data / "uniform16_elastic_wall_chain_ratio.nc"
    # A truncated or foreign file is named before anything is read (and before the Fig. 3
    # traces, read first, set a drawing process going); a missing one when its turn comes.
    # Regular files of data/ only (hertzchain.received): a FIFO would hang the read, a link out of
    # the folder would read another file.
    from ..received import open_received

    for p in [*chains["chain1"], *chains["chain2"], *mis_files, *sub_files.values(), *([ratio_file] if with_ratio else [])]:
        if os.path.lexists(p):
            with open_received(p, data) as f:
                if f.read(len(_HDF5_SIGNATURE)) != _HDF5_SIGNATURE:
                    raise ConfigError(str(p), "is damaged or not a hertzchain result (not a NetCDF-4/HDF5 file)")
    for name, files in chains.items():
        if not files:
            raise ConfigError(str(data), f"holds no {name} traces")
    # Every trace the reproduction writes must be there (a missing truncation or offset would
    # silently leave a point out of a figure, or break the fit of the series).
    missing = [name for name in expected_traces(protocol.N0) if not (data / name).is_file()]
    if missing:
        raise ConfigError(str(data / missing[0]), f"is missing ({len(missing)} trace(s) missing: "
                          f"{', '.join(missing[:4])}{', ...' if len(missing) > 4 else ''}); rerun 'hertzchain "
                          "reproduce' without --from-data")
    mis = {}
    for p in mis_files:
        bead, offset = numbered[p]
        mis[(int(bead), float(offset))] = read(p)
    subs = {label: read(p) for label, p in sub_files.items()}
    if after_fig3 is not None:
        after_fig3(mis, subs)
    walls = {name: {int(numbered[p][0]): read(p) for p in files}
             for name, files in chains.items()}
    studies = {name: protocol.study_from_datasets(name, wall, settings) for name, wall in walls.items()}
    ratio = protocol.wall_chain_ratio_from_dataset(read(ratio_file, whole=True)) if with_ratio else None
    return studies, mis, subs, ratio


def _figure_makers(studies, mis, subs, settings) -> dict:
    from . import figures as figs

    return {
        "fig1": lambda: figs.fig1(studies["chain1"], settings), "fig2": lambda: figs.fig2(studies["chain2"], settings),
        "fig3": lambda: figs.fig3(mis, subs, settings), "fig4": lambda: figs.fig4(studies["chain1"], studies["chain2"]),
        "fig5": lambda: figs.fig5(studies["chain1"], studies["chain2"], settings),
        "fig6": lambda: figs.fig6(studies["chain1"], studies["chain2"], settings),
    }


#: What the forked drawing processes draw from (set by :func:`draw` just before it forks, so the
#: children inherit the data instead of receiving a pickled copy): (folder, makers, jobs).
_DRAW_JOB: tuple | None = None

#: The prefix of a job of :func:`draw` that is not a figure (its number in ``jobs`` follows).
_JOB = "job:"


def _draw_one(name: str) -> tuple[str, Any]:
    from . import figures as figs

    assert _DRAW_JOB is not None  # (set by _draw_all before the processes fork)
    out_dir, makers, jobs = _DRAW_JOB
    if name.startswith(_JOB):
        return name, jobs[int(name[len(_JOB):])]()
    return name, figs.save_figure(makers[name](), Path(out_dir), name)


def draw(out_dir: str | Path, studies, mis, subs, settings: Settings,
         progress: Callable[[str], None] | None = None, workers: int | None = None,
         extra: dict[str, Callable] | None = None, figures=FIGURE_NAMES,
         jobs: Sequence[Callable[[], object]] = (),
         job_done: Callable[[int, Any], None] | None = None) -> dict[str, Path]:
    """Draw Figs. 1-6 (PNG + PDF) into ``out_dir``; returns {name: png path}.

    Text layout makes drawing CPU-bound, so the figures are drawn by ``workers`` forked processes
    (default: one per usable core, at most six; sequentially where fork is unavailable or with
    one core). ``extra`` ({name: function returning a figure}, e.g. :func:`_fidelity_makers`) is
    drawn in the same processes, so that every figure shares the cores; ``progress(message)`` is
    called after each of Figs. 1-6 is written (not after the extra ones: :func:`count_steps`).
    ``figures`` names the ones of Figs. 1-6 to draw (default all). ``jobs`` (calls without
    arguments: writing the traces, numbers; each result, picklable, is passed to
    ``job_done(index, result)``) are shared out among the same processes after the figures,
    filling the cores as the figures end (sequentially: before the figures). Every job and figure
    runs even when one fails (a figure that cannot be drawn loses no data); the first error is
    then raised.
    """
    global _DRAW_JOB
    makers = {name: make for name, make in _figure_makers(studies, mis, subs, settings).items() if name in figures}
    makers.update(extra or {})
    order = [n for n in _DRAW_ORDER if n in makers] + [n for n in makers if n not in _DRAW_ORDER]
    names = order + [f"{_JOB}{i}" for i in range(len(jobs))]
    workers = min(len(FIGURE_NAMES), usable_cores()) if workers is None else workers
    drawn: dict[str, Path] = {}
    errors: list[BaseException] = []

    def done(name, result):
        if name.startswith(_JOB):
            if job_done is not None:
                job_done(int(name[len(_JOB):]), result)
            return
        drawn[name] = result
        if progress is not None and name in FIGURE_NAMES:
            progress(f"drew {name}")

    _DRAW_JOB = (out_dir, makers, list(jobs))
    try:
        if workers > 1 and "fork" in multiprocessing.get_all_start_methods():
            with forked_pool(workers) as pool:
                results = pool.imap_unordered(_draw_one, names)  # the jobs are handed out now
                while True:
                    try:
                        done(*next(results))
                    except StopIteration:
                        break
                    except Exception as exc:  # noqa: BLE001 - raised below, once the other jobs are done
                        errors.append(exc)
        else:
            for name in names[len(order):] + order:
                try:
                    done(*_draw_one(name))
                except Exception as exc:  # noqa: BLE001 - raised below, once the other jobs are done
                    errors.append(exc)
    finally:
        _DRAW_JOB = None
    if errors:
        raise errors[0]
    return {name: drawn[name] for name in makers}


def _draw_early(out_dir: str | Path, makers: dict[str, Callable]) -> Callable[..., dict[str, Path]]:
    """Start drawing ``makers`` in one process forked now (in this one where fork is unavailable).

    Returns ``finish(cancel=False)``: waits for the figures and returns {name: png path};
    ``cancel=True`` stops the process instead (after a failure elsewhere).
    """
    global _DRAW_JOB
    order = [n for n in _DRAW_ORDER if n in makers] + [n for n in makers if n not in _DRAW_ORDER]
    if usable_cores() < 2 or "fork" not in multiprocessing.get_all_start_methods():
        _DRAW_JOB = (out_dir, makers, [])
        try:
            drawn = dict(_draw_one(n) for n in order)
        finally:
            _DRAW_JOB = None
        return lambda cancel=False: {} if cancel else drawn
    _DRAW_JOB = (out_dir, makers, [])
    try:
        pool = forked_pool(1)
    finally:
        _DRAW_JOB = None
    pending = pool.map_async(_draw_one, order)

    def finish(cancel: bool = False) -> dict[str, Path]:
        if cancel:
            pool.terminate()
            pool.join()
            return {}
        drawn = dict(pending.get())
        pool.close()
        pool.join()
        return {n: drawn[n] for n in makers}

    return finish


def _figure_numbers(studies, mis, subs, settings) -> dict:
    """The numbers the figures show (spectral centroids, collapse quality, Fig. 3 changes)."""
    from .figures import figure_summary

    return figure_summary(studies["chain1"], studies["chain2"], mis, subs, settings)


def _write_summary(out: Path, summary: dict) -> None:
    from ..fileio import write_text

    write_text(out / "summary.json", json.dumps(_round(summary), indent=2, allow_nan=False, default=_json_default))


def redraw(out_dir: str | Path, progress: Callable[[str], None] | None = None,
           laws_figure: Callable[..., dict[str, Path]] | None = None) -> dict:
    """Redraw the figures and the report of an existing reproduction from its data/ (no simulation).

    ``progress(message)`` is called after loading the data, after each figure and after the
    report (:func:`count_steps` minus the simulations: 8 calls). ``laws_figure`` is what
    :func:`hertzchain.paper.early.start_laws_figure` returned when the caller started the laws
    figure before importing this module (default: started here). Returns the summary, with the
    elastic-limit check of the data under ``"elastic_limit"``.
    """
    from .early import start_laws_figure

    # Scheduling (CPU-bound on two cores): the figures that need no chain's pulse fit are drawn
    # by processes forked as soon as their data is in memory, on the core this one leaves idle:
    # Fig. 5 laws (summary.json) while the imports run, Figs. 3 and 3 lateral once the Fig. 3
    # traces, read first, are in, while this process reads the chains' traces and refits their
    # pulses; then two processes draw Figs. 1, 2, 4-6.
    early = [job for job in [laws_figure or start_laws_figure(out_dir)] if job]
    try:
        return _redraw(Path(out_dir), progress or (lambda msg: None), early)
    finally:
        for job in early:
            job(cancel=True)


def _redraw(out: Path, tick: Callable[[str], None], early: list) -> dict:
    from ..errors import ConfigError
    from .report import write_report

    from ..received import read_received

    try:  # a regular file of the folder only (hertzchain.received)
        summary = json.loads(read_received(out / "summary.json", out).decode("utf-8"))
    except (OSError, ValueError) as exc:
        raise ConfigError(str(out / "summary.json"), f"cannot read it ({exc})") from None
    where = str(out / "summary.json")
    raw_settings = check_settings(summary, where)  # every field of the right type, or the key named
    known = {k: v for k, v in raw_settings.items() if k in Settings.__dataclass_fields__}
    settings = Settings(**known, eps=raw_settings.get("eps_target") or PAPER["eps"],
                        elastic=is_conservative(raw_settings["law"]))
    laws = (summary.get("fidelity") or {}).get("laws") if isinstance(summary.get("fidelity"), dict) else None
    if laws is not None and check_laws(laws):
        raise ConfigError(where, f"is damaged: {check_laws(laws)}; rerun 'hertzchain reproduce' without --from-data")
    lateral = _lateral_files(out)
    if not early:  # not started early (one core, no fork): drawn here, or not at all without its numbers
        early += [_draw_early(out, makers) for makers in [_fidelity_makers(summary, {}, {})] if makers]

    def start_fig3(mis, subs):
        from . import figures as figs

        makers = {"fig3": lambda: figs.fig3(mis, subs, settings),
                  **_fidelity_makers({}, mis, lateral and (lambda: _load_lateral(lateral)))}
        early.append(_draw_early(out, makers))

    studies, mis, subs, _ = _load_data_checked(out, settings, start_fig3, ratio=False)
    summary["elastic_limit"] = elastic_limit_summary(studies, mis, subs)
    tick("read the data")
    # the report's numbers now, while the early processes still draw, not after every figure
    summary["figures"] = _figure_numbers(studies, mis, subs, settings)
    paths = draw(out, studies, mis, subs, settings, tick, figures=[n for n in FIGURE_NAMES if n != "fig3"])
    while early:
        drawn = early[0]()
        early.pop(0)
        paths.update(drawn)
        if "fig3" in drawn:
            tick("drew fig3")
    paths = {name: paths[name] for name in [*FIGURE_NAMES, *(n for n in paths if n not in FIGURE_NAMES)]}
    try:
        write_report(out, _round(summary), paths, summary["settings"])
    except (KeyError, TypeError, ValueError, AttributeError, IndexError) as exc:
        # The report reads the summary's numbers (comparison table, notes): a hand-edited or foreign
        # summary.json is named, not reported as a bug.
        raise ConfigError(where, f"is damaged: the report cannot read it ({type(exc).__name__}: {exc}); rerun "
                          "'hertzchain reproduce' without --from-data") from None
    tick("wrote the report")
    return summary


def reproduce(out_dir: str | Path, settings: Settings | None = None,
              progress: Callable[[str], None] | None = None, figures: bool = True) -> dict:
    """Run the whole paper and write figures, data, summary.json and the report into ``out_dir``.

    ``progress(message)`` is called after each simulation, each figure and the report
    (:func:`count_steps` calls). Returns the summary dict (also written, rounded to
    SUMMARY_DIGITS significant digits, to ``summary.json``).
    """
    settings = settings or Settings()
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    tick = progress or (lambda msg: None)
    # the engines of the later model kinds (the elastic ratio, lateral freedom) are compiled by a
    # forked process while this one calibrates the law and runs the aligned chains on its engine
    # (paper/ahead.py); each kind's runs wait for theirs and load them from the cache. The fork then
    # runs the elastic wall/chain ratio itself.
    ahead = CompileAhead(settings)
    variants = None

    try:
        studies = {"chain1": protocol.run_chain_study("chain1", settings, tick)}
        # where the model and the paper disagree: other contact laws (paper/fidelity.py), started now
        # in a forked process and shared with this one once its own runs are done. The fork inherits
        # what this process has compiled (the run's law's engine: chain 1's study ran it) and loads
        # the elastic engine from the cache the compiling fork filled, so that a cold
        # run compiles none of them twice, nor two processes one function at once (ahead.py); started
        # before chain 2's study, not after it, it is done about when this process's own runs are.
        ahead.wait("elastic")
        variants = fidelity.LawVariants(settings)
        studies["chain2"] = protocol.run_chain_study("chain2", settings, tick)
        ratio = ahead.wall_chain_ratio()  # run by the compiling fork once its kernels are compiled
        tick("wall/chain ratio")
        speed = protocol.run_speed_check(settings)
        for _ in range(10):
            tick("two-speed check")
        subs = protocol.run_substitutions(settings)
        for _ in range(3):
            tick("Fig. 3c: substitutions")
        ahead.wait("lateral")
        lateral, cost = fidelity.run_lateral_misalignment(settings, progress=tick)
        mis = protocol.run_misalignment(settings)
        for _ in range(6):
            tick("Fig. 3a-b: misaligned beads")
        law_rows = variants.finish(studies, tick)
    finally:
        ahead.close()
        if variants is not None:
            variants.cancel()
    t_sim = time.perf_counter() - t0

    writes = _trace_writes(out, studies, mis, subs, ratio, lateral)
    summary = build_summary(studies, ratio, speed, settings, {"simulation_s": t_sim})
    summary["elastic_limit"] = elastic_limit_summary(studies, mis, subs)
    summary["fidelity"] = {"laws": law_rows, "misalignment": None,
                           "tracks": {k: t.describe() for k, t in fidelity.TRACKS.items()},
                           "lateral_cost": cost}

    def numbers(misalignment: dict) -> None:
        summary["fidelity"]["misalignment"] = misalignment
        # the verdicts read the numbers as summary.json stores them (rounded), so they rebuild exactly
        summary["claims"] = build_claims(_round(summary))

    if figures:
        from .report import write_report

        # the traces (~50 files, ~4 CPU-s of HDF5) and Fig. 3's numbers (pulse fits, and SciPy's
        # peak finder: 0.4 s to import) are made by the drawing processes beside the figures: on
        # two cores this process writing the traces beside two drawing ones outlasted them
        fig_paths = draw(out, studies, mis, subs, settings, tick, extra=_fidelity_makers(summary, mis, lateral),
                         jobs=[partial(fidelity.misalignment_numbers, mis, lateral), *writes],
                         job_done=lambda i, result: numbers(result) if i == 0 else None)
        summary["figures"] = _figure_numbers(studies, mis, subs, settings)
        summary["timing"]["total_s"] = time.perf_counter() - t0
        write_report(out, _round(summary), fig_paths, settings.describe())
        tick("wrote the report")
    else:
        for write in writes:
            write()
        numbers(fidelity.misalignment_numbers(mis, lateral))
    summary["timing"]["total_s"] = time.perf_counter() - t0
    _write_summary(out, summary)
    return summary


def _fidelity_makers(summary: dict, mis: dict, lateral: dict | Callable[[], dict]) -> dict[str, Callable]:
    """The model-variant figures (claims.FIGURES) that the summary and data allow, for :func:`draw`.

    ``lateral`` is the lateral-freedom records or a function reading them: called in the drawing
    process, so that reading them overlaps the other figures.
    """
    makers: dict[str, Callable] = {}
    laws = (summary.get("fidelity") or {}).get("laws")
    if laws:
        eps = summary["settings"].get("eps_target") or PAPER["eps"]
        makers["fig5_laws"] = lambda: fidelity.fig_laws(laws, eps)
    if lateral and mis:
        makers["fig3_lateral"] = lambda: fidelity.fig3_lateral(mis, lateral() if callable(lateral) else lateral)
    return makers


def _lateral_files(out: Path) -> dict:
    """The lateral-freedom Fig. 3 records of a reproduction: {(track, bead, fraction): path}."""
    import re

    found = {}
    for p in sorted((out / "data").glob("fig3_lateral_*_bead*_e*.nc")):
        m = re.fullmatch(r"fig3_lateral_(\w+)_bead(\d+)_e([\d.]+)\.nc", p.name)
        if m:
            found[(m.group(1), int(m.group(2)), float(m.group(3)))] = p
    return found


def _load_lateral(files: dict) -> dict:
    """Read the records of :func:`_lateral_files` ({key: dataset}; the wall force is all Fig. 3 draws)."""
    return {key: load_trace(p, ("wall_force",)) for key, p in files.items()}


def _json_default(x):
    if isinstance(x, (np.floating, np.integer)):
        return x.item()
    if isinstance(x, float) and not math.isfinite(x):
        return None
    raise TypeError(f"not JSON serialisable: {type(x).__name__}")
