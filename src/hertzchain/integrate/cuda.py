"""CUDA backend of the batched engine (numba.cuda); placeholder, filled below."""

from __future__ import annotations

from ..errors import ConfigError

ENGINE = "batched velocity Verlet on the GPU (numba.cuda)"
AUTO_MIN_MEMBERS = 4096
DEVICES = ("auto", "cpu", "cuda")


def check_device(device) -> None:
    if device not in DEVICES:
        raise ConfigError("device", f"must be one of {', '.join(DEVICES)}, got {device!r}")


def gpu_usable() -> bool:
    return False


def require_gpu() -> None:
    if not gpu_usable():
        raise ConfigError("device", "no usable CUDA GPU")


def use_gpu(device: str, n_members: int) -> bool:
    if device == "cuda":
        require_gpu()
        return True
    return device == "auto" and n_members >= AUTO_MIN_MEMBERS and gpu_usable()


def run_packed(pk, progress) -> None:
    raise NotImplementedError
