"""The reproduction report: ``report.md`` and a standalone ``report.html``.

:func:`write_report` turns the summary of a reproduction (the dict that
:mod:`hertzchain.paper.reproduce` writes to ``summary.json``) and the figure files into

- a table of simulated against the paper's measurements and statements with their relative
  difference and a verdict (error bars where the paper gives them: Q_fit; tolerances elsewhere),
  with the count of agreements, and apart from it the inputs (q, eps) and derived constants
  (Q^th, F_Y, delta_Y), which match by construction and are not counted;
- two sentences per figure: what it shows, and whether it agrees with the paper, written from
  the numbers (e.g. "Q_fit = 1.021 +- 0.001 lies inside the paper's error bar 1.025 +- 0.016");
- the two-speed check (the normalised results do not depend on the striker speed);
- per-bead tables of the wall pulse and the exact parameters of the run.

The HTML file embeds the figures as base64 PNG and has its CSS inline: it opens anywhere with no
other file, and its formulas are inline SVG drawn when it is written: it needs no network and no script.
Formulas are written as ASCII in the notes (``F_m``, ``tau``, ``Q^(n-n')``) and turned into TeX
(``$F_m$``, ``$\\tau$``) for both documents; figures are shown at one scale (their size in
inches). Both documents are generated from one list of blocks, so they always say the same:
this module assembles the blocks, :mod:`hertzchain.paper.notes` writes what they say (the
comparison table's rows, the figure notes) and :mod:`hertzchain.paper.render` turns them into
Markdown and HTML.

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

import math
from pathlib import Path
from typing import Any

from . import claims
from .notes import (CHAINS, Row, _diameters_m, _f, _pct, agreement_count, comparison_rows, figure_notes,
                    speed_sentence)
from .render import _to_html, _to_markdown
from ..laws import is_conservative

__all__ = ["Row", "agreement_count", "comparison_rows", "figure_notes", "speed_sentence", "write_report",
           "FIGURE_TITLES"]

#: Title of each figure in the report (the paper's numbering).
FIGURE_TITLES = {
    "fig1": "Fig. 1 - pulse evolution in chain 1 (q1 = 5.60 %)",
    "fig2": "Fig. 2 - pulse evolution in chain 2 (q2 = 8.27 %)",
    "fig3": "Fig. 3 - misalignment and local changes of the tapering",
    "fig4": "Fig. 4 - self-similar collapse of the front pulse",
    "fig5": "Fig. 5 - diameters, peak force, duration and momenta along the chains",
    "fig6": "Fig. 6 - time of flight and pulse velocity along the chains",
}


# ------------------------------------------------------------------------------------------
# document blocks (rendered by hertzchain.paper.render)
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


#: The contact laws in words.
LAW_WORDS = {"elastic": "elastic Hertz contacts (no dissipation)",
             "viscoelastic": "Kuwabara-Kono contacts with one time constant A",
             "viscoelastic_scaled": "Kuwabara-Kono contacts with A following each contact's collision time",
             "viscoelastic_sized": "Kuwabara-Kono contacts with A following the square of each contact's collision "
                                   "time (a restitution that falls with speed; the light striker's contact loses less)",
             "dashpot": "Hertz contacts with one linear dashpot gamma",
             "dashpot_scaled": "Hertz contacts with a linear dashpot following each contact pair "
                               "(gamma ~ kappa^(2/5) mu^(3/5): every pair the same restitution at a given speed)"}


def _dissipation_sentence(summary: dict, settings_desc: dict | None) -> str:
    """Which dissipation model the run uses, and the striker's two-body bounce under it."""
    desc = settings_desc or {}
    law = desc.get("law", "?")
    words = LAW_WORDS.get(law, law)
    if is_conservative(law):
        return f"Dissipation model: none, {words}."
    row = ((summary.get("fidelity") or {}).get("laws") or {}).get(law, {})
    e = row.get("striker_restitution")
    bounce = (f" Under it the 8 mm striker bounces off a free first bead with a two-body restitution of {e:.3f} at "
              f"{desc.get('striker_velocity', 0.2):g} m/s (steel balls: 0.95 or more)." if e is not None else "")
    return (f"Dissipation model: {words}, calibrated to the paper's eps = {desc.get('eps_target')} in the 26 mm "
            f"beads.{bounce}{_trend_sentence(row.get('restitution_trend'))} The claims below compare it with the "
            "other laws (which model explains which observation).")


