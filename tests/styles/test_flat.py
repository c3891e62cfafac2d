"""Tests for wallbatch.styles.flat: §15 reference numbers, physics invariants, broadcasting."""

from __future__ import annotations

import math

import mpmath
import numpy as np
import pytest

from wallbatch.styles.flat import STYLES, WallStyle, shifted_energy_force

LJ = {"epsilon": 1.0, "sigma": 1.0, "cutoff": 2.5}
MORSE = {"D0": 1.5, "alpha": 2.0, "r0": 1.1, "cutoff": 3.0}
COLLOID = {"epsilon": 1.3, "sigma": 1.0, "cutoff": 3.5}

# physics.md §15, flat walls, LAMMPS 22Jul2025.
# (style, side, r, params, shifted E, f_w[1] = side*F, absolute tolerance on f_w from its printed digits)
REFERENCE = [
    ("lj93", -1, 1.2, LJ, -0.48889776297466175, +1.2529525597914448, 1e-14),
    ("lj93", +1, 1.2, LJ, -0.48889776297466253, -1.2529525597914466, 1e-14),
    ("lj93", -1, 0.9, LJ, -0.9636204261210937, +1.1309073193, 5e-11),
    ("lj126", -1, 1.2, LJ, -0.8746483964470763, +2.211693342223078, 1e-14),
    ("lj126", -1, 0.9, LJ, 6.652435844388923, -138.65962399427687, 1e-12),
    ("lj1043", -1, 1.2, LJ, -3.0282506349571583, +7.972368600606706, 1e-14),
    ("lj1043", -1, 0.9, LJ, -3.345584562912814, -34.69793953725022, 1e-13),
    ("harmonic", -1, 1.2, {**LJ, "epsilon": 2.0}, 3.38, -5.2, 1e-14),
    ("morse", -1, 1.3, MORSE, -1.2706050535127498, +1.32594649, 5e-9),
    ("morse", +1, 0.6, MORSE, 2.9951003014371884, +28.0246456, 5e-8),
    ("colloid", -1, 1.7, {**COLLOID, "radius": 0.5}, -0.007237555410428977, +0.01498109, 5e-9),
    ("colloid", -1, 1.7, {**COLLOID, "radius": 1.0}, -0.07875864601841431, +0.12986427, 5e-9),
]


@pytest.mark.parametrize(
    "name, side, r, p, e_ref, fw_ref, fw_tol",
    REFERENCE,
    ids=[f"{row[0]}-{'lo' if row[1] < 0 else 'hi'}-{row[2]}-{i}" for i, row in enumerate(REFERENCE)],
)
def test_lammps_reference(name, side, r, p, e_ref, fw_ref, fw_tol):
    energy, force = shifted_energy_force(STYLES[name], r, p)
    assert energy == pytest.approx(e_ref, rel=1e-12)
    assert side * force == pytest.approx(fw_ref, abs=fw_tol)  # wall-vector element
    # force on the atom along dim is -side*F; e.g. lj93 xlo 1.2 is -1.25295 (attractive)
    assert -side * force == pytest.approx(-fw_ref, abs=fw_tol)


def test_sign_convention_lj93_xlo():
    _, force = shifted_energy_force(STYLES["lj93"], 1.2, LJ)
    assert force == pytest.approx(-1.25295256, abs=5e-9)  # F < 0: attractive at r = 1.2


# Per style: parameters, sample distances (inside the cut-off) and a distance near contact.
CASES = {
    "lj93": ({"epsilon": 1.3, "sigma": 0.9, "cutoff": 2.5}, [0.6, 0.95, 1.4, 2.2], 0.5),
    "lj126": ({"epsilon": 1.3, "sigma": 0.9, "cutoff": 2.5}, [0.75, 0.95, 1.4, 2.2], 0.5),
    "lj1043": ({"epsilon": 1.3, "sigma": 0.9, "cutoff": 2.5}, [0.6, 0.95, 1.4, 2.2], 0.5),
    "colloid": ({"epsilon": 1.3, "sigma": 0.8, "cutoff": 3.5, "radius": 0.5}, [0.8, 1.2, 1.7, 3.0], 0.6),
    "harmonic": ({"epsilon": 2.0, "sigma": 1.0, "cutoff": 2.5}, [0.3, 1.2, 2.0, 2.45], 0.1),
    "morse": ({"D0": 1.5, "alpha": 2.0, "r0": 1.1, "cutoff": 3.0}, [0.5, 0.9, 1.6, 2.8], 0.5),
}


