"""Integrators: the compiled velocity Verlet (default) and the scipy DOP853 reference."""
