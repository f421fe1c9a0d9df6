"""Exact derivatives of the set-up map, run config -> System arrays (:meth:`hertzchain.Model.system`).

The map is re-written here in a form that accepts complex numbers, so that every derivative is
taken by the complex step: f'(x) = Im f(x + i h) / h with h = 1e-30, exact to rounding (no
subtraction, so no step-size error; Squire & Trapp, SIAM Rev. 40 (1998) 110). Every number of the
config is read through one function that adds the step to the field being differentiated: a
variable is a config field, addressed by its dotted path, with exactly the config's meaning
(a list item that a substitution overrides, or that a truncation drops, has derivative zero).
The real part is checked against ``Model.system()`` of the same config at every use, so a change
of the set-up that this module does not know of is refused instead of differentiated wrongly.

Fields (units: the config's own, so ``diameters_mm`` is per mm):

- ``chain.diameters_mm[i]``, ``chain.uniform.diameter_mm``, ``chain.taper.q``,
  ``chain.substitutions[i].diameter_mm``, ``chain.offsets_mm[i]``, ``chain.offsets_fraction[i]``,
  ``chain.precompression``;
- ``striker.diameter_mm``, ``striker.velocity``, and ``striker.mass`` [kg] (the striker's mass at
  fixed size: not a config field yet); a flat face (``striker.shape = "flat"``, 1/R' = 0) or a
  curved one (``striker.radius_of_curvature_mm``, a field of its own);
- ``contact.A``, ``contact.gamma`` (constant or size-scaled laws); the elastic-plastic law's
  ``contact.A`` and ``contact.limiting_pressure_factor`` (its yield overlaps scale as its square);
  a registry law's own parameters (``contact.exponent``, ``contact.stiffness``,
  ``contact.restitution``; a user's law's ``contact.parameters.NAME``), through its object's
  ``parameter`` and ``contact_stiffness`` (:func:`_registry_law`);
- a protected body (``[wall] type = "body"``): ``wall.mass`` [kg], ``wall.stiffness`` [N/m] and
  ``wall.damping`` [N s/m] of its mount, and a spherical face's ``wall.radius_of_curvature_mm``;
- ``materials.NAME.density``, ``.young``, ``.poisson``, ``.yield_stress`` for a material of the
  config's ``[materials]`` or of the catalogue (``materials.AISI52100.young``): every body made
  of it, the wall cap included;
- a mass-in-mass element's ``elements.NAME.resonator.mass_fraction`` and ``.frequency`` [Hz]:
  every bead of that element (:func:`~hertzchain.gradients.faces.element_resonators`).

For a config whose chain is not a list (``preset``, ``uniform``, ``taper``), ``chain.diameters_mm[i]``
(and ``chain.offsets_mm[i]``) address bead i + 1 of the chain as built.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..config.build import chain_gravity
from ..errors import ConfigError
from ..laws import get_law
from .faces import element_contacts, element_masses, element_resonators

__all__ = ["SetupDerivatives", "setup_derivatives", "ARRAYS", "expand_paths"]

#: System arrays the set-up gives derivatives of (the engines' parameters, plus the masses and
#: the elastic limits the results may read directly), the beads' diameters and offsets [m], and
#: a protected body's mount (spring [N/m], dashpot [N s/m], deflection at rest [m]; (1,) each).
ARRAYS = ("kappa", "damping", "d0", "de", "dx0", "rsum", "fext", "inv_mass", "v0", "mass", "yield_force",
          "diameter", "offset", "mount_k", "mount_c", "mount_d0", "dyield", "res_k", "res_inv_mass")
#: The complex step (any h far below the value's own scale works: no subtraction is made).
STEP = 1e-30

_MATERIAL_FIELDS = ("density", "young", "poisson", "yield_stress")
_SCALAR_FIELDS = ("chain.uniform.diameter_mm", "chain.taper.q", "chain.precompression", "striker.diameter_mm",
                  "striker.velocity", "striker.mass", "striker.radius_of_curvature_mm", "contact.A", "contact.gamma",
                  "contact.limiting_pressure_factor",
                  "wall.mass", "wall.stiffness", "wall.damping", "wall.radius_of_curvature_mm")
_LISTS = ("chain.diameters_mm", "chain.offsets_mm", "chain.offsets_fraction")
#: What a variable may look like (the refusal of a malformed path says it).
_PATH_GRAMMAR = ("dotted names with whole-number indices, as in the config and --set: chain.diameters_mm[3], "
                 "chain.diameters_mm[16:30] (a range), chain.diameters_mm (every bead), striker.velocity, "
                 "materials.AISI52100.young")


class _Reader:
    """Every config number goes through :meth:`__call__` (a scalar) or :meth:`items` (a list): the
    value comes back with one row per row of the plan, and the complex step added in the row(s) of
    the variable that is this field. Remembers which fields the config has.

    ``rows`` maps each variable path to its row; several list items may share a row (their
    derivatives are told apart afterwards, :func:`setup_derivatives`)."""

    def __init__(self, rows: dict[str, int]):
        self.index = rows
        self.rows = max(max(rows.values(), default=-1) + 1, 1)
        self.item_rows: dict[str, list[tuple[int, int]]] = {}  # list prefix: (item, row)
        for path, i in rows.items():
            head, _, rest = path.partition("[")
            if rest.endswith("]") and rest[:-1].isdigit():
                self.item_rows.setdefault(head, []).append((int(rest[:-1]), i))
        self.seen: set[str] = set()
        self.lists: dict[str, int] = {}

    def __call__(self, path: str, value: float) -> np.ndarray:
        """(rows, 1) complex column: ``value``, plus i h in the row of ``path``."""
        self.seen.add(path)
        out = np.full((self.rows, 1), complex(value))
        i = self.index.get(path)
        if i is not None:
            out[i, 0] += 1j * STEP
        return out

    def items(self, prefix: str, values) -> np.ndarray:
        """(rows, n) complex: list ``prefix`` of the config, plus i h at item k in the row of ``prefix[k]``."""
        vals = np.asarray(values, dtype=complex)
        self.lists[prefix] = vals.size
        out = np.tile(vals, (self.rows, 1))
        pairs = np.array([(k, i) for k, i in self.item_rows.get(prefix, ()) if k < vals.size], dtype=np.int64)
        if pairs.size:
            out[pairs[:, 1], pairs[:, 0]] += 1j * STEP
        return out

    def known(self, path: str) -> bool:
        """Whether ``path`` is a field this config's set-up reads."""
        if path in self.seen:
            return True
        head, _, rest = path.partition("[")
        return bool(rest) and rest[:-1].isdigit() and int(rest[:-1]) < self.lists.get(head, 0)


