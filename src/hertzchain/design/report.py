"""Design outputs: best.toml, design.json, history.csv, pareto.csv and design.html.

The best design is compared like for like: with the problem's own base configuration (``[base]``
as it stands, what the design starts from) and with a uniform chain of as many beads as the best
design, of the base chain's first diameter and material, all three run with the same striker,
wall, contact law and run settings (duration included) and scored as the search scored
candidates (robust scenarios included, summarised the same way), and with no chain at all
(``no_chain``: the striker straight onto the wall or body, ``chain.uniform.n = 0``; left out where
that would be a flat face on a flat face); the improvement is
(reference - best) / reference in percent (positive: the design transmits less).
"""

from __future__ import annotations

import base64
import datetime as _dt
import html
import io
import json
import math
from typing import Any

import numpy as np

from .objectives import OBJECTIVES
from .search import DesignResult

__all__ = ["write_report", "compare_with_references", "objective_label", "objective_signal", "headline_sentence", "REFERENCES"]


def _toml_ready(x: Any) -> Any:
    """Plain TOML values (no NumPy scalars, no None)."""
    if isinstance(x, dict):
        return {k: _toml_ready(v) for k, v in x.items() if v is not None}
    if isinstance(x, (list, tuple)):
        return [_toml_ready(v) for v in x]
    if isinstance(x, np.generic):
        return x.item()
    return x


#: The references of the comparison, after the best design.
REFERENCES = ("base", "uniform", "no_chain")


def _reference_configs(base: dict, best_cfg: dict) -> dict[str, dict]:
    """The best design, the base configuration and the uniform chain (see the module docstring)."""
    from ..config import build_chain, parse_config

    base_chain = build_chain(parse_config(base))
    n_best = build_chain(parse_config(best_cfg)).n_beads
    common = {k: v for k, v in best_cfg.items() if k != "chain"}
    uniform = {"uniform": {"n": n_best, "diameter_mm": float(f"{base_chain.diameters[0] * 1e3:.12g}")},
               "material": base_chain.materials[0].name}
    refs = {"best": best_cfg, "base": base, "uniform": {**common, "chain": uniform}}
    # no chain at all: the striker straight onto the wall or body (what the chain buys), where that
    # is a Hertz contact (a flat striker on a flat body face is not: then left out)
    from ..config import build_model
    from ..errors import ConfigError

    none = {**common, "chain": {**uniform, "uniform": {**uniform["uniform"], "n": 0}}}
    try:
        build_model(parse_config(none))
    except ConfigError:
        return refs
    return {**refs, "no_chain": none}


def objective_label(problem) -> str:
    """How the objective is scored: ``peak_wall_force``, or with ``[design.robust]`` the statistic
    over the scenarios (``peak_wall_force, mean + 2 sigma over 6 scenarios``).

    Parameters
    ----------
    problem : DesignProblem
        The design.

    Returns
    -------
    str
        The label (what the printed and written objective values are).
    """
    rob = problem.section.robust
    if rob is None:
        return problem.objective_name
    n = len(rob.velocities or [None]) * rob.draws
    stat = {"worst": "worst case", "mean": "mean", "mean+ksigma": f"mean + {rob.k:g} sigma"}[rob.statistic]
    return f"{problem.objective_name}, {stat} over {n} scenarios" if n > 1 else problem.objective_name


