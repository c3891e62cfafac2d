"""Sampled chunks: the compiled kernel records many samples itself (compiled.FastPath.advance_sampled,
Engine.record_block) against the NumPy engine sampling step by step.

Every scene runs with WALLBATCH_NUMBA=0 (NumPy: Engine.sample at every sample step) and =1 (one
kernel call runs many sample steps and writes each sample's sum m v^2, wall energies, forces on
the walls, virial, reflect statistics, flow redraws and thermostat accumulators into arrays).
Every output of every case must agree bit for bit (the same registry functions, summed in the
same order), except where the arithmetic itself differs between NumPy and numba (morse's exp and
expm1, fix nvt's chain exp, the flow solver): 1e-14 relative there. Each test checks that the
samples really came from the kernel (sample blocks, only the step-0 sample taken by NumPy), or,
for the scenes the kernel does not sample, that they did not.
"""

from __future__ import annotations

import copy
import types

import numpy as np
import pytest
from factories import assert_same_results, run_numpy_and_compiled, slab_gas

from wallbatch.config.models import config_from_dict
from wallbatch.engine import compiled as fast
from wallbatch.engine.engine import Engine
from wallbatch.scene.build import build_case
from wallbatch.scene.case import structure_key
from wallbatch.styles import STYLES
from wallbatch.styles.cutoff import CUTOFF_MODES, CutoffStyle

pytestmark = pytest.mark.skipif(fast.njit is None, reason="numba not importable")

OUT = ["step", "time", "dt", "temp", "ke", "pe", "etot", "press", "ecouple", "econserve"]
REFLECT_OUT = OUT + ["reflect_count", "reflect_impulse"]


def face(coord, eps=1.0, sigma=1.0, rc=2.5):
    return {"coord": coord, "epsilon": eps, "sigma": sigma, "cutoff": rc}


def gas(walls, *, n=120, steps=150, thermo=1, seed=5, temperature=1.5, output=OUT, **extra):
    """n atoms of an ideal gas in a 6 x 6 x 8 slab (x, y periodic, z fixed) between `walls`."""
    return slab_gas(copy.deepcopy(walls), n=n, hi=(6.0, 6.0, 8.0), margin=1.6, temperature=temperature, seed=seed,
                    dt=0.005, steps=steps, thermo=thermo, output=list(output), **extra)


def run_both(monkeypatch, configs):
    cases = [build_case(config_from_dict(d)) for d in configs]
    assert len({structure_key(c) for c in cases}) == 1  # one batch
    return run_numpy_and_compiled(monkeypatch, cases)


def check(monkeypatch, configs, rtol=0.0, *, sampled=True, numpy_samples=1):
    """Both ways; agreement; and whether the samples came from the kernel (`sampled`; NumPy takes
    `numpy_samples` of them: step 0, and the instant of a step with trouble)."""
    ref, got, eng = run_both(monkeypatch, configs)
    assert_same_results(ref, got, rtol)
    assert eng.fast is not None and eng.fast.compiled_chunks > 0
    if sampled:
        assert eng.sample_blocks, "no sampled chunk ran"
        assert len(eng.samples) == numpy_samples
    else:
        assert not eng.sample_blocks
    return ref, got, eng


# ----------------------------------------------------------------------------- styles


def lj93():
    return {"w": {"style": "lj93", "units": "box", "energy": True, "virial": True,
                  "zlo": face(0.0), "zhi": face(8.0, eps=2.0, sigma=0.9)}}


def harmonic():
    return {"w": {"style": "harmonic", "units": "box", "energy": True, "virial": True,
                  "zlo": {"coord": 0.0, "epsilon": 20.0, "cutoff": 1.5},
                  "zhi": {"coord": 8.0, "epsilon": 10.0, "cutoff": 1.5}}}


