"""The reproduction report: ``report.md`` and a standalone ``report.html``.

:func:`write_report` turns the summary of a reproduction (the dict that
:mod:`hertzchain.paper.reproduce` writes to ``summary.json``) and the figure files into

- a table of simulated against published values with their relative difference and a verdict
  (error bars where the paper gives them: q, Q_fit; tolerances elsewhere);
- two sentences per figure: what it shows, and whether it agrees with the paper, written from
  the numbers (e.g. "Q_fit = 1.021 +- 0.001 lies inside the paper's error bar 1.025 +- 0.016");
- the two-speed check (the normalised results do not depend on the striker speed);
- per-bead tables of the wall pulse and the exact parameters of the run.

The HTML file embeds the figures as base64 PNG and has its CSS inline: it opens anywhere with no
other file; MathJax (loaded from its CDN) typesets the formulas, which read as TeX source offline.
Formulas are written as ASCII in the notes (``F_m``, ``tau``, ``Q^(n-n')``) and turned into TeX
(``$F_m$``, ``$\\tau$``) for both documents; figures are shown at one scale (their size in
inches). Both documents are generated from one list of blocks, so they always say the same.

Summary keys read (missing ones are skipped, never fatal): ``chain1``/``chain2`` {q, q_std,
Q_theory, Q_fit, Q_fit_err, beads, peak_force, duration, time_of_flight, front_momentum,
tail_momentum, [diameter_mm], [law]}, ``eps``, ``eps_err``, ``wall_to_chain_force_ratio``,
``wall_to_chain_duration_ratio``, ``yield_force``, ``yield_overlap``, [``max_force_over_yield``],
``speed_check`` {velocities, max_peak_norm_deviation, max_duration_norm_deviation}, ``paper``
(same keys, published values; default :data:`~hertzchain.paper.values.PAPER`), ``timing``,
[``hertzchain_version``], and [``figures``], the output of
:func:`hertzchain.paper.figures.figure_summary` (spectral centroids, Fig. 3 effects, collapse
quality), which makes the notes of Figs. 1-4 quantitative. All values in SI units.
"""

from __future__ import annotations

import base64
import html
import math
import os
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from .. import theory
from .values import PAPER

__all__ = ["Row", "comparison_rows", "figure_notes", "speed_sentence", "write_report", "FIGURE_TITLES"]

#: Title of each figure in the report (the paper's numbering).
FIGURE_TITLES = {
    "fig1": "Fig. 1 - pulse evolution in chain 1 (q1 = 5.60 %)",
    "fig2": "Fig. 2 - pulse evolution in chain 2 (q2 = 8.27 %)",
    "fig3": "Fig. 3 - misalignment and local changes of the tapering",
    "fig4": "Fig. 4 - self-similar collapse of the front pulse",
    "fig5": "Fig. 5 - diameters, peak force, duration and momenta along the chains",
    "fig6": "Fig. 6 - time of flight and pulse velocity along the chains",
}

CHAINS = ("chain1", "chain2")


# ------------------------------------------------------------------------------------------
# number formatting
# ------------------------------------------------------------------------------------------
def _num(x: Any) -> float | None:
    """A finite float, or None (missing, None, NaN, inf, not a number)."""
    try:
        v = float(x)
    except (TypeError, ValueError):
        return None
    return v if math.isfinite(v) else None


def _f(x: Any, fmt: str = ".3f", scale: float = 1.0, unit: str = "") -> str:
    v = _num(x)
    if v is None:
        return "n/a"
    return f"{v * scale:{fmt}}" + (f" {unit}" if unit else "")


def _pm(x: Any, err: Any, fmt: str = ".3f", scale: float = 1.0, unit: str = "") -> str:
    v, e = _num(x), _num(err)
    if v is None:
        return "n/a"
    s = f"{v * scale:{fmt}}" + (f" ± {e * scale:{fmt}}" if e is not None else "")
    return s + (f" {unit}" if unit else "")


def _rel(sim: Any, ref: Any) -> float | None:
    s, r = _num(sim), _num(ref)
    if s is None or r is None or r == 0:
        return None
    return (s - r) / r


def _pct(x: float | None, fmt: str = "+.2f") -> str:
    return "n/a" if x is None else f"{100 * x:{fmt}} %"


# ------------------------------------------------------------------------------------------
# comparison table
# ------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Row:
    """One line of the comparison table (strings ready to print, ``rel`` as a fraction)."""

    quantity: str
    simulated: str
    paper: str
    rel: float | None
    verdict: str


def _verdict_tol(rel: float | None, tol: float, note: str = "") -> str:
    if rel is None:
        return "n/a"
    word = f"agrees within {100 * tol:g} %" if abs(rel) <= tol else f"differs by {100 * rel:+.1f} %"
    return word + (f" ({note})" if note else "")


def _verdict_bar(sim: Any, sim_err: Any, ref: Any, ref_err: Any) -> str:
    s, r, re_ = _num(sim), _num(ref), _num(ref_err)
    if s is None or r is None or re_ is None or re_ <= 0:
        return "n/a"
    k = abs(s - r) / re_
    where = "inside" if k <= 1 else "outside"
    return f"{where} the paper's error bar ({k:.2f} σ)"


