"""Command line: ``hertzchain run | plot | animate | analyze | materials | reproduce | sweep``.

Every user error (bad config, bad file, bad option) ends with a one-paragraph message and exit
status 2, never a traceback. Heavy imports are deferred into the commands so ``--help`` is quick.
"""

from __future__ import annotations

import os
import sys
from contextlib import contextmanager
from pathlib import Path

import click

from .cli_options import freeze_imports, set_option


@contextmanager
def progress_bar(description: str, enabled: bool = True, lazy: bool = False):
    """A Rich progress bar on stderr; yields ``update(done, total)``.

    With ``lazy`` the bar appears at the first update, so a job refused by its checks before any
    work (bad input, not enough memory) prints only its error message.
    """
    if not enabled:
        yield None
        return
    from rich.console import Console
    from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn, TimeRemainingColumn

    state: dict = {}

    def start() -> None:
        prog = Progress(TextColumn("{task.description}"), BarColumn(), TextColumn("{task.percentage:>3.0f}%"),
                        TimeElapsedColumn(), TimeRemainingColumn(), console=Console(stderr=True), transient=False)
        prog.start()
        state.update(prog=prog, task=prog.add_task(description, total=None))

    def update(done: int, total: int) -> None:
        if not state:
            start()
        state["prog"].update(state["task"], completed=done, total=total)

    if not lazy:
        start()
    try:
        yield update
    finally:
        if state:
            state["prog"].stop()


