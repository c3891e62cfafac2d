"""Thermostats and 2-D (`fixes:`, `dimension: 2`) on the compiled path against the NumPy engine.

Each scene runs with WALLBATCH_NUMBA=0 and =1; every sampled output of every case must agree bit
for bit (Langevin: the same random stream, drawn in the kernel by numba's Generator), except fix
nvt, whose chain uses exp (NumPy's SIMD exp vs the C library's): 1e-14 relative there. Each test
checks that the chunks really ran compiled, so a silent fallback cannot pass.
"""

from __future__ import annotations

import copy

import numpy as np
import pytest
from factories import assert_same_results, run_numpy_and_compiled, slab_gas
from test_threads import run_with

from wallbatch.config.models import config_from_dict
from wallbatch.engine import compiled as fast
from wallbatch.engine import thermostats as th
from wallbatch.engine.engine import Engine
from wallbatch.scene.build import build_case
from wallbatch.scene.case import structure_key

pytestmark = pytest.mark.skipif(fast.njit is None, reason="numba not importable")

OUT = ["step", "temp", "ke", "pe", "etot", "ecouple", "econserve", "press"]
WALLS = {"w": {"style": "lj93", "units": "box", "energy": True,
               "zlo": {"coord": 0.0, "epsilon": 1.0, "sigma": 1.0, "cutoff": 2.5},
               "zhi": {"coord": 8.0, "epsilon": 1.5, "sigma": 1.0, "cutoff": 2.5}}}


WALLS_2D = {"w": {"style": "lj93", "units": "box", "energy": True,
                   "ylo": {"coord": 0.0, "epsilon": 1.0, "sigma": 1.0, "cutoff": 2.5},
                   "yhi": {"coord": 8.0, "epsilon": 1.0, "sigma": 1.0, "cutoff": 2.5}}}


def gas(fixes, *, n=300, steps=400, thermo=50, seed=5, temperature=1.5, **extra):
    """n atoms of an ideal gas between lj93 walls (x, y periodic) with the given fixes."""
    return slab_gas(copy.deepcopy(WALLS), n=n, hi=(6.0, 6.0, 8.0), margin=1.6, temperature=temperature, seed=seed, dt=0.005,
                    steps=steps, thermo=thermo, output=OUT, fixes=fixes, **extra)


def run_both(monkeypatch, configs):
    cases = [build_case(config_from_dict(d)) for d in configs]
    assert len({structure_key(c) for c in cases}) == 1
    return run_numpy_and_compiled(monkeypatch, cases)


assert_same = assert_same_results


def check(monkeypatch, configs, rtol=0.0):
    ref, got, eng = run_both(monkeypatch, configs)
    assert eng.fast is not None and eng.fast.compiled_chunks > 0 and eng.fast.fallbacks == 0
    assert_same(ref, got, rtol)
    return ref, got, eng


# ----------------------------------------------------------------------------- shared arithmetic


@pytest.fixture(scope="module")
def compiled_pairwise():
    """The kernels' pairwise_sum, called as they call it: from compiled code (it has no CPython
    entry point of its own)."""
    from numba import njit

    pairwise = fast._th_pairwise

    @njit
    def call(a, lo, n):  # noqa: ANN001, ANN202
        return pairwise(a, lo, n)

    return call


@pytest.mark.parametrize("n", [0, 1, 7, 8, 9, 127, 128, 129, 136, 1000, 1003, 4099, 10000, 65537])
def test_pairwise_sum_is_numpys_order(n, compiled_pairwise):
    a = np.random.default_rng(n).standard_normal(n + 3) * 1e3
    assert th.pairwise_sum(a, 1, n) == a[1:n + 1].sum()
    assert compiled_pairwise(a, 1, n) == a[1:n + 1].sum()


def test_chain_half_step_compiled_equals_numpy():
    """nh_half_step: NumPy on (M, C) columns of two cases, numba on one case's rows and scalars."""
    r = np.random.default_rng(1)
    eta, ed, edd = r.random((2, 3)), r.random((2, 4)) * 0.1, r.random((2, 3))
    Q = np.zeros((2, 3))
    vals = (np.array([1.2, 0.9]), np.array([1.0, 1.1]), np.array([10.0, 5.0]))
    tail = (np.array([0.1, 0.0]), np.array([0.005, 0.002]))
    ref = [a.copy() for a in (eta, ed, edd, Q)]
    with np.errstate(all="ignore"):
        t1, c1 = th.nh_half_step(*(a.T for a in ref), *vals, 30.0, 1.0, 2, *tail)
    for c in range(2):
        rows = [a[c] for a in (eta, ed, edd, Q)]
        t2, c2 = fast._th_nh(*rows, vals[0][c], vals[1][c], vals[2][c], 30.0, 1.0, 2, tail[0][c], tail[1][c])
        assert t2 == t1[c] and c2 == c1[c] and t2 != 1.0
    for a, b in zip(ref, (eta, ed, edd, Q)):
        np.testing.assert_array_equal(a, b)


