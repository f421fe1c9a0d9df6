"""``hertzchain plot``: draw a result, or a sweep's metrics table.

Heavy imports (matplotlib, xarray) are deferred into the command so that ``--help`` is quick.
"""

from __future__ import annotations

from pathlib import Path

import click

from .common import open_result, parse_window


@click.command("plot")
@click.argument("result", type=click.Path(path_type=Path))
@click.option("--out", "-o", type=click.Path(dir_okay=False, path_type=Path), required=True,
              help="Image file (PNG, PDF or SVG).")
@click.option("--kind", type=click.Choice(["signals", "spacetime", "energy", "histogram", "corner"]), default="signals",
              show_default=True,
              help="signals: one panel per signal; spacetime: contact forces, contact against time; "
                   "energy: kinetic, potential, dissipated and total. Of a sweep's metrics: histogram "
                   "(one per --signal METRIC) or corner (every pair of metrics), statistics written on them.")
@click.option("--window", metavar="T0,T1", default=None, help="Time range to show [ms], e.g. 1.5,2.5.")
@click.option("--member", type=int, default=None,
              help="Run of a batch or sweep chunk to draw (the member number of metrics.csv).")
@click.option("--signal", "signals", multiple=True,
              help="--kind signals: wall_force, sensor_force, contact_force, measured_wall_force, "
                   "measured_sensor_force, velocity, displacement (repeatable).")
@click.option("--contact", "contacts", multiple=True, type=int, help="Contacts to draw with --signal contact_force.")
@click.option("--scale", type=click.Choice(["linear", "log"]), default="linear", show_default=True,
              help="--kind spacetime: colour scale of the force.")
@click.option("--to-scale", is_flag=True, help="--kind spacetime: contacts at their positions along the chain [mm].")
@click.option("--vmax", type=float, default=None, metavar="N",
              help="--kind spacetime: top of the colour scale [N] (default: the largest force in the chain, "
                   "the short striker contact drawn saturated).")
def plot(result: Path, out: Path, kind: str, window: str | None, member: int | None, signals: tuple[str, ...],
         contacts: tuple[int, ...], scale: str, to_scale: bool, vmax: float | None) -> None:
    """Draw RESULT into an image: a hertzchain .nc (a run, a batch or a sweep chunk), or a sweep's
    metrics (its output folder or metrics.csv): --signal METRIC against the swept parameters, or,
    for an ensemble (no swept parameter) or with --kind histogram / corner, the members'
    distribution with its mean, standard deviation and quantiles."""
    from ..errors import ConfigError
    from ..fileio import check_not_input
    from ..viz.common import image_format

    image_format(out)  # an unknown --out suffix is refused before the file is read
    check_not_input(out, result)
    if result.is_dir() or result.suffix.lower() == ".csv":  # a sweep's metrics: --signal names the metric
        click.echo(f"wrote {_plot_table(result, out, kind, signals)}")
        return
    if kind in ("histogram", "corner"):
        raise ConfigError("--kind", f"{kind} draws a sweep's metrics (its folder or metrics.csv), not {result.name}")
    span = parse_window(window)
    if kind != "signals" and (signals or contacts):
        raise ConfigError("--signal", f"--signal and --contact go with --kind signals, not --kind {kind}")
    if kind != "spacetime" and (scale != "linear" or to_scale or vmax is not None):
        raise ConfigError("--scale", f"--scale, --to-scale and --vmax go with --kind spacetime, not --kind {kind}")
    ds = open_result(result)
    if kind == "signals":
        from ..viz.signals import plot_signals

        plot_signals(ds, out, signals or None, contacts or None, window=span, member=member)
    elif kind == "spacetime":
        from ..viz.spacetime import plot_spacetime

        plot_spacetime(ds, out, scale=scale, to_scale=to_scale, window=span, member=member,
                       vmax="auto" if vmax is None else vmax)
    else:
        from ..viz.energy import plot_energy

        plot_energy(ds, out, window=span, member=member)
    click.echo(f"wrote {out}")


def _plot_table(path: Path, out: Path, kind: str, signals: tuple[str, ...]) -> Path:
    """A sweep's metrics: against the swept parameters (kind signals, a sweep with parameters),
    else histograms or a corner plot of the members."""
    from ..errors import ConfigError
    from ..sweep.statistics import read_metrics
    from ..viz.metrics import plot_metrics, swept_parameters

    if kind in ("spacetime", "energy"):
        raise ConfigError("--kind", f"{kind} draws a result file (.nc); a sweep's metrics are drawn with --kind "
                          "signals, histogram or corner")
    csv = path / "metrics.csv" if path.is_dir() else path
    if kind == "signals" and swept_parameters(read_metrics(csv)):
        return plot_metrics(csv, out, *signals[:1])
    from ..viz.ensemble import plot_ensemble

    return plot_ensemble(csv, out, signals or None, kind="corner" if kind == "corner" else "histogram")
