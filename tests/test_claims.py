"""The claims table: verdicts follow the numbers (synthetic summaries, no simulation)."""

from __future__ import annotations

import copy

import pytest

from hertzchain.paper.claims import VERDICTS, build_claims, report_blocks


def _chain(f_ratio=0.6, eq7=0.6, eq7_q0=0.8, tau=0.35, eq8=0.35, eq8_q0=0.44, Q=1.02):
    return {"peak_force_ratio": f_ratio, "eq7_peak_force_ratio": eq7, "eq7_peak_force_ratio_q0": eq7_q0,
            "duration_ratio": tau, "eq8_duration_ratio": eq8, "eq8_duration_ratio_q0": eq8_q0,
            "Q_fit": Q, "Q_fit_err": 0.001, "tail_to_front": 1.0, "tail_to_front_at": {"28": 1.0},
            "momentum_spread": 0.02, "reflection_at_sensor": 0.01, "peak_force": [1.0, f_ratio], "duration": [1.0, tau], "beads": [16, 30]}


def _law(**kw):
    c2 = _chain(**kw)
    c2["tail_to_front_at"] = {"28": 2.0}
    return {"chain1": _chain(**kw), "chain2": c2,
            "figures": {"tof_gain_s": {"chain1": 1e-4, "chain2": 1e-4}, "collapse_rms": 0.004,
                        "spectra": {"chain1": {"centroid_in_hz": 5e3, "centroid_out_hz": 6e3},
                                    "chain2": {"centroid_in_hz": 5e3, "centroid_out_hz": 7e3}}}}


def _mis(drop=0.0009, tail=0.044):
    ref = {"peak_force_change": 0.0, "time_of_flight_change_s": 0.0, "tail_oscillation": 0.045}
    return {"22:0": ref, "22:0.1": {"peak_force_change": -drop, "time_of_flight_change_s": 1e-6,
                                    "tail_oscillation": tail}}


def _summary(main="viscoelastic"):
    return {"settings": {"law": main},
            "fidelity": {"laws": {"viscoelastic": _law(f_ratio=0.44), "viscoelastic_scaled": _law(f_ratio=0.58),
                                  "elastic": _law(f_ratio=0.67, eq7=0.8, eq7_q0=1.0)},
                         "misalignment": {"rigid": _mis(), "lateral": _mis(0.05, 0.02)}}}


def _row(claims, start):
    return next(c for c in claims if c["claim"].startswith(start))


def test_at_least_ten_rows_with_the_contract_keys():
    claims = build_claims(_summary())
    assert len(claims) >= 10
    for c in claims:
        assert {"claim", "quantity", "values", "verdict"} <= set(c) and c["verdict"] in VERDICTS


def test_verdicts_follow_the_numbers():
    claims = build_claims(_summary())
    eq7 = _row(claims, "The peak force follows eq. 7 with tapering reasonably well (chain 1)")
    assert eq7["values"]["viscoelastic"] == pytest.approx(0.44 / 0.6)
    assert eq7["verdicts"] == {"viscoelastic": "not reproduced", "viscoelastic_scaled": "reproduced",
                               "elastic": "partly"}
    # the run's own law does not reproduce it, another does: partly, and it says which
    assert eq7["verdict"] == "partly" and eq7["reproduced_by"] == ["viscoelastic_scaled"]
    # ... and with the size-scaled law as the run's own law, the same numbers reproduce it
    assert _row(build_claims(_summary("viscoelastic_scaled")), "The peak force follows eq. 7")["verdict"] == "reproduced"
    amp = _row(claims, "A misaligned bead lowers the amplitude slightly")
    assert amp["values"]["rigid"] == pytest.approx(0.09) and amp["verdicts"]["lateral"] == "reproduced"
    assert amp["verdict"] == "partly"
    tail = _row(claims, "A misaligned bead damps the tail")
    assert tail["values"]["lateral"] == pytest.approx(0.02 / 0.045)
    s = _summary()
    s["fidelity"]["misalignment"]["lateral"] = _mis(0.05, 0.045)
    assert _row(build_claims(s), "A misaligned bead damps the tail")["verdict"] == "not reproduced"


