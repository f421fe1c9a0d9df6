"""``hertzchain reproduce``: the paper's figures, numbers and report (or redraw them from data)."""

from __future__ import annotations

from pathlib import Path

import click

from .common import echo_warning, freeze_imports, progress_bar


@click.command("reproduce")
@click.option("--out", "-o", type=click.Path(file_okay=False, path_type=Path), default=Path("reproduction"),
              show_default=True, help="Folder for figures, data, summary.json and the report.")
@click.option("--velocity", type=float, default=0.2, show_default=True,
              help="Striker speed [m/s] (not given in the paper; normalised results do not depend on it).")
@click.option("--elastic", is_flag=True, help="No dissipation (default: calibrated to the paper's eps = 0.985).")
@click.option("--law", type=click.Choice(["dashpot_scaled", "viscoelastic_sized", "viscoelastic", "viscoelastic_scaled",
                                          "dashpot"]),
              default="dashpot_scaled", show_default=True,
              help="Dissipative contact law calibrated to eps (dashpot_scaled: a dashpot following each contact pair, "
              "the striker bounces like a steel ball but the restitution rises with speed; viscoelastic_sized: "
              "Kuwabara-Kono, A following the square of each contact's collision time, a steel-like bounce and a "
              "restitution falling with speed; viscoelastic: Kuwabara-Kono, one A; "
              "viscoelastic_scaled: Kuwabara-Kono, A following each contact's collision time).")
@click.option("--eps", type=float, default=0.985, show_default=True, help="Per-bead factor eps to calibrate to.")
@click.option("--no-figures", is_flag=True, help="Only data and summary.json.")
@click.option("--from-data", is_flag=True, help="Redraw figures and report from OUT/data without simulating.")
def reproduce(out: Path, velocity: float, elastic: bool, law: str, eps: float, no_figures: bool,
              from_data: bool) -> None:
    """Reproduce the paper (Figures 1-6, its numbers, a report) in well under a minute."""
    from ..errors import ConfigError

    if from_data:
        from ..paper.early import start_laws_figure

        laws_figure = start_laws_figure(out)  # drawn on the idle core while the imports below run
        from ..paper.reproduce import FIGURE_NAMES, redraw

        freeze_imports()
        with progress_bar("redrawing figures and report", lazy=True) as update:  # errors first, no bar
            done = [0]

            def step(msg: str) -> None:
                done[0] += 1
                update(done[0], len(FIGURE_NAMES) + 2)

            summary = redraw(out, progress=step, laws_figure=laws_figure)
        _echo_elastic_limit(summary)
        click.echo(f"redrew the figures and the report in {out}/ from {out}/data")
        return

    if not (velocity > 0 and velocity < 10):
        raise ConfigError("--velocity", f"must be a striker speed in (0, 10) m/s, got {velocity}")
    if not (0 < eps <= 1):
        raise ConfigError("--eps", f"must lie in (0, 1], got {eps}")
    from ..paper.protocol import Settings
    from ..paper.reproduce import count_steps, reproduce as run_reproduction

    freeze_imports()
    settings = Settings(striker_velocity=velocity, elastic=elastic, law=law, eps=eps)
    total = count_steps(settings, figures=not no_figures)
    with progress_bar("reproducing the paper") as update:
        done = [0]

        def tick(msg: str) -> None:
            done[0] += 1
            update(done[0], total)

        summary = run_reproduction(out, settings, progress=tick, figures=not no_figures)
    _echo_elastic_limit(summary)
    c1, c2 = summary["chain1"], summary["chain2"]
    click.echo(f"wrote {out}/ in {summary['timing']['total_s']:.1f} s: "
               f"Q1 = {c1['Q_fit']:.4f} +- {c1['Q_fit_err']:.4f} (theory {c1['Q_theory']:.4f}, paper 1.025 +- 0.016), "
               f"Q2 = {c2['Q_fit']:.4f} +- {c2['Q_fit_err']:.4f} (theory {c2['Q_theory']:.4f}, paper 1.049 +- 0.044), "
               f"eps = {summary['eps']:.4f}")


def _echo_elastic_limit(summary: dict) -> None:
    """Say on the console when a reproduction's contact forces pass the elastic limit."""
    msg = (summary.get("elastic_limit") or {}).get("message")
    if msg:
        echo_warning(msg)