def _paper(summary: dict) -> dict:
    paper = dict(PAPER)
    paper.update(summary.get("paper") or {})
    return paper


def _eps_theory(settings_desc: dict | None) -> float:
    """eps of the closed-form predictions: the run's calibrated target, or 1 for elastic runs."""
    eps = _num((settings_desc or {}).get("eps_target"))
    return eps if eps is not None else 1.0


def comparison_rows(summary: dict, settings_desc: dict | None = None) -> list[Row]:
    """Simulated against published values, with relative differences and verdicts.

    Rows: q and its standard deviation, Q_fit +- error, Q_theory (both chains); eps measured back
    in the uniform part; the wall/chain peak-force and duration ratios; the yield force and
    overlap of 26 mm beads; and, when present, the largest contact force over its yield force.
    """
    paper = _paper(summary)
    eps_th = _eps_theory(settings_desc)
    rows: list[Row] = []
    for chain in CHAINS:
        sim, ref = summary.get(chain) or {}, paper.get(chain) or {}
        k = chain[-1]
        r = _rel(sim.get("q"), ref.get("q"))
        rows.append(Row(f"chain {k}: tapering factor q{k}", _f(sim.get("q"), ".2f", 100, "%"),
                        _f(ref.get("q"), ".2f", 100, "%"), r, _verdict_tol(r, 0.01)))
        r = _rel(sim.get("q_std"), ref.get("q_std"))
        rows.append(Row(f"chain {k}: standard deviation of q{k}", _f(sim.get("q_std"), ".2f", 100, "%"),
                        _f(ref.get("q_std"), ".2f", 100, "%"), r, _verdict_tol(r, 0.02)))
        rows.append(Row(f"chain {k}: Q{k} (fit of v_n = Q^(n-n') v_n')",
                        _pm(sim.get("Q_fit"), sim.get("Q_fit_err")), _pm(ref.get("Q_fit"), ref.get("Q_fit_err")),
                        _rel(sim.get("Q_fit"), ref.get("Q_fit")),
                        _verdict_bar(sim.get("Q_fit"), sim.get("Q_fit_err"), ref.get("Q_fit"), ref.get("Q_fit_err"))))
        r = _rel(sim.get("Q_theory"), ref.get("Q_theory"))
        note = f"eq. 8 with eps = {eps_th:g}" + ("" if abs(eps_th - paper["eps"]) < 1e-9
                                                 else f"; the paper's value uses eps = {paper['eps']:g}")
        rows.append(Row(f"chain {k}: Q{k}^th (eq. 8)", _f(sim.get("Q_theory")), _f(ref.get("Q_theory")), r,
                        _verdict_tol(r, 0.005, note)))
    r = _rel(summary.get("eps"), paper.get("eps"))
    elastic = _num((settings_desc or {}).get("eps_target")) is None and (settings_desc or {}).get("law") == "elastic"
    rows.append(Row("eps measured back in the uniform part, (F_m^(n+1)/F_m^n)^(5/6)",
                    _pm(summary.get("eps"), summary.get("eps_err"), ".4f"), _f(paper.get("eps"), ".3f"), r,
                    "elastic run: eps = 1 expected" if elastic else _verdict_tol(r, 0.002)))
    for key, label in (("wall_to_chain_force_ratio", "wall/chain peak-force ratio F_m^wall / F_m^chain"),
                       ("wall_to_chain_duration_ratio", "wall/chain duration ratio tau_wall / tau_chain")):
        r = _rel(summary.get(key), paper.get(key))
        rows.append(Row(label, _f(summary.get(key)), _f(paper.get(key), ".2f"), r,
                        _verdict_tol(r, 0.05, "the paper's stated accuracy")))
    r = _rel(summary.get("yield_force"), paper.get("yield_force"))
    rows.append(Row("yield force F_Y of two 26 mm beads", _f(summary.get("yield_force"), ".0f", 1, "N"),
                    _f(paper.get("yield_force"), ".0f", 1, "N"), r, _verdict_tol(r, 0.05, "paper rounds")))
    r = _rel(summary.get("yield_overlap"), paper.get("yield_overlap"))
    rows.append(Row("yield overlap delta_Y of two 26 mm beads", _f(summary.get("yield_overlap"), ".1f", 1e6, "µm"),
                    _f(paper.get("yield_overlap"), ".0f", 1e6, "µm"), r,
                    _verdict_tol(r, 0.05, "paper gives 2 digits")))
    if _num(summary.get("max_force_over_yield")) is not None:
        m = float(summary["max_force_over_yield"])
        rows.append(Row("largest contact force / its yield force", f"{m:.3f}", "< 1 (elastic, Sec. II)", None,
                        "elastic, as in the experiment" if m < 1 else "PASSES THE ELASTIC LIMIT"))
    return rows


# ------------------------------------------------------------------------------------------
# per-figure notes
# ------------------------------------------------------------------------------------------
def _series(summary: dict, chain: str, key: str) -> list[float | None]:
    return [_num(x) for x in (summary.get(chain) or {}).get(key) or []]


def _first_last(values: list) -> tuple[float | None, float | None]:
    vals = [v for v in values if v is not None]
    return (vals[0], vals[-1]) if vals else (None, None)


