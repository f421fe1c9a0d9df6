"""``hertzchain materials``: the material catalogue."""

from __future__ import annotations

import click


@click.command("materials")
def materials() -> None:
    """List the material catalogue (SI units) with sources."""
    from ..materials import CATALOGUE

    for m in CATALOGUE.values():
        ys = "-" if m.yield_stress is None else f"{m.yield_stress:.3g}"
        click.echo(f"{m.name:16s} rho={m.density:<7g} Y={m.young:<9.3g} nu={m.poisson:<5g} sigma_Y={ys:<8s} ({m.source})")
