"""The paper's observations in words, one by one, tested on the reproduction's numbers.

Melo et al. state most of their findings in words ("the tail grows", "F_m follows eq. 7 with
tapering reasonably well", "misalignment damps the tail's oscillation"). :func:`build_claims`
turns each into a row of ``summary.json`` (``claims``):

- ``claim``: the observation, ``source``: where the paper makes it;
- ``origin``: ``"paper"``, or ``"project"`` for the project's own checks (the striker's bounce:
  the paper says nothing of it), which the report lists apart and :func:`claims_count` never
  counts as agreement with the paper;
- ``quantity``: what measures it, and ``criterion``: when it counts as reproduced (or partly);
- ``values``: the simulated quantity under every model variant -- contact laws (``elastic``,
  ``viscoelastic`` with one constant A, ``viscoelastic_scaled`` with A following each contact's
  collision time, ``viscoelastic_sized`` with A following its square, ``dashpot_scaled`` with a dashpot following each contact pair) for the
  observations on the chains and the striker's own bounce, and ``rigid`` / ``lateral`` /
  ``lateral_friction`` (offset bead held on its line, free in a groove, with friction) for Fig. 3;
- ``verdicts``: per variant, and ``verdict``: ``"reproduced"`` when the run's own model variant
  (its contact law; the rigid offset for Fig. 3) reproduces it, ``"partly"`` when it only meets
  the looser criterion or only another variant reproduces it, ``"not reproduced"`` otherwise;
  ``reproduced_by`` lists the variants that do.

Nothing here is hard-coded but the paper's statements and the thresholds that read them; every
verdict follows from the numbers of the run (:mod:`hertzchain.paper.fidelity`).
"""

from __future__ import annotations

import math
from typing import Callable

from .values import PAPER

__all__ = ["build_claims", "claims_count", "explained_by", "report_blocks", "FIGURES", "VERDICTS"]

VERDICTS = ("reproduced", "partly", "not reproduced")

#: Figures of the variants, drawn by :mod:`hertzchain.paper.fidelity` (name -> title).
FIGURES = {"fig5_laws": "Fig. 5b-c under each contact law: F_m and tau along the chains against eqs. 7-8",
           "fig3_lateral": "Fig. 3a-b with lateral freedom: the offset bead free across the axis"}


def _num(x) -> float | None:
    try:
        v = float(x)
    except (TypeError, ValueError):
        return None
    return v if math.isfinite(v) else None


def _grade(value: float | None, good: Callable[[float], bool], fair: Callable[[float], bool]) -> str | None:
    if value is None:
        return None
    return VERDICTS[0] if good(value) else VERDICTS[1] if fair(value) else VERDICTS[2]


def _row(claim: str, source: str, quantity: str, criterion: str, values: dict, main: str,
         good: Callable[[float], bool], fair: Callable[[float], bool], origin: str = "paper") -> dict | None:
    values = {k: _num(v) for k, v in values.items()}
    verdicts = {k: _grade(v, good, fair) for k, v in values.items()}
    verdicts = {k: v for k, v in verdicts.items() if v is not None}
    if not verdicts:
        return None
    own = verdicts.get(main)
    by = [k for k, v in verdicts.items() if v == VERDICTS[0]]
    if own == VERDICTS[0]:
        verdict = VERDICTS[0]
    elif own == VERDICTS[1] or by:
        verdict = VERDICTS[1]
    else:
        verdict = VERDICTS[2]
    return {"claim": claim, "source": source, "origin": origin, "quantity": quantity, "criterion": criterion,
            "values": values, "verdicts": verdicts, "main_variant": main, "reproduced_by": by, "verdict": verdict}


def _per_law(laws: dict, get: Callable[[dict], float | None]) -> dict:
    out = {}
    for law, row in laws.items():
        try:
            out[law] = get(row)
        except (KeyError, TypeError, ZeroDivisionError, IndexError):
            out[law] = None
    return out


