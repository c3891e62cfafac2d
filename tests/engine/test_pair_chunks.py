"""Fused pair chunks (wallbatch.engine.pair_compiled.PairChunks): whole chunks of steps of a
pair lj/cut scene in one compiled call per case. The per-step compiled pair path (the engine with
the fused chunks switched off) runs the same kernels step by step from Python, so every sampled
output must be the same bits; the NumPy engine (WALLBATCH_NUMBA=0) agrees to rounding. Each test
checks that the fused chunks really ran (or handed a chunk back), so a silent fallback cannot pass.
"""

from __future__ import annotations

import numpy as np
import pytest

from wallbatch.config.models import config_from_dict
from wallbatch.engine import pair_compiled
from wallbatch.engine.engine import Engine
from wallbatch.engine.pair_compiled import PairChunks
from wallbatch.scene.build import build_case
from wallbatch.scene.case import structure_key

pytestmark = pytest.mark.skipif(pair_compiled.njit is None, reason="numba not importable")

WALL = ["EDGE", 1.0, 1.0, 2.5]


def slit(eps: float = 1.0, *, steps: int = 40, thermo: int = 10, temperature: float = 2.0) -> dict:
    """An fcc LJ liquid melting between two lj93 walls (x, y periodic, z fixed): ~290 atoms."""
    return {
        "name": "lj-slit", "units": "lj", "seed": 3, "lattice": {"style": "fcc", "scale": 0.8},
        "box": {"lo": [0, 0, 0], "hi": [6.84, 6.84, 8.0], "boundary": ["p", "p", "f"]},
        "regions": {"pore": {"style": "block", "lo": [0, 0, 1.0], "hi": [6.8, 6.8, 7.0], "units": "box"}},
        "atoms": [{"group": "liquid", "create": {"lattice": {"region": "pore"}}, "mass": 1.0,
                   "velocity": {"temperature": temperature}}],
        "pair": {"style": "lj/cut", "epsilon": eps, "sigma": 1.0, "cutoff": 2.5, "shift": True},
        "walls": {"pore": {"style": "lj93", "units": "box", "energy": True, "virial": True,
                           "zlo": list(WALL), "zhi": list(WALL)}},
        "timestep": 0.005, "run": {"steps": steps, "thermo": thermo},
        "output": {"thermo": ["step", "temp", "pe", "etot", "press"]},
    }


def flow_fluid(rule: str = "lammps") -> dict:
    """An LJ fluid in a periodic box with three wall/flow walls across x (~150 atoms)."""
    return {
        "name": "flow-lj", "units": "lj", "seed": 593894,
        "box": {"lo": [0, 0, 0], "hi": [10, 6, 6], "boundary": ["p", "p", "p"]},
        "atoms": [{"group": "fluid", "create": {"random": {"count": 150, "overlap": 0.9}}, "mass": 1.0,
                   "velocity": {"temperature": 1.5}}],
        "pair": {"style": "lj/cut", "epsilon": 1.0, "sigma": 1.0, "cutoff": 2.5},
        "walls": {"fl": {"style": "flow", "axis": "x", "vflow": 0.4, "temperature": 1.5, "seed": 7,
                         "coords": [2.5, 5.0, 7.5], "units": "box", "rule": rule}},
        "timestep": 0.002, "run": {"steps": 150, "thermo": 50},
    }


def sphere_cavity() -> dict:
    """An LJ fluid in a closed box held by a wall/region lj93 sphere, plus a flat lj126 floor."""
    return {
        "name": "lj-cavity", "units": "lj", "seed": 11,
        "box": {"lo": [0, 0, 0], "hi": [12, 12, 12], "boundary": ["f", "f", "f"]},
        "regions": {"R": {"style": "sphere", "center": [6, 6, 6], "radius": 5.5, "units": "box"},
                    "start": {"style": "sphere", "center": [6, 6, 6], "radius": 4.0, "units": "box"}},
        "atoms": [{"group": "fluid", "create": {"random": {"count": 120, "region": "start", "overlap": 0.9}},
                   "mass": 1.0, "velocity": {"temperature": 2.0}}],
        "pair": {"style": "lj/cut", "epsilon": 1.0, "sigma": 1.0, "cutoff": 2.5, "shift": True},
        "walls": {"rw": {"style": "region", "region": "R", "potential": "lj93", "epsilon": 1.0, "sigma": 1.0,
                         "cutoff": 2.5},
                  "floor": {"style": "lj126", "units": "box", "energy": True, "zlo": [0.0, 1.0, 1.0, 2.5]}},
        "timestep": 0.004, "run": {"steps": 200, "thermo": 40},
        "output": {"thermo": ["step", "pe", "etot"]},
    }


def cases_of(*configs: dict) -> list:
    cases = [build_case(config_from_dict(d)) for d in configs]
    assert len({structure_key(c) for c in cases}) == 1  # one batch, as run_cases would make it
    return cases


def run_fused_and_stepwise(monkeypatch, cases):
    """(fused results, fused engine, per-step compiled results, per-step engine)."""
    monkeypatch.setenv("WALLBATCH_NUMBA", "1")
    fused = Engine(cases)
    assert isinstance(fused.fast, PairChunks)
    got = fused.run()
    with monkeypatch.context() as m:
        m.setattr(pair_compiled, "attach_pair_chunks", lambda *a: None)  # engine imports it when it runs
        step = Engine(cases)
        assert step.fast is None and step.pair.compiled
        ref = step.run()
    return got, fused, ref, step


def assert_bits(got, ref):
    assert [r.status for r in got] == [r.status for r in ref]
    assert [r.error for r in got] == [r.error for r in ref]
    for a, b in zip(got, ref):
        assert a.data.keys() == b.data.keys()
        for name in a.data:
            np.testing.assert_array_equal(a.data[name], b.data[name], err_msg=name)


def test_slit_batch_same_bits_as_stepwise(monkeypatch):
    """Two cases (different eps) melting between lj93 walls with energy and virial: fused chunks
    give the per-step compiled path's bits, with the same neighbor-list builds per case."""
    cases = cases_of(slit(1.0), slit(1.3))
    got, fused, ref, step = run_fused_and_stepwise(monkeypatch, cases)
    assert_bits(got, ref)
    assert fused.fast.compiled_chunks == 4 and fused.fast.fallbacks == 0
    np.testing.assert_array_equal(fused.pair.case_builds, step.pair.case_builds)
    assert fused.pair.case_builds.min() >= 3  # the lists were rebuilt inside the chunks
    assert np.ptp(got[0].data["pe"]) > 1.0 and got[0].data["pe"][-1] != got[1].data["pe"][-1]


