"""Two-body collisions: the coefficient of restitution of any contact law, by simulation.

A sphere a of diameter phi_a hits, head on at relative speed v, either a free sphere b at rest
or an immovable flat of material b (a wall). The collision is integrated with the engine's own
compiled Verlet and contact forces (:mod:`hertzchain.integrate.drivers.verlet`), so the restitution is
that of exactly the law a chain run uses, contact for contact: e = (v_b' - v_a') / v after the
bodies part (e = -v_a' / v on a flat). For Hertz e = 1; for Thornton's elastic-plastic law it
follows :func:`hertzchain.contact.thornton_restitution`; for the viscous laws it is what their
parameter gives at that size and speed (Kuwabara-Kono: 1 - e grows with A / t_c).
"""

from __future__ import annotations

import math

import numpy as np

from .contact import hertz_constant, yield_force
from .errors import ConfigError
from .materials import Material, get_material
from .laws import get_law, law_names, spec_of
from .plasticity import thornton_loading_overlap

__all__ = ["restitution", "contact_law"]

#: Johnson's contact time of a Hertz collision in units of delta_m / v (Contact Mechanics, 11.3).
_HERTZ_CONTACT_TIME = 2.943
#: Doublings of the simulated time allowed for the bodies to part.
_MAX_TRIES = 8


def contact_law(law):
    """A contact law object from a law object or a config name.

    Parameters
    ----------
    law : object or str
        A law (:class:`~hertzchain.Elastic`, :class:`~hertzchain.Elastoplastic`, ...) or the
        name of a registered law whose parameters all have defaults (``"elastic"``, ``"elastoplastic"``).

    Returns
    -------
    object
        The law.

    Raises
    ------
    ConfigError
        (field ``law``) an unknown name, or a law that needs a parameter given by name.
    """
    if isinstance(law, str):
        try:
            spec = get_law(law)
        except ConfigError:
            raise ConfigError("law", f"unknown contact law {law!r}; registered: {', '.join(law_names())} "
                              "(or a law object)") from None
        if any(p.default is None and not p.optional for p in spec.params):
            raise ConfigError("law", f"the {law!r} law needs its parameters ({', '.join(spec.param_names)}): give a "
                              "law object, e.g. hertzchain.Viscoelastic(A=4.5e-6) or hertzchain.HuntCrossley(0.9)")
        return spec.make({p: None for p in spec.param_names})
    try:
        spec_of(law)
    except ConfigError:
        raise ConfigError("law", f"must be a registered contact law or its name, got {type(law).__name__}") from None
    return law


def _positive(name: str, value) -> float:
    if not (isinstance(value, (int, float, np.floating)) and math.isfinite(value) and value > 0):
        raise ConfigError(name, f"must be a positive finite number, got {value!r}")
    return float(value)


def _two_body_system(velocity: float, law, diameter_a: float, mat_a: Material, diameter_b: float | None,
                     mat_b: Material):
    """The engine's arrays of sphere a (body 0) hitting sphere b at rest (body 1, no wall) or a
    flat (the wall ghost: N = 0 beads), and the pair's reduced mass [kg]."""
    from .model import System

    ra = diameter_a / 2
    rb = None if diameter_b is None else diameter_b / 2
    ma = mat_a.density * math.pi * diameter_a**3 / 6.0
    kappa = hertz_constant(ra, rb, mat_a, mat_b)
    f_y = yield_force(ra, rb, mat_a, mat_b)[0]
    if diameter_b is None:
        mass = np.array([ma, np.inf])
        mu = ma
    else:
        mb = mat_b.density * math.pi * diameter_b**3 / 6.0
        mass = np.array([ma, mb, np.inf])
        mu = ma * mb / (ma + mb)
    n = mass.size - 1  # contact slots: N + 1
    kap = np.zeros(n)
    kap[0] = kappa
    if hasattr(law, "contact_stiffness"):  # a law's own k (the power law's stiffness)
        kap = law.contact_stiffness(kap)
    fy = np.full(n, np.inf)
    fy[0] = f_y
    if hasattr(law, "contact_damping"):
        damping = law.contact_damping(np.array([mu] * n), kap)
    else:
        damping = np.where(kap > 0, float(law.parameter), 0.0)
    inv_mass = np.where(np.isfinite(mass), 1.0 / mass, 0.0)
    v0 = np.zeros(mass.size)
    v0[0] = velocity
    zeros = np.zeros(n)
    rsum = np.zeros(n)
    rsum[0] = ra + (0.0 if rb is None else rb)
    system = System(mass=mass, inv_mass=inv_mass, kappa=kap, damping=damping, d0=zeros, de=zeros.copy(),
                    dx0=rsum.copy(), rsum=rsum, fext=np.zeros(mass.size), u0=np.zeros(mass.size), v0=v0,
                    law=spec_of(law).code, misaligned=False, has_wall=diameter_b is None, yield_force=fy,
                    yield_pressure_ratio=getattr(law, "pressure_ratio", 1.0))
    return system, mu


def _engine(system):
    """``run_rkn`` where ``rkn4`` integrates the pair (engine_choice's rule for ``"auto"``), else
    ``run_verlet``; imported here, when a collision is run (no compiled module before)."""
    from .integrate.drivers.refusals import why_not

    if why_not("rkn4", system) is None:
        from .integrate.drivers.rkn import run_rkn

        return run_rkn
    from .integrate.drivers.verlet import run_verlet

    return run_verlet


