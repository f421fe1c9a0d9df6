"""``hertzchain run``: simulate the chain of a config file and save the result as NetCDF."""

from __future__ import annotations

from pathlib import Path

import click

from .common import echo_warning, progress_bar, set_option, laws_option


@click.command("run")
@laws_option
@click.argument("config", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--out", "-o", type=click.Path(dir_okay=False, path_type=Path), required=True,
              help="Result file: NetCDF (result.nc, everything), or result.csv / result.mat / result.parquet "
                   "(as hertzchain export writes them).")
@set_option
@click.option("--quiet", "-q", is_flag=True, help="No progress bar or summary.")
@click.option("--verbose", "-v", is_flag=True, help="Also say which integrator and how many threads ran, and why "
                                                    "(run.integrator / run.threads 'auto').")
def run(config: Path, out: Path, overrides: tuple[str, ...], quiet: bool, verbose: bool) -> None:
    """Simulate the chain described by CONFIG (TOML) and save the result (NetCDF, or CSV / MATLAB /
    parquet by the suffix of --out, as hertzchain export writes them)."""
    import warnings

    from ..config import (apply_instruments, build_instruments, build_model, build_probes, load_config, preflight_run,
                          simulate_config)
    from ..errors import ConfigError, DurationWarning, ElasticLimitWarning, LongRunWarning
    from ..exporting import check_format, export
    from ..fileio import check_not_input, check_writable

    # Tables only: the exchange formats (.h5md, .pvd, .data) need recorded positions or the NetCDF
    # result's model, and go through `hertzchain export`.
    tables = (".csv", ".mat", ".parquet")
    if out.suffix.lower() not in (".nc", ".nc4", ".h5", *tables):
        # A .png name (or a typo) is a mistake to catch before the run.
        raise ConfigError("--out", f"name the result *.nc (NetCDF, everything), *.csv, *.mat or *.parquet "
                          f"(as hertzchain export writes them; H5MD, VTK and LAMMPS files: run to *.nc, then "
                          f"hertzchain export); got {out.name!r}")
    if out.suffix.lower() in tables:
        check_format(out)  # parquet without pyarrow is said before the run
    cfg = load_config(config, overrides)
    check_not_input(out, config)
    # Before any work: a FIFO, a link or a device as --out, or a folder that cannot be written
    # (under a file, read-only, not ours), refused now rather than after the whole simulation.
    check_writable(out)
    probes = build_probes(cfg)
    build_instruments(cfg)  # fail on bad instrument settings before a long run
    # a calibrated law's runs compile its engine (~8 CPU-s in a fresh installation): the run's checks
    # come first, on the model with the law's parameter still 0
    model = build_model(cfg, preflight=lambda provisional: preflight_run(cfg, provisional, probes))
    # xarray (~0.5 s to import) only once the config is valid: a bad one is refused at once
    from ..result import save
    from ..runs.simulation import auto_duration
    # The pre-flight, before any work: memory refused past what is available, and a projected time
    # past a few minutes shown now (LongRunWarning), naming what to change (run.dt, run.duration).
    from ..checks import check_resources, estimate_resources, run_time_hint

    from ..engine_choice import choose_engine

    duration = auto_duration(model) if cfg.run.duration == "auto" else cfg.run.duration
    system = model.system()
    if cfg.track is None:  # refuses an integrator or thread count the model does not run, before any compilation
        integrator = choose_engine(system, cfg.run.integrator, cfg.run.threads,
                                   steps_per_radian=cfg.run.verlet_steps_per_radian, dt=cfg.run.dt).integrator
    else:
        integrator = "verlet" if cfg.run.integrator == "auto" else cfg.run.integrator
    est = estimate_resources(system, duration, probes, dt=cfg.run.dt, integrator=integrator,
                             steps_per_radian=cfg.run.steps_per_radian)
    check_resources(est, time_hint=run_time_hint(cfg.run.dt))
    # A progress bar only when the run is long enough to be worth one (> ~1e8 bead-steps).
    work = est.steps * model.chain.n_beads
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", ElasticLimitWarning)
        warnings.simplefilter("always", DurationWarning)
        with progress_bar("simulating", enabled=not quiet and work > 1e8, lazy=True) as update:
            ds = simulate_config(cfg, model, probes, progress=update)
    for w in caught:
        if not issubclass(w.category, LongRunWarning):  # the pre-flight showed it before the run
            echo_warning(w.message)
    ds = apply_instruments(ds, cfg)
    if out.suffix.lower() in tables:
        export(ds, out)
    else:
        save(ds, out)
    if verbose and "engine_choice" in ds.attrs:
        click.echo(f"engine: {ds.attrs['engine_choice']}")
    if not quiet:
        if ds.attrs.get("time_step") == "adaptive":
            step = f"adaptive dt {ds.attrs['dt']:.3g}-{ds.attrs['dt_max']:.3g} s, {ds.attrs['n_steps']} steps"
        elif ds.attrs.get("time_step") == "solve_ivp":
            step = f"{ds.attrs['integrator']}, {ds.attrs['n_steps']} right-hand-side calls"
        else:
            step = f"dt = {ds.attrs['dt']:.3g} s"
        span = f"{ds.attrs['duration'] * 1e3:.3g} ms" + (" (automatic)" if ds.attrs.get("duration_mode") == "auto" else "")
        msg = f"wrote {out} ({span}, {ds.sizes['time']} samples, {ds.sizes['contact']} contacts, {step})"
        if "wall_force" in ds:
            msg += f"; peak wall force {ds.attrs['peak_wall_force']:.4g} N at {ds.attrs['peak_wall_time'] * 1e3:.4g} ms"
            if "peak_wall_force_dynamic" in ds.attrs:  # under gravity: what the impact adds to the weight
                msg += (f" ({ds.attrs['peak_wall_force_dynamic']:.4g} N dynamic over the "
                        f"{ds.attrs['static_wall_force']:.4g} N static)")
        if "peak_body_force" in ds.attrs:
            msg += f"; the protected body passes at most {ds.attrs['peak_body_force']:.4g} N to the ground"
        if "plastic_work" in ds.attrs:  # the elastoplastic law
            msg += (f"; plastic work {ds.attrs['plastic_work']:.3g} J, deepest permanent dent "
                    f"{ds.attrs['residual_overlap_max'] * 1e6:.3g} um")
        click.echo(msg)