def test_slit_agrees_with_numpy(monkeypatch):
    """The fused chunks against the NumPy engine: rounding differences only (1e-10 over 40 steps)."""
    cases = cases_of(slit())
    monkeypatch.setenv("WALLBATCH_NUMBA", "1")
    eng = Engine(cases)
    got = eng.run()
    assert eng.fast.compiled_chunks == 4
    monkeypatch.setenv("WALLBATCH_NUMBA", "0")
    ref = Engine(cases).run()
    for key in ("temp", "pe", "etot", "press"):
        np.testing.assert_allclose(got[0].data[key], ref[0].data[key], rtol=1e-10, atol=0, err_msg=key)


@pytest.mark.parametrize("rule", ["lammps", "exact"])
def test_flow_walls_same_bits_as_stepwise(monkeypatch, rule):
    """wall/flow with pair forces: the same redraws from the same generator streams (the chunk
    runs compiled.py's flow step), so the same crossings and the same bits."""
    got, fused, ref, _ = run_fused_and_stepwise(monkeypatch, cases_of(flow_fluid(rule)))
    assert_bits(got, ref)
    assert fused.fast.compiled_chunks == 3 and fused.fast.fallbacks == 0
    assert got[0].data["flow_crossings"][1:].min() >= 3  # atoms did cross the walls


def test_region_and_flat_walls_same_bits_as_stepwise(monkeypatch):
    got, fused, ref, _ = run_fused_and_stepwise(monkeypatch, cases_of(sphere_cavity()))
    assert_bits(got, ref)
    assert fused.fast.compiled_chunks == 5
    assert np.abs(got[0].data["region_force"][1:]).max() > 0  # the cavity wall acted


def test_trouble_hands_the_chunk_back(monkeypatch):
    """An atom shot through the lower wall: the fused chunk hands the chunk back, the NumPy loop
    reports the per-step path's message; the other case of the batch runs to the end."""
    bad = slit(steps=30)
    bad["atoms"].append({"group": "bullet", "create": {"positions": [[3.4, 3.4, 0.9]]}, "mass": 1.0,
                         "velocity": {"values": [[0.0, 0.0, -400.0]]}})
    good = slit(steps=30)
    good["atoms"].append({"group": "bullet", "create": {"positions": [[3.4, 3.4, 0.9]]}, "mass": 1.0,
                          "velocity": {"values": [[0.0, 0.0, 0.0]]}})
    got, fused, ref, _ = run_fused_and_stepwise(monkeypatch, cases_of(bad, good))
    assert_bits(got, ref)
    assert got[0].status == "failed" and got[1].status == "ok"
    assert fused.fast.fallbacks >= 1 and fused.fast.compiled_chunks >= 1


def test_list_grows_inside_the_chunk(monkeypatch):
    """A pair list storage too short for the next build: the kernel grows it and the run keeps
    the per-step path's bits (which grows it in Python)."""
    monkeypatch.setenv("WALLBATCH_NUMBA", "1")
    cases = cases_of(slit(steps=20, thermo=20))
    engines = []
    for fused in (True, False):
        with monkeypatch.context() as m:
            if not fused:
                m.setattr(pair_compiled, "attach_pair_chunks", lambda *a: None)  # engine imports it when it runs
            eng = Engine(cases)
        eng.setup()
        eng.pair._neigh = eng.pair._neigh[:, :16].copy()  # room for 16 pairs
        eng.pair._xref = eng.pair._xref + 1.0  # every atom "moved": rebuild on the first step
        eng.advance(20)
        engines.append(eng)
    a, b = engines
    assert isinstance(a.fast, PairChunks) and a.fast.compiled_chunks == 1 and b.fast is None
    assert a.pair._neigh.shape[1] > 1000 and a.pair.npairs == b.pair.npairs
    np.testing.assert_array_equal(a.state.x, b.state.x)
    np.testing.assert_array_equal(a.state.v, b.state.v)
    np.testing.assert_array_equal(a.pair.case_builds, b.pair.case_builds)


@pytest.mark.parametrize("what", ["lepton never", "dt_reset with a moving wall", "dt_reset over threads",
                                  "reflect statistics over threads"])
def test_what_the_chunk_does_not_run_stays_stepwise(monkeypatch, what):
    """What the fused chunk does not run (wall/lepton faces the policy keeps in NumPy, dt/reset
    with per-step wall values, reflect statistics or dt/reset on a case cut over threads) keeps
    the per-step path."""
    d = slit()
    if what == "lepton never":
        d["walls"] = {"w": {"style": "lepton", "units": "box", "zlo": dict(LEPTON_LJ93)}}
        monkeypatch.setenv("WALLBATCH_LEPTON_COMPILED", "never")
    elif what == "reflect statistics over threads":
        d["walls"] = {"r": {"style": "reflect", "units": "box", "zlo": "EDGE", "zhi": "EDGE"}}
        d["output"] = {"thermo": ["step", "temp", "reflect_count"]}
        monkeypatch.setattr(pair_compiled, "case_parts", lambda n: 2)
    elif what == "dt_reset with a moving wall":
        d["dt_reset"] = {"every": 1, "xmax": 0.05, "tmax": 0.005, "units": "box"}
        d["variables"] = {"lo": "vdisplace(0.0, 0.5)"}
        d["walls"]["pore"]["zlo"] = {"coord": "v_lo", "epsilon": 1.0, "sigma": 1.0, "cutoff": 2.5}
    else:
        d["dt_reset"] = {"every": 1, "xmax": 0.05, "tmax": 0.005, "units": "box"}
        monkeypatch.setattr(pair_compiled, "case_parts", lambda n: 2)
    monkeypatch.setenv("WALLBATCH_NUMBA", "1")
    eng = Engine(cases_of(d))
    assert eng.fast is None and eng.pair.compiled
    assert eng.run()[0].status == "ok"


