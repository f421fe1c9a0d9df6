"""``hertzchain summary``: the statistics of a sweep's or an ensemble's metrics, as a table and JSON."""

from __future__ import annotations

import math
from pathlib import Path

import click


@click.command("summary")
@click.argument("folder", type=click.Path(path_type=Path))
@click.option("--signal", "signals", multiple=True, metavar="METRIC",
              help="Metric to summarise (repeatable; default: every metric of the table).")
@click.option("--json", "json_path", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="Where to write the statistics as JSON (default: FOLDER/summary.json).")
@click.option("--quiet", "-q", is_flag=True, help="Write the JSON only, print no table.")
def summary(folder: Path, signals: tuple[str, ...], json_path: Path | None, quiet: bool) -> None:
    """Statistics of the members of a sweep or ensemble: FOLDER is its output folder (or its
    metrics.csv). Per metric: members with a value, mean, standard deviation, min, 5 %, median,
    95 %, max, in the units shown (JSON: SI units, named per metric)."""
    from ..fileio import json_text, write_text
    from ..sweep.statistics import read_metrics, summarize

    df = read_metrics(folder)
    stats = summarize(df, list(signals) or None)
    target = json_path or ((folder if folder.is_dir() else folder.parent) / "summary.json")
    source = folder / "metrics.csv" if folder.is_dir() else folder
    write_text(target, json_text({"source": str(source), **stats}))
    if quiet:
        return
    from rich.console import Console
    from rich.table import Table

    from ..sweep.statistics import display_unit

    title = f"{stats['n_members']} members of {source}"
    extra = []
    if stats.get("fit_failures"):
        extra.append(f"{stats['fit_failures']} without a fitted wall pulse")
    if stats.get("elastic_limit_exceeded"):
        extra.append(f"{stats['elastic_limit_exceeded']} past the elastic limit")
    from rich import box

    rows = []
    for name, st in stats["metrics"].items():
        unit, k = display_unit(st["units"], df[name].to_numpy(dtype=float))
        q = st["quantiles"]
        values = [st["mean"], st["std"], st["min"], q["0.05"], q["0.5"], q["0.95"], st["max"]]
        rows.append([name, unit or "-", str(st["n"]), *(_cell(v * k) for v in values)])
    heads = ["metric", "unit", "n", "mean", "std", "min", "5 %", "median", "95 %", "max"]
    console = Console()
    if not console.is_terminal:  # a pipe or a file: no screen to fit, every row on one line
        console = Console(width=200)
    caption = title + (f" ({'; '.join(extra)})" if extra else "")

    def tables(parts):
        out = []
        for k, cols in enumerate(parts):
            table = Table(title=caption if k == 0 else None, box=box.SIMPLE_HEAD)
            for i in cols:
                table.add_column(heads[i], justify="left" if i < 2 else "right", no_wrap=True)
            for r in rows:
                table.add_row(*(r[i] for i in cols))
            out.append(table)
        return out

    # One table when it fits the screen; else two (spread, then range), or three: every row of
    # every table on one line, no digit or unit cut off.
    for parts in ([list(range(10))], [[0, 1, 2, 3, 4], [0, 1, 5, 6, 7, 8, 9]], [[0, 1, 2, 3, 4], [0, 1, 5, 6, 7],
                                                                               [0, 1, 8, 9]]):
        layout = tables(parts)
        wide = console.options.update_width(10_000)  # the width a table wants, not the one it is given
        if all(console.measure(t, options=wide).maximum <= console.width for t in layout):
            break
    for table in layout:
        console.print(table)
    click.echo(f"wrote {target}")


def _cell(v: float) -> str:
    return "-" if not math.isfinite(v) else f"{v:.4g}"