def test_missing_numbers_leave_rows_out_never_fail():
    s = _summary()
    del s["fidelity"]["misalignment"]
    partial = build_claims(s)
    assert len(partial) == len(build_claims(_summary())) - 3
    s2 = copy.deepcopy(_summary())
    del s2["fidelity"]["laws"]["elastic"]["chain1"]["Q_fit"]
    row = _row(build_claims(s2), "The pulse speeds up along the taper, v_n = Q^(n-n') v_n' with Q1")
    assert "elastic" not in row["verdicts"] and row["values"]["elastic"] is None
    assert build_claims({}) == []


def test_report_blocks_hold_the_table():
    s = _summary()
    s["claims"] = build_claims(s)
    blocks = report_blocks(s, {})
    table = next(b for b in blocks if b[0] == "table")
    assert len(table[2]) == len(s["claims"]) and table[1][-1] == "verdict"


def test_only_the_papers_claims_are_counted_and_the_projects_own_are_apart():
    """The striker's bounce is the project's own check (the paper says nothing of it): labelled as
    such, in its own table, and never in the count of the paper's claims reproduced."""
    from hertzchain.paper.claims import claims_count

    s = _summary("dashpot_scaled")
    laws = s["fidelity"]["laws"]
    laws["dashpot_scaled"] = _law(f_ratio=0.55)
    for law in laws.values():
        law["striker_restitution"], law["chain1"]["eps_measured"] = 0.96, 0.985
    claims = build_claims(s)
    own = [c for c in claims if c["origin"] == "project"]
    assert [c["claim"] for c in own] == ["The steel striker bounces off the first bead like a steel ball",
                                         "One dissipation gives both the chain's eps and a steel-like striker bounce"]
    assert all(c["verdict"] == "reproduced" and "project's own check" in c["source"] for c in own)
    paper = [c for c in claims if c["origin"] == "paper"]
    count = claims_count(claims)
    assert count["paper"] == len(paper) == len(claims) - 2 and count["project"] == 2
    assert count["reproduced"] == sum(c["verdict"] == "reproduced" for c in paper)  # the two passing checks left out
    assert count["reproduced"] + count["partly"] + count["not reproduced"] == count["paper"]
    s["claims"] = claims
    blocks = report_blocks(s, {})
    tables = [b for b in blocks if b[0] == "table"]
    assert tables[0][1][0] == "claim (paper)" and len(tables[0][2]) == count["paper"]
    assert tables[1][1][0] == "check (project's own)" and len(tables[1][2]) == 2
    said = next(b[1] for b in blocks if b[0] == "p" and b[1].startswith("Of the paper's"))
    assert said == (f"Of the paper's {count['paper']} claims, this run's own variant reproduces {count['reproduced']}, "
                    f"partly {count['partly']}, and not {count['not reproduced']}.")


def test_striker_bounce_and_one_dissipation_for_both_scales():
    """The striker's restitution is judged against steel balls (>= 0.95); the combined row only
    counts it for a variant whose chain measures the paper's eps back."""
    from hertzchain.paper.claims import explained_by

    s = _summary()
    laws = s["fidelity"]["laws"]
    laws["dashpot_scaled"] = _law(f_ratio=0.55)
    for law, e, eps in (("viscoelastic", 0.68, 0.9832), ("viscoelastic_scaled", 0.86, 0.9831),
                        ("dashpot_scaled", 0.958, 0.9842), ("elastic", 1.0, 0.9996)):
        laws[law]["striker_restitution"] = e
        laws[law]["chain1"]["eps_measured"] = eps
    claims = build_claims(s)
    bounce = _row(claims, "The steel striker bounces off the first bead")
    assert bounce["verdicts"] == {"viscoelastic": "not reproduced", "viscoelastic_scaled": "not reproduced",
                                  "dashpot_scaled": "reproduced", "elastic": "reproduced"}
    both = _row(claims, "One dissipation gives both")
    assert both["values"]["elastic"] == 0.0  # no eps: the elastic chain loses nothing
    assert both["reproduced_by"] == ["dashpot_scaled"] and both["verdict"] == "partly"
    s["settings"]["law"] = "dashpot_scaled"
    assert _row(build_claims(s), "One dissipation gives both")["verdict"] == "reproduced"
    assert "One dissipation gives both the chain's eps and a steel-like striker bounce" in \
        explained_by(claims)["dashpot_scaled"]
    s["claims"] = claims
    blocks = report_blocks(s, {})
    which = blocks[[b[:2] for b in blocks].index(("h3", "Which model explains which observation")) + 1]
    assert [r[0] for r in which[2]] == list(explained_by(claims))