# ----------------------------------------------------------------------------- thermostats


def test_langevin_same_stream_bit_for_bit(monkeypatch):
    fixes = {"a": "fix a all nve", "b": "fix b all langevin 1.0 2.0 0.5 48279"}
    ref, got, eng = check(monkeypatch, [gas(fixes), gas(fixes, seed=6)])
    assert eng.fast.compiled_chunks == 8
    t = got[0].data["temp"]
    assert t[-1] > 1.2 and np.all(got[0].data["ecouple"] == 0.0)  # heated towards 2; no tally: no ecouple
    assert not np.array_equal(got[0].data["temp"], got[1].data["temp"])


def test_cases_with_generators_after_the_first_skip_numbas_typing(monkeypatch):
    """Three Langevin cases, one kernel call per case (each its own generator): the first goes
    through numba's dispatcher, the other two to the entry point it resolved (`backend.resolved`:
    no typing of ~60 arguments per call), with the NumPy path's bits."""
    from wallbatch.engine import backend, threads

    calls = {"dispatcher": 0, "entry": 0}
    run_kernel, call_kernel = threads.run_kernel, backend.call_kernel

    def counted_run(kernel, args, *a, **k):
        calls["dispatcher"] += 1
        return run_kernel(kernel, args, *a, **k)

    def counted_call(kernel, *args):
        calls["entry"] += not hasattr(kernel, "py_func")
        return call_kernel(kernel, *args)

    monkeypatch.setattr(threads, "run_kernel", counted_run)
    monkeypatch.setattr(backend, "call_kernel", counted_call)
    monkeypatch.setenv("WALLBATCH_THREADS", "1")
    fixes = {"a": "fix a all nve", "b": "fix b all langevin 1.0 2.0 0.5 48279"}
    ref, got, eng = check(monkeypatch, [gas(fixes, seed=seed, steps=200, thermo=50) for seed in (5, 6, 7)])
    assert calls["dispatcher"] >= 1 and calls["entry"] == 2 * calls["dispatcher"]
    assert not np.array_equal(got[0].data["temp"], got[2].data["temp"])


def test_langevin_zero_tally_on_a_group(monkeypatch):
    d = gas({"a": "fix a all nve", "b": "fix b hot langevin 2.0 2.0 0.2 9 zero yes tally yes"})
    d["atoms"].append({**d["atoms"][0], "group": "hot", "create": {"random": {"count": 100, "region": "mid"}}})
    ref, got, eng = check(monkeypatch, [d])
    ec = got[0].data["ecouple"]
    assert np.all(ec[1:] != 0.0)
    # tally: etot + ecouple stays close to its start (the thermostat's work is accounted)
    econ = got[0].data["econserve"]
    assert np.ptp(econ) < 0.05 * np.ptp(got[0].data["etot"]) + 1e-3 * abs(econ[0])


def test_berendsen_and_rescale_bit_for_bit(monkeypatch):
    fixes = {"a": "fix a all nve", "b": "fix b all temp/berendsen 1.0 0.8 0.1",
             "c": "fix c all temp/rescale 7 0.9 0.9 0.01 0.5"}
    ref, got, eng = check(monkeypatch, [gas(fixes), gas(fixes, temperature=2.0)])
    t = got[1].data["temp"]
    assert abs(t[-1] - 0.8) < 0.1 and np.all(got[1].data["ecouple"][1:] > 0.0)


def test_rescale_alone_runs_in_windows_bit_for_bit(monkeypatch):
    """temp/rescale every 7 steps (samples every 50): windows end on its due steps."""
    fixes = {"a": "fix a all nve", "c": "fix c all temp/rescale 7 0.9 0.9 0.01 0.5"}
    ref, got, eng = check(monkeypatch, [gas(fixes), gas(fixes, temperature=2.0)])
    assert abs(got[1].data["temp"][-1] - 0.9) < 0.1 and got[1].data["ecouple"][-1] > 0.0


