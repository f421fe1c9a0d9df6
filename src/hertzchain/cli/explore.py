"""``hertzchain explore``: the interactive explorer, served on the local machine."""

from __future__ import annotations

import click


@click.command("explore")
@click.option("--port", type=click.IntRange(1, 65535), default=5006, show_default=True,
              help="TCP port; the app is at http://127.0.0.1:PORT/.")
@click.option("--no-browser", is_flag=True, help="Do not open the page in a browser.")
def explore(port: int, no_browser: bool) -> None:
    """Serve the interactive explorer at http://127.0.0.1:PORT/ until stopped (Ctrl-C).

    Controls for the chain (the paper's presets, a uniform block with a taper, bead diameters,
    materials), the striker, the wall and the contact law; the wall force with the paper's cos^6
    fit, the space-time map, the energies and the theory's eqs. 6-8 update as you change them,
    and "save as config" writes the TOML that `hertzchain run` reproduces the view from.
    Needs the [explore] extra (pip install 'hertzchain[explore]'). Works offline.
    """
    from ..explorer import require_panel, serve

    require_panel()
    serve(port, open_browser=not no_browser,
          ready=lambda url: click.echo(f"hertzchain explorer at {url} (Ctrl-C stops it)", err=True))
