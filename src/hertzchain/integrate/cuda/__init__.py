"""The GPU engine of a packed batch (``numba.cuda``; checked in Numba's CUDA simulator)."""
