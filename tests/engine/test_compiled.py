"""The compiled path (wallbatch.engine.compiled) against the NumPy engine, its reference.

Every scene runs twice, with WALLBATCH_NUMBA=0 (NumPy) and =1 (numba), and every sampled output
of every case must agree to 1e-14 relative (per series, against its largest magnitude), with the
same status and the same failure message. Each test also checks that the compiled path really ran
(or, for the scenes it must refuse, that it did not), so a silent fallback cannot pass.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from factories import assert_same_results, run_numpy_and_compiled, slab_gas

from wallbatch.engine import compiled as fast
from wallbatch.config.models import config_from_dict
from wallbatch.engine.engine import Engine
from wallbatch.scene.case import structure_key
from wallbatch.styles.flat import STYLES
from wallbatch.scene.build import build_case

pytestmark = pytest.mark.skipif(fast.njit is None, reason="numba not importable")

RTOL = 1e-14


# ----------------------------------------------------------------------------- helpers


def gas(walls, *, n=40, steps=300, thermo=50, dt=0.005, hi=(6.0, 6.0, 8.0), seed=5, temperature=1.5,
        output=None, **extra):
    """n atoms in a slab (x, y periodic, z fixed), no pair forces."""
    return slab_gas(walls, n=n, hi=hi, margin=1.6, temperature=temperature, seed=seed, dt=dt, steps=steps,
                    thermo=thermo, output=output, **extra)


def face(coord, eps=1.0, sigma=1.0, rc=2.5):
    return {"coord": coord, "epsilon": eps, "sigma": sigma, "cutoff": rc}


run_both = run_numpy_and_compiled


def assert_same(ref, got):
    assert_same_results(ref, got, RTOL)


def check(monkeypatch, configs, *, compiled=True):
    """Run the configs as one batch both ways; assert agreement and whether chunks ran compiled."""
    cases = [build_case(config_from_dict(d)) for d in configs]
    assert len({structure_key(c) for c in cases}) == 1  # one batch, as run_cases would make it
    ref, got, eng = run_both(monkeypatch, cases)
    assert_same(ref, got)
    if compiled:
        assert eng.fast is not None and eng.fast.compiled_chunks > 0
    return ref, got, eng


# ----------------------------------------------------------------------------- the formulas


STYLE_PARAMS = {
    "lj93": {"epsilon": 1.3, "sigma": 0.9, "cutoff": 2.5},
    "lj126": {"epsilon": 0.7, "sigma": 1.1, "cutoff": 2.5},
    "lj1043": {"epsilon": 1.1, "sigma": 1.0, "cutoff": 3.0},
    "colloid": {"epsilon": 2.0, "sigma": 1.0, "cutoff": 4.0, "radius": 0.8},
    "harmonic": {"epsilon": 3.0, "sigma": 1.0, "cutoff": 1.5},
    "morse": {"D0": 0.8, "alpha": 1.7, "r0": 1.2, "cutoff": 3.0},
}


@pytest.mark.parametrize("style", sorted(STYLE_PARAMS))
def test_compiled_forces_match_potentials(style):
    """The compiled force is the registry's own F(r), jit-compiled: same value to 1e-14 over the range."""
    p = STYLE_PARAMS[style]
    lo = p.get("radius", 0.0) + 0.05
    r = np.linspace(lo, p["cutoff"], 257)
    want = STYLES[style].energy_force(r, {k: np.full_like(r, v) for k, v in p.items()})[1]
    keys = ("D0", "alpha", "r0") if style == "morse" else ("epsilon", "sigma", "sigma")
    force = fast.FORCES[fast.STYLE_IDS[style]]  # the registry's own function, compiled
    got = np.array([force(float(ri), p[keys[0]], p[keys[1]], p[keys[2]], p["cutoff"], p.get("radius", 0.0))
                    for ri in r])
    np.testing.assert_allclose(got, want, rtol=RTOL, atol=RTOL * np.abs(want).max())


