"""The ``hertzchain`` command: the Click group, one line per subcommand, the one error path.

Each subcommand lives in a module of its own (``hertzchain/cli/<name>.py``); what they share is
in :mod:`hertzchain.cli.common`. A new command: write its module, add one ``add_command`` line
below. Every user error (bad config, bad file, bad option) ends with a one-paragraph message and
exit status 2, never a traceback. Heavy imports are deferred into the commands so ``--help`` is quick.
"""

from __future__ import annotations

import os
import sys

import click

from .. import __version__
from .analyze import analyze
from .animate import animate
from .common import user_warnings
from .compare import compare
from .design import design
from .dispersion import dispersion
from .example import example
from .explore import explore
from .export import export
from .fit import fit
from .materials import materials
from .modes import modes
from .plot import plot
from .reproduce import reproduce
from .run import run
from .sensitivity import sensitivity
from .spectrum import spectrum
from .summary import summary
from .sweep import sweep


@click.group(context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(version=__version__, prog_name="hertzchain")
def cli() -> None:
    """Impulse propagation in chains of Hertzian beads (tapered granular shock absorbers)."""


cli.add_command(run)
cli.add_command(reproduce)
cli.add_command(materials)
cli.add_command(plot)
cli.add_command(animate)
cli.add_command(analyze)
cli.add_command(compare)
cli.add_command(fit)
cli.add_command(sweep)
cli.add_command(summary)
cli.add_command(design)
cli.add_command(sensitivity)
cli.add_command(explore)
cli.add_command(export)
cli.add_command(example)
cli.add_command(modes)
cli.add_command(dispersion)
cli.add_command(spectrum)


class Terminated(KeyboardInterrupt):
    """SIGTERM (``kill``, a batch system's time limit), raised where the program is, as Ctrl-C is:
    the same clean-up runs (temporary files removed, sweeps keep their finished chunks)."""


def _on_sigterm(signum, frame) -> None:
    raise Terminated()


@user_warnings
def main(argv: list[str] | None = None) -> int:
    """Entry point: run the CLI, turning user errors into a message and exit status 2.

    The one error path of the command line: a :class:`~hertzchain.errors.HertzchainError` (bad
    config, bad file, a run that diverged), a usage error, an unreadable or unwritable file
    (OSError) or a lack of memory ends with one paragraph naming what is wrong and exit status
    2; anything else is a bug, reported as such with exit status 1. SIGTERM is handled like
    Ctrl-C (SIGINT): the job stops where it is, cleans up, and the exit status is 143 (130 for
    Ctrl-C).
    """
    import signal
    import threading

    previous = None
    if threading.current_thread() is threading.main_thread():
        previous = signal.signal(signal.SIGTERM, _on_sigterm)
    try:
        return _main(argv)
    finally:
        if previous is not None:
            signal.signal(signal.SIGTERM, previous)


def _main(argv: list[str] | None) -> int:
    """:func:`main` with SIGTERM turned into :class:`Terminated`."""
    from ..errors import HertzchainError

    try:
        cli.main(args=argv, prog_name="hertzchain", standalone_mode=False)
    except click.exceptions.Abort as exc:  # Click turns KeyboardInterrupt into Abort
        if isinstance(exc.__cause__, Terminated):
            click.echo("terminated", err=True)
            return 143
        click.echo("aborted", err=True)
        return 130
    except Terminated:
        click.echo("terminated", err=True)
        return 143
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
        click.echo(f"error: {_os_error_message(exc)}", err=True)
        return 2
    except Exception as exc:  # a bug: say so plainly, full traceback on request
        if os.environ.get("HERTZCHAIN_DEBUG"):
            raise
        click.echo(f"internal error: {type(exc).__name__}: {exc}\n"
                   "This is a bug in hertzchain; rerun with HERTZCHAIN_DEBUG=1 for the traceback.", err=True)
        return 1
    return 0


def _numba_cache_folder(exc: OSError) -> str | None:
    """The folder of Numba's cache of compiled kernels when ``exc`` was raised writing it (a full
    disk, a quota or file-size limit): Numba lets that error through without a file name, so it is
    read from the traceback's frames (``numba.core.caching`` objects keep their ``_cache_path``)."""
    folder = None
    tb = exc.__traceback__
    while tb is not None:
        frame = tb.tb_frame
        if frame.f_globals.get("__name__") == "numba.core.caching":
            folder = getattr(frame.f_locals.get("self"), "_cache_path", None) or folder
        tb = tb.tb_next
    return folder


def _os_error_message(exc: OSError) -> str:
    """What could not be read or written, and why: the file, else Numba's cache with what to do."""
    reason = exc.strerror or str(exc)
    if exc.filename is not None:
        return f"{exc.filename}: {reason}"
    folder = _numba_cache_folder(exc)
    if folder is None:
        return f"a file: {reason}"
    return (f"Numba's cache of compiled kernels ({folder}): {reason}; free space there, or point NUMBA_CACHE_DIR "
            "at a writable folder with room (each new kind of model compiles its kernels once and keeps them there)")


def entry() -> None:
    """Console-script entry point (``hertzchain``, ``python -m hertzchain.cli``)."""
    sys.exit(main())