def _diameters_m(summary: dict, chain: str) -> list[float]:
    """phi_n [m] of the chain's truncations (summary's ``diameter_mm``, else the paper's Table I)."""
    c = summary.get(chain) or {}
    beads = c.get("beads") or []
    if c.get("diameter_mm"):
        return [float(d) * 1e-3 for d in c["diameter_mm"]]
    table = theory.PAPER_CHAINS.get(chain, [])
    return [table[int(b) - 1] * 1e-3 for b in beads if 0 < int(b) <= len(table)]


def _bead_at(summary: dict, chain: str, key: str, bead: int) -> float | None:
    c = summary.get(chain) or {}
    beads = [int(b) for b in c.get("beads") or []]
    vals = c.get(key) or []
    return _num(vals[beads.index(bead)]) if bead in beads and beads.index(bead) < len(vals) else None


def _pulse_note(summary: dict, chain: str, other: str | None) -> tuple[str, str]:
    c = summary.get(chain) or {}
    k = chain[-1]
    beads = [int(b) for b in c.get("beads") or []]
    q = _num(c.get("q"))
    what = (f"Wall force of chain {k} (q = {_f(q, '.2f', 100, '%')}) cut after beads 18-28 against t - T, "
            f"with the pulse of the uniform part in (a) and the power spectra of the incoming and outgoing "
            f"pulses in (h).")
    if not beads:
        return what, "No pulse data in the summary."
    n_a, n_b = beads[0], beads[-1]
    f_a, f_b = _first_last(_series(summary, chain, "peak_force"))
    t_a, t_b = _first_last(_series(summary, chain, "duration"))
    qf, qt = _bead_at(summary, chain, "front_momentum", n_b), _bead_at(summary, chain, "tail_momentum", n_b)
    checks = {"F_m decreases": f_a is not None and f_b is not None and f_b < f_a,
              "tau decreases": t_a is not None and t_b is not None and t_b < t_a,
              "a tail grows": qf is not None and qt is not None and qt > 0.2 * qf}
    parts = [f"F_m falls from {_f(f_a, '.2f', 1, 'N')} (n = {n_a}) to {_f(f_b, '.2f', 1, 'N')} (n = {n_b}) "
             f"and tau from {_f(t_a, '.0f', 1e6)} to {_f(t_b, '.0f', 1e6, 'µs')}, while at n = {n_b} the tail "
             f"carries {_f(qt / qf if qf and qt is not None else None, '.2f')} times the front's momentum "
             f"(Q_T/Q_F)"]
    spec = ((summary.get("figures") or {}).get("spectra") or {}).get(chain)
    if spec:
        ci, co = _num(spec.get("centroid_in_hz")), _num(spec.get("centroid_out_hz"))
        bi, bo = _num(spec.get("bandwidth_in_hz")), _num(spec.get("bandwidth_out_hz"))
        checks["the spectrum moves to higher frequencies"] = (ci is not None and co is not None and co > ci) and (
            bi is None or bo is None or bo > bi)
        s = f"the spectral centroid rises from {_f(ci, '.1f', 1e-3)} to {_f(co, '.1f', 1e-3, 'kHz')}"
        if bi is not None and bo is not None:
            s += f" and the -20 dB bandwidth from {bi * 1e-3:.1f} to {bo * 1e-3:.1f} kHz"
        parts.append(s)
    if other:
        n_cmp = min(beads[-1], max(int(b) for b in (summary.get(other) or {}).get("beads") or [0]))
        r_this, r_other = (_ratio(_bead_at(summary, c, "tail_momentum", n_cmp),
                                  _bead_at(summary, c, "front_momentum", n_cmp)) for c in (chain, other))
        if r_this is not None and r_other is not None:
            more = r_this > r_other
            checks["the tail is more pronounced than in chain 1"] = more
            parts.append(f"at n = {n_cmp} the tail is {'more' if more else 'less'} pronounced than in chain "
                         f"{other[-1]} (Q_T/Q_F = {r_this:.2f} against {r_other:.2f})")
    ok = [k_ for k_, v in checks.items() if v]
    bad = [k_ for k_, v in checks.items() if not v]
    verdict = ("This agrees with the paper, which reports the same trends (" + ", ".join(ok) + ") but gives no "
               "numbers for this figure." if not bad else
               "Unlike the paper, here not: " + ", ".join(bad) + ".")
    return what, "; ".join(parts) + ". " + verdict


def _ratio(a, b):
    return a / b if a is not None and b not in (None, 0) else None


