"""
A sweep on a local Dask cluster
===============================

:func:`hertzchain.run_sweep` farms the chunks of a sweep out to a Dask cluster and writes each
chunk as it comes back. Here a ``LocalCluster`` of two workers sweeps the tapering factor q of a
short chain; on real hardware the same code takes the ``Client`` of a cluster of processes or
machines (``hertzchain sweep FILE --out DIR --scheduler tcp://HOST:8786`` from the shell; how to
start one: the user guide's "Running on a cluster").
"""

import tempfile

import matplotlib.pyplot as plt
from distributed import Client, LocalCluster

import hertzchain as hc

sweep = {
    "base": {
        "chain": {"uniform": {"n": 8, "diameter_mm": 26.0}, "taper": {"n": 8, "q": 0.05}},
        "striker": {"diameter_mm": 8.0, "velocity": 0.2},
        "run": {"duration": 2.0e-3, "sample_interval": 1e-7},
    },
    "sweep": {"mode": "grid", "chunk_size": 4,
              "parameters": {"chain.taper.q": [0.0, 0.02, 0.04, 0.06, 0.08, 0.10, 0.12, 0.14]}},
}
# Threads in this process: no worker start-up cost, and the compiled kernels are shared. Worker
# processes (LocalCluster's default, or `dask worker` on other machines) give the same chunks.
with LocalCluster(n_workers=2, threads_per_worker=1, processes=False, dashboard_address=None) as cluster, \
        Client(cluster) as client, tempfile.TemporaryDirectory() as out:
    metrics = hc.run_sweep(sweep, out, client=client).metrics

print(metrics[["chain.taper.q", "F_m", "tau"]])

fig, ax = plt.subplots(figsize=(6, 4))
ax.plot(metrics["chain.taper.q"] * 100, metrics["F_m"], "o-")
ax.set_xlabel("tapering factor q [%]")
ax.set_ylabel("peak wall force F$_m$ [N]")
ax.set_title("Wall force after 8 tapered beads (8 chains, 2 Dask workers)")
fig.tight_layout()