# ----------------------------------------------------------------------------- styles, reflect, groups


STYLE_SCENES = {
    "lj93": lambda: {"w": {"style": "lj93", "units": "box", "energy": True,
                           "zlo": face("EDGE"), "zhi": face("EDGE", eps=2.0, sigma=0.9)}},
    "lj126": lambda: {"w": {"style": "lj126", "units": "box", "zlo": face(0.0, rc=1.5), "zhi": face(8.0, rc=2.0)}},
    "lj1043": lambda: {"w": {"style": "lj1043", "units": "box", "zlo": face(0.0, rc=3.0), "zhi": face(8.0)}},
    "harmonic": lambda: {"w": {"style": "harmonic", "units": "box",
                               "zlo": {"coord": 0.0, "epsilon": 20.0, "cutoff": 1.5},
                               "zhi": {"coord": 8.0, "epsilon": 10.0, "cutoff": 1.5}}},
    "morse": lambda: {"w": {"style": "morse", "units": "box",
                            "zlo": {"coord": 0.0, "D0": 1.0, "alpha": 2.0, "r0": 1.2, "cutoff": 3.0},
                            "zhi": {"coord": 8.0, "D0": 0.5, "alpha": 1.5, "r0": 1.1, "cutoff": 2.5}}},
}


@pytest.mark.parametrize("style", sorted(STYLE_SCENES))
def test_each_style_matches_numpy(monkeypatch, style):
    _, got, eng = check(monkeypatch, [gas(STYLE_SCENES[style](), output=["step", "time", "ke", "pe", "etot"])])
    assert eng.fast.fallbacks == 0
    assert got[0].status == "ok"
    assert np.any(got[0].data["wall_force"][1:] != 0.0)  # atoms did reach the walls


def test_colloid_matches_numpy(monkeypatch):
    d = gas({"w": {"style": "colloid", "units": "box", "zlo": face(0.0, rc=3.0), "zhi": face(8.0, rc=3.0)}})
    d["atoms"][0]["radius"] = 0.6
    _, got, _ = check(monkeypatch, [d])
    assert got[0].status == "ok"


def test_several_walls_groups_and_styles_in_one_scene(monkeypatch):
    """Two wall fixes on different groups, plus a reflect wall on one group (lj93 and lj1043: the
    kernel of tests/lammps/test_hard_cases.py's cut-off and reflect scene)."""
    d = gas({"a": {"style": "lj93", "units": "box", "group": "fast", "zlo": face(0.0), "zhi": face(8.0)},
             "b": {"style": "lj1043", "units": "box", "group": "slow", "zlo": face(0.2, eps=2.0, rc=3.0)},
             "r": {"style": "reflect", "units": "box", "group": "slow", "zhi": 6.5}},
            output=["step", "ke", "pe", "reflect_count", "reflect_impulse"], steps=400, thermo=100)
    d["box"]["boundary"] = ["p", "p", "f"]
    d["atoms"] = [
        {"group": "fast", "create": {"random": {"count": 25, "region": "mid"}}, "mass": 1.0,
         "velocity": {"temperature": 2.0}},
        {"group": "slow", "create": {"random": {"count": 15, "region": "mid"}}, "mass": 3.0,
         "velocity": {"temperature": 2.0}},
    ]
    _, got, _ = check(monkeypatch, [d])
    assert got[0].status == "ok"
    assert got[0].data["reflect_count"].sum() > 0
    assert np.count_nonzero(got[0].data["wall_force"][1:, 2]) > 0  # the lj1043 face acted


@pytest.mark.parametrize("frame, thermo", [("lab", 80), ("wall", 80), ("wall", 1)])
def test_reflect_moving_walls_both_frames(monkeypatch, frame, thermo):
    """thermo 1: every step is the first of a chunk, where the wall velocity uses the position the
    previous chunk left behind."""
    walls = {"r": {"style": "reflect", "units": "box", "frame": frame, "zlo": "v_lo", "zhi": "EDGE"}}
    d = gas(walls, variables={"lo": "swiggle(1.0, 0.6, 0.4)"}, steps=400 if thermo > 1 else 150, thermo=thermo,
            n=80, output=["step", "time", "ke", "reflect_count", "reflect_impulse"])
    _, got, eng = check(monkeypatch, [d])
    assert eng.fast.fallbacks == 0
    assert got[0].data["reflect_count"][1:].sum() > (10 if thermo > 1 else 3)


