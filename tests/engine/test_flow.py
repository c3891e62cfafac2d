"""fix wall/flow (physics.md §8, decisions table): the flux-weighted redraw, the ideal gas under
the two crossing rules, segment bookkeeping, batching, and the scene checks."""

from __future__ import annotations

import math

import mpmath
import numpy as np
import pytest
from lammps_oracle import _load_lammps, requires_lammps
from scipy import stats
from scipy.special import erfc

from wallbatch.engine.flow import (
    FlowKernel,
    _velocities,
    check_flow,
    log_tail,
    positive_fraction,
    sample_flux_maxwellian,
    solve_flux_speed,
)
from wallbatch.scene.case import FlowSpec
from wallbatch.units import UNIT_SYSTEMS

LJ = UNIT_SYSTEMS["lj"]
SQPI = math.sqrt(math.pi)


# ----------------------------------------------------------------------------- analytic reference
#
# f(v) ∝ |v| exp(-γ²(v - u)²) on the whole line. In ν = γv, δ = γu: f ∝ |ν| exp(-(ν - δ)²).
# Upper tail for ν >= 0:  T(ν; δ) = ∫_ν^∞ t exp(-(t-δ)²) dt = exp(-(ν-δ)²)/2 + δ (√π/2) erfc(ν-δ)
#   (d/dν of the right side is -ν exp(-(ν-δ)²)).
# Lower tail for ν < 0:   ∫_-∞^ν |t| exp(-(t-δ)²) dt = (t = -s) ∫_|ν|^∞ s exp(-(s+δ)²) ds = T(|ν|; -δ).
# Normalisation Z = T(0; δ) + T(0; -δ); CDF F(ν) = T(|ν|; -δ)/Z for ν < 0, 1 - T(ν; δ)/Z for ν >= 0.
# Moments: I_n(δ) = ∫_0^∞ ν^n exp(-(ν-δ)²) dν (s = ν - δ, ∫_a^∞ s^k e^{-s²} in closed form):
#   I_2 = δ e^{-δ²}/2 + (√π/4)(1 + 2δ²) erfc(-δ),   I_3 = (1 + δ²) e^{-δ²}/2 + (√π/4)(3δ + 2δ³) erfc(-δ);
#   <v> = (I_2(δ) - I_2(-δ)) / (γ Z),  <v²> = (I_3(δ) + I_3(-δ)) / (γ² Z),  P(v > 0) = T(0; δ)/Z.


def tail(nu, d):
    return 0.5 * np.exp(-(nu - d) ** 2) + d * SQPI / 2 * erfc(nu - d)


def flux_cdf(v, gamma, u):
    d, nu = gamma * u, gamma * np.asarray(v, float)
    z = tail(0.0, d) + tail(0.0, -d)
    return np.where(nu < 0, tail(np.abs(nu), -d) / z, 1.0 - tail(np.maximum(nu, 0.0), d) / z)


def flux_moments(gamma, u):
    """(<v>, <v²>, P(v > 0)) of the flux-weighted shifted Maxwellian."""
    d = gamma * u
    z = tail(0.0, d) + tail(0.0, -d)
    i2 = lambda a: a * math.exp(-a * a) / 2 + SQPI / 4 * (1 + 2 * a * a) * erfc(-a)
    i3 = lambda a: (1 + a * a) * math.exp(-a * a) / 2 + SQPI / 4 * (3 * a + 2 * a ** 3) * erfc(-a)
    return (i2(d) - i2(-d)) / (gamma * z), (i3(d) + i3(-d)) / (gamma ** 2 * z), tail(0.0, d) / z


def gamma_of(kT, m):
    return 1.0 / math.sqrt(2.0 * kT / m)


def mp_tail(nu, d):
    nu, d = mpmath.mpf(nu), mpmath.mpf(d)
    return mpmath.exp(-(nu - d) ** 2) / 2 + d * mpmath.sqrt(mpmath.pi) / 2 * mpmath.erfc(nu - d)


# ----------------------------------------------------------------------------- the sampler


def test_log_tail_matches_mpmath_without_overflow_or_cancellation():
    mpmath.mp.dps = 50
    for d in (-1e3, -30.0, -5.0, -2.0, -0.3, 0.0, 0.3, 2.0, 5.0, 30.0, 1e3):
        for nu in (0.0, 1e-8, 0.01, 0.5, 1.0, 1.9, 2.5, 4.0, 10.0, 40.0, 1005.0):
            ref = float(mpmath.log(mp_tail(nu, d)))
            got = float(log_tail(nu, d))
            assert np.isfinite(got)
            assert abs(got - ref) <= 1e-13 * max(1.0, abs(ref)), (d, nu, got, ref)


def test_positive_fraction_is_the_section_8_3_formula_and_saturates():
    for d in (0.0, 0.1, 0.3266, 1.0, 2.5):
        e = math.exp(-d * d) / SQPI + d * math.erf(d)
        assert positive_fraction(d) == pytest.approx(0.5 * (1 + d / e), rel=1e-14)
    # kT = 1.5, m = 2, u = 0.4 (§8.3): P+ = 0.7620
    assert positive_fraction(gamma_of(1.5, 2.0) * 0.4) == pytest.approx(0.7620, abs=5e-5)
    assert positive_fraction(np.array([40.0, 1e8])).tolist() == [1.0, 1.0]  # exp(-δ²) underflows: no NaN


def test_analytic_reference_values_of_section_8_3():
    mean, mean2, p_plus = flux_moments(gamma_of(1.5, 2.0), 0.4)
    assert (mean, mean2, p_plus) == pytest.approx((0.7496, 1.7998, 0.7620), abs=1e-4)


@pytest.mark.parametrize("kT,m,u", [(1.5, 2.0, 0.4), (1.0, 1.0, 3.0), (0.2, 5.0, 0.05), (4.0, 0.5, 0.5)])
def test_sampler_matches_the_flux_weighted_maxwellian(kT, m, u):
    gamma = gamma_of(kT, m)
    v_axis, v_par = sample_flux_maxwellian(np.random.default_rng(2024), 20000, gamma, u)
    assert stats.kstest(v_axis, lambda v: flux_cdf(v, gamma, u)).pvalue > 0.01
    for k in range(2):  # parallel: N(0, kT/m), no flow
        assert stats.kstest(v_par[:, k], stats.norm(0.0, math.sqrt(kT / m)).cdf).pvalue > 0.01


