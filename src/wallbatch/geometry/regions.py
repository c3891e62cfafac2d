"""Regions (block, sphere, cylinder): geometry and contact lists (the fix wall/region kernel is in
wallbatch.engine.region_walls) (physics.md §5, §5.1).

A :class:`RegionGeom` is a static region in box units with a side (``in``: the allowed space is
the inside, surface included; ``out``: strictly outside). Its :meth:`RegionGeom.contacts` gives
the LAMMPS contact list of §5.1: for every atom on the allowed side, the surface points within
the cut-off, each as ``delta = x_atom - x_surface`` [length] with ``r = |delta|``.

:class:`RegionWallKernel` is fix wall/region over a batch of cases sharing one region and one
potential style: per contact, force ``F(r) delta / r`` on the atom (``F > 0`` pushes the atom away
from the surface, into the allowed side), energy ``E(r) - E(rc)`` (harmonic: ``eps (rc - r)^2``),
vector = ``-sum`` of the atom forces (the force on the wall). Colloid uses the fix wall/colloid
physics of §4.6 (wallbatch's decision); :func:`lammps_region_colloid` is LAMMPS's inconsistent
formula (quirk #1), kept only to pin the difference in tests.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np


LAMMPS_MESSAGE = "Particle outside surface of region used in fix wall/region"
LAMMPS_EES_MESSAGE = "Particle on or inside surface of region used in fix wall/region/ees"


def _norm(d: np.ndarray) -> np.ndarray:
    """|d| over the last axis as sqrt(sum of squares), the way LAMMPS computes region distances."""
    return np.sqrt(np.sum(d * d, axis=-1))


@dataclass(frozen=True)
class RegionGeom:
    """A static region in box units (physics.md §5.1).

    block: ``lo``, ``hi`` corners (3-tuples). sphere: ``center`` (3-tuple), ``radius``.
    cylinder: ``axis`` (0, 1, 2), ``center`` (c1, c2) in the two other dims in xyz order,
    ``radius``, ``lo``, ``hi`` (floats along the axis).
    """

    style: str
    side: str = "in"
    lo: Any = None
    hi: Any = None
    center: tuple[float, ...] | None = None
    radius: float | None = None
    axis: int | None = None

    @classmethod
    def from_config(cls, region: Any, spacing: float | None) -> "RegionGeom":
        """Resolve a config region: lattice units multiply every coordinate and the radius by the
        (cubic) lattice spacing, box units by 1. Lattice units without a lattice is an error."""
        if region.units == "box":
            s = 1.0
        elif spacing is None:
            raise ValueError("a region in lattice units (the default) needs a `lattice:`; "
                             "add `units: box` to the region or define a lattice")
        else:
            s = float(spacing)

        def scaled(v):
            if v is None:
                return None
            return tuple(float(a) * s for a in v) if isinstance(v, (tuple, list)) else float(v) * s

        axis = None if region.axis is None else "xyz".index(region.axis)
        return cls(region.style, region.side, scaled(region.lo), scaled(region.hi), scaled(region.center),
                   scaled(region.radius), axis)

    # -- side test -------------------------------------------------------------------------

    def inside(self, x: np.ndarray) -> np.ndarray:
        """Inside or on the surface (LAMMPS's `<=` / `>=` tests), whatever the side. (...,3) -> (...)"""
        x = np.asarray(x, float)
        if self.style == "block":
            return np.all((x >= self.lo) & (x <= self.hi), axis=-1)
        if self.style == "sphere":
            return _norm(x - self.center) <= self.radius
        rho, a = self._cyl(x)
        return (rho <= self.radius) & (a >= self.lo) & (a <= self.hi)

    def contains(self, x: np.ndarray) -> np.ndarray:
        """The §5 side test: True where an atom is on the allowed side (side in: inside or on the
        surface; side out: strictly outside). (...,3) -> (...) bool"""
        ins = self.inside(x)
        return ins if self.side == "in" else ~ins

    def distance(self, x: np.ndarray) -> np.ndarray:
        """Unsigned distance [length] from x to the region surface, from either side (for messages).
        (...,3) -> (...)"""
        x = np.asarray(x, float)
        if self.style == "sphere":
            return np.abs(_norm(x - self.center) - self.radius)
        if self.style == "block":
            lo, hi = np.asarray(self.lo), np.asarray(self.hi)
            out = _norm(x - np.clip(x, lo, hi))
            depth = np.minimum(x - lo, hi - x).min(axis=-1)
            return np.where(self.inside(x), depth, out)
        rho, a = self._cyl(x)
        radial = np.maximum(rho - self.radius, 0.0)
        axial = a - np.clip(a, self.lo, self.hi)
        depth = np.minimum(self.radius - rho, np.minimum(a - self.lo, self.hi - a))
        return np.where(self.inside(x), depth, np.sqrt(radial * radial + axial * axial))

    def misses_box(self, lo: Any, hi: Any) -> bool:
        """True when no point of the closed box [lo, hi] (box units) is on the allowed side: a
        side-in region lying wholly outside it (not even touching it), or a side-out region whose
        shape holds it whole. An axis with lo == hi (the z = 0 plane of a 2-D run) is a plane."""
        lo, hi = np.asarray(lo, float), np.asarray(hi, float)
        if self.side == "out":  # strictly outside the shape: nothing is left when the shape holds the box
            corners = np.array(np.meshgrid(*zip(lo, hi), indexing="ij")).reshape(3, -1).T
            return bool(np.all(self.inside(corners)))

        def gap(centre: np.ndarray, dims: list[int]) -> float:  # distance from a point to the box (those dims)
            return float(_norm(centre - np.clip(centre, lo[dims], hi[dims])))

        if self.style == "block":
            return any(max(self.lo[d], lo[d]) > min(self.hi[d], hi[d]) for d in range(3))
        if self.style == "sphere":
            return gap(np.asarray(self.center, float), [0, 1, 2]) > self.radius
        others = [d for d in range(3) if d != self.axis]
        return (max(self.lo, lo[self.axis]) > min(self.hi, hi[self.axis])
                or gap(np.asarray(self.center, float), others) > self.radius)

    def _cyl(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Radial distance from the axis and axial coordinate of x."""
        o1, o2 = (d for d in range(3) if d != self.axis)
        d1, d2 = x[..., o1] - self.center[0], x[..., o2] - self.center[1]
        return np.sqrt(d1 * d1 + d2 * d2), x[..., self.axis]

    # -- contacts --------------------------------------------------------------------------

    def contacts(self, x: np.ndarray, cutoff: float | np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """All §5.1 contacts within the cut-off of the atoms x (M,3); cutoff scalar or (M,).

        Returns idx (K,) into x, delta (K,3) = x - surface point and r (K,) = |delta| [length].
        Atoms not on the allowed side give none. A block inside gives up to 6 contacts per atom
        (one per face with d < rc), a cylinder inside up to 3 (curved wall, lo cap, hi cap);
        every outside region gives at most one (the nearest surface point, kept if r < rc).
        """
        x = np.asarray(x, float).reshape(-1, 3)
        rc = np.broadcast_to(np.asarray(cutoff, float), x.shape[:1])
        parts = getattr(self, f"_{self.style}_{self.side}")(x, rc)
        if not parts:
            return np.zeros(0, np.intp), np.zeros((0, 3)), np.zeros(0)
        idx, delta, r = (np.concatenate(p) for p in zip(*parts))
        return idx, delta, r

    @staticmethod
    def _axis_contact(x: np.ndarray, mask: np.ndarray, dim: int, dist: np.ndarray, sign: float):
        """Contacts along one axis: delta = sign * dist along dim, r = dist."""
        idx = np.nonzero(mask)[0]
        r = dist[idx]
        delta = np.zeros((idx.size, 3))
        delta[:, dim] = sign * r
        return idx, delta, r

    @staticmethod
    def _point_contact(x: np.ndarray, mask: np.ndarray, delta: np.ndarray, r: np.ndarray):
        idx = np.nonzero(mask)[0]
        return idx, delta[idx], r[idx]

    def _block_in(self, x, rc):
        ins = self.inside(x)
        parts = []
        for dim in range(3):
            d_lo = x[:, dim] - self.lo[dim]  # xlo face: delta = (+d, 0, 0)
            d_hi = self.hi[dim] - x[:, dim]  # xhi face: delta = (-d, 0, 0)
            parts.append(self._axis_contact(x, ins & (d_lo < rc), dim, d_lo, 1.0))
            parts.append(self._axis_contact(x, ins & (d_hi < rc), dim, d_hi, -1.0))
        return parts

    def _block_out(self, x, rc):
        lo, hi = np.asarray(self.lo), np.asarray(self.hi)
        strictly = np.all((x > lo) & (x < hi), axis=1)
        delta = x - np.clip(x, lo, hi)  # from the nearest surface point (face, edge or corner)
        r = _norm(delta)
        return [self._point_contact(x, ~strictly & (r < rc), delta, r)]

    def _sphere_in(self, x, rc):
        d = x - self.center
        rho = _norm(d)
        m = (rho <= self.radius) & (rho > 0.0)  # the exact centre feels nothing
        r = self.radius - rho
        m &= r < rc
        idx = np.nonzero(m)[0]
        return [(idx, d[idx] * (1.0 - self.radius / rho[idx])[:, None], r[idx])]

    def _sphere_out(self, x, rc):
        d = x - self.center
        rho = _norm(d)
        r = rho - self.radius
        idx = np.nonzero((rho >= self.radius) & (r < rc))[0]
        return [(idx, d[idx] * (1.0 - self.radius / rho[idx])[:, None], r[idx])]

    def _cylinder_in(self, x, rc):
        ax = self.axis
        o = [dim for dim in range(3) if dim != ax]
        rho, a = self._cyl(x)
        ins = (rho <= self.radius) & (a >= self.lo) & (a <= self.hi)
        r_wall = self.radius - rho
        idx = np.nonzero(ins & (rho > 0.0) & (r_wall < rc))[0]
        delta = np.zeros((idx.size, 3))
        delta[:, o] = (x[idx][:, o] - self.center) * (1.0 - self.radius / rho[idx])[:, None]
        d_lo, d_hi = a - self.lo, self.hi - a
        return [(idx, delta, r_wall[idx]),
                self._axis_contact(x, ins & (d_lo < rc), ax, d_lo, 1.0),
                self._axis_contact(x, ins & (d_hi < rc), ax, d_hi, -1.0)]

    def _cylinder_out(self, x, rc):
        ax = self.axis
        o = [dim for dim in range(3) if dim != ax]
        rho, a = self._cyl(x)
        strictly = (rho < self.radius) & (a > self.lo) & (a < self.hi)
        delta = np.zeros_like(x)
        with np.errstate(divide="ignore", invalid="ignore"):  # rho = 0 only where rho <= R (unused)
            rim = np.where(rho > self.radius, 1.0 - self.radius / rho, 0.0)
        delta[:, o] = (x[:, o] - self.center) * rim[:, None]  # radially: the rim, or the atom itself
        delta[:, ax] = a - np.clip(a, self.lo, self.hi)  # axially: clamped to [lo, hi]
        r = _norm(delta)
        return [self._point_contact(x, ~strictly & (r < rc), delta, r)]


