"""wall/ees: the ellipsoid-flat wall interaction (Babadi & Ejtehadi), batched over leading axes.

See the module docs of wallbatch.geometry.quaternion for the conventions.
"""

from __future__ import annotations

import numpy as np

from wallbatch.geometry.quaternion import entries, rotation_matrix, to_body, to_space
from wallbatch.styles.base import Param, WallStyle, cutoff_param

# --------------------------------------------------------------------------------------------
# wall/ees (§4.7, §6)


def sigma_n_of(a, s0, s1, s2, n0, n1, n2):
    """sigma_n = |S A^T n̂| on components (a: the 9 entries of A, floats or arrays), see :func:`sigma_n`."""
    b0, b1, b2 = to_body(a, n0, n1, n2)
    u0, u1, u2 = s0 * b0, s1 * b1, s2 * b2
    return np.sqrt(u0 * u0 + u1 * u1 + u2 * u2)


def torque_of(a, s0, s1, s2, n0, n1, n2, tw):
    """τ = T_w (n̂ × A S² A^T n̂) on components (see :func:`ees_torque`)."""
    b0, b1, b2 = to_body(a, n0, n1, n2)
    m0, m1, m2 = to_space(a, s0 * s0 * b0, s1 * s1 * b1, s2 * s2 * b2)
    return tw * (n1 * m2 - n2 * m1), tw * (n2 * m0 - n0 * m2), tw * (n0 * m1 - n1 * m0)


def _parts(q, shape, normal, a):
    a = rotation_matrix(q) if a is None else np.asarray(a, dtype=np.float64)
    n = np.asarray(normal, dtype=np.float64)
    s = np.asarray(shape, dtype=np.float64)
    lead = np.broadcast_shapes(a.shape[:-2], n.shape[:-1], s.shape[:-1])
    return entries(a), tuple(s[..., c] for c in range(3)), tuple(n[..., c] for c in range(3)), lead


def sigma_n(q: np.ndarray, shape: np.ndarray, normal: np.ndarray, a: np.ndarray | None = None) -> np.ndarray:
    """Distance [length] from the centre to the tangent plane with unit normal n̂ (§4.7), (...).

    sigma_n = |S A^T n̂| = sqrt(n̂^T A S² A^T n̂), S = diag(a, b, c); ``normal`` (..., 3) broadcasts.
    ``a``: rotation_matrix(q) if the caller already has it.
    """
    ent, s, n, lead = _parts(q, shape, normal, a)
    return sigma_n_of(ent, *s, *n)


def ees_torque(q: np.ndarray, shape: np.ndarray, normal: np.ndarray, tw: np.ndarray,
               a: np.ndarray | None = None) -> np.ndarray:
    """wall/ees torque [energy] τ = T_w (n̂ × (A S² A^T) n̂), (..., 3) (§4.7).

    ``tw`` is T_w = (1/σn) ∂E/∂σn of :func:`ees_energy_force_torque`. τ = -∂E/∂θ for rotations of
    the ellipsoid about space-fixed axes; a sphere (A S² A^T ∝ 1) gets none. Same for n̂ and -n̂.
    ``a``: rotation_matrix(q) if the caller already has it.
    """
    ent, s, n, lead = _parts(q, shape, normal, a)
    tw = np.asarray(tw, dtype=np.float64)
    parts = torque_of(ent, *s, *n, tw)
    out = np.empty(np.broadcast_shapes(lead, tw.shape) + (3,))
    for c in range(3):
        out[..., c] = parts[c]
    return out


# Taylor coefficients in s = t², t = sn/r, of the two bracketed attractive terms:
#   G(t) = Σ_j t^2j / ((2j+1)(2j+3))          = (2t - 2(1-t²) atanh t) / (4t³)
#   K(t) = Σ_j t^2j / ((2j+1)(2j+3)(2j+5))    = -(6t - 10t³ - 6(1-t²)² atanh t) / (48 t^5)
# 28 terms reach the double-precision tail (< 1e-19 relative) for t < 1/2; fewer for smaller t.
_SERIES_T = 0.5
_J = np.arange(28, dtype=np.float64)
_G_COEF = 1.0 / ((2 * _J + 1) * (2 * _J + 3))
_K_COEF = 1.0 / ((2 * _J + 1) * (2 * _J + 3) * (2 * _J + 5))


def _horner(coef: np.ndarray, s):
    """Σ_j coef[j] s^j by Horner's rule (floats or arrays)."""
    out = coef[-1] * s + coef[-2]
    for j in range(coef.shape[0] - 3, -1, -1):
        out = out * s + coef[j]
    return out


# the pieces of ees_energy_force_torque, plain arithmetic on floats or arrays (the compiled path of
# engine/asphere_compiled.py compiles these very functions)


def ees_ratios(r, sn):
    """t = sn/r, s = t², p = 1 - t² formed as ((r-sn)/r)((r+sn)/r) (exact near contact)."""
    t = sn / r
    return t, t * t, ((r - sn) / r) * ((r + sn) / r)


