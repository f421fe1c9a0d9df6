"""Integrators: the compiled velocity Verlet (default), the scipy DOP853 reference, and the
batched engines that run many chains at once.

One chain: ``kernels`` (compiled forces and Verlet steps), ``extension`` (a protected body's
mount and mass-in-mass beads, compiled), ``layout`` (a System packed into the kernels' padded
arrays), ``verlet`` (the driver: time step, chunks, probes), ``rkn`` with ``rkn_kernels`` (the
fourth-order integrator ``"rkn4"``) and ``rkn_damped`` with ``rkn_damped_kernels`` (its method for
the dissipative laws and offset beads), ``threaded`` with ``barrier`` (one long chain on several
threads), ``lateral`` (the 2D path), ``reference`` (scipy).

Many chains (``simulate_batch``), in the order a batch goes through them: ``batch`` (entry
points), ``ensemble`` / ``ragged`` / ``systems`` (members as arrays, ``Model.system()``
vectorised), ``batch_pack`` (set-up), ``batch_buffers`` (the packed batch both engines share),
``batch_engine`` (CPU) or ``cuda`` with ``cuda_kernels``, ``cuda_lanes`` and ``cuda_device`` (GPU),
``batch_results`` (RawRuns and stacked Datasets).
"""