def _material(name: str):
    from ..materials import get_material

    return get_material(name)


def _theta(mat, read: _Reader) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(compliance theta [1/Pa], density [kg/m^3], yield stress [Pa] or NaN) of a material, (rows, 1) each."""
    key = f"materials.{mat.name}."
    young = read(key + "young", mat.young)
    nu = read(key + "poisson", mat.poisson)
    rho = read(key + "density", mat.density)
    sy = read(key + "yield_stress", mat.yield_stress) if mat.yield_stress is not None else \
        np.full((read.rows, 1), complex(np.nan))
    return 3.0 * (1.0 - nu * nu) / (4.0 * young), rho, sy


def _diameters(cfg, read: _Reader) -> tuple[np.ndarray, list[str], np.ndarray]:
    """Bead diameters and offsets [m] (rows, N) and material names, as config.build._chain."""
    from ..chain import TABLE_I_MM

    c = cfg.chain
    listed = c.diameters_mm is not None
    if c.preset is not None:
        d = np.tile(np.array(TABLE_I_MM[c.preset], dtype=complex) * 1e-3, (read.rows, 1))
    elif c.uniform is not None:
        d = read("chain.uniform.diameter_mm", c.uniform.diameter_mm) * 1e-3 * np.ones(c.uniform.n)
    else:
        d = read.items("chain.diameters_mm", c.diameters_mm) * 1e-3
    if c.taper is not None:
        q = read("chain.taper.q", c.taper.q)
        d = np.concatenate([d, d[:, -1:] * (1.0 - q) ** np.arange(1, c.taper.n + 1)], axis=1)
    mats = [c.material] * d.shape[1]
    if c.truncate is not None:
        d, mats = d[:, :c.truncate], mats[:c.truncate]
    if c.materials is not None:
        mats = list(c.materials)
    for i, sub in enumerate(c.substitutions):
        if sub.diameter_mm is not None:
            d[:, sub.bead - 1] = read(f"chain.substitutions[{i}].diameter_mm", sub.diameter_mm)[:, 0] * 1e-3
        if sub.material is not None:
            mats[sub.bead - 1] = sub.material
    n = d.shape[1]
    if not listed:  # bead i + 1 as built, addressed as a list item
        d = d + read.items("chain.diameters_mm", np.zeros(n)) * 1e-3
    if c.offsets_mm is not None:
        offsets = read.items("chain.offsets_mm", c.offsets_mm) * 1e-3
    elif c.offsets_fraction is not None:
        offsets = read.items("chain.offsets_fraction", c.offsets_fraction) * d
    else:
        offsets = read.items("chain.offsets_mm", np.zeros(n)) * 1e-3
    return d, [_material(m).name for m in mats], offsets


def _elements(cfg):
    """The beads' elements when any is not a plain sphere (None: a chain of spheres)."""
    if not cfg.chain.elements:
        return None
    from ..config import build_model

    elements = build_model(cfg).chain.elements
    return None if all(el.plain for el in elements) else elements


