"""CUDA backend of the batched engine: a packed batch run on a GPU.

Written with ``numba.cuda`` (the ``gpu`` extra, ``pip install "hertzchain[gpu]"``), the same
Numba family as the CPU kernels, so it also runs on a CPU through Numba's CUDA simulator
(``NUMBA_ENABLE_CUDASIM=1``; that is how the tests check it without a GPU). Three modules:
:mod:`hertzchain.integrate.cuda.device` (the ``device`` choice: is a GPU usable),
:mod:`hertzchain.integrate.cuda.kernels` (the kernels) and this one, the launcher
(:func:`run_packed`: which kernel, the copies to and from the device, launches in chunks of
samples).

What it integrates is exactly what the CPU batch engine integrates (paper eq. 1 with the elastic,
viscoelastic, dashpot or elastic-plastic law, misaligned beads, precompression, a protected body
and mass-in-mass beads (the extension: :mod:`hertzchain.integrate.cuda.extension`); the adaptive
step of :func:`kernels.required_stride` or a fixed one; sampled probes, running maximum forces, the
wall peak tracker refined afterwards; the dissipated energy; the elastic-plastic contacts' state
and the extension's internal masses and body work, carried from launch to launch, the plastic work
and the protected body's record), in the same order of operations: one
member per thread for large batches, one warp per member (a lane per slot) below
``WARP_PER_MEMBER_BELOW`` members, where one thread per member would leave the GPU idle; and, for
aligned elastic chains of up to ``REGISTER_MAX_SLOTS`` slots, whatever the batch size, the register
kernel (``cuda_kernels._register_kernel``), which keeps a member's state on the chip. The numbers
agree with the CPU engine, not bit for bit: the GPU fuses multiplies and adds (FMA) and the CPU
reassociates its energy sums. Measured on an H100 (30 beads, 1.2 ms, ~60,000 steps): peak wall
forces within 1.4e-14 relative, sampled forces, velocities and energies within 3.3e-12, the
rounding differences of every step adding up (tests/test_cuda.py).

Layout: every per-slot array is (slot, member), so that the threads of a warp, which run
neighbouring members, read neighbouring addresses (coalesced). Inputs are the engine's packed batch
(:class:`hertzchain.integrate.batch.buffers._Packed`, built by the vectorised set-up) for members
that share a layout; outputs stay on the device for a whole launch (a chunk of samples) and are
copied into the packed batch's buffers after it.
"""

from __future__ import annotations

from typing import Callable

import numpy as np

from ...errors import ConfigError
from . import lanes as cuda_lanes
from ..batch.buffers import check_members_finite
# the device choice, importable from here as before
from .device import (AUTO_MIN_MEMBERS, DEVICES, _cuda, _simulated, check_device, gpu_usable,  # noqa: F401
                          require_gpu, use_gpu)
from .generated import generated_kernel
from .kernels import _kernels, _lanes, _register_kernel
from ..core.generated import is_generated
from ..core.extension import EXT_COLUMNS
from ..core.kernels import LAW_ELASTOPLASTIC

__all__ = ["ENGINE", "AUTO_MIN_MEMBERS", "DEVICES", "check_device", "gpu_usable", "use_gpu", "run_packed"]


#: The ``engine`` attribute of a batch computed on the GPU.
ENGINE = "batched velocity Verlet on the GPU (numba.cuda), one member per thread"
#: Threads per block of the thread-per-member kernel.
THREADS_PER_BLOCK = 128
#: Batches of fewer members run the general kernel with one warp per member: one thread per
#: member leaves most of a GPU idle there (H100, 30 beads: thread per member 1.5e9 bead-steps/s at
#: 1e3 members, 1.5e10 at 1e4; warp per member 7.8e9 and 9.6e9). They cross near 5,000 members;
#: benchmarks/ensemble.py times both kernels.
WARP_PER_MEMBER_BELOW = 5_000
#: Slot-steps (padded slots x steps, summed over members) per launch: ~0.1 s at 2e11 slot-steps/s,
#: short enough for progress reports and the display watchdog.
LAUNCH_SLOT_STEPS = 2e10
#: Device memory for the probes of one launch (its rows are copied to the host after it).
LAUNCH_OUTPUT_BYTES = 1 << 30
#: The register kernel (``cuda_kernels._register_kernel``) takes layouts of up to this many slots: its
#: positions and velocities live in registers (2 x 33 doubles at 32 slots); longer chains would
#: spill them to local memory, where the general kernel does as well.
REGISTER_MAX_SLOTS = 40
#: Whether aligned elastic batches take the register kernel (off: the general kernels, to compare).
USE_REGISTER_KERNEL = True
#: Whether aligned elastic batches on one shared fixed step take the lanes-per-chain kernel
#: (``cuda_lanes.lanes_kernel``). Off until measured on a GPU (benchmarks/gpu_kernels.py): it is
#: checked against the CPU engine through the simulator only.
USE_LANES_KERNEL = False
#: ... for layouts of up to this many slots (each lane keeps P / LANES positions in registers).
LANES_MAX_SLOTS = 64


