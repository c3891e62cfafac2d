"""Compiled chunks of steps (numba) for ellipsoid scenes: fix nve/asphere between wall/ees faces.

The NumPy engine (engine.py, walls.EESWallKernel, geometry/quaternion.py) is the reference. This
module runs its step in one compiled call per chunk (the steps between two samples; a long chunk in
calls of `KernelPath.call_steps`), for every case of the batch, from the very functions the NumPy
path calls (plain arithmetic on floats or arrays, compiled by numba for floats):
`quaternion.richardson_step` (the Richardson quaternion update of fix nve/asphere),
`quaternion.rotation_rows`, `ees.sigma_n_of`, `ees.ees_ratios`,
`ees.ees_series` / `ees.ees_closed`, `ees.ees_combine` and `ees.torque_of`. Their one branch,
`quaternion.select` (np.where), is overloaded here for scalars. One step of one atom is
engine.Engine.step with ellipsoids:

  v += dtfm f ; x += dt v ; L += dt/2 ftm2v T ; q = richardson(q, L, I, dt/2) ; periodic wrap ;
  f = 0, T = 0 ; every wall/ees face: f[dim] -= side F, T += tau ; lost-atom test ;
  v += dtfm f ; L += dt/2 ftm2v T

Atoms do not interact (no pair forces), so a chunk runs block by block: every step of the chunk
on BLOCK atoms (their structure-of-arrays buffers stay in L1 cache), then the next block. Each
step is a few simple loops over the block that the compiler vectorises: the kick, drift and
rotation; the wrap; per face the contact (distance, sigma_n, the series of G and K for every
atom, then the closed forms with their logarithm only for the contacts with sigma_n/r >= 1/2, as
ees_energy_force_torque chooses) and the force and torque; the lost test; the final kick.
Per atom the arithmetic is the NumPy path's, operation for operation, so results agree to the
last bits (NumPy's vectorised log may differ from libm's by an ulp in the closed form).

Eligible (`eligible`): ellipsoids (fix nve/asphere on every atom), wall/ees faces with constant
parameters and nothing else (no pair, thermostats, reflect, flow, region or other flat walls,
dt/reset, run-to-time). A chunk that meets trouble (an ellipsoid on or inside a wall, a lost
atom, a non-finite value) leaves the state as it was and is re-run by the NumPy loop, which
reports exactly as always. Samples (`AspherePath.advance_sampled`) are computed in the kernel: a
run of sample steps per call, the stretches between them one after the other (each block by block),
each sample's per-atom energies, wall forces, m v^2 and rotational energy kept on its last step and
summed over all atoms in the NumPy path's orders (np.bincount's atom order, region contacts slot by
slot, NumPy's pairwise sum), appended by `ChunkPlan.record_samples`; `advance` (one chunk, the
outputs of its last step from the NumPy `Engine.compute_forces` at the final positions, as in
engine/compiled.py) serves the rest. A chunk runs over threads (`run_kernel`, threads.py's rule):
runs of cases, or one case's runs of atoms when its samples are not recorded in the kernel (a
single case with work for two threads between samples samples one instant at a time: the steps
but the last split over atoms, the last in a call that records the sample).
`WALLBATCH_NUMBA=0` selects the NumPy path. The kernel is cached on disk (numba cache=True).
"""

from __future__ import annotations

import hashlib
import inspect
import math
import warnings
from collections.abc import Callable
from typing import Any

import numpy as np

from wallbatch.engine import compiled as _compiled
from wallbatch.engine import thermostats as _th
from wallbatch.engine import threads
from wallbatch.engine.compiled import REGION_KINDS, ChunkPlan, enabled
from wallbatch.engine.region_walls import RegionEESKernel
from wallbatch.engine.walls import EESWallKernel
from wallbatch.geometry import quaternion as _quat
from wallbatch.geometry.quaternion import richardson_step, rotation_rows, rotational_energy_of
from wallbatch.styles import ees as _ees
from wallbatch.styles.ees import ees_closed, ees_combine, ees_ratios, ees_series, sigma_n_of, torque_of

try:  # numba is a dependency, but the NumPy path must keep working without it
    from numba import njit
    from numba.core.errors import NumbaIRAssumptionWarning
    from numba.extending import overload, register_jitable
except Exception:  # noqa: BLE001 - any import failure means "no compiled path"
    njit = None
    NumbaIRAssumptionWarning = Warning

BLOCK = 64  # atoms per block: their buffer (NROW doubles each) stays in L1 cache over the chunk
# rows of the block buffer: positions, velocities, forces (FR, then T right after: cleared together),
# torques, quaternions, angular momenta, semi-axes, moments of inertia, dt/2 ftm2v / m, a face's
# distance, sigma_n, G, K and contact flag, and a contact's energy and force (the outputs of a
# sample: a flat face's side F in W; a region's F n in W..W+2)
X, V, FR, T, Q, L, S, IN, DTFM, R, SN, G, K, NEAR, E, W = 0, 3, 6, 9, 12, 16, 19, 22, 25, 26, 27, 28, 29, 30, 31, 32
NROW = 35
SERIES_T = 0.5  # ees_energy_force_torque: series for sigma_n/r below this, closed form above


