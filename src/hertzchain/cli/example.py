"""``hertzchain example``: the example configs shipped with the package, printed to stdout."""

from __future__ import annotations

import click


@click.command("example")
@click.argument("name", required=False)
def example(name: str | None) -> None:
    """Print the shipped example NAME to stdout; without NAME, list them.

    The configs and scope records of the repository's examples/ folder, installed with the
    package, so a wheel needs no clone:

        hertzchain example chain1 > chain1.toml && hertzchain run chain1.toml --out chain1.nc

    TOML names are run configs (chain1, contract, ... ; sweep_*, design_* and tolerance_ensemble
    for sweep and design); scope and scope_chain1_wall are oscilloscope CSV records.
    """
    from ..examples import example_names, example_summary, example_text

    if name is None:
        names = example_names()
        width = max(map(len, names))
        for n in names:
            click.echo(f"{n:<{width}}  {example_summary(n)}".rstrip())
        return
    click.echo(example_text(name), nl=False)
