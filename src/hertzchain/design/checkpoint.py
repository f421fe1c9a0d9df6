"""The checkpoint of a design search: ``checkpoint.pkl`` written after engine calls, and read back
on a rerun with nothing but the search's own classes allowed in it.

The state object is :class:`hertzchain.design.search._State` (with the optimiser and its random
streams); it stays defined there, so that checkpoints name the same classes as before.
"""

from __future__ import annotations

import pickle
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import HertzchainError
from .problem import DesignProblem

_CHECKPOINT = "checkpoint.pkl"


class DesignMismatch(HertzchainError):
    """The output folder holds the checkpoint of a different design."""


def _save(out: Path, state: Any) -> None:
    """Write the search state (with NumPy's global random state) to ``out/checkpoint.pkl``."""
    from ..fileio import write_bytes

    # NumPy's global stream too: pymoo draws from it, and cma seeds it.
    write_bytes(out / _CHECKPOINT, pickle.dumps((state, np.random.get_state()), protocol=pickle.HIGHEST_PROTOCOL))


#: What a checkpoint may name when it is read back: the search's own state (hertzchain.design),
#: the optimisers (cma, pymoo) and NumPy's arrays and generators, and plain containers. Anything
#: else (os.system, eval, ...) is refused, so that a design folder received from someone else
#: cannot run code on --resume (a pickle may call any importable function).
_CHECKPOINT_MODULES = ("hertzchain.design", "cma", "pymoo", "numpy", "collections", "copyreg")
_CHECKPOINT_BUILTINS = frozenset({"dict", "list", "set", "frozenset", "tuple", "int", "float", "complex", "bool",
                                  "str", "bytes", "bytearray", "slice", "range", "object"})


class _CheckpointUnpickler(pickle.Unpickler):
    def find_class(self, module: str, name: str):
        allowed = (name in _CHECKPOINT_BUILTINS if module == "builtins"
                   else any(module == m or module.startswith(m + ".") for m in _CHECKPOINT_MODULES))
        if allowed:
            return super().find_class(module, name)
        raise pickle.UnpicklingError(f"a design checkpoint never refers to {module}.{name}")


def _load(out: Path, problem: DesignProblem, force: bool) -> Any:
    """The search state saved in ``out`` for ``problem`` (NumPy's global random state restored), or
    None to start afresh (no checkpoint, an unreadable one, or another design's with ``force``)."""
    import io

    path = out / _CHECKPOINT
    if not path.exists():
        return None
    try:
        state, global_random = _CheckpointUnpickler(io.BytesIO(path.read_bytes())).load()
    except pickle.UnpicklingError as exc:
        if "never refers to" in str(exc) and not force:
            raise DesignMismatch(f"{path} is not a checkpoint this program wrote ({exc}): it is not loaded; remove it "
                                 "or use --force to start afresh") from None
        return None
    except Exception:  # an unreadable checkpoint (another version, truncated copy): start afresh
        return None
    if getattr(state, "hash", None) != problem.hash:
        if force:
            return None
        raise DesignMismatch(f"{out} holds the checkpoint of a different design (hash {str(state.hash)[:12]}, this one "
                             f"{problem.hash[:12]}); choose another --out or use --force to start afresh")
    np.random.set_state(global_random)
    return state