def test_later_cases_of_a_chunk_skip_numbas_typing(monkeypatch):
    """Three cases of a batch, one kernel call each per chunk: the first of the process through
    numba's dispatcher, every other through the entry point it resolved (`backend.resolved`, kept
    for the later chunks: `backend.Repeated`), with the per-step path's bits."""
    from wallbatch.engine import backend

    calls = {"dispatcher": 0, "entry": 0}
    call_kernel = backend.call_kernel

    def counted(kernel, *args):
        calls["dispatcher" if hasattr(kernel, "py_func") else "entry"] += 1
        return call_kernel(kernel, *args)

    monkeypatch.setattr(backend, "call_kernel", counted)
    got, fused, ref, _ = run_fused_and_stepwise(monkeypatch, cases_of(slit(1.0), slit(1.2), slit(1.4)))
    assert_bits(got, ref)
    assert isinstance(fused.fast, PairChunks) and fused.fast.fallbacks == 0
    total = calls["dispatcher"] + calls["entry"]
    assert calls["dispatcher"] <= 1 and total >= 3 and total % 3 == 0  # (0: kept by an earlier test's chunks)


def test_sample_takes_the_chunk_outputs(monkeypatch):
    """A chunk ending at a sample (samples not recorded in the kernel, as for a case over
    threads) gives the pair energy and virial in its last force pass: the sample's pair.compute
    at those positions takes them (no second pass over the list: the only `forces` call is the
    set-up's), with the per-step path's bits."""
    monkeypatch.setattr(PairChunks, "samples_in_kernel", lambda self, at: False)
    cases = cases_of(slit(1.0), slit(1.3))
    got, fused, ref, step = run_fused_and_stepwise(monkeypatch, cases)
    assert_bits(got, ref)
    calls = []
    forces = pair_compiled.forces
    monkeypatch.setattr(pair_compiled, "forces", lambda *a: calls.append(1) or forces(*a))
    eng = Engine(cases)
    assert_bits(eng.run(), ref)
    assert eng.fast.compiled_chunks == 4 and len(got[0].data["pe"]) == 5 and not eng.sample_blocks
    assert len(calls) == 1  # the set-up's forces; the 4 chunk-end samples took the chunks' outputs
    assert eng.pair._memo is None  # taken by the last sample


def test_remembered_outputs_only_at_their_positions():
    """pair.remember holds a chunk's outputs for exactly its positions, once: a compute at other
    positions (one atom moved by 1e-12) computes afresh, and agrees with a fresh pair's."""
    cases = cases_of(slit())
    eng = Engine(cases)
    eng.setup()
    pair, x = eng.pair, eng.state.x.copy()
    f0 = np.zeros_like(x)
    e0, w0 = pair.compute(x, f0, True)
    pair.remember(x, f0 + 1.0, e0 + 1.0, w0 + 1.0)  # marked: recognisable if taken
    f = np.zeros_like(x)
    e, w = pair.compute(x, f, True)
    np.testing.assert_array_equal(f, f0 + 1.0)
    assert e[0] == e0[0] + 1.0 and w[0] == w0[0] + 1.0
    pair.remember(x, f0 + 1.0, e0 + 1.0, w0 + 1.0)
    x[0, 5, 0] += 1e-12
    f = np.zeros_like(x)
    e, w = pair.compute(x, f, True)
    fresh = Engine(cases).pair
    fr = np.zeros_like(x)
    er, wr = fresh.compute(x, fr, True)
    np.testing.assert_array_equal(f, fr)
    assert e[0] == er[0] and w[0] == wr[0] and abs(e[0] - e0[0]) < 1e-6


def test_trouble_in_a_one_case_batch_keeps_its_list(monkeypatch):
    """One case alone: its chunk builds into the spare pair array, so a chunk handed back to
    NumPy (here after a build: the bullet moves 2 sigma per step) leaves the list, its rows and
    its reference positions as they were; the run reports what the per-step path reports."""
    bad = slit(steps=30)
    bad["atoms"].append({"group": "bullet", "create": {"positions": [[3.4, 3.4, 0.9]]}, "mass": 1.0,
                         "velocity": {"values": [[0.0, 0.0, -400.0]]}})
    monkeypatch.setenv("WALLBATCH_NUMBA", "1")
    eng = Engine(cases_of(bad))
    eng.setup()
    pair = eng.pair
    before = [a.copy() for a in (pair._neigh, pair._owner, pair._first, pair._xref, eng.state.x)]
    assert isinstance(eng.fast, PairChunks) and not eng.fast.advance(5, False)
    assert eng.fast.fallbacks == 1
    for a, b in zip(before, (pair._neigh, pair._owner, pair._first, pair._xref, eng.state.x)):
        np.testing.assert_array_equal(a, b)
    got, fused, ref, _ = run_fused_and_stepwise(monkeypatch, cases_of(bad))
    assert_bits(got, ref)
    assert got[0].status == "failed" and fused.fast.fallbacks >= 1


# wall/lepton faces: lj93 spelled out (3 parameters and fewer: arguments of the generated force),
# and a 4-parameter expression (its parameters as an array: `_vector_faces`)
LEPTON_LJ93 = {"coord": "EDGE", "cutoff": 2.5, "expression": "eps*(2/15*(sig/r)^9-(sig/r)^3)",
               "params": {"eps": 1.0, "sig": 1.0}}
LEPTON_FOUR = {"coord": 7.6, "cutoff": 2.0, "expression": "a*(r-rc)^2 + b*exp(-r/l)",
               "params": {"a": 20.0, "rc": 2.0, "b": 3.0, "l": 0.4}}


def every(d: dict, thermo: int = 1, steps: int | None = None) -> dict:
    """The scene `d` sampled every `thermo` steps (and run `steps` steps)."""
    d = dict(d)
    d["run"] = {"steps": steps or d["run"]["steps"], "thermo": thermo}
    return d


def assert_sampled_in_kernel(eng):
    """The samples after step 0 came from the kernel (sample blocks), none from a NumPy sample."""
    assert eng.fast.sampled_calls >= 1 and eng.sample_blocks
    assert len(eng.samples) == 1  # step 0's (the set-up's)


