"""``hertzchain reproduce``: the paper as one command (runs, data, summary, figures, report)."""

from __future__ import annotations

import json
import math
import time
from pathlib import Path
from typing import Callable

import numpy as np

from .. import __version__, theory
from ..result import save as _save
from . import protocol
from .protocol import ChainStudy, Settings
from .values import PAPER

__all__ = ["reproduce", "redraw", "load_data", "draw", "count_runs", "build_summary"]


def count_runs(settings: Settings) -> int:
    """Number of simulations a reproduction makes (for the progress bar)."""
    n1 = PAPER["chain1"]["n_beads"] - PAPER["n0"] + 1
    n2 = PAPER["chain2"]["n_beads"] - PAPER["n0"] + 1
    return n1 + n2 + 6 + 3 + 1 + 10


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
    out = {"law": law.name}
    if law.name == "viscoelastic":
        out["A"] = law.A
    elif law.name == "dashpot":
        out["gamma"] = law.gamma
    return out


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


_SUB_TAGS = {"reference": "reference", "dq/q = +1": "dq_plus", "dq/q = -1": "dq_minus"}


def _save_data(out: Path, studies, mis, subs, ratio) -> None:
    """Every simulated trace, as single-precision compressed NetCDF (enough to redraw figures)."""
    data = out / "data"

    def save(ds, path):
        _save(ds, path, single_precision=True)

    for name, study in studies.items():
        for n, ds in study.wall.items():
            save(ds, data / f"{name}_truncated_{n:02d}.nc")
    for (bead, frac), ds in mis.items():
        save(ds, data / f"fig3_chain2_offset_bead{bead}_e{frac:.2f}.nc")
    for label, ds in subs.items():
        save(ds, data / f"fig3c_chain1_24_{_SUB_TAGS[label]}.nc")
    save(ratio["dataset"], data / "uniform16_elastic_wall_chain_ratio.nc")


def load_data(out_dir: str | Path, settings: Settings):
    """Read back the traces of a reproduction: (studies, misalignment, substitutions, ratio)."""
    from ..errors import ConfigError
    from ..result import load

    data = Path(out_dir) / "data"
    if not data.is_dir():
        raise ConfigError(str(data), "no data folder: run 'hertzchain reproduce' first")
    try:
        return _load_data(data, settings, load)
    except ConfigError:
        raise
    except (OSError, ValueError, KeyError, AttributeError, IndexError, TypeError, RuntimeError) as exc:
        # A trace that is readable NetCDF but lacks what the protocol needs (damaged, foreign)
        raise ConfigError(str(data), f"holds a damaged or foreign trace ({type(exc).__name__}: {exc}); "
                          "rerun 'hertzchain reproduce' without --from-data") from None


def _load_data(data: Path, settings: Settings, load):
    import re

    from ..errors import ConfigError

    def read(p: Path):
        if not p.is_file():
            raise ConfigError(str(p), "is missing: rerun 'hertzchain reproduce' without --from-data")
        try:
            return load(p)
        except Exception as exc:  # noqa: BLE001 - a damaged HDF5 file raises anything (RuntimeError, OSError, ...)
            raise ConfigError(str(p), f"is damaged or not a hertzchain result ({type(exc).__name__}: {exc})") from None

    studies = {}
    for name in ("chain1", "chain2"):
        wall = {int(re.search(r"_(\d+)\.nc$", p.name).group(1)): read(p)
                for p in sorted(data.glob(f"{name}_truncated_*.nc"))}
        if not wall:
            raise ConfigError(str(data), f"holds no {name} traces")
        studies[name] = protocol.study_from_datasets(name, wall, settings)
    mis = {}
    for p in sorted(data.glob("fig3_chain2_offset_bead*_e*.nc")):
        m = re.search(r"bead(\d+)_e([\d.]+)\.nc$", p.name)
        mis[(int(m.group(1)), float(m.group(2)))] = read(p)
    subs = {label: read(data / f"fig3c_chain1_24_{tag}.nc") for label, tag in _SUB_TAGS.items()}
    ratio = protocol.wall_chain_ratio_from_dataset(read(data / "uniform16_elastic_wall_chain_ratio.nc"))
    return studies, mis, subs, ratio


