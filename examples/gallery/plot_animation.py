"""
An animation of the chain
=========================

:func:`hertzchain.animate` draws the chain to scale frame by frame, each bead coloured by the
force it carries, beside the wall force growing in time, and writes a GIF (or an MP4 when
``ffmpeg`` is installed). With positions recorded (``Probes(positions=True)``) the beads are drawn
displaced, the displacements exaggerated by a stated factor: micrometres against centimetre
beads, x1000 here. Below, four frames of the GIF as it was written.
"""

import tempfile
from pathlib import Path

import matplotlib.pyplot as plt
from PIL import Image

import hertzchain as hc

model = hc.Model(hc.paper_chain("chain1"), hc.Striker(8e-3, 0.2))
ds = hc.simulate(model, 3e-3, hc.Probes(sample_interval=1e-6, positions=True))
with tempfile.TemporaryDirectory() as tmp:
    gif = hc.animate(ds, Path(tmp) / "chain1.gif", n_frames=24, fps=12)
    movie = Image.open(gif)
    frames = []
    for k in (4, 11, 17, 22):  # the pulse in the uniform part, in the taper, at the wall, reflected
        movie.seek(k)
        frames.append(movie.convert("RGB"))

fig, axes = plt.subplots(2, 2, figsize=(9, 5.2))
for ax, frame in zip(axes.flat, frames):
    ax.imshow(frame)
    ax.axis("off")
fig.tight_layout()