def _fingerprint() -> int:
    """A number that changes with the source of every function compiled into the kernel from
    outside this file (geometry/quaternion.py, styles/ees.py, compiled._region_contacts): part of
    the kernel's on-disk cache key (numba keys a cached function by its own file only)."""
    h = hashlib.sha256()
    for src in (inspect.getsource(_quat), inspect.getsource(_ees), inspect.getsource(_th),
                inspect.getsource(_compiled._region_contacts.py_func)):
        h.update(src.encode())
    return int(h.hexdigest()[:15], 16)


# the compile message's estimate for the ellipsoid kernel: 36-43 s CPU alone on a 2-core AVX2 host
# (numba inlines the quaternion and ees arithmetic into its loops, which run 1.5-2x faster so)
COMPILE_SECONDS = 40

if njit is not None:
    jit = njit(cache=True, nogil=True, error_model="numpy")
    inline = njit(cache=True, nogil=True, error_model="numpy", inline="always")

    @overload(_quat.select)
    def _select_scalar(cond, a, b):  # noqa: ANN001, ANN202
        """quaternion.select for scalars: a if cond else b (np.where's value, without an array)."""
        return lambda cond, a, b: a if cond else b

    # the shared plain-arithmetic functions and their helpers, compiled as they are wherever a
    # compiled function calls them
    for _fn in (_quat.rotation_rows, _quat.to_body, _quat.to_space, _quat.body_omega, _quat.omega_quat,
                _quat.normalized, _quat._omega_of, _quat.richardson_step, _quat.rotational_energy_of,
                _ees._horner, _ees.ees_ratios,
                _ees.ees_series, _ees.ees_closed, _ees.ees_combine, _ees.sigma_n_of, _ees.torque_of):
        # inlined in numba's IR: the loops over atoms see the whole arithmetic and vectorise (2x faster
        # than leaving the inlining to LLVM)
        register_jitable(inline="always", error_model="numpy", nogil=True)(_fn)

    _region_contacts = _compiled._region_contacts  # a region's contacts per block (wall/region's own)
    _richardson = njit(nogil=True, error_model="numpy", inline="always")(richardson_step)
    _rotation = njit(nogil=True, error_model="numpy", inline="always")(rotation_rows)
    _sigma_n = njit(nogil=True, error_model="numpy", inline="always")(sigma_n_of)
    _ratios = njit(nogil=True, error_model="numpy", inline="always")(ees_ratios)
    _series = njit(nogil=True, error_model="numpy", inline="always")(ees_series)
    _closed = njit(nogil=True, error_model="numpy", inline="always")(ees_closed)
    _combine = njit(nogil=True, error_model="numpy", inline="always")(ees_combine)
    _torque = njit(nogil=True, error_model="numpy", inline="always")(torque_of)
    _erot = njit(nogil=True, error_model="numpy", inline="always")(rotational_energy_of)
    _mv2 = njit(nogil=True, error_model="numpy", inline="always")(_th.atom_mv2)
    _pairwise = _compiled._th_pairwise  # NumPy's summation order of x.sum(axis=-1)

    @inline
    def _unit(d, side, axis):
        """Component `axis` of the face normal n = -side e_d (walls.EESWallKernel: zeros elsewhere)."""
        return -float(side) if axis == d else 0.0

    @inline
    def _o(row):
        """Offset of a row of the block buffer (unsigned: no negative-index wraparound)."""
        return np.uint64(row * BLOCK)

    @inline
    def _kick_rotate(B, nb, dtc, dtt, dtq):
        """fix nve/asphere's initial_integrate on the block: v += dtfm f; x += dt v;
        L += dt/2 ftm2v T; q = richardson_step(q, L, I, dt/2)."""
        for d in range(3):
            ox, ov, of_, ol, ot = _o(X + d), _o(V + d), _o(FR + d), _o(L + d), _o(T + d)
            for i in range(nb):
                vi = B[ov + i] + B[_o(DTFM) + i] * B[of_ + i]
                B[ov + i] = vi
                B[ox + i] = B[ox + i] + dtc * vi
                B[ol + i] = B[ol + i] + dtt * B[ot + i]
        for i in range(nb):
            q0, q1, q2, q3 = _richardson(B[_o(Q) + i], B[_o(Q + 1) + i], B[_o(Q + 2) + i], B[_o(Q + 3) + i],
                                         B[_o(L) + i], B[_o(L + 1) + i], B[_o(L + 2) + i],
                                         B[_o(IN) + i], B[_o(IN + 1) + i], B[_o(IN + 2) + i], dtq)
            B[_o(Q) + i] = q0
            B[_o(Q + 1) + i] = q1
            B[_o(Q + 2) + i] = q2
            B[_o(Q + 3) + i] = q3

    @inline
    def _ees_face(B, nb, d, side, coord, eps, sig, cut, grp):
        """One wall/ees face on the block (walls.EESWallKernel.apply): the contacts (r < rc, group
        atoms: grp[i] != 0), F[d] -= side F, T += tau. Returns the number of contacts with
        r <= sigma_n."""
        n0, n1, n2 = _unit(d, side, 0), _unit(d, side, 1), _unit(d, side, 2)
        nbad = 0
        nclosed = 0
        ox = _o(X + d)
        lo_side = side < 0
        # the loops below read and write rows at constant offsets only (the position along d
        # copied to R first, the force along d added after): the compiler then sees that no two
        # rows overlap and vectorises them (a row offset that depends on d took ~40% longer)
        for i in range(nb):
            B[_o(R) + i] = B[ox + i]
        for i in range(nb):  # distance, sigma_n and the series, for every atom (branch-free)
            xi = B[_o(R) + i]
            r = xi - coord if lo_side else coord - xi
            a = _rotation(B[_o(Q) + i], B[_o(Q + 1) + i], B[_o(Q + 2) + i], B[_o(Q + 3) + i])
            sn = _sigma_n(a, B[_o(S) + i], B[_o(S + 1) + i], B[_o(S + 2) + i], n0, n1, n2)
            t, s, p = _ratios(r, sn)
            g_, k_ = _series(s)
            near = (r < cut) & (grp[i] != 0)
            nbad += near & (r <= sn)
            nclosed += near & (t >= SERIES_T)
            B[_o(R) + i] = r
            B[_o(SN) + i] = sn
            B[_o(G) + i] = g_
            B[_o(K) + i] = k_
            B[_o(NEAR) + i] = 1.0 if near else 0.0
        if nclosed:  # the closed forms, only where t = sigma_n / r >= 1/2
            for i in range(nb):
                r, sn = B[_o(R) + i], B[_o(SN) + i]
                t, s, p = _ratios(r, sn)
                if B[_o(NEAR) + i] != 0.0 and t >= SERIES_T:
                    g_, k_ = _closed(t, p, math.log((r - sn) / (r + sn)))
                    B[_o(G) + i] = g_
                    B[_o(K) + i] = k_
        sidef = float(side)
        of_ = _o(FR + d)
        for i in range(nb):  # force and torque of the contacts
            r, sn = B[_o(R) + i], B[_o(SN) + i]
            t, s, p = _ratios(r, sn)
            e, f, tw = _combine(r, s, p, B[_o(G) + i], B[_o(K) + i], eps, sig)
            a = _rotation(B[_o(Q) + i], B[_o(Q + 1) + i], B[_o(Q + 2) + i], B[_o(Q + 3) + i])
            t0, t1, t2 = _torque(a, B[_o(S) + i], B[_o(S + 1) + i], B[_o(S + 2) + i], n0, n1, n2, tw)
            near = B[_o(NEAR) + i] != 0.0
            B[_o(E) + i] = e  # a sample's outputs (`_keep_face`)
            B[_o(W) + i] = sidef * f
            ti = B[_o(T) + i]
            B[_o(T) + i] = ti + t0 if near else ti
            ti = B[_o(T + 1) + i]
            B[_o(T + 1) + i] = ti + t1 if near else ti
            ti = B[_o(T + 2) + i]
            B[_o(T + 2) + i] = ti + t2 if near else ti
        for i in range(nb):  # F[d] -= side F of the contacts
            fi = B[of_ + i]
            B[of_ + i] = fi - B[_o(W) + i] if B[_o(NEAR) + i] != 0.0 else fi
        return nbad

    @inline
    def _keep_face(B, nb, a0, P):
        """A sample step's outputs of one flat face on the block into P (3, N) at atoms a0..:
        contact flag, energy, side F (walls.EESWallKernel.apply's bincount weights)."""
        for i in range(nb):
            P[0, a0 + i] = B[_o(NEAR) + i]
            P[1, a0 + i] = B[_o(E) + i]
            P[2, a0 + i] = B[_o(W) + i]

    @inline
    def _region_ees(B, RB, nslot, nb, eps, sig, rec, a0, P):
        """The wall/region/ees forces and torques of a block's contacts in RB (region_walls.
        RegionEESKernel.apply): normal n = delta / r, sigma_n along n, F += F n, T += tau, slot by
        slot (each atom adds its contacts in the order np.add.at does). As _ees_face, branch-free
        passes over the block (series for every atom, closed forms only where needed, then the
        force and torque where RB flags a contact). Returns the number of contacts with r <= sigma_n.
        With `rec` (a sample step) each slot's contact flag, energy and F n go to P[slot] (6, 5, N)
        at atoms a0.. (region_walls.RegionEESKernel.apply's bincount weights, slot by slot)."""
        nbad = 0
        if rec:
            for j in range(nslot, 6):
                for i in range(nb):
                    P[j, 0, a0 + i] = 0.0
        for j in range(nslot):
            ncontact = 0
            for i in range(nb):
                ncontact += RB[j, 0, i] != 0.0
            if ncontact == 0:  # e.g. the faces of a block that no atom of the block is near
                if rec:
                    for i in range(nb):
                        P[j, 0, a0 + i] = 0.0
                continue
            nclosed = 0
            for i in range(nb):
                r = RB[j, 1, i]
                n0, n1, n2 = RB[j, 2, i] / r, RB[j, 3, i] / r, RB[j, 4, i] / r
                a = _rotation(B[_o(Q) + i], B[_o(Q + 1) + i], B[_o(Q + 2) + i], B[_o(Q + 3) + i])
                sn = _sigma_n(a, B[_o(S) + i], B[_o(S + 1) + i], B[_o(S + 2) + i], n0, n1, n2)
                t, s, p = _ratios(r, sn)
                g_, k_ = _series(s)
                contact = RB[j, 0, i] != 0.0
                nbad += contact & (r <= sn)
                nclosed += contact & (t >= SERIES_T)
                B[_o(SN) + i] = sn
                B[_o(G) + i] = g_
                B[_o(K) + i] = k_
            if nclosed:
                for i in range(nb):
                    r, sn = RB[j, 1, i], B[_o(SN) + i]
                    t, s, p = _ratios(r, sn)
                    if RB[j, 0, i] != 0.0 and t >= SERIES_T:
                        g_, k_ = _closed(t, p, math.log((r - sn) / (r + sn)))
                        B[_o(G) + i] = g_
                        B[_o(K) + i] = k_
            for i in range(nb):
                r, sn = RB[j, 1, i], B[_o(SN) + i]
                n0, n1, n2 = RB[j, 2, i] / r, RB[j, 3, i] / r, RB[j, 4, i] / r
                t, s, p = _ratios(r, sn)
                e, f, tw = _combine(r, s, p, B[_o(G) + i], B[_o(K) + i], eps, sig)
                a = _rotation(B[_o(Q) + i], B[_o(Q + 1) + i], B[_o(Q + 2) + i], B[_o(Q + 3) + i])
                t0, t1, t2 = _torque(a, B[_o(S) + i], B[_o(S + 1) + i], B[_o(S + 2) + i], n0, n1, n2, tw)
                contact = RB[j, 0, i] != 0.0
                B[_o(E) + i] = e
                B[_o(W) + i] = f * n0
                B[_o(W + 1) + i] = f * n1
                B[_o(W + 2) + i] = f * n2
                fi = B[_o(FR) + i]
                B[_o(FR) + i] = fi + f * n0 if contact else fi
                fi = B[_o(FR + 1) + i]
                B[_o(FR + 1) + i] = fi + f * n1 if contact else fi
                fi = B[_o(FR + 2) + i]
                B[_o(FR + 2) + i] = fi + f * n2 if contact else fi
                ti = B[_o(T) + i]
                B[_o(T) + i] = ti + t0 if contact else ti
                ti = B[_o(T + 1) + i]
                B[_o(T + 1) + i] = ti + t1 if contact else ti
                ti = B[_o(T + 2) + i]
                B[_o(T + 2) + i] = ti + t2 if contact else ti
            if rec:
                for i in range(nb):
                    P[j, 0, a0 + i] = RB[j, 0, i]
                    P[j, 1, a0 + i] = B[_o(E) + i]
                    P[j, 2, a0 + i] = B[_o(W) + i]
                    P[j, 3, a0 + i] = B[_o(W + 1) + i]
                    P[j, 4, a0 + i] = B[_o(W + 2) + i]
        return nbad

    @inline
    def _bincount_sum(P, row, natom):
        """sum of P[row, a] over the atoms with a contact (P[0, a] != 0) in atom order, from 0.0:
        np.bincount's sum of one case."""
        acc = 0.0
        for a in range(natom):
            if P[0, a] != 0.0:
                acc += P[row, a]
        return acc

    def _make_run_chunk(fingerprint: int) -> Any:
        """The chunk kernel; `fingerprint` (see _fingerprint) joins its on-disk cache key."""

        @jit
        def _run_chunk(at, rec, x, v, f, quat, angmom, torque, mass, shape, inertia, dt, lo, hi, periodic, ftm2v,
                       ef_meta, ef_val, groups, rg_meta, rg_geo, rg_val, xo, vo, fo, qo, lo_, to,
                       sm_face, sm_reg, sm_kin):
            """Advance every case by at[-1] steps, reading x, v, f, quat, angmom, torque and writing
            xo, vo, fo, qo, lo_, to. at (S,) int: the steps (from now, increasing) that end the
            stretches run one after the other; with `rec` each of them is a sample step whose outputs
            go to sm_face (C, S, K, 2): each wall/ees face's energy and side F summed over its contacts,
            sm_reg (C, S, KR, 4): each wall/region/ees fix's energy and sum of F n (x, y, z), and
            sm_kin (C, S, 2): sum m v^2 and sum of the rotational energies / mvv2e (NumPy's pairwise
            order). ef_meta (K, 3) int: dim, side, group row of each wall/ees face; ef_val (C, K, 4):
            coord, epsilon, sigma, cutoff. rg_meta (KR, 3) int: kind (REGION_KINDS), axis, group row of
            each wall/region/ees fix; rg_geo (KR, 10): lo xyz, hi xyz, radius, centre (compiled.py's
            layout); rg_val (C, KR, 3): epsilon, sigma, cutoff. Returns 0, or the status of the first
            trouble met (1: an ellipsoid on or inside a wall, or on the wrong side of a region, 2: a
            lost atom, 3: a non-finite value); the caller then falls back to NumPy.

            A block's atoms live in one flat buffer B, a row of BLOCK values per quantity at constant
            offsets (_o), so the compiler sees that rows never overlap and vectorises the loops. Each
            stretch runs block by block (every step of it on one block, then the next), the state kept
            in the output arrays between stretches; a sample's sums run over all atoms once every
            block has reached it."""
            if at.shape[0] > 0 and at[0] == -fingerprint:  # never: ties the on-disk cache to the shared functions
                return 5
            ncase, natom = x.shape[0], x.shape[1]
            nface = ef_meta.shape[0]
            hf = 0.5 * ftm2v
            B = np.zeros(NROW * BLOCK)
            GRP = np.zeros((nface, BLOCK), np.uint8)
            nreg = rg_meta.shape[0]
            GRPR = np.zeros((max(nreg, 1), BLOCK), np.uint8)
            RB = np.zeros((6, 5, BLOCK))  # a region's contacts of the block (compiled._region_contacts)
            XB = B[:3 * BLOCK].reshape((3, BLOCK))  # the block's positions (rows X..X+2), a view
            nblock = (natom + BLOCK - 1) // BLOCK
            ns = natom if rec else 0  # a sample's per-atom outputs
            PF = np.zeros((nface, 3, ns))
            PR = np.zeros((max(nreg, 1), 6, 5, ns))
            KS = np.zeros((2, ns))
            for c in range(ncase):
                dtc = dt[c]
                dtt = hf * dtc  # (0.5 ftm2v) dt: the angular-momentum half kick
                dtq = 0.5 * dtc
                for a in range(natom):  # the state lives in the outputs from here
                    for d in range(3):
                        xo[c, a, d] = x[c, a, d]
                        vo[c, a, d] = v[c, a, d]
                        fo[c, a, d] = f[c, a, d]
                        lo_[c, a, d] = angmom[c, a, d]
                        to[c, a, d] = torque[c, a, d]
                    for d in range(4):
                        qo[c, a, d] = quat[c, a, d]
                for ism in range(at.shape[0]):
                    nsteps = at[ism] - (at[ism - 1] if ism > 0 else 0)
                    for blk in range(nblock):
                        a0 = blk * BLOCK
                        nbi = min(a0 + BLOCK, natom) - a0
                        nb = np.uint64(nbi)
                        for jj in range(nbi):
                            a = a0 + jj
                            j = np.uint64(jj)
                            for d in range(3):
                                B[_o(X + d) + j] = xo[c, a, d]
                                B[_o(V + d) + j] = vo[c, a, d]
                                B[_o(FR + d) + j] = fo[c, a, d]
                                B[_o(L + d) + j] = lo_[c, a, d]
                                B[_o(T + d) + j] = to[c, a, d]
                                B[_o(S + d) + j] = shape[c, a, d]
                                B[_o(IN + d) + j] = inertia[c, a, d]
                            for d in range(4):
                                B[_o(Q + d) + j] = qo[c, a, d]
                            B[_o(DTFM) + j] = (hf * dtc) / mass[c, a]
                            for k in range(nface):
                                GRP[k, jj] = groups[ef_meta[k, 2], a]
                            for k in range(nreg):
                                GRPR[k, jj] = groups[rg_meta[k, 2], a]
                        for _s in range(nsteps):
                            last = rec and _s == nsteps - 1  # the sample step: keep its outputs
                            _kick_rotate(B, nb, dtc, dtt, dtq)
                            for d in range(3):  # periodic wrap
                                if periodic[d] != 0:
                                    lod, hid = lo[d], hi[d]
                                    length = hid - lod
                                    ox = _o(X + d)
                                    for i in range(nb):
                                        xi = B[ox + i]
                                        xi = xi - length if xi >= hid else xi
                                        B[ox + i] = xi + length if xi < lod else xi
                            for i in range(np.uint64(6 * BLOCK)):  # force and torque clear (FR, T: rows 6..11)
                                B[_o(FR) + i] = 0.0
                            nbad = 0
                            for k in range(nface):
                                nbad += _ees_face(B, nb, ef_meta[k, 0], ef_meta[k, 1], ef_val[c, k, 0],
                                                  ef_val[c, k, 1], ef_val[c, k, 2], ef_val[c, k, 3], GRP[k])
                                if last:
                                    _keep_face(B, nb, a0, PF[k])
                            for k in range(nreg):  # wall/region/ees (post_force, after the flat walls)
                                nslot, nwrong = _region_contacts(rg_meta[k, 0], rg_meta[k, 1], rg_geo[k], XB, GRPR,
                                                                 k, rg_val[c, k, 2], np.uint64(0), nb, RB)
                                nbad += nwrong
                                nbad += _region_ees(B, RB, nslot, nb, rg_val[c, k, 0], rg_val[c, k, 1], last, a0,
                                                    PR[k])
                            if nbad:
                                return 1
                            nlost = 0
                            for d in range(3):  # lost atoms
                                if periodic[d] == 0:
                                    lod, hid = lo[d], hi[d]
                                    ox = _o(X + d)
                                    for i in range(nb):
                                        nlost += (B[ox + i] < lod) | (B[ox + i] > hid)
                            if nlost:
                                return 2
                            for d in range(3):  # final_integrate: v += dtfm f; L += dt/2 ftm2v T
                                ov, of_, ol, ot = _o(V + d), _o(FR + d), _o(L + d), _o(T + d)
                                for i in range(nb):
                                    B[ov + i] = B[ov + i] + B[_o(DTFM) + i] * B[of_ + i]
                                    B[ol + i] = B[ol + i] + dtt * B[ot + i]
                        for jj in range(nbi):
                            a = a0 + jj
                            j = np.uint64(jj)
                            for d in range(3):
                                if not (math.isfinite(B[_o(X + d) + j]) and math.isfinite(B[_o(V + d) + j])
                                        and math.isfinite(B[_o(L + d) + j])):
                                    return 3
                                xo[c, a, d] = B[_o(X + d) + j]
                                vo[c, a, d] = B[_o(V + d) + j]
                                fo[c, a, d] = B[_o(FR + d) + j]
                                lo_[c, a, d] = B[_o(L + d) + j]
                                to[c, a, d] = B[_o(T + d) + j]
                            for d in range(4):
                                if not math.isfinite(B[_o(Q + d) + j]):
                                    return 3
                                qo[c, a, d] = B[_o(Q + d) + j]
                            if rec:  # Engine.sample's m v^2 and rotational energy of the atom
                                KS[0, a] = _mv2(mass[c, a], B[_o(V) + j], B[_o(V + 1) + j], B[_o(V + 2) + j])
                                KS[1, a] = _erot(B[_o(Q) + j], B[_o(Q + 1) + j], B[_o(Q + 2) + j],
                                                 B[_o(Q + 3) + j], B[_o(L) + j], B[_o(L + 1) + j],
                                                 B[_o(L + 2) + j], B[_o(IN) + j], B[_o(IN + 1) + j],
                                                 B[_o(IN + 2) + j])
                    if rec:  # the sample's sums over all atoms, in the NumPy path's orders
                        sm_kin[c, ism, 0] = 0.0 + _pairwise(KS[0], 0, natom)
                        sm_kin[c, ism, 1] = 0.0 + _pairwise(KS[1], 0, natom)
                        for k in range(nface):
                            sm_face[c, ism, k, 0] = _bincount_sum(PF[k], 1, natom)
                            sm_face[c, ism, k, 1] = _bincount_sum(PF[k], 2, natom)
                        for k in range(nreg):  # contacts slot by slot (RegionGeom.contacts' order)
                            for q in range(4):
                                acc = 0.0
                                for j6 in range(6):
                                    for a in range(natom):
                                        if PR[k, j6, 0, a] != 0.0:
                                            acc += PR[k, j6, 1 + q, a]
                                sm_reg[c, ism, k, q] = acc
            return 0
        return _run_chunk

    _run_chunk = _make_run_chunk(_fingerprint())