@pytest.mark.parametrize("scene", ["slit", "flow", "cavity"])
def test_samples_in_the_kernel_same_bits_as_stepwise(monkeypatch, scene):
    """Sampled every step (every 3rd for the cavity), each fused chunk records its samples itself
    (sum m v^2, the pair energy and virial of the step's pass, each wall's energy, force on the
    wall and virial, the flow redraws since the last sample): every output is the per-step
    compiled path's, bit for bit, whose samples come from the NumPy code (Engine.sample)."""
    configs = {"slit": lambda: [every(slit(1.0)), every(slit(1.3))],
               "flow": lambda: [every(flow_fluid("exact"), steps=80)],
               "cavity": lambda: [every(sphere_cavity(), thermo=3, steps=90)]}[scene]()
    got, fused, ref, _ = run_fused_and_stepwise(monkeypatch, cases_of(*configs))
    assert_bits(got, ref)
    assert_sampled_in_kernel(fused)
    assert fused.fast.fallbacks == 0 and len(got[0].data["step"]) == configs[0]["run"]["steps"] // (
        configs[0]["run"]["thermo"]) + 1
    if scene == "slit":
        assert np.ptp(got[0].data["press"]) > 0.1 and np.ptp(got[0].data["wall_energy"]) > 0
    if scene == "flow":
        crossings = got[0].data["flow_crossings"][1:]
        assert crossings.sum() >= 10 and crossings.max() > crossings.min()  # per sample, not summed
    if scene == "cavity":
        assert np.abs(got[0].data["region_force"][1:]).max() > 0 and np.ptp(got[0].data["wall_energy"][1:, 1]) > 0


def test_moving_wall_sampled_in_the_kernel(monkeypatch):
    """A wall moving with a variable and a ramped epsilon (per-step wall values) around an LJ
    liquid, sampled every step in the kernel: each sample uses its own step's values."""
    d = every(slit(), steps=30)
    d["variables"] = {"lo": "vdisplace(0.0, 2.0)", "eps": "ramp(0.5, 2.0)"}
    d["walls"]["pore"]["zlo"] = {"coord": "v_lo", "epsilon": "v_eps", "sigma": 1.0, "cutoff": 2.5}
    got, fused, ref, _ = run_fused_and_stepwise(monkeypatch, cases_of(d))
    assert_bits(got, ref)
    assert_sampled_in_kernel(fused)
    assert np.count_nonzero(np.diff(got[0].data["wall_force"][:, 0])) > 20


def test_trouble_in_a_sampled_chunk(monkeypatch):
    """A bullet through the wall in one case of two, sampled every step: the sampled chunk hands
    back, the NumPy loop fails that case at the per-step path's step with its message, and the
    other case goes on with samples in the kernel again."""
    bad = every(slit(steps=30))
    bad["atoms"].append({"group": "bullet", "create": {"positions": [[3.4, 3.4, 0.9]]}, "mass": 1.0,
                         "velocity": {"values": [[0.0, 0.0, -400.0]]}})
    good = every(slit(steps=30))
    good["atoms"].append({"group": "bullet", "create": {"positions": [[3.4, 3.4, 0.9]]}, "mass": 1.0,
                          "velocity": {"values": [[0.0, 0.0, 0.0]]}})
    got, fused, ref, _ = run_fused_and_stepwise(monkeypatch, cases_of(bad, good))
    assert_bits(got, ref)
    assert got[0].status == "failed" and got[1].status == "ok"
    assert fused.fast.fallbacks >= 1 and fused.fast.sampled_calls >= 1 and fused.sample_blocks


@pytest.mark.parametrize("scene", ["slit", "flow", "berendsen", "nvt+flow"])
def test_a_case_over_threads_records_its_samples_in_the_kernel(monkeypatch, scene):
    """A case cut over threads (`case_parts` 2 here) records its samples in the kernel as on one
    thread (`threads_take`: each sample step's rest on all atoms in one call, with a
    thermostat's end of step, the pair's energy and virial from the threads' pass): one threaded
    call for the 12 samples, the same bits as the one-thread kernel and as stepwise."""
    kind, _, walls = scene.partition("+")
    config = every(flow_fluid("exact") if "flow" in scene else slit(), steps=12)
    if kind in THERMOSTATS:
        config["fixes"] = dict(THERMOSTATS[kind])
        config["output"] = {"thermo": ["step", "temp", "pe", "etot", "press", "ecouple", "econserve"]}
    cases = cases_of(config)
    inkernel, _, ref, _ = run_fused_and_stepwise(monkeypatch, cases)
    monkeypatch.setattr(pair_compiled, "case_parts", lambda n: 2)
    monkeypatch.setattr(pair_compiled, "THREAD_MIN_USE", 0.0)  # never judged busy (a loaded test machine)
    eng = Engine(cases)
    got = eng.run()
    if kind == "nvt":  # (its chain's exp: to 1e-14 against stepwise, as in one thread)
        for name in got[0].data:
            np.testing.assert_array_equal(got[0].data[name], inkernel[0].data[name], err_msg=name)
    else:
        assert_bits(got, ref)
        assert_bits(inkernel, ref)
    assert eng.fast.compiled_chunks == 12 and eng.fast.fallbacks == 0
    assert_sampled_in_kernel(eng)
    assert eng.fast.threaded_chunks == eng.fast.sampled_calls == 1



THERMOSTATS = {
    "langevin": {"a": "fix a all nve", "b": "fix b all langevin 1.5 1.0 0.5 48279 zero yes tally yes"},
    "nvt": {"a": "fix a all nvt temp 1.5 1.0 0.3"},
    "berendsen": {"a": "fix a all nve", "b": "fix b all temp/berendsen 1.5 1.0 0.2"},
    "rescale": {"a": "fix a all nve", "b": "fix b all temp/rescale 3 1.5 1.0 0.05 0.8"},
    # two langevin fixes on the same atoms, each its own stream: the forces add in fix order
    "two-langevin": {"a": "fix a all nve", "b": "fix b all langevin 1.5 1.0 0.5 48279 zero yes tally yes",
                     "c": "fix c all langevin 0.5 0.5 2.0 977 tally yes"},
}


@pytest.mark.parametrize("kind", sorted(THERMOSTATS))
@pytest.mark.parametrize("thermo", [1, 10])
def test_thermostats_in_the_fused_chunk(monkeypatch, kind, thermo):
    """An LJ liquid between lj93 walls held by a thermostat: the fused chunk runs compiled.py's fix
    kernels (the same draws from the same Langevin streams), so the run gives the per-step path's
    bits (its thermostats are the NumPy Ensemble's), fix nvt to 1e-14 (its chain's exp), with
    ecouple and econserve from the samples the kernel records (every step, or every 10th)."""
    d = every(slit(steps=40), thermo=thermo)
    d["fixes"] = dict(THERMOSTATS[kind])
    d["output"] = {"thermo": ["step", "temp", "pe", "etot", "press", "ecouple", "econserve"]}
    got, fused, ref, _ = run_fused_and_stepwise(monkeypatch, cases_of(d))
    assert isinstance(fused.fast, PairChunks) and fused.fast.fallbacks == 0
    assert_sampled_in_kernel(fused)
    if kind == "nvt":
        for name in got[0].data:
            np.testing.assert_allclose(got[0].data[name], ref[0].data[name], rtol=1e-14, atol=1e-14, err_msg=name)
    else:
        assert_bits(got, ref)
    assert np.ptp(got[0].data["ecouple"]) > 1e-3  # the thermostat exchanged energy
    temp = got[0].data["temp"]
    assert abs(temp[-1] - temp[0]) > 0.05


