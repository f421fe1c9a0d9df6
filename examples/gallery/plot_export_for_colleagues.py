"""
Exporting a result for MATLAB and spreadsheets
==============================================

A result is a NetCDF file (:func:`hertzchain.save`); colleagues who work in MATLAB or a
spreadsheet get it with ``hertzchain export result.nc --out result.mat`` (or ``.csv``,
``.parquet``), or :func:`hertzchain.export` from Python. The CSV names each column with its
unit (``wall_force [N]``, ``contact_force[3] [N]``); the MATLAB file holds one variable per
signal (``time``, ``wall_force``, ``contact_force`` as a time x contact matrix...) and a
``units`` struct. Here both are read back and drawn: the same numbers as the simulation.
"""

import tempfile
from pathlib import Path

import matplotlib.pyplot as plt
import pandas as pd
import scipy.io

import hertzchain as hc

ds = hc.simulate(hc.Model(hc.Chain.uniform(10, 26e-3).append_taper(8, 0.06), hc.Striker(8e-3, 0.2)), "auto",
                 hc.Probes(sample_interval=1e-6, sensors=(5,)))
with tempfile.TemporaryDirectory() as tmp:
    table = pd.read_csv(hc.export(ds, Path(tmp) / "result.csv"), comment="#")  # metadata in "#" lines
    mat = scipy.io.loadmat(hc.export(ds, Path(tmp) / "result.mat"), squeeze_me=True)
print(list(table.columns[:4]), "...", f"{table.shape[1]} columns")
print("MATLAB variables:", sorted(k for k in mat if not k.startswith("__")))
print("units.wall_force =", mat["units"]["wall_force"])

fig, ax = plt.subplots(figsize=(7, 3.5))
ax.plot(table["time [s]"] * 1e3, table["wall_force [N]"], label="wall_force [N] (CSV column)")
ax.plot(mat["time"] * 1e3, mat["sensor_force"], "--", label="sensor_force, bead 5 (MATLAB variable)")
ax.set_xlabel("t [ms]")
ax.set_ylabel("F [N]")
ax.legend()
fig.tight_layout()
