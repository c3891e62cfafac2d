"""Profiles across the box: LAMMPS `compute chunk/atom bin/1d` + `fix ave/chunk ... norm all`,
batched over cases.

At each sample step (every `every` steps, the last `repeat` of them before a window closes at a
multiple of `freq`) the atoms of the profile's group are binned along the axis,
bin = floor((x - lo) / delta) clipped to [0, nbins - 1] (LAMMPS `discard mixed`), and per bin the
count, mass, m v^2 and velocity components are summed with one `np.bincount` over all cases at
once (flat index case * nbins + bin: no Python loop over atoms). When the window closes:

    density/number = sum(count) / repeat / V_bin               [1/distance^3]
    density/mass   = sum(m) / repeat / V_bin * mv2d             [mass/distance^3; g/cm^3 real, metal]
    temp           = mvv2e sum(m v^2) / (d sum(count) k_B)      [temperature] (LAMMPS adof = d, cdof 0)
    vx, vy, vz     = sum(v) / sum(count)                        [velocity]

V_bin = box volume * delta / L_axis (d = 2: box area * delta / L_axis, densities per area, as
LAMMPS); a bin with no atom in the window is 0 (not NaN).
"""

from __future__ import annotations

import numpy as np

from wallbatch.engine.state import BatchState
from wallbatch.scene.case import Case, ProfileSpec

MV2D = {"lj": 1.0, "real": 1.0 / 0.602214129, "metal": 1.0 / 0.602214129}  # mass/volume -> g/cm^3

_SUMS = {"density/number": ("count",), "density/mass": ("mass",), "temp": ("count", "mv2"),
         "vx": ("count", "vx"), "vy": ("count", "vy"), "vz": ("count", "vz")}


def output_name(profile: str, quantity: str) -> str:
    """Results variable of a profile quantity: profile_<name>_<quantity> with / -> _."""
    return f"profile_{profile}_{quantity.replace('/', '_')}"


def bin_index(coord: np.ndarray, lo: np.ndarray | float, delta: np.ndarray | float, nbins: int) -> np.ndarray:
    """Bin of each coordinate (C, N) with per-case origin `lo` and width `delta` ((C,) or
    scalars): floor((x - lo) / delta) as LAMMPS computes it (times 1/delta), clipped into range."""
    lo = np.asarray(lo, float)
    inv = 1.0 / np.asarray(delta, float)
    if lo.ndim:
        lo, inv = lo[:, None], inv[:, None]
    b = np.floor((coord - lo) * inv)
    return np.clip(b, 0, nbins - 1).astype(np.int64)


def bin_sums(bins: np.ndarray, rows: np.ndarray, nbins: int, ncases: int,
             weights: np.ndarray | None = None) -> np.ndarray:
    """Per-case, per-bin sums (ncases, nbins) of `weights` (C, N) (counts when None) for atoms in
    bins (C, N) of the live cases `rows` (C,), indices into the ncases output rows."""
    flat = (rows[:, None] * nbins + bins).ravel()
    w = None if weights is None else np.asarray(weights, float).ravel()
    return np.bincount(flat, weights=w, minlength=ncases * nbins).reshape(ncases, nbins)


class ProfileSampler:
    """Accumulates every profile of a batch and stores each closed window.

    Arrays are indexed by the batch's original case index (BatchState.rows), so cases that fail
    and leave the batch keep their rows; a failed case's windows are NaN in the results.
    """

    def __init__(self, cases: list[Case]):
        c0 = cases[0]
        self.specs: tuple[ProfileSpec, ...] = c0.profiles
        self.units = c0.units
        self.ncases = len(cases)
        steps = int(c0.steps or 0)
        self.dimension = int(c0.dimension)
        self.lengths = c0.box_hi - c0.box_lo
        self.volume = float(np.prod(self.lengths[:self.dimension]))  # an area in 2-D, as LAMMPS
        self.windows = [p.window_steps(steps) for p in self.specs]
        self.samples = [set(p.sample_steps(steps)) for p in self.specs]
        self.instants = sorted(set().union(*self.samples)) if self.samples else []
        self.sums: list[dict[str, np.ndarray]] = []
        self.out: list[dict[str, np.ndarray]] = []
        for p, wins in zip(self.specs, self.windows):
            need = sorted({k for q in p.quantities for k in _SUMS[q]})
            self.sums.append({k: np.zeros((self.ncases, p.nbins)) for k in need})
            self.out.append({q: np.full((self.ncases, len(wins), p.nbins), np.nan) for q in p.quantities})

    def sample(self, s: BatchState) -> None:
        """Bin the live cases at the current step (all cases of a step-based batch share it)."""
        if s.ncases == 0:
            return
        step = int(s.step[0])
        for p, samples, sums, out, wins in zip(self.specs, self.samples, self.sums, self.out, self.windows):
            if step not in samples:
                continue
            g = p.group
            x = s.x[:, g, p.axis]
            bins = bin_index(x, p.lo, p.delta, p.nbins)
            m = np.broadcast_to(s.mass[:, g], x.shape)
            v = s.v[:, g, :]
            rows = s.rows
            weights = {"count": None, "mass": m, "mv2": m * np.einsum("cni,cni->cn", v, v),
                       "vx": v[..., 0], "vy": v[..., 1], "vz": v[..., 2]}
            for key, acc in sums.items():
                acc += bin_sums(bins, rows, p.nbins, self.ncases, weights[key])
            if step % p.freq == 0:
                self._close(p, sums, out, wins.index(step), rows)

    def _close(self, p: ProfileSpec, sums: dict[str, np.ndarray], out: dict[str, np.ndarray], k: int,
               rows: np.ndarray) -> None:
        """Normalise the window's sums (norm all) into window k of the live rows, then reset."""
        u = self.units
        vbin = self.volume * p.delta / self.lengths[p.axis]
        count = sums.get("count")
        with np.errstate(invalid="ignore", divide="ignore"):
            for q in p.quantities:
                if q == "density/number":
                    val = sums["count"] / p.repeat / vbin
                elif q == "density/mass":
                    val = sums["mass"] / p.repeat / vbin * MV2D[u.name]
                elif q == "temp":
                    val = np.where(count > 0, u.mvv2e * sums["mv2"] / (self.dimension * count * u.boltz), 0.0)
                else:
                    val = np.where(count > 0, sums[q] / count, 0.0)
                out[q][rows, k] = val[rows]
        for acc in sums.values():
            acc[:] = 0.0

    def case_data(self, c: int, failed: bool) -> dict[str, np.ndarray]:
        """Case c's windows: output name -> (windows, bins); NaN for a failed case."""
        data = {}
        for p, out in zip(self.specs, self.out):
            for q, arr in out.items():
                data[output_name(p.name, q)] = np.full_like(arr[c], np.nan) if failed else arr[c]
        return data