def refuse_mixed_laws(laws) -> None:
    """ConfigError naming ``contact.law`` when ``laws`` (kernel law codes) mix a law the CPU
    engines generate from its declaration (``hertzchain.laws``) with other laws: the CUDA engine
    runs such a law with a kernel of its own, one per batch.

    Parameters
    ----------
    laws : array_like of int
        Law codes (``hertzchain.contact.LAW_CODES``) of the members.
    """
    codes = np.asarray(laws).ravel()
    generated = [is_generated(c) for c in codes]
    if any(generated) and (not all(generated) or np.unique(codes).size > 1):
        raise ConfigError("contact.law", "the CUDA engine runs one law declared in hertzchain.laws (power, "
                          "hunt_crossley, a user's) per batch, not mixed with other laws; split the batch or use "
                          "device = 'cpu'")


#: The elastic-plastic law's per-contact state in the packed batch's flat buffers (dmax, dres, kres
#: change during a run and are copied back after it, for the residual overlaps).
_PLASTIC_STATE = ("dyield", "dmax", "dres", "kres")
_SLOT_ARRAYS = ("mass", "inv_mass", "kappa", "damping", "d0", "de", "dx0", "rsum", "fext", "dcap")


def run_packed(pk, progress: Callable[[int, int], None] | None = None) -> None:
    """Run a packed batch (members of one layout) to the end on the GPU, results into ``pk``'s buffers.

    Parameters
    ----------
    pk:
        The engine's packed batch (``hertzchain.integrate.batch.buffers._Packed``) after set-up: every
        member with the same slot count, recorded contacts and velocity recording. Its output
        buffers, trackers and maximum forces receive the results, as the CPU engine leaves them.
    progress:
        ``progress(done, total)`` in samples, after each launch.

    Raises
    ------
    SimulationDiverged
        When a member's state became non-finite.
    ConfigError
        A law declared in ``hertzchain.laws`` mixed with other laws, or with a protected body or
        mass-in-mass beads (``contact.law``).
    """
    refuse_mixed_laws(pk.law)
    cuda = _cuda()
    nmem = pk.n_members
    p = int(pk.n_slots[0])
    generated = is_generated(int(pk.law[0]))  # a law run by the generated engines: its own kernel
    # a protected body or mass-in-mass beads: the general kernels' extended steps (cuda.extension)
    extended = pk.ext_on is not None and bool(np.any(pk.ext_on))
    width = int(pk.off[1])
    # aligned elastic members of a short chain: the register kernel (positions and velocities on
    # the chip), else one warp per member for small batches, one thread per member for large ones
    stride0 = int(pk.stride[0])
    lanes = (USE_LANES_KERNEL and not np.any(pk.general) and stride0 > 0 and np.all(pk.stride == stride0)
             and np.all(pk.n_sub == 1) and p % cuda_lanes.lanes() == 0 and p <= LANES_MAX_SLOTS)
    lanes = lanes and not generated and not extended
    register = (not lanes and not generated and not extended and USE_REGISTER_KERNEL and p <= REGISTER_MAX_SLOTS
                and not np.any(pk.general))
    warp = not (register or lanes) and nmem < WARP_PER_MEMBER_BELOW
    if lanes:
        pre = bool(np.any(pk.flat["d0"].reshape(nmem, width)[:, :p] != 0.0)
                   or np.any(pk.flat["fext"].reshape(nmem, width)[:, :p] != 0.0))
        kernel, tpb = cuda_lanes.lanes_kernel(p, cuda_lanes.lanes(), pre, cuda_lanes.chains_per_block())
    elif register:
        pre = bool(np.any(pk.flat["d0"].reshape(nmem, width)[:, :p] != 0.0)
                   or np.any(pk.flat["fext"].reshape(nmem, width)[:, :p] != 0.0))
        kernel, tpb = _register_kernel(p, pre)
    elif generated:
        warp = False
        kernel = generated_kernel(int(pk.law[0]))
    else:
        kernel = _kernels()["warp" if warp else "thread"]
    width = int(pk.off[1])
    if not (np.all(pk.n_slots == p) and np.all(pk.nrec == pk.nrec[0]) and np.all(pk.record_v == pk.record_v[0])):
        raise ConfigError("device", "the CUDA engine runs members of one layout (same number of beads and probes)")
    ns = pk.n_samples
    nrec = int(pk.nrec[0])
    nb = int(pk.nb[0])
    nc = int(pk.fmax_off[1])
    record_v = bool(pk.record_v[0])

    def slots(name: str, rows: int):
        """A flat ragged buffer as a (rows, member) device array."""
        return cuda.to_device(np.ascontiguousarray(pk.flat[name].reshape(nmem, width)[:, :rows].T))

    d = {k: slots(k, p) for k in _SLOT_ARRAYS + ("a",)}
    for name in ("u", "v", "g"):
        d[name] = slots(name, p + 1)
    d["vp"] = cuda.to_device(np.zeros((p + 1, nmem)))
    d["sc"] = cuda.to_device(np.zeros((p + 1, nmem if warp else 1)))  # the warp kernel's per-slot terms
    ints = {k: cuda.to_device(np.ascontiguousarray(getattr(pk, k), dtype=np.int64))
            for k in ("law", "wall_slot", "stride", "n_sub", "n_eval", "relax")}
    flags = {k: cuda.to_device(np.ascontiguousarray(getattr(pk, k), dtype=np.bool_)) for k in ("general", "record_v")}
    c_steps = cuda.to_device(np.ascontiguousarray(pk.c_steps, dtype=np.float64))
    rec = cuda.to_device(np.ascontiguousarray(pk.rec[:nrec]))
    fmax = cuda.to_device(np.ascontiguousarray(pk.fmax.reshape(nmem, nc).T))
    peak = cuda.to_device(np.ascontiguousarray(pk.peak[:, :8].T))
    acc = cuda.to_device(np.ascontiguousarray(pk.acc[:, :8].T))
    status = cuda.to_device(np.zeros(nmem, dtype=np.int64))
    state = slots("dmax", p) if generated else None  # the generated law's per-contact state
    # the elastic-plastic contacts' state (yield overlap, largest overlap, unloading curve), carried
    # on the device from launch to launch; a (1, 1) stand-in the kernels never read in batches
    # without such a member (the packed batch has empty state buffers then)
    plastic = not generated and bool(np.any(pk.law == LAW_ELASTOPLASTIC))
    stand_in = cuda.to_device(np.zeros((1, 1)))
    ep = {k: slots(k, p) if plastic else stand_in for k in _PLASTIC_STATE}
    # the extension (core.layout.extension's columns) as (column, slot, member), its internal
    # masses' accelerations, the protected bodies' records; stand-ins without an extended member
    ext_on = np.ascontiguousarray(pk.ext_on if extended else np.zeros(nmem), dtype=np.bool_)
    with_body = np.flatnonzero(pk.body_slot >= 0) if extended else np.zeros(0, dtype=np.int64)
    stand_in3 = cuda.to_device(np.zeros((1, 1, 1)))
    ext = stand_in3
    if extended:
        host_ext = np.zeros((EXT_COLUMNS, p, nmem))
        host_ext[:, :, ext_on] = pk.ext.reshape(-1, p, EXT_COLUMNS).transpose(2, 1, 0)
        ext = cuda.to_device(host_ext)
    wa = cuda.to_device(np.zeros((p, nmem))) if extended else stand_in
    ext_args = (wa, ext, cuda.to_device(ext_on),
                cuda.to_device(np.ascontiguousarray(pk.body_slot if extended else np.full(nmem, -1), dtype=np.int64)))

    cost = float(np.sum(pk.interval / pk.plan_dt * (p + 1) * np.where(pk.general, 2, 1)))
    per_launch = max(1, min(ns - 1, int(LAUNCH_SLOT_STEPS // max(cost, 1.0)),
                            int(LAUNCH_OUTPUT_BYTES // (8 * nmem * (nrec + 3 + plastic + (nb if record_v else 0)
                                                                 + (4 if with_body.size else 0))))))
    out_f = cuda.device_array((per_launch, nrec, nmem))
    out_ke = cuda.device_array((per_launch, nmem))
    out_pe = cuda.device_array((per_launch, nmem))
    out_ed = cuda.device_array((per_launch, nmem))
    out_wp = cuda.device_array((per_launch, nmem)) if plastic else stand_in
    out_v = cuda.device_array((per_launch if record_v else 1, nb, nmem))
    out_b = cuda.device_array((per_launch, 4, nmem)) if with_body.size else stand_in3
    host_f = pk.out_f.reshape(nmem, ns, nrec)
    host_v = pk.out_v.reshape(nmem, ns if record_v else 1, nb)
    k = 1
    while k < ns:
        k_stop = min(ns, k + per_launch)
        rows = k_stop - k
        probes = (float(pk.interval), ints["stride"], ints["n_sub"], ints["n_eval"], c_steps, ints["relax"], k,
                  k_stop, rec, out_f, out_ke, out_pe, out_ed)
        trackers = (out_v, flags["record_v"], fmax, peak, acc, status)
        tail = probes + trackers
        if lanes:
            kernel[-(-nmem // cuda_lanes.chains_per_block()), tpb](
                d["u"], d["v"], d["a"], d["g"], d["kappa"], d["inv_mass"], d["d0"], d["fext"], d["mass"],
                ints["wall_slot"], float(pk.interval), stride0, k, k_stop, rec, out_f, out_ke, out_pe, out_ed, out_v,
                flags["record_v"], fmax, peak, acc, status)
        elif generated:
            kernel[-(-nmem // THREADS_PER_BLOCK), THREADS_PER_BLOCK](
                d["u"], d["v"], d["a"], d["g"], d["vp"], state, d["mass"], d["inv_mass"], d["kappa"], d["damping"],
                d["d0"], d["de"], d["dx0"], d["rsum"], d["fext"], d["dcap"], ints["wall_slot"], *tail, *ext_args, out_b)
        elif register:
            kernel[-(-nmem // tpb), tpb](
                d["u"], d["v"], d["a"], d["g"], d["mass"], d["inv_mass"], d["kappa"], d["damping"], d["d0"], d["de"],
                d["dx0"], d["rsum"], d["fext"], d["dcap"], ints["wall_slot"], *tail)
        else:
            launch = kernel[nmem, _lanes()] if warp else kernel[-(-nmem // THREADS_PER_BLOCK), THREADS_PER_BLOCK]
            launch(
                d["u"], d["v"], d["a"], d["g"], d["vp"], *((d["sc"],) if warp else ()), d["mass"], d["inv_mass"],
                d["kappa"], d["damping"], d["d0"], d["de"], d["dx0"], d["rsum"], d["fext"], d["dcap"], ep["dyield"],
                ep["dmax"], ep["dres"], ep["kres"], ints["law"], flags["general"], ints["wall_slot"], *probes,
                out_wp, *trackers, *ext_args, out_b)
        # probes stay on the device for the whole launch; one copy per chunk
        host_f[:, k:k_stop, :] = out_f.copy_to_host()[:rows].transpose(2, 0, 1)
        pk.out_ke[:, k:k_stop] = out_ke.copy_to_host()[:rows].T
        pk.out_pe[:, k:k_stop] = out_pe.copy_to_host()[:rows].T
        pk.out_ed[:, k:k_stop] = out_ed.copy_to_host()[:rows].T
        if plastic:
            pk.out_wp[:, k:k_stop] = out_wp.copy_to_host()[:rows].T
        if record_v:
            host_v[:, k:k_stop, :] = out_v.copy_to_host()[:rows].transpose(2, 0, 1)
        if with_body.size:  # the bodies' records, member after member (buffers._member_body)
            pk.out_b.reshape(with_body.size, ns, 4)[:, k:k_stop, :] = \
                out_b.copy_to_host()[:rows][:, :, with_body].transpose(2, 0, 1)
        check_members_finite(status.copy_to_host(), k_stop * pk.interval)
        k = k_stop
        if progress is not None:
            progress(k - 1, ns - 1)
    pk.fmax.reshape(nmem, nc)[:] = fmax.copy_to_host().T
    pk.peak[:, :8] = peak.copy_to_host().T
    pk.acc[:, :8] = acc.copy_to_host().T
    if extended:  # the internal masses' state and the bodies' work at the end, as the CPU engine leaves them
        pk.ext[:] = ext.copy_to_host()[:, :, ext_on].transpose(2, 1, 0).reshape(-1, EXT_COLUMNS)
    if plastic:  # the state at the end: the members' residual overlaps are read from it
        for name in _PLASTIC_STATE[1:]:
            pk.flat[name].reshape(nmem, width)[:, :p] = ep[name].copy_to_host().T
