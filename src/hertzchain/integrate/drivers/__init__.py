"""One chain's integrators: velocity Verlet, fourth-order RKN, threads, the 2D path, scipy's DOP853."""