def _weaker(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """np.fmin of yield stresses (NaN: none given), keeping the complex part of the one chosen."""
    return np.where(np.isnan(a.real), b, np.where(np.isnan(b.real), a, np.where(a.real <= b.real, a, b)))


def _arrays(cfg, read: _Reader) -> dict[str, np.ndarray]:
    """The System arrays of ``cfg``, (rows, size) complex: the formulas of ``Model.system``."""
    d, mats, offsets = _diameters(cfg, read)
    n = d.shape[1]
    s = cfg.striker
    wall_curvature: Any = None  # no wall (else its face's curvature, below)
    names = [_material(s.material or mats[0]).name] + mats
    props = {name: _theta(_material(name), read) for name in dict.fromkeys(names)}
    theta, rho, sigma = (np.concatenate([props[m][k] for m in names], axis=1) for k in range(3))
    phi = np.concatenate([read("striker.diameter_mm", s.diameter_mm) * 1e-3, d], axis=1)
    mass = rho * math.pi * phi**3 / 6.0
    if s.mass is not None:  # a given striker mass (its size still sets its contact)
        mass[:, :1] = read("striker.mass", s.mass)
    else:
        mass[:, :1] = read("striker.mass", mass[0, 0].real) + 1j * mass[:, :1].imag
    elements = _elements(cfg)
    res_k = np.zeros((read.rows, n + 2), dtype=complex)  # mass-in-mass beads' internal springs
    res_inv_mass = np.zeros((read.rows, n + 2), dtype=complex)  # and inverse internal masses
    if elements is not None:  # a given mass, a cylinder's (gradients.faces)
        element_masses(elements, mass, rho, phi)
        element_resonators(elements, mass, res_k, res_inv_mass, read)
    r = phi / 2.0
    inv_r = 1.0 / r[:, :-1] + 1.0 / r[:, 1:]
    striker_curvature: Any = 1.0 / r[:, 0]  # the striker's face: its sphere, a flat or a curved face
    if s.shape == "flat":  # a flat face meets bead 1 sphere-on-flat: 1/R' = 0 (paper eq. 1)
        inv_r[:, :1] = 1.0 / r[:, 1:2]
        striker_curvature = 0.0 * r[:, 0]
    elif s.radius_of_curvature_mm is not None:  # a curved face of its own radius
        face = read("striker.radius_of_curvature_mm", s.radius_of_curvature_mm) * 1e-3
        inv_r[:, :1] = 1.0 / face + 1.0 / r[:, 1:2]
        striker_curvature = 1.0 / face[:, 0]
    t_sum = theta[:, :-1] + theta[:, 1:]
    s_min = _weaker(sigma[:, :-1], sigma[:, 1:])
    if cfg.wall.type != "none":
        wall = _material(cfg.wall.material or mats[-1]).name
        wt, _, ws = props[wall] if wall in props else _theta(_material(wall), read)
        # 1/R of the wall's face: a flat (the wall's cap, a body's flat face), or a body's spherical face
        wall_curvature = 0.0
        if cfg.wall.type == "body" and cfg.wall.shape == "sphere":
            wall_curvature = 1.0 / (read("wall.radius_of_curvature_mm", cfg.wall.radius_of_curvature_mm) * 1e-3)
        inv_r = np.concatenate([inv_r, 1.0 / r[:, -1:] + wall_curvature], axis=1)
        t_sum = np.concatenate([t_sum, theta[:, -1:] + wt], axis=1)
        s_min = np.concatenate([s_min, _weaker(sigma[:, -1:], ws)], axis=1)
    m = inv_r.shape[1]
    rows = read.rows
    kappa = np.zeros((rows, n + 1), dtype=complex)
    kappa[:, :m] = 1.0 / (t_sum * np.sqrt(inv_r))
    fy = np.full((rows, n + 1), np.inf, dtype=complex)
    with np.errstate(invalid="ignore"):
        # (pi sigma_Y)^3 (3 R* / (4 E*))^2, 3 R* / (4 E*) = R* (theta + theta')
        fy[:, :m] = np.where(np.isnan(s_min.real), np.inf, (math.pi * s_min) ** 3 * (t_sum / inv_r) ** 2)
    if elements is not None:  # the elliptical Hertz contacts of cylinders (gradients.faces)
        wall_face = None
        if wall_curvature is not None:  # a constant 0 (flat) or the body's face, (rows, 1)
            wc = np.asarray(wall_curvature, dtype=complex)
            wall_face = (wc[:, 0] if wc.ndim == 2 else wc + 0j * r[:, 0],) * 2
        element_contacts(elements, n, phi, (striker_curvature, striker_curvature), wall_face, t_sum, s_min, kappa,
                         fy)
    inv_mass = np.zeros((rows, n + 2), dtype=complex)
    inv_mass[:, :n + 1] = 1.0 / mass
    w = cfg.wall
    body = w.type == "body"
    zero = np.zeros((rows, 1))
    body_mass = read("wall.mass", w.mass) if body else zero + np.inf
    if body:  # a protected body: body N + 1 moves, held by its mount (contact N + 1)
        inv_mass[:, n + 1:] = 1.0 / body_mass
    spec = get_law(cfg.contact.law)
    if spec.generated:  # a registry law's k and p (Model.system)
        kappa, damping = _registry_law(cfg, read, kappa, inv_mass)
    else:
        damping = _damping(cfg, read, kappa, inv_mass, d, mats)
    plastic = spec.plastic
    ratio = read("contact.limiting_pressure_factor", cfg.contact.limiting_pressure_factor or 1.5) / 1.5 if plastic \
        else np.ones((rows, 1))
    ok = (kappa.real > 0) & np.isfinite(fy.real)
    with np.errstate(invalid="ignore", divide="ignore"):
        dyield = np.where(ok, (fy / np.where(ok, kappa, 1.0)) ** (2.0 / 3.0) * ratio**2, np.inf)
    d0 = np.zeros((rows, n + 1), dtype=complex)
    fext = np.zeros((rows, n + 2), dtype=complex)
    f0 = read("chain.precompression", cfg.chain.precompression)
    mount_k = read("wall.stiffness", w.stiffness) if body else zero
    mount_c = read("wall.damping", w.damping) if body else zero
    mount_d0 = zero.astype(complex)
    # The static state (Model.system, bodies.extend): weights along the chain (gravity, a constant
    # of the config), the precompression push on bead 1 and the loads; contact j holds bodies 0..j
    g = chain_gravity(cfg.chain)
    if g > 0:
        fext[:, :n + 1] = mass * g  # the striker rests on bead 1
        if body:
            fext[:, n + 1:] = body_mass * g
    fext[:, 1:2] += f0
    for bead, force in zip(*((cfg.load.beads, cfg.load.forces) if cfg.load is not None else ((), ()))):
        fext[:, bead] += force
    held = np.cumsum(fext, axis=1)
    if spec.generated:
        d0 = _static_overlaps(spec, held[:, :n + 1], kappa, damping)
    else:
        loaded = (held[0, :n + 1].real > 0) & (kappa[0].real > 0)
        with np.errstate(invalid="ignore", divide="ignore"):
            d0 = np.where(loaded, (held[:, :n + 1] / np.where(loaded, kappa, 1.0)) ** (2.0 / 3.0), 0.0)
            if plastic:  # statically loaded along Thornton's loading curve past its F_y (Model.system)
                f_y = fy * ratio**3
                dy = (f_y / np.where(loaded, kappa, 1.0)) ** (2.0 / 3.0)
                line = dy + (held[:, :n + 1] - f_y) / (1.5 * kappa * np.sqrt(dy))
                d0 = np.where(loaded & (held[0, :n + 1].real > f_y[0].real), line, d0)
    if body and held[0, n + 1].real > 0:  # the mount carries the static load (bodies.extend)
        mount_d0 = held[:, n + 1:] / mount_k
    de = np.diff(np.concatenate([zero, offsets, zero], axis=1), axis=1)
    de[:, n] = 0.0
    rr = np.concatenate([r, zero], axis=1)
    rsum = rr[:, :-1] + rr[:, 1:]
    dx0 = np.sqrt(rsum**2 - de**2)
    v0 = np.zeros((rows, n + 2), dtype=complex)
    v0[:, :1] = read("striker.velocity", s.velocity)
    return {"kappa": kappa, "damping": damping, "d0": d0, "de": de, "dx0": dx0, "rsum": rsum, "fext": fext,
            "inv_mass": inv_mass, "v0": v0, "mass": np.concatenate([mass, body_mass], axis=1),
            "yield_force": fy, "diameter": d, "offset": offsets, "mount_k": mount_k + 0j, "mount_c": mount_c + 0j,
            "mount_d0": mount_d0, "dyield": dyield, "res_k": res_k, "res_inv_mass": res_inv_mass}


def _registry_law(cfg, read: _Reader, kappa, inv_mass) -> tuple[np.ndarray, np.ndarray]:
    """(kappa, damping) of a law run by the generated engines, (rows, P) complex: its stiffness k
    and parameter p where there is a contact, as ``Model.system`` takes them from the law object
    (``parameter``, ``contact_stiffness``, ``contact_damping``). The object is evaluated with its
    parameters read through ``read`` (complex): a shadow of the law the config builds, its
    declared parameters replaced. A law whose methods do not take complex numbers is refused."""
    from ..config import build_model

    spec = get_law(cfg.contact.law)
    law = build_model(cfg).law
    shadow = object.__new__(type(law))
    shadow.__dict__.update(vars(law))
    own = set(type(cfg.contact).model_fields)
    for name in cfg.contact.law_parameters():
        if getattr(law, name, None) is not None:
            path = f"contact.{name}" if name in own else f"contact.parameters.{name}"
            object.__setattr__(shadow, name, read(path, getattr(law, name)))
    on = kappa[0].real > 0
    try:
        with np.errstate(invalid="ignore", divide="ignore"):
            damping = np.where(on, shadow.parameter, 0.0) + 0j
            if hasattr(shadow, "contact_stiffness"):
                kappa = np.asarray(shadow.contact_stiffness(kappa), dtype=complex)
            if hasattr(shadow, "contact_damping"):
                nc = kappa.shape[1]
                mu = 1.0 / (inv_mass[:, :nc] + inv_mass[:, 1:nc + 1])
                damping = np.asarray(shadow.contact_damping(mu, kappa), dtype=complex)
    except (TypeError, ValueError, AttributeError) as exc:
        raise ConfigError("contact.law", f"gradients evaluate law {spec.name!r}'s parameter and stiffness with complex "
                          f"numbers (the complex step), which its methods refuse ({exc}); write them with NumPy "
                          "arithmetic (docs/guide/laws.rst)") from None
    return np.broadcast_to(kappa, (read.rows, kappa.shape[1])).copy(), \
        np.broadcast_to(damping, (read.rows, kappa.shape[1])).copy()


def _static_overlaps(spec, held, kappa, damping) -> np.ndarray:
    """A registry law's overlap under the static forces ``held`` (rows, n) at every contact (rows, n)
    complex: the real part by root finding (``laws.solve.static_overlap``, as ``Model.system``),
    the complex step's part by the implicit function theorem on F(delta, 0, k, p) = S:
    delta' = (S' - dF/dk k' - dF/dp p') / (dF/d delta), with the law's declared partials."""
    from ..laws.solve import static_overlap

    out = np.zeros(kappa.shape, dtype=complex)
    for j in range(kappa.shape[1]):
        k, p, f = kappa[0, j].real, damping[0, j].real, held[0, j].real
        if not (k > 0 and f > 0):
            continue
        d = static_overlap(spec, f, k, p)
        fd, _, fk, fp = spec.partials(d, 0.0, k, p, 0.0)
        out[:, j] = d + 1j * (held[:, j].imag - fk * kappa[:, j].imag - fp * damping[:, j].imag) / fd
    return out


def _damping(cfg, read: _Reader, kappa, inv_mass, d, mats) -> np.ndarray:
    """Per-contact law parameter (Model.system): A or gamma where kappa > 0; A_j of the size-scaled law."""
    from ..contact import collision_time_scale

    k = cfg.contact
    spec = get_law(k.law)
    on = kappa[0].real > 0
    if not spec.dissipative:
        return np.zeros(kappa.shape, dtype=complex)
    if spec.plastic:  # a constant A (config.build: no size scaling)
        return np.where(on, read("contact.A", k.A or 0.0), 0.0)
    if k.eps is not None:
        raise ConfigError("contact.eps", "gradients need the law's own parameter: the calibration that turns eps into "
                          f"{spec.calibrated} is a simulation of its own; run the config once "
                          "and write the calibrated value (the result's 'model' attribute holds it) in its place")
    scaled = spec.extra.get("scaled", False)
    if spec.calibrated == "gamma" and not scaled:
        return np.where(on, read("contact.gamma", k.gamma), 0.0)
    if spec.calibrated == "A":
        a = read("contact.A", k.A)
        if not scaled:
            return np.where(on, a, 0.0)
    else:
        a = read("contact.gamma", k.gamma)
    # size-scaled laws: the reference is two beads like bead 1 (the laws' reference(): contact._ReferencePair)
    nc = kappa.shape[1]
    mu = 1.0 / (inv_mass[:, :nc] + inv_mass[:, 1:nc + 1])
    theta, rho, _ = _theta(_material(mats[0]), read)
    d1 = d[:, :1]
    k_ref = 1.0 / (2.0 * theta * np.sqrt(4.0 / d1))
    mu_ref = 0.5 * rho * math.pi * d1**3 / 6.0
    safe = np.where(on, kappa, 1.0)
    if spec.calibrated == "A":  # A_j = A (t_j / t_ref)^p, t = (mu / kappa)^(2/5), p declared with the law
        ratio = collision_time_scale(mu, safe) / collision_time_scale(mu_ref, k_ref)
        return np.where(on, a * ratio ** spec.extra.get("size_exponent", 1.0), 0.0)
    # dashpot_scaled: gamma_j = gamma (kappa_j / kappa_ref)^(2/5) (mu_j / mu_ref)^(3/5)
    return np.where(on, a * (safe / k_ref) ** 0.4 * (mu / mu_ref) ** 0.6, 0.0)


def expand_paths(cfg, variables) -> list[str]:
    """Variable paths with list ranges written out: ``chain.diameters_mm`` (every bead) and
    ``chain.diameters_mm[a:b]`` become one path per item; material names are written as the
    catalogue spells them (``materials.steel.young`` -> ``materials.AISI52100.young``).

    Parameters
    ----------
    cfg : RunConfig
        The validated config.
    variables : str or sequence of str
        Dotted paths.

    Returns
    -------
    list of str
        One path per derivative, in order, without repeats.
    """
    import re

    from ..config import build_chain, parse_path

    if isinstance(variables, str):
        variables = [variables]
    if not variables:
        raise ConfigError("variables", "name at least one config field to differentiate by, e.g. 'striker.velocity'")
    n_beads = build_chain(cfg).n_beads
    out: list[str] = []
    for raw in variables:
        if not isinstance(raw, str):
            raise ConfigError("variables", f"each variable is a dotted path (a string), got {raw!r}")
        path = raw.strip()
        m = re.fullmatch(r"(chain\.\w+)\[(\d+):(\d+)\]", path)  # a range of a list field
        if m and m.group(1) in _LISTS:
            lo, hi = int(m.group(2)), int(m.group(3))
            if not 0 <= lo < hi <= n_beads:
                raise ConfigError(raw, f"range [{lo}:{hi}] must lie inside the chain's beads [0:{n_beads}]")
            out += [f"{m.group(1)}[{i}]" for i in range(lo, hi)]
            continue
        try:  # the grammar of the config's own paths (--set, sweeps, design variables)
            tokens = parse_path(path)
        except ValueError:
            raise ConfigError("variables", f"{raw!r} is not a config path: {_PATH_GRAMMAR}") from None
        path = "".join(f"[{t}]" if isinstance(t, int) else ("." if i else "") + t for i, t in enumerate(tokens))
        if path in _LISTS:  # a list field without an index: every bead
            out += [f"{path}[{i}]" for i in range(n_beads)]
            continue
        m = re.fullmatch(r"materials\.([^.]+)\.(\w+)", path)
        if m:
            try:
                name = _material(m.group(1)).name
            except ConfigError:
                raise ConfigError(raw, f"names no material of the config or the catalogue ({m.group(1)!r})") from None
            if m.group(2) not in _MATERIAL_FIELDS:
                raise ConfigError(raw, f"a material's differentiable constants are {', '.join(_MATERIAL_FIELDS)}")
            path = f"materials.{name}.{m.group(2)}"
        out.append(path)
    return list(dict.fromkeys(out))


@dataclass
class SetupDerivatives:
    """The System arrays of a config and their derivatives by each variable, stored sparse.

    Attributes
    ----------
    values : dict
        ``{array name: real array}`` (:data:`ARRAYS`), as ``Model.system()`` gives them.
    derivatives : dict
        ``{variable path: {array name: (indices, values)}}``: the nonzero entries of
        d array / d variable, per the variable's config unit. A bead's diameter moves a few
        entries (its mass, its two contacts): the memory is linear in beads and variables.
    """

    values: dict[str, np.ndarray]
    derivatives: dict[str, dict[str, tuple[np.ndarray, np.ndarray]]]

    def dense(self, path: str, name: str) -> np.ndarray:
        """d array ``name`` / d variable ``path`` as a full array, shaped like the System's.

        Parameters
        ----------
        path, name : str
            A variable and an array name of :data:`ARRAYS`.

        Returns
        -------
        numpy.ndarray
            The derivative (zeros where the variable does not move the array).
        """
        out = np.zeros(self.values[name].size)
        idx, val = self.derivatives[path].get(name, _EMPTY)
        out[idx] = val
        return out

    def dot(self, path: str, grads: dict[str, np.ndarray]) -> float:
        """Chain rule for one variable: sum over arrays of (dJ/d array) . (d array / d ``path``).

        Parameters
        ----------
        path : str
            The variable.
        grads : dict
            ``{array name: dJ/d array}`` (an array shorter than the System's covers its first entries).

        Returns
        -------
        float
            dJ/d variable.
        """
        total = 0.0
        for name, g in grads.items():
            idx, val = self.derivatives[path].get(name, _EMPTY)
            keep = idx < g.size
            total += float(np.dot(g[idx[keep]], val[keep]))
        return total

    @property
    def nbytes(self) -> int:
        """Memory of the stored derivatives [bytes]."""
        return sum(i.nbytes + v.nbytes for d in self.derivatives.values() for i, v in d.values())


_EMPTY = (np.zeros(0, dtype=np.int64), np.zeros(0))


def _supported(path: str) -> str:
    return ("gradients know the continuous fields " + ", ".join(_SCALAR_FIELDS) + ", chain.diameters_mm[i], "
            "chain.offsets_mm[i], chain.offsets_fraction[i], chain.substitutions[i].diameter_mm, "
            "materials.NAME.{density,young,poisson,yield_stress} and a registry law's parameters given in the "
            "config (contact.exponent, contact.stiffness, contact.restitution, contact.parameters.NAME), and a "
            "mass-in-mass element's elements.NAME.resonator.{mass_fraction,frequency}")
#: List items that share a row of the complex step are COLOURS apart: a bead's diameter or offset
#: moves the entries of its own bead, body and two contacts only (indices i .. i + 1 for item i),
#: so an entry e of a shared row belongs to the one item of its colour within e - 2 .. e + 2
#: (Curtis, Powell & Reid, J. Inst. Math. Appl. 13 (1974) 117: a sparse Jacobian's columns
#: compressed by colouring). The rows: one per scalar variable, COLOURS per list, and one per
#: item whose influence is not local (:func:`_own_rows`; every diameter under gravity).
COLOURS = 5


def _own_rows(cfg) -> set[str]:
    """List items that move entries far from their own bead, and so get a row of their own: bead
    1's diameter (the reference pair of the size-scaled laws sets every contact's damping) and,
    for a listed chain extended by a taper, the last listed bead (every tapered bead scales with it)."""
    own = {"chain.diameters_mm[0]"}
    c = cfg.chain
    if c.taper is not None and c.diameters_mm is not None:
        own.add(f"chain.diameters_mm[{len(c.diameters_mm) - 1}]")
    return own


def _plan(cfg, paths: list[str]) -> tuple[dict[str, int], dict[int, np.ndarray]]:
    """Rows of the complex step: {path: row}, and for every shared row the items it holds (a
    boolean mask over item numbers); a row of its own is absent from the second."""
    own = _own_rows(cfg)
    # under gravity a bead's size sets its weight, which every contact between it and the wall holds:
    # its diameter moves the static overlaps of all of them (rows of their own, N^2 memory)
    heavy = chain_gravity(cfg.chain) > 0
    rows: dict[str, int] = {}
    # number rows: scalars and own items first, then one row per (list, colour)
    n = 0
    groups: dict[tuple[str, int], list[tuple[str, int]]] = {}
    for path in paths:
        head, _, rest = path.partition("[")
        if head in _LISTS and rest.endswith("]") and rest[:-1].isdigit() and path not in own \
                and not (heavy and head == "chain.diameters_mm"):
            k = int(rest[:-1])
            groups.setdefault((head, k % COLOURS), []).append((path, k))
        else:
            rows[path] = n
            n += 1
    masks: dict[int, np.ndarray] = {}
    for members in groups.values():
        mask = np.zeros(max(k for _, k in members) + 1, dtype=bool)
        for path, k in members:
            rows[path] = n
            mask[k] = True
        masks[n] = mask
        n += 1
    return rows, masks


def setup_derivatives(cfg, system, paths: list[str]) -> SetupDerivatives:
    """Derivatives of the System arrays of ``cfg`` by every config field of ``paths`` (complex step).

    Memory and time are linear in the beads and the variables: a list's items share a few rows
    of the complex step (:data:`COLOURS`), and every derivative is stored by its nonzero entries.

    Parameters
    ----------
    cfg : RunConfig
        The validated config.
    system : System
        ``build_model(cfg).system()``: the real part is checked against it.
    paths : list of str
        Variables (:func:`expand_paths`).

    Returns
    -------
    SetupDerivatives
        Values and derivatives.

    Raises
    ------
    ConfigError
        A path that is no continuous field of this config (naming it and the fields known), or a
        set-up this module cannot reproduce.
    """
    rows, masks = _plan(cfg, paths)
    read = _Reader(rows)
    arrays = _arrays(cfg, read)
    values = {k: v[0].real.copy() for k, v in arrays.items()}
    _check_against(values, system)
    for path in paths:
        if not read.known(path):
            kind = "an integer (a discrete choice: no derivative)" if path.endswith((".n", "truncate", ".bead")) else \
                "not a continuous parameter of this config's model"
            raise ConfigError(path, f"is {kind}; {_supported(path)}")
    out: dict[str, dict[str, tuple[np.ndarray, np.ndarray]]] = {p: {} for p in paths}
    by_row: dict[int, list[str]] = {}
    for path, i in rows.items():
        by_row.setdefault(i, []).append(path)
    for name, arr in arrays.items():
        finite = np.isfinite(arr.real)
        d = np.where(finite, arr.imag, 0.0) / STEP
        for i, members in by_row.items():
            nz = np.flatnonzero(d[i])
            if i not in masks:
                if nz.size:
                    out[members[0]][name] = (nz, d[i, nz])
                continue
            _split(out, members, masks[i], nz, d[i, nz], name)
    return SetupDerivatives(values, out)


def _split(out: dict, members: list[str], mask: np.ndarray, nz: np.ndarray, val: np.ndarray, name: str) -> None:
    """Entries of a shared row to their items: entry e belongs to the item of the row's colour in
    e - 2 .. e + 2 (:data:`COLOURS`)."""
    head = members[0].partition("[")[0]
    colour = int(members[0].partition("[")[2][:-1]) % COLOURS
    owner = nz - 2 + (colour - (nz - 2)) % COLOURS
    ok = (owner >= 0) & (owner < mask.size)
    ok[ok] = mask[owner[ok]]
    if not np.all(ok):  # an influence that is not local: a set-up this module does not know
        raise ConfigError("config", f"gradients cannot tell apart the items of {head} in System.{name} (an item "
                          "moves entries far from its bead); the config uses a set-up the sensitivity engine does "
                          "not differentiate yet")
    order = np.argsort(owner, kind="stable")
    owner, nz, val = owner[order], nz[order], val[order]
    cuts = np.flatnonzero(np.diff(owner)) + 1
    for o, idx, v in zip(np.split(owner, cuts), np.split(nz, cuts), np.split(val, cuts)):
        if o.size:
            out[f"{head}[{int(o[0])}]"][name] = (idx, v)


def _resonators(system, name: str) -> np.ndarray:
    """The System's internal springs (``res_k``) or inverse internal masses (``res_inv_mass``: 1/res_m,
    0 where a body has none), zeros without mass-in-mass beads."""
    size = system.mass.size
    if system.res_k is None:
        return np.zeros(size)
    if name == "res_k":
        return np.asarray(system.res_k, dtype=float)
    m = np.asarray(system.res_m, dtype=float)
    return np.where(m > 0, 1.0 / np.where(m > 0, m, 1.0), 0.0)


def _check_against(values: dict[str, np.ndarray], system) -> None:
    """Refuse a config whose System this module does not reproduce (a set-up it does not know)."""
    for name in ("kappa", "damping", "d0", "de", "dx0", "rsum", "fext", "inv_mass", "v0", "mass", "yield_force",
                 "mount_k", "mount_c", "mount_d0", "dyield", "res_k", "res_inv_mass"):
        ref = system.yield_overlap() if name == "dyield" else _resonators(system, name) if name.startswith("res_") \
            else getattr(system, name, 0.0)
        ref = np.atleast_1d(np.asarray(ref, dtype=float))
        mine = values[name]
        if ref.shape != mine.shape or not np.allclose(mine, ref, rtol=1e-12, atol=0.0, equal_nan=True):
            raise ConfigError("config", f"gradients cannot reproduce this model's set-up (System.{name} differs); the "
                              "config uses a feature the sensitivity engine does not differentiate yet")