def compare_with_references(result: DesignResult) -> tuple[dict, Any]:
    """Objectives of the best design, the base configuration and the uniform chain, as the search
    scored them.

    The three chains are evaluated like candidates (in every scenario of ``[design.robust]``,
    summarised the same way), so the improvement compares like with like; their nominal wall
    pulses come from one more batched call.

    Parameters
    ----------
    result : DesignResult
        A finished search.

    Returns
    -------
    (dict, xarray.Dataset)
        ``{"best" | "base" | "uniform": {name: value [SI] (None when the pulse does not reach
        the wall within the run), "n_beads", "length_mm", "feasible", "breaks"}, "improvement_percent":
        {"base" | "uniform": {name: (reference - best) / reference [%]}}}`` (``breaks``: the
        design's constraints that chain breaks, in words, empty when it meets them all; a reference
        that breaks them is no alternative the search could have chosen) and the nominal batch
        result (the records of the three, members in that order).
    """
    import warnings

    from ..config import build_model, build_probes, parse_config
    from ..errors import ElasticLimitWarning, PulseNotReachedWarning
    from ..runs.batch import simulate_batch
    from ..probes import Probes
    from .constraints import Constraints, broken_geometry, broken_run, geometric_violation, run_violation
    from .objectives import Evaluator

    prob = result.problem
    sec = prob.section
    window = None if sec.window is None else tuple(sec.window)
    cfgs = _reference_configs(prob.base, result.best["config"])
    # No geometric rejection here: the references get values even where they break the design's
    # constraints (the uniform chain may be longer or heavier); feasibility is reported beside them.
    scorer = Evaluator(prob.objectives, Constraints(pulse_at_wall=sec.constraints.pulse_at_wall), sec.robust, window)
    evs = scorer.evaluate(list(cfgs), list(cfgs.values()))
    runs = [parse_config(c) for c in cfgs.values()]
    models = [build_model(r) for r in runs]
    # every contact's force where an objective reads the largest of them (design.html plots it)
    contacts = None if {"peak_contact_force", "max_force_over_yield"} & set(prob.objectives) else ()
    probes = Probes(sample_interval=build_probes(runs[0]).sample_interval, contacts=contacts)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ElasticLimitWarning)
        # a reference whose pulse misses the wall within the run gets no value (pulse_at_wall below)
        warnings.simplefilter("ignore", PulseNotReachedWarning)
        ds = simulate_batch(models, runs[0].run.duration, probes, dt=runs[0].run.dt,
                            steps_per_radian=runs[0].run.steps_per_radian)
    out: dict[str, Any] = {}
    for name, ev in zip(cfgs, evs):
        # A chain whose pulse does not reach the wall within the run has no comparable value.
        ok = bool(ev.metrics["pulse_at_wall"])
        out[name] = {n: ev.objectives[n] if ok else None for n in prob.objectives}
        plastic = {k: ev.metrics[f"{k}_worst"] for k in ("plastic_work", "residual_overlap_max")
                   if f"{k}_worst" in ev.metrics}
        feasible = (ev.feasible and geometric_violation(sec.constraints, ev.metrics) == 0
                    and run_violation(sec.constraints, ev.metrics["force_over_yield"], True, **plastic) == 0)
        breaks = broken_geometry(sec.constraints, ev.metrics) + broken_run(sec.constraints, ev.metrics)
        if not feasible and not breaks:  # no objective value to score, or its energy balance failed
            breaks = ["its run gives no valid objective value"]
        out[name].update(n_beads=ev.metrics["n_beads"], length_mm=ev.metrics["length_mm"], pulse_at_wall=ok,
                         feasible=bool(feasible), breaks=breaks)
    out["improvement_percent"] = {
        ref: {n: (100.0 * (out[ref][n] - out["best"][n]) / out[ref][n]
                  if out[ref][n] and out["best"][n] is not None else None) for n in prob.objectives}
        for ref in REFERENCES if ref in out}
    return out, ds


def _comparison(result: DesignResult) -> tuple[dict, Any]:
    """:func:`compare_with_references`, or what it gave the same finished search before (a replay into
    the same folder: read back from ``comparison.npz``, no engine run; :mod:`.saved_comparison`)."""
    from .saved_comparison import comparison_key, read_comparison, write_comparison

    key = comparison_key(result)
    names = list(result.problem.objectives)
    saved = read_comparison(result.out_dir, key, names)
    if saved is not None:
        try:  # what the report reads of the records (a file whose layout lacks one is run again)
            _ = [saved[1]["diameter"], *(objective_signal(n, saved[1]) for n in [*names, "peak_wall_force"])]
            return saved
        except (KeyError, ValueError, IndexError, TypeError):
            pass
    comparison, ds = compare_with_references(result)
    write_comparison(result.out_dir, key, comparison, ds)
    return comparison, ds


def _measured_against(prob, best_cfg: dict) -> dict:
    """Which body the candidates were measured against: the base's wall (or protected body), the
    best candidate's, and the design variables that change it (``wall.*``)."""
    from ..config import build_model, parse_config
    from .body import measured_against

    varying = [g for g in prob.space.groups if g.startswith("wall.")]
    return {"base": measured_against(build_model(parse_config(prob.base))),
            "best": measured_against(build_model(parse_config(best_cfg))), "varied_by": varying}


def _measured_sentence(m: dict) -> str:
    if not m["varied_by"]:
        return f"Every candidate is measured against {m['base']}."
    return (f"Candidates are measured against the body the design variables {', '.join(m['varied_by'])} give; "
            f"the best against {m['best']}.")


