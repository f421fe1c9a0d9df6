"""The explorer's room: a local web app to feel how the chain, the striker, the wall and the contact law
shape the wall pulse (``hertzchain explore``), and the same app inside Jupyter
(``hertzchain.explore()``).

- :mod:`~hertzchain.explorer.settings`: what a view is (:class:`ExplorerSettings`) and the run
  config that reproduces it ("save as config");
- :mod:`~hertzchain.explorer.compute`: one view computed (the run, the cos^6 fit, the space-time
  map, the energies, paper eqs. 6-8 beside them), built on :mod:`hertzchain.viz`;
- :mod:`~hertzchain.explorer.app`: the page (Panel on Bokeh; needs the ``[explore]`` extra);
- :func:`serve`: the app on ``http://127.0.0.1:PORT/`` until stopped.

Nothing here loads Panel until the app is asked for, so the package imports without the extra.
(The room is ``explorer``, not ``explore``: a subpackage becomes an attribute of ``hertzchain``
when imported, and would then hide the function ``hertzchain.explore``.)
"""

from __future__ import annotations

__all__ = ["explore", "serve", "require_panel"]


def require_panel() -> None:
    """Fail with a clean error naming the ``[explore]`` extra when Panel is not installed.

    Raises
    ------
    ConfigError
        Panel (and Bokeh) are missing.
    """
    from ..errors import ConfigError

    try:
        import panel  # noqa: F401
    except ImportError:
        raise ConfigError("explore", "needs Panel and Bokeh: pip install 'hertzchain[explore]'") from None


def explore(settings=None, **changes):
    """The interactive explorer as a displayable object (show it as a Jupyter cell's last value).

    Parameters
    ----------
    settings : ExplorerSettings or None
        The first view (default: the paper's chain 1 hit at 0.2 m/s by an 8 mm striker).
    **changes
        :class:`~hertzchain.explorer.settings.ExplorerSettings` fields to change from it, e.g.
        ``striker_velocity=0.3`` [m/s] or ``chain="chain2"``.

    Returns
    -------
    hertzchain.explorer.app.Explorer
        A Panel viewer: displayed in a notebook, served by :func:`serve`; ``.apply(**changes)``
        changes the view from code and ``.view`` holds its numbers.
    """
    require_panel()
    import panel as pn

    from .app import Explorer
    from .settings import ExplorerSettings

    pn.extension(inline=True)  # Bokeh's and Panel's scripts inside the notebook: no CDN
    base = settings if settings is not None else ExplorerSettings()
    return Explorer(base.replace(**changes) if changes else base)


def serve(port: int, *, address: str = "127.0.0.1", open_browser: bool = False, ready=None) -> None:
    """Serve the explorer at ``http://ADDRESS:PORT/`` until stopped (Ctrl-C or SIGTERM).

    Every browser tab gets its own explorer. Bokeh's and Panel's scripts are served by the app
    itself (no CDN), so the page works offline.

    Parameters
    ----------
    port : int
        TCP port.
    address : str
        Interface to listen on (the local machine by default).
    open_browser : bool
        Open the page in the default browser once the server listens.
    ready : callable or None
        Called with the page's URL once the server listens.
    """
    require_panel()
    import panel as pn

    from .app import Explorer

    url = f"http://{address}:{port}/"
    server = pn.serve({"/": lambda: Explorer().__panel__()}, port=port, address=address, show=False,
                      start=False, title="hertzchain explorer",
                      websocket_origin=[f"{address}:{port}", f"localhost:{port}"])
    if open_browser:
        import webbrowser

        server.io_loop.add_callback(webbrowser.open, url)
    if ready is not None:
        server.io_loop.add_callback(ready, url)
    server.start()
    server.io_loop.start()
