"""``hertzchain compare``: a measured pulse next to a simulated one, with the residual."""

from __future__ import annotations

from pathlib import Path

import click

from .common import UnitsTable, open_result, signal_frame, trace_options


def simulated_signal(source: Path, signal: str):
    """The simulated force ``signal`` (``wall_force``, ``sensor_force:N``...) of a result or a run config."""
    from ..errors import ConfigError

    if not source.exists():
        raise ConfigError(str(source), "no such file")
    if source.suffix.lower() == ".toml":
        from ..config import run_config

        ds = run_config(source)
    else:
        ds = open_result(source)
    name, _, index = signal.partition(":")
    da = signal_frame(ds, name)[name]
    extra = [d for d in da.dims if d != "time"]
    if extra:
        if not index:
            raise ConfigError("--signal", f"{name} has one trace per {extra[0]} ({list(da[extra[0]].values)}): "
                              f"choose one as {name}:{da[extra[0]].values[0]}")
        try:
            da = da.sel({extra[0]: int(index)})
        except (KeyError, ValueError):
            raise ConfigError("--signal", f"{name} has no {extra[0]} {index}; "
                              f"available: {list(da[extra[0]].values)}") from None
    t = da["time"].values
    if t.dtype.kind == "m":
        import numpy as np

        da = da.assign_coords(time=t / np.timedelta64(1, "s"))
    return da


@click.command("compare")
@click.argument("measured", type=click.Path(dir_okay=False, path_type=Path))
@click.argument("simulated", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--out", "-o", type=click.Path(dir_okay=False, path_type=Path), required=True,
              help="Figure to write (.png, .pdf or .svg): overlay and residual.")
@click.option("--json", "json_path", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="Also write the numbers as JSON (SI units).")
@click.option("--signal", default="wall_force", show_default=True,
              help="Simulated signal to compare with: wall_force, sensor_force:N, measured_wall_force...")
@click.option("--align", type=click.Choice(["fit", "xcorr"]), default="fit", show_default=True,
              help="Put the simulation on the measured clock by equal fitted T, or by cross-correlation.")
@trace_options
def compare(measured: Path, simulated: Path, out: Path, json_path: Path | None, signal: str, align: str,
            column: str | None, sensitivity: float | None, sensor: str | None, time_unit: str | None) -> None:
    """Compare a MEASURED scope file with a SIMULATED result (.nc) or run config (.toml).

    Both pulses are fitted as in the paper (F_m cos^6((t - T)/tau), Sec. III); the table gives the
    differences simulated - measured of F_m, T and tau and the rms residual after alignment.
    """
    from ..fileio import json_text, write_text
    from ..lab.compare import compare_traces
    from ..lab.readers import read_trace
    from ..lab.report import plot_comparison
    from ..viz.common import image_format

    image_format(out)  # an unknown --out suffix is refused before anything is read or simulated
    meas = read_trace(measured, column, sensitivity=sensitivity, sensor=sensor, time_unit=time_unit)
    sim = simulated_signal(simulated, signal)
    comp = compare_traces(meas, sim, align=align)
    plot_comparison(comp, out, measured_label=measured.name, simulated_label=f"{simulated.name} {signal}")
    numbers = comp.as_json()
    if json_path is not None:
        write_text(json_path, json_text(numbers) + "\n")
    table = UnitsTable(f"{measured.name} vs {simulated.name} ({signal}), aligned by {align}",
                       [("", None), ("F_m", "N"), ("T", "ms"), ("tau", "us")])
    for label, p in (("measured", comp.measured), ("simulated", comp.simulated)):
        table.add_row(label, f"{p['peak_force']:.4g}", f"{p['time_of_flight'] * 1e3:.5g}", f"{p['duration'] * 1e6:.4g}")
    table.add_row("sim - meas", f"{comp.peak_force_diff:+.3g}", f"{comp.time_of_flight_diff * 1e3:+.4g}",
                  f"{comp.duration_diff * 1e6:+.3g}")
    table.print()
    click.echo(f"rms residual {comp.rms_residual:.4g} N after a shift of {comp.shift * 1e3:+.5g} ms; wrote {out}"
               + (f" and {json_path}" if json_path else ""))
