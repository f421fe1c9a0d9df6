"""What the reproduction report says, written from the numbers of a reproduction summary: the
table of simulated against published values with verdicts (:func:`comparison_rows`), two
sentences per figure (:func:`figure_notes`) and the two-speed check (:func:`speed_sentence`).

Formulas are plain ASCII here (``F_m``, ``tau``, ``Q^(n-n')``); :mod:`hertzchain.paper.render`
typesets them. The summary keys read are listed in :mod:`hertzchain.paper.report`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from .. import theory
from .values import PAPER
from ..laws import is_conservative

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
#: What a comparison row is. Only ``measured`` rows test the paper: the others match it by
#: construction (an input the run takes from it) or by arithmetic (its formula of those inputs).
ROW_KINDS = {
    "measured": "a measurement or statement of the paper (counted as agreement when it agrees)",
    "input": "an input taken from the paper (Table I's diameters; the eps the dissipation is calibrated to)",
    "derived": "the paper's formula evaluated on those inputs (eq. 8, the yield estimate of Sec. II)",
}


@dataclass(frozen=True)
class Row:
    """One line of the comparison table (strings ready to print, ``rel`` as a fraction).

    ``kind`` is a key of :data:`ROW_KINDS`; ``agrees`` whether the verdict is an agreement (None:
    no verdict, e.g. a missing number)."""

    quantity: str
    simulated: str
    paper: str
    rel: float | None
    verdict: str
    kind: str = "measured"
    agrees: bool | None = None


def agreement_count(rows: list[Row]) -> tuple[int, int]:
    """How many of the paper's measurements and statements the run agrees with, of how many judged.

    Parameters
    ----------
    rows : list of Row
        :func:`comparison_rows`.

    Returns
    -------
    (int, int)
        Agreeing ``measured`` rows, and ``measured`` rows with a verdict; inputs and derived
        constants are never counted.
    """
    judged = [r for r in rows if r.kind == "measured" and r.agrees is not None]
    return sum(bool(r.agrees) for r in judged), len(judged)


def _tol(rel: float | None, tol: float) -> bool | None:
    return None if rel is None else abs(rel) <= tol


def _verdict_tol(rel: float | None, tol: float, note: str = "", same: str = "agrees") -> str:
    if rel is None:
        return "n/a"
    word = f"{same} within {100 * tol:g} %" if abs(rel) <= tol else f"differs by {100 * rel:+.1f} %"
    return word + (f" ({note})" if note else "")


def _bar(sim: Any, ref: Any, ref_err: Any) -> float | None:
    """|sim - ref| in units of the paper's error bar (None without one)."""
    s, r, re_ = _num(sim), _num(ref), _num(ref_err)
    if s is None or r is None or re_ is None or re_ <= 0:
        return None
    return abs(s - r) / re_


