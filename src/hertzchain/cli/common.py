"""What the subcommands share: options, opening results, progress bars, Dask, warnings.

Every subcommand module imports from here and from the library below it, never from another
subcommand or from :mod:`hertzchain.cli.main`. Only Click is imported at the top: everything
heavy (Rich, xarray, the engine) is deferred into the helpers, so ``hertzchain --help`` stays quick.
"""

from __future__ import annotations

from contextlib import contextmanager
from pathlib import Path

import click

# ---------------------------------------------------------------------------------------------
# options
# ---------------------------------------------------------------------------------------------

#: ``--set DOTTED.PATH=VALUE`` (repeatable): change one config field without editing the file.
#: The values reach :func:`hertzchain.config.apply_overrides` and are validated like the file.
set_option = click.option(
    "--set", "overrides", multiple=True, metavar="DOTTED.PATH=VALUE",
    help="Override one config field, e.g. --set striker.velocity=0.3 (repeatable; TOML values).")


def _load_laws(ctx, param, paths) -> None:
    from ..laws import load_law_file

    for path in paths:
        load_law_file(path)


#: ``--laws FILE``: the only way the command line runs a user's law file (a config never names code).
laws_option = click.option(
    "--laws", "law_files", multiple=True, metavar="FILE.py", expose_value=False, callback=_load_laws,
    help="Python file that registers contact laws (hertzchain.register_law), so that configs can name them "
         "as [contact] law (repeatable). Runs that file's code: only name files you trust.")


def trace_options(func):
    """The options that say how to read a measured file (shared by analyze, compare and fit)."""
    for option in reversed((
        click.option("--column", default=None, metavar="NAME_OR_INDEX",
                     help="Signal column of a text/scope file, by header name or 0-based index "
                          "(default: the only one besides time, or the one named *force*)."),
        click.option("--sensitivity", type=float, default=None, metavar="MV_PER_N",
                     help="Sensor sensitivity [mV/N]: the signal is in volts and becomes newtons."),
        click.option("--sensor", default=None, type=click.Choice(["pcb_208a11", "pcb_200b02"], case_sensitive=False),
                     help="Sensor preset instead of --sensitivity: pcb_208a11 (112.40 mV/N, wall), "
                          "pcb_200b02 (11.24 mV/N, embedded)."),
        click.option("--time-unit", default=None, metavar="s|ms|us|ns",
                     help="Unit of the time column when the file does not name it."),
    )):
        func = option(func)
    return func


def parse_window(text: str | None) -> tuple[float, float] | None:
    """``--window "T0,T1"`` in ms -> (t0, t1) in s (None when not given)."""
    from ..errors import ConfigError

    if text is None:
        return None
    parts = text.split(",")
    try:
        t0, t1 = (float(p) for p in parts)
    except ValueError:
        raise ConfigError("--window", f"{text!r} is not T0,T1 (two times in ms, e.g. --window 1.5,2.5)") from None
    if not t1 > t0:
        raise ConfigError("--window", f"needs T0 < T1 (ms), got {text!r}")
    return t0 * 1e-3, t1 * 1e-3


def require_device(device: str) -> None:
    """Fail at once, naming ``--device``, when ``cuda`` is asked for and no GPU is usable."""
    if device != "cuda":
        return
    from ..errors import ConfigError
    from ..integrate.cuda.launch import require_gpu

    try:
        require_gpu()
    except ConfigError as exc:
        raise ConfigError("--device", exc.message) from None


def dask_client(scheduler: str | None):
    """A Dask ``Client`` connected to ``--scheduler`` (None when absent); a clean error naming it
    (:func:`hertzchain.parallel.connect`)."""
    if scheduler is None:
        return None
    from ..parallel import connect

    return connect(scheduler, notify=lambda message: click.echo(f"note: {message}", err=True))


# ---------------------------------------------------------------------------------------------
# results
# ---------------------------------------------------------------------------------------------

def open_result(path: Path):
    """A hertzchain result file read as a Dataset, or a ConfigError naming the file and what is wrong."""
    from ..errors import ConfigError
    from ..result import load

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