def test_nvt_matches_numpy(monkeypatch):
    """Bit for bit: the chain's exp is the C library's on both paths (thermostats.libm_exp)."""
    ramp = {"a": "fix a all nvt temp 1.0 1.2 0.1 tchain 3 tloop 2 drag 0.1"}
    plain = {"a": "fix a all nvt temp 1.0 1.0 0.1 tchain 3 tloop 2"}
    ref, got, eng = check(monkeypatch, [gas(ramp), gas(plain, temperature=0.7)])
    econ = got[1].data["econserve"]
    assert np.ptp(econ) < 1e-3 * abs(econ[0])  # the chain's energy balances the exchange
    assert np.ptp(got[1].data["etot"]) > 0.1 * abs(econ[0])


def test_thermostats_on_groups(monkeypatch):
    """nvt on one group, nve + berendsen on the other: group temperatures (masked pairwise sums)
    and group scaling."""
    d = gas({"a": "fix a hot nvt temp 2.0 2.0 0.1", "b": "fix b gas nve",
             "c": "fix c gas temp/berendsen 0.5 0.5 0.2"})
    d["atoms"].append({**d["atoms"][0], "group": "hot", "create": {"random": {"count": 120, "region": "mid"}}})
    ref, got, eng = check(monkeypatch, [d])
    assert got[0].data["temp"][-1] != got[0].data["temp"][0]


def test_sampling_every_step_with_langevin(monkeypatch):
    fixes = {"a": "fix a all nve", "b": "fix b all langevin 1.0 1.0 0.5 5"}
    _, got, eng = check(monkeypatch, [gas(fixes, steps=30, thermo=1, n=50)])
    assert eng.fast.compiled_chunks == 30


@pytest.mark.slow
def test_fallback_restores_the_langevin_stream(monkeypatch):
    """An atom pushed behind the wall: the chunk is handed back and the NumPy loop, re-running it
    with the restored generator, reports exactly what the NumPy path reports."""
    fixes = {"a": "fix a all nve", "b": "fix b all langevin 30.0 30.0 0.01 5"}
    d = gas(fixes, steps=2000, thermo=500, n=40)
    d["walls"]["w"]["zlo"]["cutoff"] = 0.3
    calm = gas({"a": "fix a all nve", "b": "fix b all langevin 1.0 1.0 0.5 5"}, steps=2000, thermo=500, n=40,
               seed=9)
    ref, got, eng = run_both(monkeypatch, [calm, d])
    assert eng.fast.fallbacks > 0 and eng.fast.compiled_chunks > 0
    assert [r.status for r in got] == ["ok", "failed"] and "behind the wall" in got[1].error
    assert_same(ref, got)


def test_two_langevin_fixes_hot_and_cold_bit_for_bit(monkeypatch):
    """A hot group (langevin at 2.5, zero yes, tally yes) and a cold one (langevin at 0.3, tally
    yes), each with its own seed: the kernel draws each fix's stream from its own generator and
    adds the forces in fix order, so two cases give the NumPy path's bits, the Langevin forces
    each fix keeps included; the hot atoms end hotter than the cold ones."""
    def scene(seed):
        d = gas({"a": "fix a all nve", "h": f"fix h hot langevin 2.5 2.5 0.2 {seed} zero yes tally yes",
                 "c": f"fix c gas langevin 0.3 0.3 0.2 {seed + 1} tally yes"}, steps=300, thermo=50, seed=seed)
        d["atoms"].append({**d["atoms"][0], "group": "hot", "create": {"random": {"count": 150, "region": "mid"}}})
        return d

    ref, got, eng = check(monkeypatch, [scene(5), scene(8)])
    hot, cold = (f for f in eng.ensemble.fixes if f.style == "langevin")
    assert hot.force.shape == cold.force.shape == eng.state.x.shape and hot.force.flags.c_contiguous
    assert np.all(hot.force[:, ~hot.group] == 0.0) and np.all(cold.force[:, hot.group] == 0.0)
    assert np.abs(hot.force).max() > 0 and np.abs(cold.force).max() > 0
    v2 = (eng.state.v ** 2).sum(axis=2)
    assert np.all(v2[:, hot.group].mean(axis=1) > 3.0 * v2[:, cold.group].mean(axis=1))
    assert not np.array_equal(got[0].data["ecouple"], got[1].data["ecouple"])


