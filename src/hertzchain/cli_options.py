"""Click options shared by every command that reads a config (run, sweep, fit, design, ...)."""

from __future__ import annotations

import click

#: ``--set DOTTED.PATH=VALUE`` (repeatable): change one config field without editing the file.
#: The values reach :func:`hertzchain.config.apply_overrides` and are validated like the file.
set_option = click.option(
    "--set", "overrides", multiple=True, metavar="DOTTED.PATH=VALUE",
    help="Override one config field, e.g. --set striker.velocity=0.3 (repeatable; TOML values).")