def test_registry():
    assert set(STYLES) == {"lj93", "lj126", "lj1043", "colloid", "harmonic", "morse"}
    assert set(CASES) == set(STYLES)
    for name, style in STYLES.items():
        assert isinstance(style, WallStyle)
        assert style.name == name
        assert style.shifted
        assert style.needs_radius == (name == "colloid")
        expected = ("D0", "alpha", "r0", "cutoff") if name == "morse" else ("epsilon", "sigma", "cutoff")
        assert style.params == expected


def test_too_close():
    radius = np.array([0.5, 1.0, 0.25])
    for name, style in STYLES.items():
        threshold = style.too_close({**CASES[name][0], "radius": radius})
        if name == "colloid":
            np.testing.assert_array_equal(threshold, radius)
        else:
            assert threshold == 0.0


@pytest.mark.parametrize("name", sorted(STYLES))
def test_force_is_minus_gradient(name):
    p, rs, _ = CASES[name]
    style = STYLES[name]
    r = np.array(rs)
    h = 1e-5 * r
    e_plus, _ = style.energy_force(r + h, p)
    e_minus, _ = style.energy_force(r - h, p)
    numeric = -(e_plus - e_minus) / (2.0 * h)
    _, force = style.energy_force(r, p)
    np.testing.assert_allclose(force, numeric, rtol=1e-6, atol=1e-10)


@pytest.mark.parametrize("name", sorted(STYLES))
def test_shifted_energy_zero_at_cutoff(name):
    p, rs, _ = CASES[name]
    style = STYLES[name]
    energy, _ = shifted_energy_force(style, p["cutoff"], p)
    assert energy == 0.0
    # and the shift is a constant offset
    e_shift, f_shift = shifted_energy_force(style, np.array(rs), p)
    e_raw, f_raw = style.energy_force(np.array(rs), p)
    e_rc, _ = style.energy_force(p["cutoff"], p)
    # the plain difference carries the rounding errors of E(r) and E(rc) (<= 1e-14 of each, see
    # test_stability.py); shifted_energy avoids that cancellation and is checked against mpmath there
    plain = e_raw - e_rc
    plain_rounding = 1e-14 * (np.abs(e_raw) + abs(e_rc))
    np.testing.assert_array_less(np.abs(e_shift - plain), 1e-15 * np.abs(plain) + plain_rounding)
    np.testing.assert_array_equal(f_shift, f_raw)


@pytest.mark.parametrize("name", sorted(STYLES))
def test_repulsive_near_contact(name):
    p, _, r_contact = CASES[name]
    energy, force = STYLES[name].energy_force(r_contact, p)
    assert force > 0
    shifted, _ = shifted_energy_force(STYLES[name], r_contact, p)
    assert shifted > 0


def test_lj93_minimum():
    eps, sigma = 1.7, 0.8
    p = {"epsilon": eps, "sigma": sigma, "cutoff": 2.5}
    r_min = (2.0 / 5.0) ** (1.0 / 6.0) * sigma
    energy, force = STYLES["lj93"].energy_force(r_min, p)
    assert force == pytest.approx(0.0, abs=1e-13)
    assert energy == pytest.approx(-eps * math.sqrt(10.0) / 3.0, rel=1e-14)
    assert STYLES["lj93"].energy_force(0.99 * r_min, p)[1] > 0
    assert STYLES["lj93"].energy_force(1.01 * r_min, p)[1] < 0


