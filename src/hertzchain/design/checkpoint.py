"""The checkpoint of a design search: ``checkpoint.npz``, data only, and the search resumed by replay.

A design folder may come from someone else, so its checkpoint is read as data and nothing in it
can run code: it is one NumPy ``.npz`` archive (read with ``allow_pickle=False``) holding a JSON
document (``meta``, UTF-8 bytes) and plain numeric arrays. The document carries a schema version
(:data:`SCHEMA`), the SHA-256 of the design problem (a checkpoint resumes only the same design),
every evaluated candidate (the history rows, and the evaluations by candidate key) and the
optimiser's state: CMA-ES's mean, step size sigma, covariance matrix C, iteration and evaluation
counters and the state of its random stream, or NSGA-II's generation, population and the state of
its random generator. Only what defines the search is kept: NumPy's global random state is not
(``cma`` seeds it but draws its samples from the search's own stream, ``pymoo`` draws from its own
generator, and anything else in the process may draw from it: a rerun in a new process would
never match it).

Resuming does not rebuild the optimiser from its saved attributes (``cma``'s object holds dozens
of private ones, and some of its options are strings that ``cma`` evaluates): the search runs
again from its seed, and every generation already evaluated is *replayed* from the saved rows
(no engine run; :class:`Replay`): the optimiser asks for exactly the candidates it asked for
before, learns their saved values and reaches, bit for bit, the state it had when the
checkpoint was written. That state is then compared with the saved one (mean, sigma, C,
counters, random streams): a replay that asks for other candidates or ends elsewhere (a
checkpoint of another hertzchain or ``cma`` version, or an edited file) is reported, the file set
aside, and the search starts afresh. So a resumed search ends with the result of an uninterrupted
one.

An unreadable or damaged checkpoint (truncated, not an archive, a pickle, a field of the wrong
type, a member that is not a ``.npy`` array or declares more data than it holds, a FIFO, a device
or a link out of the folder: :mod:`hertzchain.received`) and a ``checkpoint.pkl`` of an older
hertzchain (a pickle: never read) are named in a :class:`~hertzchain.errors.CheckpointWarning`,
renamed to ``<name>.unreadable-<time>`` (kept, not deleted) and the search restarts.
"""

from __future__ import annotations

import io
import itertools
import json
import math
import os
import time
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import CheckpointWarning, HertzchainError
from .objectives import Evaluation

_CHECKPOINT = "checkpoint.npz"
#: The pickle checkpoint of hertzchain before the data-only format: never read.
_LEGACY = "checkpoint.pkl"
#: Version of the checkpoint's layout; another version is set aside, not guessed at.
SCHEMA = 1
_FORMAT = "hertzchain design checkpoint"
_PHASES = ("population", "polish", "gradient", "verify")
_FIDELITIES = ("search", "full")


class DesignMismatch(HertzchainError):
    """The output folder holds the checkpoint of a different design."""


class ReplayDiverged(HertzchainError):
    """Replaying a checkpoint asked for other candidates than it holds (or ended in another state)."""


class _Damaged(Exception):
    """A checkpoint that cannot be used; the message says why."""


# ------------------------------------------------------------------------------------------
# writing
# ------------------------------------------------------------------------------------------
def _plain(x: Any) -> Any:
    """NumPy scalars as Python ones (JSON)."""
    if isinstance(x, np.generic):
        return x.item()
    if isinstance(x, np.ndarray):
        return x.tolist()
    raise TypeError(f"{type(x).__name__} cannot be written to a checkpoint")


def _evaluation_data(ev: Evaluation) -> dict:
    return {"objectives": dict(ev.objectives), "feasible": bool(ev.feasible), "violation": float(ev.violation),
            "metrics": dict(ev.metrics), "fidelity": ev.fidelity}