def _fidelity_info(prob) -> dict:
    """design.json's ``search_fidelity``: how the search ran candidates (the best are reported at full accuracy)."""
    from .problem import search_fidelity

    fid = search_fidelity(prob)
    return {"name": fid.name, "steps_per_radian": fid.steps_per_radian, "coarse_sampling": fid.coarse_sampling,
            "verify_top": prob.section.verify_top if fid.name != "full" else None}


def _history_frame(result: DesignResult):
    import pandas as pd

    rows = []
    for r in result.history:
        rows.append({k: (json.dumps(v) if isinstance(v, (list, dict)) else v) for k, v in r.items() if k != "x"})
    return pd.DataFrame(rows)


def _json_ready(x: Any) -> Any:
    """JSON values: NaN (no value: an infeasible or unsimulated candidate) becomes null."""
    if isinstance(x, dict):
        return {k: _json_ready(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_json_ready(v) for v in x]
    if isinstance(x, (float, np.floating)):
        return None if not math.isfinite(x) else float(x)
    if isinstance(x, np.generic):
        return x.item()
    return x


def _png(fig) -> str:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110, bbox_inches="tight")
    return base64.b64encode(buf.getvalue()).decode()


def _figures(result: DesignResult, comparison: dict, ds) -> list[tuple[str, str]]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Circle

    names = result.problem.objectives
    obj = names[0]
    unit = OBJECTIVES[obj][0]
    figs = []
    runs = np.cumsum([r["engine_runs"] for r in result.history])
    vals = np.array([r[obj] if r["feasible"] else np.nan for r in result.history], float)
    fig, ax = plt.subplots(figsize=(7, 3.6))
    ax.plot(runs, vals, ".", ms=3, color="0.6", label="feasible candidates")
    best_so_far = np.fmin.accumulate(np.where(np.isnan(vals), np.inf, vals))
    ax.step(runs, np.where(np.isinf(best_so_far), np.nan, best_so_far), where="post", color="C0", label="best so far")
    for ref, style in (("base", "C3--"), ("uniform", "C2:")):
        if comparison[ref][obj] is not None:
            ax.axhline(comparison[ref][obj], color=style[:2], ls=style[2:],
                       label=f"{ref} ({comparison[ref][obj]:.4g} {unit})"
                       + (", breaks the constraints" if comparison[ref]["breaks"] else ""))
    ax.set_xlabel("engine runs")
    ax.set_ylabel(f"{obj} [{unit}]")
    ax.legend(fontsize=8)
    ax.set_title("convergence")
    figs.append(("Convergence", _png(fig)))
    plt.close(fig)

    if len(names) > 1:
        fig, ax = plt.subplots(figsize=(5, 4))
        feas = [r for r in result.history if r["feasible"]]
        ax.plot([r[names[0]] for r in feas], [r[names[1]] for r in feas], ".", ms=3, color="0.6", label="feasible")
        ax.plot([r[names[0]] for r in result.pareto], [r[names[1]] for r in result.pareto], "o-", color="C0",
                label="Pareto front")
        ax.set_xlabel(f"{names[0]} [{OBJECTIVES[names[0]][0]}]")
        ax.set_ylabel(f"{names[1]} [{OBJECTIVES[names[1]][0]}]")
        ax.legend(fontsize=8)
        figs.append(("Pareto front", _png(fig)))
        plt.close(fig)

    labels = ["best", *(r for r in REFERENCES if r in comparison)]
    diam = ds["diameter"].values * 1e3
    length = max(float(np.nansum(d)) for d in diam)
    fig, ax = plt.subplots(figsize=(9, 3.2))
    for row, (label, d) in enumerate(zip(labels, diam)):
        d = d[np.isfinite(d)]
        x = 0.0
        y = -row * 40.0
        for phi in d:
            ax.add_patch(Circle((x + phi / 2, y), phi / 2, fc="C0" if label == "best" else "0.75", ec="k", lw=0.4))
            x += phi
        ax.text(-8, y, label, ha="right", va="center", fontsize=9)
    ax.set_xlim(-60, length + 10)
    ax.set_ylim(-40 * len(labels) + 20, 20)
    ax.set_aspect("equal")
    ax.set_xlabel("position along the chain [mm] (impact end at 0, wall at the right end of each chain)")
    ax.set_yticks([])
    figs.append(("Chains to scale", _png(fig)))
    plt.close(fig)

    # What each objective reads (the body's force for peak_body_force, not the face's), then the
    # wall force too when no objective reads it: the pulse the chain delivers to what it ends on.
    drawn = []
    for name in names:
        signal = objective_signal(name, ds)
        if signal[0] not in [d[0] for d in drawn]:
            note = " (Q_F integrates its front, to T + tau of the cos^6 fit)" if name == "front_momentum_at_wall" else ""
            drawn.append((*signal, f"{name}: the {signal[0].split(' [')[0]}{note}"))
    if not any(d[0] == "force on the wall [N]" for d in drawn):
        drawn.append((*objective_signal("peak_wall_force", ds), "The force on the wall (or the body's face), for reference"))
    for ylabel, xlabel, x, y, title in drawn:
        fig, ax = plt.subplots(figsize=(7, 3.6))
        marker = "o-" if xlabel.startswith("contact") else "-"
        for i, label in enumerate(labels):
            bad = "" if label == "best" or not comparison[label]["breaks"] else " (breaks the constraints)"
            ax.plot(x, y[i], marker, ms=3, lw=1.4 if label == "best" else 1.0, label=label + bad)
        ax.set_xlabel(xlabel)
        ax.set_ylabel(ylabel)
        ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0))  # beside the axes: clear of the curves
        figs.append((title, _png(fig)))
        plt.close(fig)
    return figs


