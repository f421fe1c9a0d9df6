"""``hertzchain modes``: the normal modes of a config's chain about its static equilibrium."""

from __future__ import annotations

from pathlib import Path

import click


@click.command("modes")
@click.argument("config", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--json", "json_path", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="Write frequencies [Hz], participation, labels and shapes as JSON here.")
@click.option("--out", type=click.Path(file_okay=False, path_type=Path), default=None,
              help="Folder for modes.png (the lowest mode shapes) and modes.json.")
@click.option("--count", type=click.IntRange(1, 10_000), default=20, show_default=True,
              help="Modes listed in the table (from the lowest).")
def modes(config: Path, json_path: Path | None, out: Path | None, count: int) -> None:
    """Normal modes of CONFIG's chain linearised about its static equilibrium (precompression,
    gravity, [load]): frequencies [Hz] and each mode's effective mass fraction along the chain."""
    from rich.console import Console
    from rich.table import Table

    from ..config.build import build_model
    from ..config.loading import load_config
    from ..crystal.modes import modes as compute
    from ..fileio import json_text, write_text

    model = build_model(load_config(config))
    mds = compute(model)
    data = {"frequencies_Hz": mds.frequencies.tolist(), "participation": mds.participation.tolist(),
            "labels": mds.labels, "shapes": mds.shapes.tolist()}
    if json_path is not None:
        write_text(json_path, json_text(data))
    if out is not None:
        from ..crystal.figures import plot_modes
        from ..fileio import atomic_path

        out.mkdir(parents=True, exist_ok=True)
        write_text(out / "modes.json", json_text(data))
        fig = plot_modes(mds)
        with atomic_path(out / "modes.png") as tmp:
            fig.savefig(tmp, format="png", dpi=120)
    table = Table(title=f"normal modes of {config.name}")
    for head in ("mode", "frequency [Hz]", "mass fraction"):
        table.add_column(head, justify="right", no_wrap=True)
    for k in range(min(count, mds.frequencies.size)):
        table.add_row(str(k + 1), f"{mds.frequencies[k]:.6g}", f"{mds.participation[k]:.4f}")
    Console().print(table)
    for target in (json_path, None if out is None else out / "modes.json"):
        if target is not None:
            click.echo(f"wrote {target}")