def fingerprint(optimiser: Any) -> tuple[dict, dict[str, np.ndarray]]:
    """The optimiser's state as data: (JSON scalars, arrays), its own random streams included.

    CMA-ES: mean, sigma, covariance matrix C, evolution paths, iteration and evaluation
    counters, the state of its normal sampler's generator; NSGA-II: generation, population
    (variables X, objectives F), the state of its generator. Never NumPy's global random state,
    which the search does not draw from and other code in the process may (see the module
    docstring).

    Parameters
    ----------
    optimiser : cma.CMAEvolutionStrategy, pymoo algorithm or None
        The search's optimiser.

    Returns
    -------
    (dict, dict)
        Scalars (JSON) and arrays (``.npz``).
    """
    scalars: dict[str, Any] = {}
    arrays: dict[str, np.ndarray] = {}
    if optimiser is None:
        scalars["optimiser"] = None
    elif hasattr(optimiser, "countiter"):  # cma
        scalars["optimiser"] = "cma-es"
        scalars["cma"] = {"sigma": float(optimiser.sigma), "countiter": int(optimiser.countiter),
                          "countevals": int(optimiser.countevals),
                          "randn": optimiser.opts["randn"].rng.bit_generator.state}
        arrays["cma_mean"] = np.asarray(optimiser.mean, float)
        arrays["cma_C"] = np.asarray(optimiser.C, float)
        arrays["cma_pc"] = np.asarray(optimiser.pc, float)
        arrays["cma_ps"] = np.asarray(optimiser.adapt_sigma.ps, float)
    else:  # pymoo
        scalars["optimiser"] = "nsga-ii"
        rng = getattr(optimiser, "random_state", None)
        scalars["nsga"] = {"n_gen": None if optimiser.n_gen is None else int(optimiser.n_gen),
                           "random": None if rng is None else rng.bit_generator.state}
        pop = getattr(optimiser, "pop", None)
        if pop is not None:
            arrays["nsga_X"] = np.asarray(pop.get("X"), float)
            arrays["nsga_F"] = np.asarray(pop.get("F"), float)
    return scalars, arrays


def _save(out: Path, state: Any) -> None:
    """Write the search state to ``out/checkpoint.npz`` (atomically; see the module docstring)."""
    from .. import __version__
    from ..fileio import write_bytes

    scalars, arrays = fingerprint(state.optimiser)
    meta = {
        "format": _FORMAT, "schema": SCHEMA, "hertzchain": __version__, "problem_hash": state.hash,
        "phase": state.phase, "generation": int(state.generation), "n_evaluations": int(state.n_evaluations),
        "restarts": int(state.restarts), "verified": bool(state.verified), "elapsed_s": float(state.elapsed_s),
        "state": scalars,
    }
    # History rows and cache entries never change once added: only the new ones are serialised
    # (a long search saves its growing history once a second).
    done = state.written
    parts = {"history": state.history, "cache": state.cache, "full_cache": state.full_cache}
    for name, items in parts.items():
        texts = done.setdefault(name, [])
        new = items[len(texts):] if isinstance(items, list) else \
            [[list(k), _evaluation_data(ev)] for k, ev in itertools.islice(items.items(), len(texts), None)]
        texts += [json.dumps(item, default=_plain, allow_nan=True, separators=(",", ":")) for item in new]
    head = json.dumps(meta, default=_plain, allow_nan=True, separators=(",", ":"))
    text = head[:-1] + "".join(f',"{name}":[' + ",".join(done[name]) + "]" for name in parts) + "}"
    buf = io.BytesIO()
    document = np.frombuffer(text.encode("utf-8"), np.uint8)
    np.savez(buf, meta=document, **arrays)  # type: ignore[arg-type]  # NumPy's stub: **arrays vs allow_pickle: bool
    write_bytes(out / _CHECKPOINT, buf.getvalue())


# ------------------------------------------------------------------------------------------
# reading
# ------------------------------------------------------------------------------------------
@dataclass
class Saved:
    """A checkpoint read and checked (see :func:`_load`)."""

    path: Path
    problem_hash: str
    phase: str
    generation: int
    n_evaluations: int
    elapsed_s: float
    history: list[dict]
    cache: dict
    full_cache: dict
    scalars: dict
    arrays: dict[str, np.ndarray] = field(repr=False)