def objective_signal(name: str, ds) -> tuple[str, str, np.ndarray, np.ndarray]:
    """The record an objective is read from, for each chain of the comparison (design.html plots it).

    Parameters
    ----------
    name : str
        An objective of :data:`~hertzchain.design.objectives.OBJECTIVES`.
    ds : xarray.Dataset
        The nominal batch of :func:`compare_with_references` (members: best, base, uniform).

    Returns
    -------
    (str, str, numpy.ndarray, numpy.ndarray)
        What is drawn (its label with unit), the x axis label, x [ms, or contact numbers for
        ``residual_overlap_max``] and y (member, x) in the label's unit, SI: the objective is the
        largest y of a member (its last for ``plastic_work``; the cos^6 fit's front integral of
        the wall force for ``front_momentum_at_wall``).
    """
    t = ds["time"].values * 1e3
    n_beads = ds["n_beads"].values.astype(int)
    if name in ("peak_body_force", "peak_body_acceleration"):
        var = {"peak_body_force": ("body_force", "N"), "peak_body_acceleration": ("body_acceleration", "m s-2")}[name]
        return f"|{var[0]}| of the protected body [{var[1]}]", "time [ms]", t, np.abs(ds[var[0]].values)
    if name == "energy_to_body":
        return "energy delivered to the protected body [J]", "time [ms]", t, ds["body_energy"].values
    if name == "energy_at_wall":  # (2/5) F^(5/3) / kappa^(2/3) in the bead N - wall contact (paper eq. 1)
        kappa = ds["kappa"].values[np.arange(n_beads.size), n_beads]
        f = np.maximum(ds["wall_force"].values, 0.0)
        return ("elastic energy in the bead N - wall contact [J]", "time [ms]", t,
                0.4 * f ** (5.0 / 3.0) / kappa[:, None] ** (2.0 / 3.0))
    if name in ("peak_contact_force", "max_force_over_yield"):
        force = ds["contact_force"].values  # (member, time, contact): every contact recorded
        if name == "peak_contact_force":
            return "largest force of any contact [N]", "time [ms]", t, np.nanmax(force, axis=2)
        fy = ds["yield_force"].sel(contact_all=ds["contact"].values).values  # (member, contact)
        return ("largest F / F_Y of any contact [1]", "time [ms]", t, np.nanmax(force / fy[:, None, :], axis=2))
    # without the elastoplastic law no work is plastic and no contact keeps a dent (member_metrics: 0)
    if name == "plastic_work":
        work = ds["plastic_work"].values if "plastic_work" in ds else np.zeros((n_beads.size, t.size))
        return "plastic work done in all contacts [J]", "time [ms]", t, np.nan_to_num(work)
    if name == "residual_overlap_max":
        x = ds["contact_all"].values
        dent = ds["residual_overlap"].values if "residual_overlap" in ds else np.zeros((n_beads.size, x.size))
        return "permanent overlap of each contact [m]", "contact (0 = striker - bead 1)", x, np.nan_to_num(dent)
    return "force on the wall [N]", "time [ms]", t, ds["wall_force"].values