@click.group(context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(package_name="hertzchain")
def cli() -> None:
    """Impulse propagation in chains of Hertzian beads (tapered granular shock absorbers)."""


@cli.command()
@click.argument("config", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--out", "-o", type=click.Path(dir_okay=False, path_type=Path), required=True,
              help="NetCDF file to write (e.g. result.nc).")
@set_option
@click.option("--quiet", "-q", is_flag=True, help="No progress bar or summary.")
def run(config: Path, out: Path, overrides: tuple[str, ...], quiet: bool) -> None:
    """Simulate the chain described by CONFIG (TOML) and save the result as NetCDF."""
    import warnings

    from .config import apply_instruments, build_instruments, build_model, build_probes, load_config, simulate_config
    from .errors import DurationWarning, ElasticLimitWarning
    from .fileio import check_not_input, check_target
    from .result import save
    from .simulation import auto_duration

    from .errors import ConfigError

    if out.suffix.lower() not in (".nc", ".nc4", ".h5"):
        # A result is NetCDF-4 whatever the name; a .csv or .png name is a mistake to catch before the run.
        raise ConfigError("--out", f"a result is a NetCDF file: name it *.nc (got {out.name!r})")
    cfg = load_config(config, overrides)
    check_not_input(out, config)
    check_target(out)  # refuse a FIFO, a link or a device as --out before any work
    model = build_model(cfg)
    probes = build_probes(cfg)
    build_instruments(cfg)  # fail on bad instrument settings before a long run
    # A progress bar only when the run is long enough to be worth one (> ~1e8 bead-steps).
    from .integrate.verlet import auto_time_step

    dt = cfg.run.dt or auto_time_step(model.system())
    duration = auto_duration(model) if cfg.run.duration == "auto" else cfg.run.duration
    work = duration / dt * model.chain.n_beads
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", ElasticLimitWarning)
        warnings.simplefilter("always", DurationWarning)
        with progress_bar("simulating", enabled=not quiet and work > 1e8, lazy=True) as update:
            ds = simulate_config(cfg, model, probes, progress=update)
    for w in caught:
        click.echo(f"warning: {w.message}", err=True)
    ds = apply_instruments(ds, cfg)
    save(ds, out)
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
        click.echo(msg)


def _open_result(path: Path):
    from .errors import ConfigError
    from .result import load

    if not path.exists():
        raise ConfigError(str(path), "no such file")
    try:
        ds = load(path)
    except Exception as exc:  # noqa: BLE001 - a damaged HDF5 file raises anything (RuntimeError, OSError, ...)
        raise ConfigError(str(path), f"is not a hertzchain NetCDF result, or is damaged "
                          f"({type(exc).__name__}: {exc})") from None
    # What every command reads: a time axis and at least one force signal.
    forces = [v for v in ("wall_force", "sensor_force", "contact_force") if v in ds]
    if "time" not in ds.coords or ds.time.ndim != 1 or ds.time.size < 2 or not forces:
        raise ConfigError(str(path), "is not a hertzchain result: it needs a 'time' axis of at least 2 samples and "
                          "one of wall_force, sensor_force, contact_force")
    return ds


@cli.command()
@click.option("--out", "-o", type=click.Path(file_okay=False, path_type=Path), default=Path("reproduction"),
              show_default=True, help="Folder for figures, data, summary.json and the report.")
@click.option("--velocity", type=float, default=0.2, show_default=True,
              help="Striker speed [m/s] (not given in the paper; normalised results do not depend on it).")
@click.option("--elastic", is_flag=True, help="No dissipation (default: calibrated to the paper's eps = 0.985).")
@click.option("--law", type=click.Choice(["viscoelastic", "viscoelastic_scaled", "dashpot"]), default="viscoelastic",
              show_default=True, help="Dissipative contact law calibrated to eps (viscoelastic_scaled: Kuwabara-Kono "
              "A following each contact's collision time, the same eps in every bead size).")
@click.option("--eps", type=float, default=0.985, show_default=True, help="Per-bead factor eps to calibrate to.")
@click.option("--no-figures", is_flag=True, help="Only data and summary.json.")
@click.option("--from-data", is_flag=True, help="Redraw figures and report from OUT/data without simulating.")
def reproduce(out: Path, velocity: float, elastic: bool, law: str, eps: float, no_figures: bool,
              from_data: bool) -> None:
    """Reproduce the paper (Figures 1-6, its numbers, a report) in well under a minute."""
    from .errors import ConfigError

    if from_data:
        from .paper.early import start_laws_figure

        laws_figure = start_laws_figure(out)  # drawn on the idle core while the imports below run
        from .paper.reproduce import FIGURE_NAMES, redraw

        freeze_imports()
        with progress_bar("redrawing figures and report", lazy=True) as update:  # errors first, no bar
            done = [0]

            def step(msg: str) -> None:
                done[0] += 1
                update(done[0], len(FIGURE_NAMES) + 2)

            summary = redraw(out, progress=step, laws_figure=laws_figure)
        _echo_elastic_limit(summary)
        click.echo(f"redrew the figures and the report in {out}/ from {out}/data")
        return

    if not (velocity > 0 and velocity < 10):
        raise ConfigError("--velocity", f"must be a striker speed in (0, 10) m/s, got {velocity}")
    if not (0 < eps <= 1):
        raise ConfigError("--eps", f"must lie in (0, 1], got {eps}")
    from .paper.protocol import Settings
    from .paper.reproduce import count_steps, reproduce as run_reproduction

    freeze_imports()
    settings = Settings(striker_velocity=velocity, elastic=elastic, law=law, eps=eps)
    total = count_steps(settings, figures=not no_figures)
    with progress_bar("reproducing the paper") as update:
        done = [0]

        def tick(msg: str) -> None:
            done[0] += 1
            update(done[0], total)

        summary = run_reproduction(out, settings, progress=tick, figures=not no_figures)
    _echo_elastic_limit(summary)
    c1, c2 = summary["chain1"], summary["chain2"]
    click.echo(f"wrote {out}/ in {summary['timing']['total_s']:.1f} s: "
               f"Q1 = {c1['Q_fit']:.4f} +- {c1['Q_fit_err']:.4f} (theory {c1['Q_theory']:.4f}, paper 1.025 +- 0.016), "
               f"Q2 = {c2['Q_fit']:.4f} +- {c2['Q_fit_err']:.4f} (theory {c2['Q_theory']:.4f}, paper 1.049 +- 0.044), "
               f"eps = {summary['eps']:.4f}")


def _echo_elastic_limit(summary: dict) -> None:
    """Say on the console when a reproduction's contact forces pass the elastic limit."""
    msg = (summary.get("elastic_limit") or {}).get("message")
    if msg:
        click.echo(f"warning: {msg}", err=True)


@cli.command()
def materials() -> None:
    """List the material catalogue (SI units) with sources."""
    from .materials import CATALOGUE

    for m in CATALOGUE.values():
        ys = "-" if m.yield_stress is None else f"{m.yield_stress:.3g}"
        click.echo(f"{m.name:16s} rho={m.density:<7g} Y={m.young:<9.3g} nu={m.poisson:<5g} sigma_Y={ys:<8s} ({m.source})")


def _register_subcommands() -> None:
    # One line per subcommand module (each command lives in its own module).
    from .analyze_cli import analyze
    from .animate_cli import animate
    from .compare_cli import compare
    from .fit_cli import fit
    from .design_cli import design
    from .plot_cli import plot
    from .sweep_cli import sweep

    cli.add_command(sweep)
    cli.add_command(design)
    cli.add_command(plot)
    cli.add_command(animate)
    cli.add_command(analyze)
    cli.add_command(compare)
    cli.add_command(fit)


_register_subcommands()


def _show_warning(message, category, filename, lineno, file=None, line=None) -> None:
    """Warnings reach the user as one line ``warning: ...`` on stderr (no file name or code line)."""
    click.echo(f"warning: {message}", err=True)


def _user_warnings(func):
    """Run ``func`` with warnings shown as :func:`_show_warning` lines and NumPy's floating-point
    RuntimeWarnings (overflow, invalid value...) silenced: every result is checked by
    :mod:`hertzchain.checks`, which raises or warns in the user's terms."""
    import functools

    @functools.wraps(func)
    def wrapper(*args, **kwargs):
        import warnings

        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            warnings.showwarning = _show_warning
            return func(*args, **kwargs)

    return wrapper


@_user_warnings
def main(argv: list[str] | None = None) -> int:
    """Entry point: run the CLI, turning user errors into a message and exit status 2.

    The one error path of the command line: a :class:`~hertzchain.errors.HertzchainError` (bad
    config, bad file, a run that diverged), a usage error, an unreadable or unwritable file
    (OSError) or a lack of memory ends with one paragraph naming what is wrong and exit status
    2; anything else is a bug, reported as such with exit status 1.
    """
    from .errors import HertzchainError

    try:
        cli.main(args=argv, prog_name="hertzchain", standalone_mode=False)
    except click.exceptions.Abort:
        click.echo("aborted", err=True)
        return 130
    except click.exceptions.ClickException as exc:
        exc.show()
        return 2 if isinstance(exc, click.UsageError) else exc.exit_code
    except HertzchainError as exc:
        click.echo(f"error: {exc}", err=True)
        return 2
    except KeyboardInterrupt:
        click.echo("interrupted", err=True)
        return 130
    except MemoryError:
        click.echo("error: not enough memory for this job; shorten run.duration, raise run.sample_interval "
                   "or record fewer contacts (probes.contacts)", err=True)
        return 2
    except OSError as exc:  # a file the job needed could not be read or written
        where = exc.filename if exc.filename is not None else "a file"
        click.echo(f"error: {where}: {exc.strerror or exc}", err=True)
        return 2
    except Exception as exc:  # a bug: say so plainly, full traceback on request
        if os.environ.get("HERTZCHAIN_DEBUG"):
            raise
        click.echo(f"internal error: {type(exc).__name__}: {exc}\n"
                   "This is a bug in hertzchain; rerun with HERTZCHAIN_DEBUG=1 for the traceback.", err=True)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())


def entry() -> None:
    """Console-script entry point."""
    sys.exit(main())