def _number(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def _scalar(v: Any) -> bool:
    return v is None or isinstance(v, (int, float, str, bool))


def _need(ok: bool, what: str) -> None:
    if not ok:
        raise _Damaged(what)


def _key(raw: Any, where: str) -> tuple:
    """A candidate key written as ``[[group, value], ...]`` (a list value: a list range)."""
    _need(isinstance(raw, list), f"{where}: a candidate key is a list")
    out = []
    for item in raw:
        _need(isinstance(item, list) and len(item) == 2 and isinstance(item[0], str), f"{where}: a key item is "
              "[path, value]")
        v = item[1]
        if isinstance(v, list):
            _need(all(_scalar(e) for e in v), f"{where}: a list value holds numbers or names")
            v = tuple(v)
        else:
            _need(_scalar(v), f"{where}: a value is a number or a name")
        out.append((item[0], v))
    return tuple(out)


def _evaluation(raw: Any, where: str, objectives: list[str]) -> Evaluation:
    _need(isinstance(raw, dict), f"{where}: an evaluation is a table")
    objs, metrics = raw.get("objectives"), raw.get("metrics")
    _need(isinstance(objs, dict) and set(objs) == set(objectives) and all(_number(v) for v in objs.values()),
          f"{where}: objectives {objectives} as numbers")
    _need(isinstance(metrics, dict) and all(isinstance(k, str) and _scalar(v) for k, v in metrics.items()),
          f"{where}: metrics are named numbers")
    _need(isinstance(raw.get("feasible"), bool), f"{where}: feasible is true or false")
    _need(_number(raw.get("violation")) and raw["violation"] >= 0, f"{where}: violation is a number >= 0")
    _need(raw.get("fidelity") in _FIDELITIES, f"{where}: fidelity is one of {_FIDELITIES}")
    return Evaluation({k: float(v) for k, v in objs.items()}, raw["feasible"], float(raw["violation"]),
                      dict(metrics), fidelity=raw["fidelity"])


def _cache(raw: Any, where: str, objectives: list[str]) -> dict:
    _need(isinstance(raw, list), f"{where} is a list")
    out = {}
    for i, entry in enumerate(raw):
        _need(isinstance(entry, list) and len(entry) == 2, f"{where}[{i}] is [key, evaluation]")
        out[_key(entry[0], f"{where}[{i}]")] = _evaluation(entry[1], f"{where}[{i}]", objectives)
    return out


def _rows(raw: Any, dim: int) -> list[dict]:
    _need(isinstance(raw, list), "history is a list")
    for i, row in enumerate(raw):
        where = f"history[{i}]"
        _need(isinstance(row, dict), f"{where} is a table")
        x = row.get("x")
        _need(isinstance(x, list) and len(x) == dim and all(_number(v) and math.isfinite(v) for v in x),
              f"{where}.x is {dim} finite numbers")
        _need(row.get("phase") in _PHASES, f"{where}.phase is one of {_PHASES}")
        _need(row.get("fidelity") in _FIDELITIES, f"{where}.fidelity is one of {_FIDELITIES}")
        for k in ("evaluation", "generation", "engine_runs"):
            _need(isinstance(row.get(k), int) and not isinstance(row[k], bool) and row[k] >= 0,
                  f"{where}.{k} is a count")
        _need(row["evaluation"] == i, f"{where}.evaluation is {i}")
    return raw


def _read(path: Path, problem) -> Saved:
    """The checkpoint at ``path`` checked field by field (:class:`_Damaged` otherwise)."""
    from ..received import load_npz

    # A received folder's file: a regular one only (a FIFO would hang the read), every member a
    # .npy array of numbers whose header is checked before it is allocated (hertzchain.received).
    try:
        files = load_npz(path, path.parent)
    except ValueError as exc:
        raise _Damaged(f"not a NumPy .npz archive of plain arrays ({exc})") from None
    raw_meta = files.pop("meta", None)
    _need(raw_meta is not None and raw_meta.dtype == np.uint8 and raw_meta.ndim == 1, "no 'meta' document")
    assert raw_meta is not None  # (_need raised otherwise)
    try:
        meta = json.loads(raw_meta.tobytes().decode("utf-8"))
    except (UnicodeDecodeError, ValueError, RecursionError) as exc:
        raise _Damaged(f"its 'meta' document is not JSON ({type(exc).__name__})") from None
    _need(isinstance(meta, dict) and meta.get("format") == _FORMAT, "not a hertzchain design checkpoint")
    _need(meta.get("schema") == SCHEMA, f"layout version {meta.get('schema')!r}, this hertzchain reads {SCHEMA}")
    _need(isinstance(meta.get("problem_hash"), str), "no problem hash")
    for k in ("generation", "n_evaluations"):
        _need(isinstance(meta.get(k), int) and not isinstance(meta[k], bool) and meta[k] >= 0, f"{k} is a count")
    _need(_number(meta.get("elapsed_s")) and math.isfinite(meta["elapsed_s"]) and meta["elapsed_s"] >= 0,
          "elapsed_s is a time")
    _need(meta.get("phase") in ("population", "polish", "gradient", "done"),
          "phase is population, polish, gradient or done")
    _need(isinstance(meta.get("state"), dict), "no optimiser state")
    for name, arr in files.items():
        _need(arr.dtype.kind in "fiub", f"array {name!r} holds numbers")
    objectives = list(problem.objectives)
    return Saved(path=path, problem_hash=meta["problem_hash"], phase=meta["phase"], generation=meta["generation"],
                 n_evaluations=meta["n_evaluations"], elapsed_s=float(meta["elapsed_s"]),
                 history=_rows(meta.get("history"), problem.space.dim),
                 cache=_cache(meta.get("cache"), "cache", objectives),
                 full_cache=_cache(meta.get("full_cache"), "full_cache", objectives),
                 scalars=meta["state"], arrays=files)


def set_aside(path: Path, why: str) -> Path:
    """Rename an unusable checkpoint to ``<name>.unreadable-<time>`` (kept, not deleted) and warn.

    Parameters
    ----------
    path : Path
        The checkpoint.
    why : str
        What is wrong with it (for the warning).

    Returns
    -------
    Path
        Its new name.
    """
    stamp = time.strftime("%Y%m%d-%H%M%S")
    target = path.with_name(f"{path.name}.unreadable-{stamp}")
    n = 1
    while target.exists():
        n += 1
        target = path.with_name(f"{path.name}.unreadable-{stamp}-{n}")
    try:
        path.rename(target)
        kept = f"kept as {target.name}"
    except OSError as exc:
        target, kept = path, f"it could not be renamed ({exc.strerror}) and stays as it is"
    warnings.warn(CheckpointWarning(f"{path}: {why}; it is not used ({kept}) and the design search starts "
                                    "afresh"), stacklevel=3)
    return target


def _load(out: Path, problem, force: bool) -> Saved | None:
    """The checkpoint saved in ``out`` for ``problem``, or None to start afresh.

    None when there is none, or after an unusable one was set aside with a warning
    (:func:`set_aside`), or for another design's checkpoint with ``force``; a checkpoint of
    another design without ``force`` raises :class:`DesignMismatch`.
    """
    legacy = out / _LEGACY
    if legacy.exists():
        set_aside(legacy, "a checkpoint of an older hertzchain, a Python pickle, which can run code when read; "
                  "hertzchain never reads one")
    path = out / _CHECKPOINT
    if not os.path.lexists(path):  # lexists: a dangling link is set aside like any unusable file
        return None
    try:
        saved = _read(path, problem)
    except _Damaged as exc:
        set_aside(path, f"is damaged or not a design checkpoint ({exc})")
        return None
    if saved.problem_hash != problem.hash:
        if force:
            return None
        raise DesignMismatch(f"{out} holds the checkpoint of a different design (hash {saved.problem_hash[:12]}, "
                             f"this one {problem.hash[:12]}); choose another --out or use --force to start afresh")
    return saved


def _same(a: np.ndarray, b: np.ndarray) -> bool:
    """Equal arrays, NaN equal to NaN."""
    if a.shape != b.shape:
        return False
    if a.dtype.kind == "f" and b.dtype.kind == "f":
        return bool(np.array_equal(a, b, equal_nan=True))
    return bool(np.array_equal(a, b))


# ------------------------------------------------------------------------------------------
# replay
# ------------------------------------------------------------------------------------------
class Replay:
    """The generations of a checkpoint handed back to the search in order, without engine runs.

    :meth:`evaluate` stands for the evaluator while saved rows are left: it checks that the
    search asks for the saved candidates (:class:`ReplayDiverged` otherwise), fills the caches
    as the original evaluations did and returns the saved fitness values. :meth:`check` compares
    the state the replay reached with the saved one.

    Parameters
    ----------
    saved : Saved
        The checkpoint.
    """

    def __init__(self, saved: Saved):
        self.saved = saved
        self.pos = 0
        self.checked = False

    @property
    def active(self) -> bool:
        """Saved rows are left to replay."""
        return self.pos < len(self.saved.history)

    def evaluate(self, problem, state, xs: list[np.ndarray], phase: str) -> list[list[float]]:
        """The saved evaluations of the points ``xs`` (unit-cube coordinates) of one engine call.

        Parameters
        ----------
        problem : DesignProblem
            The design.
        state : hertzchain.design.search._State
            The search state (history, caches and counters are updated as by the evaluator).
        xs : list of numpy.ndarray
            The points the search evaluates.
        phase : str
            ``population``, ``polish``, ``gradient`` or ``verify``.

        Returns
        -------
        list of list of float
            The fitness values the search minimises.
        """
        rows = self.saved.history[self.pos:self.pos + len(xs)]
        if len(rows) != len(xs):
            raise ReplayDiverged(f"the checkpoint ends within a generation ({len(rows)} of {len(xs)} candidates)")
        verify = phase == "verify"
        cache, saved_cache = (state.full_cache, self.saved.full_cache) if verify else (state.cache, self.saved.cache)
        out = []
        for x, row in zip(xs, rows):
            expect = [float(v) for v in x]
            if row["x"] != expect or row["phase"] != phase or row["generation"] != state.generation:
                raise ReplayDiverged(f"evaluation {row['evaluation']}: the search asks for {expect} ({phase}, "
                                     f"generation {state.generation}), the checkpoint holds {row['x']} "
                                     f"({row['phase']}, generation {row['generation']})")
            key = problem.space.key(x)
            if key not in cache:
                if key not in saved_cache:
                    raise ReplayDiverged(f"evaluation {row['evaluation']}: candidate {key} has no saved evaluation")
                cache[key] = saved_cache[key]
            state.n_evaluations += row["engine_runs"]
            state.history.append(dict(row))
            out.append(cache[key].fitness(problem.objectives))
        self.pos += len(xs)
        return out

    def check(self, state) -> None:
        """Once the saved rows are replayed: the search must be where the checkpoint says.

        Parameters
        ----------
        state : hertzchain.design.search._State
            The replayed search state.
        """
        if self.active or self.checked:
            return
        self.checked = True
        s = self.saved
        if (state.generation, state.n_evaluations) != (s.generation, s.n_evaluations):
            raise ReplayDiverged(f"the replay ends at generation {state.generation} after {state.n_evaluations} "
                                 f"engine runs, the checkpoint at generation {s.generation} after {s.n_evaluations}")
        scalars, arrays = fingerprint(state.optimiser)
        differ = [k for k in scalars if scalars[k] != s.scalars.get(k)]
        differ += [k for k in arrays if k not in s.arrays or not _same(arrays[k], s.arrays[k])]
        differ += [k for k in s.arrays if k not in arrays]
        if differ:
            raise ReplayDiverged(f"the replayed optimiser differs from the saved one in {', '.join(sorted(differ))}")