def _fig3_note(summary: dict) -> tuple[str, str]:
    what = ("Wall force of the full chain 2 with bead 22 (16 mm) or bead 28 (9 mm) offset perpendicular to "
            "the axis by e, and of chain 1 cut after bead 24 with one bead replaced (dq/q = +1, -1).")
    figs = summary.get("figures") or {}
    mis, subs = figs.get("misalignment") or {}, figs.get("substitutions") or {}
    if not mis and not subs:
        return what, ("The summary has no Fig. 3 numbers (pass figures.figure_summary(...) as "
                      "summary['figures']); compare the curves by eye.")
    parts, verdicts = [], []
    if mis:
        ref = {r["bead"]: r for r in mis if _num(r.get("offset_fraction")) == 0}
        worst_dT, worst_dF = 0.0, 0.0
        for b in sorted({r["bead"] for r in mis}):
            rows = sorted((r for r in mis if r["bead"] == b), key=lambda r: r["offset_fraction"])
            big, base = rows[-1], ref.get(b)
            if base is None or big is base:
                continue
            dF = big["peak_force"] / base["peak_force"] - 1
            dT = big["time_of_flight"] - base["time_of_flight"]
            worst_dT, worst_dF = max(worst_dT, abs(dT)), max(worst_dF, abs(dF))
            parts.append(f"e = {big['offset_m'] * 1e3:.2f} mm ({100 * big['offset_fraction']:.0f} %) at bead {b} changes "
                         f"F_m by {100 * dF:+.2f} % and T by {dT * 1e6:+.1f} µs")
        verdicts.append(f"as in the paper the front pulse speed is unchanged (|dT| <= {worst_dT * 1e6:.1f} µs); "
                        f"the paper's slight amplitude loss and damped tail oscillations are barely present "
                        f"(|dF_m| <= {100 * worst_dF:.2f} %): here the offset bead is held frictionless on its "
                        f"track, so only the geometry of the contacts changes")
    if subs and "reference" in subs:
        base = subs["reference"]
        signs = []
        for lab, expect in (("dq/q = +1", -1), ("dq/q = -1", +1)):
            if lab not in subs:
                continue
            dtau = subs[lab]["duration"] / base["duration"] - 1
            dT = subs[lab]["time_of_flight"] - base["time_of_flight"]
            parts.append(f"{lab} changes tau by {100 * dtau:+.2f} % and T by {dT * 1e6:+.1f} µs")
            signs.append((lab, math.copysign(1, dtau) == expect))
        if signs:
            if all(ok for _, ok in signs):
                verdicts.append("the substitutions agree in sign with the paper (+1: narrower, -1: wider front pulse)")
            else:
                verdicts.append("the substitutions disagree in sign with the paper for "
                                + ", ".join(lab for lab, ok in signs if not ok))
    text = "; ".join(verdicts)
    return what, "; ".join(parts) + ". " + text[:1].upper() + text[1:] + "."


def _fig4_note(summary: dict) -> tuple[str, str]:
    figs = summary.get("figures") or {}
    n = figs.get("collapse_pulses")
    what = (f"All {n if n else 'the'} pulses of Figs. 1-2 as F/F_m against (t - T)/tau, each with its own "
            f"cos^6 fit, over Nesterenko's cos^6.")
    rms = _num(figs.get("collapse_rms"))
    if rms is None:
        return what, "The summary has no collapse measure; the paper finds that the rising parts collapse."
    ok = rms < 0.03
    return what, (f"The loading parts fall on cos^6 with an rms deviation of at most {rms:.3f} F_m: "
                  + ("the self-similar front of the paper's Fig. 4 is reproduced."
                     if ok else "worse than the paper's collapse."))


def _relative_spread(values: list[float]) -> float | None:
    """Relative sample standard deviation of a series (None with fewer than two values)."""
    if len(values) < 2:
        return None
    mean = sum(values) / len(values)
    var = sum((v - mean) ** 2 for v in values) / (len(values) - 1)
    return math.sqrt(var) / mean if mean else None


def _fig5_note(summary: dict, settings_desc: dict | None) -> tuple[str, str]:
    what = ("Bead diameters with the fit phi_0 (1-q)^(n-n0), peak force F_m and duration tau of the wall pulse "
            "with eqs. 7-8 (anchored at n0 = 16), and the front and tail momenta Q_F, Q_T along both chains.")
    eps = _eps_theory(settings_desc)
    parts, f_dev, tau_closer, spreads = [], [], [], []
    for chain in CHAINS:
        c = summary.get(chain) or {}
        beads = [int(b) for b in c.get("beads") or []]
        q = _num(c.get("q"))
        if not beads or q is None:
            continue
        k, n0, N = chain[-1], beads[0], beads[-1]
        f_a, f_b = _first_last(_series(summary, chain, "peak_force"))
        t_a, t_b = _first_last(_series(summary, chain, "duration"))
        r, r0 = theory.ballistic_ratios(q, eps), theory.ballistic_ratios(0.0, eps)
        f_pred, f_pred0 = r.force ** (N - n0), r0.force ** (N - n0)
        phi = _diameters_m(summary, chain)
        tau_pred = tau_pred0 = None
        if len(phi) == len(beads):  # tau_n = (phi_n/2) sqrt(10) / v_n, v_n from eq. 8
            tau_pred = (phi[-1] / phi[0]) / r.speed ** (N - n0)
            tau_pred0 = (phi[-1] / phi[0]) / r0.speed ** (N - n0)
        f_sim, t_sim = _ratio(f_b, f_a), _ratio(t_b, t_a)
        qf, qt = _series(summary, chain, "front_momentum"), _series(summary, chain, "tail_momentum")
        spread = _relative_spread([a + b for a, b in zip(qf, qt) if a is not None and b is not None])
        parts.append(f"chain {k}: F_m({N})/F_m({n0}) = {_f(f_sim)} (eq. 7: {f_pred:.3f} with q, {f_pred0:.3f} "
                     f"with q = 0), tau({N})/tau({n0}) = {_f(t_sim)} (eq. 8: {_f(tau_pred)} with q, "
                     f"{_f(tau_pred0)} with q = 0), Q_F + Q_T constant to {_f(spread, '.0f', 100)} % (relative standard deviation)")
        if f_sim is not None:
            f_dev.append((k, f_sim / f_pred - 1, f_sim < f_pred0))
        if t_sim is not None and tau_pred is not None:
            tau_closer.append("q = 0" if abs(t_sim - tau_pred0) < abs(t_sim - tau_pred) else "tapered")
        if spread is not None:
            spreads.append(spread)
    if not parts:
        return what, "No pulse data in the summary."
    verdict = []
    if f_dev:
        below_q0 = all(b for *_, b in f_dev)
        first = ("as in the paper F_m falls well below the q = 0 prediction" if below_q0 else
                 "unlike the paper F_m does not fall below the q = 0 prediction")
        if all(abs(d) <= 0.05 for _, d, _ in f_dev):
            first += " and follows eq. 7 within 5 %, as the paper finds"
        else:
            first += (", but ends " + " and ".join(f"{100 * d:+.0f} % (chain {k})" for k, d, _ in f_dev)
                      + " off eq. 7, where the paper reports reasonable agreement")
        verdict.append(first)
    if tau_closer:
        verdict.append("tau is closer to the " + ("q = 0" if all(c == "q = 0" for c in tau_closer) else
                                                  "tapered" if all(c == "tapered" for c in tau_closer) else
                                                  "mixed") + " prediction (the paper: close to the tapered one)")
    if spreads:
        worst = 100 * max(spreads)
        verdict.append(f"the total momentum Q_F + Q_T is conserved to {worst:.0f} % along the chains, as in the paper"
                       if worst < 10 else f"the total momentum Q_F + Q_T varies by {worst:.0f} % along the chains, "
                       "unlike the paper (conserved)")
    text = "; ".join(verdict) + f" (predictions with eps = {eps:g})."
    return what, "; ".join(parts) + ". " + text[:1].upper() + text[1:]


