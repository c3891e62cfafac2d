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

Fused chunks (`pair_chunk`, driven by `PairChunks`, attached by the engine when compiled.py's
own chunks decline because of the pair): a whole chunk of steps of one case in one call, the
step of engine.Engine.step (kick, drift, wrap, list check and rebuild, force clear, pair forces,
flat soft faces (wall/table faces too) and wall/region fixes with compiled.py's kernels, lost
atoms, kick, wall/flow with compiled.py's `_flow_step`), so no Python runs between steps. It
calls the very kernels of the per-step compiled path, so both give the same bits; trouble hands
the chunk back to NumPy. The samples of a chunk are recorded in it (`PairChunks.advance_sampled`:
the outputs of Engine.sample, with compiled.py's sample functions). It also runs, with
compiled.py's functions, the `fixes:` its kernels run (thermostats, enforce2d), wall/reflect faces
on fixed dimensions, and, for a case on one thread, reflect statistics, wall/reflect/stochastic
faces and fix dt/reset; wall/lepton faces with the scene's generated forces (compiled.pieces_for
with `extra`) when compiled.lepton_compiled_wanted says the run pays for their kernel. A run to a
simulated time fuses the steps before each landing step (`PairChunks.advance_to_time`). Not
fused: other fixes, the landing steps of time-based runs, dt/reset and thermostats in them.

One large case over threads (`_chunk_threaded`, THREAD_MIN_ATOMS atoms per thread at least):
the same step in pieces, with the list build (runs of cells, `build_threaded`) and the force pass
(runs of rows, `forces_threaded`) split over threads, and the rest of the step over runs of atoms;
the thermostats' sums over all atoms and the Langevin draws (atom after atom from the case's
stream) run between those parts, in the calling thread (`fix_phase`). Each atom gets its force
additions in the one-thread order (an addition to an atom an earlier part touches waits in a
log), so the results are those of one thread, bit for bit. The parts' kernel calls, one per part
and step, skip numba's typing of their arguments after the first (`backend.Repeated`: ~2 ms a call
otherwise).

All kernels are `@njit(cache=True)` without fastmath (results are reproducible) and take
C-contiguous arrays (float64 positions, int32/int64 lists, bool flags: one compiled signature each).
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import inspect
import math
import threading
import time
import weakref
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from wallbatch.engine import backend
from wallbatch.engine import compiled as _compiled
from wallbatch.engine import pages, threads
from wallbatch.engine.lj import lj_terms, min_image
from wallbatch.engine.state import landing_tol

try:  # numba is a dependency, but the NumPy path must keep working without it
    from numba import njit
except Exception:  # noqa: BLE001 - any import failure means "no compiled path"
    njit = None


# lj.py's per-pair arithmetic compiled into the build and force pass: part of the kernels' cache names
_FORMULA_KEY = hashlib.sha256((inspect.getsource(lj_terms) + inspect.getsource(min_image)).encode()).hexdigest()[:12]


def enabled() -> bool:
    """True if the compiled path may be used: numba imports and backend.use_numba()."""
    return njit is not None and backend.use_numba()


