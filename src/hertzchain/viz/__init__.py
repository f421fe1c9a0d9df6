"""Pictures: figures and animations of results, sweeps and the paper, in one room.

- :mod:`~hertzchain.viz.common`: what every picture of a result needs (choosing a member of a
  batch, a time window, the title, bead and contact positions, the image format, saving);
- :mod:`~hertzchain.viz.signals`, :mod:`~hertzchain.viz.spacetime`, :mod:`~hertzchain.viz.energy`:
  ``hertzchain plot --kind signals | spacetime | energy``;
- :mod:`~hertzchain.viz.metrics`: a sweep's ``metrics.csv`` against its swept parameters;
- :mod:`~hertzchain.viz.animation`: ``hertzchain animate``, the chain to scale frame by frame;
- :mod:`~hertzchain.viz.style`: the Agg figure factory and the paper's look (fonts, colours,
  PNG + PDF), used by the paper's figures in :mod:`hertzchain.paper`.

Every function returns or writes a Matplotlib figure built on its own Agg canvas (no pyplot
state, the session's backend untouched). Nothing is imported here, so that a process drawing
with :mod:`~hertzchain.viz.style` alone loads neither xarray nor SciPy.

Display units: time in ms, force in N, energy in mJ, positions along the chain in mm.
"""