def _fig6_note(summary: dict, settings_desc: dict | None) -> tuple[str, str]:
    what = ("Time of flight T along both chains (embedded sensors for n <= 16, wall shifted to meet them at "
            "n = 16), its departure from the restitution-only prediction T(eps; q = 0), and the local speed "
            "v_n with the fit v_n = Q^(n-n') v_n' and eq. 8.")
    paper = _paper(summary)
    parts = []
    for chain in CHAINS:
        c, ref = summary.get(chain) or {}, paper.get(chain) or {}
        Q, Qe, Qp, Qpe = (_num(c.get("Q_fit")), _num(c.get("Q_fit_err")), _num(ref.get("Q_fit")),
                          _num(ref.get("Q_fit_err")))
        if Q is None or Qp is None:
            continue
        inside = Qpe is not None and abs(Q - Qp) <= Qpe
        s = (f"chain {chain[-1]}: Q_fit = {_pm(Q, Qe)} lies {'inside' if inside else 'outside'} the paper's "
             f"error bar {_pm(Qp, Qpe)}")
        Qt, Qtp = _num(c.get("Q_theory")), _num(ref.get("Q_theory"))
        if Qt is not None:
            s += (f" and exceeds eq. 8 (Q_th = {Qt:.3f}) by {100 * (Q / Qt - 1):.1f} % (paper: {Qp:.3f} against "
                  f"{_f(Qtp)}, {100 * (Qp / Qtp - 1):.1f} %)" if Qtp else "")
        gain = _num(((summary.get("figures") or {}).get("tof_gain_s") or {}).get(chain))
        if gain is not None:
            s += (f"; at the last bead the pulse arrives {gain * 1e6:.0f} µs before T(eps; q = 0)"
                  + (", earlier than the restitution-only prediction as in the paper" if gain > 0 else
                     ", unlike the paper"))
        parts.append(s)
    if not parts:
        return what, "No velocity fit in the summary."
    return what, "; ".join(parts) + "."


def figure_notes(summary: dict, settings_desc: dict | None = None) -> dict[str, tuple[str, str]]:
    """Two sentences per figure: (what it shows, how it compares with the paper, from the numbers)."""
    return {
        "fig1": _pulse_note(summary, "chain1", None),
        "fig2": _pulse_note(summary, "chain2", "chain1"),
        "fig3": _fig3_note(summary),
        "fig4": _fig4_note(summary),
        "fig5": _fig5_note(summary, settings_desc),
        "fig6": _fig6_note(summary, settings_desc),
    }


def speed_sentence(summary: dict) -> str:
    """The two-speed check in words (``summary['speed_check']``)."""
    sc = summary.get("speed_check") or {}
    v = [_num(x) for x in sc.get("velocities") or []]
    dp, dt = _num(sc.get("max_peak_norm_deviation")), _num(sc.get("max_duration_norm_deviation"))
    if len(v) < 2 or None in v or dp is None:
        return "The two-speed check was not run."
    ok = dp < 0.01 and (dt is None or dt < 0.01)
    return ((f"The normalised results {'do not depend' if ok else 'DEPEND'} on the striker speed: between "
             f"v = {v[0]:g} and {v[1]:g} m/s the normalised peak forces F_m,n / F_m,n0 of chain 1 differ by at "
             f"most {100 * dp:.3f} %") + (f" and the normalised durations tau_n / tau_n0 by at most {100 * dt:.3f} %"
                                          if dt is not None else "") +
            (" (Hertz chains have no force scale: F_m ~ v^(6/5), times ~ v^(-1/5))." if ok else "."))