@pytest.mark.parametrize("frame, pbc", [("lab", False), ("wall", False), ("lab", True)])
def test_reflect_without_statistics_final_state_bit_for_bit(monkeypatch, frame, pbc):
    """Reflect faces without reflect outputs (the kernel's branch-free pass) on a group, moving
    (frame wall) or on a periodic x dimension (pbc: the wrap then stays after the reflect):
    positions and velocities at the end equal the NumPy engine's bit for bit, and atoms were
    reflected (the wall frame's 2 v_wall - v changes the kinetic energy)."""
    walls = {"r": {"style": "reflect", "units": "box", "frame": frame, "group": "slow", "zlo": "v_lo", "zhi": 6.9},
             "s": {"style": "reflect", "units": "box", "zlo": 0.3, "zhi": 7.7}}
    if pbc:
        walls["x"] = {"style": "reflect", "units": "box", "pbc": True, "xlo": 0.4, "xhi": 5.1}
    d = gas(walls, variables={"lo": "swiggle(1.0, 0.6, 0.4)"}, steps=400, thermo=100, n=60,
            output=["step", "ke"])
    d["atoms"] = [{"group": g, "create": {"random": {"count": 30, "region": "mid"}}, "mass": m,
                   "velocity": {"temperature": 2.0}} for g, m in (("fast", 1.0), ("slow", 3.0))]
    cases = [build_case(config_from_dict(d))]
    monkeypatch.setenv("WALLBATCH_NUMBA", "0")
    ref = Engine(cases)
    ref_res = ref.run()
    monkeypatch.setenv("WALLBATCH_NUMBA", "1")
    eng = Engine(cases)
    res = eng.run()
    assert eng.fast.compiled_chunks > 0 and eng.fast.fallbacks == 0
    assert_same_results(ref_res, res)  # bit for bit
    assert np.array_equal(eng.state.x, ref.state.x) and np.array_equal(eng.state.v, ref.state.v)
    c0, x, v = cases[0], eng.state.x[0], eng.state.v[0]
    free = c0.x[:, 2] + c0.v[:, 2] * (400 * 0.005)  # where the atoms would be without walls
    assert np.count_nonzero((free < 0.3) | (free > 7.7)) > 5  # so many were reflected
    assert np.all(x[:, 2] >= 0.3) and np.all(x[:, 2] <= 7.7) and np.all(x[30:, 2] <= 6.9)
    moved = not np.array_equal(np.abs(v[30:, 2]), np.abs(c0.v[30:, 2]))  # |v_z| changes only off a moving wall
    assert moved == (frame == "wall")
    if pbc:
        assert np.all((x[:, 0] >= 0.4) & (x[:, 0] <= 5.1))


# ----------------------------------------------------------------------------- variables and batches


def test_time_dependent_variables_and_per_case_constants(monkeypatch):
    """A wall moving with vdisplace, epsilon ramping with the run, a constant swept per case."""
    def cfg(k):
        walls = {"w": {"style": "lj93", "units": "box", "energy": True,
                       "zlo": {"coord": "v_lo", "epsilon": "v_eps", "sigma": 1.0, "cutoff": 2.5},
                       "zhi": {"coord": 8.0, "epsilon": "v_k", "sigma": 1.0, "cutoff": 2.5}}}
        return gas(walls, variables={"lo": "vdisplace(0.0, 0.4)", "eps": "ramp(0.5, 2.0)", "k": k},
                   steps=250, thermo=50)
    _, got, eng = check(monkeypatch, [cfg(1.0), cfg(1.7), cfg(0.4)])
    assert eng.fast.fallbacks == 0 and [r.status for r in got] == ["ok"] * 3


