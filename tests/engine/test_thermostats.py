"""Thermostat kernels (engine/thermostats.py) against closed forms; LAMMPS parity is in
test_thermo_lammps.py."""

from __future__ import annotations

import numpy as np
import pytest

from wallbatch.engine.thermostats import (
    NHChain,
    berendsen_factor,
    group_dof,
    kinetic_sum,
    langevin_force,
    langevin_power,
    ramp,
    rescale_factor,
    scale_group,
    temperature,
)


def _gas(C=3, N=20, seed=1):
    rng = np.random.default_rng(seed)
    return rng.normal(0.0, 1.0, (C, N, 3)), rng.uniform(0.5, 2.0, (C, N))


def test_dof_and_temperature_closed_form():
    assert group_dof(10) == 27 and group_dof(10, 2) == 18 and group_dof(1) == 0
    v, m = _gas()
    mask = np.arange(20) < 7
    want = np.array([(m[c, :7, None] * v[c, :7] ** 2).sum() for c in range(3)]) * 2.5 / (18 * 0.5)
    np.testing.assert_allclose(temperature(v, m, mask, 18, 2.5, 0.5), want, rtol=1e-14)
    assert np.all(temperature(v, m, mask, 0, 1.0, 1.0) == 0.0)


def test_ramp_is_linear_and_zero_length_run_stays_at_start():
    t = ramp(np.array([1.0, 2.0]), np.array([3.0, 2.0]), np.array([25, 25]), 0, 100)
    np.testing.assert_allclose(t, [1.5, 2.0], rtol=1e-15)
    assert np.all(ramp(np.array([1.0]), np.array([3.0]), np.array([0]), 0, 0) == 1.0)


def test_berendsen_lambda_and_energy_bookkeeping():
    v, m = _gas()
    dof = group_dof(20)
    T = temperature(v, m, None, dof, 1.0, 1.0)
    target, dt, damp = np.array([0.5, 1.0, 2.0]), np.full(3, 0.005), np.array([0.1, 0.2, 1.0])
    lam, removed = berendsen_factor(T, target, dt, damp, dof, 1.0)
    np.testing.assert_allclose(lam ** 2, 1.0 + dt / damp * (target / T - 1.0), rtol=1e-14)
    ke0 = 0.5 * kinetic_sum(v, m)
    scale_group(v, lam, None)
    np.testing.assert_allclose(ke0 - 0.5 * kinetic_sum(v, m), removed, rtol=1e-12)
    # the relaxation: T' - T0 = (1 - dt/damp) (T - T0)
    np.testing.assert_allclose(temperature(v, m, None, dof, 1.0, 1.0) - target, (1 - dt / damp) * (T - target),
                               rtol=1e-12)


def test_rescale_window_fraction_and_energy():
    v, m = _gas()
    dof = group_dof(20)
    T = temperature(v, m, None, dof, 1.0, 1.0)
    target = T + np.array([0.01, -0.5, 0.3])  # first inside the window
    window, fraction = np.full(3, 0.05), np.array([1.0, 0.5, 0.25])
    factor, removed = rescale_factor(T, target, window, fraction, dof, 1.0)
    assert factor[0] == 1.0 and removed[0] == 0.0
    ke0 = 0.5 * kinetic_sum(v, m)
    scale_group(v, factor, None)
    T1 = temperature(v, m, None, dof, 1.0, 1.0)
    np.testing.assert_allclose(T1[1:], (T - fraction * (T - target))[1:], rtol=1e-13)
    np.testing.assert_allclose(ke0 - 0.5 * kinetic_sum(v, m), removed, rtol=1e-12, atol=1e-14)


def test_scale_group_touches_only_the_group():
    v, _ = _gas()
    mask = np.arange(20) % 3 == 0
    v0 = v.copy()
    scale_group(v, np.array([2.0, 3.0, 4.0]), mask)
    assert np.array_equal(v[:, ~mask], v0[:, ~mask])
    np.testing.assert_array_equal(v[:, mask], v0[:, mask] * np.array([2.0, 3.0, 4.0])[:, None, None])