def test_two_nvt_fixes_hot_and_cold(monkeypatch):
    """Two Nose-Hoover chains, a hot group (T 2.5, tchain 3, tloop 2) and a cold one (T 0.4 ramped to
    0.6, tchain 2, drag): the kernel keeps the chains side by side, each with its own length and
    tloop, and gives the NumPy path's bits (the chains' exp is the C library's on both paths), ecouple (both chains'
    energies) included, sampled every 50 steps and every step; each group ends near its target."""
    def scene(thermo, steps=400):
        d = gas({"h": "fix h hot nvt temp 2.5 2.5 0.1 tchain 3 tloop 2",
                 "c": "fix c gas nvt temp 0.4 0.6 0.2 tchain 2 drag 0.2"}, steps=steps, thermo=thermo)
        d["atoms"].append({**d["atoms"][0], "group": "hot", "create": {"random": {"count": 150, "region": "mid"}}})
        return d

    ref, got, eng = check(monkeypatch, [scene(50)])
    hot, cold = eng.ensemble.nvt
    assert hot.chain.eta.shape[1] == 3 and cold.chain.eta.shape[1] == 2 and np.all(hot.chain.eta[:, 0] != 0.0)
    v2 = (eng.state.v ** 2).sum(axis=2)
    t_hot, t_cold = v2[0, hot.group].mean() / 3, v2[0, cold.group].mean() / 3
    assert abs(t_hot - 2.5) < 0.5 and abs(t_cold - 0.6) < 0.2
    assert np.ptp(got[0].data["ecouple"]) > 10.0  # the chains exchanged energy (~150 here)
    _, _, every = check(monkeypatch, [scene(1, steps=30)])
    assert every.fast.sampled_calls > 0


def with_frozen(fixes: dict, **kw) -> dict:
    """`gas` (300 atoms, group gas) plus 120 atoms of group hot in the middle; `fixes` decides who
    is integrated (atoms in no nve or nvt group are frozen)."""
    d = gas(fixes, **kw)
    d["atoms"].append({**d["atoms"][0], "group": "hot", "create": {"random": {"count": 120, "region": "mid"}}})
    return d


FROZEN = {  # who is integrated; the others stay where they are
    "nve on hot": {"a": "fix a hot nve"},
    "nve on gas": {"a": "fix a gas nve"},
    "nvt on hot, langevin": {"a": "fix a hot nvt temp 2.0 2.0 0.1", "b": "fix b all langevin 1.0 1.0 0.5 48279"},
    "nve + berendsen on gas": {"a": "fix a gas nve", "b": "fix b gas temp/berendsen 0.5 0.5 0.2"},
}


@pytest.mark.parametrize("who", sorted(FROZEN))
@pytest.mark.parametrize("thermo", [1, 20])
def test_frozen_atoms_run_compiled_bit_for_bit(monkeypatch, who, thermo):
    """An integrator on part of the atoms (without pair forces): the kernel with `_K_FROZEN` keeps
    the others' v and x as they are (the walls still push them, a Langevin fix on all atoms still
    adds its force), every output the NumPy engine's, bit for bit, sampled every step or every
    20th; the frozen atoms have not moved by a bit."""
    d = with_frozen(FROZEN[who], steps=60, thermo=thermo)
    ref, got, eng = check(monkeypatch, [d])
    assert eng.fast.kernel.dispatcher.py_func.__globals__["_K_FROZEN"] is True
    case = build_case(config_from_dict(d))
    moving = eng.ensemble.integrated
    assert 0 < moving.sum() < moving.size
    x, v = eng.state.x[0], eng.state.v[0]
    assert np.array_equal(x[~moving], case.x[~moving]) and np.array_equal(v[~moving], case.v[~moving])
    assert np.all(np.any(x[moving] != case.x[moving], axis=1))
    assert np.ptp(got[0].data["temp"]) > 0


