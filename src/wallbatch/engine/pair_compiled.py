"""Compiled kernels (numba) for `pair_style lj/cut` (pair.py): displacement check, cell-list
neighbor build and a fused force pass. pair.py's NumPy path is the reference: the force pass runs
its per-pair arithmetic operation for operation (the values of each pair are the same bits; only
the order of the sums over pairs differs), and the build lists the same pairs (distances within
reach). See pair.py for the physics and units.

Neighbor build of one case: atoms are binned in cells of width >= reach/2 (reach = rc + skin;
periodic dims: [lo, hi) cut into floor(L / (reach/2)) cells, or one cell if that is fewer than 5;
fixed dims: the atoms' extent, not wrapped), the cells are filled by a counting sort (stable in
atom index), and each atom, taken in cell order, scans a half stencil: the cells at offsets
(a, b, g) in -2..2 lexicographically after (0, 0, 0) and the atoms after it in its own cell, for
atoms within reach (minimum image in periodic dims). Each pair is listed once. The result is in
CSR form: the partners j of atom owner[s] are neigh[first[s]:first[s+1]]; the order is fixed by
the positions alone (cell order, then atom index), and atoms near in space are near in the list.

All kernels are `@njit(cache=True)` without fastmath (results are reproducible) and take
C-contiguous arrays (float64 positions, int32/int64 lists, bool flags: one compiled signature each).
"""

from __future__ import annotations

import os

import numpy as np

try:  # numba is a dependency, but the NumPy path must keep working without it
    from numba import njit
except Exception:  # noqa: BLE001 - any import failure means "no compiled path"
    njit = None


def enabled() -> bool:
    """True if the compiled path may be used (numba importable, WALLBATCH_NUMBA not 0)."""
    return njit is not None and os.environ.get("WALLBATCH_NUMBA", "1").strip().lower() not in ("0", "false", "no", "off")