def test_nh_half_step_from_rest_closed_form():
    """tchain 1, chain at rest: eta_dot = dt/4 w^2 (T/T0 - 1); scale exp(-dt/2 eta_dot); then the
    second quarter kick with the scaled temperature; eta = dt/2 eta_dot(first)."""
    dt, damp, T0, T, dof = 0.01, 0.2, 1.0, 1.7, 57
    ch = NHChain.start(1, 1, np.array([damp]), dof, 1.0)
    ch.setup(np.array([T]), np.array([T0]))
    w2 = 1.0 / damp ** 2
    np.testing.assert_allclose(ch.eta_mass[0, 0], dof * T0 / w2, rtol=1e-15)
    fac = ch.half_step(np.array([dt]), np.array([T0]))
    ed1 = dt / 4 * w2 * (T / T0 - 1)
    f = np.exp(-dt / 2 * ed1)
    np.testing.assert_allclose(fac, f, rtol=1e-14)
    np.testing.assert_allclose(ch.t_current, T * f * f, rtol=1e-14)
    np.testing.assert_allclose(ch.eta[0, 0], dt / 2 * ed1, rtol=1e-14)
    np.testing.assert_allclose(ch.eta_dot[0, 0], ed1 + dt / 4 * w2 * (T * f * f / T0 - 1), rtol=1e-14)


def test_nh_chain_conserves_its_extended_energy_to_second_order():
    """Free particles under fix nvt: KE + chain energy is conserved with an O(dt^2) error (the
    chain is integrated by a symmetric Trotter splitting); halving dt quarters the drift."""
    def drift(dt):
        v, m = _gas(C=2, N=30, seed=4)
        dof = group_dof(30)
        ch = NHChain.start(2, 3, np.array([0.05, 0.1]), dof, 1.0)
        ch.setup(temperature(v, m, None, dof, 1.0, 1.0), np.array([0.3, 2.5]))
        h0 = 0.5 * kinetic_sum(v, m) + ch.energy()
        h = []
        for _ in range(round(0.5 / dt)):
            scale_group(v, ch.half_step(np.full(2, dt), ch.t_target), None)
            ch.t_current = temperature(v, m, None, dof, 1.0, 1.0)
            scale_group(v, ch.half_step(np.full(2, dt), ch.t_target), None)
            h.append(0.5 * kinetic_sum(v, m) + ch.energy() - h0)
        return np.max(np.abs(h), axis=0), v, m, ch
    d1, *_ = drift(0.004)
    d2, v, m, _ = drift(0.002)
    assert np.all(d1 > 0) and np.all(d1 < 0.2)  # KE is ~50 here
    np.testing.assert_allclose(d1 / d2, 4.0, rtol=0.1)
    # after a few damping times the temperature has moved to the target's side
    T = temperature(v, m, None, group_dof(30), 1.0, 1.0)
    assert T[0] < 0.8 and T[1] > 1.5


