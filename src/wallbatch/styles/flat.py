"""Flat-wall potential styles as pure functions on arrays (physics.md §4.1-4.6).

Every style is one registry entry (`WallStyle`, at the end of this module) with three functions
of the same positional arguments ``(r, p0, p1, p2, rc, radius)``:

* ``r`` [length] is the distance from the wall into the allowed region (``delta`` of §3.2),
  ``r > 0``; for colloid it is the distance of the particle *centre*.
* ``p0, p1, p2`` are the style's parameters in LAMMPS order (epsilon, sigma; or D0, alpha, r0),
  ``rc`` the cut-off, ``radius`` the particle radius. Everything broadcasts: ``r`` may be
  ``(C, N)`` with per-case parameters ``(C, 1)`` and a per-atom ``radius`` ``(C, N)``; the
  force functions are plain arithmetic and are jit-compiled as they are for scalars.
* ``<style>_energy`` [energy] is the *unshifted* energy, ``<style>_force = -dE/dr`` [force] the
  scalar wall force with ``F > 0`` repulsive. The engine applies ``f[dim] += -side * F`` and
  ``vec += side * F`` (§3.2).

Each style also has ``<style>_shifted -> E(r) - E(rc)`` (``WallStyle.shifted_energy``),
written so that the difference never cancels: as r -> rc it is a factor (rc - r), formed from
the exact difference of the inputs, times a sum of positive terms (LJ: a^n - b^n = (a - b) sum
a^k b^(n-1-k); Morse: expm1; colloid: the same for its two terms, plus the atanh addition theorem
and a series in (R/r)^2 for the far field).

Accuracy: relative error <= 1e-13 against a 50-digit evaluation of the closed forms for E, F and
the shifted energy, wherever the value is not near one of its own roots (tests/styles/test_stability.py
defines this precisely); lengths enter only as ratios (sigma/r, R/r, (rc - r)/rc), so any length
scale works as long as the result is representable.

No state, no cut-off or error logic here: masking ``r >= rc`` and the "on or inside the wall"
test (:meth:`WallStyle.too_close`) belong to the engine (§3.3).
"""

from __future__ import annotations

import numpy as np

from wallbatch.styles.base import Param, Params, WallStyle, cutoff_param, shifted_energy_force

__all__ = ["STYLES", "WallStyle", "Param", "Params", "shifted_energy_force", "colloid"]

_SQRT2 = np.sqrt(2.0)
_TWO_PI = 2.0 * np.pi
_LJ1043_SHIFT = 0.61 / _SQRT2  # s' = (0.61 / sqrt 2) sigma, §4.3


# ---- lj93 (§4.1): E = eps [ (2/15) (sigma/r)^9 - (sigma/r)^3 ], F = eps [ (6/5) sigma^9/r^10 - 3 sigma^3/r^4 ]


def lj93_energy(r, eps, sigma, p2, rc, radius):
    sr = sigma / r
    sr3 = sr * sr * sr
    sr9 = sr3 * sr3 * sr3
    return eps * ((2.0 / 15.0) * sr9 - sr3)


def lj93_force(r, eps, sigma, p2, rc, radius):
    sr = sigma / r
    sr3 = sr * sr * sr
    sr9 = sr3 * sr3 * sr3
    return eps * (1.2 * sr9 - 3.0 * sr3) / r


def lj93_shifted(r, eps, sigma, p2, rc, radius):
    """E(r) - E(rc) of lj93 (§4.1). [energy]

    With s = sigma/r, c = sigma/rc and s - c = s (rc - r)/rc:
    s^3 - c^3 = (s - c)(s^2 + s c + c^2),  s^9 - c^9 = (s^3 - c^3)(s^6 + s^3 c^3 + c^6),
    E(r) - E(rc) = eps (s^3 - c^3) [ (2/15)(s^6 + s^3 c^3 + c^6) - 1 ].
    """
    s = sigma / r
    c = sigma / rc
    d3 = s * ((rc - r) / rc) * (s * s + s * c + c * c)
    s3 = s * s * s
    c3 = c * c * c
    return eps * d3 * ((2.0 / 15.0) * (s3 * s3 + s3 * c3 + c3 * c3) - 1.0)