def _chain_claims(laws: dict, main: str) -> list[dict | None]:
    rows = []
    for chain in ("chain1", "chain2"):
        k = chain[-1]
        rows.append(_row(
            f"The peak force follows eq. 7 with tapering reasonably well (chain {k})", "Sec. III, Fig. 5b",
            f"[F_m(N)/F_m(16)] / [eq. 7 with q{k} and the variant's eps], chain {k}",
            "within 10 % of 1 (partly: within 25 %)",
            _per_law(laws, lambda r: r[chain]["peak_force_ratio"] / r[chain]["eq7_peak_force_ratio"]), main,
            lambda v: abs(v - 1) <= 0.10, lambda v: abs(v - 1) <= 0.25))
        rows.append(_row(
            f"The decrease of F_m is not attributable to dissipation alone (chain {k})", "Sec. III, Fig. 5b",
            f"[F_m(N)/F_m(16)] / [eq. 7 with q = 0 and the variant's eps], chain {k}",
            "below 0.95 (partly: below 1)",
            _per_law(laws, lambda r: r[chain]["peak_force_ratio"] / r[chain]["eq7_peak_force_ratio_q0"]), main,
            lambda v: v < 0.95, lambda v: v < 1.0))
        rows.append(_row(
            f"The pulse duration follows the ballistic prediction with tapering, eq. 8 (chain {k})",
            "Sec. III, Fig. 5c",
            f"position of tau(N)/tau(16) between tau_n = (phi_n/2) sqrt(10)/v_n with the real phi_n and the "
            f"speeds of eq. 8 with q = 0 (0) or with q{k} (1), chain {k}",
            "within 0.25 of 1 (partly: closer to 1 than to 0)",
            _per_law(laws, lambda r: (r[chain]["duration_ratio"] - r[chain]["eq8_duration_ratio_q0"])
                     / (r[chain]["eq8_duration_ratio"] - r[chain]["eq8_duration_ratio_q0"])), main,
            lambda v: abs(v - 1) <= 0.25, lambda v: v > 0.5))
        paper_q, paper_err = PAPER[chain]["Q_fit"], PAPER[chain]["Q_fit_err"]
        rows.append(_row(
            f"The pulse speeds up along the taper, v_n = Q^(n-n') v_n' with Q{k} = {paper_q} +- {paper_err}",
            "Sec. III, Fig. 6c", f"fitted Q{k}", "inside the paper's error bar (partly: within two of them)",
            _per_law(laws, lambda r: r[chain]["Q_fit"]), main,
            lambda v: abs(v - paper_q) <= paper_err, lambda v: abs(v - paper_q) <= 2 * paper_err))
    rows.append(_row(
        "No detectable reflected wave while the pulse propagates", "Sec. III",
        "largest force at the sensor in bead 12 after its pulse (t > T + 3 tau) and before the wall's echo can "
        "return, over its F_m (larger of the two chains)", "< 0.05 (partly: < 0.1)",
        _per_law(laws, lambda r: max(r["chain1"]["reflection_at_sensor"], r["chain2"]["reflection_at_sensor"])),
        main, lambda v: v < 0.05, lambda v: v < 0.1))
    rows.append(_row(
        "The pulse arrives earlier than the restitution-only prediction T(eps; q = 0)", "Sec. III, Fig. 6a-b",
        "smaller of the two chains' T(eps; q = 0) - T at the last bead [µs]", "> 0 µs in both chains",
        _per_law(laws, lambda r: 1e6 * min(r["figures"]["tof_gain_s"]["chain1"], r["figures"]["tof_gain_s"]["chain2"])),
        main, lambda v: v > 0, lambda v: False))
    rows.append(_row(
        "A tail grows behind the front pulse", "Sec. III, Figs. 1-2, 5d",
        "smaller of the two chains' tail/front momentum Q_T/Q_F at the last bead",
        "> 0.2 (partly: > 0.05)",
        _per_law(laws, lambda r: min(r["chain1"]["tail_to_front"], r["chain2"]["tail_to_front"])), main,
        lambda v: v > 0.2, lambda v: v > 0.05))
    rows.append(_row(
        "The tail is more pronounced in chain 2 (larger q) than in chain 1", "Sec. III, Fig. 2",
        "(Q_T/Q_F of chain 2) / (Q_T/Q_F of chain 1) at n = 28", "> 1",
        _per_law(laws, lambda r: r["chain2"]["tail_to_front_at"]["28"] / r["chain1"]["tail_to_front_at"]["28"]), main,
        lambda v: v > 1, lambda v: False))
    rows.append(_row(
        "The spectrum moves to higher frequencies through the taper", "Sec. III, Figs. 1h, 2h",
        "smaller of the two chains' spectral-centroid ratio out/in", "> 1",
        _per_law(laws, lambda r: min(s["centroid_out_hz"] / s["centroid_in_hz"]
                                     for s in r["figures"]["spectra"].values())), main,
        lambda v: v > 1, lambda v: False))
    rows.append(_row(
        "The total momentum Q_F + Q_T is conserved along the chain", "Sec. III, Fig. 5d",
        "larger of the two chains' relative spread of Q_F + Q_T over the truncations",
        "< 10 % (partly: < 20 %)",
        _per_law(laws, lambda r: max(r["chain1"]["momentum_spread"], r["chain2"]["momentum_spread"])), main,
        lambda v: v < 0.10, lambda v: v < 0.20))
    rows.append(_row(
        "The front pulse keeps Nesterenko's cos^6 shape (self-similar collapse)", "Sec. III, Fig. 4",
        "largest rms deviation from cos^6 on the loading part [F_m]", "< 0.03 (partly: < 0.06)",
        _per_law(laws, lambda r: r["figures"]["collapse_rms"]), main,
        lambda v: v < 0.03, lambda v: v < 0.06))
    return rows