def morse():
    return {"w": {"style": "morse", "units": "box", "energy": True, "virial": True,
                  "zlo": {"coord": 0.0, "D0": 1.0, "alpha": 2.0, "r0": 1.2, "cutoff": 3.0},
                  "zhi": {"coord": 8.0, "D0": 0.5, "alpha": 1.5, "r0": 1.1, "cutoff": 2.5}}}


def with_reflect(walls):
    """A reflect wall on the slow group below the soft zhi face, so both act every few steps."""
    return {**walls, "r": {"style": "reflect", "units": "box", "zhi": 6.2}}


def swept(make, key, values, reflect=True):
    """Configs of one batch that differ in the zlo face's parameter `key` (and the seed)."""
    out = []
    for k, value in enumerate(values):
        walls = make()
        walls["w"]["zlo"][key] = value
        out.append(gas(with_reflect(walls) if reflect else walls, seed=5 + k, output=REFLECT_OUT if reflect else OUT))
    return out


# morse without the reflect wall: the kernel of test_compiled.py's morse slit (reflect counts sampled
# every step are checked with lj93 and harmonic)
@pytest.mark.parametrize("make, key, values, rtol, reflect", [
    (lj93, "epsilon", [0.5, 1.0, 2.0], 0.0, True),
    (harmonic, "epsilon", [5.0, 20.0, 40.0], 0.0, True),
    (morse, "D0", [0.3, 1.0, 1.5], 1e-14, False),  # exp/expm1: NumPy's vs the C library's
], ids=["lj93", "harmonic", "morse"])
def test_every_step_samples_match_numpy(monkeypatch, make, key, values, rtol, reflect):
    """Three cases with different wall parameters, sampled every step: every output (ke, temp,
    press with the walls' virial, pe, each fix's energy, each face's force, reflect counts and
    impulses per step) equals the NumPy engine's."""
    ref, got, eng = check(monkeypatch, swept(make, key, values, reflect), rtol)
    assert eng.fast.fallbacks == 0
    for r in got:
        assert r.status == "ok" and r.data["step"].tolist() == list(range(151))
        assert np.count_nonzero(r.data["wall_force"][:, 0]) > 30  # atoms in the wall's range on many steps
        assert np.count_nonzero(r.data["wall_energy"]) > 30
        assert not reflect or r.data["reflect_count"].sum() > 5
    # the walls' virial is in press: press != the ideal-gas part alone
    n, volume = 120, 6.0 * 6.0 * 8.0
    ideal = got[0].data["temp"] * (3 * n - 3) / 3.0 / volume
    assert np.abs(got[0].data["press"] - ideal).max() > 1e-3


ENERGY_PARAMS = {  # per style: parameters, the closest distance tested
    "lj93": ({"epsilon": 1.3, "sigma": 0.9}, 0.09), "lj126": ({"epsilon": 1.3, "sigma": 0.9}, 0.3),
    "lj1043": ({"epsilon": 1.3, "sigma": 0.9}, 0.2), "harmonic": ({"epsilon": 2.0, "sigma": 1.0}, 0.05),
    "morse": ({"D0": 1.3, "alpha": 2.0, "r0": 0.9}, 0.05), "colloid": ({"epsilon": 1.3, "sigma": 0.9, "radius": 0.5}, 0.6),
}


@pytest.mark.parametrize("mode", [0, 1, 2], ids=["shift", "force-shift", "smooth"])
@pytest.mark.parametrize("name", sorted(ENERGY_PARAMS))
def test_compiled_energy_is_the_numpy_energy(name, mode):
    """The kernel's energy of each (style, cut-off mode) is the NumPy CutoffStyle.energy: bit for
    bit, or to 1e-14 where the style's functions call libm (morse: exp, expm1; colloid: log1p, atanh)."""
    style = STYLES[name]
    assert fast.energy_compiled(style)
    assert (fast.STYLE_IDS[name], mode) in fast.MODE_ENERGIES  # every style runs every mode compiled
    p = {**ENERGY_PARAMS[name][0], "cutoff": 2.5, "switch_on": 1.0}
    cs = CutoffStyle(style, CUTOFF_MODES[mode])
    r = np.linspace(ENERGY_PARAMS[name][1], p["cutoff"], 301)
    want = cs.energy(r, {k: (np.full_like(r, v) if k == "radius" else v) for k, v in p.items()})
    args = [float(a) for a in (*style.args(p), p["switch_on"])]
    got = np.array([fast.MODE_ENERGIES[(fast.STYLE_IDS[name], mode)](float(ri), *args) for ri in r])
    if name in ("morse", "colloid"):
        np.testing.assert_allclose(got, want, rtol=0, atol=1e-14 * np.abs(want).max())
    else:
        np.testing.assert_array_equal(got, want)
    assert np.abs(want).max() > 0.0