@pytest.mark.parametrize("scene", ["reflect statistics", "stochastic", "flow", "run to a time"])
def test_frozen_atoms_with_other_walls_and_runs_bit_for_bit(monkeypatch, scene):
    """Frozen atoms beside wall/reflect with statistics, wall/reflect/stochastic, wall/flow, and in
    a run to a simulated time: the NumPy engine's bits on every output."""
    d = with_frozen({"a": "fix a gas nve"}, steps=100, thermo=10)
    if scene == "reflect statistics":
        d["walls"] = {"r": {"style": "reflect", "units": "box", "zlo": 1.5, "zhi": 6.5}}
        d["output"] = {"thermo": OUT + ["reflect_count", "reflect_impulse"]}
    elif scene == "stochastic":
        d["walls"] = {"th": {"style": "reflect/stochastic", "rstyle": "diffusive", "seed": 2024, "units": "box",
                             "zlo": {"coord": 1.5, "temp": 2.0}, "zhi": {"coord": 6.5, "temp": 0.5}}}
        d["output"] = {"thermo": OUT + ["reflect_count"]}
    elif scene == "flow":
        d["walls"]["f"] = {"style": "flow", "axis": "x", "vflow": 0.5, "temperature": 1.5, "seed": 11,
                           "coords": [1.5, 4.5], "units": "box"}
        d["output"] = {"thermo": OUT + ["flow_crossings"]}
    else:
        d["timestep"] = 0.0045
        d["run"] = {"time": 0.45, "thermo": {"time": 0.1}}
    ref, got, eng = check(monkeypatch, [d])
    assert eng.fast.kernel.dispatcher.py_func.__globals__["_K_FROZEN"] is True
    counts = [k for k in ("reflect_count", "flow_crossings") if k in got[0].data]
    assert all(got[0].data[k][1:].sum() > 5 for k in counts)  # the walls acted


def test_frozen_atoms_with_dt_reset_bit_for_bit(monkeypatch):
    """Frozen atoms with fix dt/reset (the kernel's final kick fused with dt/reset's test)."""
    d = with_frozen({"a": "fix a gas nve"}, steps=80, thermo=10)
    d["dt_reset"] = {"every": 1, "xmax": 0.02, "tmax": 0.005, "units": "box"}
    d["output"] = {"thermo": OUT + ["dt"]}
    ref, got, eng = check(monkeypatch, [d])
    assert np.ptp(got[0].data["dt"]) > 0  # dt/reset acted


def test_frozen_atoms_split_over_threads_give_the_bits_of_one_thread(monkeypatch):
    """One case with frozen atoms split over two threads by atoms (each its atoms' rows of the
    integrated mask): one thread's bits."""
    configs = [with_frozen({"a": "fix a gas nve"}, n=3000, steps=60, thermo=20)]
    monkeypatch.setattr(fast, "SPLIT_SAMPLE_STEPS", 1)  # (samples 20 steps apart: split all the same)
    one, _, split1 = run_with(monkeypatch, configs, 1)
    two, eng2, split2 = run_with(monkeypatch, configs, 2)
    assert split1["atoms"] == 0 and split2["atoms"] >= 1 and eng2.fast.fallbacks == 0
    assert_same(one, two)


@pytest.mark.parametrize("fix", ["fix b all langevin 1.0 2.0 0.5 48279 tally yes", "fix b all nvt temp 1.0 2.0 0.1",
                                 "fix b all temp/berendsen 1.0 2.0 0.2", "fix b all temp/rescale 5 1.0 2.0 0.05 0.5"])
def test_thermostats_with_dt_reset_bit_for_bit(monkeypatch, fix):
    """fix dt/reset every step (xmax small enough that dt changes) with a thermostat: Engine.step
    resets dt after the thermostats' end_of_step, so the candidates come from the scaled
    velocities (`_late_dt_low`); two cases of different xmax. Every output, dt and time included,
    is the NumPy path's, bit for bit, and dt did change."""
    fixes = {"a": "fix a all nve", "b": fix} if "nvt" not in fix else {"b": fix}
    configs = []
    for xmax in (0.004, 0.006):
        d = gas(fixes, steps=200, thermo=20)
        d["dt_reset"] = {"every": 1, "xmax": xmax, "tmax": 0.005, "units": "box"}
        d["output"] = {"thermo": OUT + ["dt", "time"]}
        configs.append(d)
    ref, got, eng = check(monkeypatch, configs)
    dt = got[0].data["dt"]
    assert np.unique(dt).size >= 3 and dt.max() <= 0.005


@pytest.mark.parametrize("fix", ["fix b all langevin 1.5 1.5 0.5 48279 tally yes", "fix b all nvt temp 1.5 1.5 0.1",
                                 "fix b all temp/berendsen 1.5 1.5 0.2"])
