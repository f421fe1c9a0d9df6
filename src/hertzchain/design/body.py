"""The design objectives of a protected body (``wall.type = "body"``): what reaches the body itself.

- ``peak_body_force`` [N]: the largest force its mount passes to the ground, |k x + c v|;
- ``peak_body_acceleration`` [m/s^2]: its largest acceleration (what a payload feels);
- ``energy_to_body`` [J]: the most energy the chain had delivered to it at any time (the work of
  contact N on the body: its kinetic energy, its mount's elastic energy and what the mount's
  dashpot took).

All three are read off the sampled records (``run.sample_interval``), as the engine writes them
for every member with a body (:func:`hertzchain.result.body_arrays`).
"""

from __future__ import annotations

import numpy as np

__all__ = ["BODY_OBJECTIVES", "body_records", "body_objective", "measured_against"]

#: Objectives that need a protected body, and the record each one reads.
BODY_OBJECTIVES = {"peak_body_force": "body_force", "peak_body_acceleration": "body_acceleration",
                   "energy_to_body": "body_energy"}


def body_records(runs, systems) -> dict | None:
    """The protected bodies' signals of a batch's RawRuns, (member, time) each.

    Parameters
    ----------
    runs : list of RawRun
        The batch's runs (``RawRun.body``: the engine's record of the body).
    systems : list
        Every member's ``MemberSystem`` (its mount: ``mount_k``, ``mount_c``, ``mount_d0``).

    Returns
    -------
    dict or None
        ``body_force`` [N], ``body_acceleration`` [m/s^2], ``body_energy`` [J], NaN rows for the
        members without a body; None when no member has one.
    """
    from ..result import body_arrays

    if all(r.body is None for r in runs):
        return None
    shape = (len(runs), runs[0].time.size)
    out = {k: np.full(shape, np.nan) for k in BODY_OBJECTIVES.values()}
    for i, (r, sy) in enumerate(zip(runs, systems)):
        if r.body is not None:
            arrays = body_arrays(r.body, sy)
            for k in out:
                out[k][i] = arrays[k][1]
    return out


def body_objective(name: str, records: dict | None, shape: tuple[int, int]) -> np.ndarray:
    """One body objective of every member.

    Parameters
    ----------
    name : str
        A key of :data:`BODY_OBJECTIVES`.
    records : dict or None
        :func:`body_records` (None: no member has a body).
    shape : tuple
        (members, samples) of the batch.

    Returns
    -------
    numpy.ndarray
        (members,): the largest magnitude over the samples (the most energy for
        ``energy_to_body``); NaN for a member without a body.
    """
    series = records[BODY_OBJECTIVES[name]] if records is not None else np.full(shape, np.nan)
    return np.max(series if name == "energy_to_body" else np.abs(series), axis=1)


def measured_against(model) -> str:
    """What a design's candidates end on, in words (the design report says it for every candidate).

    Parameters
    ----------
    model : hertzchain.Model
        A candidate's model.

    Returns
    -------
    str
        E.g. ``"an immovable flat wall of AISI52100"`` or ``"a protected body of 1 kg on a mount of
        1e+06 N/m and 0 N s/m, its flat face of AISI52100"``.
    """
    wall = model.wall
    material = model.wall_material.name if model.wall_material is not None else "-"
    if not wall.is_body:
        return f"an immovable flat wall of {material}" if wall.present else "a free end"
    face = "flat" if wall.face_radius is None else f"spherical (R = {wall.face_radius * 1e3:g} mm)"
    return (f"a protected body of {wall.mass:g} kg on a mount of {wall.stiffness:g} N/m and {wall.damping:g} N s/m, "
            f"its {face} face of {material}")