# ------------------------------------------------------------------------------------------
# maths: the notes are written with ASCII formulas (F_m, tau, Q^(n-n')); both documents show
# them as maths ($...$ for Markdown renderers, MathJax in the HTML page)
# ------------------------------------------------------------------------------------------
_GREEK = {"tau": r"\tau", "eps": r"\varepsilon", "phi": r"\phi", "delta": r"\delta", "sigma": r"\sigma",
          "kappa": r"\kappa", "omega": r"\omega"}
#: Whole ASCII formulas and their TeX (matched before the single symbols).
_FORMULAS = [
    ("(F_m^(n+1)/F_m^n)^(5/6)", r"(F_m^{n+1}/F_m^{n})^{5/6}"),
    ("v_n = Q^(n-n') v_n'", r"v_n = Q^{n-n'} v_{n'}"),
    ("phi_0 (1-q)^(n-n0)", r"\phi_0 (1-q)^{n-n_0}"),
    ("F_m cos^6((t-T)/tau)", r"F_m \cos^6((t-T)/\tau)"),
    ("T(eps; q = 0)", r"T(\varepsilon; q = 0)"),
    ("F_m ~ v^(6/5), times ~ v^(-1/5)", r"F_m \propto v^{6/5}$, times $\propto v^{-1/5}"),
    ("(t - T)/tau", r"(t - T)/\tau"),
    ("|dT|", r"|\Delta T|"),
    ("|dF_m|", r"|\Delta F_m|"),
    ("F/F_m", r"F/F_m"),
    ("Q_F + Q_T", r"Q_F + Q_T"),
    ("Q_T/Q_F", r"Q_T/Q_F"),
    ("F_m,n / F_m,n0", r"F_{m,n} / F_{m,n_0}"),
    ("tau_n / tau_n0", r"\tau_n / \tau_{n_0}"),
    ("F_m^wall / F_m^chain", r"F_m^{wall} / F_m^{chain}"),
    ("tau_wall / tau_chain", r"\tau_{wall} / \tau_{chain}"),
    ("cos^6", r"\cos^6"),
]
_SYMBOL = re.compile(r"(?<![\w$\\])(Q(\d)\^th|[A-Za-z]{1,5}(?:_[A-Za-z0-9']{1,5}|\^\([^)\s]*\)|\^[A-Za-z0-9]+)+"
                     r"|(?:tau|eps|phi|delta|sigma)(?![\w]))(?![\w(])")


def _tex_symbol(token: str) -> str:
    m = re.fullmatch(r"Q(\d)\^th", token)
    if m:
        return f"Q_{m.group(1)}^{{th}}"
    head = re.match(r"[A-Za-z]+", token).group(0)
    out = _GREEK.get(head, head)
    for kind, part in re.findall(r"([_^])(\([^)]*\)|[A-Za-z0-9']+)", token[len(head):]):
        part = part.strip("()")
        part = _GREEK.get(part, part)
        out += f"{kind}{{{part}}}" if len(part) > 1 else f"{kind}{part}"
    return out


def _texify(text: str) -> str:
    """ASCII formulas of a note -> TeX between $...$ (text already holding $ is left alone)."""
    if "$" in text:
        return text
    marks: list[str] = []

    def keep(tex: str) -> str:
        marks.append(f"${tex}$")
        return f"\x00{len(marks) - 1}\x00"

    for ascii_, tex in _FORMULAS:
        text = text.replace(ascii_, keep(tex))
    text = re.sub(r"(?<![\w$\\])([A-Za-z]+_[A-Za-z0-9]+|tau|eps)\((\d+)\)",
                  lambda m: keep(f"{_tex_symbol(m.group(1))}({m.group(2)})"), text)
    text = _SYMBOL.sub(lambda m: keep(_tex_symbol(m.group(0))), text)
    return re.sub("\x00(\\d+)\x00", lambda m: marks[int(m.group(1))], text)


# ------------------------------------------------------------------------------------------
# document blocks -> markdown / html
# ------------------------------------------------------------------------------------------
_UNITS = {"striker_velocity": "m/s", "striker_diameter": "m", "duration": "s", "sample_interval": "s"}


def _settings_rows(settings_desc: dict | None, summary: dict) -> list[list[str]]:
    rows = [[str(k), _show(v) + (f" {_UNITS[k]}" if k in _UNITS and v is not None else "")]
            for k, v in (settings_desc or {}).items()]
    for chain in CHAINS:
        law = (summary.get(chain) or {}).get("law")
        if law:
            rows.append([f"contact law ({chain})", ", ".join(f"{k} = {_show(v)}" for k, v in law.items())
                         + (" (A in s)" if "A" in law else "") + (" (gamma in N s/m)" if "gamma" in law else "")])
    if summary.get("hertzchain_version"):
        rows.append(["hertzchain version", str(summary["hertzchain_version"])])
    for k, v in (summary.get("timing") or {}).items():
        rows.append([f"timing: {k}", _show(v)])
    return rows