def test_report_states_the_dissipation_model_and_the_strikers_bounce():
    from hertzchain.paper.report import _dissipation_sentence

    s = _summary("dashpot_scaled")
    s["fidelity"]["laws"]["dashpot_scaled"] = {"striker_restitution": 0.958146}
    text = _dissipation_sentence(s, {"law": "dashpot_scaled", "eps_target": 0.985, "striker_velocity": 0.2})
    assert "dashpot following each contact pair" in text and "0.958 at 0.2 m/s" in text and "0.985" in text
    assert "none" in _dissipation_sentence(s, {"law": "elastic"})


def test_comparison_counts_only_the_papers_measurements():
    """q, sigma_q (Table I's diameters, an input), eps (the calibration target), Q^th (eq. 8), F_Y and
    delta_Y (Sec. II's formula) match by construction: listed apart, never counted as agreements.
    Counted: Q1, Q2 against the paper's error bars, the wall/chain ratios (within 5 %) and the
    elastic-limit statement."""
    from hertzchain.paper.notes import agreement_count, comparison_rows
    from hertzchain.paper.report import _blocks
    from hertzchain.paper.values import PAPER

    summary = {c: {k: PAPER[c][k] for k in ("q", "q_std", "Q_theory")} for c in ("chain1", "chain2")}
    summary["chain1"].update(Q_fit=1.018, Q_fit_err=0.001)   # inside 1.025 +- 0.016
    summary["chain2"].update(Q_fit=1.20, Q_fit_err=0.002)    # outside 1.049 +- 0.044
    summary.update(eps=0.9842, eps_err=1e-4, wall_to_chain_force_ratio=1.94, wall_to_chain_duration_ratio=1.25,
                   yield_force=474.0, yield_overlap=11.2e-6, max_force_over_yield=0.34)
    desc = {"eps_target": 0.985, "law": "dashpot_scaled"}
    rows = comparison_rows(summary, desc)
    kinds = {r.quantity.split(" (")[0]: r.kind for r in rows}
    assert [q for q, k in kinds.items() if k == "measured"] == [
        "chain 1: Q1", "chain 2: Q2", "wall/chain peak-force ratio F_m^wall / F_m^chain",
        "wall/chain duration ratio tau_wall / tau_chain", "largest contact force / its yield force"]
    assert {q for q, k in kinds.items() if k == "derived"} == {
        "chain 1: Q1^th", "chain 2: Q2^th", "yield force F_Y of two 26 mm beads", "yield overlap delta_Y of two 26 mm beads"}
    assert sum(k == "input" for k in kinds.values()) == 5  # q and sigma_q of both chains, eps measured back
    # Q1 inside, Q2 outside, force ratio within 5 %, duration ratio off by 15 %, elastic: 3 of 5
    assert agreement_count(rows) == (3, 5)
    assert not any("agrees" in r.verdict for r in rows if r.kind != "measured")  # inputs "match", never "agree"
    blocks = _blocks(summary, {}, desc)
    i = blocks.index(("h2", "Simulated against the paper's measurements"))
    assert blocks[i + 1][1].startswith("3 of the 5 measurements and statements of the paper compared here agree")
    assert len(blocks[i + 2][2]) == 5 and len(blocks[i + 5][2]) == 9  # counted table, then inputs + derived apart
    assert {row[1] for row in blocks[i + 5][2]} == {"input", "derived"}