def _num(v: float | None, fmt: str, suffix: str = "") -> str:
    return "pulse not at the wall within the run" if v is None else f"{v:{fmt}}{suffix}"


def headline_sentence(info: dict) -> str:
    """The design's headline: the best objective and how much lower it is than each reference,
    a reference that breaks the design's constraints said to (it is no alternative the search could
    have chosen).

    Parameters
    ----------
    info : dict
        :func:`write_report`'s content of design.json.

    Returns
    -------
    str
        E.g. ``"Best peak_body_force: 41.2 N; 12.3 % lower than the base configuration, 30.1 % lower
        than a uniform chain of 8 beads (which breaks the constraints: design.constraints.max_length_mm
        = 150 (it has 208))."``
    """
    cmp, units = info["comparison"], info["units"]
    value = info["best"]["objective"]
    shown = (f"{value:.6g} {units[info['objectives'][0]]}" if not isinstance(value, dict)
             else ", ".join(f"{k} {v:.6g} {units[k]}" for k, v in value.items()))
    parts = []
    refs = (("base", "the base configuration"), ("uniform", f"a uniform chain of {cmp['uniform']['n_beads']} beads"),
            ("no_chain", "no chain (the striker straight onto the wall or body)"))
    for ref, words in refs:
        if ref not in cmp:  # no_chain is left out where it is no Hertz contact
            continue
        imp = cmp["improvement_percent"][ref]
        if all(v is None for v in imp.values()):
            text = f"no comparison with {words} (its pulse does not reach the wall within the run)"
        else:
            text = ", ".join("n/a" if v is None else f"{abs(v):.1f} % {'lower' if v >= 0 else 'higher'}"
                             for v in imp.values()) + f" than {words}"
        if cmp[ref]["breaks"]:
            text += f" (which breaks the constraints: {'; '.join(cmp[ref]['breaks'])})"
        parts.append(text)
    infeasible = "" if info["best"]["feasible"] else " No candidate met every constraint: this best is the least infeasible."
    return f"Best {info['objective_label']}: {shown}; {'; '.join(parts)}.{infeasible}"


def _html(result: DesignResult, info: dict, figs: list[tuple[str, str]]) -> str:
    cmp = info["comparison"]
    names = result.problem.objectives
    rows = ""
    for ref in ("best", *(r for r in REFERENCES if r in cmp)):
        cells = "".join(f"<td>{_num(cmp[ref][n], '.5g')}</td>" for n in names)
        imp = "" if ref == "best" else "; ".join(_num(cmp["improvement_percent"][ref][n], "+.2f", " %") for n in names)
        if ref != "best" and cmp[ref]["breaks"]:
            imp += " (against a chain that breaks the constraints)"
        ok = "yes" if cmp[ref]["feasible"] else f"<b>no</b>: breaks {html.escape('; '.join(cmp[ref]['breaks']))}"
        rows += (f"<tr><td>{ref}</td><td>{cmp[ref]['n_beads']}</td><td>{cmp[ref]['length_mm']:.1f}</td><td>{ok}</td>"
                 f"{cells}<td>{imp}</td></tr>")
    heads = "".join(f"<th>{n} [{OBJECTIVES[n][0]}]</th>" for n in names)
    variables = "".join(f"<tr><td><code>{html.escape(k)}</code></td><td>{html.escape(json.dumps(v))}</td></tr>"
                        for k, v in info["best"]["variables"].items())
    images = "".join(f"<h2>{html.escape(t)}</h2><img src='data:image/png;base64,{b}'/>" for t, b in figs)
    robust = "" if info["robust"] is None else (f", every chain scored over the same robust scenarios "
                                                f"({html.escape(info['objective_label'])})")
    feasible = "" if info["best"]["feasible"] else "<p><b>No candidate met every constraint; this is the least infeasible.</b></p>"
    headline = f"<p id='headline'>{html.escape(headline_sentence(info))}</p>"
    return f"""<!DOCTYPE html><html><head><meta charset="utf-8"><title>hertzchain design</title>
<style>body{{font-family:sans-serif;max-width:60em;margin:auto}} td,th{{padding:2px 8px;border-bottom:1px solid #ddd}}</style>
</head><body><h1>hertzchain design: {html.escape(info['objective_label'])}</h1>{feasible}{headline}
<p>{info['n_evaluations']} engine runs in {info['generations']} engine calls, {info['elapsed_s']:.1f} s
({info['evaluations_per_s']:.0f} runs/s), seed {info['seed']}. Improvement = (reference - best) / reference{robust}.
{html.escape(_measured_sentence(info['measured_against']))}</p>
<table><tr><th>chain</th><th>beads</th><th>length [mm]</th><th>meets the constraints</th>{heads}<th>improvement of the best</th></tr>{rows}</table>
<h2>Best design</h2><table>{variables}</table>{images}</body></html>"""