def test_sampler_mean_and_positive_fraction_within_three_standard_errors():
    gamma = gamma_of(1.5, 2.0)
    n = 200_000
    v, vp = sample_flux_maxwellian(np.random.default_rng(7), n, gamma, 0.4)
    mean, mean2, p_plus = flux_moments(gamma, 0.4)
    assert abs(v.mean() - mean) < 3 * v.std() / math.sqrt(n)
    assert abs((v > 0).mean() - p_plus) < 3 * math.sqrt(p_plus * (1 - p_plus) / n)
    assert abs((v * v).mean() - mean2) < 3 * (v * v).std() / math.sqrt(n)
    assert abs(vp.var() - 0.75) < 3 * 0.75 * math.sqrt(2 / (2 * n))


def test_sampler_per_atom_masses():
    """gamma per atom (masses differ): each mass gets its own distribution."""
    kT, u, n = 1.5, 0.4, 30000
    mass = np.where(np.arange(n) % 2 == 0, 1.0, 4.0)
    gamma = 1.0 / np.sqrt(2 * kT / mass)
    v, vp = sample_flux_maxwellian(np.random.default_rng(3), n, gamma, u)
    for m in (1.0, 4.0):
        sel, g = mass == m, gamma_of(kT, m)
        assert stats.kstest(v[sel], lambda x, g=g: flux_cdf(x, g, u)).pvalue > 0.01
        assert stats.kstest(vp[sel].ravel(), stats.norm(0.0, math.sqrt(kT / m)).cdf).pvalue > 0.01
    # the heavy atoms are really slower: their parallel spread is half the light ones'
    assert vp[mass == 4.0].std() / vp[mass == 1.0].std() == pytest.approx(0.5, abs=0.02)


def test_draw_order_is_side_uniforms_speed_uniforms_then_normals():
    n, gamma = 5, np.linspace(0.5, 2.0, 5)
    rng = np.random.default_rng(11)
    clone = np.random.default_rng(11)
    v, vp = sample_flux_maxwellian(rng, n, gamma, 0.4)
    u1, u2, g = clone.random(n), clone.random(n), clone.standard_normal((n, 2))
    assert rng.bit_generator.state == clone.bit_generator.state  # nothing else was drawn
    np.testing.assert_array_equal(vp, g / (gamma[:, None] * math.sqrt(2.0)))
    side = np.where(u1 > positive_fraction(gamma * 0.4), -1.0, 1.0)
    nu = solve_flux_speed(side * gamma * 0.4, 1.0 - u2)
    np.testing.assert_array_equal(v, side * nu / gamma)


def test_solver_is_accurate_and_finite_for_extreme_uniforms_and_flows():
    mpmath.mp.dps = 60
    for d in (-1e3, -30.0, -5.0, -0.3, 0.0, 0.3, 5.0, 30.0, 1e4):
        u = np.array([1e-300, 2.0 ** -53, 1e-10, 0.3, 0.5, 0.999, 1.0 - 2.0 ** -53, 1.0])
        nu = solve_flux_speed(np.full(u.size, d), u)
        assert np.all(np.isfinite(nu)) and np.all(nu >= 0.0)
        assert nu[-1] == 0.0  # u = 1: the lower end
        assert np.all(np.diff(nu) <= 0.0)  # larger u, smaller speed
        for k in range(6):  # T(ν)/T(0) = u (the conditioning of ν - δ limits |δ| = 1e3, 1e4)
            ratio = float(mp_tail(nu[k], d) / mp_tail(0, d))
            assert ratio == pytest.approx(u[k], rel=1e-9 if abs(d) >= 1e3 else 1e-12), (d, u[k])
    # whole redraws at extreme gamma (hot / cold gas) and flow: finite, and a cold gas streams at vflow
    rng = np.random.default_rng(5)
    for gamma, u in ((1e-6, 0.4), (1e6, 0.4), (1.0, 1e3), (1e3, 1e-9)):
        v, vp = sample_flux_maxwellian(rng, 1000, gamma, u)
        assert np.all(np.isfinite(v)) and np.all(np.isfinite(vp))
    v, _ = sample_flux_maxwellian(rng, 1000, 1e6, 0.4)
    assert np.all(np.abs(v - 0.4) < 1e-5)


def lammps_newton(delta: float, U2: float) -> float:
    """LAMMPS's speed solve as physics.md §8.3 states it: 10 plain Newton steps on
    exp(x²) √π (ξ - δ erfc x) - 1 = 0, ξ = U2 (E + δ), from the mode; returns ν = x + δ."""
    e = math.exp(-delta * delta) / SQPI + delta * math.erf(delta)
    xi = U2 * (e + delta)
    x = (math.sqrt(delta * delta + 2) - delta) / 2
    for _ in range(10):
        x -= (math.exp(x * x) * SQPI * (xi - delta * math.erfc(x)) - 1) / (2 * (x + delta))
    return x + delta


def test_quirk_11_lammps_newton_truncates_the_tail():
    """LAMMPS's fixed 10 Newton steps agree with the converged solve for ordinary uniforms but
    stall for small ones: with U2 <= 1e-6 it returns about 3.66 whatever U2 is (kT 1.5, m 2, u 0.4), so speeds in the
    upper tail (beyond the ~1e-6 quantile) are never drawn. wallbatch solves to convergence."""
    d = gamma_of(1.5, 2.0) * 0.4
    for U2 in (0.9, 0.5, 0.1, 1e-3):
        assert solve_flux_speed(d, U2)[0] == pytest.approx(lammps_newton(d, U2), rel=1e-12)
    stalled = [lammps_newton(d, U2) for U2 in (1e-12, 1e-300)]
    assert stalled == pytest.approx([3.660244, 3.660244], abs=1e-6)
    ours = solve_flux_speed(d, np.array([1e-12, 1e-300]))
    assert ours == pytest.approx([5.539062, 26.599529], rel=1e-6)
    mpmath.mp.dps = 50
    assert float(mp_tail(ours[0], d) / mp_tail(0, d)) == pytest.approx(1e-12, rel=1e-10)


