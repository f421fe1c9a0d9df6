"""Granular crystals: the static equilibrium of a loaded chain, its linear modes and Bloch band
structure, harmonic drives and steady-state transmission spectra.

The modules are loaded one by one (``hertzchain.equilibrium`` and the other public names are
re-exported lazily by :mod:`hertzchain`); this package imports nothing itself, so that the engine
(:mod:`hertzchain.bodies`, :mod:`hertzchain.runs.simulation`) can use one of its modules without the rest.
"""