# ----------------------------------------------------------------------------- the Python side


# the chunk kernel's arguments split over threads (engine/threads.py): those with a leading case
# axis, and those with an atom axis (its index); the ellipsoids never interact, and the kernel
# writes no per-case counter, so any split gives the bits of one call
CASE_AXIS = frozenset({"x", "v", "f", "quat", "angmom", "torque", "mass", "shape", "inertia", "dt", "ef_val", "rg_val",
                       "xo", "vo", "fo", "qo", "lo_", "to", "sm_face", "sm_reg", "sm_kin"})
ATOM_AXIS = {**{k: 1 for k in ("x", "v", "f", "quat", "angmom", "torque", "mass", "shape", "inertia", "xo", "vo",
                               "fo", "qo", "lo_", "to")}, "groups": 1}


def plan_split(named: dict[str, Any], nthreads: int) -> tuple[str, list[slice]] | None:
    """How to split a `_run_chunk` call (threads.run_kernel's `plan`): runs of cases, or for one
    case, unless its samples are recorded (`rec`: their sums run over all atoms), runs of atoms
    (threads.split_edges: enough work for each); None: one call."""
    ncase, natom = named["x"].shape[:2]
    return threads.split_edges(ncase, natom, int(named["at"][-1]), nthreads, atoms=not named["rec"])