def _show(v: Any) -> str:
    if isinstance(v, float):
        return f"{v:.6g}"
    if v is None:
        return "none"
    return str(v)


def _bead_table(summary: dict, chain: str) -> tuple[list[str], list[list[str]]] | None:
    c = summary.get(chain) or {}
    beads = [int(b) for b in c.get("beads") or []]
    if not beads:
        return None
    phi = _diameters_m(summary, chain)
    cols = [("peak_force", ".3f", 1.0), ("duration", ".1f", 1e6), ("time_of_flight", ".4f", 1e3),
            ("front_momentum", ".3f", 1e3), ("tail_momentum", ".3f", 1e3)]
    header = ["n", "phi_n [mm]", "F_m [N]", "tau [µs]", "T [ms]", "Q_F [mN s]", "Q_T [mN s]"]
    rows = []
    for i, b in enumerate(beads):
        row = [str(b), _f(phi[i] if i < len(phi) else None, ".2f", 1e3)]
        for key, fmt, scale in cols:
            vals = c.get(key) or []
            row.append(_f(vals[i] if i < len(vals) else None, fmt, scale))
        rows.append(row)
    return header, rows


def _figure_png(path: Any) -> Path | None:
    """The PNG of a figure entry: a path (PNG or PDF beside a PNG) or a {"png": ...} dict."""
    if isinstance(path, dict):
        path = path.get("png") or next(iter(path.values()), None)
    if path is None:
        return None
    p = Path(path)
    return p if p.suffix.lower() == ".png" else p.with_suffix(".png")


def _blocks(summary: dict, figures: dict, settings_desc: dict | None) -> list[tuple]:
    rows = comparison_rows(summary, settings_desc)
    notes = figure_notes(summary, settings_desc)
    law = (settings_desc or {}).get("law", "?")
    blocks: list[tuple] = [
        ("h1", "hertzchain reproduction of Melo, Job, Santibanez, Tapia, PRE 2006"),
        ("p", "Experimental evidence of shock mitigation in a Hertzian tapered chain: simulated with "
              f"hertzchain ({law} contacts), measured and analysed with the paper's protocol (wall force of the "
              "chains truncated after bead 16, 17, ..., N; embedded sensors in the uniform part; cos^6 fit of "
              "the loading part)."),
        ("h2", "Simulated against published values"),
        ("table", ["quantity", "simulated", "paper", "relative difference", "verdict"],
         [[r.quantity, r.simulated, r.paper, _pct(r.rel), r.verdict] for r in rows]),
        ("p", speed_sentence(summary)),
        ("h2", "Figures"),
    ]
    for name in sorted(figures, key=lambda n: (n not in FIGURE_TITLES, n)):
        what, agree = notes.get(name, ("", ""))
        blocks.append(("figure", name, FIGURE_TITLES.get(name, name), _figure_png(figures[name]), what, agree))
    blocks.append(("h2", "Wall pulse along the chains"))
    for chain in CHAINS:
        table = _bead_table(summary, chain)
        if table:
            blocks.append(("h3", f"Chain {chain[-1]}"))
            blocks.append(("table",) + table)
    blocks.append(("h2", "Parameters of this run"))
    blocks.append(("table", ["parameter", "value"], _settings_rows(settings_desc, summary), "verbatim"))
    return blocks


def _md_cell(s: str) -> str:
    return str(s).replace("|", "\\|").replace("\n", " ")


def _to_markdown(blocks: list[tuple], out_dir: Path) -> str:
    lines: list[str] = []
    for b in blocks:
        kind = b[0]
        if kind in ("h1", "h2", "h3"):
            lines += ["#" * int(kind[1]) + " " + b[1], ""]
        elif kind == "p":
            lines += [_texify(b[1]), ""]
        elif kind == "table":
            header, rows = b[1], b[2]
            tex = (lambda x: x) if b[3:] == ("verbatim",) else _texify  # parameter names stay code
            lines.append("| " + " | ".join(_md_cell(tex(h)) for h in header) + " |")
            lines.append("|" + "|".join("---" for _ in header) + "|")
            lines += ["| " + " | ".join(_md_cell(tex(c)) for c in row) + " |" for row in rows]
            lines.append("")
        elif kind == "figure":
            _, name, title, png, what, agree = b
            what, agree = _texify(what), _texify(agree)
            lines += [f"### {title}", ""]
            if png is not None:
                rel = os.path.relpath(png.resolve(), out_dir).replace(os.sep, "/")
                width = _display_width(png)
                size = f' width="{width}"' if width else ""
                lines += [f'<img src="{rel}" alt="{html.escape(title)}"{size}>', ""]
                pdf = png.with_suffix(".pdf")
                if pdf.exists():
                    pdf_rel = os.path.relpath(pdf.resolve(), out_dir).replace(os.sep, "/")
                    lines += [f"Vector version: [{pdf.name}]({pdf_rel})", ""]
            lines += [f"*Shows:* {what}", "", f"*Against the paper:* {agree}", ""]
    return "\n".join(lines).rstrip() + "\n"


