"""``hertzchain analyze``: the paper's pulse fits (Sec. III) on a result or a measured scope file."""

from __future__ import annotations

from pathlib import Path

import click

from .common import UnitsTable, open_result, signal_frame, trace_options

_NETCDF = (".nc", ".nc4", ".netcdf", ".cdf", ".h5")


@click.command("analyze")
@click.argument("source", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--signal", "signals", multiple=True,
              help="Result signals: wall_force, sensor_force, contact_force, measured_wall_force, "
                   "measured_sensor_force (repeatable; default wall and sensors).")
@trace_options
@click.option("--tail-end", type=float, default=None, metavar="SECONDS",
              help="Time [s] where the tail momentum Q_T stops (before a reflected pulse comes back).")
@click.option("--json", "json_path", is_flag=False, flag_value="-", default=None, metavar="PATH",
              help="Write the rows as JSON to PATH (SI units, named in each row's \"units\"); --json alone prints "
                   "them instead of the table. Exit status 2 when no pulse could be fitted.")
def analyze(source: Path, signals: tuple[str, ...], column: str | None, sensitivity: float | None,
            sensor: str | None, time_unit: str | None, tail_end: float | None, json_path: str | None) -> None:
    """Fit every chosen pulse of SOURCE (a result .nc, or a measured scope file) as in the paper.

    The loading part of each pulse is fitted with F_m cos^6((t - T)/tau) (paper Sec. III); the front
    and tail momenta Q_F, Q_T are the integrals before and after T + tau (up to --tail-end).
    Scope files: delimited text in any usual spelling, Tektronix CSV/.isf, PicoScope CSV/TXT,
    LeCroy .trc; volts become newtons with --sensitivity or --sensor.
    """
    import math

    from ..analysis import analyze_signals
    from ..analysis.io import ROW_UNITS
    from ..errors import ConfigError
    from ..fileio import json_text, write_text

    if not source.exists():
        raise ConfigError(str(source), "no such file")
    if tail_end is not None and not (math.isfinite(tail_end) and tail_end > 0):
        raise ConfigError("--tail-end", f"must be a positive time in s, got {tail_end}")
    units_note = "a hertzchain result"
    if source.suffix.lower() in _NETCDF:
        if sensitivity is not None or sensor is not None or time_unit is not None:
            raise ConfigError("--sensitivity", "a hertzchain result is already in SI units (N, s); "
                              "--sensitivity, --sensor and --time-unit apply to scope files")
        ds = open_result(source)
        if column is not None:
            signals = signals + (column,)
        chosen = signals or tuple(s for s in ("wall_force", "sensor_force") if s in ds) or ("contact_force",)
        rows = []
        for name in chosen:
            frame = signal_frame(ds, name)
            if name == "wall_force" and "static_wall_force" in ds.attrs:
                # under gravity the pulse stands on the weights: fit what the impact adds (the dynamic part)
                frame = frame - float(ds.attrs["static_wall_force"])
            if tail_end is not None:
                frame = frame.sel(time=slice(None, tail_end))
            rows += analyze_signals(frame, signals=(name,))
    else:
        from ..lab.readers import read_trace

        da = read_trace(source, column, sensitivity=sensitivity, sensor=sensor, time_unit=time_unit, baseline=False)
        if tail_end is not None:
            da = da.sel(time=slice(None, tail_end))
            if da.size < 10:
                raise ConfigError("--tail-end", f"{tail_end} s leaves {da.size} samples of {source.name}")
        rows = analyze_signals(da.to_dataset(name=da.name), signals=(da.name,))
        units_note = f"read with time in {da.attrs['time_unit']}, signal in {da.attrs['raw_unit']}"
        if not math.isnan(da.attrs["sensitivity_mV_per_N"]):
            units_note += f" / {da.attrs['sensitivity_mV_per_N']:g} mV/N"
    failed = all(r.get("error") for r in rows)
    # NaN (a failed fit) becomes null: valid JSON. Every row says the units of its numbers (SI).
    out_rows = [{**r, "units": dict(ROW_UNITS)} for r in rows]
    if json_path == "-":
        click.echo(json_text(out_rows))
    else:
        if json_path is not None:
            write_text(json_path, json_text(out_rows) + "\n")
        table = UnitsTable(f"pulse fits of {source.name} ({units_note}): loading part, F_m cos^6((t-T)/tau)",
                            [("signal", None), ("F_m", "N"), ("T", "ms"), ("tau", "us"), ("Q_F", "mN s"),
                             ("Q_T", "mN s")])
        for r in rows:
            label = r["signal"] + ("" if r.get("index") is None else f"[{r['index']}]")
            if r.get("error"):
                table.add_row(label, r["error"], "", "", "", "", style="red")
                continue
            table.add_row(label, f"{r['peak_force']:.4g} ± {r['peak_force_err']:.1g}",
                          f"{r['time_of_flight'] * 1e3:.5g} ± {r['time_of_flight_err'] * 1e3:.1g}",
                          f"{r['duration'] * 1e6:.4g} ± {r['duration_err'] * 1e6:.1g}",
                          f"{r['front_momentum'] * 1e3:.4g}", f"{r['tail_momentum'] * 1e3:.4g}")
        table.print()
        if source.suffix.lower() in _NETCDF and "peak_wall_force_dynamic" in ds.attrs:
            # under gravity the wall force stands on the weight: the impact's own part beside the total
            click.echo(f"peak wall force {ds.attrs['peak_wall_force']:.4g} N = {ds.attrs['static_wall_force']:.4g} N "
                       f"static (the weights) + {ds.attrs['peak_wall_force_dynamic']:.4g} N dynamic; the wall_force "
                       "fit is of the dynamic part")
        if json_path is not None:
            click.echo(f"wrote {json_path}")
    if failed:
        raise ConfigError(str(source), f"no pulse could be fitted in any of its {len(rows)} signal(s) (the reasons "
                          "are in the table): " + "; ".join(f"{r['signal']}: {r['error']}" for r in rows[:3]))
