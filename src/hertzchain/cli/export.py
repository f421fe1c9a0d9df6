"""``hertzchain export``: a result as CSV, MATLAB or parquet for colleagues who do not read NetCDF."""

from __future__ import annotations

from pathlib import Path

import click

from .common import open_result


@click.command("export")
@click.argument("result", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--out", "-o", type=click.Path(dir_okay=False, path_type=Path), required=True,
              help="FILE.csv (signals, units in the header), FILE.mat (MATLAB variables with a units "
                   "struct) or FILE.parquet (needs the [export] extra).")
def export(result: Path, out: Path) -> None:
    """Write RESULT (a hertzchain .nc) as CSV, MATLAB or parquet, by the suffix of --out (SI units).

    A .mat file holds one variable per signal and coordinate (time [s], wall_force [N],
    contact_force as a time x contact matrix...), a struct `units` and a struct `attrs` (the run's
    config and model as JSON text).
    """
    from ..exporting import check_format
    from ..exporting import export as write
    from ..fileio import check_not_input

    check_format(out)  # a wrong suffix or a missing pyarrow is said before the file is read
    check_not_input(out, result)
    ds = open_result(result)
    write(ds, out)
    click.echo(f"wrote {out} ({ds.sizes['time']} samples)")