# ---- lj126 (§4.2): E = 4 eps [ (sigma/r)^12 - (sigma/r)^6 ], F = (4 eps / r) [ 12 (sigma/r)^12 - 6 (sigma/r)^6 ]


def lj126_energy(r, eps, sigma, p2, rc, radius):
    sr = sigma / r
    sr2 = sr * sr
    sr6 = sr2 * sr2 * sr2
    sr12 = sr6 * sr6
    return 4.0 * eps * (sr12 - sr6)


def lj126_force(r, eps, sigma, p2, rc, radius):
    sr = sigma / r
    sr2 = sr * sr
    sr6 = sr2 * sr2 * sr2
    sr12 = sr6 * sr6
    return eps * (48.0 * sr12 - 24.0 * sr6) / r


def lj126_shifted(r, eps, sigma, p2, rc, radius):
    """E(r) - E(rc) of lj126 (§4.2). [energy]

    s^6 - c^6 = (s - c)(s^2 + s c + c^2)(s^3 + c^3), s^12 - c^12 = (s^6 - c^6)(s^6 + c^6):
    E(r) - E(rc) = 4 eps (s^6 - c^6) (s^6 + c^6 - 1).
    """
    s = sigma / r
    c = sigma / rc
    s3 = s * s * s
    c3 = c * c * c
    d6 = s * ((rc - r) / rc) * (s * s + s * c + c * c) * (s3 + c3)
    return 4.0 * eps * d6 * (s3 * s3 + c3 * c3 - 1.0)


# ---- lj1043 (§4.3), Magda 10-4-3 with s' = (0.61/sqrt 2) sigma:
#   E = 2 pi eps [ (2/5) (sigma/r)^10 - (sigma/r)^4 - sqrt2 sigma^3 / (3 (r + s')^3) ]
#   F = 2 pi eps [ 4 sigma^10 / r^11 - 4 sigma^4 / r^5 - sqrt2 sigma^3 / (r + s')^4 ]


def lj1043_energy(r, eps, sigma, p2, rc, radius):
    # eps (0.4 s^10 - s^4) as (eps s^4)(0.4 s^6 - 1): eps joins before the high powers, so that
    # no intermediate overflows where the energy itself is finite
    sr = sigma / r
    sr2 = sr * sr
    sr4 = sr2 * sr2
    rs = r + _LJ1043_SHIFT * sigma
    ss = sigma / rs
    ss3 = ss * ss * ss
    return _TWO_PI * ((eps * sr4) * (0.4 * (sr4 * sr2) - 1.0) - eps * (_SQRT2 / 3.0) * ss3)


def lj1043_force(r, eps, sigma, p2, rc, radius):
    # 4 eps (s^10 - s^4)/r as 4 ((eps s^4)/r)(s^6 - 1): divide by r before multiplying by s^6,
    # with eps first, so that intermediates stay finite wherever the force is (r = 1e-33 sigma)
    sr = sigma / r
    sr2 = sr * sr
    sr4 = sr2 * sr2
    rs = r + _LJ1043_SHIFT * sigma
    ss = sigma / rs
    ss3 = ss * ss * ss
    return _TWO_PI * (4.0 * ((eps * sr4) / r) * (sr4 * sr2 - 1.0) - eps * _SQRT2 * ss3 / rs)


