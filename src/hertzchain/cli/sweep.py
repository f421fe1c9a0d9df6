"""``hertzchain sweep``: run or resume a parameter sweep.

Heavy imports (numba, xarray, dask) are deferred into the command so that ``hertzchain --help``
stays quick.
"""

from __future__ import annotations

from pathlib import Path

import click

from .common import dask_client, require_device, set_option, laws_option


@click.command("sweep")
@laws_option
@click.argument("sweep_file", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--out", "-o", "out", type=click.Path(file_okay=False, path_type=Path), required=True,
              help="Output folder: chunks/*.nc, sweep.json and metrics.csv. Rerunning resumes.")
@click.option("--scheduler", default=None, metavar="ADDRESS",
              help="Dask scheduler address (e.g. tcp://host:8786); chunks run here when absent.")
@click.option("--force", is_flag=True, help="Replace the results of a different sweep found in --out.")
@set_option
@click.option("--quiet", "-q", is_flag=True, help="No progress bar or summary.")
@click.option("--device", type=click.Choice(["auto", "cpu", "cuda"]), default="auto", show_default=True,
              help="Where chunks run: the CPU, the CUDA GPU (pip install \"hertzchain[gpu]\"), or auto (the GPU "
                   "when one is usable and a chunk is large enough to gain).")
def sweep(sweep_file: Path, out: Path, scheduler: str | None, force: bool, overrides: tuple[str, ...],
          quiet: bool, device: str) -> None:
    """Run the sweep described by SWEEP_FILE (TOML: [base] run config + [sweep] table).

    Finished chunks are written at once, so an interrupted sweep resumes where it stopped when
    rerun with the same --out. --set paths are relative to [base] (e.g. --set striker.diameter_mm=10). The table OUT/metrics.csv has one row per member: the swept values
    and the wall-pulse metrics F_m [N], T [s], tau [s], Q_F [N s], Q_T [N s] (paper Sec. III).
    With [sweep] analysis = "dispersion" each member's chain is one period of a periodic chain
    instead: the table holds its band gaps [Hz], and OUT/gap_map.png draws them against the first
    swept parameter (a band-gap map).
    """
    from rich.console import Console
    from rich.progress import (BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn,
                               TimeRemainingColumn)

    from ..sweep import load_sweep, run_sweep

    cfg = load_sweep(sweep_file, overrides)
    require_device(device)  # fail now, naming the option, rather than in the first chunk
    client = dask_client(scheduler)
    console = Console(stderr=True)
    try:
        if quiet:
            result = run_sweep(cfg, out, client=client, force=force, device=device)
        else:
            console.print(f"sweep {sweep_file.name}: {cfg.n_members} members in {len(cfg.chunks())} chunks "
                          f"({'Dask at ' + scheduler if scheduler else 'local, all cores'})")
            with Progress(TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(), TimeElapsedColumn(),
                          TimeRemainingColumn(), console=console) as prog:
                task = prog.add_task("members", total=cfg.n_members)

                def update(done: int, total: int) -> None:
                    prog.update(task, completed=done, total=total)

                result = run_sweep(cfg, out, client=client, progress=update, force=force, device=device)
    finally:
        if client is not None:
            client.close()
    if cfg.sweep.analysis == "dispersion":  # a band-gap map: the gaps against the first swept parameter
        from ..crystal.figures import plot_gap_map
        from ..fileio import atomic_path

        fig = plot_gap_map(result.metrics, cfg.parameter_names[0])
        with atomic_path(out / "gap_map.png") as tmp:
            fig.savefig(tmp, format="png", dpi=120)
        if not quiet:
            with_gaps = int((result.metrics["gap_count"] > 0).sum())
            click.echo(f"wrote {result.metrics_path}, gaps.nc and gap_map.png ({len(result.metrics)} members, "
                       f"{with_gaps} with a band gap)")
        return
    if quiet:
        return
    df = result.metrics
    msg = (f"wrote {result.metrics_path} ({len(df)} members; {len(result.computed)} chunks computed, "
           f"{len(result.skipped)} resumed)")
    n_fail = int((df["fit_error"] != "").sum())
    from ..sweep.statistics import past_elastic_limit

    n_over = past_elastic_limit(df)  # an elastoplastic member yields by design: not counted
    if n_fail:
        msg += f"; {n_fail} members without a fitted wall pulse (see column fit_error)"
    if n_over:
        msg += f"; warning: {n_over} members pass the elastic limit (column elastic_limit_exceeded)"
    click.echo(msg)