def signal_frame(ds, name: str):
    """A one-signal Dataset on a ``time`` dimension (the instrument's ``*_scope_time`` renamed)."""
    import xarray as xr

    from ..errors import ConfigError

    if name not in ds.data_vars:
        forces = [v for v in ds.data_vars if ds[v].attrs.get("units") == "N" and any(str(d).endswith("time")
                                                                                  for d in ds[v].dims)]
        raise ConfigError("--signal", f"{name!r} is not a signal of this result; available: {', '.join(forces)}")
    da = ds[name]
    tdim = next((d for d in da.dims if str(d).endswith("time")), None)
    if tdim is None:
        raise ConfigError("--signal", f"{name!r} is not a time signal (dims {da.dims})")
    if tdim != "time":
        da = da.reset_coords(drop=True).rename({tdim: "time"})
    return xr.Dataset({name: da})


# ---------------------------------------------------------------------------------------------
# tables
# ---------------------------------------------------------------------------------------------

class UnitsTable:
    """A table whose every header carries its unit (``F_m [N]``) at every terminal width.

    Printed as a Rich table when it fits the terminal (or the pipe's 80 columns) with every cell
    whole; in a narrower one, as one block per row of ``header [unit]: value`` lines, rather
    than cutting headers and numbers with ellipses or folding a number over two lines. The
    headers are escaped (Rich takes ``[ms]`` for a style and drops it).

    Parameters
    ----------
    title : str
        The table's title.
    columns : list of (str, str or None)
        Header and unit of each column (None: no unit, e.g. a label).
    """

    def __init__(self, title: str, columns: list[tuple[str, str | None]]):
        self.title = title
        self.headers = [name if unit is None else f"{name} [{unit}]" for name, unit in columns]
        self.rows: list[tuple[list[str], str | None]] = []

    def add_row(self, *cells: str, style: str | None = None) -> None:
        """Add a row of plain-text cells (``style``: a Rich style for the whole row, e.g. "red")."""
        self.rows.append(([str(c) for c in cells], style))

    def _rich(self):
        from rich.markup import escape
        from rich.table import Table

        table = Table(title=escape(self.title))
        for h in self.headers:
            table.add_column(escape(h), justify="right", no_wrap=True)
        for cells, style in self.rows:
            table.add_row(*[escape(c) for c in cells], style=style)
        return table

    def print(self, console=None) -> None:
        """Print to ``console`` (default: stdout)."""
        from rich.console import Console
        from rich.markup import escape

        from rich.cells import cell_len

        console = console or Console()
        # Every cell whole on one line: the widest cell of each column, its padding and the rules.
        widths = [max([cell_len(h)] + [cell_len(cells[j]) for cells, _ in self.rows])
                  for j, h in enumerate(self.headers)]
        if sum(w + 3 for w in widths) + 1 <= console.width:
            console.print(self._rich())
            return
        console.print(escape(self.title))
        for cells, style in self.rows:
            for h, c in zip(self.headers, cells):
                if c:
                    console.print(f"  {escape(h)}: {escape(c)}", style=style)
            console.print("")


# ---------------------------------------------------------------------------------------------
# progress, warnings, memory
# ---------------------------------------------------------------------------------------------

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


def echo_warning(message) -> None:
    """Tell the user about a doubt: one line ``warning: ...`` on stderr."""
    click.echo(f"warning: {message}", err=True)


def show_warning(message, category, filename, lineno, file=None, line=None) -> None:
    """Warnings reach the user as one line ``warning: ...`` on stderr (no file name or code line)."""
    echo_warning(message)


def user_warnings(func):
    """Run ``func`` with warnings shown as :func:`show_warning` lines and NumPy's floating-point
    RuntimeWarnings (overflow, invalid value...) silenced: every result is checked by
    :mod:`hertzchain.checks`, which raises or warns in the user's terms."""
    import functools

    @functools.wraps(func)
    def wrapper(*args, **kwargs):
        import warnings

        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            warnings.showwarning = show_warning
            return func(*args, **kwargs)

    return wrapper


def freeze_imports() -> None:
    """Move the objects alive now (the imported modules: most of the heap) out of the garbage
    collector's reach. They live to the end anyway; otherwise each full collection rescans them
    (~0.1 s each with numba, scipy and xarray loaded: ~0.45 s of ``reproduce --from-data``,
    ~0.15 s of the 0.8 s ``examples/design_taper.toml`` search), and forked worker processes
    would touch (copy) their pages doing so. For commands: a library call leaves the collector
    as it is."""
    import gc

    gc.freeze()