@pytest.mark.parametrize("thermo", [1, 7])
def test_reflect_walls_in_the_fused_chunk(monkeypatch, thermo):
    """An LJ liquid between wall/reflect faces, one moving with a variable (frame wall: the
    reflected velocity is taken relative to the wall's), with reflect_count and reflect_impulse:
    the fused chunk reflects with compiled.py's `_reflect_face` and records the statistics per
    sample (take_stats), the per-step path's bits."""
    d = every(slit(steps=60), thermo=thermo)
    d["variables"] = {"top": "vdisplace(7.0, -1.0)"}
    d["walls"] = {"r": {"style": "reflect", "units": "box", "frame": "wall", "zlo": 1.6, "zhi": "v_top"}}
    d["output"] = {"thermo": ["step", "temp", "pe", "etot", "press", "reflect_count", "reflect_impulse"]}
    got, fused, ref, _ = run_fused_and_stepwise(monkeypatch, cases_of(d))
    assert_bits(got, ref)
    assert_sampled_in_kernel(fused)
    assert fused.fast.fallbacks == 0
    counts = got[0].data["reflect_count"][1:]
    assert counts.sum(axis=0).min() >= 3 and counts.max() >= 1  # both faces reflected, per sample
    assert np.abs(got[0].data["reflect_impulse"][1:]).sum() > 0


@pytest.mark.parametrize("tabstyle", ["linear", "spline"])
def test_table_walls_in_the_fused_chunk(monkeypatch, tabstyle):
    """An LJ liquid between wall/table faces (the shipped table file: LJ93 below, HARMONIC above),
    sampled every 2 steps: the fused chunk runs compiled.py's table loop (`_table_faces`) and
    records the table energies in the kernel, the per-step path's bits."""
    from pathlib import Path

    table = str(Path(__file__).resolve().parents[2] / "configs" / "tables" / "walls.table")
    d = every(slit(steps=40), thermo=2)
    d["walls"] = {"tab": {"style": "table", "tabstyle": tabstyle, "N": 500, "units": "box", "energy": True,
                          "virial": True,
                          "zlo": {"coord": 0.8, "file": table, "keyword": "LJ93", "cutoff": 2.5},
                          "zhi": {"coord": 7.5, "file": table, "keyword": "HARMONIC", "cutoff": 1.5}}}
    got, fused, ref, _ = run_fused_and_stepwise(monkeypatch, cases_of(d))
    assert_bits(got, ref)
    assert_sampled_in_kernel(fused)
    assert fused.fast.fallbacks == 0
    energy = got[0].data["wall_energy"][1:, 0]
    assert np.ptp(energy) > 0 and np.abs(got[0].data["wall_force"][1:]).min(axis=0).max() > 0


def lepton_slit(thermo: int, b: float = 3.0) -> dict:
    """The LJ slit between wall/lepton faces (LEPTON_LJ93 below, LEPTON_FOUR above with this b)."""
    d = every(slit(steps=60), thermo=thermo)
    four = dict(LEPTON_FOUR, params=dict(LEPTON_FOUR["params"], b=b))
    d["walls"] = {"lep": {"style": "lepton", "units": "box", "energy": True, "virial": True,
                          "zlo": dict(LEPTON_LJ93), "zhi": four}}
    return d


@pytest.mark.parametrize("thermo", [1, 20])
def test_lepton_walls_in_the_fused_chunk(monkeypatch, thermo):
    """An LJ liquid between wall/lepton faces, one with its parameters as arguments of the generated
    force and one with them as an array, two cases (b differs): the fused chunk runs the scene's
    generated forces (compiled.pieces_for with `extra`) and records their energies in the kernel,
    the per-step path's bits (its walls are the NumPy expressions)."""
    monkeypatch.setenv("WALLBATCH_LEPTON_COMPILED", "always")
    got, fused, ref, _ = run_fused_and_stepwise(monkeypatch, cases_of(lepton_slit(thermo), lepton_slit(thermo, 5.0)))
    assert_bits(got, ref)
    assert_sampled_in_kernel(fused)
    assert fused.fast.fallbacks == 0 and fused.fast.compiled_chunks == 60 // thermo
    for res in got:  # both faces act on the liquid
        assert np.all(res.data["wall_force"][1:] != 0.0) and np.ptp(res.data["wall_energy"][1:, 0]) > 0
    assert not np.array_equal(got[0].data["wall_energy"], got[1].data["wall_energy"])


def test_lepton_walls_over_threads(monkeypatch):
    """The same scene with its case cut over threads (`case_parts` 2 here): every part's rest of
    the step runs the generated faces on its atoms, the bits of the one-thread chunk."""
    monkeypatch.setenv("WALLBATCH_LEPTON_COMPILED", "always")
    cases = cases_of(lepton_slit(20))
    one, _, ref, _ = run_fused_and_stepwise(monkeypatch, cases)
    monkeypatch.setattr(pair_compiled, "case_parts", lambda n: 2)
    monkeypatch.setattr(pair_compiled, "THREAD_MIN_USE", 0.0)  # never judged busy (a loaded test machine)
    eng = Engine(cases)
    got = eng.run()
    assert_bits(got, one)
    assert_bits(got, ref)
    assert eng.fast.threaded_chunks >= 1 and eng.fast.fallbacks == 0


