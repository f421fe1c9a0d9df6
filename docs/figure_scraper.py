"""Sphinx-Gallery image scraper for hertzchain's figures.

hertzchain's plotting functions return Matplotlib figures on their own Agg canvas, outside
pyplot (``hertzchain.plot_spacetime``...), which Sphinx-Gallery's Matplotlib scraper (it walks
``pyplot.get_fignums()``) does not see. This scraper saves every such figure an example holds in
a variable, once, after the block that made it. ``conf.py`` names it by this module's name,
before the Matplotlib scraper.
"""

from __future__ import annotations

import weakref
from pathlib import PurePosixPath

_SEEN: "weakref.WeakSet" = weakref.WeakSet()


def hertzchain_scraper(block, block_vars, gallery_conf, **kwargs) -> str:
    """Save the figures held in the example's variables that pyplot does not manage."""
    import matplotlib.pyplot as plt
    from matplotlib.figure import Figure
    from sphinx_gallery.scrapers import figure_rst

    # pyplot's open figures are the Matplotlib scraper's (it runs next and closes them): marked
    # as seen, so that a later block does not take them for hertzchain's once closed
    _SEEN.update(plt.figure(n) for n in plt.get_fignums())
    figures = [v for v in block_vars["example_globals"].values() if isinstance(v, Figure) and v not in _SEEN]
    paths = []
    for fig, path in zip(figures, block_vars["image_path_iterator"]):
        fig.savefig(str(path), dpi=100)
        _SEEN.add(fig)
        paths.append(PurePosixPath(path))
    return figure_rst(paths, gallery_conf["src_dir"]) if paths else ""


def _get_sg_image_scraper():
    """What Sphinx-Gallery calls to get the scraper named by this module."""
    return hertzchain_scraper