def test_thermostats_with_flow_walls_bit_for_bit(monkeypatch, fix):
    """A gas between flow walls (wall/flow along x) with a thermostat: the thermostats' end_of_step,
    then the flow walls' redraws (Engine.step's order); every output is the NumPy path's, bit for
    bit, and atoms crossed the flow walls."""
    fixes = {"a": "fix a all nve", "b": fix} if "nvt" not in fix else {"b": fix}
    d = gas(fixes, steps=200, thermo=20)
    d["walls"]["f"] = {"style": "flow", "axis": "x", "vflow": 0.5, "temperature": 1.5, "seed": 11,
                       "coords": [1.5, 4.5], "units": "box"}
    d["output"] = {"thermo": OUT + ["flow_crossings"]}
    ref, got, eng = check(monkeypatch, [d])
    assert got[0].data["flow_crossings"][1:].sum() > 10


# ----------------------------------------------------------------------------- 2-D


def test_two_dimensional_scene_runs_compiled(monkeypatch):
    xy = np.random.default_rng(4).random((200, 2)) * [10.0, 5.0] + [0.0, 1.5]
    d = {"units": "lj", "seed": 3, "dimension": 2,
         "box": {"lo": [0, 0, -0.5], "hi": [10, 8, 0.5], "boundary": ["p", "f", "p"]},
         "atoms": [{"group": "gas", "create": {"positions": [[a, b, 0.0] for a, b in xy.tolist()]}, "mass": 1.0,
                    "velocity": {"temperature": 1.0}}],
         "walls": copy.deepcopy(WALLS_2D), "timestep": 0.005, "run": {"steps": 300, "thermo": 100},
         "output": {"thermo": OUT}}
    _, got, eng = check(monkeypatch, [d])
    _, got2, eng2 = check(monkeypatch, [{**d, "fixes": {"a": "fix a all nve",
                                                         "t": "fix t all langevin 1.5 1.5 0.3 7"}}])
    assert eng.fast.compiled_chunks == 3 and eng2.fast.compiled_chunks == 3
    assert np.all(got[0].data["wall_force"][1:] != 0.0)  # atoms reached the y walls
    # both ran the kernel that integrates x and y only (`_K_2D`), with the NumPy engine's bits
    for e in (eng, eng2):
        assert e.fast.kernel.dispatcher.py_func.__globals__["_K_2D"] is True


def test_two_d_kernel_only_where_z_updates_are_the_identity(monkeypatch):
    """`two_d_eligible`: a 2-D scene with enforce2d on every atom, after its setup (v_z = f_z =
    +0.0); not with a -0.0 in v_z, f_z or z, a z outside the periodic box, or in 3-D."""
    xy = np.random.default_rng(4).random((50, 2)) * [10.0, 5.0] + [0.0, 1.5]
    d = {"units": "lj", "seed": 3, "dimension": 2,
         "box": {"lo": [0, 0, -0.5], "hi": [10, 8, 0.5], "boundary": ["p", "f", "p"]},
         "atoms": [{"group": "gas", "create": {"positions": [[a, b, 0.0] for a, b in xy.tolist()]}, "mass": 1.0,
                    "velocity": {"temperature": 1.0}}],
         "walls": copy.deepcopy(WALLS_2D), "timestep": 0.005, "run": {"steps": 20, "thermo": 10}}
    monkeypatch.setenv("WALLBATCH_NUMBA", "1")
    eng = Engine([build_case(config_from_dict(d))])
    eng.run()
    plan = eng.fast.plan_source()
    s = plan.state
    assert fast.two_d_eligible(plan)
    for name, index, value in (("v", (0, 3, 2), -0.0), ("f", (0, 3, 2), -0.0), ("x", (0, 3, 2), -0.0),
                               ("x", (0, 3, 2), 0.7), ("v", (0, 3, 2), 1e-300)):
        arr = getattr(s, name)
        saved = arr[index]
        arr[index] = value
        assert not fast.two_d_eligible(plan), (name, value)
        arr[index] = saved
    assert fast.two_d_eligible(plan)
    eng3 = Engine([build_case(config_from_dict(gas({"a": "fix a all nve"}, n=50, steps=20, thermo=10)))])
    eng3.run()
    assert not fast.two_d_eligible(eng3.fast.plan_source())
    assert eng3.fast.kernel.dispatcher.py_func.__globals__["_K_2D"] is False