#: Two-body restitution of steel balls near 0.2 m/s: 0.95 or more (criterion of the striker's
#: bounce; the paper gives none, this is what hardened steel balls do at such speeds).
STEEL_RESTITUTION = 0.95
#: |eps measured back - the paper's eps| within which a variant counts as giving the chain's eps.
EPS_TOLERANCE = 0.003


def _collision_claims(laws: dict, main: str) -> list[dict | None]:
    """The striker's own bounce, and whether one dissipation gives it together with the chain's eps."""
    def both(r: dict) -> float | None:
        e, eps = _num(r.get("striker_restitution")), _num(r["chain1"]["eps_measured"])
        if e is None or eps is None:
            return None
        return e if abs(eps - PAPER["eps"]) <= EPS_TOLERANCE else 0.0

    # The project's own checks (origin "project"): the paper says nothing of the striker's bounce;
    # they chose the reproduction's law, so they are never counted as agreement with the paper.
    return [
        _row("The steel striker bounces off the first bead like a steel ball",
             "project's own check, not in the paper; two-body impacts of steel balls",
             "restitution of the 8 mm striker on a free 26 mm bead at the run's speed, under the variant's law",
             f">= {STEEL_RESTITUTION} (partly: >= 0.9)", _per_law(laws, lambda r: r["striker_restitution"]), main,
             lambda v: v >= STEEL_RESTITUTION, lambda v: v >= 0.9, origin="project"),
        _row("One dissipation gives both the chain's eps and a steel-like striker bounce",
             "project's own check, not in the paper; Sec. III's eps = 0.985 with two-body impacts",
             f"striker restitution where eps measured back in chain 1 is within {EPS_TOLERANCE} of "
             f"{PAPER['eps']}, else 0", f">= {STEEL_RESTITUTION} (partly: >= 0.9)", _per_law(laws, both), main,
             lambda v: v >= STEEL_RESTITUTION, lambda v: v >= 0.9, origin="project"),
    ]


def claims_count(claims: list[dict]) -> dict[str, int]:
    """How many of the paper's own claims the run reproduces (the project's checks not counted).

    Parameters
    ----------
    claims : list of dict
        Rows of :func:`build_claims`.

    Returns
    -------
    dict
        ``paper`` (the paper's claims in the table), ``reproduced``, ``partly``, ``not reproduced``
        (verdicts of the run's own variant on them) and ``project`` (rows of the project's own
        checks, listed apart).
    """
    paper = [c for c in claims if c.get("origin", "paper") == "paper"]
    out = {"paper": len(paper), **{v: sum(c["verdict"] == v for c in paper) for v in VERDICTS}}
    out["project"] = len(claims) - len(paper)
    return out


def explained_by(claims: list[dict]) -> dict[str, list[str]]:
    """Which model explains which observation: {variant: [claims it reproduces]}.

    Parameters
    ----------
    claims : list of dict
        Rows of :func:`build_claims`.

    Returns
    -------
    dict
        Every variant of the table, with the claims whose criterion it meets (in table order).
    """
    out: dict[str, list[str]] = {}
    for c in claims:
        for variant, verdict in c["verdicts"].items():
            out.setdefault(variant, [])
            if verdict == VERDICTS[0]:
                out[variant].append(c["claim"])
    return out


