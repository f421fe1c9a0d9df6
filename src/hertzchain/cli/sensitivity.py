"""``hertzchain sensitivity``: exact derivatives of a run's result with respect to config fields."""

from __future__ import annotations

from pathlib import Path
from typing import Literal

import click

from .common import parse_window, set_option, laws_option

#: The API's argument names (what its errors name) -> this command's options.
_OPTIONS = {"variables": "--wrt", "objective": "--objective", "window": "--window"}


@click.command("sensitivity")
@laws_option
@click.argument("config", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--wrt", "variables", multiple=True, required=True, metavar="PATH",
              help="Config field to differentiate by (repeatable): chain.diameters_mm (every bead), "
                   "chain.diameters_mm[20], chain.diameters_mm[16:30], striker.velocity, contact.A, "
                   "materials.AISI52100.young, a registry law's contact.exponent or contact.parameters.NAME, ...")
@click.option("--objective", default="peak_wall_force", show_default=True,
              help="Result to differentiate: peak_wall_force, peak_wall_time, time_of_flight, pulse_duration, "
                   "front_momentum_at_wall, energy_at_wall, peak_contact_force, peak_contact_force[j], "
                   "max_force_over_yield; a protected body's peak_body_force, peak_body_acceleration, "
                   "energy_to_body; the elastic-plastic law's plastic_work, residual_overlap_max.")
@click.option("--mode", type=click.Choice(["auto", "adjoint", "tangent"]), default="auto", show_default=True,
              help="Reverse (adjoint) or forward (tangent) differentiation; both give the same numbers; auto: the tangent "
                   "for one field, the adjoint for more (the cheaper of the two).")
@click.option("--window", default=None, metavar="T0,T1", help="Time window [ms] of energy_at_wall.")
@set_option
@click.option("--plot", "plot_path", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="Write a bar chart (per bead for list fields, elasticities for the others), e.g. sens.png.")
@click.option("--json", "json_path", is_flag=False, flag_value="-", default=None, metavar="PATH",
              help="Write the result as JSON to PATH; --json alone prints it instead of the table.")
def sensitivity(config: Path, variables: tuple[str, ...], objective: str, mode: Literal["auto", "adjoint", "tangent"],
                window: str | None, overrides: tuple[str, ...], plot_path: Path | None, json_path: str | None) -> None:
    """Derivatives of a result of CONFIG (TOML) by config fields, exact (discrete adjoint of the run).

    Each derivative is in the result's unit per the field's config unit (a diameter in mm: N/mm for
    the peak wall force); the elasticity (x / J) dJ/dx is the relative change per relative change.
    The derivative is that of the computed result on the step sequence the run used.
    """
    import math

    from ..config import load_config
    from ..fileio import json_text, write_text
    from ..gradients import sensitivity as compute
    from ..viz.common import image_format

    if plot_path is not None:
        image_format(plot_path, "--plot")  # a bad suffix fails before the run
    from ..errors import ConfigError

    cfg = load_config(config, overrides)
    try:
        sens = compute(cfg, list(variables), objective, mode=mode, window=parse_window(window))
    except ConfigError as exc:  # the API's argument names, as this command's options
        option = _OPTIONS.get(exc.field)
        if option is None:
            raise
        raise type(exc)(option, exc.message) from None
    data = sens.as_dict()
    if json_path == "-":
        click.echo(json_text(data))
    else:
        if json_path is not None:
            write_text(json_path, json_text(data) + "\n")
        from rich.console import Console
        from rich.table import Table

        table = Table(title=f"d {objective} / d field   ({objective} = {sens.value:.6g} {sens.unit}; {sens.mode}, "
                            f"{sens.n_steps} steps, {sens.elapsed_s:.2g} s)")
        for col in ("field", "value", "derivative", "unit", "elasticity"):
            table.add_column(col, justify="left" if col == "field" else "right")
        for row in data["variables"]:
            el = row["elasticity"]
            table.add_row(row["path"], "" if row["value"] is None or math.isnan(row["value"]) else f"{row['value']:.6g}",
                          f"{row['derivative']:.6g}", row["derivative_unit"], "" if el is None else f"{el:+.4g}")
        Console().print(table)
        beads = [r for r in data["variables"] if r["path"].startswith("chain.diameters_mm[")]
        if len(beads) > 1:
            top = max(beads, key=lambda r: abs(r["derivative"]))
            bead = int(top["path"].split("[")[1][:-1]) + 1
            click.echo(f"bead {bead} matters most: {top['derivative']:+.4g} {top['derivative_unit']}")
        for note in sens.notes:
            click.echo(f"note: {note}")
        if json_path is not None:
            click.echo(f"wrote {json_path}")
    if plot_path is not None:
        from ..viz.sensitivity import plot_sensitivity

        plot_sensitivity(sens, plot_path)
        if json_path != "-":
            click.echo(f"wrote {plot_path}")