def test_energy_and_force_of_a_face_are_the_registry_sums(monkeypatch):
    """One sample by hand: the recorded wall energy and force on the wall of the last step equal the
    registry's E(r) - E(rc) and F(r) summed over the atoms within the cut-off of each face."""
    monkeypatch.setenv("WALLBATCH_NUMBA", "1")
    d = gas(lj93(), steps=40, thermo=1, output=OUT)
    d["output"]["dump"] = {"every": 40, "fields": ["x"]}
    case = build_case(config_from_dict(d))
    eng = Engine([case])
    res = eng.run()[0]
    assert eng.sample_blocks
    z = res.frames["x"][-1][:, 2]
    st = STYLES["lj93"]
    energy, forces = 0.0, []
    for r, p, side in ((z - 0.0, {"epsilon": 1.0, "sigma": 1.0, "cutoff": 2.5}, -1.0),
                       (8.0 - z, {"epsilon": 2.0, "sigma": 0.9, "cutoff": 2.5}, 1.0)):
        r = r[r < 2.5]
        energy += st.shifted_energy(r, p).sum()
        forces.append(side * st.force(r, *st.args(p)).sum())
    assert res.data["wall_energy"][-1, 0] == pytest.approx(energy, rel=1e-13, abs=1e-15)
    np.testing.assert_allclose(res.data["wall_force"][-1], forces, rtol=1e-13, atol=1e-15)
    assert res.data["pe"][-1] == res.data["wall_energy"][-1, 0]
    assert abs(energy) > 1e-3  # atoms were in range


@pytest.mark.parametrize("mode", ["shift", "smooth"])
def test_colloid_slit_sampled_every_step(monkeypatch, mode):
    """colloid (radius 0.6 particles; its E(r) - E(rc) picks the far-field series or the closed
    form per atom, styles.flat.colloid_dg, compiled per value): two cases, sampled every step,
    outputs equal to 1e-14 (atanh and log1p: NumPy's vs the C library's)."""
    configs = []
    for k, eps in enumerate((1.0, 2.5)):
        walls = {"w": {"style": "colloid", "units": "box", "energy": True, "virial": True, "cutoff_mode": mode,
                       "zlo": face(0.0, eps=eps, rc=3.0), "zhi": face(8.0, rc=3.0)}}
        if mode == "smooth":
            walls["w"]["switch_on"] = 2.0
        d = gas(walls, seed=5 + k, steps=100)
        d["atoms"][0]["radius"] = 0.6
        configs.append(d)
    _, got, eng = check(monkeypatch, configs, 1e-14)
    assert eng.fast.fallbacks == 0
    assert np.count_nonzero(got[1].data["wall_energy"]) > 30


REGIONS = {
    "block-in": ({"style": "block", "lo": [0.5, 0.5, 0.5], "hi": [9.5, 9.5, 9.5]},
                 {"style": "block", "lo": [2.0, 2.0, 2.0], "hi": [8.0, 8.0, 8.0]}),
    "sphere-out": ({"style": "sphere", "center": [5.0, 5.0, 5.0], "radius": 2.0, "side": "out"},
                   {"style": "block", "lo": [0.0, 0.0, 0.0], "hi": [10.0, 10.0, 2.5]}),
    "cylinder-in": ({"style": "cylinder", "axis": "z", "center": [5.0, 5.0], "radius": 4.0, "lo": 0.5, "hi": 9.5},
                    {"style": "block", "lo": [3.0, 3.0, 2.0], "hi": [7.0, 7.0, 8.0]}),
}