def _fig3_claims(mis: dict) -> list[dict | None]:
    """Fig. 3a-b claims, with the variants rigid / lateral / lateral_friction."""

    def worst(var: str, key: str, pick=max, scale=1.0, absolute=False):
        rows = [r for name, r in (mis.get(var) or {}).items() if not name.endswith(":0")]
        vals = [abs(r[key]) if absolute else r[key] for r in rows if _num(r.get(key)) is not None]
        return scale * pick(vals) if vals else None

    def tail_ratio(var: str):
        rows = mis.get(var) or {}
        out = []
        for name, r in rows.items():
            b, fr = name.split(":")
            ref = (mis.get("rigid") or {}).get(f"{b}:0") or rows.get(f"{b}:0")
            if float(fr) == max(float(n.split(":")[1]) for n in rows if n.split(":")[0] == b) and float(fr) > 0 and ref:
                if ref["tail_oscillation"] > 0:
                    out.append(r["tail_oscillation"] / ref["tail_oscillation"])
        return max(out) if out else None

    variants = [v for v in ("rigid", "lateral", "lateral_friction") if v in mis]
    return [
        _row("The front pulse velocity is nearly unchanged by a misaligned bead", "Sec. IV, Fig. 3a-b",
             "largest |change of the time of flight T| over the offsets [µs]", "< 5 µs (partly: < 15 µs)",
             {v: worst(v, "time_of_flight_change_s", scale=1e6, absolute=True) for v in variants}, "rigid",
             lambda x: x < 5, lambda x: x < 15),
        _row("A misaligned bead lowers the amplitude slightly", "Sec. IV, Fig. 3a-b",
             "largest drop of F_m over the offsets [%] (positive = lower)",
             "between 0.5 % and 10 % (partly: above 0.1 %)",
             {v: worst(v, "peak_force_change", pick=min, scale=-100.0) for v in variants}, "rigid",
             lambda x: 0.5 <= x <= 10, lambda x: x > 0.1),
        _row("A misaligned bead damps the tail's oscillation (peak near t - T = 0.38 ms)", "Sec. IV, Fig. 3a-b",
             "largest ratio of the tail peak's prominence (t - T in 0.25-0.55 ms) at the largest offset to the "
             "aligned chain's", "< 0.7 (partly: < 0.9)",
             {v: tail_ratio(v) for v in variants}, "rigid", lambda x: x < 0.7, lambda x: x < 0.9),
    ]


def build_claims(summary: dict) -> list[dict]:
    """The claims table (at least ten rows) from a reproduction summary with ``fidelity`` numbers.

    Parameters
    ----------
    summary : dict
        ``summary.json`` of :func:`hertzchain.paper.reproduce.reproduce`: reads
        ``summary["fidelity"]["laws"]`` ({law: numbers}), ``summary["fidelity"]["misalignment"]``
        ({variant: {"bead:fraction": numbers}}) and ``summary["settings"]["law"]`` (the run's
        own variant).

    Returns
    -------
    list of dict
        One row per claim: ``claim``, ``source``, ``quantity``, ``criterion``, ``values``
        {variant: number}, ``verdicts`` {variant: verdict}, ``main_variant``, ``reproduced_by``
        and ``verdict`` ("reproduced", "partly" or "not reproduced").
    """
    fid = summary.get("fidelity") or {}
    main = (summary.get("settings") or {}).get("law", "viscoelastic")
    laws = fid.get("laws") or {}
    rows = _chain_claims(laws, main) + _collision_claims(laws, main) + _fig3_claims(fid.get("misalignment") or {})
    return [r for r in rows if r is not None]


def _fmt(v) -> str:
    v = _num(v)
    if v is None:
        return "n/a"
    return f"{v:.3g}" if abs(v) < 1e4 else f"{v:.3e}"