def test_long_varying_chunk_is_split(monkeypatch):
    """Per-step values of a long chunk are computed a few steps at a time (VALUE_BUDGET)."""
    monkeypatch.setattr(fast, "VALUE_BUDGET", 300)
    walls = {"w": {"style": "harmonic", "units": "box",
                   "zlo": {"coord": "v_lo", "epsilon": 20.0, "cutoff": 1.5}, "zhi": face(8.0)}}
    _, _, eng = check(monkeypatch, [gas(walls, variables={"lo": "cwiggle(0.0, 0.5, 0.3)"}, steps=200, thermo=100)])
    assert eng.fast.compiled_chunks > 2  # more sub-chunks than samples


def test_sweep_batch_with_mixed_failures(monkeypatch):
    """Cases of one batch: two fine, one with a zero-strength wall inside the gas (an atom crosses
    it mid-run), one with a huge timestep. Same statuses, messages and numbers both ways."""
    def cfg(coord, eps=1.0, dt=0.005):
        return gas({"w": {"style": "lj93", "units": "box", "zlo": {"coord": coord, "epsilon": eps, "sigma": 1.0,
                                                                    "cutoff": 2.5}, "zhi": face(8.0)}},
                   dt=dt, steps=300, thermo=20)
    configs = [cfg(0.0), cfg(0.3), cfg(1.5, eps=0.0), cfg(0.0, dt=0.4)]
    _, got, eng = check(monkeypatch, configs)
    assert [r.status for r in got] == ["ok", "ok", "failed", "failed"]
    assert "(wall/lj93 zlo)" in got[2].error
    assert int(got[2].error.split(" at step ")[1].split(":")[0]) > 20  # mid-run, after a compiled chunk
    assert eng.fast.fallbacks >= 1  # a chunk with trouble went back to NumPy, the later ones did not
    assert eng.fast.compiled_chunks >= 3


def test_lost_atom_message_is_the_numpy_one(monkeypatch):
    d = gas({"w": {"style": "lj93", "units": "box", "zlo": face(0.0)}}, steps=400, thermo=100, temperature=4.0)
    ref, got, eng = check(monkeypatch, [d], compiled=False)
    assert got[0].status == "failed" and "Lost atoms" in got[0].error
    assert eng.fast.fallbacks >= 1


# ----------------------------------------------------------------------------- dt/reset and time-based runs


def dt_reset_scene(**run):
    d = gas({"w": {"style": "lj93", "units": "box", "energy": True, "zlo": face(0.0), "zhi": face(8.0)}},
            output=["step", "time", "dt", "ke", "pe", "etot"])
    d["atoms"].append({"group": "close", "create": {"positions": [[2.0, 2.0, 0.55], [4.0, 4.0, 7.5]]},
                       "mass": 2.0})
    d["dt_reset"] = {"every": 2, "tmin": 1.0e-5, "tmax": 0.01, "xmax": 0.02, "emax": 0.5, "units": "box",
                     "group": "gas"}
    d["run"] = run
    return d


def test_dt_reset_step_based(monkeypatch):
    d = dt_reset_scene(steps=300, thermo=60)
    del d["dt_reset"]["group"]  # all atoms: the close ones set dt while they are pushed away
    _, got, eng = check(monkeypatch, [d])
    assert eng.fast.fallbacks == 0
    assert len(np.unique(got[0].data["dt"])) > 2  # dt really changed


def test_dt_reset_time_based(monkeypatch):
    _, got, eng = check(monkeypatch, [dt_reset_scene(time=1.0, thermo={"time": 0.25})])
    assert eng.fast.fallbacks == 0
    assert got[0].data["time"].tolist() == [0.0, 0.25, 0.5, 0.75, 1.0]