@pytest.mark.parametrize("rstyle", ["diffusive", "maxwell", "diffusive+maxwell"])
def test_stochastic_walls_in_the_fused_chunk(monkeypatch, rstyle):
    """An LJ liquid between wall/reflect/stochastic thermal walls (reflect counts and impulses),
    one fix with both faces, or two fixes (a diffusive floor, a Maxwell ceiling, each its seed):
    the fused chunk draws from each fix's streams in NumPy's order (`_stochastic_faces`), the
    per-step path's bits, the statistics recorded per sample in the kernel."""
    d = every(slit(steps=60), thermo=3)
    extra = {"accom": 0.5} if rstyle == "maxwell" else {}
    d["walls"] = {"th": {"style": "reflect/stochastic", "rstyle": rstyle, "seed": 2024, "units": "box",
                         "zlo": {"coord": 1.65, "temp": 1.0, **extra}, "zhi": {"coord": 6.9, "temp": 3.0, **extra}}}
    if rstyle == "diffusive+maxwell":
        d["walls"] = {"lo": {"style": "reflect/stochastic", "rstyle": "diffusive", "seed": 2024, "units": "box",
                             "zlo": {"coord": 1.65, "temp": 1.0}},
                      "hi": {"style": "reflect/stochastic", "rstyle": "maxwell", "seed": 2025, "units": "box",
                             "zhi": {"coord": 6.9, "temp": 3.0, "accom": 0.5}}}
    d["output"] = {"thermo": ["step", "temp", "pe", "etot", "reflect_count", "reflect_impulse"]}
    got, fused, ref, _ = run_fused_and_stepwise(monkeypatch, cases_of(d))
    assert_bits(got, ref)
    assert_sampled_in_kernel(fused)
    assert fused.fast.fallbacks == 0
    counts = got[0].data["reflect_count"][1:]
    assert counts.sum(axis=0).min() >= 3 and counts.max() >= 1


@pytest.mark.parametrize(("every_n", "thermo"), [(1, 1), (3, 5)])
def test_dt_reset_in_the_fused_chunk(monkeypatch, every_n, thermo):
    """fix dt/reset (every 1 and every 3) on an LJ liquid between lj93 walls: the fused chunk
    resets dt in the kernel (each atom's candidate, the group's minimum, the clamp to tmin/tmax),
    closing the time accumulator as BatchState.set_dt does: the same dt, time and outputs as the
    per-step path, bit for bit, and the run's end state (dt, atime) the same."""
    d = every(slit(steps=30, temperature=3.0), thermo=thermo)
    d["dt_reset"] = {"every": every_n, "xmax": 0.02, "tmin": 0.0005, "tmax": 0.006, "units": "box"}
    d["output"] = {"thermo": ["step", "time", "dt", "temp", "pe", "etot", "press"]}
    got, fused, ref, step = run_fused_and_stepwise(monkeypatch, cases_of(d))
    assert_bits(got, ref)
    assert_sampled_in_kernel(fused)
    assert fused.fast.fallbacks == 0
    dt = got[0].data["dt"]
    assert np.unique(dt).size >= 3 and dt.min() >= 0.0005 and dt.max() <= 0.006  # dt did change
    for name in ("dt", "atime", "atimestep", "step"):
        np.testing.assert_array_equal(getattr(fused.state, name), getattr(step.state, name), err_msg=name)


def liquid_2d() -> dict:
    """A 2-D LJ liquid (dimension 2: enforce2d among the fixes, z left out of the pair's minimum
    image) of 60 atoms in a channel between lj93 walls at the y edges, sampled every 2nd step."""
    rng = np.random.default_rng(4)
    side = np.arange(0.6, 11.0, 1.1)
    x = np.array([[a, b, 0.0] for a in side for b in np.arange(1.6, 8.0, 1.1)])
    x += rng.uniform(-0.05, 0.05, (1, 3)) * [1, 1, 0]
    return {"name": "lj-2d", "units": "lj", "seed": 9, "dimension": 2,
            "box": {"lo": [0, 0, -0.5], "hi": [11.0, 9.5, 0.5], "boundary": ["p", "f", "p"]},
            "atoms": [{"group": "fluid", "create": {"positions": x.tolist()}, "mass": 1.0,
                       "velocity": {"temperature": 1.5}}],
            "pair": {"style": "lj/cut", "epsilon": 1.0, "sigma": 1.0, "cutoff": 2.5},
            "walls": {"w": {"style": "lj93", "units": "box", "energy": True, "ylo": list(WALL), "yhi": list(WALL)}},
            "timestep": 0.004, "run": {"steps": 60, "thermo": 2},
            "output": {"thermo": ["step", "temp", "pe", "etot"]}}


def test_two_dimensional_liquid_in_the_fused_chunk(monkeypatch):
    """The 2-D liquid (`liquid_2d`): the fused chunk gives the per-step path's bits, and every atom
    stays in the plane."""
    got, fused, ref, _ = run_fused_and_stepwise(monkeypatch, cases_of(liquid_2d()))
    assert_bits(got, ref)
    assert_sampled_in_kernel(fused)
    assert fused.fast.fallbacks == 0
    assert [f.style for f in fused.ensemble.fixes if f.style == "enforce2d"] == ["enforce2d"]
    assert np.all(fused.state.x[..., 2] == 0.0) and np.all(fused.state.v[..., 2] == 0.0)
    assert np.ptp(got[0].data["pe"]) > 0.1


def test_sample_budget_splits_the_sampled_chunks(monkeypatch):
    """The samples a fused chunk records are bounded by compiled.SAMPLE_BUDGET through the flat
    chunks' own rule (FastPath.sample_steps, plus the pair's energy and virial): 12 doubles a
    sample for two reflect faces with statistics. With a budget of one sample per call, the 60
    samples take 60 calls, reflect statistics handed on from call to call, the per-step bits."""
    from wallbatch.engine import compiled

    d = every(slit(steps=60), thermo=1)
    d["walls"] = {"r": {"style": "reflect", "units": "box", "zlo": 1.6, "zhi": 6.6}}
    d["output"] = {"thermo": ["step", "temp", "pe", "etot", "press", "reflect_count", "reflect_impulse"]}
    cases = cases_of(d)
    monkeypatch.setenv("WALLBATCH_NUMBA", "1")
    eng = Engine(cases)
    plan = eng.fast.plan_source()
    assert compiled.FastPath.sample_steps(plan, extra=2) == compiled.SAMPLE_BUDGET // 12
    monkeypatch.setattr(compiled, "SAMPLE_BUDGET", 12)
    assert compiled.FastPath.sample_steps(plan, extra=2) == 1
    got, fused, ref, _ = run_fused_and_stepwise(monkeypatch, cases)
    assert_bits(got, ref)
    assert fused.fast.fallbacks == 0 and fused.fast.sampled_calls == 60
    assert got[0].data["reflect_count"][1:].sum() >= 3