@pytest.mark.parametrize("fix", ["fix b all nvt temp 1.0 2.0 0.1", "fix b all langevin 1.0 2.0 0.5 48279"])
def test_thermostat_batches_over_threads_give_the_bits_of_one_thread(monkeypatch, fix):
    """Four cases with fix nvt (one call for a run of cases) or fix langevin (one call per case,
    its own generator): two threads take runs of cases, and every output is one thread's, bit for
    bit."""
    fixes = {"b": fix} if "nvt" in fix else {"a": "fix a all nve", "b": fix}
    configs = [gas(fixes, n=200, steps=600, thermo=100, seed=seed) for seed in (5, 6, 7, 8)]
    one, eng1, split1 = run_with(monkeypatch, configs, 1)
    two, eng2, split2 = run_with(monkeypatch, configs, 2)
    assert split1["cases"] == 0 and split2["cases"] >= 1 and eng2.fast.fallbacks == 0 and eng2.fast.compiled_chunks > 0
    assert_same(one, two)
    assert not np.array_equal(two[0].data["temp"], two[3].data["temp"]) and two[3].data["temp"][-1] > 1.6  # heated


@pytest.mark.slow
def test_trouble_in_one_thread_falls_back_and_fails_as_numpy(monkeypatch):
    """Four Langevin cases over two threads, the last driven behind a wall: the chunk is handed back
    (every generator restored) and the NumPy loop reports what the NumPy path reports; the others
    end as there."""
    calm = [gas({"a": "fix a all nve", "b": f"fix b all langevin 1.0 1.0 0.5 {seed}"}, steps=2000, thermo=1000,
                n=100, seed=seed) for seed in (9, 10, 11)]
    bad = gas({"a": "fix a all nve", "b": "fix b all langevin 30.0 30.0 0.01 5"}, steps=2000, thermo=1000, n=100)
    bad["walls"]["w"]["zlo"]["cutoff"] = 0.3
    monkeypatch.setenv("WALLBATCH_THREADS", "2")
    from wallbatch.engine import threads

    before = threads.splits["cases"]
    ref, got, eng = run_both(monkeypatch, [*calm, bad])
    assert threads.splits["cases"] > before and eng.fast.fallbacks > 0
    assert [r.status for r in got] == ["ok", "ok", "ok", "failed"] and "behind the wall" in got[3].error
    assert_same(ref, got)


# ----------------------------------------------------------------------------- call length


@pytest.mark.parametrize("in_kernel", [True, False])
def test_long_chunks_take_several_kernel_calls_with_the_same_bits(monkeypatch, in_kernel):
    """A chunk longer than CALL_WORK atom-steps (samples recorded in the kernel, or one chunk per
    sample) runs as several kernel calls, so a Ctrl-C between them stops the run soon; the
    results are those of one call per chunk, bit for bit (here with fix nvt and two cases)."""
    from wallbatch.engine import threads

    configs = [gas({"b": "fix b all nvt temp 1.0 1.3 0.1"}, n=40, steps=600, thermo=200, seed=seed)
               for seed in (5, 6)]
    cases = [build_case(config_from_dict(d)) for d in configs]
    monkeypatch.setenv("WALLBATCH_NUMBA", "1")
    if not in_kernel:
        monkeypatch.setattr(fast.FastPath, "samples_in_kernel", lambda self, at: False)
    calls = []
    real = threads.run_kernel
    monkeypatch.setattr(threads, "run_kernel", lambda *a, **k: (calls.append(a[1][0]), real(*a, **k))[1])
    whole = Engine(cases).run()
    n_whole, steps_whole = len(calls), max(calls)
    calls.clear()
    monkeypatch.setattr(fast, "CALL_WORK", 2 * 40 * 7)  # 7 steps of the two cases per call
    monkeypatch.setattr(fast.FastPath, "least_steps", 1)  # (not FLAT_MIN_CALL_STEPS)
    split = Engine(cases).run()
    # one call for the three samples, or one per sample's chunk; then calls of 7 steps at most (with
    # samples in the kernel, a sample's call runs the last 7 steps before it, the steps before those
    # go first in calls of their own: Engine.run's `lead_steps`)
    assert (n_whole, steps_whole) == ((1, 600) if in_kernel else (3, 200))
    assert calls == ([7] * 27 + [4, 7] if in_kernel else [7] * 28 + [4]) * 3
    assert_same(whole, split)
    assert whole[0].data["temp"][-1] != whole[1].data["temp"][-1]  # two cases, real numbers


