"""wall/flow's compiled velocity redraw (wallbatch.engine.flow_compiled) against the NumPy
reference (wallbatch.engine.flow with WALLBATCH_NUMBA=0).

Both run the same arithmetic per redraw with SciPy's erfc/erfcx/expit; only exp and log differ
(NumPy's AVX-512 versions vs the C library's, 1 ulp apart on a few percent of arguments). The
solver stops at rounding level (its documented tolerance), so most redraws are bit-identical and
the rest differ by a few ulp of the solver's own tolerance: the bounds below are that tolerance.
"""

from __future__ import annotations

import numpy as np
import pytest

from wallbatch.config.models import config_from_dict
from wallbatch.engine import flow, flow_compiled
from wallbatch.engine.engine import Engine
from wallbatch.scene.build import build_case

pytestmark = pytest.mark.skipif(flow_compiled.njit is None, reason="numba not importable")


def both(monkeypatch, u1, u2, g, gamma, vflow):
    monkeypatch.setenv("WALLBATCH_NUMBA", "0")
    ref = flow._velocities(u1, u2, g, gamma, vflow)
    monkeypatch.setenv("WALLBATCH_NUMBA", "1")
    got = flow._velocities(u1, u2, g, gamma, vflow)
    return ref, got


def test_log_tail_and_solver_match_numpy():
    """log_tail over every branch (y < 0, δ >= 0, δ < 0 with each continued-fraction band) to
    4e-16 relative; the solver's ν within its own stopping tolerance, most of them bit for bit."""
    rng = np.random.default_rng(7)
    nu = np.concatenate([rng.uniform(0, 12, 3000), [0.0, 1e-300, 2.0, 3.0, 5.0, 30.0]])
    delta = np.concatenate([rng.uniform(-8, 8, 3000), [0.0, -1.0, -2.0, -4.0, 3.0, -25.0]])
    ref = flow.log_tail(nu, delta)
    got = np.array([flow_compiled.log_tail(a, b) for a, b in zip(nu, delta)])
    np.testing.assert_allclose(got, ref, rtol=4e-16, atol=1e-300)
    u = np.concatenate([1.0 - rng.random(3000), [1.0, 2.0 ** -53, 1e-300, 0.5, 1 - 2.0 ** -52, 0.999999]])
    x = flow.solve_flux_speed(delta, u)
    y = np.array([flow_compiled.solve_flux_speed(a, b, 100) for a, b in zip(delta, u)])
    assert np.all(np.isfinite(y)) and y[-6] == 0.0 == x[-6]  # u = 1: ν = 0
    assert np.mean(x == y) > 0.95
    np.testing.assert_allclose(y, x, rtol=1e-12, atol=2e-13)


@pytest.mark.parametrize("vflow", [0.01, 0.4, 4.0, 40.0])
def test_velocities_match_numpy(monkeypatch, vflow):
    """The redraws of 20000 atoms with per-atom masses: v_par bit for bit (g / (γ√2)), v_axis
    side-for-side identical and within the solver tolerance, |Δν| <= 2e-13 (ν = γ|v| ~ 1)."""
    rng = np.random.default_rng(11)
    n = 20000
    u1, u2, g = flow._draw(rng, n)
    u2[:3] = [0.0, 1.0 - 2.0 ** -53, 0.5]
    gamma = 1.0 / np.sqrt(2.0 * 1.5 / rng.choice([1.0, 3.0, 39.9], n))
    (ra, rp), (ga, gp) = both(monkeypatch, u1, u2, g, gamma, vflow)
    np.testing.assert_array_equal(gp, rp)
    np.testing.assert_array_equal(np.sign(ga), np.sign(ra))
    assert np.mean(ga == ra) > 0.95
    np.testing.assert_allclose(ga * gamma, ra * gamma, rtol=1e-12, atol=2e-13)


@pytest.mark.slow
@pytest.mark.parametrize("rule", ["exact", "lammps"])
def test_flow_scene_compiled_matches_numpy(monkeypatch, rule):
    """A batch of two ideal gases (400 atoms, different seeds and vflow) between three flow walls,
    400 steps, in the compiled chunks (flow_compiled's solver inside engine.compiled._flow_step,
    the draws from each case's generator in the NumPy order): the same crossings per sample and the
    same sampled outputs (to 1e-12: a few ulp per redraw carried along straight lines); the
    chunks really ran compiled. The crossing detection and pending-return logic is also covered
    by every test of tests/engine/test_flow.py, which run the compiled code by default."""
    def cfg(seed, vflow):
        return {"units": "lj", "seed": seed, "timestep": 0.005,
                "box": {"lo": [0, 0, 0], "hi": [10.0, 3.0, 3.0], "boundary": ["p", "p", "p"]},
                "atoms": [{"group": "gas", "create": {"random": {"count": 400}}, "mass": 1.0,
                           "velocity": {"temperature": 1.5}}],
                "walls": {"fl": {"style": "flow", "axis": "x", "vflow": vflow, "temperature": 1.5, "seed": 99 + seed,
                                 "coords": [2.5, 5.0, 7.5], "units": "box", "rule": rule}},
                "run": {"steps": 400, "thermo": 50},
                "output": {"thermo": ["step", "ke", "temp", "flow_crossings"]}}
    cases = [build_case(config_from_dict(cfg(3, 0.4))), build_case(config_from_dict(cfg(4, 1.2)))]
    monkeypatch.setenv("WALLBATCH_NUMBA", "0")
    ref = Engine(cases).run()
    monkeypatch.setenv("WALLBATCH_NUMBA", "1")
    eng = Engine(cases)
    got = eng.run()
    assert eng.fast is not None and eng.fast.compiled_chunks > 0 and eng.fast.fallbacks == 0
    for r, g in zip(ref, got):
        assert r.status == g.status == "ok"
        assert r.data["flow_crossings"].sum() > 200
        np.testing.assert_array_equal(g.data["flow_crossings"], r.data["flow_crossings"])
        for key in ("ke", "temp"):
            np.testing.assert_allclose(g.data[key], r.data[key], rtol=1e-12)


