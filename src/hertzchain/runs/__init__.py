"""The public runs, one layer above the engine: :func:`simulation.simulate` (one chain),
:func:`batch.simulate_batch` (many; :mod:`batch_results` stacks them) and
:func:`track.simulate_lateral` (beads free to leave the axis). Each shares the pre-flight checks of
:mod:`hertzchain.checks` with the command line.
"""
