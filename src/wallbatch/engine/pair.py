"""Batched Lennard-Jones pair forces, `pair_style lj/cut` with one atom type (physics.md §12).

For a pair i, j at distance r < rc (minimum image in periodic dimensions):

    E(r)  = 4 eps [ (sigma/r)^12 - (sigma/r)^6 ]  (- E(rc) with `pair_modify shift yes`) [energy]
    F_i   = (24 eps / r^2) [ 2 (sigma/r)^12 - (sigma/r)^6 ] (x_i - x_j),   F_j = -F_i     [force]

Each pair is counted once. The shift changes only the energy. The virial is the trace of
LAMMPS's virial tensor, W = sum over pairs of r_ij . F_ij [energy], so the caller gets
press = (dof kB T + W) / (3 V) * nktv2p.

Units are LAMMPS's: positions, sigma, cutoff and skin [length], eps [energy], forces
[energy/length] (lj: reduced; real: kcal/mol/Angstrom; metal: eV/Angstrom). No conversion
factor enters the pair force.

Neighbor list (Verlet list with a skin, like LAMMPS's `neigh_modify every 1 delay 0 check yes`):
each case keeps the pairs closer than rc + skin at its last build, found with
`scipy.spatial.cKDTree`. A case is rebuilt, alone, when one of its atoms has moved more than
skin/2 (minimum image in periodic dimensions) since that case's last build. Rebuilding per case,
never the whole batch, keeps each case's pair order, and so its forces bit for bit, independent of
which other cases share its batch. The pairs of all cases are stored flattened (atom index
c*N + i), so one vectorised pass over all pairs of all cases computes the forces; the scatter to
atoms sums the runs of equal i (pairs are sorted by i) with `np.add.reduceat` and the j side
with `np.bincount` (for 156k pairs: 1 ms, against 2 ms with six `np.bincount` and 12 ms with
`np.add.at`); work arrays are reused between steps.

Compiled path (pair_compiled.py; the default when numba imports and WALLBATCH_NUMBA is not "0",
`compiled=False` forces NumPy): the same per-case rebuild decisions, a cell-list build per case
(the same pairs, each once, in cell order; CSR rows in (C, ...) arrays) and a force pass per case
that gathers each row's separations into contiguous buffers, computes the pair terms in one
vectorised loop and adds them in list order (with outputs, the energy and virial in the same pass).
Each pair's values come from the same functions (lj.py's `min_image`, `lj_terms`, compiled into
the kernels); only the order of the sums differs, so the paths agree to rounding
(tests: <= 1e-13 relative to the case's force, energy and virial scales). Each case is still
computed alone, so its numbers never depend on its batch. For N = 4000 at density 0.8 (137k
pairs): force pass ~0.7 ms, build ~2 ms; for N = 97,556 (3.4M pairs) ~17 ms and ~33 ms. Scenes
whose other fixes the chunk kernels run (flat soft walls, wall/region, one wall/flow) run whole
chunks of steps in one compiled call per case (a long chunk in several: pair_compiled.PairChunks),
with the same bits as this path step by step; a sampled chunk's outputs come from its last force pass (`remember`).
"""

from __future__ import annotations

import numpy as np

from wallbatch.engine import backend, pages
from wallbatch.engine.lj import lj_terms, min_image

# LAMMPS's default neighbor skin per unit style [length] (0.3 sigma in lj; 2 Angstrom in real/metal)
DEFAULT_SKIN = {"lj": 0.3, "real": 2.0, "metal": 2.0}


def default_skin(units: str) -> float:
    """LAMMPS's default neighbor skin [length] for a unit style."""
    return DEFAULT_SKIN[units]


def lj_pair(r2: np.ndarray, epsilon, sigma) -> tuple[np.ndarray, np.ndarray]:
    """Unshifted pair energy E(r) [energy] and fpair = F/r = -(dE/dr)/r [force/length] from r^2.

    E = 4 eps (s6^2 - s6), fpair = 24 eps (2 s6^2 - s6) / r^2 with s6 = (sigma^2 / r^2)^3
    (`lj_terms` without a cut-off); everything broadcasts.
    """
    fpair, energy = lj_terms(r2, 24.0 * epsilon, 4.0 * epsilon, sigma * sigma, np.inf, 0.0)
    return energy, fpair