def test_time_based_run_batch_with_different_timesteps(monkeypatch):
    """Cases land on each sample time after different numbers of steps (clipped last step)."""
    configs = []
    for dt in (0.003, 0.007, 0.011):
        d = gas({"w": {"style": "lj93", "units": "box", "zlo": face(0.0), "zhi": face(8.0, rc=1.5)}}, dt=dt,
                output=["step", "time", "dt", "ke"])  # the kernel of the other time-based lj93 slits
        d["run"] = {"time": 0.6, "thermo": {"time": 0.2}}
        configs.append(d)
    _, got, eng = check(monkeypatch, configs)
    assert eng.fast.fallbacks == 0
    assert [r.data["step"][-1] for r in got] == [3 * math.ceil(0.2 / dt) for dt in (0.003, 0.007, 0.011)]


def test_time_dependent_variable_in_time_based_run_stays_in_numpy(monkeypatch):
    """Per-step values cannot be precomputed when the step's dt is clipped: NumPy runs it."""
    d = gas({"w": {"style": "harmonic", "units": "box",
                   "zlo": {"coord": "v_lo", "epsilon": 20.0, "cutoff": 1.5}, "zhi": face(8.0)}},
            variables={"lo": "vdisplace(0.0, 0.3)"})
    d["run"] = {"time": 0.5, "thermo": {"time": 0.25}}
    _, _, eng = check(monkeypatch, [d], compiled=False)
    assert eng.fast.compiled_chunks == 0


# ----------------------------------------------------------------------------- selection


def test_switch_and_whitelist(monkeypatch):
    case = build_case(config_from_dict(gas({"w": {"style": "lj93", "units": "box", "zlo": face(0.0)}}, steps=10)))
    monkeypatch.setenv("WALLBATCH_NUMBA", "0")
    assert Engine([case]).fast is None
    monkeypatch.setenv("WALLBATCH_NUMBA", "1")
    eng = Engine([case])
    assert eng.fast is not None
    eng.setup()
    eng.pair = object()  # a feature the kernel does not know: the NumPy loop must run the chunk
    assert not eng.fast.advance(5, True)
    eng.pair = None
    eng.state.quat = np.zeros((1, case.natoms, 4))
    assert not eng.fast.advance(5, True)
    eng.state.quat = None
    assert eng.fast.advance(5, True) and eng.state.step[0] == 5
    monkeypatch.setattr(fast, "njit", None)  # numba missing: NumPy everywhere
    assert Engine([case]).fast is None


def test_variable_error_and_negative_parameter_fall_back(monkeypatch):
    """A variable that divides by zero at step 40, an epsilon that turns negative at step 120:
    the NumPy loop reports both with its own messages."""
    def cfg(expr_lo, expr_eps):
        return gas({"w": {"style": "lj93", "units": "box",
                          "zlo": {"coord": "v_lo", "epsilon": "v_eps", "sigma": 1.0, "cutoff": 2.5},
                          "zhi": face(8.0)}},
                   variables={"lo": expr_lo, "eps": expr_eps}, steps=200, thermo=50)
    _, got, _ = check(monkeypatch, [cfg("0.1/(step-40)", "1.0")], compiled=False)
    assert got[0].status == "failed" and "Divide by 0" in got[0].error and "step 40" in got[0].error
    _, got, _ = check(monkeypatch, [cfg("0.0", "1.0 - step/120")], compiled=False)
    assert got[0].status == "failed" and "evaluated to" in got[0].error and "< 0" in got[0].error


def test_real_units_and_masses(monkeypatch):
    """ftm2v != 1: real units, two masses, lj1043 with per-face parameters."""
    d = gas({"w": {"style": "lj1043", "units": "box", "zlo": face(0.0, eps=0.2, sigma=3.0, rc=9.0),
                   "zhi": face(30.0, eps=0.3, sigma=3.2, rc=9.0)}},
            hi=(20.0, 20.0, 30.0), dt=2.0, temperature=300.0, steps=300, thermo=100, units="real")
    d["regions"]["mid"] = {"style": "block", "lo": [0, 0, 4.0], "hi": [20, 20, 26.0], "units": "box"}
    d["atoms"][0]["mass"] = 39.9
    _, got, _ = check(monkeypatch, [d])
    assert got[0].status == "ok" and math.isfinite(got[0].data["ke"][-1])