def test_lj126_minimum():
    eps, sigma = 1.7, 0.8
    p = {"epsilon": eps, "sigma": sigma, "cutoff": 2.5}
    r_min = 2.0 ** (1.0 / 6.0) * sigma
    energy, force = STYLES["lj126"].energy_force(r_min, p)
    assert force == pytest.approx(0.0, abs=1e-13)
    assert energy == pytest.approx(-eps, rel=1e-14)


def test_harmonic():
    p = {"epsilon": 2.0, "sigma": 1.0, "cutoff": 2.5}
    energy, force = STYLES["harmonic"].energy_force(2.5, p)
    assert energy == 0.0 and force == 0.0
    r = np.linspace(0.01, 2.5, 50)
    energy, force = STYLES["harmonic"].energy_force(r, p)
    assert np.all(force >= 0)
    np.testing.assert_allclose(energy, 2.0 * (r - 2.5) ** 2, rtol=1e-15)


def test_morse_minimum():
    p = {"D0": 1.5, "alpha": 2.0, "r0": 1.1, "cutoff": 3.0}
    energy, force = STYLES["morse"].energy_force(1.1, p)
    assert force == 0.0
    assert energy == pytest.approx(-1.5, rel=1e-15)
    # near r0 the force is accurate (expm1), not a difference of two ~1 numbers
    _, force = STYLES["morse"].energy_force(1.1 + 1e-9, p)
    assert force == pytest.approx(2 * 2.0 * 1.5 * (-2.0 * 1e-9), rel=1e-6)


# ---- colloid against an mpmath evaluation of the §4.6 closed form ----

mpmath.mp.dps = 40


def _colloid_energy_mp(r, radius, eps, sigma):
    r, big_r, eps, sigma = (mpmath.mpf(x) for x in (r, radius, eps, sigma))
    d = r - big_r
    rep = sigma**6 / 7560 * ((6 * big_r - d) / d**7 + (d + 8 * big_r) / (d + 2 * big_r) ** 7)
    att = (2 * big_r * (d + big_r) + d * (d + 2 * big_r) * (mpmath.log(d) - mpmath.log(d + 2 * big_r))) / (
        d * (d + 2 * big_r)
    )
    return eps * (rep - att / 6)


@pytest.mark.parametrize(
    "radius, r, sigma",
    [
        (0.5, 1.7, 1.0),
        (1.0, 1.7, 1.0),
        (0.3, 0.35, 1.0),  # close to contact, repulsive
        (2.0, 2.5, 0.8),  # large sphere
        (0.1, 1.0, 1.0),  # R small relative to r
        (0.05, 2.0, 1.0),
        (0.01, 1.0, 1.0),
        (0.2, 3.0, 0.5),
    ],
)
def test_colloid_against_mpmath(radius, r, sigma):
    eps = 1.3
    e_ref = _colloid_energy_mp(r, radius, eps, sigma)
    f_ref = -mpmath.diff(lambda x: _colloid_energy_mp(x, radius, eps, sigma), mpmath.mpf(r))
    energy, force = STYLES["colloid"].energy_force(r, {"epsilon": eps, "sigma": sigma, "radius": radius})
    assert energy == pytest.approx(float(e_ref), rel=1e-12)
    assert force == pytest.approx(float(f_ref), rel=1e-12)


def test_colloid_shift_uses_own_radius():
    p = {**COLLOID, "radius": np.array([0.5, 1.0])}
    energy, force = shifted_energy_force(STYLES["colloid"], np.array([1.7, 1.7]), p)
    np.testing.assert_allclose(energy, [-0.007237555410428977, -0.07875864601841431], rtol=1e-12)
    np.testing.assert_allclose(force, [-0.01498109, -0.12986427], atol=5e-9)


# ---- broadcasting: r (C, N), per-case params (C, 1), per-atom radius (C, N) ----