def run_kernel(kernel: Any, args: tuple) -> int:
    """`kernel(*args)` (`_run_chunk`) over the threads threads.count() allows (`plan_split`);
    the first nonzero status (the caller then hands the whole chunk back to NumPy)."""
    return threads.run_kernel(kernel, args, plan=plan_split, case_axis=CASE_AXIS, atom_axis=ATOM_AXIS, counters=())


def eligible(plan: ChunkPlan) -> bool:
    """Whitelist: ellipsoids integrated by fix nve/asphere, wall/ees faces and wall/region/ees
    fixes (block, sphere, cylinder; in or out) with constant coordinates and parameters; nothing
    else (pair, fixes, reflect, other walls, flow, dt/reset)."""
    if plan.others != ("ellipsoids",) or plan.state.quat is None:
        return False
    if getattr(plan, "ensemble", None) is not None:  # integrator groups, thermostats, 2-D: NumPy
        return False
    if plan.reflect or plan.flow or plan.dt_reset is not None:
        return False
    for w in plan.region:
        if type(w) is not RegionEESKernel or (w.geom.style, w.geom.side) not in REGION_KINDS:
            return False
        if any(isinstance(w.params.get(k), str) for k in ("epsilon", "sigma", "cutoff")):
            return False
    for w in plan.soft:
        if type(w) is not EESWallKernel:
            return False
        for face in w.faces:
            if not isinstance(face.coord, np.ndarray) or any(
                    not isinstance(face.params.get(k), np.ndarray) for k in ("epsilon", "sigma", "cutoff")):
                return False
    return True


