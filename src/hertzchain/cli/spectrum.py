"""``hertzchain spectrum``: steady-state transmission of a driven chain against frequency."""

from __future__ import annotations

from pathlib import Path

import click

from .common import progress_bar


@click.command("spectrum")
@click.argument("config", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--out", type=click.Path(file_okay=False, path_type=Path), required=True,
              help="Folder for transmission.csv, transmission.nc and transmission.png (a rerun resumes).")
@click.option("--fmin", type=click.FloatRange(min=0, min_open=True), required=True, help="Lowest frequency [Hz].")
@click.option("--fmax", type=click.FloatRange(min=0, min_open=True), required=True, help="Highest frequency [Hz].")
@click.option("--points", type=click.IntRange(1, 100_000), default=40, show_default=True, help="Frequencies.")
@click.option("--log", "log_scale", is_flag=True, help="Frequencies spaced logarithmically (default: linearly).")
@click.option("--settle-cycles", type=click.FloatRange(min=0), default=200.0, show_default=True,
              help="Drive cycles after the ramp before the measurement (the transient must die out).")
@click.option("--measure-cycles", type=click.FloatRange(min=1), default=20.0, show_default=True,
              help="Whole cycles over which the amplitudes are measured.")
@click.option("--batch", type=click.IntRange(1, 10_000), default=8, show_default=True,
              help="Frequencies run at once by the batched engine (one per thread in turn) and written together.")
@click.option("--quiet", "-q", is_flag=True, help="No progress bar.")
def spectrum(config: Path, out: Path, fmin: float, fmax: float, points: int, log_scale: bool, settle_cycles: float,
             measure_cycles: float, batch: int, quiet: bool) -> None:
    """Stepped-sine transmission of CONFIG's chain driven by its [drive] (type = "harmonic"): the
    amplitude of the wall force (of the last contact with a free end) at the drive frequency over
    the drive's force amplitude (on bead 1, or bead N with [drive] end = "last"), in the steady
    state. The frequencies run --batch at a time in one compiled call; each batch is written to
    OUT/transmission.csv as it completes, and a rerun skips the frequencies done."""
    import numpy as np

    from ..config.build import build_model
    from ..config.loading import load_config
    from ..crystal.spectrum import SpectrumSettings, transmission_spectrum
    from ..errors import ConfigError
    from ..fileio import atomic_path, write_bytes

    if fmax < fmin:
        raise ConfigError("--fmax", f"({fmax:g} Hz) must not be below --fmin ({fmin:g} Hz)")
    cfg = load_config(config)
    model = build_model(cfg)
    if model.drive is None:
        raise ConfigError("drive", "the config has no [drive] section: add one with type = 'harmonic'")
    freqs = np.geomspace(fmin, fmax, points) if log_scale else np.linspace(fmin, fmax, points)
    settings = SpectrumSettings(settle_cycles=settle_cycles, measure_cycles=measure_cycles,
                                steps_per_radian=cfg.run.steps_per_radian, dt=cfg.run.dt)
    with progress_bar("spectrum", enabled=not quiet, lazy=True) as update:
        ds = transmission_spectrum(model, freqs, out, settings, progress=update, batch=batch)
    write_bytes(out / "transmission.nc", ds.to_netcdf())
    from ..crystal.figures import plot_transmission

    fig = plot_transmission(ds)
    with atomic_path(out / "transmission.png") as tmp:
        fig.savefig(tmp, format="png", dpi=120)
    best = int(np.argmax(ds.transmission.values))
    click.echo(f"wrote {out / 'transmission.csv'}, transmission.nc and transmission.png ({ds.frequency.size} "
               f"frequencies; largest transmission {ds.transmission.values[best]:.4g} at "
               f"{ds.frequency.values[best]:.6g} Hz)")