#: Time steps the collision may take, all tries together (~10 s of the compiled Verlet, which
#: measured 34 s for a dashpot of 1e5 N s/m on an 8 mm sphere: 8e8 steps at worst).
_MAX_STEPS = 1e8


def _check_steps(system, duration: float, law, mu: float) -> None:
    """Refuse, before the run, a collision whose adaptive step makes it take more than
    :data:`_MAX_STEPS` steps over all tries (a dashpot so strong that its damping time mu/gamma
    is a tiny fraction of the contact time: the step resolves it), naming ``law``."""
    from .integrate.drivers.verlet import step_plan

    dt = step_plan(system, duration / 8, None, None).dt
    steps = duration / dt * (2**_MAX_TRIES - 1)  # every try doubles the time: the worst case
    if steps > _MAX_STEPS:
        damping = float(system.damping[0])
        raise ConfigError("law", f"{type(law).__name__} makes this collision take up to {steps:.3g} time steps of "
                          f"{dt:.3g} s (more than {_MAX_STEPS:.0e}): its damping time mu/gamma = "
                          f"{mu / damping if damping > 0 else math.inf:.3g} s is a tiny fraction of the contact time "
                          f"({duration / 2:.3g} s), an overdamped contact whose restitution is ~0; give a weaker "
                          "damping")


def restitution(velocity: float, law, diameter_a: float, material_a: str | Material,
                diameter_b: float | None = None, material_b: str | Material | None = None) -> float:
    """Coefficient of restitution of a head-on two-body collision, simulated with ``law``.

    Sphere a (diameter ``diameter_a``, ``material_a``) hits at relative speed ``velocity`` either
    sphere b (``diameter_b``, ``material_b``) at rest, or, with ``diameter_b=None``, an immovable
    flat of ``material_b`` (a sphere-on-flat Hertz contact, 1/R' = 0 in paper eq. 1). The
    collision is integrated until the bodies have parted, with the engine ``integrator = "auto"``
    picks for the law (the fourth-order ``rkn4``, for every law: the kernels a chain of that law
    runs on, so that nothing else compiles); e = (v_b' - v_a') / v (sphere) or -v_a' / v (flat).

    Parameters
    ----------
    velocity : float
        Relative impact speed [m/s] (> 0).
    law : object or str
        Contact law object (:class:`~hertzchain.Elastic`, :class:`~hertzchain.Elastoplastic`,
        :class:`~hertzchain.Viscoelastic`, :class:`~hertzchain.ScaledViscoelastic`,
        :class:`~hertzchain.Dashpot`, :class:`~hertzchain.PowerLaw`, :class:`~hertzchain.HuntCrossley`,
        a registered user law) or the name ``"elastic"`` or ``"elastoplastic"``.
    diameter_a : float
        Diameter of sphere a [m].
    material_a : str or Material
        Material of sphere a (catalogue name or :class:`~hertzchain.Material`).
    diameter_b : float or None
        Diameter of sphere b [m]; None: a flat.
    material_b : str or Material or None
        Material of sphere b or of the flat (default: ``material_a``).

    Returns
    -------
    float
        e [-]: 1 for an elastic collision; 0 when the bodies stay together.

    Raises
    ------
    ConfigError
        A bad input, naming it (``velocity``, ``diameter_a``, ``diameter_b``, ``law``, ``material``).

    Examples
    --------
    >>> import hertzchain as hc
    >>> round(hc.restitution(0.2, "elastic", 8e-3, "AISI52100", 26e-3), 6)
    1.0
    """
    v = _positive("velocity", velocity)
    da = _positive("diameter_a", diameter_a)
    db = None if diameter_b is None else _positive("diameter_b", diameter_b)
    mat_a = get_material(material_a)
    mat_b = mat_a if material_b is None else get_material(material_b)
    law = contact_law(law)
    system, mu = _two_body_system(v, law, da, mat_a, db, mat_b)
    kappa = float(hertz_constant(da / 2, None if db is None else db / 2, mat_a, mat_b))
    # First guess of the time the bodies stay together: Hertz's t_c = 2.943 delta_m / v, or the
    # half period of the unloading stiffness at the deepest overlap Thornton's loading reaches.
    energy = 0.5 * mu * v * v
    dm = (2.5 * energy / kappa) ** 0.4
    dmax = thornton_loading_overlap(energy, kappa, float(system.yield_overlap()[0]))
    duration = 2.0 * max(_HERTZ_CONTACT_TIME * dm / v, math.pi * math.sqrt(mu / (1.5 * kappa * math.sqrt(dmax))))
    _check_steps(system, duration, law, mu)
    run = _engine(system)
    for _ in range(_MAX_TRIES):
        raw = run(system, duration, duration / 8, record_velocities=True, record_positions=True)
        assert raw.displacement is not None and raw.velocity is not None  # (recorded: asked for above)
        u, vel = raw.displacement[-1], raw.velocity[-1]
        if db is None:
            gap, rel = -u[0], -vel[0]
        else:
            gap, rel = u[1] - u[0], vel[1] - vel[0]
        if gap > 0 and rel >= 0:  # parted, and moving apart (a free pair never meets again)
            return float(rel / v)
        duration *= 2.0
    return float(max(rel, 0.0) / v)