def _verdict_bar(sim: Any, sim_err: Any, ref: Any, ref_err: Any) -> str:
    k = _bar(sim, ref, ref_err)
    if k is None:
        return "n/a"
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
    """Simulated against published values, with relative differences, verdicts and what each is.

    The paper's measurements and statements (``kind="measured"``, counted by
    :func:`agreement_count`): Q_fit +- error of both chains (Sec. III, Fig. 6c), the wall/chain
    peak-force and duration ratios (Sec. II, quoted from Job et al. 2005 within 5 %) and, when
    present, the largest contact force over its yield force ("bead's deformation always keeps
    elastic behavior", Sec. II). Inputs (``"input"``): q and its standard deviation (Table I's
    diameters, which the run uses), eps measured back in the uniform part (the dissipation is
    calibrated to the paper's eps). Derived constants (``"derived"``): Q^th (eq. 8 of q and
    eps), the yield force F_Y and overlap delta_Y of 26 mm beads (Sec. II's estimate from the
    material constants). Matching an input or a derived constant checks the set-up; it does not
    test the paper.
    """
    paper = _paper(summary)
    eps_th = _eps_theory(settings_desc)
    rows: list[Row] = []
    for chain in CHAINS:
        sim, ref = summary.get(chain) or {}, paper.get(chain) or {}
        k = chain[-1]
        r = _rel(sim.get("q"), ref.get("q"))
        rows.append(Row(f"chain {k}: tapering factor q{k}", _f(sim.get("q"), ".2f", 100, "%"),
                        _f(ref.get("q"), ".2f", 100, "%"), r, _verdict_tol(r, 0.01, "Table I's diameters", "matches"),
                        "input", _tol(r, 0.01)))
        r = _rel(sim.get("q_std"), ref.get("q_std"))
        rows.append(Row(f"chain {k}: standard deviation of q{k}", _f(sim.get("q_std"), ".2f", 100, "%"),
                        _f(ref.get("q_std"), ".2f", 100, "%"), r,
                        _verdict_tol(r, 0.02, "Table I's diameters", "matches"), "input", _tol(r, 0.02)))
        bar = _bar(sim.get("Q_fit"), ref.get("Q_fit"), ref.get("Q_fit_err"))
        rows.append(Row(f"chain {k}: Q{k} (fit of v_n = Q^(n-n') v_n')",
                        _pm(sim.get("Q_fit"), sim.get("Q_fit_err")), _pm(ref.get("Q_fit"), ref.get("Q_fit_err")),
                        _rel(sim.get("Q_fit"), ref.get("Q_fit")),
                        _verdict_bar(sim.get("Q_fit"), sim.get("Q_fit_err"), ref.get("Q_fit"), ref.get("Q_fit_err")),
                        "measured", None if bar is None else bar <= 1))
        r = _rel(sim.get("Q_theory"), ref.get("Q_theory"))
        note = f"eq. 8 with eps = {eps_th:g}" + ("" if abs(eps_th - paper["eps"]) < 1e-9
                                                 else f"; the paper's value uses eps = {paper['eps']:g}")
        rows.append(Row(f"chain {k}: Q{k}^th (eq. 8)", _f(sim.get("Q_theory")), _f(ref.get("Q_theory")), r,
                        _verdict_tol(r, 0.005, note, "matches"), "derived", _tol(r, 0.005)))
    r = _rel(summary.get("eps"), paper.get("eps"))
    elastic = _num((settings_desc or {}).get("eps_target")) is None and is_conservative((settings_desc or {}).get("law"))
    rows.append(Row("eps measured back in the uniform part, (F_m^(n+1)/F_m^n)^(5/6)",
                    _pm(summary.get("eps"), summary.get("eps_err"), ".4f"), _f(paper.get("eps"), ".3f"), r,
                    "elastic run: eps = 1 expected" if elastic
                    else _verdict_tol(r, 0.002, "the dissipation is calibrated to it", "matches"),
                    "input", None if elastic else _tol(r, 0.002)))
    for key, label in (("wall_to_chain_force_ratio", "wall/chain peak-force ratio F_m^wall / F_m^chain"),
                       ("wall_to_chain_duration_ratio", "wall/chain duration ratio tau_wall / tau_chain")):
        r = _rel(summary.get(key), paper.get(key))
        rows.append(Row(label, _f(summary.get(key)), _f(paper.get(key), ".2f"), r,
                        _verdict_tol(r, 0.05, "the paper's stated accuracy"), "measured", _tol(r, 0.05)))
    r = _rel(summary.get("yield_force"), paper.get("yield_force"))
    rows.append(Row("yield force F_Y of two 26 mm beads", _f(summary.get("yield_force"), ".0f", 1, "N"),
                    _f(paper.get("yield_force"), ".0f", 1, "N"), r,
                    _verdict_tol(r, 0.05, "paper rounds", "matches"), "derived", _tol(r, 0.05)))
    r = _rel(summary.get("yield_overlap"), paper.get("yield_overlap"))
    rows.append(Row("yield overlap delta_Y of two 26 mm beads", _f(summary.get("yield_overlap"), ".1f", 1e6, "µm"),
                    _f(paper.get("yield_overlap"), ".0f", 1e6, "µm"), r,
                    _verdict_tol(r, 0.05, "paper gives 2 digits", "matches"), "derived", _tol(r, 0.05)))
    if _num(summary.get("max_force_over_yield")) is not None:
        m = float(summary["max_force_over_yield"])
        rows.append(Row("largest contact force / its yield force", f"{m:.3f}", "< 1 (elastic, Sec. II)", None,
                        "elastic, as in the experiment" if m < 1 else "PASSES THE ELASTIC LIMIT", "measured", m < 1))
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
                     f"{_f(tau_pred0)} with the speeds of q = 0 and the real diameters), Q_F + Q_T constant "
                     f"to {_f(spread, '.0f', 100)} % (relative standard deviation)")
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

