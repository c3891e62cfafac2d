"""Thermal walls (engine/stochastic.py): reflected velocity distributions, positions, LAMMPS."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats

from lammps_oracle import requires_lammps
from wallbatch.engine.stochastic import reflect_positions, reflect_velocities, thermal_sigma

K = 40000
KT, MASS = 2.0, 1.0
SIGMA = math.sqrt(KT / MASS)
U = np.array([0.5, 0.0, 0.0])  # wall velocity (x); the wall is normal to z
V_IN = np.array([0.3, -0.2, -2.0])  # every atom hits the zlo wall with this velocity


def _draw(rstyle, accom=None, seed=3, side=-1, v_in=V_IN):
    v = np.tile(v_in, (K, 1))
    if side == 1:
        v[:, 2] = -v[:, 2]
    return reflect_velocities(rstyle, np.random.default_rng(seed), v, 2, side, np.full(K, SIGMA), U, accom)


def test_thermal_sigma_units():
    # real units: kB = 0.0019872067 kcal/mol/K, mvv2e = 48.88821291^2; argon at 300 K
    s = thermal_sigma(300.0, np.array([39.948]), 0.0019872067, 48.88821291**2)
    assert s[0] == pytest.approx(math.sqrt(1.380649e-23 * 300 / (39.948e-3 / 6.02214076e23)) * 1e-5, rel=2e-5)


@pytest.mark.parametrize("side", [-1, 1])
def test_diffusive_is_the_flux_maxwellian(side):
    v = _draw("diffusive", side=side)
    away = -side
    assert np.all(away * v[:, 2] > 0)
    assert stats.kstest(away * v[:, 2] / SIGMA, stats.rayleigh.cdf).pvalue > 0.01
    assert stats.kstest((v[:, 0] - U[0]) / SIGMA, stats.norm.cdf).pvalue > 0.01
    assert stats.kstest(v[:, 1] / SIGMA, stats.norm.cdf).pvalue > 0.01
    # the test has power: a wall without its velocity fails it
    assert stats.kstest(v[:, 0] / SIGMA, stats.norm.cdf).pvalue < 1e-6


def test_maxwell_mixes_diffusive_and_specular():
    a = 0.3
    v = _draw("maxwell", accom=a)
    spec = np.all(v == V_IN * [1, 1, -1], axis=1)
    frac = 1.0 - spec.mean()
    assert abs(frac - a) < 4 * math.sqrt(a * (1 - a) / K)
    d = v[~spec]
    assert stats.kstest(d[:, 2] / SIGMA, stats.rayleigh.cdf).pvalue > 0.01
    assert stats.kstest((d[:, 0] - U[0]) / SIGMA, stats.norm.cdf).pvalue > 0.01
    assert np.all(_draw("maxwell", accom=0.0) == V_IN * [1, 1, -1])


def test_ccl_distributions():
    """Tangential: Gaussian, mean u + (1-a)(v-u), variance a(2-a) kT/m. Normal: (2/a_n) w'^2 is
    noncentral chi-square (2 dof, noncentrality 2 (1-a_n) w^2 / a_n), w = v_n / (sqrt2 sigma)."""
    acc = np.array([0.3, 0.8, 0.6])
    v = _draw("ccl", accom=acc)
    for d, a in ((0, 0.3), (1, 0.8)):
        mean = U[d] + (1 - a) * (V_IN[d] - U[d])
        sd = SIGMA * math.sqrt(a * (2 - a))
        assert stats.kstest((v[:, d] - mean) / sd, stats.norm.cdf).pvalue > 0.01
    an = acc[2]
    w_in = abs(V_IN[2]) / (math.sqrt(2) * SIGMA)
    w = v[:, 2] / (math.sqrt(2) * SIGMA)
    assert np.all(w > 0)
    nc = 2 * (1 - an) * w_in**2 / an
    assert stats.kstest(2 * w**2 / an, stats.ncx2(2, nc).cdf).pvalue > 0.01
    # limits: a = 0 is specular, a_t = 1 and a_n = 1 is diffusive
    np.testing.assert_allclose(_draw("ccl", accom=[0.0, 0.0, 0.0]), np.tile(V_IN * [1, 1, -1], (K, 1)), rtol=1e-14)
    full = _draw("ccl", accom=[1.0, 1.0, 1.0])
    assert stats.kstest(full[:, 2] / SIGMA, stats.rayleigh.cdf).pvalue > 0.01


def test_same_seed_same_draws_and_unknown_rule():
    np.testing.assert_array_equal(_draw("ccl", [0.2, 0.5, 0.7], seed=9), _draw("ccl", [0.2, 0.5, 0.7], seed=9))
    with pytest.raises(ValueError, match="unknown reflection rule 'bounce'"):
        _draw("bounce")


def test_positions_leave_the_wall_at_the_crossing():
    x = np.array([[1.0, 2.0, -0.009], [0.0, 0.0, 10.02]])
    v_old = np.array([[0.3, -0.2, -2.0], [0.0, 1.0, 4.0]])
    v_new = np.array([[0.1, 0.4, 1.5], [0.5, 0.0, -1.0]])
    coords = np.array([0.0, 10.0])
    out = np.vstack([reflect_positions(x[i : i + 1], v_old[i : i + 1], v_new[i : i + 1], 2, coords[i]) for i in range(2)])
    t = np.array([0.009 / 2.0, 0.02 / 4.0])
    np.testing.assert_allclose(out[:, 2], coords + v_new[:, 2] * t, rtol=1e-14)
    np.testing.assert_allclose(out[:, :2], x[:, :2] + (v_new - v_old)[:, :2] * t[:, None], rtol=1e-14, atol=1e-15)


# ------------------------------------------------------------------------------ LAMMPS


@pytest.mark.lammps
@requires_lammps
@pytest.mark.parametrize(
    "rstyle,args,accom",
    [("diffusive", "", None), ("maxwell", " 0.3", 0.3), ("ccl", " 0.3 0.8 0.6", [0.3, 0.8, 0.6])],
)
@pytest.mark.parametrize("face", ["zlo", "zhi"])
def test_lammps_reflected_distribution_and_position(rstyle, args, accom, face):
    """Two-sample KS tests of every component against LAMMPS's wall/reflect/stochastic (one
    step of 20000 atoms, all crossing), and LAMMPS's positions obey the crossing rule."""
    from lammps_walls import probe_wall  # noqa: PLC0415

    n = 20000
    side = -1 if face == "zlo" else 1
    v_in = V_IN if side == -1 else V_IN * [1, 1, -1]
    out = probe_wall(
        f"wall/reflect/stochastic {rstyle} 4711 {face} EDGE {KT!r} 0.5 0.0 0.0{args} units box",
        np.full(n, 0.001), face, v=v_in, steps=1, dt=0.005,
    )  # fmt: skip
    ours = reflect_velocities(rstyle, np.random.default_rng(11), np.tile(v_in, (n, 1)), 2, side, np.full(n, SIGMA), U, accom)
    for d in range(3):
        assert stats.ks_2samp(out["v"][:, d], ours[:, d]).pvalue > 1e-3, d
    # LAMMPS: v_n' has the right sign, and x_n = coord + v_n' t with t = depth / |v_n|
    coord = -5.0 if side == -1 else 5.0
    t = (0.005 * 2.0 - 0.001) / 2.0
    assert np.all(-side * out["v"][:, 2] > 0)
    np.testing.assert_allclose(out["x"][:, 2], coord + out["v"][:, 2] * t, atol=1e-12)
    # mean impulse per reflection m (v_n' - v_n) agrees within 4 standard errors
    imp_l = out["v"][:, 2] - v_in[2]
    imp_o = ours[:, 2] - v_in[2]
    se = math.sqrt(imp_l.var() / n + imp_o.var() / n)
    assert abs(imp_l.mean() - imp_o.mean()) < 4 * se