@pytest.mark.parametrize("shape", sorted(REGIONS))
def test_region_walls_sampled_every_step(monkeypatch, shape):
    """wall/region (lj93 and harmonic, energy and virial) in a 10^3 box, two cases: each
    fix's energy and force on the wall (summed contact by contact in RegionGeom.contacts' order),
    pe and press at every step equal the NumPy engine's bit for bit."""
    region, start = REGIONS[shape]
    configs = []
    for k, eps in enumerate((1.0, 1.8)):
        d = gas({}, steps=100, n=60, seed=5 + k, temperature=2.0)
        closed = region.get("side", "in") == "in"  # an obstacle (side out) sits in a periodic box
        d["box"] = {"lo": [0, 0, 0], "hi": [10.0, 10.0, 10.0], "boundary": ["f" if closed else "p"] * 3}
        d["regions"] = {"R": {**region, "units": "box"}, "mid": {**start, "units": "box"}}
        d["walls"] = {
            "a": {"style": "region", "region": "R", "potential": "lj93", "epsilon": eps, "sigma": 1.0,
                  "cutoff": 2.5, "energy": True, "virial": True},
            "b": {"style": "region", "region": "R", "potential": "harmonic", "epsilon": 50.0 * eps, "cutoff": 1.0,
                  "energy": True}}
        configs.append(d)
    _, got, eng = check(monkeypatch, configs)
    assert eng.fast.fallbacks == 0
    for r in got:
        assert r.status == "ok"
        assert np.count_nonzero(r.data["region_force"][:, 0]) > 20  # the walls acted on many steps
        assert np.count_nonzero(r.data["wall_energy"][:, 1]) > 5


STOCHASTIC = {
    "diffusive": {"rstyle": "diffusive", "zlo": {"coord": 1.55, "temp": 1.0}},
    "maxwell": {"rstyle": "maxwell", "zlo": {"coord": 1.55, "temp": 0.7, "vel": [0.3, 0.0, 0.0], "accom": 0.4}},
    "ccl": {"rstyle": "ccl", "zlo": {"coord": 1.55, "temp": 0.5, "vel": [0.2, -0.1, 0.0], "accom": [0.3, 0.8, 0.6]}},
}