def lj1043_shifted(r, eps, sigma, p2, rc, radius):
    """E(r) - E(rc) of lj1043 (§4.3). [energy]

    s^4 - c^4 = (s - c)(s + c)(s^2 + c^2), s^10 - c^10 = (s - c)(s^4 + s^3 c + ... + c^4)(s^5 + c^5),
    and with w = sigma/(r + s'), w_c = sigma/(rc + s'), w - w_c = w (rc - r)/(rc + s'):
    w^3 - w_c^3 = (w - w_c)(w^2 + w w_c + w_c^2);
    E(r) - E(rc) = 2 pi eps [ (2/5)(s^10 - c^10) - (s^4 - c^4) - (sqrt2/3)(w^3 - w_c^3) ].
    """
    h = rc - r
    s = sigma / r
    c = sigma / rc
    ds = eps * (s * (h / rc))  # eps (s - c): eps first, so the powers below stay finite
    s2, c2, sc = s * s, c * c, s * c
    d4 = ds * (s + c) * (s2 + c2)
    d10 = ds * (s2 * s2 + c2 * c2 + sc * (s2 + c2) + sc * sc) * (s2 * s2 * s + c2 * c2 * c)
    shift = _LJ1043_SHIFT * sigma
    w = sigma / (r + shift)
    wc = sigma / (rc + shift)
    dw3 = w * (h / (rc + shift)) * (w * w + w * wc + wc * wc)
    return _TWO_PI * (0.4 * d10 - d4 - eps * (_SQRT2 / 3.0) * dw3)


# ---- harmonic (§4.4): a repulsive spring resting at the cut-off, epsilon = K [energy/length^2]
#   E = eps (r - rc)^2 (already 0 at rc), F = 2 eps (rc - r) (>= 0 for r <= rc)


def harmonic_energy(r, eps, sigma, p2, rc, radius):
    dr = rc - r
    return eps * dr * dr


def harmonic_force(r, eps, sigma, p2, rc, radius):
    return 2.0 * eps * (rc - r)


# E(r) - E(rc) = E(r) exactly
harmonic_shifted = harmonic_energy


# ---- morse (§4.5): E = D0 [ e^{-2 a (r - r0)} - 2 e^{-a (r - r0)} ], F = 2 a D0 [ e^{-2 a (r - r0)} - e^{-a (r - r0)} ]


def morse_energy(r, d0, alpha, r0, rc, radius):
    x = -alpha * (r - r0)
    ex = np.exp(x)
    em1 = np.expm1(x)  # e^x - 1, exact near r0 where F -> 0 (em1 + 1 is not: x << 0)
    return d0 * ex * (em1 - 1.0)


def morse_force(r, d0, alpha, r0, rc, radius):
    x = -alpha * (r - r0)
    return 2.0 * alpha * d0 * np.exp(x) * np.expm1(x)


def morse_shifted(r, d0, alpha, r0, rc, radius):
    """E(r) - E(rc) of morse (§4.5). [energy]

    With e = exp(-a (r - r0)), e_c = exp(-a (rc - r0)):
    E(r) - E(rc) = D0 (e - e_c)(e + e_c - 2) = D0 (e - e_c) [ expm1(-a(r-r0)) + expm1(-a(rc-r0)) ],
    e - e_c = -e expm1(-a (rc - r)).
    """
    x = -alpha * (r - r0)
    em1 = np.expm1(x)
    emc1 = np.expm1(-alpha * (rc - r0))
    diff = -np.exp(x) * np.expm1(-alpha * (rc - r))
    return d0 * diff * (em1 + emc1)


# ---- colloid (§4.6): a finite-size sphere against a flat wall
# Colloid's attraction g(x) = 2x/(1 - x^2) - 2 atanh(x) = sum_k>=1 4k/(2k+1) x^(2k+1), x = R/r.
# The closed form cancels (both terms ~ 2x while g ~ (4/3) x^3, error ~ 4 ulp/x^2): below x = 0.2
# the series is used (12 terms: truncation < 3e-17 relative); above, the closed form loses
# < 100 ulp (1.1e-14).
_G_SWITCH = 0.2
_G_COEF = tuple(4.0 * k / (2.0 * k + 1.0) for k in range(1, 13))


def _colloid_g_series(x: np.ndarray) -> np.ndarray:
    """g(x) = x^3 sum_k 4k/(2k+1) x^(2k-2), Horner in x^2 (x <= 0.2)."""
    y = x * x
    acc = _G_COEF[-1]
    for c in _G_COEF[-2::-1]:
        acc = acc * y + c
    return x * y * acc