class PairLJCut:
    """`pair_style lj/cut` for a batch of C cases of N atoms (one atom type, one box).

    epsilon [energy], sigma [length], cutoff [length]: per-case (C,) arrays (scalars broadcast).
    shift: `pair_modify shift yes` (energy only). box_lo, box_hi (3,) [length]; periodic (3,) bool.
    skin [length]: neighbor skin (LAMMPS default: :func:`default_skin`). Minimum image needs
    cutoff < L/2 in every periodic dimension.

    `builds` counts neighbor-list builds over all cases, `case_builds` (C,) per case.
    compiled: use the numba kernels (default: when numba imports and WALLBATCH_NUMBA != "0");
    False forces the NumPy path.
    """

    def __init__(self, epsilon, sigma, cutoff, *, box_lo, box_hi, periodic, shift: bool = False,
                 skin: float = DEFAULT_SKIN["lj"], compiled: bool | None = None):
        eps, sig, rc = np.broadcast_arrays(*(np.atleast_1d(np.asarray(a, dtype=float))
                                             for a in (epsilon, sigma, cutoff)))
        if eps.ndim != 1:
            raise ValueError("epsilon, sigma and cutoff must be scalars or (C,) arrays")
        self.box_lo = np.asarray(box_lo, dtype=float).reshape(3)
        self.box_hi = np.asarray(box_hi, dtype=float).reshape(3)
        self.periodic = np.asarray(periodic, dtype=bool).reshape(3)
        self.length = self.box_hi - self.box_lo
        self.shift = bool(shift)
        self.skin = float(skin)
        if not np.all(np.isfinite(eps)) or np.any(eps < 0):
            raise ValueError(f"pair lj/cut: epsilon must be finite and >= 0, got {eps}")
        if not np.all(np.isfinite(sig)) or np.any(sig <= 0):
            raise ValueError(f"pair lj/cut: sigma must be finite and > 0, got {sig}")
        if not np.all(np.isfinite(rc)) or np.any(rc <= 0):
            raise ValueError(f"pair lj/cut: cutoff must be finite and > 0, got {rc}")
        if not np.isfinite(self.skin) or self.skin < 0:
            raise ValueError(f"pair lj/cut: neighbor skin must be >= 0, got {skin}")
        if np.any(self.length <= 0):
            raise ValueError("pair lj/cut: box_hi must exceed box_lo in every dimension")
        for d in np.flatnonzero(self.periodic):
            if np.any(2.0 * rc >= self.length[d]):
                raise ValueError(f"pair lj/cut: cutoff {rc.max()} must be less than half the periodic box "
                                 f"length {self.length[d]} in {'xyz'[d]} (minimum image)")
        self.epsilon, self.sigma, self.cutoff = eps.copy(), sig.copy(), rc.copy()
        self.builds = 0
        self.case_builds = np.zeros(len(eps), dtype=np.int64)
        self._pairs: list[np.ndarray] = [np.empty((0, 2), dtype=np.int64)] * len(eps)  # local (i, j), i < j
        self._bad = np.zeros(len(eps), dtype=bool)  # non-finite positions at the last build
        self._xref: np.ndarray | None = None  # (C, N, 3) positions at each case's last build
        self._flat: dict[str, np.ndarray] | None = None
        self._work = np.empty((5, 0))
        want = backend.numba_allowed() if compiled is None else bool(compiled)  # numba imported only if wanted
        self._nb = None  # the pair_compiled module on the compiled path
        if want:
            from wallbatch.engine import pair_compiled as pair_numba

            if pair_numba.njit is None:
                if compiled:
                    raise RuntimeError("pair lj/cut: compiled=True needs numba")
                want = False
            else:
                self._nb = pair_numba
        self.compiled = want
        self._first: np.ndarray | None = None  # compiled path: (C, N+1) CSR row starts per case
        self._owner = np.empty((len(eps), 0), dtype=np.int32)  # (C, N) atom of each CSR row
        self._neigh = np.empty((len(eps), 0), dtype=np.int32)  # (C, capacity) j of each pair
        self._memo: tuple[np.ndarray, ...] | None = None  # remember(): outputs of a compiled chunk's last step
        self._memo_x: np.ndarray | None = None  # remember()'s copy of the positions (kept array)
        self._spare = np.empty(0, dtype=np.int32)  # a one-case batch's second pair array (spare_list)
        self._split: tuple[int, object] | None = None  # (builds, RowSplit) of one large case's threaded pass
        self._ws = None  # pair_compiled.Workspace of one large case's threaded builds and passes (`workspace`)

    def workspace(self):  # noqa: ANN201 - pair_compiled.Workspace (imported lazily)
        """The kept work arrays and threads of this pair's threaded builds and passes (compiled path)."""
        if self._ws is None:
            self._ws = self._nb.Workspace()
        return self._ws

    @property
    def ncases(self) -> int:
        return len(self.epsilon)

    @property
    def npairs(self) -> int:
        """Pairs in the neighbor lists of all cases (closer than cutoff + skin at their builds)."""
        if self.compiled:
            return 0 if self._first is None else int(self._first[:, -1].sum())
        return sum(len(p) for p in self._pairs)

    # -- neighbor list -----------------------------------------------------------------------

    def _min_image(self, d: np.ndarray) -> np.ndarray:
        """Minimum image in periodic dims of displacements d (..., 3), in place."""
        for k in np.flatnonzero(self.periodic):
            dk = d[..., k]
            dk -= self.length[k] * np.rint(dk / self.length[k])
        return d

    def _build(self, c: int, pos: np.ndarray) -> None:
        """Pairs (i < j) of case c closer than cutoff + skin, with a cKDTree."""
        self.builds += 1
        self.case_builds[c] += 1
        self._bad[c] = not np.isfinite(pos).all()
        if self._bad[c] or len(pos) < 2:
            self._pairs[c] = np.empty((0, 2), dtype=np.int64)
            return
        reach = self.cutoff[c] + self.skin
        p = pos - self.box_lo
        boxsize = np.empty(3)
        for k in range(3):
            if self.periodic[k]:
                pk = np.mod(p[:, k], self.length[k])
                pk[pk >= self.length[k]] = 0.0  # np.mod(-tiny, L) rounds to L
                p[:, k] = pk
                boxsize[k] = self.length[k]
            else:  # cKDTree wraps every dim: a period longer than extent + reach never joins two atoms
                p[:, k] -= p[:, k].min()
                top = p[:, k].max()
                boxsize[k] = top + 2.0 * reach + 1.0
                if boxsize[k] <= top:  # reach lost to rounding (an atom at 1e60): 1 ulp is > reach
                    boxsize[k] = np.nextafter(top, np.inf)
        from scipy.spatial import cKDTree  # lazy: ~0.2 s of import, only for the NumPy pair path

        pairs = cKDTree(p, boxsize=boxsize).query_pairs(reach, output_type="ndarray")
        key = np.sort(pairs[:, 0].astype(np.int64) * len(pos) + pairs[:, 1])  # by i, then j
        self._pairs[c] = np.stack(np.divmod(key, len(pos)), axis=1)

    def _flatten(self, natoms: int) -> None:
        """All cases' pairs as one flat list (atom c*N + i), with per-pair coefficients, the runs of
        equal i (pairs are sorted by i within a case) and the pair ranges of the cases."""
        counts = np.array([len(p) for p in self._pairs], dtype=np.int64)
        case = np.repeat(np.arange(self.ncases), counts)
        both = np.concatenate(self._pairs) if self._pairs else np.empty((0, 2), dtype=np.int64)
        i, j = both[:, 0] + case * natoms, both[:, 1] + case * natoms
        eps, sig, rc = self.epsilon, self.sigma, self.cutoff
        coef = {"eps": eps, "sig2": sig * sig, "rc2": rc * rc, "offset": self.offsets()}
        uniform = len(eps) > 0 and all(np.all(v == v[0]) for v in coef.values())
        run = np.flatnonzero(np.r_[True, i[1:] != i[:-1]]) if len(i) else np.empty(0, dtype=np.int64)
        starts = np.r_[0, np.cumsum(counts)[:-1]].astype(np.int64)
        flat = {"i": i, "j": j, "run": run, "run_atom": i[run],
                "case_start": starts[counts > 0], "case_nonempty": counts > 0}
        for k, v in coef.items():  # one number when all cases agree, else one value per pair
            flat[k] = float(v[0]) if uniform else v[case]
        self._flat = flat
        if self._work.shape[1] < len(i):  # reused work arrays (grow only): no fresh pages each step
            self._work = np.empty((5, int(1.2 * len(i))))

    def _update(self, x: np.ndarray) -> None:
        """Rebuild the cases with an atom moved more than skin/2 since their last build."""
        C, N = x.shape[:2]
        if C != self.ncases:
            raise ValueError(f"pair lj/cut holds {self.ncases} cases, x has {C}")
        if self._xref is None or self._xref.shape != x.shape:
            need = np.ones(C, dtype=bool)
            self._xref = np.array(x, dtype=float)
        else:
            d = self._min_image(x - self._xref)
            moved2 = np.einsum("cni,cni->cn", d, d).max(axis=1, initial=0.0)
            need = ~(moved2 <= (0.5 * self.skin) ** 2)  # NaN positions rebuild (and are flagged bad)
        if need.any() or self._flat is None:
            for c in np.flatnonzero(need):
                self._build(c, x[c])
                self._xref[c] = x[c]
            self._flatten(N)

    def _build_compiled(self, c: int, pos: np.ndarray) -> None:
        """Pairs of case c closer than cutoff + skin (each once), with the cell-list kernel."""
        self.builds += 1
        self.case_builds[c] += 1
        self._bad[c] = not np.isfinite(pos).all()
        if self._bad[c] or len(pos) < 2:
            self._first[c] = 0
            return
        reach = float(self.cutoff[c] + self.skin)
        parts = self._nb.case_parts(len(pos)) if self.ncases == 1 else 1  # one large case: over threads
        if self._neigh.shape[1] < len(pos):  # the first build: room for the pairs guessed (not a try in vain)
            self._grow(self._estimate_pairs(pos, reach))
        while True:  # the case's rows of the (C, ...) arrays are the kernel's output buffers
            if parts >= 2:  # the same list, bit for bit
                ws = self.workspace()
                m = self._nb.build_threaded(pos, self.box_lo, self.length, self.periodic, reach,
                                            self._owner[c], self._first[c], self._neigh[c], parts, ws.crew(parts),
                                            buffer=ws.buffer)
            else:
                m = self._nb.build_case(pos, self.box_lo, self.length, self.periodic, reach,
                                        self._owner[c], self._first[c], self._neigh[c])
            if m >= 0:
                return
            self._grow(self._estimate_pairs(pos, reach))

    def _estimate_pairs(self, pos: np.ndarray, reach: float) -> int:
        """Upper guess of the pairs within reach: uniform density in the atoms' bounding volume."""
        n = len(pos)
        span = np.where(self.periodic, self.length, self._nb.atom_extent(pos) + reach)
        ball = 4.0 / 3.0 * np.pi * reach**3
        guess = 0.5 * n * n * min(1.0, ball / float(np.prod(span)))
        return int(1.3 * guess) + 2 * len(pos) + 2 * self._neigh.shape[1]

    def _grow(self, capacity: int) -> None:
        """Grow every case's row of the pair array to at least `capacity` (keeps the content)."""
        grown = pages.empty((self.ncases, capacity), np.int32)  # (4 kB pages: pages.py)
        grown[:, :self._neigh.shape[1]] = self._neigh
        self._neigh = grown

    def spare_list(self) -> np.ndarray:
        """A one-case batch's spare pair array (capacity of the current one), for a compiled chunk
        to build into while the current list stays intact (`adopt_list` swaps them)."""
        if len(self._spare) < self._neigh.shape[1]:
            self._spare = pages.empty(self._neigh.shape[1], np.int32)
        return self._spare

    def adopt_list(self, c: int, neigh: np.ndarray) -> None:
        """Case c's pairs are now neigh[:first[c, -1]] (owner and first already written): a
        one-case batch takes the array itself (the old one becomes the spare), others copy."""
        m = int(self._first[c, -1])
        if self.ncases == 1 and neigh.dtype == np.int32 and neigh.flags.c_contiguous:
            self._spare, self._neigh = self._neigh[0], neigh.reshape(1, -1)
            return
        if m > self._neigh.shape[1]:
            self._grow(len(neigh))
        self._neigh[c, :m] = neigh[:m]

    def _update_compiled(self, x: np.ndarray) -> None:
        """As _update, with the compiled displacement check and cell-list build."""
        C, N = x.shape[:2]
        if C != self.ncases:
            raise ValueError(f"pair lj/cut holds {self.ncases} cases, x has {C}")
        if self._xref is None or self._xref.shape != x.shape or self._first is None:
            need = np.ones(C, dtype=bool)
            self._xref = np.array(x, dtype=float)
            self._first = np.zeros((C, N + 1), dtype=np.int64)
            self._owner = np.zeros((C, N), dtype=np.int32)
        else:
            need = np.empty(C, dtype=bool)
            self._nb.moved_cases(x, self._xref, self.length, self.periodic, (0.5 * self.skin) ** 2, need)
        for c in np.flatnonzero(need):
            self._build_compiled(c, x[c])
            self._xref[c] = x[c]

    def offsets(self) -> np.ndarray:
        """Energy shift per case (C,) [energy]: E(rc) with `pair_modify shift yes`, else 0."""
        eps, sig, rc = self.epsilon, self.sigma, self.cutoff
        return lj_pair(rc * rc, eps, sig)[0] if self.shift else np.zeros_like(eps)

    def remember(self, x: np.ndarray, f: np.ndarray, energy: np.ndarray, virial: np.ndarray) -> None:
        """Keep the pair forces f (C, N, 3), energy and virial (C,) that the compiled chunk computed
        at positions x (its last step): the next compute() at exactly these positions returns them
        instead of a second pass (a sampled chunk's outputs). Any other call forgets them."""
        keep = self._memo_x  # the positions' copy goes into the same array each time (no fresh pages)
        if keep is None or keep.shape != np.shape(x):
            keep = self._memo_x = np.array(x, dtype=float)
        else:
            np.copyto(keep, x)
        self._memo = (keep, f, energy, virial)

    def _recall(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
        memo, self._memo = self._memo, None
        if memo is None or memo[0].shape != x.shape or not np.array_equal(memo[0], x):
            return None
        return memo[1:]

    def _compute_compiled(self, x: np.ndarray, f: np.ndarray, outputs: bool) -> tuple[np.ndarray, np.ndarray] | None:
        """compute() with the fused kernel: per case, one pass over its half list (forces, and
        energy and virial with outputs)."""
        C = x.shape[0]
        memo = self._recall(x)
        if memo is not None:
            f += memo[0]
            return (memo[1].copy(), memo[2].copy()) if outputs else None
        self._update_compiled(x)
        eps, sig, rc = self.epsilon, self.sigma, self.cutoff
        offset = self.offsets()
        direct = f.dtype == np.float64 and f.flags.c_contiguous
        out = f if direct else np.zeros(x.shape)
        energy, virial = np.zeros(C), np.zeros(C)
        parts = self._nb.case_parts(x.shape[1]) if C == 1 and not self._bad[0] else 1
        if parts >= 2:  # one large case over threads: the same bits
            held = self._split if self._split is not None and self._split[0] == self.builds else None
            energy[0], virial[0], split = self._nb.forces_case_threaded(
                x[0], out[0], self._owner[0], self._first[0], self._neigh[0], 24.0 * float(eps[0]),
                4.0 * float(eps[0]), float(sig[0] * sig[0]), float(rc[0] * rc[0]), float(offset[0]), self.length,
                self.periodic, bool(outputs), parts, None if held is None else held[1], self.workspace().crew(parts),
                self.workspace().buffer)
            self._split = (self.builds, split)  # kept while no build changes the list
        else:
            self._nb.forces(x, out, self._owner, self._first, self._neigh, eps, sig * sig, rc * rc, offset,
                            self.length, self.periodic, self._bad, bool(outputs), energy, virial)
        if not direct:
            f += out
        if self._bad.any():
            f[self._bad] = np.nan
        if not outputs:
            return None
        energy[self._bad] = np.nan
        virial[self._bad] = np.nan
        return energy, virial

    # -- forces ------------------------------------------------------------------------------

    def compute(self, x: np.ndarray, f: np.ndarray, outputs: bool) -> tuple[np.ndarray, np.ndarray] | None:
        """Add pair forces [force] into f (C, N, 3) in place for positions x (C, N, 3) [length].

        With `outputs`, return (energy (C,) [energy], virial W (C,) [energy]), W = sum r_ij . F_ij. A case whose positions are not finite gets NaN forces
        (and NaN energy and virial).
        """
        if self.compiled:
            return self._compute_compiled(np.ascontiguousarray(x, dtype=np.float64), f, outputs)
        C, N = x.shape[:2]
        self._update(x)
        p = self._flat
        i, j = p["i"], p["j"]
        dx, dy, dz, r2, t = self._work[:, :len(i)]
        xt = np.ascontiguousarray(x.reshape(C * N, 3).T)  # (3, C*N): fast 1-D gathers
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            for k, dk in enumerate((dx, dy, dz)):  # d = x_i - x_j, minimum image
                xt[k].take(i, out=dk, mode="clip")  # indices are valid; "clip" avoids a buffer copy
                dk -= xt[k].take(j, out=t, mode="clip")
                if self.periodic[k]:
                    dk[:] = min_image(dk, 1.0 / self.length[k], self.length[k])
            np.multiply(dx, dx, out=r2)
            r2 += np.multiply(dy, dy, out=t)
            r2 += np.multiply(dz, dz, out=t)
            eps = p["eps"]
            fpair, e = lj_terms(r2, 24.0 * eps, 4.0 * eps, p["sig2"], p["rc2"], p["offset"])
            for k, dk in enumerate((dx, dy, dz)):  # F_i += fpair d, F_j -= fpair d
                np.multiply(fpair, dk, out=t)
                fk = -np.bincount(j, t, C * N)
                if len(i):
                    fk[p["run_atom"]] += np.add.reduceat(t, p["run"])  # i is grouped: runs of equal i
                f[:, :, k] += fk.reshape(C, N)
            if self._bad.any():
                f[self._bad] = np.nan
            if not outputs:
                return None
            energy, virial = np.zeros(C), np.zeros(C)
            if len(i):
                energy[p["case_nonempty"]] = np.add.reduceat(e, p["case_start"])
                np.multiply(fpair, r2, out=t)  # r . F = fpair r^2
                virial[p["case_nonempty"]] = np.add.reduceat(t, p["case_start"])
        energy[self._bad] = np.nan
        virial[self._bad] = np.nan
        return energy, virial

    def energy_forces(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Energy (C,) [energy] and pair forces (C, N, 3) [force] in fresh arrays (for a minimizer)."""
        f = np.zeros_like(x, dtype=float)
        energy, _ = self.compute(x, f, True)
        return energy, f

    def take(self, keep: np.ndarray) -> None:
        """Keep only some cases (a boolean (C,) mask or indices), in the given order."""
        keep = np.asarray(keep)
        idx = np.flatnonzero(keep) if keep.dtype == bool else keep.astype(np.int64).ravel()
        self._memo = self._split = None
        self._spare = np.empty(0, dtype=np.int32)
        self.epsilon, self.sigma, self.cutoff = self.epsilon[idx], self.sigma[idx], self.cutoff[idx]
        self.case_builds = self.case_builds[idx]
        self._bad = self._bad[idx]
        self._pairs = [self._pairs[c] for c in idx.tolist()]
        self._neigh = self._neigh[idx]
        if self._first is not None:
            self._first, self._owner = self._first[idx], self._owner[idx]
        if self.compiled:
            if self._xref is not None:
                self._xref = self._xref[idx]
            return
        if self._xref is not None:
            self._xref = self._xref[idx]
            self._flatten(self._xref.shape[1])
        else:
            self._flat = None
