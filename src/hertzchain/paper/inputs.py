"""What ``hertzchain reproduce --from-data`` reads, checked as data before anything is drawn.

A reproduction folder may be edited, copied in part or received from someone else: its
``summary.json`` is read as data (:func:`check_settings`, :func:`check_laws`: every field the
redraw relies on has the right type, or a :class:`~hertzchain.errors.ConfigError` names the file
and the key), and its ``data/`` folder must hold every trace the reproduction writes
(:func:`expected_traces`), or the missing ones are named. Nothing heavy is imported here:
:mod:`hertzchain.paper.early` checks the model-variant numbers before it forks.
"""

from __future__ import annotations

import math
from typing import Any, TypeGuard

from ..errors import ConfigError

__all__ = ["check_settings", "check_laws", "expected_traces", "SUB_TAGS"]

#: Fig. 3c: the substitution runs and their file tags.
SUB_TAGS = {"reference": "reference", "dq/q = +1": "dq_plus", "dq/q = -1": "dq_minus"}

#: settings of summary.json: key -> (kind, required); kinds: "positive" number, "fraction" in (0, 1]
#: or null, "name" (text), "count" (an int >= 1).
_SETTINGS = {"striker_velocity": "positive", "striker_diameter": "positive", "eps_target": "fraction",
             "law": "name", "duration": "positive", "sample_interval": "positive", "material": "name",
             "n0": "count"}


def _number(v: Any) -> TypeGuard[float]:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


def check_settings(summary: Any, where: str) -> dict:
    """The ``settings`` of a reproduction's summary, each of the right type.

    Parameters
    ----------
    summary : Any
        ``summary.json`` as read.
    where : str
        The file (the error's field).

    Returns
    -------
    dict
        The settings.

    Raises
    ------
    ConfigError
        Naming ``summary.json``, the key and what it must be.
    """
    settings = summary.get("settings") if isinstance(summary, dict) else None
    if not isinstance(settings, dict):
        raise ConfigError(where, "is not the summary of a reproduction: its 'settings' are missing or damaged "
                          "(not a table); rerun 'hertzchain reproduce' without --from-data")
    for key, kind in _SETTINGS.items():
        v = settings.get(key)
        ok = {"positive": _number(v) and v > 0, "fraction": v is None or (_number(v) and 0 < v <= 1),
              "name": isinstance(v, str) and v != "",
              "count": isinstance(v, int) and not isinstance(v, bool) and v >= 1}[kind]
        if not ok:
            need = {"positive": "a positive number", "fraction": "a number in (0, 1] or null", "name": "a name",
                    "count": "a whole number >= 1"}[kind]
            raise ConfigError(where, f"settings.{key} is {v!r}; it must be {need} (is the summary damaged? rerun "
                              "'hertzchain reproduce' without --from-data)")
    return settings


def check_laws(laws: Any) -> str | None:
    """Why the model-variant numbers (``fidelity.laws``) cannot be drawn, or None when they can.

    Parameters
    ----------
    laws : Any
        ``summary["fidelity"]["laws"]``: {law: {chain: {"beads", "peak_force", "duration"}}}.

    Returns
    -------
    str or None
        The first key that is wrong, and how.
    """
    if not isinstance(laws, dict) or not laws:
        return "fidelity.laws is not a table of contact laws"
    for law, row in laws.items():
        if not isinstance(row, dict):
            return f"fidelity.laws.{law} is not a table"
        for chain in ("chain1", "chain2"):
            c = row.get(chain)
            if not isinstance(c, dict):
                return f"fidelity.laws.{law}.{chain} is missing"
            beads = c.get("beads")
            if not (isinstance(beads, list) and beads and all(isinstance(b, int) and not isinstance(b, bool)
                                                               and 1 <= b <= 200 for b in beads)):
                return f"fidelity.laws.{law}.{chain}.beads is not a list of bead numbers"
            for key in ("peak_force", "duration"):
                vals = c.get(key)
                if not (isinstance(vals, list) and len(vals) == len(beads) and all(_number(x) for x in vals)
                        and vals[0] != 0):
                    return (f"fidelity.laws.{law}.{chain}.{key} is not {len(beads)} numbers (one per bead) "
                            "starting with a non-zero one")
    return None


def expected_traces(n0: int) -> list[str]:
    """The trace files (in ``data/``) a reproduction writes and ``--from-data`` reads.

    Parameters
    ----------
    n0 : int
        The first truncation (bead 16 in the paper).

    Returns
    -------
    list of str
        File names: the truncated chains, Fig. 3a-b (rigid and with lateral freedom) and Fig. 3c.
    """
    from ..chain import TABLE_I_MM
    from . import fidelity, protocol

    names = [f"{chain}_truncated_{n:02d}.nc" for chain in ("chain1", "chain2")
             for n in range(n0, len(TABLE_I_MM[chain]) + 1)]
    names += [f"fig3_chain2_offset_bead{b}_e{f:.2f}.nc" for b in protocol.MISALIGNED_BEADS
              for f in protocol.MISALIGNMENT_FRACTIONS]
    names += [f"fig3_lateral_{track}_bead{b}_e{f:.2f}.nc" for track in fidelity.TRACKS
              for b in protocol.MISALIGNED_BEADS for f in fidelity.LATERAL_FRACTIONS]
    names += [f"fig3c_chain1_24_{tag}.nc" for tag in SUB_TAGS.values()]
    return names