def _colloid_g_closed(x: np.ndarray, d: np.ndarray, dp: np.ndarray) -> np.ndarray:
    """g(x) = 2x/(1 - x^2) - log1p(2x/(1 - x)), with d = 1 - x, dp = 1 - x^2 formed exactly."""
    return 2.0 * x / dp - np.log1p(2.0 * x / d)


def _colloid_g(x: np.ndarray, d: np.ndarray, dp: np.ndarray) -> np.ndarray:
    """g(x) for x of any shape: the closed form, with the series where x < 0.2 (far field)."""
    small = x < _G_SWITCH
    if small.all():
        return _colloid_g_series(x)
    g = _colloid_g_closed(x, d, dp)
    if small.any():  # only reached for ndim >= 1
        idx = np.nonzero(small)
        g[idx] = _colloid_g_series(x[idx])
    return g


def colloid_energy(r, eps, sigma, p2, rc, big_r):
    """Finite-size sphere against a flat wall (§4.6). [energy]

    r is the centre distance, R = radius (per atom), D = r - R the surface gap. §4.6 writes

    E = eps { sigma^6/7560 [ (6R - D)/D^7 + (D + 8R)/(D + 2R)^7 ]
              - (1/6) [ 2R(D+R) + D(D+2R) (ln D - ln(D+2R)) ] / [D(D+2R)] }

    evaluated here in the algebraically equal, cancellation-free form in the dimensionless
    x = R/r, d = D/r (from the exact r - R), 1 - x^2 = d (1 + x) = (r^2 - R^2)/r^2 and
    u = (sigma/r) / (1 - x^2):

    E = eps { (4/945) u^6 x^3 (7 + 14 x^2 + 3 x^4) / (1 - x^2)  -  g(x) / 6 }
    F = (eps/r) x^3 / (1 - x^2)^2 [ (4/315) u^6 (21 + 63 x^2 + 27 x^4 + x^6) - 2/3 ]

    with g(x) = 2x/(1 - x^2) - 2 atanh(x) = 2x/(1 - x^2) - log1p(2R/D), replaced by its series
    (4/3) x^3 + (8/5) x^5 + ... for x < 0.2 where the two terms cancel (far field).
    """
    x = np.asarray(big_r / r, dtype=float)
    d = (r - big_r) / r  # D/r; r - R is exact near contact
    dp = d * (1.0 + x)  # 1 - x^2
    y = x * x
    u = sigma / r / dp
    u2 = u * u
    u6 = u2 * u2 * u2
    g = _colloid_g(x, d, dp)
    return eps * ((4.0 / 945.0) * u6 * x * y * ((3.0 * y + 14.0) * y + 7.0) / dp - g / 6.0)


def colloid_force(r, eps, sigma, p2, rc, big_r):
    """F = -dE/dr of colloid (see colloid_energy). [force]"""
    x = big_r / r
    d = (r - big_r) / r
    dp = d * (1.0 + x)
    y = x * x
    u = sigma / r / dp
    u2 = u * u
    u6 = u2 * u2 * u2
    v = x / dp  # x^3/(1-x^2)^2 = x v^2: no intermediate (1-x^2)^2 to underflow
    poly = ((y + 27.0) * y + 63.0) * y + 21.0
    return eps * (x * v * v / r) * ((4.0 / 315.0) * u6 * poly - 2.0 / 3.0)


def colloid(r, p: Params) -> tuple[np.ndarray, np.ndarray]:
    """(E, F) of colloid from a parameter mapping (epsilon, sigma, radius). [energy], [force]"""
    return COLLOID.energy_force(r, p)


def _colloid_dg_series(x: np.ndarray, xc: np.ndarray, dx: np.ndarray) -> np.ndarray:
    """g(x) - g(xc) = (x - xc) sum_k 4k/(2k+1) P_{2k+1}(x, xc) for x, xc <= 0.2 (far field),
    P_n = (x^n - xc^n)/(x - xc) = sum_j x^j xc^(n-1-j) from P_{n+2} = x^2 P_n + xc^n (x + xc)."""
    x2 = x * x
    xc2 = xc * xc
    xsum = x + xc
    pn = 1.0  # P_1
    xcn = xc  # xc^1
    acc = 0.0
    for c in _G_COEF:
        pn = x2 * pn + xcn * xsum
        xcn = xcn * xc2
        acc = acc + c * pn
    return dx * acc


