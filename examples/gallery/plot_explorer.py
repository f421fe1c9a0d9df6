"""
The explorer: see it live
=========================

``hertzchain explore`` (the ``[explore]`` extra) serves an interactive page on your machine:
change the chain, the striker, the wall or the contact law and the wall force with the paper's
cos^6 fit, the space-time map, the energies and the ballistic theory (paper eqs. 6-8) update in a
fraction of a second; "save as config" writes the TOML that ``hertzchain run`` reproduces the
view from. In Jupyter, ``hertzchain.explore()`` is the same app. Below: the page (a screenshot
taken by the project's browser test in headless Chromium), then the numbers behind one view
computed without a browser, as the app computes them.
"""

from pathlib import Path

import matplotlib.pyplot as plt

from hertzchain.explorer.compute import compute_view
from hertzchain.explorer.settings import ExplorerSettings

# run from the repository root, or from examples/gallery as the documentation build does
docs = next(p for p in (Path("docs"), Path("../../docs")) if (p / "_static" / "explorer.png").exists())
fig, ax = plt.subplots(figsize=(10, 6.9))
ax.imshow(plt.imread(docs / "_static" / "explorer.png"))
ax.axis("off")
fig.tight_layout()

view = compute_view(ExplorerSettings(chain="chain2", striker_velocity=0.3, law="viscoelastic", eps=0.985))
print(f"wall peak {view.force.max():.4f} N; cos^6 fit F_m = {view.fit.peak_force:.4f} N, "
      f"T = {view.fit.time_of_flight * 1e3:.4f} ms, tau = {view.fit.duration * 1e6:.2f} us")
for row in view.theory:
    print(f"{row.equation:>5}  {row.theory:>16}  {row.simulated:>14}")
print(view.settings.toml())
