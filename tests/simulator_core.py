"""Run Numba's CUDA simulator on one CPU.

The simulator runs each GPU thread of a block as a Python thread, and its main thread polls them
in a busy loop. With a second idle core the poller and the block threads hand the GIL back and
forth across cores, and a comparison that takes ~23 s on one core took more than 200 s
(``tests/cuda_compare.py bodies``, 2 idle cores; 22 s when the other core was busy with another
test). The comparison scripts pin themselves to one CPU before they simulate anything.
"""

from __future__ import annotations

import os


def pin_to_one_cpu() -> None:
    """Restrict this process (and the threads it starts later) to one of its allowed CPUs, where
    the platform allows it (Linux); elsewhere nothing changes."""
    if os.environ.get("NUMBA_ENABLE_CUDASIM") == "1" and hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {min(os.sched_getaffinity(0))})