def _splits_atoms(plan: ChunkPlan, steps: int) -> bool:
    """Whether chunks of `steps` steps of this plan are one case with work for two threads over
    its atoms (threads.split_edges with two threads, whatever this process has)."""
    s = plan.state
    return s.ncases == 1 and threads.split_edges(1, s.x.shape[1], steps, 2) is not None


def sampled_eligible(plan: ChunkPlan) -> bool:
    """Whether the kernel records this scene's samples itself (`AspherePath.advance_sampled`): an
    engine that takes the records, and no fix_modify virial on a wall/ees fix (ees has none)."""
    return plan.record_samples is not None and not any(w.virial for w in plan.soft)


class AspherePath(_compiled.KernelPath):
    """The compiled path of one Engine with ellipsoids (see module docstring): `plan_source()`
    gives the plan of the next chunk (Engine.compiled_plan)."""

    step_cost = _compiled.ASPHERE_STEP_COST
    least_steps = _compiled.ASPHERE_MIN_CALL_STEPS

    def __init__(self, plan_source: Callable[[], ChunkPlan]):
        self.plan_source = plan_source
        self.compiled_chunks = 0  # chunks run compiled (tests and benchmarks read these)
        self.sampled_calls = 0  # kernel calls that recorded samples themselves (advance_sampled)
        self.fallbacks = 0  # chunks handed back to NumPy
        self._spare: tuple[np.ndarray, ...] = ()
        self._skip = 0  # after trouble in a sampled call: instants left to the one-at-a-time path

    def advance_to_time(self, target: float) -> bool:
        """Runs to a simulated time are left to the NumPy loop."""
        return False

    def samples_in_kernel(self, at: np.ndarray) -> bool:
        """Whether `advance_sampled` records the samples `at` (steps from now, increasing) in the kernel."""
        at = np.asarray(at, np.int64)
        if at.size == 0 or at[0] <= 0 or np.any(np.diff(at) <= 0):
            return False
        plan = self.plan_source()
        if not (enabled() and eligible(plan) and sampled_eligible(plan)):
            return False
        # one case with enough work between two samples for two threads over its atoms: one instant
        # at a time (`advance`: the steps but the last split over atoms, the last recording the
        # sample), so that its chunks can be split. The rule counts two threads whatever this
        # process has, so the path does not depend on WALLBATCH_THREADS
        steps = max(1, int(at[-1]) // at.size)
        return not _splits_atoms(plan, steps)

    def advance(self, nsteps: int, sample: bool) -> bool:
        """Run nsteps steps and the sample of the last one; False: let the NumPy loop do it. One
        case with work for two threads over its atoms (`_splits_atoms`: whatever this process's
        threads, so the path does not depend on them) runs its steps but the last in calls split
        over atoms, then the last one in a call that records its sample (its sums over all atoms);
        else the sample's outputs come from NumPy."""
        if nsteps <= 0:
            return False
        plan = self.plan_source()
        if sample and nsteps > 1 and enabled() and eligible(plan) and sampled_eligible(plan) and \
                _splits_atoms(plan, nsteps - 1):
            if not self.in_calls(self._steps, nsteps - 1, False):
                return False
            if not self._chunk(np.ones(1, np.int64), True, True):
                plan.advance_numpy(1, True)  # that step in NumPy (trouble is reported there)
            return True
        return self.in_calls(self._steps, nsteps, sample)  # (a Ctrl-C is seen between calls)

    def _steps(self, nsteps: int, sample: bool) -> bool:
        return self._chunk(np.array([nsteps], np.int64), sample, False)

    def advance_sampled(self, at: np.ndarray) -> int:
        """Run to the sample steps `at` (counted from now, increasing), every sample's outputs computed
        in the kernel and appended by plan.record_samples; returns how many were run (all, or 0:
        nothing done, the caller goes one instant at a time: after trouble in the kernel, for as many
        instants as this call had, so the NumPy loop reports it)."""
        if self._skip > 0:
            self._skip -= 1
            return 0
        if not self.samples_in_kernel(at):
            return 0
        at = np.asarray(at, np.int64)
        at = self.one_call(at)  # the call within its share of CALL_WORK
        if self._chunk(at, True, True):
            return int(at.size)
        self._skip = int(at.size) - 1
        return 0

    def _chunk(self, at: np.ndarray, sample: bool, rec: bool) -> bool:
        plan = self.plan_source()
        s = plan.state
        if s.ncases == 0 or s.failed or not enabled() or not eligible(plan):
            return False
        faces = [(w, face) for w in plan.soft for face in w.faces]
        groups: list[np.ndarray] = [np.ones(s.x.shape[1], np.uint8)]
        meta = []
        for w, face in faces:
            g = 0
            if not w.all_atoms:
                groups.append(w.group.astype(np.uint8))
                g = len(groups) - 1
            meta.append((face.dim, face.side, g))
        C = s.ncases
        ef_meta = np.array(meta, np.int64).reshape(-1, 3)
        ef_val = np.zeros((C, len(faces), 4))
        for k, (_, face) in enumerate(faces):
            ef_val[:, k, 0] = face.coord
            for j, key in enumerate(("epsilon", "sigma", "cutoff")):
                ef_val[:, k, 1 + j] = face.params[key]
        KR = len(plan.region)
        rg_meta = np.zeros((KR, 3), np.int64)
        rg_geo = np.zeros((KR, 10))
        rg_val = np.zeros((C, KR, 3))
        N = s.x.shape[1]
        for k, w in enumerate(plan.region):
            g = w.geom
            row = 0
            if w.atoms.size != N:
                groups.append(np.isin(np.arange(N), w.atoms).astype(np.uint8))
                row = len(groups) - 1
            rg_meta[k] = (REGION_KINDS[(g.style, g.side)], g.axis or 0, row)
            if g.style == "block":
                rg_geo[k, 0:3], rg_geo[k, 3:6] = g.lo, g.hi
            elif g.style == "sphere":
                rg_geo[k, 6], rg_geo[k, 7:10] = g.radius, g.center
            else:
                rg_geo[k, 0], rg_geo[k, 3], rg_geo[k, 6], rg_geo[k, 7:9] = g.lo, g.hi, g.radius, g.center
            for j, key in enumerate(("epsilon", "sigma", "cutoff")):
                rg_val[:, k, j] = np.broadcast_to(np.asarray(w.params[key], float), (C,))
        names = ("x", "v", "f", "quat", "angmom", "torque", "mass", "shape", "inertia")
        for name in names:
            arr = getattr(s, name)
            if not arr.flags.c_contiguous or arr.dtype != np.float64:
                setattr(s, name, np.ascontiguousarray(arr, dtype=np.float64))
        if not self._spare or self._spare[0].shape != s.x.shape:
            self._spare = (*(np.empty_like(s.x) for _ in range(3)), np.empty_like(s.quat), np.empty_like(s.angmom),
                           np.empty_like(s.torque))
        xo, vo, fo, qo, lo_, to = self._spare
        periodic = np.zeros(3, np.int64)
        periodic[s.periodic] = 1
        S = at.size if rec else 0
        sm_face, sm_reg, sm_kin = np.zeros((C, S, len(faces), 2)), np.zeros((C, S, KR, 4)), np.zeros((C, S, 2))
        if not _run_chunk.signatures:  # a first compile is long: say so (not when it loads from the disk cache)
            _compiled.announce_compile(_run_chunk, COMPILE_SECONDS)
        with warnings.catch_warnings():  # numba's pedantic SSA note on the inlined Horner loop, at compile
            warnings.simplefilter("ignore", NumbaIRAssumptionWarning)
            status = run_kernel(_run_chunk, (at, bool(rec), s.x, s.v, s.f, s.quat, s.angmom, s.torque, s.mass, s.shape,
                                s.inertia, np.ascontiguousarray(s.dt, dtype=float), np.asarray(s.box_lo, float),
                                np.asarray(s.box_hi, float), periodic, float(s.units.ftm2v), ef_meta, ef_val,
                                np.stack(groups), rg_meta, rg_geo, rg_val, xo, vo, fo, qo, lo_, to,
                                sm_face, sm_reg, sm_kin))  # in threads where there is work for them
        if status != 0:
            self.fallbacks += 1
            return False
        nsteps = int(at[-1])
        self.compiled_chunks += 1 if not rec else S  # a sampled call counts once per sample it replaces
        self.sampled_calls += bool(rec)
        self._spare = (s.x, s.v, s.f, s.quat, s.angmom, s.torque)
        s.x, s.v, s.f, s.quat, s.angmom, s.torque = xo, vo, fo, qo, lo_, to
        s.ctx = None
        s.var_step = {}
        if rec:
            step = s.step[:, None] + at[None, :]
            s.step += nsteps
            plan.record_samples(**_sample_record(plan, at, step, sm_face, sm_reg, sm_kin))
            return True
        s.step += nsteps
        # the forces and torques before the chunk (free now) take the NumPy pass's
        _compiled.finish_chunk(plan, s, sample, keep=("f", "torque"),
                               scratch={"f": self._spare[2], "torque": self._spare[5]})
        return True


def _sample_record(plan: ChunkPlan, at: np.ndarray, step: np.ndarray, sm_face: np.ndarray, sm_reg: np.ndarray,
                   sm_kin: np.ndarray) -> dict[str, Any]:
    """Engine.record's arguments (plan.record_samples) of a sampled call: each fix's energy and
    vector summed as the NumPy fixes sum them (faces in order from zero), the clock (dt is constant:
    no dt/reset here), sum m v^2 and the rotational energy (erot, times mvv2e as Engine.sample)."""
    s = plan.state
    C, S = step.shape
    out: dict[str, tuple[np.ndarray, ...]] = {}
    k = 0
    for w in plan.soft:
        energy = np.zeros((C, S))
        vector = np.zeros((C, S, len(w.faces)))
        for j in range(len(w.faces)):
            energy += sm_face[:, :, k, 0]
            vector[:, :, j] = sm_face[:, :, k, 1]
            k += 1
        out[w.fix_id] = (energy, vector)
    for k, w in enumerate(plan.region):
        out[w.fix_id] = (sm_reg[:, :, k, 0], -sm_reg[:, :, k, 1:4])
    dt = np.repeat(s.dt[:, None], S, axis=1)
    time = s.atime[:, None] + (step - s.atimestep[:, None]) * s.dt[:, None]
    return {"step": step, "time": time, "dt": dt, "mv2": sm_kin[:, :, 0], "out": out,
            "virial": np.zeros((C, S)) if "press" in plan.outputs else None,
            "erot": s.units.mvv2e * sm_kin[:, :, 1]}


def attach_asphere_path(plan_source: Callable[[], ChunkPlan]) -> AspherePath | None:
    """The compiled path for an ellipsoid scene whose plans `plan_source` gives, or None."""
    if njit is None or not enabled() or not eligible(plan_source()):
        return None
    return AspherePath(plan_source)


__all__: list[Any] = ["AspherePath", "attach_asphere_path", "eligible", "sampled_eligible", "BLOCK"]
