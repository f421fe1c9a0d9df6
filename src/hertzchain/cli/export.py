"""``hertzchain export``: a result as CSV, MATLAB or parquet for colleagues who do not read NetCDF, and as
H5MD, VTK (ParaView) or LAMMPS input for particle codes."""

from __future__ import annotations

from pathlib import Path

import click

from .common import open_result


@click.command("export")
@click.argument("result", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--out", "-o", type=click.Path(dir_okay=False, path_type=Path), required=True,
              help="FILE.csv (signals, units in the header), FILE.mat (MATLAB variables with a units "
                   "struct), FILE.parquet (needs the [export] extra), FILE.h5md (H5MD trajectories), "
                   "FILE.pvd (ParaView, .vtp frames beside it) or FILE.data (LAMMPS, in.FILE beside it).")
@click.option("--frames", type=int, default=None, metavar="N",
              help="FILE.pvd only: N frames evenly spread over the run (default 200).")
def export(result: Path, out: Path, frames: int | None) -> None:
    """Write RESULT (a hertzchain .nc) in the format of the suffix of --out (SI units).

    A .mat file holds one variable per signal and coordinate (time [s], wall_force [N],
    contact_force as a time x contact matrix...), a struct `units` and a struct `attrs` (the run's
    config and model as JSON text). For particle codes: .h5md (H5MD 1.1, positions, velocities
    and forces of the striker and every bead; the run needs probes.positions), .pvd (a ParaView
    time series of the bodies with their diameters and forces) and .data (a LAMMPS data file of
    the chain at impact and the input script in.NAME of the run, elastic Hertz contacts).
    """
    from ..exporting import check_format
    from ..exporting import export as write
    from ..fileio import check_not_input

    from ..errors import ConfigError

    suffix = check_format(out)  # a wrong suffix or a missing pyarrow is said before the file is read
    if frames is not None and suffix != ".pvd":
        raise ConfigError("--frames", f"applies to FILE.pvd only, not to {suffix}")
    check_not_input(out, result)
    ds = open_result(result)
    write(ds, out, frames=frames)
    extra = {".pvd": "; its .vtp frames beside it", ".data": f"; input script {out.with_name('in.' + out.stem)}"}
    click.echo(f"wrote {out} ({ds.sizes['time']} samples{extra.get(suffix, '')})")