def timed_slit(dt: float) -> dict:
    """The slit run to a simulated time sampled at times (run: {time: ...}): intervals that are
    not whole steps, so each ends with a clipped, landing step."""
    d = slit(steps=1)
    d["timestep"] = dt
    d["run"] = {"time": 0.3, "thermo": {"time": 0.1}}
    d["output"] = {"thermo": ["step", "time", "dt", "temp", "pe", "etot", "press"]}
    return d


def test_time_based_run_fuses_the_steps_before_each_landing(monkeypatch):
    """A run to a simulated time, two cases of different timesteps in one batch: the steps before
    each interval's landing step run in fused chunks, the landing steps in the NumPy loop; every
    output (time, dt, step too) is the per-step path's, bit for bit."""
    cases = cases_of(timed_slit(0.0045), timed_slit(0.007))
    got, fused, ref, step = run_fused_and_stepwise(monkeypatch, cases)
    assert_bits(got, ref)
    assert fused.fast.compiled_chunks == 3 and fused.fast.fallbacks == 0  # one chunk per interval
    # 0.1 / 0.0045 = 22.2: 22 steps, the 23rd lands; 0.1 / 0.007 = 14.3: the 15th lands, so the
    # batch fuses min(22, 14) = 14 steps of each interval, then the loop finishes both cases
    steps = [r.data["step"] for r in got]
    np.testing.assert_array_equal(steps[0], [0, 23, 46, 69])
    np.testing.assert_array_equal(steps[1], [0, 15, 30, 45])
    np.testing.assert_allclose([r.data["time"] for r in got], [[0, 0.1, 0.2, 0.3]] * 2, rtol=0, atol=1e-14)
    assert np.all(fused.pair.case_builds >= 1)


def test_steps_before_counts_the_unclipped_steps_exactly():
    """`steps_before` against the loop's own test, step by step, for times near the edges."""
    rng = np.random.default_rng(5)
    for _ in range(200):
        dt = float(rng.uniform(1e-4, 0.1))
        atime, base = float(rng.uniform(0, 5)), int(rng.integers(0, 50))
        target = atime + base * dt + float(rng.choice([rng.uniform(0, 3), dt * rng.integers(0, 40)]))
        tol = 1e-12 * max(1.0, abs(target))
        k = 0
        while True:  # Engine.advance_to_time's own conditions, one step at a time
            now = np.float64(atime) + np.int64(base + k) * np.float64(dt)
            if not (now < target - tol and not dt >= target - now - tol):
                break
            k += 1
        got = pair_compiled.steps_before(np.array([atime]), np.array([base + 7]), np.array([7]), np.array([dt]),
                                         target)
        assert got == k, (dt, atime, base, target)
    two = pair_compiled.steps_before(np.zeros(2), np.zeros(2, np.int64), np.zeros(2, np.int64),
                                     np.array([0.01, 0.03]), 0.1)
    assert two == 3  # 0.1 / 0.03: steps 1-3 end at 0.03, 0.06, 0.09; the 4th lands (clipped)
    assert pair_compiled.steps_before(np.zeros(1), np.zeros(1, np.int64), np.zeros(1, np.int64), np.zeros(1),
                                      0.1) == 0  # dt 0 never lands: nothing fused (no endless count)


def test_time_based_run_with_a_ramped_berendsen_is_fused(monkeypatch):
    """In a run to a simulated time a thermostat's target ramps with the time (time / run time):
    the fused chunks take it from the case's clock and give the per-step path's bits; the gas
    cools along the ramp (from 2 towards 1.5 .. 1.0)."""
    d = timed_slit(0.005)
    d["fixes"] = dict(THERMOSTATS["berendsen"])
    got, fused, ref, _ = run_fused_and_stepwise(monkeypatch, cases_of(d))
    assert_bits(got, ref)
    assert fused.fast.compiled_chunks == 3 and fused.fast.fallbacks == 0
    assert got[0].data["temp"][-1] < 1.7