if njit is not None:
    jit = njit(cache=True, nogil=True, error_model="numpy")  # x/0 -> inf/nan as in NumPy

    @jit
    def moved_cases(x: np.ndarray, xref: np.ndarray, length: np.ndarray, periodic: np.ndarray,
                    limit2: float, need: np.ndarray) -> None:
        """need[c] = some atom of case c moved more than sqrt(limit2) since xref (minimum image in
        periodic dims), NaN counting as moved: the NumPy path's ~(max |d|^2 <= limit2)."""
        C, N = x.shape[0], x.shape[1]
        for c in range(C):
            need[c] = False
            for i in range(N):
                d2 = 0.0
                for k in range(3):
                    d = x[c, i, k] - xref[c, i, k]
                    if periodic[k]:
                        d -= length[k] * np.rint(d / length[k])
                    d2 += d * d
                if not d2 <= limit2:
                    need[c] = True
                    break

    @jit
    def _cell_shift(c: int, o: int, n: int, per: bool, length: float) -> tuple[int, float]:
        """Cell c + o in a dim of n cells and the image shift of its atoms [length] (+-L when the
        offset wraps a periodic dim), or cell -1 if there is none. A periodic dim has 1 cell (only
        o = 0; the minimum image is then taken per pair) or at least 5 (offsets -2..2 distinct)."""
        r = c + o
        if per:
            if n == 1:
                return (0 if o == 0 else -1), 0.0
            if r >= n:
                return r - n, length
            if r < 0:
                return r + n, -length
            return r, 0.0
        return (r if 0 <= r < n else -1), 0.0

    @jit
    def build_case(pos: np.ndarray, lo: np.ndarray, length: np.ndarray, periodic: np.ndarray, reach: float,
                   owner: np.ndarray, first: np.ndarray, neigh: np.ndarray) -> int:
        """Half neighbor list of one case, each pair within reach once (minimum image in periodic
        dims), written into owner (N,) int32, first (N+1,) int64 and neigh (capacity,) int32: the
        partners of atom owner[s] are neigh[first[s]:first[s+1]]. Returns the number of pairs, or
        -1 if neigh is too short (then call again with a longer one)."""
        N = pos.shape[0]
        first[0] = 0
        if N < 2:
            first[N] = 0
            return 0
        reach2 = reach * reach
        p = np.empty((N, 3))  # from lo, wrapped into [0, L) (periodic dims), or from the lowest atom
        ext = np.empty(3)
        nb = np.empty(3, np.int64)
        for k in range(3):
            if periodic[k]:
                L = length[k]
                for i in range(N):
                    v = pos[i, k] - lo[k]
                    v -= L * np.floor(v / L)
                    if not (0.0 <= v < L):
                        v = 0.0
                    p[i, k] = v
                ext[k] = L
            else:
                mn, mx = pos[0, k], pos[0, k]
                for i in range(N):
                    mn = min(mn, pos[i, k])
                    mx = max(mx, pos[i, k])
                for i in range(N):
                    p[i, k] = pos[i, k] - mn
                ext[k] = mx - mn
            # float first: a far-away atom (extent 1e60) must not overflow the int conversion
            nb[k] = max(1, int(min(ext[k] / (0.5 * reach), float(max(64, 2 * N)), 1048576.0)))
        while nb[0] * nb[1] * nb[2] > max(64, 2 * N):  # few atoms in a big box: fewer, wider cells
            k = 0 if nb[0] >= nb[1] and nb[0] >= nb[2] else (1 if nb[1] >= nb[2] else 2)
            nb[k] = max(1, nb[k] // 2)
        for k in range(3):  # offsets -2..2 must be 5 distinct cells in a periodic dim: else one cell
            if periodic[k] and nb[k] < 5:
                nb[k] = 1
        cell = np.empty(N, np.int64)
        ccoord = np.empty((N, 3), np.int64)
        for i in range(N):
            cid = 0
            for k in range(3):
                ck = int(p[i, k] / (ext[k] / nb[k])) if nb[k] > 1 else 0
                ck = min(max(ck, 0), nb[k] - 1)
                ccoord[i, k] = ck
                cid = cid * nb[k] + ck
            cell[i] = cid
        ncell = nb[0] * nb[1] * nb[2]
        cstart = np.zeros(ncell + 1, np.int64)
        for i in range(N):
            cstart[cell[i] + 1] += 1
        for q in range(ncell):
            cstart[q + 1] += cstart[q]
        fill = cstart[:-1].copy()
        order = owner  # atoms sorted by cell, ascending index within a cell
        xs = np.empty((N, 3))  # their positions p, contiguous per cell
        for i in range(N):
            s = fill[cell[i]]
            fill[cell[i]] += 1
            order[s] = i
            for k in range(3):
                xs[s, k] = p[i, k]
        # Half stencil: cell offsets (a, b, g) lexicographically after (0, 0, 0), and the atoms
        # after s in its own cell. Cells along z are contiguous in the sorted order, so each
        # (a, b) row is one range of sorted atoms, or two when it wraps a periodic z.
        n0, n1, n2 = nb[0], nb[1], nb[2]
        L0, L1, L2 = length[0], length[1], length[2]
        # a periodic dim of one cell: minimum image per pair, d -= rint(d / L) L; other dims
        # get 1/L = 0 there, so d is unchanged (no branch in the loop)
        inv0 = 1.0 / L0 if periodic[0] and n0 == 1 else 0.0
        inv1 = 1.0 / L1 if periodic[1] and n1 == 1 else 0.0
        inv2 = 1.0 / L2 if periodic[2] and n2 == 1 else 0.0
        per2 = periodic[2] and n2 > 1
        seg_lo = np.empty(32, np.int64)  # per cell: the sorted-atom ranges of its half stencil
        seg_hi = np.empty(32, np.int64)
        seg_sh = np.empty((32, 3))  # image shift of each range [length]
        cap = len(neigh)
        m = 0
        for q in range(ncell):
            if cstart[q] == cstart[q + 1]:
                continue
            c0, c1, c2 = q // (n1 * n2), (q // n2) % n1, q % n2
            nseg = 0
            for a in range(3):
                r0, sh0 = _cell_shift(c0, a, n0, periodic[0], L0)
                if r0 < 0:
                    continue
                for b in range(-2, 3):
                    if a == 0 and b < 0:
                        continue
                    r1, sh1 = _cell_shift(c1, b, n1, periodic[1], L1)
                    if r1 < 0:
                        continue
                    row = (r0 * n1 + r1) * n2
                    own = a == 0 and b == 0  # own row, the first: offsets g = 0 .. +2
                    z_lo = c2 if own or n2 == 1 else c2 - 2
                    z_hi = c2 if n2 == 1 else c2 + 2
                    seg_lo[nseg], seg_hi[nseg] = cstart[row + max(z_lo, 0)], cstart[row + min(z_hi, n2 - 1) + 1]
                    seg_sh[nseg, 0], seg_sh[nseg, 1], seg_sh[nseg, 2] = sh0, sh1, 0.0
                    nseg += 1
                    if per2 and z_hi >= n2:  # wraps above: cells 0 .. z_hi - n2, images at +L
                        seg_lo[nseg], seg_hi[nseg] = cstart[row], cstart[row + z_hi - n2 + 1]
                        seg_sh[nseg, 0], seg_sh[nseg, 1], seg_sh[nseg, 2] = sh0, sh1, L2
                        nseg += 1
                    if per2 and z_lo < 0:  # wraps below: cells n2 + z_lo .. n2 - 1, images at -L
                        seg_lo[nseg], seg_hi[nseg] = cstart[row + n2 + z_lo], cstart[row + n2]
                        seg_sh[nseg, 0], seg_sh[nseg, 1], seg_sh[nseg, 2] = sh0, sh1, -L2
                        nseg += 1
            for s in range(cstart[q], cstart[q + 1]):
                first[s] = m
                for g in range(nseg):
                    lo_t = s + 1 if g == 0 else seg_lo[g]  # own cell: the atoms after s
                    hi_t = seg_hi[g]
                    if m + hi_t - lo_t > cap:
                        return -1
                    y0, y1, y2 = xs[s, 0] - seg_sh[g, 0], xs[s, 1] - seg_sh[g, 1], xs[s, 2] - seg_sh[g, 2]
                    for t in range(lo_t, hi_t):
                        d0 = y0 - xs[t, 0]
                        d0 -= np.rint(d0 * inv0) * L0
                        d1 = y1 - xs[t, 1]
                        d1 -= np.rint(d1 * inv1) * L1
                        d2 = y2 - xs[t, 2]
                        d2 -= np.rint(d2 * inv2) * L2
                        neigh[m] = order[t]  # kept only if within reach (branch-free append)
                        m += d0 * d0 + d1 * d1 + d2 * d2 <= reach2
        first[N] = m
        return m

    @njit(nogil=True, error_model="numpy", inline="always")
    def _pair_terms(n, gx, gy, gz, tx, ty, tz, e24, s2c, rcut2, inv0, inv1, inv2, L0, L1, L2):
        """fpair d of n pairs from their raw separations g = x_i - x_j (contiguous buffers, no
        indirect access: the loop vectorises): the minimum image, then the NumPy path's operations
        (module docstring of `forces`), into t."""
        for k in range(n):
            d0 = gx[k]
            d0 -= np.rint(d0 * inv0) * L0
            d1 = gy[k]
            d1 -= np.rint(d1 * inv1) * L1
            d2 = gz[k]
            d2 -= np.rint(d2 * inv2) * L2
            r2 = d0 * d0 + d1 * d1 + d2 * d2
            inside = 1.0 if r2 < rcut2 else 0.0
            t = s2c / r2
            s6 = t * t * t
            fpair = (s6 * 2.0 - 1.0) * s6 * e24 / r2 * inside
            tx[k] = fpair * d0
            ty[k] = fpair * d1
            tz[k] = fpair * d2

    @jit
    def forces_case(xc: np.ndarray, fc: np.ndarray, ow: np.ndarray, fr: np.ndarray, nc: np.ndarray, e24: float,
                    s2c: float, rcut2: float, length: np.ndarray, periodic: np.ndarray) -> None:
        """Add the pair forces of one case (positions xc (N, 3), half list ow/fr/nc) into fc (N, 3).

        Per row s of the list (atom i = ow[s]), three passes: gather the separations x_i - x_j
        into contiguous buffers, compute fpair d for all of them in one vectorised loop
        (`_pair_terms`), then add them in list order: F_i += sum (one sum, added at the end of the
        row) and F_j -= each. The additions are the ones of a single fused loop in the same order,
        so the bits do not depend on the split."""
        inv0 = 1.0 / length[0] if periodic[0] else 0.0
        inv1 = 1.0 / length[1] if periodic[1] else 0.0
        inv2 = 1.0 / length[2] if periodic[2] else 0.0
        L0, L1, L2 = length[0], length[1], length[2]
        nrow = len(ow)
        most = 0
        for s in range(nrow):
            most = max(most, fr[s + 1] - fr[s])
        buf = np.empty((6, most))
        gx, gy, gz, tx, ty, tz = buf[0], buf[1], buf[2], buf[3], buf[4], buf[5]
        for s in range(nrow):
            i = ow[s]
            xi0, xi1, xi2 = xc[i, 0], xc[i, 1], xc[i, 2]
            k0 = fr[s]
            n = fr[s + 1] - k0
            for k in range(n):
                j = nc[k0 + k]
                gx[k] = xi0 - xc[j, 0]
                gy[k] = xi1 - xc[j, 1]
                gz[k] = xi2 - xc[j, 2]
            _pair_terms(n, gx, gy, gz, tx, ty, tz, e24, s2c, rcut2, inv0, inv1, inv2, L0, L1, L2)
            fi0, fi1, fi2 = 0.0, 0.0, 0.0
            for k in range(n):
                j = nc[k0 + k]
                a, b, c = tx[k], ty[k], tz[k]
                fi0 += a
                fi1 += b
                fi2 += c
                fc[j, 0] -= a
                fc[j, 1] -= b
                fc[j, 2] -= c
            fc[i, 0] += fi0
            fc[i, 1] += fi1
            fc[i, 2] += fi2

    @jit
    def outputs_case(xc: np.ndarray, ow: np.ndarray, fr: np.ndarray, nc: np.ndarray, e24: float, e4: float,
                     s2c: float, rcut2: float, off: float, length: np.ndarray, periodic: np.ndarray
                     ) -> tuple[float, float]:
        """Energy (shifted by off per pair inside rc) and virial sum fpair r^2 of one case, summed
        over the list in order (the per-pair values of `_pair_terms`)."""
        inv0 = 1.0 / length[0] if periodic[0] else 0.0
        inv1 = 1.0 / length[1] if periodic[1] else 0.0
        inv2 = 1.0 / length[2] if periodic[2] else 0.0
        L0, L1, L2 = length[0], length[1], length[2]
        esum, wsum = 0.0, 0.0
        for s in range(len(ow)):
            i = ow[s]
            for q in range(fr[s], fr[s + 1]):
                j = nc[q]
                d0 = xc[i, 0] - xc[j, 0]
                d0 -= np.rint(d0 * inv0) * L0
                d1 = xc[i, 1] - xc[j, 1]
                d1 -= np.rint(d1 * inv1) * L1
                d2 = xc[i, 2] - xc[j, 2]
                d2 -= np.rint(d2 * inv2) * L2
                r2 = d0 * d0 + d1 * d1 + d2 * d2
                inside = 1.0 if r2 < rcut2 else 0.0
                t = s2c / r2
                s6 = t * t * t
                fpair = (s6 * 2.0 - 1.0) * s6 * e24 / r2 * inside
                esum += ((s6 - 1.0) * s6 * e4 - off) * inside
                wsum += fpair * r2
        return esum, wsum

    @jit
    def forces(x: np.ndarray, f: np.ndarray, owner: np.ndarray, first: np.ndarray, neigh: np.ndarray,
               eps: np.ndarray, sig2: np.ndarray, rc2: np.ndarray, offset: np.ndarray, length: np.ndarray,
               periodic: np.ndarray, bad: np.ndarray, outputs: bool, energy: np.ndarray,
               virial: np.ndarray) -> None:
        """Add the pair forces of every case that is not bad into f (C, N, 3) (`forces_case`); with
        outputs, also energy[c] (shifted by offset[c] per pair inside rc) and virial[c] = sum
        fpair r^2 (`outputs_case`).

        Per pair, the NumPy path's operations: d = x_i - x_j, d -= rint(d (1/L)) L in periodic
        dims (bad cases are skipped, so d is finite), r2, s6 = ((sig2/r2)^2)(sig2/r2),
        fpair = (((2 s6) - 1) s6)(24 eps)/r2, times (r2 < rc2): computed for every listed pair,
        then zeroed outside rc (no branch).
        """
        for c in range(x.shape[0]):
            if bad[c]:
                continue
            forces_case(x[c], f[c], owner[c], first[c], neigh[c], 24.0 * eps[c], sig2[c], rc2[c], length, periodic)
            if outputs:
                energy[c], virial[c] = outputs_case(x[c], owner[c], first[c], neigh[c], 24.0 * eps[c], 4.0 * eps[c],
                                                    sig2[c], rc2[c], offset[c], length, periodic)
