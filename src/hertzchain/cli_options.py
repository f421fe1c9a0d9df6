"""Click options shared by every command that reads a config (run, sweep, fit, design, ...)."""

from __future__ import annotations

import click

#: ``--set DOTTED.PATH=VALUE`` (repeatable): change one config field without editing the file.
#: The values reach :func:`hertzchain.config.apply_overrides` and are validated like the file.
set_option = click.option(
    "--set", "overrides", multiple=True, metavar="DOTTED.PATH=VALUE",
    help="Override one config field, e.g. --set striker.velocity=0.3 (repeatable; TOML values).")


def require_device(device: str) -> None:
    """Fail at once, naming ``--device``, when ``cuda`` is asked for and no GPU is usable."""
    if device != "cuda":
        return
    from .errors import ConfigError
    from .integrate.cuda import require_gpu

    try:
        require_gpu()
    except ConfigError as exc:
        raise ConfigError("--device", exc.message) from None


def dask_client(scheduler: str | None):
    """A Dask ``Client`` connected to ``--scheduler`` (None when absent); a clean error naming it."""
    if scheduler is None:
        return None
    from .errors import ConfigError

    try:
        from distributed import Client

        return Client(scheduler, timeout="20s")
    except (OSError, TimeoutError, ValueError) as exc:
        raise ConfigError("--scheduler", f"cannot connect to the Dask scheduler at {scheduler!r}: {exc}") from None


def freeze_imports() -> None:
    """Move the objects alive now (the imported modules: most of the heap) out of the garbage
    collector's reach. They live to the end anyway; otherwise each full collection rescans them
    (~0.1 s each with numba, scipy and xarray loaded: ~0.45 s of ``reproduce --from-data``,
    ~0.15 s of the 0.8 s ``examples/design_taper.toml`` search), and forked worker processes
    would touch (copy) their pages doing so. For commands: a library call leaves the collector
    as it is."""
    import gc

    gc.freeze()