def test_kernel_end_of_step_compiled_matches_numpy(monkeypatch):
    """FlowKernel.end_of_step compiled (detect + apply) against the NumPy code on a batch of three
    cases (rules exact and lammps, axes x and z, a group, per-atom masses) with forces turning
    atoms round in front of walls (a harmonic pull to the box centre): same crossings per step,
    same segments and pending returns, velocities within the solver tolerance."""
    from wallbatch.scene.case import FlowSpec
    from wallbatch.units import UNIT_SYSTEMS

    n, L, dt = 80, 10.0, 0.02
    grp = np.arange(n) % 5 != 0
    specs = [FlowSpec("flow", np.ones(n, bool), 0, 0.4, 1.5, np.array([2.5, 5.0, 7.5]), "exact"),
             FlowSpec("flow", grp, 2, 1.0, 0.5, np.array([4.0]), "lammps"),
             FlowSpec("flow", np.ones(n, bool), 0, 2.0, 1.0, np.array([1.0, 9.0]), "exact")]
    rng = np.random.default_rng(5)
    x0 = rng.random((3, n, 3)) * L
    v0 = rng.normal(0.3, 1.0, (3, n, 3))
    mass = rng.choice([1.0, 2.0], (3, n))

    def run(numba: str):
        monkeypatch.setenv("WALLBATCH_NUMBA", numba)
        k = flow.FlowKernel(specs, [np.random.default_rng(s) for s in (1, 2, 3)], np.zeros(3), np.full(3, L),
                            UNIT_SYSTEMS["lj"])
        x, v = x0.copy(), v0.copy()
        k.setup(x)
        history = []
        for _ in range(400):
            v -= dt * 0.8 * (x - L / 2) / mass[..., None]
            x += dt * v
            x[:] = np.mod(x, L)
            k.end_of_step(x, v, mass)
            history.append((k.take_crossings(), k.segments.copy(), k.pend.copy()))
        return v, history

    v_ref, h_ref = run("0")
    v_got, h_got = run("1")
    total = 0
    for (c0, s0, p0), (c1, s1, p1) in zip(h_ref, h_got):
        np.testing.assert_array_equal(c1, c0)
        np.testing.assert_array_equal(s1, s0)
        np.testing.assert_array_equal(p1, p0)
        total += c0.sum()
    assert total > 300 and any((p != 0).any() for _, _, p in h_ref)  # crossings and pending returns happened
    np.testing.assert_allclose(v_got, v_ref, rtol=1e-11, atol=1e-11)


@pytest.mark.slow
def test_flow_chunk_handed_back_keeps_the_random_streams(monkeypatch):
    """Flow walls with a weak harmonic z wall that a fast atom gets through: the compiled chunk
    hands back to NumPy, which re-runs it from the same generator states, so both paths report
    the same failure at the same step and the surviving case (stiff wall) has the same crossings."""
    def cfg(eps):
        return {"units": "lj", "seed": 8, "timestep": 0.005,
                "box": {"lo": [0, 0, 0], "hi": [10.0, 4.0, 4.0], "boundary": ["p", "p", "f"]},
                "regions": {"mid": {"style": "block", "lo": [0, 0, 1.0], "hi": [10, 4, 3.0], "units": "box"}},
                "atoms": [{"group": "gas", "create": {"random": {"count": 300, "region": "mid"}}, "mass": 1.0,
                           "velocity": {"temperature": 4.0}}],
                "walls": {"fl": {"style": "flow", "axis": "x", "vflow": 0.4, "temperature": 4.0, "seed": 5,
                                 "coords": [5.0], "units": "box"},
                          "z": {"style": "harmonic", "units": "box", "zlo": [0.0, eps, 1.0, 0.8],
                                "zhi": [4.0, eps, 1.0, 0.8]}},
                "run": {"steps": 600, "thermo": 100},
                "output": {"thermo": ["step", "ke", "flow_crossings"]}}
    cases = [build_case(config_from_dict(cfg(0.5))), build_case(config_from_dict(cfg(200.0)))]
    monkeypatch.setenv("WALLBATCH_NUMBA", "0")
    ref = Engine(cases).run()
    monkeypatch.setenv("WALLBATCH_NUMBA", "1")
    eng = Engine(cases)
    got = eng.run()
    assert ref[0].status == got[0].status == "failed" and got[0].error == ref[0].error
    assert ref[1].status == got[1].status == "ok"
    assert eng.fast.fallbacks > 0 and eng.fast.compiled_chunks > 0
    np.testing.assert_array_equal(got[1].data["flow_crossings"], ref[1].data["flow_crossings"])
    np.testing.assert_allclose(got[1].data["ke"], ref[1].data["ke"], rtol=1e-12)
