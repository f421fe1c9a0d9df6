"""``hertzchain fit``: calibrate config fields on measured traces (least squares, exact Jacobian)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import click

from .common import UnitsTable, dask_client, echo_warning, progress_bar, set_option, trace_options, laws_option

#: Per-trace keys of a MEASURED argument that say how to read the file (the rest are config paths).
READ_KEYS = ("column", "sensitivity", "sensor", "time_unit")


def parse_measured(item: str) -> tuple[Path, str | None, list[str], dict]:
    """``FILE[@KEY=VALUE...]`` -> (file, signal, config overrides, read options).

    KEY is ``signal`` (``wall`` or ``sensor:N``), one of :data:`READ_KEYS` (how to read this
    file: ``column=CH2``, ``sensor=pcb_200b02``, ``sensitivity=11.0``, ``time_unit=us``), or a
    dotted config path for this trace only (``chain.truncate=16``).
    """
    from ..errors import ConfigError

    if Path(item).exists() or "@" not in item:
        return Path(item), None, [], {}
    name, *settings = item.split("@")
    signal, overrides = None, []
    read: dict[str, Any] = {}
    for s in settings:
        key, eq, value = s.partition("=")
        if not eq:
            raise ConfigError(item, f"{s!r} is not KEY=VALUE (e.g. {name}@chain.truncate=16@signal=wall)")
        if key == "signal":
            signal = value
        elif key in READ_KEYS:
            if key == "sensitivity":
                try:
                    read[key] = float(value)
                except ValueError:
                    raise ConfigError(item, f"sensitivity={value!r} is not a number (mV/N)") from None
            else:
                read[key] = value
        else:
            overrides.append(s)
    return Path(name), signal, overrides, read


@click.command("fit")
@laws_option
@click.argument("config", type=click.Path(dir_okay=False, path_type=Path))
@click.argument("measured", nargs=-1, required=True)
@click.option("--free", "free", multiple=True, required=True, metavar="DOTTED.PATH",
              help="Parameter to fit (repeatable): a numeric config field (striker.velocity, contact.A, "
                   "materials.NAME.young...) or gain, time_offset, baseline.")
@click.option("--out", "-o", type=click.Path(file_okay=False, path_type=Path), required=True,
              help="Folder for fit.json, calibrated.toml, fit.png and fit.html.")
@click.option("--signal", default="wall", show_default=True,
              help="What the traces measure: wall, or sensor:N (bead N); per trace as FILE@signal=sensor:12.")
@trace_options
@set_option
@click.option("--max-evaluations", type=int, default=100, show_default=True,
              help="Most model evaluations (each one run per trace).")
@click.option("--jacobian", type=click.Choice(["exact", "differences"]), default="exact", show_default=True,
              help="The config fields' columns of the Jacobian: exact (the tangent model, docs: Sensitivities) "
                   "or forward finite differences (one batched run per field).")
@click.option("--bootstrap", type=int, default=0, metavar="N",
              help="Also N residual-bootstrap refits: errors that do not assume a linear model (N x the fit's cost).")
@click.option("--scheduler", default=None, metavar="ADDRESS",
              help="Dask scheduler address (e.g. tcp://host:8786): the --bootstrap refits run on its workers.")
@click.option("--quiet", "-q", is_flag=True, help="No progress bar or table.")
def fit(config: Path, measured: tuple[str, ...], free: tuple[str, ...], out: Path, signal: str, column: str | None,
        sensitivity: float | None, sensor: str | None, time_unit: str | None, overrides: tuple[str, ...],
        max_evaluations: int, jacobian: str, bootstrap: int, scheduler: str | None, quiet: bool) -> None:
    """Calibrate the --free fields of CONFIG on the MEASURED traces by least squares.

    Each MEASURED is a scope file, optionally followed by settings for that trace only:
    FILE@chain.truncate=16 (the paper's protocol: the wall trace of each truncated chain),
    FILE@signal=sensor:12@sensor=pcb_200b02 (the embedded sensor, read with its own sensitivity),
    FILE@column=CH2. The model is seen through the instrument (sampled
    at the scope's times, times gain, shifted by time_offset, plus baseline); the Jacobian's config
    columns are exact (the tangent model beside each trace's run), or finite differences where the
    tangent model does not cover the model (the summary line says which).
    """
    from ..config import apply_overrides, parse_config, read_toml
    from ..errors import ConfigError
    from ..lab.fit import Trace, fit_traces
    from ..lab.readers import read_trace
    from ..lab.report import prepare_folder, write_fit_outputs

    from ..extras import require

    require("lab", "fit", ("tomli_w",))  # fit.toml is written at the end: the extra is checked first
    if max_evaluations < 1:
        raise ConfigError("--max-evaluations", f"must be at least 1, got {max_evaluations}")
    data = read_toml(config)
    parse_config(apply_overrides(data, overrides))  # a bad file or --set fails before reading traces
    prepare_folder(out)  # ... and an unusable --out before the fit
    traces = []
    for item in measured:
        path, sig, sets, own = parse_measured(item)
        options: dict[str, Any] = {"column": column, "time_unit": time_unit}
        if "sensitivity" not in own and "sensor" not in own:
            options.update(sensitivity=sensitivity, sensor=sensor)
        options.update(own)
        da = read_trace(path, **options)
        traces.append(Trace(da, sig or signal, tuple(sets), path.name))
    # Lazy: a fit refused at its start (bad start, a parameter the data cannot fix) prints only why.
    with progress_bar("fitting" + (f" (+{bootstrap} bootstrap refits)" if bootstrap else ""),
                      enabled=not quiet, lazy=True) as update:
        # The bar counts engine calls against a typical budget (~20 per fit), capped below 100 %.
        budget = 20 * (1 + bootstrap)

        def tick(n: int, cost: float) -> None:
            if update is not None:
                update(min(n, budget - 1), budget)

        client = dask_client(scheduler) if bootstrap else None
        try:
            result = fit_traces(data, traces, free, overrides=overrides, max_evaluations=max_evaluations,
                                bootstrap=bootstrap, progress=tick, client=client,
                                jacobian="exact" if jacobian == "exact" else "finite differences")
        finally:
            if client is not None:
                client.close()
        if update is not None:
            update(budget, budget)
    paths = write_fit_outputs(result, out)
    for doubt in result.warnings:
        echo_warning(doubt)
    if quiet:
        return
    table = UnitsTable(f"fit of {config.name} on {len(traces)} trace(s): "
                       f"{'converged' if result.converged else 'NOT converged'}, s^2 = {result.residual_variance:.3g}",
                       [("parameter", None), ("unit", None), ("value", None), ("stderr", None), ("start", None)]
                       + ([("bootstrap stderr", None)] if bootstrap else []))
    boot = result.as_json()["parameters"]
    for n, v, s, s0 in zip(result.names, result.values, result.stderr, result.start):
        extra = (f"{boot[n]['bootstrap']['stderr']:.2g}",) if bootstrap else ()
        table.add_row(n, boot[n]["unit"], f"{v:.6g}", f"{s:.2g}", f"{s0:.6g}", *extra)
    table.print()
    click.echo(f"{result.n_evaluations} evaluations ({result.n_members} chains in batched engine calls, "
               f"{result.n_tangent_runs} tangent runs; Jacobian: {result.jacobian}) in {result.elapsed:.2f} s; "
               f"wrote {', '.join(str(p) for p in paths.values())}")