def test_a_call_runs_call_work_atom_steps_but_never_fewer_than_its_least_steps():
    """call_steps: CALL_WORK atom-steps over the batch (an atom-step of the pair and the ellipsoid
    kernels counted PAIR_STEP_COST and ASPHERE_STEP_COST times), but never fewer steps than each
    path's least (a call copies every atom into the kernel and back: shorter calls of a large case
    ran it 35% slower, N = 1e6 flat)."""
    from types import SimpleNamespace

    from wallbatch.engine.asphere_compiled import AspherePath
    from wallbatch.engine.pair_compiled import PairChunks

    def plan(ncases, natoms):
        return SimpleNamespace(state=SimpleNamespace(ncases=ncases, x=np.zeros((ncases, natoms, 3))))

    assert fast.call_steps(plan(2, 1000)) == fast.CALL_WORK // 2000 == 5000
    assert fast.call_steps(plan(1, 1000), fast.PAIR_STEP_COST) == fast.CALL_WORK // (25 * 1000) == 400
    assert fast.call_steps(plan(1, 10**6), 1, 200) == 200 and fast.call_steps(plan(1, 10**9)) == 1
    for path, cost, least in ((fast.FastPath, 1, fast.FLAT_MIN_CALL_STEPS),
                              (PairChunks, fast.PAIR_STEP_COST, fast.PAIR_MIN_CALL_STEPS),
                              (AspherePath, fast.ASPHERE_STEP_COST, fast.ASPHERE_MIN_CALL_STEPS)):
        p = SimpleNamespace(plan_source=lambda: plan(1, 10**6), step_cost=path.step_cost,
                            least_steps=path.least_steps)
        assert (path.step_cost, path.least_steps) == (cost, least)
        assert fast.KernelPath.call_steps(p) == max(least, fast.CALL_WORK // (cost * 10**6))
        p.plan_source = lambda: plan(1, 100)
        assert fast.KernelPath.call_steps(p) == fast.CALL_WORK // (cost * 100)


# ----------------------------------------------------------------------------- runs to a simulated time


@pytest.mark.parametrize("fix", ["fix b all langevin 1.0 2.0 0.5 48279 tally yes", "fix b all nvt temp 1.0 2.0 0.1",
                                 "fix b all temp/berendsen 1.0 2.0 0.2"])
def test_thermostats_in_a_run_to_a_time_bit_for_bit(monkeypatch, fix):
    """A run to a simulated time (`run: {time: ...}`, samples at times) with a thermostat whose
    target ramps 1 -> 2: the ramp follows the time (time / run time, as the NumPy path's
    ramp_fraction), the landing steps clip dt; two cases at timesteps that do not divide the
    sample interval (0.005 and 0.0045: they land on different steps). The compiled chunks give the
    NumPy path's bits on every output, and the gas heats towards the ramp's end."""
    fixes = {"a": "fix a all nve", "b": fix} if "langevin" in fix or "berendsen" in fix else {"b": fix}
    configs = []
    for dt in (0.005, 0.0045):
        d = gas(fixes, steps=10)
        d["timestep"] = dt
        d["run"] = {"time": 1.0, "thermo": {"time": 0.1}}
        configs.append(d)
    ref, got, eng = check(monkeypatch, configs)
    assert [len(r.data["step"]) for r in got] == [11, 11]
    assert got[0].data["step"][-1] == 200 and got[1].data["step"][-1] == 230  # 23 steps per 0.1, the last clipped
    assert got[0].data["temp"][-1] > 1.5


@pytest.mark.parametrize("numba", ["0", "1"])
def test_langevin_in_a_run_to_a_time_does_not_depend_on_the_batch(monkeypatch, numba):
    """Batched with a case at another timestep, a Langevin case waits idle while the other reaches
    each sample time: its next step must start from the forces it had (walls and its last
    Langevin force), as when it runs alone. On both paths the case's outputs are the same bits
    alone and batched (the NumPy path used to zero an idle case's Langevin force: heavier later)."""
    monkeypatch.setenv("WALLBATCH_NUMBA", numba)
    fixes = {"a": "fix a all nve", "b": "fix b all langevin 1.0 2.0 0.5 48279 tally yes"}

    def config(dt):
        d = gas(fixes, steps=10)
        d["timestep"] = dt
        d["run"] = {"time": 0.5, "thermo": {"time": 0.1}}
        return build_case(config_from_dict(d))

    alone = Engine([config(0.005)]).run()[0]
    batched = Engine([config(0.005), config(0.0045)]).run()[0]
    for name in ("temp", "ke", "etot", "ecouple"):
        np.testing.assert_array_equal(batched.data[name], alone.data[name], err_msg=name)
    assert np.ptp(alone.data["ecouple"]) > 0
