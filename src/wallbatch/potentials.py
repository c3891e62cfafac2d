"""Flat-wall potential styles as pure functions on arrays (physics.md §4.1-4.6).

Every style is a function ``energy_force(r, p) -> (E, F)``:

* ``r`` [length] is the distance from the wall into the allowed region (``delta`` of §3.2),
  ``r > 0``; for ``colloid`` it is the distance of the particle *centre*.
* ``p`` maps parameter names (``epsilon``, ``sigma``, ``cutoff``, ``radius``, ``D0``, ``alpha``,
  ``r0``) to floats or arrays. Everything broadcasts: ``r`` may be ``(C, N)`` with per-case
  parameters ``(C, 1)`` and a per-atom ``radius`` ``(C, N)``.
* ``E`` [energy] is the *unshifted* energy, ``F = -dE/dr`` [force] the scalar wall force with
  ``F > 0`` repulsive. The engine applies ``f[dim] += -side * F`` and ``vec += side * F``
  (§3.2); :func:`shifted_energy_force` gives the shifted energy ``E(r) - E(rc)``.

No state, no cut-off or error logic here: masking ``r >= rc`` and the "on or inside the wall"
test (:meth:`WallStyle.too_close`) belong to the engine (§3.3).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass

import numpy as np

Params = Mapping[str, np.ndarray | float]
EnergyForce = Callable[[np.ndarray, Params], tuple[np.ndarray, np.ndarray]]

_SQRT2 = np.sqrt(2.0)
_TWO_PI = 2.0 * np.pi
_LJ1043_SHIFT = 0.61 / _SQRT2  # s' = (0.61 / sqrt 2) sigma, §4.3


def lj93(r, p: Params) -> tuple[np.ndarray, np.ndarray]:
    """9-3 wall (§4.1). [energy], [force]

    E = eps [ (2/15) (sigma/r)^9 - (sigma/r)^3 ]
    F = eps [ (6/5) sigma^9 / r^10 - 3 sigma^3 / r^4 ]
    """
    eps = p["epsilon"]
    sr = p["sigma"] / r
    sr3 = sr * sr * sr
    sr9 = sr3 * sr3 * sr3
    energy = eps * ((2.0 / 15.0) * sr9 - sr3)
    force = eps * (1.2 * sr9 - 3.0 * sr3) / r
    return energy, force


def lj126(r, p: Params) -> tuple[np.ndarray, np.ndarray]:
    """12-6 wall (§4.2). [energy], [force]

    E = 4 eps [ (sigma/r)^12 - (sigma/r)^6 ]
    F = (4 eps / r) [ 12 (sigma/r)^12 - 6 (sigma/r)^6 ]
    """
    eps = p["epsilon"]
    sr = p["sigma"] / r
    sr2 = sr * sr
    sr6 = sr2 * sr2 * sr2
    sr12 = sr6 * sr6
    energy = 4.0 * eps * (sr12 - sr6)
    force = eps * (48.0 * sr12 - 24.0 * sr6) / r
    return energy, force


def lj1043(r, p: Params) -> tuple[np.ndarray, np.ndarray]:
    """Magda 10-4-3 wall (§4.3), with s' = (0.61/sqrt 2) sigma. [energy], [force]

    E = 2 pi eps [ (2/5) (sigma/r)^10 - (sigma/r)^4 - sqrt2 sigma^3 / (3 (r + s')^3) ]
    F = 2 pi eps [ 4 sigma^10 / r^11 - 4 sigma^4 / r^5 - sqrt2 sigma^3 / (r + s')^4 ]
    """
    eps = p["epsilon"]
    sigma = p["sigma"]
    sr = sigma / r
    sr2 = sr * sr
    sr4 = sr2 * sr2
    sr10 = sr4 * sr4 * sr2
    rs = r + _LJ1043_SHIFT * sigma
    ss = sigma / rs
    ss3 = ss * ss * ss
    energy = _TWO_PI * eps * (0.4 * sr10 - sr4 - (_SQRT2 / 3.0) * ss3)
    force = _TWO_PI * eps * (4.0 * (sr10 - sr4) / r - _SQRT2 * ss3 / rs)
    return energy, force


def harmonic(r, p: Params) -> tuple[np.ndarray, np.ndarray]:
    """Repulsive spring resting at the cut-off (§4.4); epsilon is K [energy/length^2].

    E = eps (r - rc)^2          (already 0 at rc)
    F = 2 eps (rc - r)          (>= 0 for r <= rc)
    """
    eps = p["epsilon"]
    dr = p["cutoff"] - r
    return eps * dr * dr, 2.0 * eps * dr


def morse(r, p: Params) -> tuple[np.ndarray, np.ndarray]:
    """Morse wall (§4.5). [energy], [force]

    E = D0 [ e^{-2 a (r - r0)} - 2 e^{-a (r - r0)} ]
    F = 2 a D0 [ e^{-2 a (r - r0)} - e^{-a (r - r0)} ]
    """
    d0 = p["D0"]
    alpha = p["alpha"]
    x = -alpha * (r - p["r0"])
    em1 = np.expm1(x)  # e^x - 1, exact near r0 where F -> 0
    ex = em1 + 1.0
    energy = d0 * ex * (em1 - 1.0)
    force = 2.0 * alpha * d0 * ex * em1
    return energy, force


def colloid(r, p: Params) -> tuple[np.ndarray, np.ndarray]:
    """Finite-size sphere against a flat wall (§4.6). [energy], [force]

    r is the centre distance, R = p["radius"] (per atom), D = r - R the surface gap. §4.6 writes

    E = eps { sigma^6/7560 [ (6R - D)/D^7 + (D + 8R)/(D + 2R)^7 ]
              - (1/6) [ 2R(D+R) + D(D+2R) (ln D - ln(D+2R)) ] / [D(D+2R)] }

    evaluated here in the algebraically equal, cancellation-free form (D + R = r,
    D(D+2R) = (r-R)(r+R) = q)

    E = eps { 4 sigma^6 r R^3 (7 r^4 + 14 r^2 R^2 + 3 R^4) / (945 q^7)
              - (1/6) [ 2 R r / q - log1p(2R/D) ] }
    F = (4/315) eps sigma^6 (R^9 + 27 R^7 r^2 + 63 R^5 r^4 + 21 R^3 r^6) / q^8
        - (2/3) eps R^3 / q^2

    The attractive bracket still loses about (r/R)^2 ulps for R << r (the leading terms of
    2Rr/q and log1p(2R/D) cancel).
    """
    eps = p["epsilon"]
    sigma = p["sigma"]
    big_r = p["radius"]
    s2 = sigma * sigma
    s6 = s2 * s2 * s2
    r2 = r * r
    rad2 = big_r * big_r
    rad3 = rad2 * big_r
    q = (r - big_r) * (r + big_r)  # r^2 - R^2 = D (D + 2R)
    q2 = q * q
    q4 = q2 * q2
    q7 = q4 * q2 * q
    rep_e = (4.0 / 945.0) * s6 * r * rad3 * ((7.0 * r2 + 14.0 * rad2) * r2 + 3.0 * rad2 * rad2) / q7
    att_e = (2.0 * big_r * r / q - np.log1p(2.0 * big_r / (r - big_r))) / 6.0
    energy = eps * (rep_e - att_e)
    poly = rad3 * (((21.0 * r2 + 63.0 * rad2) * r2 + 27.0 * rad2 * rad2) * r2 + rad2 * rad2 * rad2)
    force = eps * ((4.0 / 315.0) * s6 * poly / (q4 * q4) - (2.0 / 3.0) * rad3 / q2)
    return energy, force


@dataclass(frozen=True)
class WallStyle:
    """One flat-wall style: its LAMMPS per-face argument names and its energy/force function."""

    name: str
    params: tuple[str, ...]  # per-face arguments after coord, in LAMMPS order
    energy_force: EnergyForce
    shifted: bool = True  # energy reported as E(r) - E(rc)
    needs_radius: bool = False  # per-atom radius required (colloid)

    def too_close(self, p: Params) -> np.ndarray | float:
        """Threshold t: an atom within the cut-off with delta <= t is "on or inside" the wall (§3.3).

        0 for every style except colloid, where it is the particle radius.
        """
        return p["radius"] if self.needs_radius else 0.0


_LJ_ARGS = ("epsilon", "sigma", "cutoff")

STYLES: dict[str, WallStyle] = {
    s.name: s
    for s in (
        WallStyle("lj93", _LJ_ARGS, lj93),
        WallStyle("lj126", _LJ_ARGS, lj126),
        WallStyle("lj1043", _LJ_ARGS, lj1043),
        WallStyle("colloid", _LJ_ARGS, colloid, needs_radius=True),
        WallStyle("harmonic", _LJ_ARGS, harmonic),  # sigma is read but ignored
        WallStyle("morse", ("D0", "alpha", "r0", "cutoff"), morse),
    )
}


def shifted_energy_force(style: WallStyle, r, p: Params) -> tuple[np.ndarray, np.ndarray]:
    """(E(r) - E(rc), F(r)) for ``style``, rc = p["cutoff"]. [energy], [force]

    The offset E(rc) uses the same (per-atom) parameters, e.g. colloid's own radius. For a
    style with ``shifted=False`` the energy is returned unshifted.
    """
    energy, force = style.energy_force(r, p)
    if style.shifted:
        energy = energy - style.energy_force(p["cutoff"], p)[0]
    return energy, force
