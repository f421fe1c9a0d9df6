"""The engine: compiled integrators of one chain and of many, and their derivatives.

Subpackages by role; each imports only the ones listed after it (``pyproject.toml``'s layer
contract "engine", checked by ``tests/test_architecture.py``):

``derivatives`` and ``cuda``
    The taped primal run, the tangent-linear and adjoint models (``derivatives``); the GPU engine of
    a packed batch (``cuda``: device choice, kernels, lanes, launcher).
``batch``
    Many members as arrays (``ensemble``, ``ragged``, ``systems``: ``Model.system()`` vectorised),
    their packing (``pack``, ``buffers``) and the CPU batched engine (``engine``).
``drivers``
    One chain: velocity Verlet (``verlet``), the fourth-order ``"rkn4"`` (``rkn`` and
    ``rkn_kernels``; ``rkn_damped`` and ``rkn_damped_kernels`` for the dissipative laws and offsets),
    threads on long chains (``threaded``, ``threaded_laws``), the 2D path (``lateral``), scipy's
    DOP853 (``reference``) and which integrator takes which model (``refusals``).
``core``
    The compiled pieces every engine shares: the contact-law codes and peak tracking
    (``primitives``), forces and Verlet steps (``kernels``, ``fused``), energies, the protected body
    and mass-in-mass beads (``extension``), a System packed into padded arrays (``layout``), the
    thread barrier and the loops generated from a registry law (``generated``).

The public runs built on it (``simulate``, ``simulate_batch``, the lateral run) are
:mod:`hertzchain.runs`.
"""