@pytest.mark.parametrize("thermo", [1, 3])
@pytest.mark.parametrize("rstyle", ["diffusive", "maxwell", "ccl"])
def test_stochastic_reflect_sampled_in_the_kernel(monkeypatch, rstyle, thermo):
    """wall/reflect/stochastic (after a wall/reflect face, with a soft wall) sampled every step and
    every third step: a sweep of three cases (own seeds and temperatures, one case per call with
    its generator) records its reflection counts and impulses in the kernel, after the wall/reflect
    ones, and every output and random stream is the NumPy engine's bit for bit."""
    configs = []
    for k, (seed, temp) in enumerate(((77, 1.0), (78, 2.0), (79, 0.6))):
        st = copy.deepcopy(STOCHASTIC[rstyle])
        st["zlo"]["temp"] = st["zlo"]["temp"] * temp
        soft = harmonic()  # its zlo face reaches past the stochastic one; the kernel of test_stochastic_engine.py
        soft["w"]["zlo"].update(epsilon=0.5, cutoff=2.0)
        walls = {**soft, "r": {"style": "reflect", "units": "box", "zhi": 6.45},
                 "s": {"style": "reflect/stochastic", "seed": seed, "units": "box", **st}}
        configs.append(gas(walls, steps=150, thermo=thermo, output=REFLECT_OUT, seed=5 + k, temperature=1.5 * temp))
    ref, got, eng = check(monkeypatch, configs)
    assert eng.fast.fallbacks == 0 and not eng.fast._sampled_refused and eng.fast.sampled_calls > 0
    for r in got:
        count = r.data["reflect_count"]
        assert count.shape == (150 // thermo + 1, 2)
        assert count[:, 0].sum() > 5 and count[:, 1].sum() > 5  # both faces reflected atoms
        assert np.count_nonzero(count[:, 1]) > 3  # reset at each sample: counts spread over samples
        assert np.count_nonzero(r.data["wall_force"][:, 0]) > 3  # the soft zlo face acted
    assert not np.array_equal(got[0].data["reflect_count"], got[1].data["reflect_count"])


@pytest.mark.parametrize("thermo", [1, 25])
def test_two_stochastic_fixes_in_the_kernel(monkeypatch, thermo):
    """Two wall/reflect/stochastic fixes after a wall/reflect face: a diffusive floor at T 1.0 and
    a Maxwell ceiling at T 0.5 moving along x, each its own seed. The kernel draws each fix's faces
    from that fix's generator, fix after fix, and records their counts after the wall/reflect
    face's; two cases give the NumPy engine's outputs and streams bit for bit."""
    configs = []
    for k, seed in enumerate((77, 91)):
        soft = harmonic()
        soft["w"]["zlo"].update(epsilon=0.5, cutoff=2.0)
        walls = {**soft, "r": {"style": "reflect", "units": "box", "zhi": 6.6},
                 "s": {"style": "reflect/stochastic", "seed": seed, "units": "box", **STOCHASTIC["diffusive"]},
                 "t": {"style": "reflect/stochastic", "seed": seed + 1, "units": "box", "rstyle": "maxwell",
                       "zhi": {"coord": 6.45, "temp": 0.5, "vel": [0.3, 0.0, 0.0], "accom": 0.4}}}
        configs.append(gas(walls, steps=150, thermo=thermo, output=REFLECT_OUT, seed=5 + k, temperature=1.5))
    ref, got, eng = check(monkeypatch, configs)
    assert eng.fast.fallbacks == 0 and eng.fast.sampled_calls > 0
    for r in got:
        count = r.data["reflect_count"]
        assert count.shape == (150 // thermo + 1, 3)
        assert count[:, 1].sum() > 5 and count[:, 2].sum() > 5  # both stochastic faces reflected atoms
    assert not np.array_equal(got[0].data["reflect_count"], got[1].data["reflect_count"])


# ----------------------------------------------------------------------------- fixes, dt/reset, flow


@pytest.mark.parametrize("fixes, rtol", [
    ({"a": "fix a all nve", "b": "fix b all langevin 1.0 2.0 0.5 48279 tally yes"}, 0.0),
    ({"a": "fix a all nve", "b": "fix b all temp/berendsen 1.0 0.8 0.1"}, 0.0),
    ({"a": "fix a all nve", "c": "fix c all temp/rescale 7 0.9 0.9 0.01 0.5"}, 0.0),
    ({"a": "fix a all nvt temp 1.0 1.2 0.1 tchain 3"}, 1e-14),  # the chain's exp: NumPy's vs libm's
], ids=["langevin", "berendsen", "rescale", "nvt"])
def test_thermostats_sampled_every_step(monkeypatch, fixes, rtol):
    """Two cases with a thermostat, sampled every step: ecouple and econserve from the kernel's
    accumulators (and chain) at each sample step equal the NumPy engine's."""
    configs = [gas(lj93(), fixes=fixes, steps=60), gas(lj93(), fixes=fixes, steps=60, seed=6, temperature=2.0)]
    _, got, eng = check(monkeypatch, configs, rtol)
    assert eng.fast.fallbacks == 0
    assert np.count_nonzero(np.diff(got[1].data["ecouple"])) > 5  # the thermostat exchanged energy (rescale: every 7 steps)


def test_dt_reset_sampled_every_step(monkeypatch):
    """dt/reset changes dt inside a sampled chunk: each sample's dt and time are the NumPy ones."""
    d = gas(lj93(), steps=120)
    d["atoms"].append({"group": "close", "create": {"positions": [[2.0, 2.0, 0.55], [4.0, 4.0, 7.5]]},
                       "mass": 2.0})
    d["dt_reset"] = {"every": 2, "tmin": 1.0e-5, "tmax": 0.01, "xmax": 0.02, "emax": 0.5, "units": "box"}
    _, got, eng = check(monkeypatch, [d])
    assert len(np.unique(got[0].data["dt"])) > 2


@pytest.mark.slow
def test_flow_crossings_per_sample(monkeypatch):
    """wall/flow in the kernel, sampled every 2 steps with a dump every 3 (the redraws of a chunk up
    to a dump count in the next sample): redraws per sample equal NumPy's; ke to 1e-12 (the flux
    solver's few ulp)."""
    def cfg(seed, vflow):
        return {"units": "lj", "seed": seed, "timestep": 0.005,
                "box": {"lo": [0, 0, 0], "hi": [10.0, 3.0, 3.0], "boundary": ["p", "p", "p"]},
                "atoms": [{"group": "gas", "create": {"random": {"count": 200}}, "mass": 1.0,
                           "velocity": {"temperature": 1.5}}],
                "walls": {"fl": {"style": "flow", "axis": "x", "vflow": vflow, "temperature": 1.5, "seed": 99 + seed,
                                 "coords": [2.5, 5.0, 7.5], "units": "box"}},
                "run": {"steps": 200, "thermo": 2},
                "output": {"thermo": ["step", "ke", "temp", "flow_crossings"], "dump": {"every": 3, "fields": ["v"]}}}
    ref, got, eng = run_both(monkeypatch, [cfg(3, 0.4), cfg(4, 1.2)])
    assert eng.sample_blocks and len(eng.samples) == 1 and eng.fast.fallbacks == 0
    for r, g in zip(ref, got):
        assert r.status == g.status == "ok"
        assert r.data["flow_crossings"].sum() > 40
        np.testing.assert_array_equal(g.data["flow_crossings"], r.data["flow_crossings"])
        np.testing.assert_array_equal(g.data["step"], r.data["step"])
        np.testing.assert_allclose(g.data["ke"], r.data["ke"], rtol=1e-12)


# ----------------------------------------------------------------------------- schedules, variables, failures


def test_dumps_between_samples_and_an_odd_last_step(monkeypatch):
    """thermo 3 over 100 steps (the last sample at 100) with a dump every 7 steps: the sampled
    chunks stop at each dump; samples and frames equal NumPy's."""
    d = gas(with_reflect(lj93()), steps=100, thermo=3, output=REFLECT_OUT)
    d["output"]["dump"] = {"every": 7, "fields": ["x", "v"]}
    other = gas(with_reflect(lj93()), steps=100, thermo=3, seed=9, output=REFLECT_OUT)
    other["output"] = copy.deepcopy(d["output"])
    ref, got, eng = check(monkeypatch, [d, other])
    assert got[0].data["step"][-1] == 100 and len(eng.sample_blocks) > 5
    for a, b in zip(ref, got):
        for key in ("time", "x", "v"):
            np.testing.assert_array_equal(b.frames[key], a.frames[key])


def test_moving_wall_and_ramped_parameter(monkeypatch):
    """Per-step wall values (a wall moving with a variable, epsilon ramping): each sample's outputs
    use that step's values."""
    walls = {"w": {"style": "lj93", "units": "box", "energy": True, "virial": True,
                   "zlo": {"coord": "v_lo", "epsilon": "v_eps", "sigma": 1.0, "cutoff": 2.5},
                   "zhi": face(8.0)}}
    d = gas(walls, variables={"lo": "vdisplace(0.0, 0.4)", "eps": "ramp(0.5, 2.0)"}, steps=120)
    _, got, eng = check(monkeypatch, [d])
    assert eng.fast.fallbacks == 0
    assert np.count_nonzero(got[0].data["wall_force"][:, 0]) > 30


def test_a_case_failing_mid_chunk(monkeypatch):
    """A case of the batch crosses a zero-strength wall mid-run: the sampled chunk goes back to its
    last sample before the trouble, NumPy runs the step with trouble (and fails the case with its
    message), the others go on sampled. Same statuses, messages and numbers."""
    def cfg(coord, eps=1.0):
        return gas({"w": {"style": "lj93", "units": "box", "energy": True,
                          "zlo": {"coord": coord, "epsilon": eps, "sigma": 1.0, "cutoff": 2.5}, "zhi": face(8.0)}},
                   steps=200, thermo=2)
    _, got, eng = check(monkeypatch, [cfg(0.0), cfg(1.5, eps=0.0), cfg(0.3)], numpy_samples=2)
    assert [r.status for r in got] == ["ok", "failed", "ok"]
    step = int(got[1].error.split(" at step ")[1].split(":")[0])
    assert step > 10  # mid-run
    assert np.isnan(got[1].data["ke"]).all() and not np.isnan(got[0].data["ke"]).any()
    assert eng.fast.fallbacks >= 1 and len(eng.sample_blocks) >= 2


def test_one_run_keeps_to_one_kernel(monkeypatch):
    """A one-case run whose whole length would be split over two threads but whose samples are
    close together runs every sample in the kernel (no threads), so it compiles one kernel, not a
    one-instant kernel for the first chunks and a sampled one for the last (as when the choice
    followed each chunk's length)."""
    from wallbatch.engine import threads

    monkeypatch.setenv("WALLBATCH_THREADS", "2")
    monkeypatch.setattr(threads, "MIN_WORK", 2000)  # 300 atoms x 150 steps: split; x 10 steps: not
    ref, got, eng = run_both(monkeypatch, [gas(lj93(), n=300, steps=150, thermo=10)])
    assert_same_results(ref, got)
    assert len(eng.fast.kernel_names) == 1
    assert eng.fast.sampled_calls > 0 and len(eng.samples) == 1  # step 0 only from NumPy


def test_both_ways_of_sampling_share_one_kernel(monkeypatch):
    """Samples recorded in the kernel and samples taken one instant at a time (a case split over
    two threads between samples) run the same kernel: one compile per kind of scene, whatever the
    sample spacing; both give NumPy's bits."""
    from wallbatch.engine import threads

    monkeypatch.setenv("WALLBATCH_THREADS", "2")
    monkeypatch.setattr(threads, "MIN_WORK", 2000)
    ref, got, near = run_both(monkeypatch, [gas(lj93(), n=300, steps=150, thermo=5)])  # 1500: no split
    assert_same_results(ref, got)
    ref, got, far = run_both(monkeypatch, [gas(lj93(), n=300, steps=150, thermo=50)])  # 15000: split
    assert_same_results(ref, got)
    assert near.fast.sampled_calls > 0 and far.fast.sampled_calls == 0 and far.fast.compiled_chunks == 3
    assert near.fast.kernel_names == far.fast.kernel_names and len(near.fast.kernel_names) == 1


def test_samples_close_together_stay_in_the_kernel_on_one_thread(monkeypatch):
    """A case that two threads could split between samples (enough atom-steps) but whose samples
    are fewer than SPLIT_SAMPLE_STEPS steps apart records them in the kernel on one thread: each
    sample of a split case is a NumPy pass over all atoms (two threads were 1.6-1.7x slower than
    one at N = 1e6 sampled every 10 steps). At that spacing and beyond, the steps go to the
    threads. The same bits either way."""
    from wallbatch.engine import threads

    monkeypatch.setenv("WALLBATCH_THREADS", "2")
    monkeypatch.setattr(threads, "MIN_WORK", 1)  # any sample spacing has the atom-steps for a split
    spacing = fast.SPLIT_SAMPLE_STEPS
    before = threads.splits["atoms"]
    ref, got, near = run_both(monkeypatch, [gas(lj93(), n=300, steps=4 * (spacing - 1), thermo=spacing - 1)])
    assert_same_results(ref, got)
    assert near.fast.sampled_calls > 0 and threads.splits["atoms"] == before
    ref, got, far = run_both(monkeypatch, [gas(lj93(), n=300, steps=4 * spacing, thermo=spacing)])
    assert_same_results(ref, got)
    assert far.fast.sampled_calls == 0 and threads.splits["atoms"] > before


def python_eface():
    """`_eface` as Python, with the contacts loop `_eloop` and the flat face's contact readers it
    calls as Python too (so it takes Python force and energy functions)."""
    names = ("_eloop", "_flat_at", "_flat_contact")
    env = {**fast._eface.py_func.__globals__, **{n: getattr(fast, n).py_func for n in names}}
    return types.FunctionType(fast._eface.py_func.__code__, env)


@pytest.mark.parametrize("form", ["positional", "array"])
def test_lepton_energy_offset_is_evaluated_once_per_face_and_sample(form):
    """The outputs loop of a wall/lepton face (`_eface`, the contacts loop `_eloop` on a flat
    face, through the generated `_face_out` /
    `_vector_out` dispatch, run here as Python with a harmonic E(r) = k (rc - r)^2 + b that records
    each r it is evaluated at) subtracts E(rc) evaluated once per call, not once per atom, and
    returns sum E(r) - E(rc), sum side F(r) and sum F(r) r over the group atoms within the cut-off,
    in atom order."""
    seen: list[float] = []
    k, b, rc, coord = 3.0, 0.25, 1.5, 0.5

    def energy(r, p):
        seen.append(r)
        return p[0] * (rc - r) ** 2 + p[1]

    def force(r, p):
        return 2.0 * p[0] * (rc - r)

    z = np.array([0.9, 2.4, 1.2, 0.6, 1.9, 1.7])  # r = z - coord: 0.4, 1.9 (out), 0.7, 0.1, 1.4, 1.2
    X = np.zeros((3, z.size))
    X[2] = z
    groups = np.array([[1, 1, 1, 1, 1, 0]])  # the last atom, within the cut-off, is not in the group
    if form == "positional":
        ns = {"_eface": python_eface(), "_nan": np.nan,
              "_EXTRA_0": lambda r, p0, p1, p2, c, rad, ron: force(r, (p0, p1)),
              "_EEXTRA_0": lambda r, p0, p1, p2, c, rad, ron: energy(r, (p0, p1))}
        exec(fast._outputs_source((), "face", (0,)), ns)  # noqa: S102 - the generated dispatch
        e, fs, vir = ns["_face_out"](len(fast.COMPILED_STYLES), fast.SHIFT, X, np.zeros(z.size), groups, 0, 2, -1,
                                     coord, k, b, 0.0, rc, 0.0, z.size)
    else:
        ns = {"_eface": python_eface(), "_nan": np.nan, "_VEXTRA_0": fast._vector_args(force),
              "_VEENERGY_0": fast._vector_args(energy)}
        exec(fast._vector_outputs_source((fast.VECTOR_MARK + "kernel\ndef energy(",)), ns)  # noqa: S102
        e, fs, vir = ns["_vector_out"](0, X, np.zeros(z.size), groups, 0, 2, -1, coord, np.array([k, b]), rc,
                                       z.size)
    r = (z - coord)[[0, 2, 3, 4]]  # the group atoms within the cut-off, in atom order
    assert seen == [rc, *r]  # E(rc) once, first; then E(r) of each atom
    assert e == pytest.approx(np.sum(k * (rc - r) ** 2), rel=1e-15)  # the b's cancel
    f = 2.0 * k * (rc - r)
    assert fs == pytest.approx(-np.sum(f), rel=1e-15) and vir == pytest.approx(np.sum(f * r), rel=1e-15)
