"""Which device a batch runs on: the ``device`` choice and whether a CUDA GPU is usable.

Device-neutral and cheap to import: numba.cuda is imported only when asked (``_cuda``), so the
CPU path and the checks of a ``device`` value never load it. The CUDA kernels
(:mod:`hertzchain.integrate.cuda.kernels`) and their launcher (:mod:`hertzchain.integrate.cuda.launch`)
build on it.
"""

from __future__ import annotations

import functools

import numpy as np

from ...errors import ConfigError

__all__ = ["AUTO_MIN_MEMBERS", "DEVICES", "check_device", "gpu_usable", "peak_tracker", "require_gpu", "use_gpu"]


#: ``device="auto"`` uses the GPU from this many members. Smaller batches stay on the CPU: a GPU
#: launch costs ~0.1 s of set-up and copies, and a few thousand chains leave an H100 mostly idle
#: (1.3e10 bead-steps/s at 1e3 chains with the register kernel, 8e9 with the general ones, against
#: ~1.3e9 on 2 CPU cores and ~5.6e9 on 16).
AUTO_MIN_MEMBERS = 4096
#: Accepted values of ``device``.
DEVICES = ("auto", "cpu", "cuda")


def check_device(device) -> None:
    """Refuse an unknown ``device`` (ConfigError naming ``device``).

    Parameters
    ----------
    device:
        ``"auto"``, ``"cpu"`` or ``"cuda"``.
    """
    if device not in DEVICES:
        raise ConfigError("device", f"must be one of {', '.join(repr(d) for d in DEVICES)}, got {device!r}")


def _cuda():
    """numba.cuda, or None when the ``numba-cuda`` package is missing."""
    if not hasattr(np, "row_stack"):  # numba-cuda 0.30 still calls it; NumPy 2.5 removed the alias
        np.row_stack = np.vstack
    try:
        from numba import cuda
    except ImportError:
        return None
    return cuda


def _simulated() -> bool:
    from numba import config

    return bool(config.ENABLE_CUDASIM)  # type: ignore[attr-defined]  # numba sets it at import


@functools.lru_cache(maxsize=1)
def gpu_usable() -> bool:
    """True when a real CUDA GPU can run the kernels (Numba's simulator does not count).

    Returns
    -------
    bool
        Whether ``device="auto"`` may choose the GPU (asked once per process: importing
        numba.cuda and querying the driver takes ~1 s).
    """
    cuda = _cuda()
    if cuda is None or _simulated():
        return False
    try:
        return bool(cuda.is_available()) and len(cuda.gpus) > 0
    except Exception:  # driver or toolkit libraries missing or broken: no usable GPU
        return False


def require_gpu() -> None:
    """Raise a ConfigError naming ``device`` unless a GPU (or Numba's CUDA simulator) is usable."""
    if _cuda() is None:
        raise ConfigError("device", "'cuda' needs the numba-cuda package: pip install \"hertzchain[gpu]\" "
                          "(or use device='cpu' / 'auto')")
    if not (_simulated() or gpu_usable()):
        raise ConfigError("device", "'cuda' needs a usable CUDA GPU and driver, and none was found; "
                          "use device='cpu' or 'auto'")


def use_gpu(device: str, n_members: int) -> bool:
    """Whether a batch of ``n_members`` runs on the GPU for this ``device`` choice.

    Parameters
    ----------
    device:
        ``"cpu"``: never; ``"cuda"``: always (an error when no GPU is usable); ``"auto"``: when a
        GPU is usable and ``n_members >= AUTO_MIN_MEMBERS``.
    n_members:
        Members in the batch.

    Returns
    -------
    bool
        True for the GPU.
    """
    check_device(device)
    if device == "cuda":
        require_gpu()
        return True
    return device == "auto" and n_members >= AUTO_MIN_MEMBERS and gpu_usable()


def peak_tracker(cuda, inline: dict):
    """The device function ``track_peak(fw, t, dt, peak, m)``: ``kernels._track_peak`` for member m
    (``peak`` is (8, M)), compiled with ``cuda`` (numba.cuda or the simulator's module) and the
    kernels' device options ``inline``; shared by the built-in laws' kernels and the generated ones."""
    @cuda.jit(device=True, **inline)
    def track_peak(fw, t, dt, peak, m):
        if fw > peak[0, m]:
            peak[0, m] = fw
            peak[1, m] = t
            peak[2, m] = peak[5, m]
            peak[6, m] = dt
            peak[4, m] = 1.0
        elif peak[4, m] != 0.0:
            peak[3, m] = fw
            peak[7, m] = dt
            peak[4, m] = 0.0
        peak[5, m] = fw
    return track_peak