def draw(out_dir: str | Path, studies, mis, subs, settings: Settings) -> dict[str, Path]:
    """Draw Figs. 1-6 (PNG + PDF) into ``out_dir``; returns {name: png path}."""
    from . import figures as figs

    drawn = {
        "fig1": lambda: figs.fig1(studies["chain1"], settings), "fig2": lambda: figs.fig2(studies["chain2"], settings),
        "fig3": lambda: figs.fig3(mis, subs, settings), "fig4": lambda: figs.fig4(studies["chain1"], studies["chain2"]),
        "fig5": lambda: figs.fig5(studies["chain1"], studies["chain2"], settings),
        "fig6": lambda: figs.fig6(studies["chain1"], studies["chain2"], settings),
    }
    return {name: figs.save_figure(make(), Path(out_dir), name) for name, make in drawn.items()}


def _figure_numbers(studies, mis, subs, settings) -> dict:
    """The numbers the figures show (spectral centroids, collapse quality, Fig. 3 changes)."""
    from .figures import figure_summary

    return figure_summary(studies["chain1"], studies["chain2"], mis, subs, settings)


def redraw(out_dir: str | Path) -> dict:
    """Redraw the figures and the report of an existing reproduction from its data/ (no simulation)."""
    from ..errors import ConfigError
    from .report import write_report

    out = Path(out_dir)
    try:
        summary = json.loads((out / "summary.json").read_bytes().decode("utf-8"))
    except (OSError, ValueError) as exc:
        raise ConfigError(str(out / "summary.json"), f"cannot read it ({exc})") from None
    try:
        known = {k: v for k, v in summary["settings"].items() if k in Settings.__dataclass_fields__}
        settings = Settings(**known, eps=summary["settings"].get("eps_target") or PAPER["eps"],
                            elastic=summary["settings"]["law"] == "elastic")
    except (KeyError, TypeError, AttributeError, ValueError) as exc:
        raise ConfigError(str(out / "summary.json"), f"is not the summary of a reproduction: its 'settings' "
                          f"are missing or damaged ({type(exc).__name__}: {exc})") from None
    studies, mis, subs, _ = load_data(out, settings)
    paths = draw(out, studies, mis, subs, settings)
    summary["figures"] = _figure_numbers(studies, mis, subs, settings)
    write_report(out, summary, paths, summary["settings"])
    return summary


def reproduce(out_dir: str | Path, settings: Settings | None = None,
              progress: Callable[[str], None] | None = None, figures: bool = True) -> dict:
    """Run the whole paper and write figures, data, summary.json and the report into ``out_dir``.

    Returns the summary dict (also written to ``summary.json``).
    """
    settings = settings or Settings()
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    tick = progress or (lambda msg: None)
    studies = {name: protocol.run_chain_study(name, settings, tick) for name in ("chain1", "chain2")}
    mis = protocol.run_misalignment(settings)
    for _ in range(6):
        tick("Fig. 3a-b: misaligned beads")
    subs = protocol.run_substitutions(settings)
    for _ in range(3):
        tick("Fig. 3c: substitutions")
    ratio = protocol.run_wall_chain_ratio(settings)
    tick("wall/chain ratio")
    speed = protocol.run_speed_check(settings)
    for _ in range(10):
        tick("two-speed check")
    t_sim = time.perf_counter() - t0
    _save_data(out, studies, mis, subs, ratio)
    summary = build_summary(studies, ratio, speed, settings, {"simulation_s": t_sim})
    fig_paths: dict[str, Path] = {}
    if figures:
        from .report import write_report

        fig_paths = draw(out, studies, mis, subs, settings)
        summary["figures"] = _figure_numbers(studies, mis, subs, settings)
        summary["timing"]["total_s"] = time.perf_counter() - t0
        write_report(out, summary, fig_paths, settings.describe())
    summary["timing"]["total_s"] = time.perf_counter() - t0
    from ..fileio import write_text

    write_text(out / "summary.json", json.dumps(summary, indent=2, allow_nan=False, default=_json_default))
    return summary


def _json_default(x):
    if isinstance(x, (np.floating, np.integer)):
        return x.item()
    if isinstance(x, float) and not math.isfinite(x):
        return None
    raise TypeError(f"not JSON serialisable: {type(x).__name__}")