def test_one_compiled_signature(monkeypatch):
    """Every scene above runs the same compiled specialisation of the kernel (a new one would cost a
    full compilation): array layouts and argument types do not depend on the scene."""
    _, _, eng = check(monkeypatch, [gas(STYLE_SCENES["lj93"](), steps=20, thermo=10)])
    kernel = fast.kernel_for(((fast.STYLE_IDS["lj93"], 0),), fixes=False, dtr=False, reflect=False, time=False,
                             sampled=True)
    assert eng.fast.kernel is kernel and len(kernel.signatures) == 1


def test_a_case_sent_to_a_worker_still_runs_compiled():
    """Workers receive pickled cases: their style entries are copies of the registry's, and the
    compiled path must still take them (it once fell back to NumPy, 100x slower, under --jobs 2)."""
    import pickle

    from wallbatch.config.models import config_from_dict as _cfg
    from wallbatch.engine.engine import Engine as _Engine
    from wallbatch.scene.build import build_case as _build

    d = {"name": "p", "seed": 1, "box": {"lo": [0, 0, 0], "hi": [6, 6, 10], "boundary": ["p", "p", "f"]},
         "atoms": [{"group": "g", "create": {"positions": [[3, 3, 5], [2, 2, 3]]}, "mass": 1.0}],
         "regions": {"ball": {"style": "sphere", "center": [3, 3, 5], "radius": 4.5, "units": "box"}},
         "walls": {"w": {"style": "lj93", "units": "box", "zlo": [0.0, 1.0, 1.0, 2.5], "zhi": [10.0, 1.0, 1.0, 2.5]},
                   "r": {"style": "region", "region": "ball", "potential": "harmonic", "epsilon": 1.0,
                         "sigma": 1.0, "cutoff": 1.0}},
         "run": {"steps": 10, "thermo": 5}}
    case = pickle.loads(pickle.dumps(_build(_cfg(d))))
    engine = _Engine([case])
    assert engine.fast is not None


def test_finish_chunk_sets_the_kernels_forces_aside_without_copying():
    """A sampled chunk's end: the NumPy output pass writes its forces into the scratch array (the
    kernel's spare buffer), and the kernel's own forces come back as the same array, values
    untouched; without scratch they are copied aside and written back. Also after the pass raises."""
    import types

    f = np.arange(12.0).reshape(1, 4, 3)
    scratch = np.zeros_like(f)
    calls = []

    def outputs():
        s.f[...] = -1.0  # the NumPy pass's forces
        calls.append(s.f)
        return {"w": (np.ones(1),)}

    plan = types.SimpleNamespace(compute_outputs=outputs, finish_step=lambda out, sample: calls.append(out))
    s = types.SimpleNamespace(f=f, ctx=1, var_step={1: 2})
    fast.finish_chunk(plan, s, True, scratch={"f": scratch})
    assert s.f is f and np.array_equal(f, np.arange(12.0).reshape(1, 4, 3))
    assert calls[0] is scratch and np.all(scratch == -1.0) and list(calls[1]) == ["w"]
    assert s.ctx is None and s.var_step == {}
    fast.finish_chunk(plan, s, True)  # no scratch: the pass writes into f, the copy is put back
    assert s.f is f and calls[2] is f and np.array_equal(f, np.arange(12.0).reshape(1, 4, 3))

    def broken():
        s.f[...] = np.nan
        raise RuntimeError("outputs failed")

    plan.compute_outputs = broken
    with pytest.raises(RuntimeError):
        fast.finish_chunk(plan, s, True, scratch={"f": scratch})
    assert s.f is f and np.array_equal(f, np.arange(12.0).reshape(1, 4, 3))