def _trend_sentence(trend: Any) -> str:
    """The law's restitution against impact speed (``fidelity.laws.<law>.restitution_trend``), with the
    exponent of 1 - e ~ v^x between the two lowest speeds (viscoelastic spheres: x = 1/5); "" when
    the summary has no trend (an older one) or a damaged one."""
    speeds, e = (trend.get("speeds"), trend.get("restitution")) if isinstance(trend, dict) else (None, None)
    if not (isinstance(speeds, list) and isinstance(e, list) and len(speeds) == len(e) >= 2
            and all(isinstance(x, (int, float)) and not isinstance(x, bool) and 0 < x for x in speeds)
            and all(isinstance(x, (int, float)) and not isinstance(x, bool) and 0 <= x < 1 for x in e)):
        return ""
    x = math.log((1 - e[1]) / (1 - e[0])) / math.log(speeds[1] / speeds[0])
    way = "falls" if e[-1] < e[0] else "rises"
    return (f" Its restitution {way} with the impact speed: e = {', '.join(f'{v:.3f}' for v in e)} at "
            f"{', '.join(f'{v:g}' for v in speeds)} m/s (1 - e ~ v^({x:.2f}) between the two lowest; "
            "viscoelastic spheres: 1 - e ~ v^(1/5), falling).")


def _agreement_sentence(rows: list[Row]) -> str:
    """How many of the paper's measurements and statements the run agrees with (inputs not counted)."""
    agree, judged = agreement_count(rows)
    n_other = sum(r.kind != "measured" for r in rows)
    return (f"{agree} of the {judged} measurements and statements of the paper compared here agree with the "
            f"simulation. The {n_other} inputs and derived constants below are listed apart and not counted; "
            "the claims the paper states in words follow further down.")


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
        ("p", _dissipation_sentence(summary, settings_desc)),
        ("h2", "Simulated against the paper's measurements"),
        ("p", _agreement_sentence(rows)),
        ("table", ["quantity", "simulated", "paper", "relative difference", "verdict"],
         [[r.quantity, r.simulated, r.paper, _pct(r.rel), r.verdict] for r in rows if r.kind == "measured"]),
        ("h3", "Inputs and derived constants (set-up checks, not agreements)"),
        ("p", "The run takes the inputs from the paper (Table I's diameters, hence q; the eps its dissipation is "
              "calibrated to, measured back here) and the derived constants are the paper's formulas evaluated on "
              "them (eq. 8 for Q^th; Sec. II's yield estimate for F_Y and delta_Y): that they match shows the set-up "
              "is the paper's; it does not test the paper, and they are not counted above."),
        ("table", ["quantity", "what it is", "simulated", "paper", "relative difference", "check"],
         [[r.quantity, "input" if r.kind == "input" else "derived", r.simulated, r.paper, _pct(r.rel), r.verdict]
          for r in rows if r.kind != "measured"]),
        ("p", speed_sentence(summary)),
        ("h2", "Figures"),
    ]
    for name in sorted((n for n in figures if n not in claims.FIGURES), key=lambda n: (n not in FIGURE_TITLES, n)):
        what, agree = notes.get(name, ("", ""))
        blocks.append(("figure", name, FIGURE_TITLES.get(name, name), _figure_png(figures[name]), what, agree))
    blocks += claims.report_blocks(summary, figures)  # claims table and model variants (paper/claims.py)
    blocks.append(("h2", "Wall pulse along the chains"))
    for chain in CHAINS:
        table = _bead_table(summary, chain)
        if table:
            blocks.append(("h3", f"Chain {chain[-1]}"))
            blocks.append(("table",) + table)
    blocks.append(("h2", "Parameters of this run"))
    blocks.append(("table", ["parameter", "value"], _settings_rows(settings_desc, summary), "verbatim"))
    return blocks



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