def test_langevin_drag_noise_amplitude_and_zero():
    v, m = _gas(C=2, N=12)
    mask = np.arange(12) < 9
    T, damp, dt = np.array([1.5, 0.7]), np.array([0.5, 2.0]), np.array([0.005, 0.002])
    half = np.full(v.shape, 0.5)
    f = langevin_force(v, m, mask, T, damp, dt, half, 1.0, 1.0, 1.0)  # u = 1/2: drag only
    np.testing.assert_allclose(f[:, mask], (-m[:, :, None] * v / damp[:, None, None])[:, mask], rtol=1e-15)
    assert np.all(f[:, ~mask] == 0.0)
    # u = 1 vs u = 0: the uniform's spread times g2; g2^2 / 12 = 2 kB T m / (damp dt)
    spread = langevin_force(v, m, mask, T, damp, dt, np.ones(v.shape), 1.0, 1.0, 1.0) \
        - langevin_force(v, m, mask, T, damp, dt, np.zeros(v.shape), 1.0, 1.0, 1.0)
    np.testing.assert_allclose(spread[:, mask, 0] ** 2 / 12,
                               (2 * T[:, None] * m / (damp[:, None] * dt[:, None]))[:, mask], rtol=1e-13)
    # zero yes: the random forces of the group sum to zero
    u = np.random.default_rng(0).random(v.shape)
    fz = langevin_force(v, m, mask, T, damp, dt, u, 1.0, 1.0, 1.0, zero=True)
    fz -= langevin_force(v, m, mask, T, damp, dt, half, 1.0, 1.0, 1.0)
    np.testing.assert_allclose(fz[:, mask].sum(axis=1), 0.0, atol=1e-12)
    assert np.abs(fz[:, mask]).max() > 1.0
    np.testing.assert_allclose(langevin_power(f, v), np.einsum("cni,cni->c", f, v), rtol=1e-15)


def test_langevin_units_real():
    """In real units the drag is -m v / (damp ftm2v) (a force) and the noise variance
    2 kB T m / (damp dt mvv2e) / ftm2v^2."""
    from wallbatch.units import UNIT_SYSTEMS

    u = UNIT_SYSTEMS["real"]
    v, m = _gas(C=1, N=4)
    T, damp, dt = np.array([300.0]), np.array([100.0]), np.array([2.0])
    f = langevin_force(v, m, None, T, damp, dt, np.full(v.shape, 0.5), u.ftm2v, u.mvv2e, u.boltz)
    np.testing.assert_allclose(f, -m[..., None] * v / (100.0 * u.ftm2v), rtol=1e-15)
    spread = langevin_force(v, m, None, T, damp, dt, np.ones(v.shape), u.ftm2v, u.mvv2e, u.boltz) \
        - langevin_force(v, m, None, T, damp, dt, np.zeros(v.shape), u.ftm2v, u.mvv2e, u.boltz)
    np.testing.assert_allclose(spread[..., 0] ** 2 / 12,
                               2 * u.boltz * 300.0 * m / (100.0 * 2.0 * u.mvv2e) / u.ftm2v ** 2, rtol=1e-13)


def test_batched_chain_equals_one_case_at_a_time():
    v, m = _gas(C=3, N=15, seed=9)
    dof = group_dof(15)
    damp, target = np.array([0.1, 0.3, 0.05]), np.array([1.0, 2.0, 0.5])

    def run(vv, mm, d, t):
        ch = NHChain.start(len(d), 3, d, dof, 1.0)
        ch.setup(temperature(vv, mm, None, dof, 1.0, 1.0), t)
        for _ in range(50):
            scale_group(vv, ch.half_step(np.full(len(d), 0.005), t), None)
            ch.t_current = temperature(vv, mm, None, dof, 1.0, 1.0)
            scale_group(vv, ch.half_step(np.full(len(d), 0.005), t), None)
        return vv, ch.energy()

    vb, eb = run(v.copy(), m, damp, target)
    for c in range(3):
        v1, e1 = run(v[c:c + 1].copy(), m[c:c + 1], damp[c:c + 1], target[c:c + 1])
        assert np.array_equal(v1[0], vb[c]) and e1[0] == eb[c]


@pytest.mark.parametrize("tloop", [1, 3])
def test_nh_tloop_substeps_compose(tloop):
    """With tloop sub-steps the returned factor is the product of the sub-step factors and
    t_current follows it exactly."""
    ch = NHChain.start(1, 2, np.array([0.1]), 30, 1.0, tloop=tloop)
    ch.setup(np.array([2.0]), np.array([1.0]))
    fac = ch.half_step(np.array([0.01]), np.array([1.0]))
    np.testing.assert_allclose(ch.t_current, 2.0 * fac ** 2, rtol=1e-14)
    assert 0.99 < fac[0] < 1.0