def write_report(result: DesignResult, figures: bool = True) -> dict:
    """Write the design outputs into ``result.out_dir`` (each file atomically).

    Parameters
    ----------
    result : DesignResult
        A finished search (:func:`hertzchain.run_design`).
    figures : bool
        Also write ``design.html`` (convergence, front, chains to scale, wall pulses).

    Returns
    -------
    dict
        The content of ``design.json``: ``best: {objective, variables, feasible, metrics}``,
        ``n_evaluations``, ``objective_name``, ``objective_label`` (with ``[design.robust]``: the
        statistic over the scenarios, e.g. ``peak_wall_force, mean + 2 sigma over 6 scenarios``),
        ``objectives``, ``units``, ``comparison`` (the base configuration and the uniform chain
        of as many beads, improvement in percent), ``generations``, ``elapsed_s``,
        ``evaluations_per_s``, ``seed``, ``budget``, ``pareto`` (several objectives), ``hash``,
        ``search_fidelity`` (``name``: ``"search"`` or ``"full"``, ``steps_per_radian`` and
        ``coarse_sampling`` of the search runs, ``verify_top``), ``measured_against`` (the wall or
        protected body every candidate ends on, in words: ``base``, ``best`` and the design
        variables ``varied_by`` that change it).
    """
    import tomli_w

    from .. import __version__
    from ..fileio import write_text

    out = result.out_dir
    prob = result.problem
    if result.best is None:
        raise ValueError("the search evaluated no candidate")
    comparison, ds = _comparison(result)
    info = {
        "objective_name": prob.objective_name,
        "objective_label": objective_label(prob),
        "objectives": prob.objectives,
        "units": {n: OBJECTIVES[n][0] for n in prob.objectives},
        "best": {k: result.best[k] for k in ("objective", "variables", "feasible", "metrics")},
        "n_evaluations": int(result.n_evaluations),
        "budget": prob.section.budget,
        "generations": result.generations,
        "seed": prob.section.seed,
        "elapsed_s": result.elapsed_s,
        "evaluations_per_s": result.n_evaluations / result.elapsed_s if result.elapsed_s > 0 else math.nan,
        "robust": None if prob.section.robust is None else prob.section.robust.model_dump(mode="json"),
        "search_fidelity": _fidelity_info(prob),
        "comparison": comparison,
        "measured_against": _measured_against(prob, result.best["config"]),
        "hash": prob.hash,
        "hertzchain_version": __version__,
        "created_utc": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
    }
    if len(prob.objectives) > 1:
        info["pareto"] = [{"objectives": {n: r[n] for n in prob.objectives},
                           "variables": {g: r[g] for g in prob.space.groups}} for r in result.pareto]
    header = (f"# Best design found by hertzchain design ({info['objective_label']} = "
              f"{json.dumps(_json_ready(info['best']['objective']))}); run it with: hertzchain run best.toml --out best.nc\n")
    write_text(out / "best.toml", header + tomli_w.dumps(_toml_ready(result.best["config"])))
    write_text(out / "design.json", json.dumps(_json_ready(info), indent=2))
    df = _history_frame(result)
    write_text(out / "history.csv", df.to_csv(index=False))
    if len(prob.objectives) > 1:
        keep = ["evaluation", "generation", *prob.space.groups, *prob.objectives, *[c for c in (
            "min_diameter_mm", "length_mm", "mass_kg", "n_beads", "force_over_yield", "plastic_work_worst",
            "residual_overlap_max_worst") if c in df]]
        front = df[df["evaluation"].isin([r["evaluation"] for r in result.pareto])][keep]
        write_text(out / "pareto.csv", front.to_csv(index=False))
    if figures:
        write_text(out / "design.html", _html(result, info, _figures(result, comparison, ds)))
    return info
