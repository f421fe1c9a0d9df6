"""``hertzchain dispersion``: the band structure of the periodic chain whose period is a config's chain."""

from __future__ import annotations

import json
from pathlib import Path

import click


@click.command("dispersion")
@click.argument("config", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--points", type=click.IntRange(2, 100_000), default=201, show_default=True,
              help="Wavenumbers from 0 to pi.")
@click.option("--json", "json_path", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="Write the branches' ranges and the gaps [Hz] as JSON here.")
@click.option("--out", type=click.Path(file_okay=False, path_type=Path), default=None,
              help="Folder for dispersion.nc (frequency over wavenumber and branch) and dispersion.png.")
def dispersion(config: Path, points: int, json_path: Path | None, out: Path | None) -> None:
    """Bloch band structure of an endless repetition of CONFIG's chain (one period: any beads,
    materials, mass-in-mass elements) under chain.precompression [N]: each branch's range and the
    band gaps [Hz]; wavenumbers in radians per period."""
    from rich.console import Console
    from rich.table import Table

    from ..config.build import build_chain
    from ..config.loading import load_config
    from ..crystal.dispersion import dispersion as compute
    from ..fileio import json_text, write_text

    cfg = load_config(config)
    ds = compute(build_chain(cfg), cfg.chain.precompression, points=points)
    gaps = ds.attrs["gaps"]
    f = ds.frequency.values
    data = {"precompression_N": cfg.chain.precompression,
            "branches_Hz": [[float(f[:, b].min()), float(f[:, b].max())] for b in range(f.shape[1])],
            "gaps_Hz": gaps}
    if json_path is not None:
        write_text(json_path, json_text(data))
    if out is not None:
        from ..crystal.figures import plot_dispersion
        from ..fileio import atomic_path, write_bytes

        out.mkdir(parents=True, exist_ok=True)
        stored = ds.copy()
        stored.attrs["gaps"] = json.dumps(gaps)  # NetCDF attributes hold no nested lists
        stored.attrs["stiffness"] = json.dumps(ds.attrs["stiffness"])
        write_bytes(out / "dispersion.nc", stored.to_netcdf())
        fig = plot_dispersion(ds)
        with atomic_path(out / "dispersion.png") as tmp:
            fig.savefig(tmp, format="png", dpi=120)
    table = Table(title=f"band structure of {config.name} at {cfg.chain.precompression:g} N")
    for head in ("branch", "from [Hz]", "to [Hz]"):
        table.add_column(head, justify="right", no_wrap=True)
    for b, (lo, hi) in enumerate(data["branches_Hz"]):
        table.add_row(str(b), f"{lo:.6g}", f"{hi:.6g}")
    console = Console()
    console.print(table)
    click.echo("gaps: " + (", ".join(f"{lo:.6g}-{hi:.6g} Hz" for lo, hi in gaps) if gaps else "none"))
    if json_path is not None:
        click.echo(f"wrote {json_path}")
    if out is not None:
        click.echo(f"wrote {out / 'dispersion.nc'} and {out / 'dispersion.png'}")