def ees_series(s):
    """G and K of the module notes as Taylor series in s = t² (all 28 terms; for t < 1/2)."""
    return _horner(_G_COEF, s), _horner(_K_COEF, s)


def ees_closed(t, p, ln):
    """G and K in closed form, ln = ln((r-sn)/(r+sn)) (for t >= 1/2, where ~1 digit cancels)."""
    t3 = t * t * t
    return (2.0 * t + p * ln) / (4.0 * t3), -(6.0 * t - 10.0 * t3 + 3.0 * p * p * ln) / (48.0 * t3 * t * t)


def ees_combine(r, s, p, g, k, eps, sig):
    """E, F, T_w of :func:`ees_energy_force_torque` from the ratios and G, K."""
    x = sig / r
    x2 = x * x
    x3 = x2 * x
    x9 = x3 * x3 * x3
    p2 = p * p
    p4 = p2 * p2
    p7 = p4 * p2 * p
    p8 = p4 * p4
    s2 = s * s
    energy = eps * (sig * sig * sig) * (
        -(1.0 / 3.0) * x3 * g / p + (2.0 / 945.0) * x9 * (7.0 + 14.0 * s + 3.0 * s2) / p7)
    force = eps * (sig * sig) * (
        -(1.0 / 3.0) * x3 * x / p2 + (2.0 / 315.0) * x9 * x * (21.0 + 63.0 * s + 27.0 * s2 + s2 * s) / p8)
    torque = eps * sig * (-4.0 * x3 * x2 * k / p2 + (4.0 / 315.0) * x9 * x2 * (21.0 + 30.0 * s + 5.0 * s2) / p8)
    return energy, force, torque


def ees_energy_force_torque(r, sn, epsilon, sigma) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """wall/ees energy, force and torque factor (§4.7), arrays broadcast.

    r [length] distance of the centre from the wall, sn = sigma_n [length] (r > sn >= 0, else the
    result is not finite), epsilon [energy/length^3] (the effective Hamaker constant
    8π² ρ_wall ρ_ellipsoid ε_LJ a b c), sigma [length]. Returns

    * E [energy], *unshifted* (LAMMPS applies no cut-off shift to ees),
    * F = -∂E/∂r [force], F > 0 repulsive,
    * T_w = (1/sn) ∂E/∂sn [energy/length^2]; the torque is T_w (n̂ × A S² A^T n̂) (:func:`ees_torque`).

    With t = sn/r, p = 1 - t² = h/r² (formed as ((r-sn)/r)((r+sn)/r), exact near contact) and
    x = σ/r the closed forms of §4.7 are rewritten as

        E   = εσ³ [ -(1/3) x³ G(t)/p  + (2/945) x⁹ (7 + 14t² + 3t⁴)/p⁷ ]
        F   = εσ² [ -(1/3) x⁴ / p²    + (2/315) x¹⁰ (21 + 63t² + 27t⁴ + t⁶)/p⁸ ]
        T_w = εσ  [ -4 x⁵ K(t)/p²     + (4/315) x¹¹ (21 + 30t² + 5t⁴)/p⁸ ]

    where only G and K hide a cancellation (the ln term against the rational part, all digits
    lost as t -> 0). They are summed as Taylor series in t² for t < 1/2, and from the closed forms
    with ln((r-sn)/(r+sn)) for t >= 1/2, where at most ~1 digit cancels. Far field:
    E -> -εσ⁶/(9r³), F -> -εσ⁶/(3r⁴), T_w -> -4εσ⁶/(15r⁵).
    """
    r, sn, eps, sig = np.broadcast_arrays(*(np.asarray(v, dtype=np.float64) for v in (r, sn, epsilon, sigma)))
    out_shape = r.shape
    r, sn, eps, sig = (v.reshape(-1) for v in (r, sn, eps, sig))
    t, s, p = ees_ratios(r, sn)
    far = t < _SERIES_T
    # always all 28 terms: each element's value must not depend on the others in the array, so a
    # case gives bit-identical numbers alone or in any batch
    g, k = ees_series(s)
    if not np.all(far):
        near = ~far
        with np.errstate(invalid="ignore", divide="ignore"):
            ln = np.log((r[near] - sn[near]) / (r[near] + sn[near]))
        g[near], k[near] = ees_closed(t[near], p[near], ln)
    energy, force, torque = ees_combine(r, s, p, g, k, eps, sig)
    return energy.reshape(out_shape), force.reshape(out_shape), torque.reshape(out_shape)


# wall/ees on flat faces: its energy needs the ellipsoid's orientation, so no (r, p) function (the
# kernel calls ees_energy_force_torque); its energy is not shifted at the cut-off (LAMMPS, §4.7)
EES = WallStyle(
    "ees",
    (Param("epsilon", "energy/distance^3", min=0.0, doc="effective Hamaker constant"),
     Param("sigma", "distance", min=0.0, doc="length scale sigma"),
     cutoff_param()),
    shifted=False, needs_shape=True, region=False, compiled=False, virial=False,
    doc="ellipsoid against a flat wall (Babadi-Ejtehadi); needs atoms with a shape")