def _colloid_dg_closed(x: np.ndarray, xc: np.ndarray, dx: np.ndarray, dp: np.ndarray, dpc: np.ndarray,
                       one_m: np.ndarray) -> np.ndarray:
    """g(x) - g(xc) = 2 dx (1 + x xc)/(dp dpc) - 2 atanh(dx/one_m) (atanh addition theorem), with
    dx = x - xc, dp = 1 - x^2, dpc = 1 - xc^2 and one_m = 1 - x xc formed without cancellation."""
    return 2.0 * dx * (1.0 + x * xc) / (dp * dpc) - 2.0 * np.arctanh(dx / one_m)


def colloid_shifted(r, eps, sigma, p2, rc, big_r):
    """E(r) - E(rc) of colloid (§4.6), the particle's own R in both terms. [energy]

    In units of rc (rho = r/rc, b = R/rc, s = sigma/rc, h = (r - rc)/rc; q = rho^2 - b^2 and
    q_c = 1 - b^2 formed from the exact r - R and rc - R) the repulsion is (4/945) s^6 b^3 phi
    with phi(rho) = N(rho)/q^7, N(rho) = 7 rho^5 + 14 rho^3 b^2 + 3 rho b^4, and

    phi(rho) - phi(1) = h [ A/q_c^7 - N(rho) (rho + 1) sum_{j=0..6} q^(j-7) q_c^(-1-j) ],
    A = (N(rho) - N(1))/h = 7 (1 + rho + ... + rho^4) + 14 b^2 (1 + rho + rho^2) + 3 b^4

    (opposite signs, but the second term is at least 2.8 times the first, the minimum being at
    rho -> 1, b -> 0: the difference loses at most a factor 2.1). The
    attraction -g(x)/6, x = R/r, x_c = R/rc, by the atanh addition theorem (_colloid_dg_closed)
    with x - x_c = -x h and 1 - x x_c = D/r + x (rc - R)/rc; for x, x_c < 0.2 (far field) by
    the difference of the series (_colloid_dg_series).
    """
    h = (r - rc) / rc
    rho = r / rc
    b = big_r / rc
    dct = (rc - big_r) / rc  # (rc - R)/rc
    a = 1.0 / ((r - big_r) / rc * (rho + b))  # 1/q
    ac = 1.0 / (dct * (1.0 + b))  # 1/q_c
    b2 = b * b
    big_a = (7.0 * ((((rho + 1.0) * rho + 1.0) * rho + 1.0) * rho + 1.0)
             + 14.0 * b2 * ((rho + 1.0) * rho + 1.0) + 3.0 * b2 * b2)
    rho2 = rho * rho
    n_rho = rho * ((7.0 * rho2 + 14.0 * b2) * rho2 + 3.0 * b2 * b2)
    p7 = 1.0  # sum_{j=0..6} a^(6-j) ac^j, from P_{n+1} = a P_n + ac^n
    acn = 1.0
    for _ in range(6):
        acn = acn * ac
        p7 = a * p7 + acn
    ac2 = ac * ac
    dphi = h * (big_a * (ac2 * ac2 * ac2 * ac) - n_rho * (rho + 1.0) * a * ac * p7)
    s2 = (sigma / rc) ** 2
    rep = (4.0 / 945.0) * s2 * s2 * s2 * b2 * b * dphi

    return eps * (rep - colloid_dg(r, big_r, rc, h, b, dct) / 6.0)