class RanMars:
    """Marsaglia RANMAR as physics.md §8.4 states it (for comparing with LAMMPS draws)."""

    def __init__(self, seed: int):
        ij, kl = divmod(seed - 1, 30082)
        i, j, k, l = (ij // 177) % 177 + 2, ij % 177 + 2, (kl // 169) % 178 + 1, kl % 169
        self.u = [0.0] * 98
        for ii in range(1, 98):
            s, t = 0.0, 0.5
            for _ in range(24):
                mm = ((i * j) % 179) * k % 179
                i, j, k = j, k, mm
                l = (53 * l + 1) % 169
                if (l * mm) % 64 >= 32:
                    s += t
                t *= 0.5
            self.u[ii] = s
        self.c, self.cd, self.cm = 362436 / 16777216, 7654321 / 16777216, 16777213 / 16777216
        self.i97, self.j97, self.saved = 97, 33, None
        self.uniform()

    def uniform(self) -> float:
        uni = self.u[self.i97] - self.u[self.j97]
        if uni < 0:
            uni += 1.0
        self.u[self.i97] = uni
        self.i97 = self.i97 - 1 or 97
        self.j97 = self.j97 - 1 or 97
        self.c -= self.cd
        if self.c < 0:
            self.c += self.cm
        uni -= self.c
        return uni + 1.0 if uni < 0 else uni

    def gaussian(self) -> float:
        if self.saved is None:
            while True:
                v1, v2 = 2 * self.uniform() - 1, 2 * self.uniform() - 1
                r = v1 * v1 + v2 * v2
                if 0 < r < 1:
                    break
            fac = math.sqrt(-2 * math.log(r) / r)
            self.saved = v1 * fac
            return v2 * fac
        g, self.saved = self.saved, None
        return g

    def redraw_numbers(self) -> tuple[float, float, float, float]:
        """One LAMMPS redraw: uniform, uniform, gaussian, gaussian."""
        return self.uniform(), self.uniform(), self.gaussian(), self.gaussian()


def lammps_like_redraw(r: RanMars, gamma: float, vflow: float) -> np.ndarray:
    """wallbatch's redraw fed LAMMPS's random numbers (U2 is LAMMPS's upper-tail fraction, so 1 - U2
    is passed as wallbatch's uniform)."""
    u1, u2, g1, g2 = r.redraw_numbers()
    va, vp = _velocities(np.array([u1]), np.array([1.0 - u2]), np.array([[g1, g2]]), np.array([gamma]), vflow)
    return np.array([va[0], vp[0, 0], vp[0, 1]])


def test_section_8_4_reference_redraw():
    """SEED 12345, T 1.5 (lj), m 2, VFLOW 0.4, axis x: LAMMPS's first redraw (physics.md §8.4)."""
    got = lammps_like_redraw(RanMars(12345), gamma_of(1.5, 2.0), 0.4)
    np.testing.assert_allclose(got, [-2.3556598391693333, -0.1910514866443394, -0.40982402773149185],
                               rtol=1e-14)


def _lammps(commands: list[str]):
    lmp = _load_lammps().lammps(cmdargs=["-log", "none", "-screen", "none", "-nocite"])
    for c in commands:
        lmp.command(c)
    return lmp


def _lammps_atoms(lmp, n: int) -> tuple[np.ndarray, np.ndarray]:
    ids = np.array(lmp.numpy.extract_atom("id")[:n])
    order = np.argsort(ids)
    return (np.array(lmp.numpy.extract_atom("x")[:n])[order].copy(),
            np.array(lmp.numpy.extract_atom("v")[:n])[order].copy())


@requires_lammps
def test_redraws_match_lammps_with_per_type_masses():
    """Three atoms of masses 1, 2, 0.5 cross x = 5 in one step; LAMMPS redraws them in index
    order. wallbatch's sampler fed the same RANMAR numbers gives the same velocities."""
    lmp = _lammps([
        "units lj", "atom_style atomic", "boundary p p p", "region box block 0 10 0 4 0 4 units box",
        "create_box 3 box", "mass 1 1.0", "mass 2 2.0", "mass 3 0.5",
        "create_atoms 1 single 4.99 1 1 units box", "create_atoms 2 single 4.98 2 2 units box",
        "create_atoms 3 single 4.97 3 3 units box", "create_atoms 1 single 7.00 3 3 units box",
        "velocity all set 1.0 0.0 0.0 units box", "fix 1 all nve",
        "fix 2 all wall/flow x 0.4 1.5 12345 2 5.0 8.0 units box",
        "neigh_modify every 1 delay 0 check no", "timestep 0.05", "run 1",
    ])
    _, v = _lammps_atoms(lmp, 4)
    r = RanMars(12345)
    expect = [lammps_like_redraw(r, gamma_of(1.5, m), 0.4) for m in (1.0, 2.0, 0.5)]
    np.testing.assert_allclose(v[:3], expect, rtol=1e-13)
    np.testing.assert_array_equal(v[3], [1.0, 0.0, 0.0])  # did not cross: untouched


class RanMarsGenerator:
    """The kernel's generator interface (random(n), standard_normal((n, 2))) on RANMAR, for one
    redraw at a time: side uniform, speed uniform (as 1 - U2, see lammps_like_redraw), two
    gaussians, the order LAMMPS draws them in."""

    def __init__(self, seed: int):
        self.r, self.calls = RanMars(seed), 0

    def random(self, n: int) -> np.ndarray:
        assert n == 1
        self.calls += 1
        u = self.r.uniform()
        return np.array([u if self.calls % 2 else 1.0 - u])

    def standard_normal(self, shape: tuple[int, int]) -> np.ndarray:
        assert shape == (1, 2)
        return np.array([[self.r.gaussian(), self.r.gaussian()]])


@requires_lammps
def test_rule_lammps_follows_lammps_with_wrapping_every_step():
    """One atom over 600 steps crossing two flow walls and the periodic boundary (LAMMPS with
    neigh_modify every 1 check no, i.e. wrapped every step): rule lammps, fed RANMAR, follows
    LAMMPS's trajectory, redraw for redraw."""
    L, dt, walls = 10.0, 0.05, np.array([3.0, 6.5])
    lmp = _lammps([
        "units lj", "atom_style atomic", "boundary p p p", f"region box block 0 {L} 0 4 0 4 units box",
        "create_box 1 box", "mass 1 1.5", "create_atoms 1 single 2.5 2 2 units box",
        "velocity all set 1.3 0.0 0.0 units box", "fix 1 all nve",
        "fix 2 all wall/flow x 0.4 1.5 4242 2 3.0 6.5 units box",
        "neigh_modify every 1 delay 0 check no", f"timestep {dt}", "run 0",
    ])
    x = np.array([[[2.5, 2.0, 2.0]]])
    v = np.array([[[1.3, 0.0, 0.0]]])
    mass = np.array([[1.5]])
    k = FlowKernel([FlowSpec("f", np.array([True]), 0, 0.4, 1.5, walls, "lammps")], [RanMarsGenerator(4242)],
                   np.zeros(3), np.array([L, 4.0, 4.0]), LJ)
    k.setup(x)
    crossings = 0.0
    for _ in range(6):
        lmp.command("run 100 pre no post no")
        for _ in range(100):
            x += dt * v
            for d in range(3):  # LAMMPS's pbc(): x >= hi -> x - L (at least lo); x < lo -> x + L
                hi = L if d == 0 else 4.0
                x[..., d] = np.where(x[..., d] >= hi, np.maximum(x[..., d] - hi, 0.0), x[..., d])
                x[..., d] = np.where(x[..., d] < 0.0, x[..., d] + hi, x[..., d])
            k.end_of_step(x, v, mass)
        crossings += k.take_crossings()[0]
        xl, vl = _lammps_atoms(lmp, 1)
        np.testing.assert_allclose(v[0, 0], vl[0], rtol=1e-11)
        np.testing.assert_allclose(x[0, 0], xl[0], rtol=1e-11, atol=1e-11)
    assert crossings >= 15  # 22: over both walls and the periodic boundary, both ways


# ----------------------------------------------------------------------------- the ideal gas

# Ideal gas (no forces) along x in a periodic box 0..10 with flow walls at 2.5, 5, 7.5;
# vflow 0.4, T 1.5, m 1 (lj). Targets (physics.md 8.3b, decisions table):
#   rule exact:  the shifted Maxwellian: <v_x> = 0.4, <v_x²> = kT/m + vflow² = 1.66, <v_y²> = 1.5;
#   rule lammps: time density ∝ Z± M(v - vflow) on each side of 0 (Z± = the flux on that side):
#                <v_x> = 0.7276, <v_x²> = 1.7910.
# Each atom starts from its rule's stationary state (uniform in x, velocities from the density
# above), so the time averages have no start-up transient. Atoms of an ideal gas are independent,
# so each atom's time average is an independent sample: SE = std over atoms / sqrt(atoms).
# Discrete time adds an O(dt/segment) bias (an atom keeps its old velocity for part of the step
# after crossing; with rule lammps each immediate return takes at least one step). Measured with
# 16 x 1000 atoms over 60 time units and several dt: exact <v_x²> + 0.75 dt/Ls, lammps <v_x>
# - 0.65 dt/Ls and <v_x²> + 1.1 dt/Ls (Ls = segment length). Here dt/Ls = 0.004: about half a
# standard error; an event-driven (exact-time) simulation gave 0.4005 / 1.6604 and 0.7291 / 1.7940.
# Crossing rates (crossings per atom per time unit; 4 walls counting the periodic boundary, 10
# long): exact: every arrival at a wall is one crossing: 4/10 <|v|>_M = 0.4 (Z+ + Z-) = 0.4116;
# lammps: arrivals 4/10 (Z+² + Z-²)/D with D = Z+ Φ(u/σ) + Z- Φ(-u/σ), times the mean number of
# redraws before the atom leaves the wall, (1 + P∓)/(1 - P+ P-) for an arrival from the ± side
# (P± = Z±/(Z+ + Z-)).

GAS = {"C": 8, "N": 2000, "L": 10.0, "walls": (2.5, 5.0, 7.5), "dt": 0.01, "steps": 1200, "u": 0.4, "kT": 1.5,
       "m": 1.0}


def _half_moments(u, s):
    a = u / s
    pp, pm, phi = stats.norm.cdf(a), stats.norm.cdf(-a), stats.norm.pdf(a)
    zp, zm = u * pp + s * phi, s * phi - u * pm  # flux on each side: ∫_{v>0} v M, -∫_{v<0} v M
    m2p, m2m = (u * u + s * s) * pp + u * s * phi, (u * u + s * s) * pm - u * s * phi
    return pp, pm, zp, zm, m2p, m2m


def lammps_rule_targets(u, kT, m):
    """(<v_x>, <v_x²>, crossing rate per unit density and wall) under the LAMMPS rule."""
    pp, pm, zp, zm, m2p, m2m = _half_moments(u, math.sqrt(kT / m))
    den = zp * pp + zm * pm
    p_plus, p_minus = zp / (zp + zm), zm / (zp + zm)
    redraws = (zp * zp * (1 + p_minus) + zm * zm * (1 + p_plus)) / (1 - p_plus * p_minus)
    return (zp * zp - zm * zm) / den, (zp * m2p + zm * m2m) / den, redraws / den


def _stationary_vx(rng, shape, u, kT, m, rule):
    s = math.sqrt(kT / m)
    vx = u + s * rng.standard_normal(shape)
    if rule == "lammps":  # keep v < 0 with probability Z-/Z+ (rejection, each atom until accepted)
        _, _, zp, zm, _, _ = _half_moments(u, s)
        todo = np.ones(shape, bool)
        while todo.any():
            todo &= (vx < 0) & (rng.random(shape) > zm / zp)
            vx[todo] = u + s * rng.standard_normal(int(todo.sum()))
    return vx


def ideal_gas(rule: str, seed: int = 20) -> dict[str, np.ndarray]:
    """The ballistic loop: x += v dt, wrap, end_of_step. Returns per-atom time averages and the
    crossings per case."""
    g = GAS
    C, N, L = g["C"], g["N"], g["L"]
    rng = np.random.default_rng(seed)
    x = np.zeros((C, N, 3))
    x[..., 0] = rng.random((C, N)) * L
    v = np.empty((C, N, 3))
    v[..., 0] = _stationary_vx(rng, (C, N), g["u"], g["kT"], g["m"], rule)
    v[..., 1:] = math.sqrt(g["kT"] / g["m"]) * rng.standard_normal((C, N, 2))
    mass = np.full((C, N), g["m"])
    specs = [FlowSpec("flow", np.ones(N, bool), 0, g["u"], g["kT"], np.array(g["walls"]), rule)] * C
    k = FlowKernel(specs, [np.random.default_rng([seed, c]) for c in range(C)], np.zeros(3),
                   np.array([L, 1.0, 1.0]), LJ)
    k.setup(x)
    s1, s2, sy = np.zeros((C, N)), np.zeros((C, N)), np.zeros((C, N))
    for _ in range(g["steps"]):
        x[..., 0] += g["dt"] * v[..., 0]
        x[..., 0] = np.where(x[..., 0] >= L, x[..., 0] - L, x[..., 0])
        x[..., 0] = np.where(x[..., 0] < 0.0, x[..., 0] + L, x[..., 0])
        k.end_of_step(x, v, mass)
        s1 += v[..., 0]
        s2 += v[..., 0] ** 2
        sy += v[..., 1] ** 2 + v[..., 2] ** 2
    n = g["steps"]
    return {"vx": s1.ravel() / n, "vx2": s2.ravel() / n, "vy2": sy.ravel() / (2 * n),
            "crossings": k.take_crossings()}


SLOW_FIXTURES = ("gas",)  # 3-9 s: conftest.py marks every test that takes it `slow`


@pytest.fixture(scope="module")
def gas() -> dict[str, dict[str, np.ndarray]]:
    return {rule: ideal_gas(rule) for rule in ("exact", "lammps")}


def _mean_se(a: np.ndarray) -> tuple[float, float]:
    return float(a.mean()), float(a.std(ddof=1) / math.sqrt(a.size))


def test_lammps_rule_targets_are_those_of_physics_md():
    vx, vx2, _ = lammps_rule_targets(0.4, 1.5, 1.0)
    assert (vx, vx2) == pytest.approx((0.7276, 1.7910), abs=1e-4)  # physics.md 8.3b: 0.728 and 1.79


def test_ideal_gas_rule_exact_gives_the_shifted_maxwellian(gas):
    g, res = GAS, gas["exact"]
    for key, target in (("vx", g["u"]), ("vx2", g["kT"] / g["m"] + g["u"] ** 2), ("vy2", g["kT"] / g["m"])):
        mean, se = _mean_se(res[key])
        assert abs(mean - target) < 3 * se, (key, mean, target, se)
    assert _mean_se(res["vx"])[1] < 0.006 and _mean_se(res["vx2"])[1] < 0.012  # the check has teeth
    # crossings: every arrival at one of the 4 walls, <|v|>_M per unit density
    _, _, zp, zm, _, _ = _half_moments(g["u"], math.sqrt(g["kT"] / g["m"]))
    per_case = res["crossings"] / g["N"] / (g["steps"] * g["dt"])
    mean, se = _mean_se(per_case)
    assert abs(mean - 4 / g["L"] * (zp + zm)) < 3 * se and se < 0.005


def test_ideal_gas_rule_lammps_streams_too_fast(gas):
    g, res = GAS, gas["lammps"]
    vx_t, vx2_t, rate = lammps_rule_targets(g["u"], g["kT"], g["m"])
    for key, target in (("vx", vx_t), ("vx2", vx2_t), ("vy2", g["kT"] / g["m"])):
        mean, se = _mean_se(res[key])
        assert abs(mean - target) < 3 * se, (key, mean, target, se)
    per_case = res["crossings"] / g["N"] / (g["steps"] * g["dt"])
    mean, se = _mean_se(per_case)
    assert abs(mean - 4 / g["L"] * rate) < 3 * se and se < 0.01


def test_ideal_gas_tells_the_rules_apart(gas):
    for key in ("vx", "vx2"):
        (a, sa), (b, sb) = _mean_se(gas["exact"][key]), _mean_se(gas["lammps"][key])
        assert b - a > 10 * math.hypot(sa, sb), key
    # parallel components do not care about the rule
    (a, sa), (b, sb) = _mean_se(gas["exact"]["vy2"]), _mean_se(gas["lammps"]["vy2"])
    assert abs(a - b) < 3 * math.hypot(sa, sb)


# ----------------------------------------------------------------------------- bookkeeping


def make_kernel(n: int, rule: str = "exact", walls=(2.5, 5.0, 7.5), seeds=(1,), group=None, vflow=0.4,
                temperature=1.5, axis=0, L=10.0, units=LJ) -> FlowKernel:
    group = np.ones(n, bool) if group is None else group
    specs = [FlowSpec("flow", group, axis, vflow, temperature, np.array(walls, float), rule) for _ in seeds]
    return FlowKernel(specs, [np.random.default_rng(s) for s in seeds], np.zeros(3), np.full(3, L), units)


def atoms_at(xs, v_axis=1.0, axis=0) -> tuple[np.ndarray, np.ndarray]:
    xs = np.atleast_2d(np.asarray(xs, float))
    x = np.full(xs.shape + (3,), 0.5)
    x[..., axis] = xs
    v = np.zeros_like(x)
    v[..., axis] = v_axis
    return x, v


def test_setup_segments_with_atoms_on_walls_and_outside_the_box():
    k = make_kernel(8)
    x, _ = atoms_at([0.0, 2.4999, 2.5, 5.0, 7.5, 9.9999, 10.2, -0.1])
    k.setup(x)
    # on a wall: the segment above it (W[k] <= x < W[k+1]); unwrapped coordinates are wrapped first
    assert k.segments.tolist() == [[0, 0, 1, 2, 3, 3, 0, 3]]


def passages(x0: np.ndarray, x1: np.ndarray, walls: np.ndarray, L: float) -> np.ndarray:
    """Wall images (walls + j L, including the box bound 0 + j L) between two unwrapped positions."""
    w = np.concatenate([[0.0], walls])
    count = lambda x: np.floor((x[..., None] - w) / L).sum(-1)  # images <= x
    return np.abs(count(x1) - count(x0))


def ballistic(k: FlowKernel, x, v, mass, steps: int, dt: float, L: float, wrap: bool = True):
    for _ in range(steps):
        x[..., 0] += dt * v[..., 0]
        if wrap:
            x[..., 0] = np.mod(x[..., 0], L)
        k.end_of_step(x, v, mass)


def test_rule_lammps_redraws_once_per_wall_passage_including_the_periodic_boundary():
    """Positions wrapped every step: the number of redraws equals the number of wall passages of
    the unwrapped trajectories (the periodic boundary counting as a wall), no more (§8.5)."""
    rng = np.random.default_rng(4)
    n, L, dt, walls = 400, 10.0, 0.02, np.array([2.5, 5.0, 7.5])
    k = make_kernel(n, "lammps")
    x, v = atoms_at(rng.random(n) * L)
    v[..., 0] = rng.normal(0.4, 1.2, (1, n))
    mass = np.ones((1, n))
    k.setup(x)
    xu = x[..., 0].copy()
    expected = 0
    for _ in range(500):
        step = dt * v[..., 0]
        expected += passages(xu, xu + step, walls, L).sum()
        xu += step
        x[..., 0] = np.mod(xu, L)
        k.end_of_step(x, v, mass)
    got = k.take_crossings()
    assert got.dtype == float and got.shape == (1,)
    assert got[0] == expected > 300
    assert k.take_crossings()[0] == 0.0  # reset


def test_wrapping_late_or_never_does_not_add_redraws():
    """LAMMPS redraws twice per boundary crossing when wrapping is delayed (quirk #9). The kernel
    takes segments of the wrapped coordinate: unwrapped or late-wrapped positions give the same
    redraws, bit for bit, as wrapping every step."""
    rng = np.random.default_rng(8)
    n, L, dt = 300, 10.0, 0.02
    x0, v0 = atoms_at(rng.random(n) * L)
    v0[..., 0] = rng.normal(0.4, 1.2, (1, n))
    runs = []
    for mode in ("every", "never", "every 7"):
        k = make_kernel(n, "exact", seeds=(3,))
        x, v = x0.copy(), v0.copy()
        k.setup(x)
        for i in range(400):
            x[..., 0] += dt * v[..., 0]
            if mode == "every" or (mode == "every 7" and i % 7 == 0):
                x[..., 0] = np.mod(x[..., 0], L)
            k.end_of_step(x, v, np.ones((1, n)))
        runs.append((np.mod(x[..., 0], L), v.copy(), k.take_crossings()[0]))
    for xr, vr, cr in runs[1:]:
        np.testing.assert_array_equal(vr, runs[0][1])
        np.testing.assert_allclose(xr, runs[0][0], atol=1e-9)
        assert cr == runs[0][2] > 0


def test_one_atom_across_the_periodic_boundary():
    """An atom leaving through boxhi and wrapped to the low end is one crossing; with a late wrap
    (x past boxhi for two steps, then wrapped) still one."""
    for rule in ("exact", "lammps"):
        for path in ([9.95, 0.05, 0.15, 0.25], [9.95, 10.05, 10.15, 0.25]):
            k = make_kernel(1, rule, vflow=5.0, temperature=0.01)  # cold fast flow: P+ = 1, always forward
            x, v = atoms_at([path[0]])
            k.setup(x)
            counts = []
            for p in path[1:]:
                x[0, 0, 0] = p
                v[0, 0, 0] = 1.0
                k.end_of_step(x, v, np.ones((1, 1)))
                counts.append(k.take_crossings()[0])
            assert counts == [1.0, 0.0, 0.0], (rule, path)
            assert k.segments.tolist() == [[0]]


def _cross_wall_once(rule: str, n: int = 4000, seed: int = 9):
    """n atoms just below the wall at 2.5 moving +1 cross it in the first step (dt 0.01)."""
    rng = np.random.default_rng(seed)
    k = make_kernel(n, rule, seeds=(seed,))
    x, v = atoms_at(2.5 - 0.005 * (1.0 - rng.random(n)))  # in [2.495, 2.5): segment 0
    mass = np.ones((1, n))
    k.setup(x)
    ballistic(k, x, v, mass, 1, 0.01, 10.0)
    return k, x, v, mass


def test_rule_exact_return_over_the_crossed_wall_is_not_a_crossing():
    k, x, v, mass = _cross_wall_once("exact")
    n = x.shape[1]
    assert k.take_crossings()[0] == n
    back = v[0, :, 0] < 0
    assert 0.25 * n < back.sum() < 0.36 * n  # P- = 0.306 for vflow 0.4, T 1.5, m 1
    # the redraw that points back keeps the atom in the segment it came from (the one it heads into)
    np.testing.assert_array_equal(k.segments[0], np.where(back, 0, 1))
    v1 = v.copy()
    ballistic(k, x, v, mass, 30, 0.01, 10.0)  # 0.3 time units: nobody reaches another wall
    returned = back & (x[0, :, 0] < 2.5)
    assert returned.sum() > 0.97 * back.sum()
    assert k.take_crossings()[0] == 0.0  # the returns were not crossings
    np.testing.assert_array_equal(v, v1)  # and nobody was redrawn
    np.testing.assert_array_equal(k.segments[0], np.where(back, 0, 1))


def test_rule_lammps_redraws_on_the_return():
    k, x, v, mass = _cross_wall_once("lammps")
    n = x.shape[1]
    assert k.take_crossings()[0] == n
    back = v[0, :, 0] < 0
    np.testing.assert_array_equal(k.segments[0], np.ones(n))  # LAMMPS: the segment it sits in
    ballistic(k, x, v, mass, 30, 0.01, 10.0)
    # every return is a crossing (some atoms bounce more than once: each bounce counts)
    assert k.take_crossings()[0] >= 0.97 * back.sum()


def test_rule_exact_turning_round_before_the_wall_is_a_crossing():
    """A pending atom (redrawn back over the wall) that turns round before reaching it (a force
    would do this) re-enters the segment it sits in: that is a crossing and a redraw."""
    k, x, v, mass = _cross_wall_once("exact")
    k.take_crossings()
    back = v[0, :, 0] < 0
    turn = back & (np.arange(back.size) % 2 == 0)
    v[0, turn, 0] = 0.3  # turned round, not moved
    v1 = v.copy()
    k.end_of_step(x, v, mass)
    assert k.take_crossings()[0] == turn.sum()
    assert np.all(v[0, turn] != v1[0, turn])  # redrawn
    np.testing.assert_array_equal(v[0, ~turn], v1[0, ~turn])  # still heading back, or in their segment
    # after the redraw: pending again if it points back, else settled in the segment it sits in
    np.testing.assert_array_equal(k.segments[0, turn], np.where(v[0, turn, 0] < 0, 0, 1))


def test_two_walls_in_one_step_is_one_redraw_and_does_not_crash():
    for rule in ("exact", "lammps"):
        k = make_kernel(4, rule, seeds=(2,))
        x, v = atoms_at([1.0, 9.9, 6.0, 0.5])
        k.setup(x)
        x[0, :, 0] = [6.0, 2.6, 1.0, 0.6]  # over 2.5 and 5; over 10|0 and 2.5; back over 5 and 2.5; none
        v[0, 2, 0] = -1.0
        k.end_of_step(x, v, np.ones((1, 4)))
        assert k.take_crossings()[0] == 3.0
        assert np.all(np.isfinite(v))
        assert v[0, 3].tolist() == [1.0, 0.0, 0.0]
        ballistic(k, x, v, np.ones((1, 4)), 200, 0.05, 10.0)  # and carries on
        assert np.all(np.isfinite(v))


def test_group_mask():
    n = 200
    group = np.arange(n) % 3 == 0
    k = make_kernel(n, "lammps", group=group)
    x, v = atoms_at(np.full(n, 2.49))
    k.setup(x)
    x[0, :, 0] = 2.51
    v0 = v.copy()
    k.end_of_step(x, v, np.ones((1, n)))
    assert k.take_crossings()[0] == group.sum()
    np.testing.assert_array_equal(v[0, ~group], v0[0, ~group])
    assert np.all(v[0, group, 1] != 0.0)


def test_units_real_use_kT_over_mvv2e():
    """real units: velocities in Angstrom/fs, kT_v = boltz T / mvv2e (argon, 300 K)."""
    real = UNIT_SYSTEMS["real"]
    n, m, T, u = 5000, 39.948, 300.0, 0.002
    k = make_kernel(n, "lammps", vflow=u, temperature=T, units=real)
    x, v = atoms_at(np.full(n, 2.49))
    k.setup(x)
    x[0, :, 0] = 2.51
    k.end_of_step(x, v, np.full((1, n), m))
    kT_v = real.boltz * T / real.mvv2e
    sigma = math.sqrt(kT_v / m)
    assert sigma == pytest.approx(0.00249, rel=1e-2)  # 249 m/s
    assert stats.kstest(v[0, :, 1:].ravel(), stats.norm(0, sigma).cdf).pvalue > 0.01
    assert stats.kstest(v[0, :, 0], lambda w: flux_cdf(w, 1 / math.sqrt(2 * kT_v / m), u)).pvalue > 0.01


def _random_gas(C: int, n: int, seed: int):
    rng = np.random.default_rng(seed)
    x = np.full((C, n, 3), 0.5)
    x[..., 0] = rng.random((C, n)) * 10.0
    v = np.zeros((C, n, 3))
    v[..., 0] = rng.normal(0.4, 1.2, (C, n))
    return x, v, np.ones((C, n))


def test_reproducible_for_equal_seeds_and_different_otherwise():
    out = []
    for seed in (5, 5, 6):
        k = make_kernel(100, "exact", seeds=(seed,))
        x, v, mass = _random_gas(1, 100, 0)
        k.setup(x)
        ballistic(k, x, v, mass, 300, 0.02, 10.0)
        out.append((v, k.take_crossings()))
    np.testing.assert_array_equal(out[0][0], out[1][0])
    assert out[0][1] == out[1][1]
    assert not np.array_equal(out[0][0], out[2][0])


def test_take_and_batch_invariance():
    """A case's results do not depend on the batch it runs in, and take() keeps cases intact:
    three cases run 150 steps, case 1 leaves, the rest run 150 more; the same two cases run
    alone give identical bits."""
    n, seeds = 80, (11, 12, 13)
    x, v, mass = _random_gas(3, n, 1)
    k = make_kernel(n, "exact", seeds=seeds)
    k.setup(x)
    ballistic(k, x, v, mass, 150, 0.02, 10.0)
    first = k.take_crossings()
    keep = np.array([True, False, True])
    k.take(keep)
    x, v, mass = x[keep], v[keep], mass[keep]
    ballistic(k, x, v, mass, 150, 0.02, 10.0)
    second = k.take_crossings()
    assert k.ncases == 2 and second.shape == (2,)
    for j, c in enumerate((0, 2)):
        xa, va, ma = (a[c:c + 1].copy() for a in _random_gas(3, n, 1))
        alone = make_kernel(n, "exact", seeds=(seeds[c],))
        alone.setup(xa)
        ballistic(alone, xa, va, ma, 150, 0.02, 10.0)
        assert alone.take_crossings()[0] == first[c]
        ballistic(alone, xa, va, ma, 150, 0.02, 10.0)
        assert alone.take_crossings()[0] == second[j]
        np.testing.assert_array_equal(va[0], v[j])
        np.testing.assert_array_equal(xa[0], x[j])


def test_cases_with_different_axes_walls_and_rules_share_a_batch():
    n, L, dt = 60, 10.0, 0.02
    specs = [FlowSpec("flow", np.ones(n, bool), 0, 0.4, 1.5, np.array([2.5, 5.0, 7.5]), "exact"),
             FlowSpec("flow", np.ones(n, bool), 2, 1.0, 0.5, np.array([4.0]), "lammps")]
    rng = np.random.default_rng(2)
    x0 = rng.random((2, n, 3)) * L
    v0 = rng.normal(0.4, 1.0, (2, n, 3))

    def run(kernel, x, v):
        kernel.setup(x)
        for _ in range(300):
            x += dt * v
            x[:] = np.mod(x, L)
            kernel.end_of_step(x, v, np.ones(x.shape[:2]))
        return x, v, kernel.take_crossings()

    both = run(FlowKernel(specs, [np.random.default_rng(s) for s in (1, 2)], np.zeros(3), np.full(3, L), LJ),
               x0.copy(), v0.copy())
    for c in range(2):
        one = run(FlowKernel([specs[c]], [np.random.default_rng(c + 1)], np.zeros(3), np.full(3, L), LJ),
                  x0[c:c + 1].copy(), v0[c:c + 1].copy())
        np.testing.assert_array_equal(one[1][0], both[1][c])
        assert one[2][0] == both[2][c] > 0


def test_kernel_refuses_bad_parameters():
    with pytest.raises(ValueError, match="temperature must be > 0"):
        make_kernel(4, temperature=0.0)
    with pytest.raises(ValueError, match="temperature must be > 0"):
        make_kernel(4, temperature=-1.5)
    with pytest.raises(ValueError, match="vflow must be > 0"):
        make_kernel(4, vflow=0.0)
    with pytest.raises(ValueError, match="strictly increasing"):
        make_kernel(4, walls=(5.0, 2.5))
    with pytest.raises(ValueError, match="on or outside the box"):
        make_kernel(4, walls=(2.5, 10.0))
    with pytest.raises(ValueError, match="rule must be"):
        make_kernel(4, rule="fast")
    spec = FlowSpec("flow", np.ones(4, bool), 0, 0.4, 1.5, np.array([5.0]))
    with pytest.raises(ValueError, match="generators"):
        FlowKernel([spec, spec], [np.random.default_rng(1)], np.zeros(3), np.full(3, 10.0), LJ)
    k = make_kernel(4)
    x, v = atoms_at([1.0, 2.0, 3.0, 4.0])
    with pytest.raises(RuntimeError, match="setup"):
        k.end_of_step(x, v, np.ones((1, 4)))


# ----------------------------------------------------------------------------- check_flow

LO, HI, PERIODIC = np.zeros(3), np.array([10.0, 6.0, 4.0]), np.array([True, True, False])


def test_check_flow_accepts_a_valid_scene():
    assert check_flow(0, PERIODIC, LO, HI, [2.5, 5.0, 7.5]) == []
    assert check_flow("y", PERIODIC, LO, HI, [3.0], temperature=1.5, vflow=0.4) == []


@pytest.mark.parametrize("axis,coords,kw,needles", [
    ("z", [2.0], {}, ["non-periodic boundary along the flow axis z", "make the box periodic along z"]),
    (0, [5.0, 2.5], {}, ["strictly increasing", "ascending order"]),
    (0, [2.5, 2.5], {}, ["strictly increasing"]),
    (0, [0.0, 5.0], {}, ["[0.0] lie on or outside the box (0 .. 10 along x)", "strictly inside"]),
    (0, [5.0, 10.0], {}, ["[10.0] lie on or outside"]),
    (1, [7.0], {}, ["outside the box (0 .. 6 along y)"]),
    (0, [-1.0, 12.0], {}, ["[-1.0, 12.0] lie on or outside"]),
    (0, [], {}, ["at least one wall"]),
    (0, [5.0], {"temperature": 0.0}, ["temperature must be > 0", "NaN"]),
    (0, [5.0], {"temperature": -1.0}, ["temperature must be > 0"]),
    (0, [5.0], {"vflow": -0.4}, ["vflow must be > 0"]),
    ("q", [5.0], {}, ["axis must be x, y or z"]),
])
def test_check_flow_errors(axis, coords, kw, needles):
    errors = check_flow(axis, PERIODIC, LO, HI, coords, **kw)
    assert len(errors) == 1, errors
    for needle in needles:
        assert needle in errors[0]


def test_check_flow_reports_every_problem():
    errors = check_flow("z", PERIODIC, LO, HI, [3.0, 1.0, 9.0], temperature=0.0)
    assert len(errors) == 4  # non-periodic, unsorted, 9 outside z's 0..4, T <= 0


# ----------------------------------------------------------------------------- engine wiring


def test_a_run_with_a_flow_wall_redraws():
    from wallbatch.config.models import config_from_dict
    from wallbatch.batch.runner import run_config

    cfg = {"name": "flowgas", "units": "lj", "seed": 7,
           "box": {"lo": [0, 0, 0], "hi": [10, 10, 10], "boundary": ["p", "p", "p"]},
           "atoms": [{"group": "gas", "create": {"random": {"count": 200}}, "mass": 1.0,
                      "velocity": {"temperature": 1.5}}],
           "walls": {"inflow": {"style": "flow", "axis": "x", "vflow": 0.4, "temperature": 1.5, "seed": 593894,
                                "coords": [2.5, 5.0, 7.5], "units": "box"}},
           "run": {"steps": 200, "thermo": 100}, "output": {"thermo": ["step", "temp", "flow_crossings"]}}
    ds = run_config(config_from_dict(cfg))
    assert str(ds["status"].values) == "ok", str(ds["error"].values)
    # 200 atoms, 4 walls over 10, |v| ~ 1.1: about 0.44 crossings per atom per time unit, 0.5 time units a sample
    crossings = ds["flow_crossings"].values[1:]
    assert np.all((crossings > 20) & (crossings < 90)), crossings