_CSS = """
body { font-family: -apple-system, "Segoe UI", Helvetica, Arial, sans-serif; max-width: 60em;
       margin: 2em auto; padding: 0 1em; color: #222; line-height: 1.45; }
h1 { font-size: 1.5em; border-bottom: 2px solid #446; padding-bottom: .2em; }
h2 { font-size: 1.25em; margin-top: 1.8em; border-bottom: 1px solid #ccd; }
h3 { font-size: 1.05em; margin-top: 1.4em; }
table { border-collapse: collapse; margin: .8em 0; font-size: .9em; }
th, td { border: 1px solid #ccd; padding: .25em .6em; text-align: left; vertical-align: top; }
th { background: #eef0f6; }
tr:nth-child(even) td { background: #fafbfd; }
figure { margin: 1em 0 2em 0; }
figure img { max-width: 100%; border: 1px solid #ddd; box-sizing: border-box; }
figcaption { font-size: .92em; margin-top: .4em; }
.missing { color: #a00; }
"""


#: Figures are shown at one scale: a full-width figure (7 in, the paper's two columns) spans
#: the page (_PAGE_PX pixels), a one-column one (3.4 in) half of it.
_FIGURE_DPI, _PX_PER_INCH = 200, 100
_PAGE_PX = 7.0 * _PX_PER_INCH


def _display_width(png: Path) -> int | None:
    """Width [px] to show a figure at, from its PNG size (written at _FIGURE_DPI)."""
    try:
        head = png.read_bytes()[:24]
    except OSError:
        return None
    if head[:8] != b"\x89PNG\r\n\x1a\n":
        return None
    return round(int.from_bytes(head[16:20], "big") / _FIGURE_DPI * _PX_PER_INCH)


#: MathJax typesets the $...$ formulas of the page (shown as TeX source when offline).
_MATHJAX = ("<script>window.MathJax = {tex: {inlineMath: [['\\\\(', '\\\\)']]}};</script>"
            '<script id="MathJax-script" async src="https://cdn.jsdelivr.net/npm/mathjax@3/es5/tex-chtml.js">'
            "</script>")


def _html_math(text: str) -> str:
    """Escape a note for HTML and mark its formulas \\(...\\) for MathJax."""
    return re.sub(r"\$([^$]+)\$", lambda mm: f"\\({mm.group(1)}\\)", html.escape(_texify(str(text))))


def _to_html(blocks: list[tuple]) -> str:
    e = html.escape
    m = _html_math
    body: list[str] = []
    title = "hertzchain reproduction"
    for b in blocks:
        kind = b[0]
        if kind in ("h1", "h2", "h3"):
            if kind == "h1":
                title = b[1]
            body.append(f"<{kind}>{e(b[1])}</{kind}>")
        elif kind == "p":
            body.append(f"<p>{m(b[1])}</p>")
        elif kind == "table":
            header, rows = b[1], b[2]
            cell = e if b[3:] == ("verbatim",) else m
            body.append("<table><thead><tr>" + "".join(f"<th>{cell(str(h))}</th>" for h in header)
                        + "</tr></thead><tbody>")
            body += ["<tr>" + "".join(f"<td>{cell(str(c))}</td>" for c in row) + "</tr>" for row in rows]
            body.append("</tbody></table>")
        elif kind == "figure":
            _, name, ftitle, png, what, agree = b
            body.append(f'<h3 id="{e(name)}">{e(ftitle)}</h3><figure>')
            if png is not None and png.is_file():
                data = base64.b64encode(png.read_bytes()).decode("ascii")
                width = _display_width(png)
                size = f' style="width: {100 * width / _PAGE_PX:.1f}%"' if width else ""
                body.append(f'<img alt="{e(ftitle)}" src="data:image/png;base64,{data}"{size}>')
            else:
                body.append(f'<p class="missing">figure file missing: {e(str(png))}</p>')
            body.append(f"<figcaption><b>Shows:</b> {m(what)}<br><b>Against the paper:</b> {m(agree)}"
                        "</figcaption></figure>")
    return ("<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">"
            f"<title>{e(title)}</title><style>{_CSS}</style>{_MATHJAX}</head><body>\n"
            + "\n".join(body) + "\n</body></html>\n")


def write_report(out_dir: str | Path, summary: dict, figures: dict[str, Any],
                 settings_desc: dict | None = None) -> dict[str, Path]:
    """Write ``report.md`` and the standalone ``report.html`` into ``out_dir``.

    Parameters
    ----------
    out_dir:
        Folder of the reproduction (created if needed); Markdown links to the figures are relative
        to it.
    summary:
        The reproduction summary (see the module docstring for the keys read); missing keys give
        "n/a" entries, never an error.
    figures:
        {name: path of the PNG} ("fig1".."fig6"; a PDF path with a PNG beside it, or the dict
        {"png": ..., "pdf": ...}, also works). Every figure is embedded in the HTML as base64.
    settings_desc:
        The run's parameters (``Settings.describe()``), printed as given; its ``eps_target`` (None
        for elastic runs) sets the eps of the closed-form predictions quoted in the notes.

    Returns
    -------
    {"md": path, "html": path}
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    blocks = _blocks(summary, dict(figures or {}), settings_desc)
    md, page = out / "report.md", out / "report.html"
    from ..fileio import write_text

    write_text(md, _to_markdown(blocks, out.resolve()))
    write_text(page, _to_html(blocks))
    return {"md": md, "html": page}