def colloid_dg(r, big_r, rc, h, b, dct):
    """g(x) - g(x_c) of colloid_shifted (x = R/r, x_c = b = R/rc, h = (r - rc)/rc, dct = (rc - R)/rc):
    the difference of the series where max(x, x_c) < 0.2 (far field), else the closed form, chosen
    per element. The compiled path (wallbatch.engine.compiled) overloads this function for floats
    with the same choice, so colloid_shifted compiles as it is. [1]"""
    shape = np.broadcast_shapes(np.shape(r), np.shape(big_r), np.shape(rc))
    x = np.broadcast_to(np.asarray(big_r / r, dtype=float), shape)
    dx = -x * h
    small = np.maximum(x, b) < _G_SWITCH
    if small.all():
        return _colloid_dg_series(x, b, dx)
    d = (r - big_r) / r
    dg = _colloid_dg_closed(x, b, dx, d * (1.0 + x), dct * (1.0 + b), d + x * dct)
    if small.any():  # only reached for ndim >= 1
        idx = np.nonzero(small)
        dg[idx] = _colloid_dg_series(x[idx], np.broadcast_to(b, x.shape)[idx], dx[idx])
    return dg


# ----------------------------------------------------------------------------- registry entries

# Lennard-Jones-like parameters: epsilon (>= 0) and sigma (>= 0), either may be a variable.
_EPS = Param("epsilon", "energy", min=0.0, doc="wall strength epsilon")
_SIGMA = Param("sigma", "distance", min=0.0, doc="length scale sigma")
_LJ = (_EPS, _SIGMA, cutoff_param())

LJ93 = WallStyle("lj93", _LJ, lj93_force, lj93_energy, lj93_shifted,
                 doc="9-3 wall: E = eps [(2/15)(sigma/r)^9 - (sigma/r)^3]")
LJ126 = WallStyle("lj126", _LJ, lj126_force, lj126_energy, lj126_shifted,
                  doc="12-6 wall: E = 4 eps [(sigma/r)^12 - (sigma/r)^6]")
LJ1043 = WallStyle(
    "lj1043", _LJ, lj1043_force, lj1043_energy, lj1043_shifted,
    doc="Magda 10-4-3 wall: E = 2 pi eps [(2/5)(sigma/r)^10 - (sigma/r)^4 - sqrt2 sigma^3/(3 (r + s')^3)]",
    decision="wall/lj1043 atom on or behind the wall: wallbatch stops the case with an error, like every other "
             "style; LAMMPS silently skips the atom (and includes one exactly at the cut-off with E = 0, F != 0). "
             "A run that reaches such a state differs: wallbatch fails, LAMMPS goes on")
COLLOID = WallStyle("colloid", _LJ, colloid_force, colloid_energy, colloid_shifted, needs_radius=True,
                    region_quirk=True,  # colloid_shifted's per-element choice: colloid_dg (overloaded for floats)
                    doc="finite-size sphere (radius R) against a flat wall; r is the centre distance")
HARMONIC = WallStyle(
    "harmonic",
    (Param("epsilon", "energy/distance^2", min=0.0, doc="spring constant K"),
     Param("sigma", "distance", min=0.0, required=False, placeholder=1.0, doc="read and ignored (LAMMPS)"),
     cutoff_param()),
    harmonic_force, harmonic_energy, harmonic_shifted,
    doc="repulsive spring resting at the cut-off: E = K (r - rc)^2")
MORSE = WallStyle(
    "morse",
    (Param("D0", "energy", min=0.0, doc="well depth D0"),
     Param("alpha", "1/distance", doc="stiffness alpha (a variable alpha is ignored by LAMMPS)",
           lammps_variable_note="wall/morse alpha as a variable: LAMMPS ignores a variable alpha (alpha = 0, no "
                                "force); the variable is constant here, so its value is written as a number"),
     Param("r0", "distance", min=0.0, doc="position of the minimum r0"),
     cutoff_param()),
    morse_force, morse_energy, morse_shifted,
    doc="Morse wall: E = D0 [exp(-2 a (r - r0)) - 2 exp(-a (r - r0))]")

STYLES: dict[str, WallStyle] = {s.name: s for s in (LJ93, LJ126, LJ1043, COLLOID, HARMONIC, MORSE)}