if njit is not None:
    jit = njit(cache=True, nogil=True, error_model="numpy")  # x/0 -> inf/nan as in NumPy
    _image = njit(nogil=True, error_model="numpy", inline="always")(min_image)
    _lj_pair = njit(nogil=True, error_model="numpy", inline="always")(lj_terms)

    def _keyed(fn: Any) -> Any:
        """fn jitted with its on-disk cache named by a digest of lj.py's `lj_terms` and
        `min_image` too: numba keys a cached function by its own file only, and these are compiled
        into the build and force pass (inlined), so an edit of them must not load a stale kernel."""
        return jit(_compiled._relink(fn, name=f"{fn.__name__}_{_FORMULA_KEY}"))

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

    # The binning of `build_case` in pieces that runs of atoms can do in threads (`bin_threaded`):
    # extent (min/max over the atoms in fixed dims) -> cells per dim -> each atom's cell and the
    # counts per cell of each run -> prefix sums -> scatter, each run its atoms in index order after
    # the runs before: the counting sort of one pass, bit for bit.

    @jit
    def _bin_extent(pos: np.ndarray, a_lo: int, a_hi: int, periodic: np.ndarray, mm: np.ndarray) -> None:
        """mm (2, 3) = the min and max of atoms a_lo .. a_hi - 1 in each fixed dim (inf and -inf for
        none), folded in atom order (min/max of the runs' folds, in run order, are those of one fold)."""
        for k in range(3):
            if a_lo >= a_hi:
                mm[0, k], mm[1, k] = np.inf, -np.inf
            elif not periodic[k]:
                mn, mx = pos[a_lo, k], pos[a_lo, k]
                for i in range(a_lo, a_hi):
                    mn = min(mn, pos[i, k])
                    mx = max(mx, pos[i, k])
                mm[0, k], mm[1, k] = mn, mx

    @jit
    def _bin_grid(mms: np.ndarray, lo: np.ndarray, length: np.ndarray, periodic: np.ndarray, reach: float,
                  N: int, base: np.ndarray, ext: np.ndarray, nb: np.ndarray) -> None:
        """The cell grid of N atoms from the runs' extents mms (runs, 2, 3) (`_bin_extent`): per
        dim the origin base (lo, or the lowest atom in fixed dims), the extent ext (L, or the
        atoms' spread) and the cells nb: floor(ext / (reach/2)) (at least 1; at most 2N cells in
        all, halving the widest dim; a periodic dim of fewer than 5 cells gets 1)."""
        for k in range(3):
            if periodic[k]:
                base[k], ext[k] = lo[k], length[k]
            else:
                mn, mx = mms[0, 0, k], mms[0, 1, k]
                for r in range(1, mms.shape[0]):
                    mn = min(mn, mms[r, 0, k])
                    mx = max(mx, mms[r, 1, k])
                base[k], ext[k] = mn, mx - mn
            # float first: a far-away atom (extent 1e60) must not overflow the int conversion
            nb[k] = max(1, int(min(ext[k] / (0.5 * reach), float(max(64, 2 * N)), 1048576.0)))
        while nb[0] * nb[1] * nb[2] > max(64, 2 * N):  # few atoms in a big box: fewer, wider cells
            k = 0 if nb[0] >= nb[1] and nb[0] >= nb[2] else (1 if nb[1] >= nb[2] else 2)
            nb[k] = max(1, nb[k] // 2)
        for k in range(3):  # offsets -2..2 must be 5 distinct cells in a periodic dim: else one cell
            if periodic[k] and nb[k] < 5:
                nb[k] = 1

    @jit
    def _bin_cells(pos: np.ndarray, a_lo: int, a_hi: int, periodic: np.ndarray, base: np.ndarray,
                   ext: np.ndarray, nb: np.ndarray, p: np.ndarray, cell: np.ndarray, count: np.ndarray) -> None:
        """For atoms a_lo .. a_hi - 1: p[i] = the position from base (wrapped into [0, L) in
        periodic dims), cell[i] = its cell (x slowest, z fastest), and count[q] (zeros in) += the
        atoms of cell q."""
        for k in range(3):  # dim by dim: loops that vectorise
            b = base[k]
            if periodic[k]:
                L = ext[k]
                for i in range(a_lo, a_hi):
                    v = pos[i, k] - b
                    v -= L * np.floor(v / L)
                    if not (0.0 <= v < L):
                        v = 0.0
                    p[i, k] = v
            else:
                for i in range(a_lo, a_hi):
                    p[i, k] = pos[i, k] - b
        for i in range(a_lo, a_hi):
            cid = 0
            for k in range(3):
                ck = int(p[i, k] / (ext[k] / nb[k])) if nb[k] > 1 else 0
                ck = min(max(ck, 0), nb[k] - 1)
                cid = cid * nb[k] + ck
            cell[i] = cid
        for i in range(a_lo, a_hi):
            count[cell[i] + 1] += 1

    @jit
    def _bin_starts(counts: np.ndarray, cstart: np.ndarray, fills: np.ndarray) -> None:
        """counts (runs, ncell + 1): run r's atoms of cell q at counts[r, q + 1]. cstart[q + 1] =
        the atoms of cells <= q (cstart[0] = 0), fills[r, q] = where run r's first atom of cell q
        goes (the runs in order within a cell)."""
        acc = 0
        cstart[0] = 0
        for q in range(fills.shape[1]):
            for r in range(counts.shape[0]):
                fills[r, q] = acc
                acc += counts[r, q + 1]
            cstart[q + 1] = acc

    @jit
    def _bin_scatter(p: np.ndarray, cell: np.ndarray, a_lo: int, a_hi: int, fill: np.ndarray, owner: np.ndarray,
                     xs: np.ndarray) -> None:
        """The counting sort's scatter of atoms a_lo .. a_hi - 1 in index order: atom i goes to
        slot fill[cell[i]] (then advanced), owner[slot] = i and xs[slot] = p[i]."""
        for i in range(a_lo, a_hi):
            s = fill[cell[i]]
            fill[cell[i]] = s + 1
            owner[s] = i
            xs[s, 0], xs[s, 1], xs[s, 2] = p[i, 0], p[i, 1], p[i, 2]

    @jit
    def _bin(pos: np.ndarray, lo: np.ndarray, length: np.ndarray, periodic: np.ndarray, reach: float,
             owner: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The cells of `build_case` (N >= 2 atoms): owner (N,) = the atoms sorted by cell (a
        counting sort, ascending index within a cell); returns their positions from lo (wrapped in
        periodic dims; from the lowest atom in fixed dims) in that order xs (N, 3), the cell starts
        cstart (ncell + 1,) into the sorted atoms and the cells per dim nb (3,). The pieces of
        `bin_threaded` on one run of atoms."""
        N = pos.shape[0]
        mms = np.zeros((1, 2, 3))
        _bin_extent(pos, 0, N, periodic, mms[0])
        base, ext, nb = np.empty(3), np.empty(3), np.empty(3, np.int64)
        _bin_grid(mms, lo, length, periodic, reach, N, base, ext, nb)
        ncell = nb[0] * nb[1] * nb[2]
        p = np.empty((N, 3))
        cell = np.empty(N, np.int64)
        counts = np.zeros((1, ncell + 1), np.int64)
        _bin_cells(pos, 0, N, periodic, base, ext, nb, p, cell, counts[0])
        cstart = np.empty(ncell + 1, np.int64)
        fills = np.empty((1, ncell), np.int64)
        _bin_starts(counts, cstart, fills)
        xs = np.empty((N, 3))
        _bin_scatter(p, cell, 0, N, fills[0], owner, xs)
        return xs, cstart, nb

    def _scan(xs: np.ndarray, cstart: np.ndarray, nb: np.ndarray, order: np.ndarray, length: np.ndarray,
              periodic: np.ndarray, reach: float, q_lo: int, q_hi: int, m0: int, cap: int, first: np.ndarray,
              neigh: np.ndarray, mark: np.ndarray, partners: bool) -> int:
        """The rows of the cells q_lo .. q_hi - 1 (`_bin`) of `build_case`'s list: first[s] for
        their sorted atoms s and their partners written into neigh from m0 on, not beyond cap; with
        a mark array (N,) (else of length 0), mark[j] = 1 for each atom the rows touch (their
        owners only unless `partners`), except partners in cells before q_hi (what `RowSplit`
        needs: those atoms' own rows are in these cells or before). Returns the end of the written
        pairs, or -1 if they do not fit."""
        reach2 = reach * reach
        marking = len(mark) > 0
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
        image = inv0 != 0.0 or inv1 != 0.0 or inv2 != 0.0
        seg_lo = np.empty(32, np.int64)  # per cell: the sorted-atom ranges of its half stencil
        seg_hi = np.empty(32, np.int64)
        seg_sh = np.empty((32, 3))  # image shift of each range [length]
        m = m0
        for q in range(q_lo, q_hi):
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
            # the partners of cell q are in cells before (c0 + 3) n1 n2 (offsets a <= 2 along the
            # slowest dim; a wrapped offset lands before q): mark them only if that passes q_hi
            mark_partners = marking and partners and (c0 + 3) * n1 * n2 > q_hi
            for s in range(cstart[q], cstart[q + 1]):
                first[s] = m
                for g in range(nseg):
                    lo_t = s + 1 if g == 0 else seg_lo[g]  # own cell: the atoms after s
                    hi_t = seg_hi[g]
                    if m + hi_t - lo_t > cap:
                        return -1
                    y0, y1, y2 = xs[s, 0] - seg_sh[g, 0], xs[s, 1] - seg_sh[g, 1], xs[s, 2] - seg_sh[g, 2]
                    if image:
                        for t in range(lo_t, hi_t):
                            d0 = _image(y0 - xs[t, 0], inv0, L0)
                            d1 = _image(y1 - xs[t, 1], inv1, L1)
                            d2 = _image(y2 - xs[t, 2], inv2, L2)
                            neigh[m] = order[t]  # kept only if within reach (branch-free append)
                            m += d0 * d0 + d1 * d1 + d2 * d2 <= reach2
                    else:  # no one-cell periodic dim: the image is d itself (d - rint(0 d) L = d)
                        for t in range(lo_t, hi_t):
                            d0 = y0 - xs[t, 0]
                            d1 = y1 - xs[t, 1]
                            d2 = y2 - xs[t, 2]
                            neigh[m] = order[t]
                            m += d0 * d0 + d1 * d1 + d2 * d2 <= reach2
                if marking:  # the atoms this row touches (`RowSplit`)
                    mark[order[s]] = 1
                    if mark_partners:
                        for k in range(first[s], m):
                            mark[neigh[k]] = 1
        return m

    _scan = _keyed(_scan)

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
        xs, cstart, nb = _bin(pos, lo, length, periodic, reach, owner)
        m = _scan(xs, cstart, nb, owner, length, periodic, reach, 0, len(cstart) - 1, 0, len(neigh), first, neigh,
                  np.empty(0, np.uint8), False)
        if m >= 0:
            first[N] = m
        return m

    build_case = _keyed(build_case)

    @njit(nogil=True, error_model="numpy", inline="always")
    def _pair_terms(n, gx, gy, gz, tx, ty, tz, te, tw, outputs, e24, e4, s2c, rcut2, off, inv0, inv1, inv2,
                    L0, L1, L2):
        """fpair d of n pairs from their raw separations g = x_i - x_j (contiguous buffers, no
        indirect access: the loop vectorises) into t: the minimum image (`_image`), then the
        pair terms (`_lj_pair`, lj.py's lj_terms); with outputs also each pair's energy into
        te and its virial fpair r^2 into tw (two loops: the branch stays out of the loop)."""
        if outputs:
            for k in range(n):
                d0 = _image(gx[k], inv0, L0)
                d1 = _image(gy[k], inv1, L1)
                d2 = _image(gz[k], inv2, L2)
                r2 = d0 * d0 + d1 * d1 + d2 * d2
                fpair, e = _lj_pair(r2, e24, e4, s2c, rcut2, off)
                tx[k] = fpair * d0
                ty[k] = fpair * d1
                tz[k] = fpair * d2
                te[k] = e
                tw[k] = fpair * r2
        else:
            for k in range(n):
                d0 = _image(gx[k], inv0, L0)
                d1 = _image(gy[k], inv1, L1)
                d2 = _image(gz[k], inv2, L2)
                r2 = d0 * d0 + d1 * d1 + d2 * d2
                fpair, _ = _lj_pair(r2, e24, e4, s2c, rcut2, off)
                tx[k] = fpair * d0
                ty[k] = fpair * d1
                tz[k] = fpair * d2

    @njit(nogil=True, error_model="numpy", inline="always")
    def _row_buffers(fr: np.ndarray, s_lo: int, s_hi: int, outputs: bool) -> np.ndarray:
        """Scratch for the rows s_lo .. s_hi - 1 (`_row_terms`): 6 (8 with outputs) buffers as long
        as the longest row."""
        most = 0
        for s in range(s_lo, s_hi):
            most = max(most, fr[s + 1] - fr[s])
        return np.empty((8 if outputs else 6, most))

    @njit(nogil=True, error_model="numpy", inline="always")
    def _images(length: np.ndarray, periodic: np.ndarray) -> tuple[float, float, float, float, float, float]:
        """(1/L or 0 in non-periodic dimensions, then L) per dimension: `_image`'s arguments."""
        return (1.0 / length[0] if periodic[0] else 0.0, 1.0 / length[1] if periodic[1] else 0.0,
                1.0 / length[2] if periodic[2] else 0.0, length[0], length[1], length[2])

    @njit(nogil=True, error_model="numpy", inline="always")
    def _row_terms(xc: np.ndarray, nc: np.ndarray, i: int, k0: int, n: int, buf: np.ndarray, outputs: bool,
                   e24: float, e4: float, s2c: float, rcut2: float, off: float,
                   img: tuple[float, float, float, float, float, float]) -> None:
        """One row of the half list (atom i, its n partners nc[k0:k0 + n]): gather the separations
        x_i - x_j into contiguous buffers, then compute the pair terms for all of them in one
        vectorised loop (`_pair_terms`; img: `_images`): forces into buf[3:6], with outputs
        energies and virials into buf[6:8]."""
        xi0, xi1, xi2 = xc[i, 0], xc[i, 1], xc[i, 2]
        gx, gy, gz = buf[0], buf[1], buf[2]
        for k in range(n):
            j = nc[k0 + k]
            gx[k] = xi0 - xc[j, 0]
            gy[k] = xi1 - xc[j, 1]
            gz[k] = xi2 - xc[j, 2]
        te, tw = (buf[6], buf[7]) if outputs else (buf[0], buf[0])
        _pair_terms(n, gx, gy, gz, buf[3], buf[4], buf[5], te, tw, outputs, e24, e4, s2c, rcut2, off, img[0], img[1],
                    img[2], img[3], img[4], img[5])

    @njit(nogil=True, error_model="numpy", inline="always")
    def _row_ew(buf: np.ndarray, n: int) -> tuple[float, float]:
        """A row's energy and virial sums, in list order (`_row_terms` with outputs)."""
        te, tw = buf[6], buf[7]
        er, wr = 0.0, 0.0
        for k in range(n):
            er += te[k]
            wr += tw[k]
        return er, wr

    @njit(nogil=True, error_model="numpy", inline="always")
    def _defer(lj: np.ndarray, lv: np.ndarray, q: int, qd: int, cut: int, j: int, a: float, b: float,
               c: float) -> tuple[int, int]:
        """Log the addition (a, b, c) to atom j (`forces_part`): upwards from q for j < cut, else
        downwards from qd - 1. Returns the log's new ends (q, qd)."""
        if j < cut:
            lj[q] = j
            lv[q, 0], lv[q, 1], lv[q, 2] = a, b, c
            return q + 1, qd
        qd -= 1
        lj[qd] = j
        lv[qd, 0], lv[qd, 1], lv[qd, 2] = a, b, c
        return q, qd

    def forces_case(xc: np.ndarray, fc: np.ndarray, ow: np.ndarray, fr: np.ndarray, nc: np.ndarray, e24: float,
                    e4: float, s2c: float, rcut2: float, off: float, length: np.ndarray, periodic: np.ndarray,
                    outputs: bool) -> tuple[float, float]:
        """Add the pair forces of one case (positions xc (N, 3), half list ow/fr/nc) into fc (N, 3);
        with outputs, return (energy, virial): the energy shifted by off per pair inside rc and
        the virial sum fpair r^2, each summed per row in list order, then the rows' sums in row
        order (else (0, 0)): the order `forces_threaded` keeps, so threads give the same bits.

        Per row s of the list (atom i = ow[s]), three passes: gather the separations x_i - x_j
        into contiguous buffers, compute the pair terms for all of them in one vectorised loop
        (`_pair_terms`), then add them in list order: F_i += sum (one sum, added at the end of the
        row) and F_j -= each. The additions are the ones of a single fused loop in the same order,
        so the bits do not depend on the split."""
        nrow = len(ow)
        buf = _row_buffers(fr, 0, nrow, outputs)
        img = _images(length, periodic)
        tx, ty, tz = buf[3], buf[4], buf[5]
        esum, wsum = 0.0, 0.0
        for s in range(nrow):
            i = ow[s]
            k0 = fr[s]
            n = fr[s + 1] - k0
            _row_terms(xc, nc, i, k0, n, buf, outputs, e24, e4, s2c, rcut2, off, img)
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
            if outputs:
                er, wr = _row_ew(buf, n)
                esum += er
                wsum += wr
        return esum, wsum

    forces_case = _keyed(forces_case)

    # ------------------------------------------------------------------ one case over threads
    # The list build and the force pass of one case cut in parts run by threads (`build_threaded`,
    # `forces_threaded`), with the bits of the one-thread kernels: the parts of the build are runs
    # of cells, their rows joined where the one-thread build writes them (`_join`); the
    # force pass keeps each atom's additions in list order (`RowSplit`, `forces_part`, `_replay_atoms`).

    @jit
    def _join(first: np.ndarray, neigh: np.ndarray, aside: np.ndarray, rs: np.ndarray, base: np.ndarray,
              dest: np.ndarray, k_lo: int, k_hi: int, s_lo: int, s_hi: int) -> None:
        """Join a threaded build (`build_threaded`): part p >= 1 wrote the rows rs[p] .. rs[p+1] - 1
        into aside[base[p]:...] (first[s] pointing there); its pairs go to neigh[dest[p]:dest[p+1]]
        after the parts before. This call copies the pairs bound for neigh[k_lo:k_hi] and moves
        first[s] for the rows s_lo <= s < s_hi (runs that threads do at once). The list is then
        the one-thread list."""
        for p in range(1, len(base)):
            a, b = max(k_lo, dest[p]), min(k_hi, dest[p + 1])
            shift = base[p] - dest[p]
            for k in range(a, b):
                neigh[k] = aside[k + shift]
            a, b = max(s_lo, rs[p]), min(s_hi, rs[p + 1])
            for s in range(a, b):
                first[s] -= shift

    @jit
    def _touch(ow: np.ndarray, fr: np.ndarray, nc: np.ndarray, s_lo: int, s_hi: int, mark: np.ndarray,
               partners: bool) -> None:
        """mark[j] = 1 for every atom the rows s_lo .. s_hi - 1 of a list touch (owner, and
        partner if `partners`)."""
        for s in range(s_lo, s_hi):
            mark[ow[s]] = 1
            if partners:
                for k in range(fr[s], fr[s + 1]):
                    mark[nc[k]] = 1

    def forces_part(xc: np.ndarray, fc: np.ndarray, ow: np.ndarray, fr: np.ndarray, nc: np.ndarray, s_lo: int,
                    s_hi: int, part: int, firstp: np.ndarray, mixed: np.ndarray, lj: np.ndarray, lv: np.ndarray,
                    q0: int, q1: int, cut: int, e24: float,
                    e4: float, s2c: float, rcut2: float, off: float, length: np.ndarray, periodic: np.ndarray,
                    outputs: bool, rowew: np.ndarray) -> tuple[int, int]:
        """The rows s_lo .. s_hi - 1 of `forces_case`, part `part` of a `RowSplit`: each pair's
        terms and each row's sum as there; an addition to an atom this part touches first (firstp)
        goes into fc at once, any other waits in the log (lj: the atom, lv: the value added, from
        q0 on for atoms j < cut, from q1 - 1 down for the others, so that a thread replaying the
        atoms below cut or those above reads only theirs; mixed[s] (`_mixed`) says which rows have
        partners, or an owner, of other parts) for `_replay_atoms`, which adds it after the parts
        before. With outputs, rowew[s] = the row's energy and virial sums (as forces_case's;
        `_row_sums` adds them in row order).
        Returns the ends of the log written: (up, down).
        Parts run at once in threads: each writes only its own atoms of fc and its own rows."""
        buf = _row_buffers(fr, s_lo, s_hi, outputs)
        img = _images(length, periodic)
        tx, ty, tz = buf[3], buf[4], buf[5]
        q, qd = q0, q1
        for s in range(s_lo, s_hi):
            i = ow[s]
            k0 = fr[s]
            n = fr[s + 1] - k0
            _row_terms(xc, nc, i, k0, n, buf, outputs, e24, e4, s2c, rcut2, off, img)
            fi0, fi1, fi2 = 0.0, 0.0, 0.0
            ms = mixed[s]
            if ms & 1:  # some partner is another part's first: its additions wait in the log
                for k in range(n):
                    j = nc[k0 + k]
                    a, b, c = tx[k], ty[k], tz[k]
                    fi0 += a
                    fi1 += b
                    fi2 += c
                    if firstp[j] == part:
                        fc[j, 0] -= a
                        fc[j, 1] -= b
                        fc[j, 2] -= c
                    else:  # x - a and x + (-a) are the same number
                        q, qd = _defer(lj, lv, q, qd, cut, j, -a, -b, -c)
            else:  # forces_case's loop
                for k in range(n):
                    j = nc[k0 + k]
                    a, b, c = tx[k], ty[k], tz[k]
                    fi0 += a
                    fi1 += b
                    fi2 += c
                    fc[j, 0] -= a
                    fc[j, 1] -= b
                    fc[j, 2] -= c
            if ms & 2:  # the owner is another part's first
                q, qd = _defer(lj, lv, q, qd, cut, i, fi0, fi1, fi2)
            else:
                fc[i, 0] += fi0
                fc[i, 1] += fi1
                fc[i, 2] += fi2
            if outputs:
                rowew[s, 0], rowew[s, 1] = _row_ew(buf, n)
        return q, qd

    forces_part = _keyed(forces_part)

    @jit
    def _first_marks(marks: np.ndarray, a_lo: int, a_hi: int, firstp: np.ndarray) -> None:
        """firstp[j] = the first part p with marks[p, j] (0 if none), for a_lo <= j < a_hi."""
        parts = marks.shape[0]
        for j in range(a_lo, a_hi):
            firstp[j] = 0
        for p in range(parts - 1, -1, -1):
            for j in range(a_lo, a_hi):
                if marks[p, j]:
                    firstp[j] = p

    @jit
    def _row_sums(rowew: np.ndarray) -> tuple[float, float]:
        """The energy and virial of `forces_part`'s rows (rowew (rows, 2)), added in row order: the
        bits of `forces_case`'s sums."""
        esum, wsum = 0.0, 0.0
        for s in range(rowew.shape[0]):
            esum += rowew[s, 0]
            wsum += rowew[s, 1]
        return esum, wsum

    @jit
    def _mixed(fr: np.ndarray, nc: np.ndarray, ow: np.ndarray, runs: np.ndarray, rb: np.ndarray,
               firstp: np.ndarray, mixed: np.ndarray, room: np.ndarray) -> None:
        """For the rows of runs (k, 2) (each [s_lo, s_hi)): mixed[s] = 1 if some partner of row s
        is first touched by a part before the row's own (rows rb[p] .. rb[p+1] - 1 are part p's),
        + 2 if its owner is (0: the row adds everything at once);
        room[p] += the additions part p's rows here log in `forces_part` (partners and owners
        whose first part is another): its exact log length."""
        for r in range(runs.shape[0]):
            s_lo, s_hi = runs[r, 0], runs[r, 1]
            if s_lo >= s_hi:
                continue
            p = 0
            while rb[p + 1] <= s_lo:
                p += 1
            for s in range(s_lo, s_hi):
                while rb[p + 1] <= s:
                    p += 1
                m = 0
                for k in range(fr[s], fr[s + 1]):
                    m += firstp[nc[k]] != p
                own = firstp[ow[s]] != p
                mixed[s] = (m > 0) | (own << 1)
                room[p] += m + own

    @jit
    def _replay_atoms(fc: np.ndarray, lj: np.ndarray, lv: np.ndarray, starts: np.ndarray, ends: np.ndarray,
                      tops: np.ndarray, downs: np.ndarray, a_lo: int, a_hi: int) -> None:
        """Add the logged additions of the parts (`forces_part`; part p's at starts[p] .. ends[p] - 1
        upwards, then at tops[p] - 1 .. downs[p] downwards: written in that order) to the atoms
        a_lo <= j < a_hi into fc, part after part, each in order (threads replay their own atoms at
        once; an atom's additions are all in one of the two runs of a part)."""
        for p in range(len(starts)):
            for q in range(starts[p], ends[p]):
                j = lj[q]
                if a_lo <= j < a_hi:
                    fc[j, 0] += lv[q, 0]
                    fc[j, 1] += lv[q, 1]
                    fc[j, 2] += lv[q, 2]
            for q in range(tops[p] - 1, downs[p] - 1, -1):
                j = lj[q]
                if a_lo <= j < a_hi:
                    fc[j, 0] += lv[q, 0]
                    fc[j, 1] += lv[q, 1]
                    fc[j, 2] += lv[q, 2]

    def forces(x: np.ndarray, f: np.ndarray, owner: np.ndarray, first: np.ndarray, neigh: np.ndarray,
               eps: np.ndarray, sig2: np.ndarray, rc2: np.ndarray, offset: np.ndarray, length: np.ndarray,
               periodic: np.ndarray, bad: np.ndarray, outputs: bool, energy: np.ndarray,
               virial: np.ndarray) -> None:
        """Add the pair forces of every case that is not bad into f (C, N, 3) (`forces_case`); with
        outputs, also energy[c] (shifted by offset[c] per pair inside rc) and virial[c] = sum
        fpair r^2, in the same pass.

        Per pair, the NumPy path's operations: d = x_i - x_j, d -= rint(d (1/L)) L in periodic
        dims (bad cases are skipped, so d is finite), then lj.py's lj_terms: r2,
        s6 = ((sig2/r2)^2)(sig2/r2), fpair = (((2 s6) - 1) s6)(24 eps)/r2, times (r2 < rc2):
        computed for every listed pair, then zeroed outside rc (no branch).
        """
        for c in range(x.shape[0]):
            if bad[c]:
                continue
            e, w = forces_case(x[c], f[c], owner[c], first[c], neigh[c], 24.0 * eps[c], 4.0 * eps[c], sig2[c],
                               rc2[c], offset[c], length, periodic, outputs)
            if outputs:
                energy[c], virial[c] = e, w

    forces = _keyed(forces)


# ----------------------------------------------------------------------------- fused pair chunks
# Whole chunks of steps of a pair scene in one compiled call per case (a long chunk in several of
# `KernelPath.call_steps` steps; PairChunks below): the step of engine.Engine.step with the pair
# forces of `forces_case` and the wall forces of the chunk kernels of engine/compiled.py (the
# registry's compiled functions, imported, not copied).

if njit is not None:
    from wallbatch.engine.compiled import BLOCK

    def _soft_face(*args):  # noqa: ANN002, ANN202 - placeholders: pair_chunk_for links the scene's pieces
        raise NotImplementedError

    _region_walls = _flow_step = _sample_faces = _sample_regions = _table_faces = _stochastic_faces = _soft_face
    _vector_faces = _soft_face
    # what a scene's pair chunk compiles (`pair_chunk_for`: False leaves that code out, numba prunes it)
    _K_FIXES = _K_REFLECT = _K_DTR = _K_VECTOR = True
    TABLE_STYLE = _compiled.TABLE_STYLE
    _mv2_sum, _take_stats = _compiled._mv2_sum, _compiled._take_stats  # a sample's sum m v^2, reflect statistics
    # the `fixes:` of compiled.py's chunks (thermostats, enforce2d) and their state at a sample
    _fix_pre, _fix_post_force, _fix_end = _compiled._fix_pre, _compiled._fix_post_force, _compiled._fix_end
    _langevin_setup, _sample_fixes = _compiled._langevin_setup, _compiled._sample_fixes
    _reflect_face = _compiled._reflect_face  # wall/reflect
    _dt_candidate, _group_low, _clamp = _compiled._dt_candidate, _compiled._group_low, _compiled._clamp  # dt/reset

    @jit
    def _moved(xc: np.ndarray, xref: np.ndarray, length: np.ndarray, periodic: np.ndarray, limit2: float) -> bool:
        """Some atom of one case moved more than sqrt(limit2) since xref (`moved_cases`)."""
        for i in range(xc.shape[0]):
            d2 = 0.0
            for k in range(3):
                d = xc[i, k] - xref[i, k]
                if periodic[k]:
                    d -= length[k] * np.rint(d / length[k])
                d2 += d * d
            if not d2 <= limit2:
                return True
        return False

    @njit(nogil=True, error_model="numpy", inline="always")
    def _drift(x: np.ndarray, v: np.ndarray, f: np.ndarray, dtfm: np.ndarray, dt: float, lo: np.ndarray,
               hi: np.ndarray, box_per: np.ndarray, moving: np.ndarray) -> None:
        """initial_integrate (v += dtfm f, x += dt v) of the integrated atoms (moving[a] != 0;
        an empty `moving`: every atom) and the periodic wrap of one case."""
        N = x.shape[0]
        every = moving.shape[0] == 0
        for a in range(N):
            if every or moving[a] != 0:
                for d in range(3):
                    va = v[a, d] + dtfm[a] * f[a, d]
                    v[a, d] = va
                    x[a, d] = x[a, d] + dt * va
        for d in range(3):
            if box_per[d]:
                lod, hid = lo[d], hi[d]
                L = hid - lod
                for a in range(N):
                    xa = x[a, d]
                    xa = xa - L if xa >= hid else xa
                    x[a, d] = xa + L if xa < lod else xa

    @njit(nogil=True, error_model="numpy", inline="always")
    def _copy_atoms(dst: np.ndarray, src: np.ndarray) -> None:
        """dst[:] = src for (N, 3) arrays, as a plain loop: numba compiles an array-to-array slice
        assignment with its shape-mismatch message (str, repr, join: ~5 s of a first compile)."""
        for a in range(src.shape[0]):
            for d in range(3):
                dst[a, d] = src[a, d]

    @njit(nogil=True, error_model="numpy", inline="always")
    def _finite(x: np.ndarray) -> bool:
        for a in range(x.shape[0]):
            for d in range(3):
                if not math.isfinite(x[a, d]):
                    return False
        return True

    @njit(nogil=True, error_model="numpy", inline="always")
    def _dt_candidates(v: np.ndarray, f: np.ndarray, mass: np.ndarray, ftm2v: float, mvv2e: float, xmax: float,
                       emax: float, VF: np.ndarray, CAND: np.ndarray) -> None:
        """fix dt/reset: each atom's largest dt (`_dt_candidate`, compiled.py's) into CAND, block by
        block: a block's v and f are copied to the (6, BLOCK) scratch VF first, so the candidate
        loop reads rows and vectorises (~4x faster than reading the (N, 3) arrays; the same bits)."""
        N = v.shape[0]
        for u0 in range(0, N, BLOCK):
            n = min(BLOCK, N - u0)
            for i in range(n):
                for d in range(3):
                    VF[d, i] = v[u0 + i, d]
                    VF[3 + d, i] = f[u0 + i, d]
            cb, mb = CAND[u0:u0 + n], mass[u0:u0 + n]  # (views: indices from 0 vectorise, `u0 + i` does not)
            for i in range(n):
                cb[i] = _dt_candidate(VF[0, i], VF[1, i], VF[2, i], VF[3, i], VF[4, i], VF[5, i], mb[i], ftm2v,
                                      mvv2e, xmax, emax)

    @jit
    def _dtfm(mass: np.ndarray, dt: float, ftm2v: float) -> np.ndarray:
        """dt/2 ftm2v / m per atom: `pair_chunk`'s, the same bits."""
        hdt = (0.5 * ftm2v) * dt
        out = np.empty(len(mass))
        for a in range(len(mass)):
            out[a] = hdt / mass[a]
        return out

    def _pre_step(x: np.ndarray, v: np.ndarray, f: np.ndarray, dtfm: np.ndarray, dt: float, lo: np.ndarray,
                  hi: np.ndarray, box_per: np.ndarray, xref: np.ndarray, length: np.ndarray, pair_per: np.ndarray,
                  limit2: float, rf_meta: np.ndarray, rf_row: np.ndarray, rf_prev: np.ndarray, mass: np.ndarray,
                  groups: np.ndarray, ftm2v: float, mrow: int) -> int:
        """The first half of `pair_chunk`'s step for `_chunk_threaded` on a run of atoms: drift and
        wrap (of the integrated atoms: group row mrow, -1 every atom), the wall/reflect faces
        (rf_meta rows, this step's coords rf_row, the last step's rf_prev: `pair_chunk`'s calls of
        `_reflect_face`, without statistics; none: 0 rows), then 0 (the list holds), 1 (rebuild it)
        or 3 (a non-finite position); f is cleared (after the drift)."""
        _drift(x, v, f, dtfm, dt, lo, hi, box_per, groups[mrow] if mrow >= 0 else groups[0, :0])
        X, V = x.T, v.T
        RS = np.zeros((1, rf_meta.shape[0], 2))  # (no statistics: untouched)
        for k in range(rf_meta.shape[0]):  # wall/reflect (post_integrate)
            coord = rf_row[k]
            vwall = (coord - rf_prev[k]) / dt if dt > 0 else 0.0
            _reflect_face(rf_meta[k, 0], rf_meta[k, 1], rf_meta[k, 2] == 1, rf_meta[k, 3], coord, vwall, False, 0, k,
                          X, V, mass, groups, RS, ftm2v, 0, x.shape[0])
        status = 0
        if _moved(x, xref, length, pair_per, limit2):
            status = 1 if _finite(x) else 3
        f[:] = 0.0
        return status

    def _make_pair_chunk(fingerprint: int):
        """The fused chunk kernel; `fingerprint` joins its on-disk cache key (numba keys a cached
        function by its own file: the wall kernels come from compiled.py and the styles)."""

        @jit
        def pair_chunk(nsteps, post, x, v, f, mass, radius, dt, ftm2v, lo, hi, box_per, length, pair_per, reach,
                       limit2, lj, sample, fpair, ew, xref, owner, first, neigh, spare, sf_meta, sf_val, groups, rg,
                       fl, fix, rfl, tb, lp, sto, dtr, sm):
            """Advance one case (x, v, f: (N, 3), written in place) by nsteps velocity-Verlet steps
            of engine.Engine.step: v += dtfm f, x += dt v; periodic wrap; the pair list rebuilt
            (`build_case`) when an atom moved more than skin/2 since xref; f = 0, pair forces
            (`forces_case`), soft flat faces and wall/region fixes (compiled.py's kernels), lost
            atoms; v += dtfm f; wall/flow. With `sample`, the last step's pair pass
            also gives the pair energy and virial (ew[0], ew[1]) and its pair forces are copied to
            fpair (N, 3) (the outputs of that step, without a second pass). With `post` only the
            rest of the step after the pair forces (already in f): walls, lost atoms, final_integrate
            and wall/flow (`_chunk_threaded` runs the first part). Returns (status, builds, neigh):
            status 0, 1 (an atom on/behind a wall), 2 (a lost atom) or 3 (a non-finite value; the
            caller then hands the chunk back to NumPy); neigh is the list after the chunk: the caller's
            (not written) if no build ran, else `spare` (the first build writes there, so the
            caller's list survives a chunk handed back) or a longer array when the list grew.

            lj = (24 eps, 4 eps, sigma^2, rc^2, energy offset): the pair's parameters (`forces_case`).

            rg = (rg_meta, rg_geo, rg_val): the wall/region fixes (compiled.FastPath._regions, this
            case's row of rg_val). fl = (fl_int, fl_f, fl_walls, fl_grp, fl_phys, fl_pend, fl_prev,
            fl_cross, fl_rng): the case's wall/flow fix (compiled.py's `_flow_step`; fl_int[0] = 0: none).

            fix = (fx, fx_rng, step0, fb): the case's `fixes:` (compiled.py's `_fix_arrays` of this case
            alone, row 0; its Langevin generator), run as compiled.py's kernels run them: `_fix_pre` before the
            drift (fix nvt's first half step, the Langevin random forces), `_fix_post_force` after
            the walls (Langevin forces, enforce2d), `_fix_end` after the final kick (fix nvt's
            second half step, temp/berendsen, temp/rescale, the tally; status 6: a zero
            temperature). step0: the case's step count before the chunk (ramps, temp/rescale's
            every). fb: the per-atom buffers of the fixes (`fix_buffers`, N rows; none without
            fixes). With `post` only `_fix_post_force`, on the part's rows of fb: `_chunk_threaded`
            runs the rest on the whole case (`fix_phase`).

            rfl = (rf_meta, rf_val, rf_prev, rf_stat, stats): the case's wall/reflect faces (compiled.py's
            `_reflect_arrays`; rf_val (S or 1, K): each face's coord per step), reflected after the
            drift and wrap (`chunk_eligible`: on fixed dimensions, where the wrap does not act) by
            compiled.py's `_reflect_face` with the face's velocity over the step; with `stats` the
            reflections and impulse added to rf_stat. Not with `post` either.

            tb: the wall/table faces' tables (compiled.py's `_tables` and a scratch of N bytes
            rounded up to 64: `_table_faces`, style TABLE_STYLE in sf_meta).

            lp (K, P): this case's parameters of the wall/lepton faces whose generated force takes
            them as an array (compiled.py's `_lepton_rows`; style -2 - j in sf_meta: `_vector_faces`);
            other wall/lepton faces are styles of `_soft_face` (the scene's generated dispatch).

            sto = (st_meta, st_val, st_stat, st_flag, st_rng, mvv2e): wall/reflect/stochastic fixes
            (compiled.py's `_stochastic_arrays` of this case, row 0; their generators), after the
            wall/reflect faces (`_stochastic_faces`; faces on fixed dimensions); mvv2e: the units'
            m v^2 to energy.

            dtr = (dtr_every, dtr_group, dtr_par (xmax, emax, tmin, tmax), clk): fix dt/reset (every 0: none),
            at the end of each due step (engine.Engine.reset_dt: compiled.py's `_dt_candidate` per
            atom, the group's minimum, `_clamp`); a new dt closes the time accumulator as
            BatchState.set_dt does. clk (in and out): dt, atime, atimestep of the case.

            sm = (at, mv2, clock, face, rstat, acc, chain, cross, reg, ew): samples recorded in the kernel
            (`PairChunks.advance_sampled`; compiled.py's `_sample_arrays` of this case, then the pair's
            energy and virial (S, 2); at (S,) empty: none). After step at[k] (steps of this
            chunk, counted from 1) the outputs of Engine.sample go to row k: sum m v^2, the pair
            energy and virial of that step's pair pass, each soft face's (energy, force on the wall,
            virial) and each wall/region fix's (energy, force x y z, virial) (compiled.py's
            `_sample_faces` and `_sample_regions`, the flat chunks' own), the flow redraws since the
            last sample, the fixes' state for ecouple (`_sample_fixes`), the reflect statistics
            since the last sample (take_stats) and the clock (step, dt, atime, atimestep)."""
            if nsteps == -fingerprint:  # never: ties the on-disk cache to the wall kernels
                return 5, 0, neigh
            N = x.shape[0]
            e24, e4, s2c, rcut2, off = lj
            rg_meta, rg_geo, rg_val = rg
            fl_int, fl_f, fl_walls, fl_grp, fl_phys, fl_pend, fl_prev, fl_cross, fl_rng = fl
            X, V, F = x.T, v.T, f.T  # (3, N) views: the wall kernels' layout
            dtfm = _dtfm(mass, dt, ftm2v)
            vary = sf_val.shape[0] > 1
            RB = np.empty((6, 5, BLOCK))
            CI = np.empty(N if fl_int[0] != 0 else 0, np.int64)
            DIR = np.empty(N if fl_int[0] != 0 else 0)
            fx, fx_rng, step0, fb = fix
            mrow = fx[11][2]  # the integrated atoms' group row (-1: every atom)
            moving = groups[mrow] if mrow >= 0 else groups[0, :0]
            nmov = moving.shape[0]
            rf_meta, rf_val, rf_prev, rf_stat, stats = rfl
            st_meta, st_val, st_stat, st_flag, st_rng, mvv2e = sto
            dtr_every, dtr_group, dtr_par, clk = dtr
            sm_at, sm_mv2, sm_clock, sm_face, sm_rstat, sm_fx, sm_chain, sm_cross, sm_reg, sm_ew = sm
            CAND = np.empty(N if dtr_every > 0 else 0)  # fix dt/reset: each atom's largest dt
            VF = np.empty((6, BLOCK if dtr_every > 0 else 0))  # and a block's v, f (`_dt_candidates`)
            nrf, nst = rf_meta.shape[0], st_meta.shape[0]
            ST = (st_meta, st_val, st_stat, st_flag, st_rng, np.empty(N if nst else 0, np.int64),
                  np.empty((4, N if nst else 0)))  # `_stochastic_faces`' arguments and scratch
            RS = np.zeros((1, nrf, 2))  # one step's reflect statistics (`_reflect_face`'s rstat)
            rvary = rf_val.shape[0] > 1
            nsm, ism = sm_at.shape[0], 0
            KS = np.empty(N if nsm else 0)  # m v^2 per atom at a sample
            RBS = np.empty((6, 5, N if nsm and rg_meta.shape[0] else 0))  # a case's region contacts at a sample
            SF = sf_val.reshape((1, sf_val.shape[0], sf_val.shape[1], sf_val.shape[2]))  # `_sample_faces`' (C, S, K, 6)
            LP = lp.reshape((1, lp.shape[0], lp.shape[1]))  # `_sample_faces`' (C, K, P)
            fx_meta = fx[0]
            nfx = N if fx_meta.shape[0] else 0
            thermo = False  # a fix that couples the atoms (not enforce2d alone)
            # `fix_buffers(nfx, L)`: sqrt(m), each langevin fix's drag, random and whole forces, scratch
            SQM, G1a, FRa, FLa, KB = fb
            G1, FR, FL = G1a.T, FRa.T, FLa.T  # (L, nfx) and (3 L, nfx) views, as V and F
            if _K_FIXES:  # (an `if` on the flag: numba prunes the branch, a scene without fixes compiles none of it)
                for k in range(fx_meta.shape[0]):
                    thermo = thermo or fx_meta[k, 0] != _compiled.FIX_ENFORCE2D
                if G1.shape[0]:
                    _langevin_setup(0, mass, fx, ftm2v, SQM, G1)
            fxp = (fx_meta, G1, FR, FL)
            builds = 0
            e, w = 0.0, 0.0
            for step in range(nsteps):
                si = step if vary else 0
                due = ism < nsm and step + 1 == sm_at[ism]  # a sample recorded here
                if _K_FIXES:
                    if thermo and not post:  # fix nvt's first half step, the Langevin random forces
                        _fix_pre(0, step0 + step + 1, dt, clk[1], clk[2], V, mass, groups, fx, fx_rng, SQM, FR, KB)
                if not post:  # post: the pair forces of this step are in f (`_chunk_threaded`)
                    _drift(x, v, f, dtfm, dt, lo, hi, box_per, moving)
                    if _K_REFLECT:
                        for k in range(nrf):  # wall/reflect (post_integrate)
                            coord = rf_val[step if rvary else 0, k]
                            vwall = (coord - rf_prev[k]) / dt if dt > 0 else 0.0
                            RS[0, k, 0] = 0.0
                            RS[0, k, 1] = 0.0
                            _reflect_face(rf_meta[k, 0], rf_meta[k, 1], rf_meta[k, 2] == 1, rf_meta[k, 3], coord,
                                          vwall, stats, 0, k, X, V, mass, groups, RS, ftm2v, 0, N)
                            rf_prev[k] = coord
                            rf_stat[k, 0] += RS[0, k, 0]
                            rf_stat[k, 1] += RS[0, k, 1]
                        if nst:  # wall/reflect/stochastic (post_integrate, after the wall/reflect fixes)
                            _stochastic_faces(0, 0, N, X, V, mass, groups, ST, ftm2v, mvv2e)
                    if _moved(x, xref, length, pair_per, limit2):  # neighbor list (check yes)
                        if not _finite(x):
                            return 3, builds, neigh
                        target = neigh if builds > 0 else spare
                        m = build_case(x, lo, length, pair_per, reach, owner, first, target)
                        while m < 0:
                            target = np.empty(2 * len(target) + 4 * N, np.int32)
                            m = build_case(x, lo, length, pair_per, reach, owner, first, target)
                        neigh = target
                        _copy_atoms(xref, x)
                        builds += 1
                    f[:] = 0.0  # force clear, pair forces
                    last = sample and step == nsteps - 1
                    e, w = forces_case(x, f, owner, first, neigh, e24, e4, s2c, rcut2, off, length, pair_per,
                                       last or due)
                    if last:
                        ew[0], ew[1] = e, w
                        _copy_atoms(fpair, f)
                nbad = 0
                for k in range(sf_meta.shape[0]):  # soft flat walls, fix order
                    if sf_meta[k, 0] == TABLE_STYLE:  # wall/table: the face's table from tb (data, not code)
                        nbad += _table_faces(tb, k, X, F, groups, sf_meta[k, 3], sf_meta[k, 1], sf_meta[k, 2],
                                             sf_val[si, k, 0], sf_val[si, k, 4], 0, N)
                    elif _K_VECTOR and sf_meta[k, 0] < TABLE_STYLE:  # wall/lepton, parameters as an array
                        nbad += _vector_faces(-2 - sf_meta[k, 0], X, F, radius, groups, sf_meta[k, 3], sf_meta[k, 1],
                                              sf_meta[k, 2], sf_val[si, k, 0], lp[k], sf_val[si, k, 4], 0, N)
                    else:
                        nbad += _soft_face(sf_meta[k, 0], sf_meta[k, 4], X, F, radius, groups, sf_meta[k, 3],
                                           sf_meta[k, 1], sf_meta[k, 2], sf_val[si, k, 0], sf_val[si, k, 1],
                                           sf_val[si, k, 2], sf_val[si, k, 3], sf_val[si, k, 4], sf_val[si, k, 5], 0,
                                           N)
                if rg_meta.shape[0]:  # wall/region fixes, block by block
                    for u0 in range(0, N, BLOCK):
                        nbad += _region_walls(0, u0, min(u0 + BLOCK, N), X, F, radius, groups, rg_meta, rg_geo,
                                              rg_val, RB)
                if nbad:
                    return 1, builds, neigh
                if _K_FIXES:
                    if nfx:  # post_force fixes: Langevin forces, enforce2d
                        _fix_post_force(0, N, V, F, groups, fxp)
                for d in range(3):  # lost atoms
                    if not box_per[d]:
                        for a in range(N):
                            if (x[a, d] < lo[d]) | (x[a, d] > hi[d]):
                                return 2, builds, neigh
                for a in range(N):  # final_integrate (of the integrated atoms)
                    if nmov == 0 or moving[a] != 0:
                        for d in range(3):
                            v[a, d] = v[a, d] + dtfm[a] * f[a, d]
                if _K_FIXES:
                    # fix nvt's second half step, temp/berendsen, temp/rescale, the tally; also in the
                    # tail of a case over threads with wall/flow (post, all atoms): before the flow walls,
                    # and in a sample step's tail on all atoms (fx_int[0] = 1, `_chunk_steps`)
                    if thermo and (not post or fl_int[0] != 0 or fx[11][0] != 0):
                        if _fix_end(0, step0 + step + 1, dt, clk[1], clk[2], V, mass, groups, fx, KB, FL) != 0:
                            return 6, builds, neigh
                if fl_int[0] != 0:  # fix wall/flow (end_of_step)
                    _flow_step(X, V, mass, fl_int, fl_f, fl_walls, fl_grp, fl_phys, fl_pend, fl_prev, fl_cross,
                               fl_rng, CI, DIR)
                now = step0 + step + 1  # the case's step count after this step
                if _K_DTR:
                    if dtr_every > 0 and now % dtr_every == 0:  # fix dt/reset (end_of_step)
                        _dt_candidates(v, f, mass, ftm2v, mvv2e, dtr_par[0], dtr_par[1], VF, CAND)
                        new = _clamp(_group_low(CAND, groups, dtr_group, 0, N), N, dtr_par)
                        if new != dt:  # BatchState.set_dt
                            clk[1] = clk[1] + (now - clk[2]) * dt
                            clk[2] = now
                            dt = new
                            dtfm = _dtfm(mass, dt, ftm2v)
                if due:  # the outputs of Engine.sample at this step (positions are the force pass's)
                    _sample_faces(0, si, X, radius, groups, sf_meta, SF, tb, LP, sm_face[ism])
                    if rg_meta.shape[0]:
                        _sample_regions(0, X, radius, groups, rg_meta, rg_geo, rg_val, RBS, sm_reg[ism])
                    sm_mv2[ism] = _mv2_sum(mass, V, KS, N)
                    sm_ew[ism, 0] = e
                    sm_ew[ism, 1] = w
                    if fl_int[0] != 0:  # flow redraws since the last sample (take_crossings)
                        sm_cross[ism] = fl_cross[0]
                        fl_cross[0] = 0.0
                    if _K_FIXES:
                        _sample_fixes(0, fx, sm_fx[ism], sm_chain[ism])
                    if _K_REFLECT:  # reflect statistics since the last sample
                        _take_stats(rf_stat, sm_rstat[ism], 0)
                        if st_flag[0] != 0:  # wall/reflect/stochastic's, after them
                            _take_stats(st_stat[0], sm_rstat[ism], nrf)
                    sm_clock[ism, 0] = now
                    sm_clock[ism, 1] = dt
                    sm_clock[ism, 2] = clk[1]
                    sm_clock[ism, 3] = clk[2]
                    ism += 1
            for a in range(N):
                for d in range(3):
                    if not (math.isfinite(x[a, d]) and math.isfinite(v[a, d])):
                        return 3, builds, neigh
            if _K_FIXES and not post:
                for a in range(nfx):  # the last step's Langevin forces (each langevin fix's `force`)
                    for d in range(FL.shape[0]):
                        fx[13][0, a, d] = FL[d, a]
            clk[0] = dt
            return 0, builds, neigh

        return pair_chunk

    def _fix_phase(phase: int, stepn: int, dt: float, ftm2v: float, mass: np.ndarray, v: np.ndarray,
                   groups: np.ndarray, fix: tuple, clk: np.ndarray) -> int:
        """The parts of `pair_chunk`'s fixes that read every atom of the case, for
        `_chunk_threaded` (the rest, `_fix_post_force`, runs on each thread's atoms): phase 0 the
        Langevin factors (`_langevin_setup`), 1 `_fix_pre` of step stepn (fix nvt's first half
        step, the Langevin random forces drawn atom after atom), 2 `_fix_end` of step stepn (fix
        nvt's second half step, temp/berendsen, temp/rescale, the tally: group sums over all the
        atoms), 3 as 2 and then the Langevin forces into the fix's `force` (the chunk's last
        step), 4 those forces only (a case with wall/flow, whose tail ran `_fix_end` before the
        flow walls). The same calls on the same arrays as `pair_chunk`'s own: the same bits. Returns
        `_fix_end`'s status (6: a zero temperature), else 0. clk: the case's clock (dt, atime,
        atimestep), for a thermostat's ramp in a run to a time."""
        fx, fx_rng, _step0, fb = fix
        SQM, G1a, FRa, FLa, KB = fb
        V = v.T
        if phase == 0:
            if G1a.shape[1]:
                _langevin_setup(0, mass, fx, ftm2v, SQM, G1a.T)
            return 0
        if phase == 1:
            return _fix_pre(0, stepn, dt, clk[1], clk[2], V, mass, groups, fx, fx_rng, SQM, FRa.T, KB)
        status = 0
        if phase != 4:  # (4: the tail with wall/flow ran the step's end itself: the forces only)
            status = _fix_end(0, stepn, dt, clk[1], clk[2], V, mass, groups, fx, KB, FLa.T)
        if phase >= 3 and status == 0:
            for a in range(FLa.shape[0]):  # the last step's Langevin forces (each langevin fix's `force`)
                for d in range(FLa.shape[1]):
                    fx[13][0, a, d] = FLa[a, d]
        return status

    _fix_draws = _compiled._fix_draws

    def _fix_draws_part(stepn: int, dt: float, groups: np.ndarray, fix: tuple, rngs: tuple, clk: np.ndarray,
                        a_lo: int, a_hi: int) -> int:
        """`_fix_phase`'s phase 1 for the atoms a_lo .. a_hi - 1 only, when it is only Langevin random
        forces (no fix nvt, no zero yes: `_chunk_steps`' split draws): each langevin fix's from
        rngs[l], a generator standing where the one-thread stream reaches atom a_lo. Threads draw
        their runs at once; the forces and the stream's end are the one call's."""
        fx, _rng, _step0, fb = fix
        SQM, G1a, FRa, FLa, KB = fb
        return _fix_draws(0, stepn, dt, clk[1], clk[2], groups, fx, rngs, SQM, FRa.T, a_lo, a_hi)

    @functools.lru_cache(maxsize=1)
    def _compiled_key() -> str:
        """A digest of compiled.py (the fix and reflect kernels `fix_phase` and `pre_step` call) and
        thermostats.py (their arithmetic), in those functions' names: numba keys a cached function
        by its own file only."""
        from wallbatch.engine import thermostats  # noqa: PLC0415 - only to key the cache

        h = hashlib.sha256((inspect.getsource(_compiled) + inspect.getsource(thermostats)).encode())
        return h.hexdigest()[:12]

    @functools.lru_cache(maxsize=1)
    def fix_phase() -> Any:
        """`_fix_phase` compiled (its on-disk cache keyed by `_compiled_key`)."""
        return jit(_compiled._relink(_fix_phase, name=f"fix_phase_{_compiled_key()}"))

    @functools.lru_cache(maxsize=1)
    def fix_draws() -> Any:
        """`_fix_draws_part` compiled (its on-disk cache keyed by `_compiled_key`)."""
        return jit(_compiled._relink(_fix_draws_part, name=f"fix_draws_{_compiled_key()}"))

    @functools.lru_cache(maxsize=1)
    def pre_step() -> Any:
        """`_pre_step` compiled (its on-disk cache keyed by `_compiled_key`)."""
        return jit(_compiled._relink(_pre_step, name=f"pre_step_{_compiled_key()}"))

    def pair_chunk_for(soft: tuple[tuple[int, int], ...], region: tuple[tuple[int, int], ...] = (),
                       flow: bool = False, tables: bool = False, stochastic: bool = False, fixes: bool = False,
                       reflect: bool = False, dtr: bool = False, extra: tuple[str, ...] = ()) -> Any:
        """The fused chunk kernel of one kind of pair scene: `pair_chunk` linked to the scene's
        soft-face dispatch, region walls and flow step from compiled.pieces_for (the same
        specialised pieces as the scene's chunk kernel, with the generated forces of its
        wall/lepton faces, `extra`), with the code of `fixes:`, wall/reflect (and
        wall/reflect/stochastic) and fix dt/reset only if the scene has them, named by their
        fingerprint so numba caches each on disk in its own index file (with `extra`, beside the
        generated module the scene's forces are written to)."""
        return _pair_chunk_for(tuple(sorted(set(soft))), tuple(sorted(set(region))), bool(flow), bool(tables),
                               bool(stochastic), bool(fixes), bool(reflect), bool(dtr), tuple(extra))

    @functools.lru_cache(maxsize=32)
    def _pair_chunk_for(soft: tuple[tuple[int, int], ...], region: tuple[tuple[int, int], ...], flow: bool,
                        tables: bool = False, stochastic: bool = False, fixes: bool = False, reflect: bool = False,
                        dtr: bool = False, extra: tuple[str, ...] = ()) -> Any:
        p = _compiled.pieces_for(soft, region, flow, extra=extra, tables=tables, stochastic=stochastic)
        vector = any(src.startswith(_compiled.VECTOR_MARK) for src in extra)
        flags = {"_K_FIXES": fixes, "_K_REFLECT": reflect or stochastic, "_K_DTR": dtr, "_K_VECTOR": vector}
        h = hashlib.sha256()
        h.update(str(p.fingerprint).encode())
        h.update(repr(sorted(flags.items())).encode())
        h.update(inspect.getsource(_compiled).encode())
        h.update(Path(__file__).read_bytes())  # (with `extra` numba keys the cache by the generated module's file)
        fp = int(h.hexdigest()[:15], 16)
        fn = _compiled._relink(_make_pair_chunk(fp).py_func, name=f"pair_chunk_{fp:015x}", filename=p.filename,
                               _soft_face=p.soft_face, _vector_faces=p.vector_faces,
                               _region_walls=p.region_walls, _flow_step=p.flow_step, _sample_faces=p.sample_faces,
                               _sample_regions=p.sample_regions,
                               _table_faces=_compiled._table_faces if tables else _compiled._no_table_faces,
                               _stochastic_faces=_compiled._stochastic_faces if stochastic
                               else _compiled._no_stochastic_faces, **flags)
        return njit(cache=True, nogil=True, error_model="numpy")(fn)


# the compile message's estimates [s] (measured on a 2-core AVX2 host, first runs, one thread: the
# chunk kernel of an LJ slit ~13-15 s, and ~12-15 s more for the pair kernels every pair scene
# shares, the list build and force pass, when they are not cached yet; errs long)
PAIR_COMPILE_SECONDS, PAIR_FIXES_SECONDS, PAIR_SHARED_SECONDS = 15, 20, 15


def compile_estimate(fixes: bool, lepton: bool = False) -> float:
    """The compile message's estimate for a pair scene's chunk kernel [s]: PAIR_COMPILE_SECONDS
    (PAIR_FIXES_SECONDS with thermostats; compiled.LEPTON_PAIR_COMPILE_S with wall/lepton faces),
    plus PAIR_SHARED_SECONDS when the shared list build and force pass are not compiled or in
    numba's disk cache yet."""
    own = _compiled.LEPTON_PAIR_COMPILE_S if lepton else PAIR_FIXES_SECONDS if fixes else PAIR_COMPILE_SECONDS
    shared = [build_case, forces_case] if njit is not None else []
    if all(k.signatures or _compiled._cached_on_disk(k) for k in shared):
        return own
    return own + PAIR_SHARED_SECONDS


THREAD_MIN_ATOMS = 8_192  # atoms per thread below which one case's chunk runs in one call (`_chunk_threaded`)
# A threaded chunk whose process used less than THREAD_MIN_USE of its threads' cores (CPU time over
# wall time: the cores were busy with other work, and threads that meet twice a step wait for each
# other) is followed by BUSY_SKIP case chunks in one call (the same bits either way), then threads again.
THREAD_MIN_USE = 0.6
BUSY_SKIP = 4
BUSY_MIN_WALL = 0.05  # [s] a shorter chunk is not judged


def case_parts(natoms: int) -> int:
    """Threads for one case of natoms atoms (`_chunk_threaded`, and the pair's builds and passes
    outside chunks): threads.count(), at most one per THREAD_MIN_ATOMS atoms (1: one call)."""
    return max(1, min(threads.count(), natoms // THREAD_MIN_ATOMS, 64))


def forces_case_threaded(x: np.ndarray, f: np.ndarray, owner: np.ndarray, first: np.ndarray, neigh: np.ndarray,
                         e24: float, e4: float, s2c: float, rcut2: float, off: float, length: np.ndarray,
                         periodic: np.ndarray, outputs: bool, parts: int, split: "RowSplit | None" = None,
                         run: Callable[[list], list] = threads._in_threads,
                         buffer: "Buffer | None" = None) -> tuple[float, float, "RowSplit"]:
    """`forces_case` over `parts` threads (`RowSplit`, `forces_threaded`, the logs replayed by the
    threads, each a run of atoms; `run`: threads._in_threads or a `Crew`): the same bits; returns
    (energy, virial, the split), the split to pass again while the list stays the same; `buffer`:
    the split's scratch arrays (`RowSplit`; default fresh ones)."""
    if split is None or len(split.rb) != parts + 1 or len(split.mixed) != len(owner):
        split = RowSplit(owner, first, neigh, parts, run, buffer=_fresh if buffer is None else buffer)
    N = len(f)
    cut = [N * p // parts for p in range(parts + 1)]
    _, e, w = forces_threaded(x, f, owner, first, neigh, split, e24, e4, s2c, rcut2, off, length, periodic, run,
                              replay=False, outputs=outputs, cut=cut[1] if parts == 2 else N)
    run([lambda p=p: split.replay(f, cut[p], cut[p + 1]) for p in range(parts)])
    return e, w, split


Buffer = Callable[[str, tuple, Any], np.ndarray]


def _fresh(name: str, shape: tuple, dtype: Any) -> np.ndarray:
    """A new array (the default `Buffer`: nothing kept; large ones in 4 kB pages, pages.py)."""
    return pages.empty(shape, dtype)


def fix_buffers(n: int, nlang: int, buffer: Buffer = _fresh) -> tuple[np.ndarray, ...]:
    """`pair_chunk`'s per-atom buffers of the fixes for n atoms (0: a case without fixes) and
    nlang langevin fixes, from `buffer` (content undefined: the kernel writes each before it reads
    it): sqrt(m), each langevin fix's drag (n, nlang), the step's random forces (n, 3 nlang: x, y,
    z of each fix), the Langevin forces (n, 3 nlang) and a scratch for sums over atoms. A thread's
    part of a case takes its rows."""
    return (buffer("fix_sqm", (n,), float), buffer("fix_drag", (n, nlang), float),
            buffer("fix_random", (n, 3 * nlang), float), buffer("fix_force", (n, 3 * nlang), float),
            buffer("fix_sums", (n,), float))


def bin_threaded(pos: np.ndarray, lo: np.ndarray, length: np.ndarray, periodic: np.ndarray, reach: float,
                 owner: np.ndarray, parts: int, run: Callable[[list], list] = threads._in_threads,
                 buffer: Buffer = _fresh) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """`_bin` with runs of atoms in `parts` threads (`run`): each run's extent, then (grid from
    them) each run's cells and counts, the prefix sums here, then each run scatters its atoms in
    index order after the runs before: the same owner, xs, cstart and nb, bit for bit. Work arrays
    come from `buffer(name, shape, dtype)` (kept arrays: a fresh one of this size is a fresh
    mapping whose pages fault again, ~2 ms a build at N = 1e5)."""
    N = pos.shape[0]
    cut = [N * r // parts for r in range(parts + 1)]
    mms = np.zeros((parts, 2, 3))
    run([lambda r=r: _bin_extent(pos, cut[r], cut[r + 1], periodic, mms[r]) for r in range(parts)])
    base, ext, nb = np.empty(3), np.empty(3), np.empty(3, np.int64)
    _bin_grid(mms, lo, length, periodic, reach, N, base, ext, nb)
    ncell = int(nb[0] * nb[1] * nb[2])
    p, cell = buffer("bin_p", (N, 3), np.float64), buffer("bin_cell", (N,), np.int64)
    counts = buffer("bin_counts", (parts, ncell + 1), np.int64)
    counts[:] = 0
    run([lambda r=r: _bin_cells(pos, cut[r], cut[r + 1], periodic, base, ext, nb, p, cell, counts[r])
         for r in range(parts)])
    cstart = np.empty(ncell + 1, np.int64)  # (returned: the caller may keep it)
    fills = buffer("bin_fills", (parts, ncell), np.int64)
    _bin_starts(counts, cstart, fills)
    xs = buffer("bin_xs", (N, 3), np.float64)
    run([lambda r=r: _bin_scatter(p, cell, cut[r], cut[r + 1], fills[r], owner, xs) for r in range(parts)])
    return xs, cstart, nb


def build_threaded(pos: np.ndarray, lo: np.ndarray, length: np.ndarray, periodic: np.ndarray, reach: float,
                   owner: np.ndarray, first: np.ndarray, neigh: np.ndarray, parts: int,
                   run: Callable[[list], list] = threads._in_threads, marks: np.ndarray | None = None,
                   rows: np.ndarray | None = None, shares: np.ndarray | None = None, buffer: Buffer = _fresh,
                   zones: np.ndarray | None = None) -> int:
    """`build_case` with its binning in runs of atoms (`bin_threaded`) and its scan of the cells cut
    in `parts` runs of cells (about equal atoms), one per thread (`run`: threads._in_threads or a
    `Crew`): part 0 writes its rows into neigh, part p >= 1 into its share of a second array (in
    proportion to its atoms; `buffer("aside", ...)`), and `_join` then copies them after part 0's,
    in threads. The same list, bit for bit; -1 if some part's share was too short (call again with
    a longer neigh). With `marks` (parts, N) uint8 zeros and `rows` (parts + 1,): marks[p] = the
    atoms part p's rows touch (all `RowSplit` needs: not those owned by part p or before, whose
    first part is known without), rows = the parts' first rows (for `RowSplit`). `shares` (parts +
    1,), from 0 up to 1: part p starts at about atom shares[p] N (default p / parts). Work arrays
    from `buffer` (`bin_threaded`). With `zones` (parts, 2, 2): each part's runs of rows [lo, hi)
    that may have partners another part touches first (`row_zones`; for `RowSplit`)."""
    N = pos.shape[0]
    if N < 2 * parts:  # (no marks: RowSplit marks itself)
        if rows is not None:
            rows[:] = -1
        return build_case(pos, lo, length, periodic, reach, owner, first, neigh)
    first[0] = 0
    xs, cstart, nb = bin_threaded(pos, lo, length, periodic, reach, owner, parts, run, buffer)
    ncell = len(cstart) - 1
    starts = [N * p // parts for p in range(parts)] if shares is None else [int(N * shares[p]) for p in range(parts)]
    qb = np.maximum.accumulate(np.searchsorted(cstart, starts, side="left")).astype(np.int64)
    qb = np.append(np.minimum(qb, ncell), ncell)
    rs = cstart[qb]  # the first row of each part
    cap = len(neigh)
    base = (cap * rs[:-1]) // N  # part p >= 1: its share of `aside`, from base[p]
    base[0] = 0
    edges = np.append(base, cap)
    edges[1] = cap  # part 0: all of neigh
    aside = buffer("aside", (cap,), np.int32)
    none = np.empty(0, np.uint8)

    def scan(p: int) -> int:
        return _scan(xs, cstart, nb, owner, length, periodic, reach, int(qb[p]), int(qb[p + 1]), int(base[p]),
                     int(edges[p + 1]), first, aside if p else neigh,
                     none if marks is None else marks[p], p < parts - 1)

    ends = np.asarray(run([lambda p=p: scan(p) for p in range(parts)]), np.int64)
    if (ends < 0).any():
        return -1
    dest = np.cumsum(np.concatenate(([0], ends - base)))  # where each part's pairs go in neigh
    m = int(dest[-1])
    if m > cap:
        return -1
    moved = m - int(dest[1])  # the pairs of parts >= 1, joined in `parts` runs
    cut = [int(dest[1]) + moved * t // parts for t in range(parts + 1)]
    rcut = [int(rs[1]) + (N - int(rs[1])) * t // parts for t in range(parts + 1)]
    run([lambda t=t: _join(first, neigh, aside, rs, base, dest, cut[t], cut[t + 1], rcut[t], rcut[t + 1])
         for t in range(parts)])
    first[N] = m
    if rows is not None:
        rows[:] = rs
    if zones is not None:
        row_zones(qb, cstart, nb, bool(periodic[0]), zones)
    return m


def row_zones(qb: np.ndarray, cstart: np.ndarray, nb: np.ndarray, xper: bool, zones: np.ndarray) -> None:
    """zones[p] = two runs of rows [lo, hi) of part p (cells qb[p] .. qb[p+1] - 1 of `_scan`'s grid
    nb, cell starts cstart) outside which no row has a partner, or an owner, that a part before p
    touches first (`RowSplit` checks only these). A row of a cell in x layer c (x slowest: a
    layer is nb[1] nb[2] cells) has its partners in layers c .. c + 2 (half stencil), and in
    layers 0 and 1 if c + 2 wraps a periodic x. So the atoms the parts before p touch are in
    layers up to c' + 2 (c': the layer of cell qb[p] - 1), and in layers 0 and 1 through a wrap:
    part p's rows that can meet them are those of layers up to c' + 2 (run 0) and, with a periodic
    x, those of layers n0 - 2 and up (run 1). With a periodic x and a part 0 of less than two
    layers (the atoms of layers 0 and 1 may then be another part's), all rows: run 0."""
    layer = int(nb[1] * nb[2])
    n0 = int(nb[0])
    zones[0] = 0
    for p in range(1, len(qb) - 1):
        a, b = int(qb[p]), int(qb[p + 1])
        if xper and int(qb[1]) < 2 * layer:  # a thin part 0 (or one layer): every row
            head, wrap = b, b
        else:
            head = min(b, ((a - 1) // layer + 3) * layer)
            wrap = max(a, (n0 - 2) * layer) if xper else b
        head = max(a, head)
        zones[p, 0] = cstart[a], cstart[head]
        zones[p, 1] = cstart[max(head, min(wrap, b))], cstart[b]


_NO_ROWS = np.empty((0, 2))


def _share_runs(runs: np.ndarray, parts: int) -> list[np.ndarray]:
    """The runs of rows runs (k, 2) ([lo, hi) each, in order) cut into `parts` lists of runs of
    about equal rows, in order (each thread's share of `_mixed`)."""
    runs = runs[runs[:, 1] > runs[:, 0]]
    sizes = runs[:, 1] - runs[:, 0]
    ends = np.cumsum(sizes)
    total = int(ends[-1]) if len(ends) else 0
    out = []
    for t in range(parts):
        a, b = total * t // parts, total * (t + 1) // parts  # rows a .. b - 1 of the runs laid end to end
        piece = []
        for (lo, hi), e in zip(runs.tolist(), ends.tolist()):
            s0 = e - (hi - lo)  # where this run starts, end to end
            u, v = max(a, s0), min(b, e)
            if u < v:
                piece.append((lo + u - s0, lo + v - s0))
        out.append(np.array(piece, np.int64).reshape(-1, 2))
    return out


class RowSplit:
    """The parts of a list's threaded force pass: rows rb[p] .. rb[p+1] - 1 for part p (about equal
    pairs, or `build_threaded`'s parts with its marks); firstp[j] = the first part whose rows touch atom j (owner or partner), the one that
    adds into f[j] at once: a later part logs its additions to j (lj, lv; part p's at logs[p] ..
    logs[p+1] - 1, exactly as many as its rows log) for `replay`. `reuse`: an earlier split whose
    arrays this one may take (it must not be used after); `buffer`: where the log arrays and the
    rows' outputs come from when not reused (scratch, consumed within a pass: a `Workspace`'s
    kept arrays may serve every split of one pair); `zones`: with the build's marks and rows, its
    `row_zones`, the only rows that can have partners of another part (else all but part 0's)."""

    def __init__(self, owner: np.ndarray, first: np.ndarray, neigh: np.ndarray, parts: int,
                 run: Callable[[list], list] = threads._in_threads, marks: np.ndarray | None = None,
                 rows: np.ndarray | None = None, reuse: "RowSplit | None" = None, buffer: "Buffer" = _fresh,
                 zones: np.ndarray | None = None):
        nrow = len(owner)
        total = int(first[nrow])
        built = not (marks is None or rows is None or rows[0] < 0)
        if not built:  # parts of about equal pairs, marked here
            self.rb = np.append(np.searchsorted(first[:nrow + 1], [total * p // parts for p in range(parts)]),
                                nrow).astype(np.int64)
            marks = np.zeros((parts, nrow), np.uint8)
            rb = self.rb
            run([lambda p=p: _touch(owner, first, neigh, int(rb[p]), int(rb[p + 1]), marks[p], p < parts - 1)
                 for p in range(parts)])  # the last part's partners: first touched before or by it
        else:  # the parts of `build_threaded` (about equal atoms) and its marks
            self.rb = rows.astype(np.int64)
        rb = self.rb
        keep = reuse is not None and len(reuse.firstp) == nrow  # its arrays' pages are mapped
        self.firstp = reuse.firstp if keep else np.empty(nrow, np.uint8)  # the first part with a mark (0: none)
        cut = [nrow * p // parts for p in range(parts + 1)]
        run([lambda p=p: _first_marks(marks, cut[p], cut[p + 1], self.firstp) for p in range(parts)])
        self.mixed = reuse.mixed if keep else np.empty(nrow, np.uint8)
        self.mixed[:] = 0  # rows of part 0 have none; the others' rows that may have, shared out
        runs = zones[1:].reshape(-1, 2) if built and zones is not None else np.array([[rb[1], nrow]], np.int64)
        rooms = np.zeros((parts, parts), np.int64)  # per thread: each part's logged additions
        shared = _share_runs(runs, parts)
        run([lambda p=p: _mixed(first, neigh, owner, shared[p], rb, self.firstp, self.mixed, rooms[p])
             for p in range(parts)])
        room = rooms.sum(axis=0)  # exact: part 0 logs nothing, the others only their mixed rows' additions
        self.logs = np.concatenate(([0], np.cumsum(room))).astype(np.int64)
        need = int(self.logs[-1])
        if reuse is not None and len(reuse.lj) >= need:  # the last split's logs: their pages are mapped
            self.lj, self.lv = reuse.lj, reuse.lv
        else:  # kept arrays of a size class (`buffer`): a fresh array is a fresh mapping whose pages
            size = 1 << max(12, (need + need // 8).bit_length())  # fault on first touch (~10-60 us each)
            self.lj, self.lv = buffer("log_j", (size,), np.int32), buffer("log_v", (size, 3), np.float64)
        self._buffer = buffer
        self._rowew = None if reuse is None or reuse._rowew is None or len(reuse._rowew) != nrow else reuse._rowew

    def replay(self, f: np.ndarray, a_lo: int, a_hi: int) -> None:
        """Add the logged additions of the last `forces_threaded` pass to atoms a_lo .. a_hi - 1 into f."""
        starts, tops = self.logs[:-1], self.logs[1:]
        _replay_atoms(f, self.lj, self.lv, starts, self.ends if a_lo < self.cut else starts,
                      tops, self.downs if a_hi > self.cut else tops, a_lo, a_hi)

    def row_outputs(self) -> np.ndarray:
        """The (rows, 2) array the parts write each row's energy and virial sums into (kept)."""
        if self._rowew is None:
            self._rowew = self._buffer("rowew", (len(self.mixed), 2), np.float64)
        return self._rowew


def forces_threaded(x: np.ndarray, f: np.ndarray, owner: np.ndarray, first: np.ndarray, neigh: np.ndarray,
                    split: RowSplit, e24: float, e4: float, s2c: float, rcut2: float, off: float, length: np.ndarray,
                    periodic: np.ndarray, run: Callable[[list], list] = threads._in_threads,
                    replay: bool = True, outputs: bool = False, cut: int | None = None) -> tuple[np.ndarray, float, float]:
    """`forces_case` with its rows cut in the parts of `split`, one per thread, then the logged
    additions (`RowSplit.replay`): every atom's force gets the same additions in the same order as in
    `forces_case`, so the same bits; with outputs, so are the energy and virial (each row's sums,
    then the rows in order). Returns (each part's CPU seconds (its thread's), energy, virial; 0, 0
    without outputs). Without `replay` the caller replays the logs (`split.replay`, e.g. each
    thread its own atoms: logged additions to atoms below `cut` (default: all) and to the others
    are kept apart, so a thread replaying one side reads only its own)."""
    rb, logs = split.rb, split.logs
    rowew = split.row_outputs() if outputs else _NO_ROWS
    split.cut = len(f) if cut is None else cut

    def part(p: int) -> tuple[tuple[int, int], float]:
        t = time.thread_time()
        q = forces_part(x, f, owner, first, neigh, int(rb[p]), int(rb[p + 1]), p, split.firstp, split.mixed,
                        split.lj, split.lv, int(logs[p]), int(logs[p + 1]), split.cut, e24, e4, s2c, rcut2, off,
                        length, periodic, outputs, rowew)
        return q, time.thread_time() - t

    got = run([lambda p=p: part(p) for p in range(len(rb) - 1)])
    split.ends = np.array([g[0][0] for g in got], np.int64)
    split.downs = np.array([g[0][1] for g in got], np.int64)
    if replay:
        split.replay(f, 0, len(f))
    e, w = _row_sums(rowew) if outputs else (0.0, 0.0)
    return np.array([g[1] for g in got]), e, w


class Crew:
    """Threads kept for the calls of one chunk: `crew(calls)` runs calls[0] here and calls[k] on
    worker k (at most `size` calls), and returns their results (an exception is re-raised); cheaper
    than new threads at each of a step's meetings (threads._in_threads). `close()` ends them."""

    def __init__(self, size: int):
        self.size = size
        self._go = [threading.Semaphore(0) for _ in range(size - 1)]
        self._done = threading.Semaphore(0)
        self._jobs: list[Any] = [None] * (size - 1)
        self._out: list[Any] = [None] * size
        self._workers = [threading.Thread(target=self._work, args=(k,), name=f"wallbatch-pair-{k + 1}", daemon=True)
                         for k in range(size - 1)]
        for t in self._workers:
            t.start()

    def _work(self, k: int) -> None:
        while True:
            self._go[k].acquire()
            job = self._jobs[k]
            if job is None:
                return
            try:
                self._out[k + 1] = job()
            except BaseException as exc:  # noqa: BLE001 - handed to the calling thread
                self._out[k + 1] = exc
            self._done.release()

    def __call__(self, calls: list[Callable[[], Any]]) -> list[Any]:
        n = len(calls)
        for k in range(1, n):
            self._jobs[k - 1] = calls[k]
            self._go[k - 1].release()
        try:
            first = calls[0]()
        finally:
            for _ in range(1, n):
                self._done.acquire()
        out = [first] + self._out[1:n]
        for r in out:
            if isinstance(r, BaseException):
                raise r
        return out

    def close(self) -> None:
        for k, go in enumerate(self._go):
            self._jobs[k] = None
            go.release()
        for t in self._workers:
            t.join()


class Workspace:
    """What one pair keeps for its threaded builds and passes: work arrays by name (`buffer`: a
    fresh array of this size is a fresh mapping whose pages fault again on first touch, dearer
    still in two threads at once) and a `Crew` (`crew`), ended with this object."""

    def __init__(self) -> None:
        self._bufs: dict[str, np.ndarray] = {}
        self._crew: Crew | None = None
        self._end: Any = None

    def buffer(self, name: str, shape: tuple, dtype: Any) -> np.ndarray:
        """A C-contiguous array kept under `name` (new if the shape or type differs; content undefined)."""
        b = self._bufs.get(name)
        if b is None or b.shape != tuple(shape) or b.dtype != np.dtype(dtype):
            b = self._bufs[name] = pages.empty(shape, dtype)  # (large ones in 4 kB pages: pages.py)
        return b

    def crew(self, parts: int) -> "Crew":
        """A `Crew` of `parts` threads, kept."""
        if self._crew is None or self._crew.size != parts:
            if self._end is not None:
                self._end()
            self._crew = Crew(parts)
            self._end = weakref.finalize(self, self._crew.close)
        return self._crew


def atom_extent(pos: np.ndarray) -> np.ndarray:
    """max - min of positions pos (N >= 1, 3) per dim (NumPy's axis-0 reductions of an (N, 3)
    array are slow: ~10 ms at N = 1e5)."""
    mm = np.empty((2, 3))
    _bin_extent(np.ascontiguousarray(pos, dtype=np.float64), 0, len(pos), np.zeros(3, np.bool_), mm)
    return mm[1] - mm[0]


def _chunk_threaded(kernel: Any, args: tuple, parts: int, held: dict | None = None, crew: "Crew | None" = None,
                    buffer: Buffer = _fresh) -> tuple[int, int, np.ndarray]:
    """`kernel(*args)` (a `pair_chunk` call of one case) over `parts` threads, step by step:
    the list build if due (`build_threaded`), the pair forces (`forces_threaded`), then on runs of
    atoms the kernel with `post` for the rest of the step (walls, lost atoms, final_integrate) and
    `_pre_step` for the start of the next (drift, wrap, list check): two meetings of the threads a
    step. With wall/flow the rest of the step runs on all atoms in one call (its random stream is
    drawn atom after atom). With thermostats, what reads every atom (`fix_phase`: the end of the
    step, then the start of the next) runs between the `post` parts and the `_pre_step` parts:
    three meetings a step. A sampled chunk's last pair pass gives the energy and virial too (each
    row's sums by the parts, then the rows in order, as `forces_case`). Every value is that of the one call, bit
    for bit; returns what it returns (a chunk with trouble may stop at another step of it: the
    caller discards it and the NumPy loop re-runs it). `held` carries what the next chunk of the
    case can reuse: "split" (the `RowSplit` of the list the chunk ends with; in: that of the list it
    starts with, or None) and "shares" (the parts' shares of the atoms for the next build). `crew`:
    a `Crew` of `parts` threads to run the parts (else one for this call); `buffer`: the builds'
    work arrays (`build_threaded`)."""
    if crew is not None and crew.size == parts:
        return _chunk_steps(kernel, args, parts, crew, {} if held is None else held, buffer)
    crew = Crew(parts)
    try:
        return _chunk_steps(kernel, args, parts, crew, {} if held is None else held, buffer)
    finally:
        crew.close()


def _chunk_steps(kernel: Any, args: tuple, parts: int, crew: Crew, held: dict,
                 buffer: Buffer = _fresh) -> tuple[int, int, np.ndarray]:
    """`_chunk_threaded`'s steps, the threads' calls run by `crew`."""
    a = dict(zip(_signature_names(kernel), args))
    nsteps, x, v, f, xref = a["nsteps"], a["x"], a["v"], a["f"], a["xref"]
    owner, first, neigh, spare = a["owner"], a["first"], a["neigh"], a["spare"]
    lo, hi, box_per, length, per = a["lo"], a["hi"], a["box_per"], a["length"], a["pair_per"]
    dt, limit2, lj = a["dt"], a["limit2"], a["lj"]
    N = x.shape[0]
    dtfm = _dtfm(a["mass"], dt, a["ftm2v"])
    sf_val, sample, fpair = a["sf_val"], a["sample"], a["fpair"]
    vary = sf_val.shape[0] > 1
    runs = [slice(N * p // parts, N * (p + 1) // parts) for p in range(parts)]
    fix = a["fix"]  # `fixes:`: those that read every atom (`fix_phase`) between the parts' calls
    fb = fix[3]
    coupled = fb[0].shape[0] > 0 and bool(np.any(fix[0][0][:, 0] != _compiled.FIX_ENFORCE2D))
    step0, mass, groups, ftm2v = fix[2], a["mass"], a["groups"], a["ftm2v"]
    mrow = int(fix[0][11][2])  # the integrated atoms' group row (-1: every atom; frozen atoms stay)
    clk = a["dtr"][3]  # the case's clock (dt, atime, atimestep): a thermostat's ramp in a run to a time
    part_groups = [np.ascontiguousarray(groups[:, r]) for r in runs]  # (G, N) rows: each part's copy
    a.update(nsteps=1, post=True, sample=False)
    flow = int(a["fl"][0][0]) != 0
    if flow:  # wall/flow: the rest of the step on all atoms
        tails = [a]
    else:
        tails = [dict(a, x=x[r], v=v[r], f=f[r], mass=mass[r], radius=a["radius"][r], groups=part_groups[p],
                      fix=(*fix[:3], tuple(b[r] for b in fb) if fb[0].shape[0] else fb)) for p, r in enumerate(runs)]
    rf_meta, rf_val, rf_prev = a["rfl"][:3]  # wall/reflect without statistics (`chunk_eligible`)
    pre_kernel = pre_step()
    at_step = [0]  # the step whose start `pre` runs (its faces' coords)

    def pre(p: int) -> int:
        r = runs[p]
        row = rf_val[at_step[0] if rf_val.shape[0] > 1 else 0]
        return pre_kernel(x[r], v[r], f[r], dtfm[r], dt, lo, hi, box_per, xref[r], length, per, limit2, rf_meta, row,
                          rf_prev, mass[r], part_groups[p], ftm2v, mrow)

    def tail_pre(p: int, step: int) -> tuple[int, int]:
        """The rest of step `step` on part p's atoms (all atoms with wall/flow: tails[0]), then,
        but after the last step, the first part of the next one: (its status, `pre`'s)."""
        t = tails[p] if p < len(tails) else None
        if pending is not None:  # this part's atoms' logged pair forces first
            r = runs[p] if len(tails) == parts else slice(0, N)
            pending.replay(f, r.start, r.stop)
            if sample and step == nsteps - 1:  # the sample's pair forces (`pair_chunk`'s fpair)
                fpair[r] = f[r]
        if t is not None:
            t.update(neigh=neigh, sf_val=sf_val[step:step + 1] if vary else sf_val)
            if flow:  # (its `_fix_end` counts the case's steps from the fix tuple's step0)
                t["fix"] = (fix[0], fix[1], step0 + step, fix[3])
            st = tail_kernel(*t.values())[0]  # (`call_kernel`: a Ctrl-C is a KeyboardInterrupt)
            if st != 0:
                return st, 0
        return 0, (pre(p) if step + 1 < nsteps and len(tails) == parts and not coupled else 0)

    def pres() -> int:
        return max(crew([lambda p=p: pre(p) for p in range(parts)]))  # 3: a non-finite position

    def faces_moved() -> None:
        """After every part's `pre` of step at_step: the faces' coords of that step become the
        last ones (`pair_chunk`'s rf_prev[k] = coord, once all parts read the old ones)."""
        if rf_meta.shape[0]:
            rf_prev[:] = rf_val[at_step[0] if rf_val.shape[0] > 1 else 0]

    # every part's call, at every step, has arguments of the same types: typed once (`backend.Repeated`)
    tail_kernel = backend.Repeated(kernel)
    phase = backend.Repeated(fix_phase()) if coupled else None
    sm = a["sm"]  # samples in the kernel (`advance_sampled`): sm[0] their steps, from 1
    due = {int(t) - 1: i for i, t in enumerate(sm[0])}  # step index: sample index
    sample_kernel = backend.Repeated(kernel) if due else None
    one = np.ones(1, np.int64)

    # a sample step's tail with a thermostat runs the fixes' end of step too (fx_int[0] = 1), before
    # the sample reads them (with wall/flow the tail on all atoms runs it anyway)
    fx_end = fix[0] if not coupled or flow else (*fix[0][:11], np.array([1, *fix[0][11][1:]], np.int64),
                                                   *fix[0][12:])

    def sample_tail(step: int, i: int) -> tuple[int, int]:
        """The rest of sample step `step` (sample i) on all atoms in one call (with a thermostat its
        end of step too), which records the sample as the one-thread kernel records it (sums over
        the atoms in their order): (status, 0)."""
        pending.replay(f, 0, N)
        t = dict(a, neigh=neigh, sf_val=sf_val[step:step + 1] if vary else sf_val,
                 fix=(fx_end, fix[1], step0 + step, fix[3]), sm=(one, *(b[i:i + 1] for b in sm[1:])))
        return sample_kernel(*t.values())[0], 0

    pending = old = None
    split = held.get("split")  # the starting list's, if the caller kept it
    builds = 0
    built = False  # the list is this chunk's build: its marks and parts serve RowSplit
    fast = None  # each part's least CPU time of a pass on this chunk's latest list (`_rebalance`)
    marks, rows = buffer("marks", (parts, N), np.uint8), np.empty(parts + 1, np.int64)
    zones = np.zeros((parts, 2, 2), np.int64)  # the build's `row_zones` (for RowSplit)
    shares = held.get("shares")
    if shares is None or len(shares) != parts + 1:
        shares = np.arange(parts + 1) / parts
    held["split"] = None  # (a chunk with trouble keeps nothing)
    draws = SplitDraws.of(fix, groups, [r.start for r in runs]) if coupled and len(tails) == parts else None
    draw = backend.Repeated(fix_draws()) if draws is not None else None

    def start(stepn: int) -> int:
        """The start of step stepn: `_fix_pre` (phase 1), then `pre` in parts; with `draws`, each
        part draws its own atoms' random forces first, in the same call as its `pre`."""
        if draws is None:
            phase(1, stepn, dt, ftm2v, mass, v, groups, fix, clk)
            return pres()
        gens = draws.ready()

        def part(p: int) -> int:
            draw(stepn, dt, groups, fix, gens[p], clk, runs[p].start, runs[p].stop)
            return pre(p)

        out = max(crew([lambda p=p: part(p) for p in range(parts)]))
        draws.done()
        return out

    if coupled:  # the Langevin factors, then the first step's start (`pair_chunk`'s `_fix_pre`)
        phase(0, 0, dt, ftm2v, mass, v, groups, fix, clk)
        st = start(step0 + 1)
    else:
        st = pres()
    faces_moved()
    for step in range(nsteps):
        if st == 3:
            return 3, builds, neigh
        if st == 1:
            target = neigh if builds > 0 else spare
            marks[:] = 0
            m = build_threaded(x, lo, length, per, a["reach"], owner, first, target, parts, crew, marks, rows, shares,
                               buffer, zones)
            while m < 0:
                target = pages.empty(2 * len(target) + 4 * N, np.int32)
                marks[:] = 0
                m = build_threaded(x, lo, length, per, a["reach"], owner, first, target, parts, crew, marks, rows,
                                   shares, buffer, zones)
            neigh = target
            xref[:] = x
            builds += 1
            split, old = None, split
            built, fast = True, None
        if split is None:
            split = RowSplit(owner, first, neigh, parts, crew, *((marks, rows) if built else (None, None)), reuse=old,
                             buffer=buffer, zones=zones)
        last = sample and step == nsteps - 1  # the sample's pair pass: also the energy and virial
        isample = due.get(step)
        cpu, e, w = forces_threaded(x, f, owner, first, neigh, split, *lj, length, per, crew, replay=False,
                                    outputs=last or isample is not None, cut=runs[1].start if parts == 2 else N)
        pending = split  # its logs are replayed by tail_pre, each part its own atoms
        if last:
            a["ew"][0], a["ew"][1] = e, w
        if built and rows[0] >= 0 and cpu.min() > 0:  # next build: parts of about equal force time, from
            fast = cpu if fast is None else np.minimum(fast, cpu)  # each part's quickest pass on this list
            shares = _rebalance(shares, rows / N, fast)  # (a pass slowed by other work would skew it)
        at_step[0] = step + 1  # (the next step's start, in `tail_pre` or `pres`)
        if isample is not None:  # a sample step's rest on all atoms, the sample recorded; the next start in parts
            got = [sample_tail(step, isample)]
            sm[-1][isample, 0], sm[-1][isample, 1] = e, w  # (the pair's energy and virial: this step's pass)
            if got[0][0] == 0:
                if coupled and step == nsteps - 1:  # the last step's Langevin forces (each fix's `force`)
                    phase(4, step0 + step + 1, dt, ftm2v, mass, v, groups, fix, clk)
                if step + 1 < nsteps:
                    got.append((0, start(step0 + step + 2) if coupled else pres()))
        elif len(tails) == parts and not coupled:  # the rest of this step and the start of the next, atoms in parts
            got = crew([lambda p=p: tail_pre(p, step) for p in range(parts)])
        else:  # the rest of the step on each part (wall/flow: on all atoms), the fixes' sums over all
            # atoms (the end of this step, the start of the next), then the next start in parts
            got = crew([lambda p=p: tail_pre(p, step) for p in range(parts)]) if len(tails) == parts \
                else [tail_pre(0, step)]
            ok = all(g[0] == 0 for g in got)
            if ok and coupled:
                last = step == nsteps - 1
                fs = 0
                if not flow:
                    fs = phase(3 if last else 2, step0 + step + 1, dt, ftm2v, mass, v, groups, fix, clk)
                elif last:  # (the tail ran the step's end on all atoms, before the flow walls: Engine.step's order)
                    phase(4, step0 + step + 1, dt, ftm2v, mass, v, groups, fix, clk)
                if fs != 0:  # (6: a zero temperature; the NumPy loop reports it)
                    return fs, builds, neigh
            if ok and step + 1 < nsteps:
                got.append((0, start(step0 + step + 2) if coupled else pres()))
        pending = None
        bad = next((g[0] for g in got if g[0] != 0), 0)
        if bad != 0:
            return bad, builds, neigh
        if step + 1 < nsteps:
            faces_moved()
        st = max(g[1] for g in got)
    held["split"], held["shares"] = split, shares
    return 0, builds, neigh


class SplitDraws:
    """A step's Langevin random forces drawn by the threads at once, each its own run of atoms
    (`fix_draws`), with the one thread's stream: part p draws from copies of the fixes'
    generators (PCG64) advanced past the draws of the atoms before its run (three uniforms, one
    64-bit output each, per atom of the fix's group); then each fix's own generator takes the last
    part's end, where the one thread's stream ends. `of` gives None where the split would change
    the stream or the forces: another bit generator, a generator holding half of a 64-bit output,
    fix nvt in the scene (its chain's half step scales the velocities there), zero yes (the
    group's sums in atom order)."""

    def __init__(self, gens: tuple, before: np.ndarray):
        self.gens = gens
        self.before = before  # (parts, fixes): draws of each fix's stream before part p's atoms
        self.copies = [gens] + [tuple(np.random.Generator(np.random.PCG64(0)) for _ in gens)
                                for _ in range(1, len(before))]

    @classmethod
    def of(cls, fix: tuple, groups: np.ndarray, starts: list[int]) -> "SplitDraws | None":
        """For `_chunk_steps`' fix tuple, its groups (G, N) and the parts' first atoms, or None."""
        meta, gens = fix[0][0], fix[1]
        kinds = meta[:, 0]
        if len(starts) < 2 or not len(gens) or np.any(kinds == _compiled.FIX_NVT):
            return None
        lang = np.flatnonzero(kinds == _compiled.FIX_LANGEVIN)
        if not len(lang) or np.any(meta[lang, 3] & 1):
            return None
        for g in gens:
            if not isinstance(g.bit_generator, np.random.PCG64) or g.bit_generator.state["has_uint32"]:
                return None
        before = np.zeros((len(starts), len(gens)), np.int64)
        for k in lang:
            row = groups[int(meta[k, 1])]
            before[:, int(meta[k, 4])] = [3 * int(np.count_nonzero(row[:a])) for a in starts]
        return cls(gens, before)

    def ready(self) -> list[tuple]:
        """Each part's generators for this step's draws (part 0: the fixes' own)."""
        for p in range(1, len(self.copies)):
            for g, c, skip in zip(self.gens, self.copies[p], self.before[p]):
                c.bit_generator.state = g.bit_generator.state
                c.bit_generator.advance(int(skip))
        return self.copies

    def done(self) -> None:
        """After every part drew: each fix's generator where its one-thread stream is."""
        for g, c in zip(self.gens, self.copies[-1]):
            g.bit_generator.state = c.bit_generator.state


def _rebalance(shares: np.ndarray, bounds: np.ndarray, cpu: np.ndarray) -> np.ndarray:
    """The parts' starting shares of the atoms for the next build, from the shares the list has
    (`bounds`, parts + 1 fractions) and the CPU seconds each part's force pass took: each part's
    atoms scaled by its speed (atoms per second), half way from `shares` (the results do not depend
    on the split, only the time)."""
    speed = np.diff(bounds) / cpu
    want = np.concatenate(([0.0], np.cumsum(speed) / speed.sum()))
    return 0.5 * (shares + want)


def _signature_names(kernel: Any) -> tuple[str, ...]:
    return threads._signature_names(getattr(kernel, "py_func", kernel))


def reflect_on_threads(plan: "_compiled.ChunkPlan") -> bool:
    """Whether a case cut over threads runs its wall/reflect faces in `_chunk_threaded` (each
    thread its atoms, `_pre_step`): not with reflect statistics (reflect_count, reflect_impulse:
    the impulse would be summed in another order) nor wall/reflect/stochastic (its stream is
    drawn atom after atom). True without reflect faces."""
    return _compiled._stochastic_kernel(plan) is None and not any(w.stats for w in _compiled._plain_reflect(plan))


def threads_take(plan: "_compiled.ChunkPlan") -> bool:
    """Whether a case large enough for threads (`case_parts`) runs its chunks over them
    (`_chunk_threaded`, samples recorded in the kernel included: a sample step's rest runs on all
    atoms in one call, with a thermostat's end of step, and records the sample as the one-thread
    kernel does): not with fix dt/reset (dt may change at any step, one thread decides it), and
    wall/reflect only as `reflect_on_threads`. Decided by the scene alone."""
    return plan.dt_reset is None and reflect_on_threads(plan)


def chunk_eligible(plan: "_compiled.ChunkPlan", pair: Any) -> bool:
    """Whether `PairChunks` runs this plan: pair lj/cut on its compiled path with what the chunk
    kernels of compiled.py run: flat soft walls of the registry's compiled styles and wall/table
    faces, wall/region, one wall/flow, the `fixes:` of `compiled.fixes_eligible` (thermostats,
    enforce2d; with wall/flow too), wall/reflect on fixed dimensions, atoms outside every
    integrator's group (frozen), all of them for a case over threads too (`_chunk_threaded`); and,
    for a case on one thread (`case_parts`), wall/reflect with statistics and
    wall/reflect/stochastic (`compiled._stochastic_eligible`) on fixed dimensions
    (`reflect_on_threads`), fix dt/reset (not with wall/flow or wall values that vary with time);
    wall/lepton faces when `compiled.lepton_compiled_wanted` (kind "pair") says the run pays for
    their kernel. Nothing else."""
    if njit is None or plan.others != ("pair",):
        return False
    ens = plan.ensemble
    # a case over threads keeps on its per-step path: reflect statistics and stochastic walls, dt/reset
    if (not reflect_on_threads(plan) or plan.dt_reset is not None) and case_parts(plan.state.x.shape[1]) >= 2:
        return False
    if ens is not None and not _compiled.fixes_eligible(plan):
        return False
    if plan.dt_reset is not None and (plan.flow or _compiled.FastPath._uses_time(plan)):
        return False  # compiled.py's order with wall/flow; per-step wall values depend on dt
    if not _compiled._stochastic_eligible(plan) or any(face.dim in plan.state.periodic
                                                          for w in plan.reflect for face in w.faces):
        return False  # reflect faces on fixed dims only (the kernel reflects after the wrap)
    if not pair.compiled or pair.ncases != plan.state.ncases:
        return False
    if not _compiled.eligible(dataclasses.replace(plan, others=()), kind="pair"):
        return False
    for w in plan.soft:  # the registry's compiled styles, wall/table, or wall/lepton (generated forces)
        for st in _compiled._face_styles(w):
            if _compiled._is_table(st) or _compiled._generated_force(st) is not None:
                continue
            sid = _compiled.STYLE_IDS.get(st.name)
            if sid is None or _compiled.COMPILED_STYLES[sid] != st:
                return False
    return not any(w.style.needs_radius and not w._radius_checked for w in plan.region)


class PairChunks(_compiled.KernelPath):
    """Engine.advance for pair scenes: each case's chunk of steps in one `pair_chunk` call, on
    copies of its state that replace it when every case of the batch finished the chunk cleanly.
    Anything the kernel meets (an atom on/behind a wall, a lost atom, a non-finite value) hands the
    chunk back to the NumPy loop, which re-runs it from the same state (random streams restored)
    and reports as always. On a sampled chunk the outputs come from the NumPy `compute_forces` at
    the final positions (as compiled.FastPath), or, for a case on one thread, all the samples of a
    run of them are recorded in the kernel (`advance_sampled`). Time-based runs: the steps before
    each landing step in one chunk (`advance_to_time`)."""

    step_cost = _compiled.PAIR_STEP_COST
    least_steps = _compiled.PAIR_MIN_CALL_STEPS

    def __init__(self, plan_source: Callable[[], "_compiled.ChunkPlan"], pair: Any):
        self.plan_source = plan_source
        self.pair = pair
        self.compiled_chunks = 0
        self.fallbacks = 0
        self.threaded_chunks = 0  # case chunks run by `_chunk_threaded`
        self.busy_skip = 0  # case chunks to run in one call before trying threads again
        # a one-case batch's threaded chunk's (key, owner, first, held): its RowSplit and shares,
        # for the next chunk if it starts from that very list (`_reuse`)
        self._held: tuple | None = None
        # the chunks' copies of the state, kept across chunks (`Workspace.buffer`: a fresh array of
        # this size is a fresh mapping whose pages fault again, about 2 ms per 2.4 MB here)
        self._buffer = Workspace().buffer
        self.sampled_calls = 0  # kernel calls that recorded samples themselves (advance_sampled)
        self._sampled_refused = False  # the scene's samples are not recorded in the kernel
        # a sampled chunk met trouble before this step (with this many live cases): sample by sample
        # up to it, or until the NumPy loop dropped the case with trouble
        self._numpy_until = (-1, 0)

    def _reuse(self, c: int, C: int, parts: int, owner: np.ndarray, first: np.ndarray, pair: Any) -> dict:
        """What `_chunk_threaded` may reuse for case c (`held`): the last threaded chunk's, if it
        left this very list (same case, builds, parts, owner and first), or the split of the pair's
        own threaded pass on it (`PairLJCut.compute` of one case, e.g. the set-up's), else a fresh dict."""
        got, self._held = self._held, None
        if got is None or got[0] != (c, C, int(pair.case_builds[c]), parts, len(owner)):
            own = getattr(pair, "_split", None)
            if C == 1 and own is not None and own[0] == pair.builds and len(own[1].rb) == parts + 1:
                return {"split": own[1]}  # the list has not been rebuilt since that pass
            return {}
        if not (np.array_equal(got[1], owner) and np.array_equal(got[2], first)):
            return {}
        return got[3]

    def advance_to_time(self, target: float) -> bool:
        """Engine.advance_to_time for pair scenes: the steps every live case takes at its own dt
        before the one that lands on `target` (`steps_before`) in one chunk (`advance`'s, no
        sample), then False: the NumPy loop takes the last step(s), clipping dt to land, and
        samples. Those steps are the ones of a step-based run (the loop's dt stays, its time
        accumulator stays closed), so the bits are the NumPy loop's alone. A thermostat's target
        ramps with time / run time in such a run: the kernel's fixes take it from the case's clock
        (`clk`, `_fix_phase`'s too on threads). Not with fix dt/reset (dt may change at any step)."""
        plan = self.plan_source()
        s = plan.state
        if s.ncases == 0 or plan.dt_reset is not None:
            return False
        k = steps_before(s.atime, s.step, s.atimestep, s.dt, target)
        if _compiled.FastPath._uses_time(plan):  # per-step wall values: at most the steps `_chunk` takes
            k = min(k, _compiled.FastPath.value_steps(plan))
        if k > 0:
            self.advance(k, False)  # (trouble: nothing done, the NumPy loop meets it)
        return False

    def advance(self, nsteps: int, sample: bool) -> bool:
        """Run nsteps steps (and the sample of the last one), as kernel calls of at most
        `call_steps` steps (a Ctrl-C is seen between them); False: let the NumPy loop do it."""
        return self.in_calls(self._chunk, nsteps, sample)

    def samples_in_kernel(self, at: np.ndarray) -> bool:
        """Whether `advance_sampled` records the samples `at` (steps from now, increasing) in the
        kernel: a scene `chunk_eligible` takes whose cases run on one thread each (`case_parts`;
        a case over threads samples one instant at a time, as before). Decided by the scene alone,
        so a run keeps to one way (batch/runner.py warms that kernel); either way gives the same bits."""
        at = np.asarray(at, np.int64)
        if self._sampled_refused or at.size == 0 or at[0] <= 0 or np.any(np.diff(at) <= 0):
            return False
        plan = self.plan_source()
        s = plan.state
        if s.ncases == 0 or not enabled() or not chunk_eligible(plan, self.pair) or (
                case_parts(s.x.shape[1]) >= 2 and not threads_take(plan)):
            self._sampled_refused = s.ncases > 0  # not asked again
            return False
        until, live = self._numpy_until  # not over steps a sampled chunk met trouble in
        return int(s.step.min()) >= until or s.ncases != live

    def advance_sampled(self, at: np.ndarray) -> int:
        """Run to the sample steps `at` (counted from now, increasing), recording every sample inside
        the kernel (Engine.record_samples); returns how many were run: all of them, or 0 (nothing
        done: the caller goes sample by sample, the NumPy loop meeting the trouble a chunk met)."""
        if not self.samples_in_kernel(at):
            return 0
        at = np.asarray(at, np.int64)
        plan = self.plan_source()
        at = at[:_compiled.FastPath.sample_steps(plan, extra=2)]  # (+ the pair's energy and virial)
        at = self.one_call(at)  # the call within its share of CALL_WORK
        if _compiled.FastPath._uses_time(plan):  # per-step wall values: the steps `_chunk` takes
            at = at[at <= _compiled.FastPath.value_steps(plan)]
            if at.size == 0:
                return 0
        start = int(plan.state.step.max())
        if self._chunk(int(at[-1]), True, at):
            return int(at.size)
        self._numpy_until = (start + int(at[-1]), plan.state.ncases)  # sample by sample (`samples_in_kernel`)
        return 0

    def _chunk(self, nsteps: int, sample: bool, at: np.ndarray | None = None) -> bool:
        """`advance`, or with `at` (sample steps of this chunk, the last = nsteps) `advance_sampled`'s
        chunk: every case's samples recorded in its kernel call, then appended as one block."""
        plan = self.plan_source()
        s, pair = plan.state, self.pair
        if s.ncases == 0 or s.failed or nsteps <= 0 or not enabled() or not chunk_eligible(plan, pair):
            return False
        sample = sample and at is None  # (samples in the kernel: not the last pass's outputs handed to NumPy)
        if pair._first is None or pair._xref is None or pair._xref.shape != s.x.shape or pair._bad.any():
            return False
        C, N = s.x.shape[:2]
        varying = _compiled.FastPath._uses_time(plan)
        if varying and nsteps > _compiled.FastPath.value_steps(plan):
            return False
        values = _compiled.FastPath._values(plan, nsteps if varying else 1, varying)
        if values is None:
            self.fallbacks += 1
            return False
        sf_val = np.ascontiguousarray(values[0])
        groups: list[np.ndarray] = [np.ones(N, np.uint8)]

        def group(mask: np.ndarray, all_atoms: bool) -> int:
            if all_atoms:
                return 0
            groups.append(np.asarray(mask).astype(np.uint8))
            return len(groups) - 1

        soft_faces = [(w, st, face) for w in plan.soft for st, face in zip(_compiled._face_styles(w), w.faces)]
        extra = _compiled._lepton_extra(plan)  # generated forces (wall/lepton), numbered after the registry's styles
        sf_meta = np.array([[_compiled.face_style_id(st, extra), face.dim, face.side, group(w.group, w.all_atoms),
                             w.cutoff.mode_id] for w, st, face in soft_faces], np.int64).reshape(-1, 5)
        lp_val = _compiled._lepton_rows(soft_faces, C)  # wall/lepton faces' parameters as arrays
        tables = bool(np.any(sf_meta[:, 0] == _compiled.TABLE_STYLE))
        tb = (*_compiled._tables(soft_faces), np.zeros(((N + 63) // 64) * 64 if tables else 0, np.uint8))
        rg_meta, rg_geo, rg_val = _compiled.FastPath._regions(plan, group)
        fx, fx_fixes, fx_rngs = _compiled._fix_arrays(plan, group)  # thermostats, enforce2d
        rf_meta, rf_prev, rf_stat, stats = _compiled._reflect_arrays(plan, group)  # wall/reflect
        sto = _compiled._stochastic_arrays(plan, group)  # wall/reflect/stochastic
        sk = _compiled._stochastic_kernel(plan)
        dtr = plan.dt_reset  # fix dt/reset
        if dtr is not None:  # (no per-step values with it: `chunk_eligible`)
            dtr_group = group(dtr.group, bool(dtr.group.all()))
            dtr_par = np.ascontiguousarray(plan.dt_reset_params, dtype=float)
        else:
            dtr_group, dtr_par = 0, np.zeros((C, 4))
        clk = np.stack([s.dt, s.atime, s.atimestep], axis=1).astype(float)  # (C, 3), written by the kernel
        rf_val = np.ascontiguousarray(values[1])
        groups_arr = np.stack(groups)
        box_per = np.zeros(3, np.int64)
        box_per[s.periodic] = 1
        lo, hi = np.asarray(s.box_lo, float), np.asarray(s.box_hi, float)
        rc2 = pair.cutoff * pair.cutoff
        offset = pair.offsets()
        pair._memo = None  # (the last chunk's outputs, if no sample took them: fpair is overwritten)
        # a sampled chunk's last pair pass: its forces, for the sample
        fpair = self._buffer("fpair", (C, N, 3), float) if sample else np.empty((C, 0, 3))
        bufs = [self._buffer(k, a.shape, a.dtype) for k, a in (("x", s.x), ("v", s.v), ("f", s.f), ("xref", pair._xref),
                                                            ("owner", pair._owner), ("first", pair._first))]
        ew = np.zeros((C, 2))
        fk = plan.flow[0] if plan.flow else None
        generators = _compiled._chunk_generators(plan, fx_rngs)
        rng_states = [r.bit_generator.state for r in generators]
        if fk is not None:
            phys, pend = fk.phys.astype(np.int64), fk.pend.astype(np.int64)
            # redraws since the last sample: the pending count, then the chunk's (a sample in the
            # kernel reports and zeroes it)
            prev = np.ascontiguousarray(fk.prev, dtype=float).copy()
            cross = np.array(fk.crossings, dtype=float).reshape(C, 1)
        sm = (*_compiled._sample_arrays(at, C, sf_meta.shape[0], rf_meta.shape[0] + sto[0].shape[0], fx,
                                         rg_meta.shape[0]),
              np.zeros((C, 0 if at is None else at.size, 2)))  # (+ the pair's energy and virial)
        n = len(_compiled.COMPILED_STYLES)
        kernel = pair_chunk_for(tuple({(int(r[0]), int(r[4])) for r in sf_meta if 0 <= r[0] < n}),
                                tuple({(int(r[2]), int(r[4])) for r in rg_meta}), fk is not None, tables,
                                sk is not None, fixes=bool(fx[0].shape[0]), reflect=bool(rf_meta.shape[0]),
                                dtr=dtr is not None, extra=extra)
        if not kernel.signatures:
            _compiled.announce_compile(kernel, compile_estimate(bool(fx[0].shape[0]), bool(extra)))
        done = []
        call = backend.Repeated(kernel)  # the cases' one-thread calls: numba's typing once (same types)
        threadable = threads_take(plan)  # (else one thread: dt/reset, reflect statistics)
        for c in range(C):
            x, v, f, xref, owner, first = (b[c] for b in bufs)  # copies of the case's state (kept arrays)
            for b, a in zip((x, v, f, xref, owner, first), (s.x, s.v, s.f, pair._xref, pair._owner, pair._first)):
                np.copyto(b, a[c])
            neigh = pair._neigh[c]  # read only: a build in the chunk writes into `spare`
            spare = pair.spare_list() if C == 1 else pages.empty(pair._neigh.shape[1], np.int32)
            if fk is None:
                fl = _compiled._NO_FLOW
            else:
                fl = (np.array([1, fk.axis[c], int(fk.exact[c])], np.int64),
                      np.array([fk.lo[c], fk.length[c], fk.vflow[c], fk.kT[c]]),
                      np.ascontiguousarray(fk.walls[c][np.isfinite(fk.walls[c])]), fk.group[c].astype(np.uint8),
                      phys[c], pend[c], prev[c], cross[c], fk.rngs[c])
            args = (int(nsteps), False, x, v, f, np.ascontiguousarray(s.mass[c], dtype=float),
                    np.ascontiguousarray(s.radius[c], dtype=float), float(s.dt[c]), float(s.units.ftm2v), lo, hi,
                    box_per, pair.length, pair.periodic, float(pair.cutoff[c] + pair.skin), (0.5 * pair.skin) ** 2,
                    (24.0 * float(pair.epsilon[c]), 4.0 * float(pair.epsilon[c]), float(pair.sigma[c] ** 2),
                     float(rc2[c]), float(offset[c])), bool(sample), fpair[c], ew[c], xref, owner, first, neigh, spare,
                    sf_meta, sf_val[c], groups_arr, (rg_meta, rg_geo, rg_val[c:c + 1]), fl,
                    (_compiled._fix_slice(fx, slice(c, c + 1)), fx_rngs[c] if fx_rngs else _compiled._NO_RNGS,
                     int(s.step[c]), fix_buffers(N if fx[0].shape[0] else 0, fx[13].shape[2] // 3, self._buffer)),
                    (rf_meta, rf_val[c], rf_prev[c], rf_stat[c], bool(stats)), tb, lp_val[c],
                    (sto[0], sto[1][c:c + 1], sto[2][c:c + 1], sto[3],
                     _compiled._stochastic_rngs(plan, c), float(s.units.mvv2e)),
                    (int(dtr.every) if dtr is not None else 0, dtr_group, dtr_par[c], clk[c]),
                    (sm[0], *(a[c] for a in sm[1:])))
            parts = case_parts(N) if threadable else 1
            if parts >= 2 and self.busy_skip > 0:  # the cores were busy with other work: one thread
                self.busy_skip -= 1
                parts = 1
            held: dict = {}
            if parts >= 2:
                held = self._reuse(c, C, parts, owner, first, pair)
                wall, cpu = time.perf_counter(), time.process_time()
                ws = pair.workspace()
                status, builds, neigh = _chunk_threaded(kernel, args, parts, held, ws.crew(parts), ws.buffer)
                wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
                self.threaded_chunks += 1
                if wall > BUSY_MIN_WALL and cpu < THREAD_MIN_USE * parts * wall:
                    self.busy_skip = BUSY_SKIP
            else:  # (`call_kernel`: a Ctrl-C is a KeyboardInterrupt)
                status, builds, neigh = call(*args)
            if status != 0:
                self._held = None
                for r, st in zip(generators, rng_states):  # the NumPy loop re-runs the chunk with the same draws
                    r.bit_generator.state = st
                self.fallbacks += 1
                return False
            done.append((x, v, f, xref, owner, first, neigh, builds, held))
        if extra:  # compiled (and cached on disk by numba) by now: later processes load it
            _compiled._mark_compiled(extra, "pair")
        for c, (x, v, f, xref, owner, first, neigh, builds, held) in enumerate(done):
            s.x[c], s.v[c], s.f[c] = x, v, f
            pair._xref[c], pair._owner[c], pair._first[c] = xref, owner, first
            if builds:
                pair.adopt_list(c, neigh)
            pair.builds += builds
            pair.case_builds[c] += builds
            if held.get("split") is not None and C == 1:  # the next chunk's RowSplit, if the list stays
                kept = (self._buffer("held_owner", owner.shape, owner.dtype),
                        self._buffer("held_first", first.shape, first.dtype))
                np.copyto(kept[0], owner)
                np.copyto(kept[1], first)
                self._held = ((c, C, int(pair.case_builds[c]), len(held["shares"]) - 1, N), *kept, held)
        if sample and at is None:  # the sample's pair.compute at these positions takes them instead of a second pass
            pair.remember(s.x, fpair, ew[:, 0].copy(), ew[:, 1].copy())
        s.step += nsteps
        s.dt[...], s.atime[...], s.atimestep[...] = clk[:, 0], clk[:, 1], clk[:, 2]  # (fix dt/reset)
        s.ctx = None
        s.var_step = {}
        if fk is not None:
            fk.phys, fk.pend, fk.prev = phys.astype(np.intp), pend.astype(np.int8), prev
            fk.crossings = cross[:, 0].copy()
        if fx_fixes:
            _compiled._fix_store(fx, fx_fixes, plan)
        _compiled._reflect_store(plan, rf_prev, rf_stat, sto[2])
        if at is not None:
            self.compiled_chunks += int(at.size)  # once per sample: each the chunk it replaces
            self.sampled_calls += 1
            plan.record_samples(**self._sample_record(plan, sm, fx_fixes))
            return True
        self.compiled_chunks += 1
        _compiled.finish_chunk(plan, s, sample)
        return True

    @staticmethod
    def _sample_record(plan: "_compiled.ChunkPlan", sm: tuple, fixes: list[Any]) -> dict[str, Any]:
        """Engine.record_samples' arguments from a sampled chunk's `sm` arrays: compiled.py's
        `_sample_record` of the walls' outputs, fixes and clock, with the pair's energy and
        virial, the virial summed from the pair's as Engine.compute_forces sums it."""
        ew = sm[-1]
        args = _compiled._sample_record(plan, sm[:-1], fixes, virial=ew[:, :, 1])
        args["pair"] = (ew[:, :, 0].copy(), ew[:, :, 1].copy())
        return args


def steps_before(atime: np.ndarray, step: np.ndarray, atimestep: np.ndarray, dt: np.ndarray, target: float) -> int:
    """The steps every case takes in Engine.advance_to_time(target) before its first step that
    lands (or ends) the run: the least over the cases of the leading steps j = 0, 1, ... whose
    time now = atime + (step + j - atimestep) dt (BatchState.time) satisfies now < target - tol
    and dt < (target - now) - tol (not `landing`), with the loop's own expressions, so the count
    is exact: each of them runs at dt unclipped, as a step-based step does."""
    tol = landing_tol(target)
    atime, dt = np.asarray(atime, float), np.asarray(dt, float)
    base = np.asarray(step, np.int64) - np.asarray(atimestep, np.int64)
    if not np.all(np.isfinite(dt) & (dt > 0.0)):  # (no step would land: leave it to the loop)
        return 0

    def unclipped(j: np.ndarray) -> np.ndarray:
        now = atime + (base + j) * dt
        return (now < target - tol) & (dt < target - now - tol)

    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        guess = np.floor((target - atime) / dt) - base - 2.0  # about where the first clipped step is
    j = np.where(np.isfinite(guess), np.clip(guess, 0.0, 2.0**52), 0.0).astype(np.int64)
    while True:  # back to a step that is unclipped (or 0) ...
        back = (j > 0) & ~unclipped(j - 1)
        if not back.any():
            break
        j = np.where(back, j - 1, j)
    while True:  # ... then forward to the first clipped one: j unclipped steps before it
        ahead = unclipped(j)
        if not ahead.any():
            break
        j = np.where(ahead, j + 1, j)
    return int(j.min()) if j.size else 0


def attach_pair_chunks(plan_source: Callable[[], "_compiled.ChunkPlan"], pair: Any) -> PairChunks | None:
    """The fused chunks for the engine whose plans `plan_source` gives, or None."""
    if not enabled() or not chunk_eligible(plan_source(), pair):
        return None
    return PairChunks(plan_source, pair)
