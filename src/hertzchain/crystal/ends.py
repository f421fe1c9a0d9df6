"""A drive that enters at bead N (``[drive] end = "last"``): the same chain held the other way round.

A driven chain lies between its driven end and the opposite boundary, where the transmitted force
is measured. With ``end = "first"`` (the default, DESIGN's convention) the drive acts on bead 1 and
the wall (``[wall]``) stands after bead N. With ``end = "last"`` the drive acts on bead N and the
wall stands before bead 1: the precompression F0 pushes bead N towards it, a force drive adds
s(t) to bead N towards the wall, a displacement drive's massless driver presses on bead N.
Contacts keep the model's numbering: contact j joins bead j and bead j + 1, contact 0 is then
wall-bead 1 (``wall_force``, the transmitted force), contact N bead N-driver (absent for a force
drive). Forces and the drive act along the chain towards the wall, as everywhere.

This is the chain of the model read from bead N: :func:`from_driven_end` turns a model with
``end = "last"`` into that chain (beads, elements, offsets and loads renumbered i -> N + 1 - i,
contacts j -> N - j, the drive on its bead 1); every analysis (the driven run, the equilibrium,
the linearised matrices) runs on it and maps its numbers back here, so both ends go through one
code path and a symmetric chain transmits the same from either end.
"""

from __future__ import annotations

import dataclasses
import json

import numpy as np

__all__ = ["driven_from_last", "from_driven_end", "mirrored_probes", "dataset_to_model_numbers",
           "equilibrium_to_model_numbers"]


def driven_from_last(model) -> bool:
    """True when ``model`` has a drive entering at bead N (``drive.end == "last"``)."""
    return model.drive is not None and getattr(model.drive, "end", "first") == "last"


def from_driven_end(model):
    """The model read from its driven end (module docstring): for ``end = "last"``, beads, loads and
    offsets renumbered i -> N + 1 - i and the drive on (its) bead 1; ``model`` itself otherwise."""
    if not driven_from_last(model):
        return model
    chain, n = model.chain, model.chain.n_beads
    # the Chain's own constructor (through replace: this module imports nothing of the package, so
    # that the equilibrium, low in the layers, can use it)
    turned = dataclasses.replace(chain, diameters=chain.diameters[::-1].copy(), materials=tuple(chain.materials[::-1]),
                                 offsets=chain.offsets[::-1].copy() if chain.offsets.any() else None,
                                 elements=tuple(chain.elements[::-1]))
    loads = tuple((n + 1 - bead, force) for bead, force in model.loads)
    return dataclasses.replace(model, chain=turned, loads=loads, drive=dataclasses.replace(model.drive, end="first"))


def mirrored_probes(probes, n_beads: int):
    """``probes`` in the numbers of :func:`from_driven_end`'s chain: contacts j -> N - j, sensors
    (beads) i -> N + 1 - i."""
    contacts = probes.contacts
    if isinstance(contacts, tuple):
        contacts = tuple(sorted(n_beads - c for c in contacts))
    return dataclasses.replace(probes, contacts=contacts, sensors=tuple(n_beads + 1 - s for s in probes.sensors))


def dataset_to_model_numbers(ds, model):
    """A run of :func:`from_driven_end`'s chain in ``model``'s numbers: the ``contact``,
    ``contact_all``, ``bead`` and ``sensor`` coordinates renumbered back (and sorted), the model's
    own description in the attributes."""
    n = model.chain.n_beads
    back = {"contact": lambda c: n - c, "contact_all": lambda c: n - c, "bead": lambda b: n + 1 - b,
            "sensor": lambda b: n + 1 - b}
    for name, f in back.items():
        if name in ds.coords:
            ds = ds.assign_coords({name: (name, f(ds[name].values), ds[name].attrs)}).sortby(name)
    over = json.loads(ds.attrs.get("elastic_limit_contacts", "[]"))
    described = json.dumps(model.describe())
    config = ds.attrs.get("config")
    ds.attrs.update(model=described, elastic_limit_contacts=json.dumps(sorted(n - c for c in over)))
    if config is not None and config.startswith('{"model": '):  # no config given: the model's own
        ds.attrs["config"] = '{"model": ' + described + "}"
    return ds


def equilibrium_to_model_numbers(eq, model):
    """An :class:`~hertzchain.crystal.statics.Equilibrium` of :func:`from_driven_end`'s chain in
    ``model``'s numbers: contact j -> N - j, bead i -> N + 1 - i; body 0 is then the wall (its
    displacement the mount's deflection, its position the wall's face), body N + 1 the driver's
    side. Displacements and positions stay measured along the chain from the driven end towards
    the wall (the turned chain's axis)."""
    n = model.chain.n_beads
    wall_face = float(eq.positions[n] + model.chain.radii[0] + eq.mount_deflection)
    return dataclasses.replace(eq, overlaps=eq.overlaps[::-1].copy(), forces=eq.forces[::-1].copy(),
                               displacements=np.concatenate([[eq.mount_deflection], eq.displacements[:0:-1]]),
                               positions=np.concatenate([[wall_face], eq.positions[:0:-1]]),
                               external=eq.external[::-1].copy())