@pytest.mark.parametrize("name", sorted(STYLES))
def test_broadcasting(name):
    style = STYLES[name]
    base, rs, _ = CASES[name]
    n_cases, n_atoms = 3, 4
    scale = np.array([[0.9], [1.0], [1.1]])  # (C, 1)
    p = {key: value * scale for key, value in base.items() if key != "radius"}
    r = np.array(rs)[None, :] * np.ones((n_cases, 1))  # (C, N)
    if style.needs_radius:
        p["radius"] = np.array([[0.3, 0.4, 0.5, 0.45]]) * scale * np.ones((1, n_atoms))  # (C, N)
    energy, force = shifted_energy_force(style, r, p)
    assert energy.shape == force.shape == (n_cases, n_atoms)
    for c in range(n_cases):
        for i in range(n_atoms):
            p_ci = {key: float(np.broadcast_to(value, (n_cases, n_atoms))[c, i]) for key, value in p.items()}
            e_ci, f_ci = shifted_energy_force(style, float(r[c, i]), p_ci)
            assert energy[c, i] == pytest.approx(e_ci, rel=1e-15, abs=1e-300)
            assert force[c, i] == pytest.approx(f_ci, rel=1e-15, abs=1e-300)
    if style.needs_radius:
        np.testing.assert_array_equal(style.too_close(p), p["radius"])


def _lj1043_mp(r: float, eps: float, sigma: float, rc: float) -> tuple[mpmath.mpf, mpmath.mpf]:
    """lj1043 E(r) - E(rc) and F(r) in 50-digit arithmetic (the textbook form, physics §4.3)."""
    with mpmath.workdps(50):
        r, eps, sigma, rc = (mpmath.mpf(v) for v in (r, eps, sigma, rc))
        shift = mpmath.mpf("0.61") / mpmath.sqrt(2) * sigma

        def energy(x):
            return 2 * mpmath.pi * eps * (mpmath.mpf(2) / 5 * (sigma / x) ** 10 - (sigma / x) ** 4
                                          - mpmath.sqrt(2) * sigma ** 3 / (3 * (x + shift) ** 3))

        force = 2 * mpmath.pi * eps * (4 * sigma ** 10 / r ** 11 - 4 * sigma ** 4 / r ** 5
                                       - mpmath.sqrt(2) * sigma ** 3 / (r + shift) ** 4)
        return energy(r) - energy(rc), force


@pytest.mark.parametrize("r, eps, sigma", [(1e-33, 1e-70, 1.0), (1e-33, 1e-40, 1e-3), (1e-20, 1e-100, 2.0)])
def test_lj1043_no_overflow_where_finite(r, eps, sigma):
    """Intermediate powers of sigma/r stay finite wherever the result is: at r = 1e-33 sigma the
    force is 2.5e294 (eps = 1e-70), not inf; energy, force and shifted energy within 1e-13."""
    st = STYLES["lj1043"]
    p = {"epsilon": eps, "sigma": sigma, "cutoff": 2.5 * sigma}
    e_ref, f_ref = _lj1043_mp(r, eps, sigma, 2.5 * sigma)
    with np.errstate(all="raise"):
        energy, force = shifted_energy_force(st, r, p)
    assert math.isfinite(force) and math.isfinite(energy)
    assert force == pytest.approx(float(f_ref), rel=1e-13)
    assert energy == pytest.approx(float(e_ref), rel=1e-13)
    if (r, eps, sigma) == (1e-33, 1e-70, 1.0):
        assert force == pytest.approx(2.5132741228718346e294, rel=1e-13)  # 8 pi 1e293


def test_lj1043_normal_range_unchanged():
    """Across the usual range the reordered arithmetic agrees with the exact values to round-off."""
    st = STYLES["lj1043"]
    p = {"epsilon": 1.3, "sigma": 0.9, "cutoff": 2.5}
    for r in np.linspace(0.45, 2.49, 205):
        e_ref, f_ref = _lj1043_mp(float(r), 1.3, 0.9, 2.5)
        energy, force = shifted_energy_force(st, float(r), p)
        scale = 1.0 + abs(float(f_ref))
        assert abs(force - float(f_ref)) <= 4e-15 * scale * 10, r
        assert abs(energy - float(e_ref)) <= 4e-14 * (1.0 + abs(float(e_ref))), r