def report_blocks(summary: dict, figures: dict) -> list[tuple]:
    """Report blocks (see :mod:`hertzchain.paper.report`): the claims table, the variants' numbers
    and their figures (:data:`FIGURES`, when drawn)."""
    claims = summary.get("claims") or []
    if not claims:
        return []
    fid = summary.get("fidelity") or {}
    variants = list(dict.fromkeys(k for c in claims for k in c["values"]))
    count = claims_count(claims)

    def table(rows: list[dict], first: str) -> tuple:
        return ("table", [first, "quantity", "criterion", *variants, "verdict"],
                [[f"{c['claim']} ({c['source']})", c["quantity"], c["criterion"],
                  *[_fmt(c["values"].get(v)) + ("" if c["verdicts"].get(v) != "reproduced" else " ✓") for v in variants],
                  c["verdict"] + (f" (by {', '.join(c['reproduced_by'])})" if c["verdict"] == "partly" and c["reproduced_by"]
                                  else "")] for c in rows])

    own = [c for c in claims if c.get("origin", "paper") != "paper"]
    blocks: list[tuple] = [
        ("h2", "The paper's observations, claim by claim"),
        ("p", "Each observation the paper states in words, the quantity that tests it and its value under every "
              "model variant: contact laws (elastic; Kuwabara-Kono with one constant A; Kuwabara-Kono with A "
              "following each contact's collision time, so that every bead size has the same eps, as eq. 6 "
              "assumes; Kuwabara-Kono with A following the square of the collision time, a restitution falling "
              "with speed and a light striker's contact losing less; a dashpot following each contact pair, whose "
              "loss falls with the impact speed) and, "
              "for Fig. 3, the offset bead held rigidly on its line (the 1D model) or free across "
              "the axis in a groove, without and with friction. Verdict: reproduced by this run's own variant; "
              "partly when only the looser criterion holds or only another variant reproduces it."),
        ("p", f"Of the paper's {count['paper']} claims, this run's own variant reproduces {count['reproduced']}, "
              f"partly {count['partly']}, and not {count['not reproduced']}."),
        table([c for c in claims if c not in own], "claim (paper)"),
    ]
    if own:
        blocks += [("h3", "The project's own checks (not claims of the paper)"),
                   ("p", "The paper says nothing of these; the project added them (they weighed the choice of the "
                         "reproduction's contact law), so they are not counted as agreement with the paper."),
                   table(own, "check (project's own)")]
    explained = explained_by(claims)
    mark = {c["claim"]: " (project's own check)" for c in own}
    blocks += [("h3", "Which model explains which observation"),
               ("table", ["variant", "claims it reproduces"],
                [[v, "; ".join(c + mark.get(c, "") for c in cs) if cs else "none"] for v, cs in explained.items()])]
    laws = fid.get("laws") or {}
    if laws:
        rows = []
        for law, r in laws.items():
            for chain in ("chain1", "chain2"):
                c = r[chain]
                rows.append([law, chain[-1], _fmt(c["peak_force_ratio"]), _fmt(c["eq7_peak_force_ratio"]),
                             _fmt(c["eq7_peak_force_ratio_q0"]), _fmt(c["duration_ratio"]),
                             _fmt(c["eq8_duration_ratio"]), _fmt(c["eq8_duration_ratio_q0"])])
        blocks += [("h3", "F_m and tau along the chains under each contact law"),
                   ("table", ["law", "chain", "F_m(N)/F_m(16)", "eq. 7 (q)", "eq. 7 (q = 0)", "tau(N)/tau(16)",
                              "eq. 8 (q)", "eq. 8 speeds of q = 0, real phi_n"], rows)]
    mis = fid.get("misalignment") or {}
    if mis:
        rows = []
        for var, entries in mis.items():
            for name, r in entries.items():
                b, fr = name.split(":")
                rows.append([var, b, f"{100 * float(fr):.0f} %", f"{100 * r['peak_force_change']:+.2f} %",
                             f"{1e6 * r['time_of_flight_change_s']:+.1f}", f"{r['tail_oscillation']:.4f}",
                             _fmt(r.get("max_lateral_kinetic_energy")), _fmt(r.get("friction_loss"))])
        cost = fid.get("lateral_cost") or {}
        blocks += [("h3", "Fig. 3a-b with the offset bead rigid or free across the axis"),
                   ("table", ["variant", "bead", "offset e/phi", "change of F_m", "change of T [µs]",
                              "tail peak prominence [N]", "max transverse KE [J]", "friction loss [J]"], rows)]
        if _num(cost.get("ns_per_bead_step")) is not None:
            blocks.append(("p", f"The 2D runs took {cost['seconds']:.2f} s for {cost['bead_steps']:.3g} bead-steps "
                                f"({cost['ns_per_bead_step']:.1f} ns each, sampling every "
                                f"{(summary.get('settings') or {}).get('sample_interval', 0) * 1e9:g} ns and building the "
                                "results included; the stepping alone: benchmarks/lateral.py)."))
    for name, title in FIGURES.items():
        if name in figures:
            blocks.append(("figure", name, title, _png(figures[name]), FIGURE_NOTES[name],
                           "the numbers are in the tables and the claims above"))
    return blocks


def _png(path):
    from pathlib import Path

    p = Path(path if not isinstance(path, dict) else path.get("png"))
    return p if p.suffix.lower() == ".png" else p.with_suffix(".png")


#: What each variant figure shows (the numbers are in the tables above it).
FIGURE_NOTES = {
    "fig5_laws": "Peak force and duration of the wall pulse of the chains truncated after bead n, over their "
                 "values at n = 16, under each contact law, with eqs. 7-8 for eps = 1 and the paper's eps "
                 "(with the chain's q, and q = 0: dissipation alone; the durations all use the chain's real "
                 "diameters, tau_n = (phi_n/2) sqrt(10)/v_n, so the q = 0 one is not a uniform chain's).",
    "fig3_lateral": "Wall force of chain 2 with bead 22 or 28 offset by 5 % and 10 % of its diameter: held on "
                    "its line (1D model), free in a round groove, and in the groove with Coulomb friction; the "
                    "shaded band is the tail window where the paper sees the oscillation damped.",
}