@pytest.mark.parametrize("in_kernel", [True, False])
@pytest.mark.parametrize("scene", ["slit", "flow"])
def test_long_chunks_take_several_kernel_calls_with_the_same_bits(monkeypatch, scene, in_kernel):
    """A chunk longer than its share of compiled.CALL_WORK (an atom-step counted PAIR_STEP_COST
    times) runs as several kernel calls, so a Ctrl-C between them stops the run soon. Each call
    hands the list, its reference positions and the flow walls' state to the next: the results
    and the list builds are those of one call per chunk, bit for bit."""
    from wallbatch.engine import compiled

    configs = {"slit": [slit(1.0), slit(1.3)], "flow": [flow_fluid("exact")]}[scene]
    if in_kernel:
        configs = [every(d, thermo=d["run"]["thermo"]) for d in configs]
    cases = cases_of(*configs)
    monkeypatch.setenv("WALLBATCH_NUMBA", "1")
    if not in_kernel:
        monkeypatch.setattr(PairChunks, "samples_in_kernel", lambda self, at: False)
    calls = []
    real = PairChunks._chunk
    monkeypatch.setattr(PairChunks, "_chunk", lambda self, n, *a: (calls.append(n), real(self, n, *a))[1])
    whole = Engine(cases)
    got_whole = whole.run()
    thermo, steps = configs[0]["run"]["thermo"], configs[0]["run"]["steps"]
    # one call for all the samples, or one per sample's chunk
    assert calls == ([steps] if in_kernel else [thermo] * (steps // thermo)) and whole.fast.fallbacks == 0
    calls.clear()
    natoms = whole.state.x.shape[1]
    monkeypatch.setattr(compiled, "CALL_WORK", compiled.PAIR_STEP_COST * len(cases) * natoms * 3)  # 3 steps a call
    monkeypatch.setattr(PairChunks, "least_steps", 1)  # (not PAIR_MIN_CALL_STEPS)
    split = Engine(cases)
    got_split = split.run()
    # calls of 3 steps at most; with samples in the kernel, a sample's call runs the last 3 steps
    # before it, the steps before those go first in calls of their own (Engine.run: `lead_steps`)
    def threes(n: int) -> list[int]:
        return [3] * (n // 3) + [n % 3] * (n % 3 > 0)

    assert calls == (threes(thermo - 3) + [3] if in_kernel else threes(thermo)) * (steps // thermo)
    assert split.fast.sampled_calls == (steps // thermo if in_kernel else 0)
    assert_bits(got_split, got_whole)
    np.testing.assert_array_equal(split.pair.case_builds, whole.pair.case_builds)
    assert whole.pair.case_builds.min() >= 2 and split.fast.fallbacks == 0


@pytest.mark.parametrize("fix", ["fix t all langevin 2.0 3.0 0.5 6211 tally yes", "fix t all nvt temp 2.0 3.0 0.1"])
def test_thermostat_in_a_run_to_a_time_fuses_the_steps_before_each_landing(monkeypatch, fix):
    """`timed_slit`'s two cases with a thermostat whose target ramps 2 -> 3: the ramp follows the
    time (time / run time), which the fused steps take from the case's clock; every output is the
    per-step path's, bit for bit, with one fused chunk per interval."""
    cases = []
    for dt in (0.0045, 0.007):
        d = timed_slit(dt)
        d["fixes"] = {"i": "fix i all nve", "t": fix} if "langevin" in fix else {"t": fix}
        d["output"]["thermo"] += ["ecouple", "econserve"]
        cases.append(d)
    got, fused, ref, _ = run_fused_and_stepwise(monkeypatch, cases_of(*cases))
    assert_bits(got, ref)
    assert fused.fast.compiled_chunks == 3 and fused.fast.fallbacks == 0
    assert np.ptp(got[0].data["ecouple"]) > 0


@pytest.mark.parametrize("kind", ["langevin", "nvt", "berendsen", "rescale"])
def test_thermostat_with_dt_reset_in_the_fused_chunk(monkeypatch, kind):
    """fix dt/reset every step with each thermostat on the LJ liquid: the fused chunk resets dt
    from the velocities the thermostats left (Engine.step's order); the per-step path's bits on
    every output, dt and time included, and dt did change."""
    d = every(slit(steps=30, temperature=3.0), thermo=3)
    d["fixes"] = dict(THERMOSTATS[kind])
    d["dt_reset"] = {"every": 1, "xmax": 0.02, "tmin": 0.0005, "tmax": 0.006, "units": "box"}
    d["output"] = {"thermo": ["step", "time", "dt", "temp", "pe", "etot", "ecouple"]}
    got, fused, ref, _ = run_fused_and_stepwise(monkeypatch, cases_of(d))
    assert_bits(got, ref)
    assert fused.fast.compiled_chunks > 0 and fused.fast.fallbacks == 0
    assert np.unique(got[0].data["dt"]).size >= 3


@pytest.mark.parametrize("kind", ["langevin", "nvt", "berendsen"])
def test_thermostat_with_flow_walls_in_the_fused_chunk(monkeypatch, kind):
    """The LJ fluid between wall/flow walls with each thermostat: the thermostats' end of step,
    then the flow walls' redraws, in the kernel; the per-step path's bits."""
    d = flow_fluid("exact")
    d["fixes"] = dict(THERMOSTATS[kind])
    d["output"] = {"thermo": ["step", "temp", "pe", "etot", "ecouple", "flow_crossings"]}
    got, fused, ref, _ = run_fused_and_stepwise(monkeypatch, cases_of(d))
    assert_bits(got, ref)
    assert fused.fast.compiled_chunks > 0 and fused.fast.fallbacks == 0
    assert got[0].data["flow_crossings"][1:].sum() > 5


def frozen_post(fixes: dict) -> dict:
    """An LJ fluid (~150 atoms, periodic) around a frozen post: a column of 12 atoms that no
    integrator moves (fix nve on the fluid only), sampled every 10 steps."""
    post = [[5.0 + 0.9 * i, 3.0 + 0.9 * j, 0.5 + 1.0 * k] for i in range(2) for j in range(2) for k in range(3)]
    d = flow_fluid("exact")
    del d["walls"]
    d["atoms"] = [{"group": "post", "mass": 1.0, "create": {"positions": post}, "velocity": {"values": [0.2, 0, 0]}},
                  *d["atoms"]]
    d["fixes"] = fixes
    d["run"] = {"steps": 120, "thermo": 10}
    d["output"] = {"thermo": ["step", "temp", "ke", "pe", "etot", "ecouple"],
                   "dump": {"every": 60, "fields": ["x", "v"]}}
    return d


def test_two_nvt_fixes_in_the_fused_chunk(monkeypatch):
    """Two Nose-Hoover chains on two groups of an LJ fluid (the fluid ramped from 1.5 to 1.0, the
    post held at 0.5 with a chain of 2): the fused chunk keeps the chains side by side, each its
    length, and gives the per-step path's outputs (ecouple included) to 1e-14 (the chains' exp)."""
    case = cases_of(frozen_post({"t": "fix t fluid nvt temp 1.5 1.0 0.1",
                                 "p": "fix p post nvt temp 0.5 0.5 0.2 tchain 2"}))
    got, fused, ref, _ = run_fused_and_stepwise(monkeypatch, case)
    assert isinstance(fused.fast, PairChunks) and fused.fast.compiled_chunks > 0 and fused.fast.fallbacks == 0
    for name in got[0].data:
        np.testing.assert_allclose(got[0].data[name], ref[0].data[name], rtol=1e-14, atol=1e-14, err_msg=name)
    assert [f.chain.eta.shape[1] for f in fused.ensemble.nvt] == [3, 2]
    assert np.ptp(got[0].data["ecouple"]) > 1e-3


@pytest.mark.parametrize("fixes", [{"i": "fix i fluid nve"},
                                   {"i": "fix i fluid nve", "t": "fix t fluid langevin 1.5 1.5 0.5 77 tally yes"},
                                   {"t": "fix t fluid nvt temp 1.5 1.0 0.1"}])
def test_frozen_atoms_in_the_fused_chunk(monkeypatch, fixes):
    """Atoms outside every integrator's group (a frozen post in the fluid): the fused chunk
    integrates the others only; the per-step path's bits on every output and frame, and the post
    keeps its positions and velocities to the bit while the fluid moves."""
    case = cases_of(frozen_post(fixes))
    got, fused, ref, _ = run_fused_and_stepwise(monkeypatch, case)
    assert_bits(got, ref)
    for name in ("x", "v"):
        np.testing.assert_array_equal(got[0].frames[name], ref[0].frames[name], err_msg=name)
    assert fused.fast.compiled_chunks > 0 and fused.fast.fallbacks == 0
    x, v = got[0].frames["x"], got[0].frames["v"]
    assert np.array_equal(x[:, :12], np.broadcast_to(case[0].x[:12], x[:, :12].shape))
    assert np.array_equal(v[:, :12], np.broadcast_to(case[0].v[:12], v[:, :12].shape))
    assert np.abs(x[-1, 12:] - x[0, 12:]).max() > 0.05
