"""Ellipsoids between wall/ees faces on the compiled path (wallbatch.engine.asphere_compiled)
against the NumPy engine, its reference.

Each scene runs with WALLBATCH_NUMBA=0 and =1 (test_compiled.py's `run_both`): every sampled output
of every case agrees to 1e-14 relative, with the same status and failure message, and the test
asserts that chunks really ran compiled (or fell back, or were refused) so a silent fallback
cannot pass. The kernel's pieces are the NumPy path's own functions compiled: checked directly.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from test_compiled import RTOL, assert_same, run_both
from test_threads import run_with

from wallbatch.config.models import config_from_dict
from wallbatch.engine import asphere_compiled as ac
from wallbatch.engine.asphere_compiled import AspherePath
from wallbatch.engine.engine import Engine
from wallbatch.geometry import quaternion as quat
from wallbatch.scene.build import build_case
from wallbatch.scene.case import structure_key
from wallbatch.styles import ees

pytestmark = pytest.mark.skipif(ac.njit is None, reason="numba not importable")

ROD = {"mass": 1.3, "shape": [1.0, 0.45, 0.6], "orientation": "random", "angmom": {"values": [0.1, -0.2, 0.3]}}


def slit(*, n=70, eps=2.0, sigma=1.0, cutoff=5.0, steps=300, thermo=50, dt=0.002, seed=7, temperature=1.5,
         walls=None, side=12.0, extra_atoms=(), boundary=("p", "p", "f")) -> dict:
    """n ellipsoids (semi-axes 1, 0.45, 0.6; 70 per 12 x 12: 2 blocks of atoms and a partial one
    beyond BLOCK) started in 2 < z < 6 between wall/ees faces at z = 0 and 8."""
    face = {"coord": "EDGE", "epsilon": eps, "sigma": sigma, "cutoff": cutoff}
    return {"units": "lj", "seed": seed,
            "box": {"lo": [0, 0, 0], "hi": [side, side, 8], "boundary": list(boundary)},
            "regions": {"mid": {"style": "block", "lo": [0, 0, 2], "hi": [side, side, 6], "units": "box"}},
            "atoms": [{"group": "rods", "create": {"random": {"count": n, "region": "mid", "overlap": 1.2}},
                       **ROD, "velocity": {"temperature": temperature}}, *extra_atoms],
            "walls": walls if walls is not None else {
                "slit": {"style": "ees", "units": "box", "energy": True, "zlo": face, "zhi": dict(face)}},
            "timestep": dt, "run": {"steps": steps, "thermo": thermo},
            "output": {"thermo": ["step", "time", "temp", "ke", "pe", "etot", "erot"]}}


def check(monkeypatch, configs, *, compiled=True):
    """Run the configs as one batch both ways; assert agreement and that chunks ran compiled."""
    cases = [build_case(config_from_dict(d)) for d in configs]
    assert len({structure_key(c) for c in cases}) == 1
    ref, got, eng = run_both(monkeypatch, cases)
    assert_same(ref, got)
    if compiled:
        assert isinstance(eng.fast, AspherePath) and eng.fast.compiled_chunks > 0
    return ref, got, eng


@pytest.mark.slow
def test_ellipsoid_slit_matches_numpy_over_a_batch(monkeypatch):
    """Three cases of one batch with different epsilon, sigma and seeds; both faces act on every
    atom (the cut-off spans the slit), the energy exchange with the walls is real."""
    configs = [slit(eps=2.0, seed=7), slit(eps=0.7, sigma=1.2, seed=8), slit(eps=3.5, sigma=0.8, seed=9)]
    ref, got, eng = check(monkeypatch, configs)
    assert eng.fast.fallbacks == 0
    for r in ref:
        assert np.all(r.data["wall_energy"] != 0.0)
        assert np.ptp(r.data["erot"]) > 1e-3  # the torques turn the rods
        assert np.ptp(r.data["pe"]) > 1e-3
    # the compiled state itself, not only the sampled outputs
    monkeypatch.setenv("WALLBATCH_NUMBA", "0")
    numpy_engine = Engine([build_case(config_from_dict(d)) for d in configs])
    numpy_engine.run()
    for name in ("x", "v", "f", "quat", "angmom", "torque"):
        want, have = getattr(numpy_engine.state, name), getattr(eng.state, name)
        np.testing.assert_allclose(have, want, rtol=0, atol=RTOL * np.abs(want).max(), err_msg=name)


def test_first_compile_is_announced_with_its_estimate(monkeypatch, capsys):
    """The ellipsoid kernel's first compile (~40 s) says so on stderr, once, with its own
    estimate; a kernel numba already built (or loads from disk) says nothing."""
    from wallbatch.engine import compiled as fast

    real = ac._run_chunk

    class Fresh:
        """The kernel as before its first compile: no signatures yet; everything else the kernel's."""

        signatures: list = []

        def __getattr__(self, name):
            return getattr(real, name)

        def __call__(self, *args):
            return real(*args)

    monkeypatch.setattr(ac, "_run_chunk", Fresh())
    monkeypatch.setattr(fast, "_ANNOUNCED", set())
    monkeypatch.setattr(fast, "_cached_on_disk", lambda k: False)
    monkeypatch.setenv("WALLBATCH_NUMBA", "1")
    for _ in range(2):
        eng = Engine([build_case(config_from_dict(slit(n=20, steps=20, thermo=10)))])
        assert eng.run()[0].status == "ok" and isinstance(eng.fast, AspherePath) and eng.fast.compiled_chunks > 0
    err = capsys.readouterr().err
    assert err.count("compiling kernels for this scene, once") == 1
    assert f"~{ac.COMPILE_SECONDS:g} s" in err
    monkeypatch.setattr(ac, "_run_chunk", real)  # built in this process: nothing to say
    monkeypatch.setattr(fast, "_ANNOUNCED", set())
    Engine([build_case(config_from_dict(slit(n=20, steps=20, thermo=10)))]).run()
    assert "compiling" not in capsys.readouterr().err


def test_contacts_near_the_wall_take_the_closed_form(monkeypatch):
    """Rods started close to the walls (sigma_n / r >= 1/2: G and K from the closed forms with the
    logarithm) and far from them (series), sampled every step."""
    pos = [[2.0, 2.0, 1.05], [5.0, 5.0, 6.9], [8.0, 8.0, 4.0], [3.0, 8.0, 1.4]]
    rods = {"group": "rods", "create": {"positions": pos}, **ROD, "orientation": "aligned",
            "velocity": {"values": [[0.1, 0.0, -0.5], [0.0, 0.2, 0.6], [0.3, 0.1, 0.0], [0.0, 0.0, -0.3]]}}
    d = slit(steps=120, thermo=1, eps=1.0)
    d["atoms"] = [rods]
    ref, got, eng = check(monkeypatch, [d])
    assert eng.fast.fallbacks == 0 and eng.fast.compiled_chunks == 120
    # the closed form really was taken: sigma_n / r >= 1/2 at the start (aligned: sigma_n = 0.6)
    assert 0.6 / 1.05 >= ac.SERIES_T and 0.6 / (8.0 - 6.9) >= ac.SERIES_T


def test_groups_and_point_atoms(monkeypatch):
    """wall/ees on the rods only, slow point atoms (no orientation: moments 0) between them, and
    the faces along x with y and z periodic."""
    dots = {"group": "dots", "create": {"positions": [[4.0, 3.0, 3.0], [4.5, 9.0, 5.0], [3.5, 6.0, 7.0]]},
            "mass": 2.0, "velocity": {"values": [[0.01, 0.02, 0.0], [-0.01, 0.0, 0.03], [0.0, 0.01, -0.02]]}}
    face = {"coord": "EDGE", "epsilon": 1.5, "sigma": 1.0, "cutoff": 3.0}
    d = slit(n=40, extra_atoms=(dots,), boundary=("f", "p", "p"),
             walls={"xw": {"style": "ees", "units": "box", "group": "rods", "energy": True,
                           "xlo": face, "xhi": {**face, "coord": 12.0}}})
    d["regions"]["mid"] = {"style": "block", "lo": [2, 0, 0], "hi": [10, 12, 8], "units": "box"}
    ref, got, eng = check(monkeypatch, [d])
    assert eng.fast.fallbacks == 0
    assert np.any(ref[0].data["wall_force"] != 0.0)


def rod_into_a_weak_wall() -> list[dict]:
    """Two cases of 20 rods and a bullet rod between weak wall/ees faces: in the first the bullet
    is shot into the lower wall (z velocity -30), in the second it drifts (0.1)."""
    configs = []
    for vz, seed in ((-30.0, 7), (0.1, 8)):
        d = slit(n=20, eps=0.05, steps=400, thermo=100, seed=seed)
        d["atoms"].append({"group": "bullet", "create": {"positions": [[6.0, 6.0, 4.0]]}, **ROD,
                           "velocity": {"values": [[0.0, 0.0, vz]]}})
        configs.append(d)
    return configs


@pytest.mark.slow
def test_an_ellipsoid_inside_a_wall_falls_back_and_fails_as_numpy(monkeypatch):
    """A fast rod driven into a weak wall: the chunk falls back, NumPy fails the case with its
    message; the other case of the batch runs on (compiled again after the failure)."""
    ref, got, eng = check(monkeypatch, rod_into_a_weak_wall())
    assert [r.status for r in got] == ["failed", "ok"]
    assert "Particle on or inside fix wall surface" in got[0].error
    assert eng.fast.fallbacks >= 1 and eng.fast.compiled_chunks >= 1


def test_a_lost_ellipsoid_falls_back_and_fails_as_numpy(monkeypatch):
    d = slit(n=10, boundary=("f", "p", "f"), steps=200, thermo=50)
    d["atoms"].append({"group": "bullet", "create": {"positions": [[11.5, 6.0, 4.0]]}, **ROD,
                       "velocity": {"values": [[20.0, 0.0, 0.0]]}})
    d["regions"]["mid"]["hi"] = [10, 12, 6]
    ref, got, eng = check(monkeypatch, [d], compiled=False)
    assert got[0].status == "failed" and "left the box" in got[0].error
    assert eng.fast.fallbacks >= 1


@pytest.mark.parametrize("what", ["variable", "pair", "lj93"])
def test_scenes_the_kernel_refuses_run_on_numpy(monkeypatch, what):
    d = slit(n=12, steps=20, thermo=10)
    if what == "variable":
        d["variables"] = {"top": "8.0 - 0.001*step"}
        d["walls"]["slit"]["zhi"]["coord"] = "v_top"
    elif what == "pair":
        d["pair"] = {"style": "lj/cut", "epsilon": 0.1, "sigma": 1.0, "cutoff": 2.5}
    else:
        d["walls"]["flat"] = {"style": "lj93", "units": "box", "xlo": {"coord": "EDGE", "epsilon": 1.0,
                                                                         "sigma": 1.0, "cutoff": 2.5}}
        d["box"]["boundary"] = ["f", "p", "f"]
    cases = [build_case(config_from_dict(d))]
    ref, got, eng = run_both(monkeypatch, cases)
    assert eng.fast is None
    assert_same(ref, got)


# ----------------------------------------------------------------------------- the pieces


@pytest.mark.slow  # over 2.5 s
def test_compiled_richardson_is_the_numpy_one_bit_for_bit():
    rng = np.random.default_rng(3)
    q = quat.random_quaternions(rng, 200)
    ang = rng.normal(size=(200, 3))
    moments = rng.uniform(0.1, 2.0, size=(200, 3))
    moments[:5] = 0.0  # point particles keep q
    moments[5:10, 0] = 0.0  # a rod's vanishing moment
    want = quat.richardson(q, ang, moments, 0.004)
    for i in range(200):
        got = ac._richardson(*q[i], *ang[i], *moments[i], 0.004)
        assert np.array_equal(np.array(got), want[i]), i
    np.testing.assert_array_equal(want[:5], q[:5])


# numba's pedantic SSA note on the inlined Horner loop when `_series` compiles (benign; the engine
# hides it the same way around its chunk call)
@pytest.mark.slow
@pytest.mark.filterwarnings("ignore::numba.core.errors.NumbaIRAssumptionWarning")
def test_compiled_ees_pieces_are_the_numpy_ones():
    """r from just above sigma_n (closed forms) to far (series): E, F, T_w and the torque and
    sigma_n of the compiled pieces equal ees_energy_force_torque / ees_torque / sigma_n."""
    rng = np.random.default_rng(5)
    q = quat.random_quaternions(rng, 300)
    semi = np.array([1.0, 0.45, 0.6])
    normal = np.array([0.0, 0.0, -1.0])
    sn = ees.sigma_n(q, semi, normal)
    r = sn * np.geomspace(1.0005, 12.0, 300)
    e, f, tw = ees.ees_energy_force_torque(r, sn, 1.7, 0.9)
    tau = ees.ees_torque(q, semi, normal, tw)
    closed = 0
    for i in range(300):
        a = ac._rotation(*q[i])
        s_n = ac._sigma_n(a, *semi, *normal)
        assert s_n == sn[i]
        t, s, p = ac._ratios(r[i], s_n)
        if t < ac.SERIES_T:
            g, k = ac._series(s)
        else:
            g, k = ac._closed(t, p, math.log((r[i] - s_n) / (r[i] + s_n)))
            closed += 1
        got = ac._combine(r[i], s, p, g, k, 1.7, 0.9)
        np.testing.assert_allclose(got, (e[i], f[i], tw[i]), rtol=1e-14, atol=0)
        np.testing.assert_allclose(ac._torque(a, *semi, *normal, got[2]), tau[i], rtol=1e-14,
                                   atol=1e-14 * np.abs(tau[i]).max())
    assert 30 < closed < 270


# ----------------------------------------------------------------------------- wall/region/ees


def region_scene(region: dict, *, start: dict, n=40, boundary=("f", "f", "f"), eps=2.0, cutoff=3.0, steps=300,
                 thermo=50, seed=4, group=None, extra_atoms=()) -> dict:
    """n ellipsoids started in `start`, held by a wall/region/ees of `region` in a 12^3 box."""
    wall = {"style": "region/ees", "region": "R", "epsilon": eps, "sigma": 1.0, "cutoff": cutoff, "energy": True}
    if group:
        wall["group"] = group
    return {"units": "lj", "seed": seed,
            "box": {"lo": [0, 0, 0], "hi": [12, 12, 12], "boundary": list(boundary)},
            "regions": {"R": {**region, "units": "box"}, "start": {**start, "units": "box"}},
            "atoms": [{"group": "rods", "create": {"random": {"count": n, "region": "start", "overlap": 1.2}},
                       **ROD, "velocity": {"temperature": 1.5}}, *extra_atoms],
            "walls": {"cage": wall}, "timestep": 0.002, "run": {"steps": steps, "thermo": thermo},
            "output": {"thermo": ["step", "time", "temp", "ke", "pe", "etot", "erot"]}}


REGIONS = {
    "sphere in": ({"style": "sphere", "center": [6, 6, 6], "radius": 5.5},
                  {"style": "sphere", "center": [6, 6, 6], "radius": 3.5}, ("f", "f", "f")),
    "block in": ({"style": "block", "lo": [0.5, 0.5, 0.5], "hi": [11.5, 11.5, 11.5]},
                 {"style": "block", "lo": [2.5, 2.5, 2.5], "hi": [9.5, 9.5, 9.5]}, ("f", "f", "f")),
    "cylinder in": ({"style": "cylinder", "axis": "y", "center": [6, 6], "radius": 5.5, "lo": 0.5, "hi": 11.5},
                    {"style": "cylinder", "axis": "y", "center": [6, 6], "radius": 3.5, "lo": 2.5, "hi": 9.5},
                    ("f", "f", "f")),
    "sphere out": ({"style": "sphere", "center": [6, 6, 6], "radius": 2.5, "side": "out"},
                   {"style": "block", "lo": [0, 0, 0], "hi": [12, 12, 2.5]}, ("p", "p", "p")),
    "cylinder out": ({"style": "cylinder", "axis": "z", "center": [6, 6], "radius": 2.0, "lo": 3.0, "hi": 9.0,
                      "side": "out"}, {"style": "block", "lo": [0, 0, 0], "hi": [12, 3.0, 12]}, ("p", "p", "p")),
}


@pytest.mark.parametrize("name", sorted(REGIONS))
def test_region_ees_matches_numpy(monkeypatch, name):
    region, start, boundary = REGIONS[name]
    configs = [region_scene(region, start=start, boundary=boundary),
               region_scene(region, start=start, boundary=boundary, eps=0.8, seed=5)]
    ref, got, eng = check(monkeypatch, configs)
    assert eng.fast.fallbacks == 0
    for r in ref:
        assert r.status == "ok" and np.any(r.data["region_force"] != 0.0)  # the region wall acts
        assert np.ptp(r.data["pe"]) > 1e-4


def test_region_ees_and_flat_ees_on_groups(monkeypatch):
    """A flat wall/ees on one group of rods and a wall/region/ees sphere on another, together."""
    region, start, _ = REGIONS["sphere in"]
    more = {"group": "others", "create": {"random": {"count": 15, "region": "start", "overlap": 1.2}}, **ROD,
            "velocity": {"temperature": 1.0}}
    d = region_scene(region, start=start, group="rods", extra_atoms=(more,), n=25)
    d["walls"]["floor"] = {"style": "ees", "units": "box", "group": "others", "energy": True,
                           "zlo": {"coord": 0.4, "epsilon": 1.0, "sigma": 1.0, "cutoff": 6.0}}
    ref, got, eng = check(monkeypatch, [d])
    assert eng.fast.fallbacks == 0
    assert np.any(ref[0].data["wall_force"] != 0.0) and np.any(ref[0].data["region_force"] != 0.0)


def test_region_ees_too_close_falls_back_and_fails_as_numpy(monkeypatch):
    region, start, boundary = REGIONS["sphere in"]
    d = region_scene(region, start=start, boundary=boundary, eps=0.02, n=10, steps=300, thermo=100)
    d["atoms"].append({"group": "bullet", "create": {"positions": [[6.0, 6.0, 6.0]]}, **ROD,
                       "velocity": {"values": [[0.0, 0.0, 400.0]]}})
    ref, got, eng = check(monkeypatch, [d], compiled=False)
    assert got[0].status == "failed" and "wall/region/ees" in got[0].error
    assert eng.fast.fallbacks >= 1


# ----------------------------------------------------------------------------- samples in the kernel

SAMPLED_OUT = ["step", "time", "dt", "temp", "ke", "pe", "etot", "erot", "press", "atoms"]  # + the fixes' outputs


def sampled_check(monkeypatch, configs, nsamples):
    """Both ways, every output to 1e-14; the compiled run's samples (all but step 0's) came from
    the kernel (AspherePath.advance_sampled: sample blocks, no NumPy outputs), and the same run with
    the kernel's samples switched off (one chunk per sample, NumPy's outputs at its positions) gives
    the same trajectory bit for bit and the same outputs to 1e-14."""
    ref, got, eng = check(monkeypatch, configs)
    assert eng.fast.fallbacks == 0 and eng.fast.sampled_calls > 0
    assert len(eng.samples) == 1 and sum(b[2]["step"].shape[1] for b in eng.sample_blocks) == nsamples
    monkeypatch.setattr(ac, "sampled_eligible", lambda plan: False)
    plain = Engine([build_case(config_from_dict(d)) for d in configs])
    one_by_one = plain.run()
    assert plain.fast.sampled_calls == 0 and not plain.sample_blocks and plain.fast.compiled_chunks == nsamples
    for name in ("x", "v", "quat", "angmom"):
        np.testing.assert_array_equal(getattr(plain.state, name), getattr(eng.state, name), err_msg=name)
    assert_same(one_by_one, got)  # NumPy's vectorised log (closed forms) vs libm's: an ulp at times
    return ref, got, eng


@pytest.mark.parametrize("thermo", [1, 7])
def test_flat_ees_sampled_in_the_kernel(monkeypatch, thermo):
    """Three cases between two wall/ees faces (one on a group of rods, point atoms too), sampled
    every step and every 7th: energies, forces on each face, erot, ke, temp, press from the kernel."""
    dots = {"group": "dots", "create": {"positions": [[4.0, 3.0, 3.0], [4.5, 9.0, 5.0]]}, "mass": 2.0,
            "velocity": {"values": [[0.01, 0.02, 0.3], [-0.01, 0.0, -0.4]]}}
    configs = []
    for eps, sigma, seed in ((2.0, 1.0, 7), (0.7, 1.2, 8), (3.5, 0.8, 9)):
        face = {"coord": "EDGE", "epsilon": eps, "sigma": sigma, "cutoff": 3.0}
        d = slit(n=70, steps=84, thermo=thermo, seed=seed, extra_atoms=(dots,),
                 walls={"lo": {"style": "ees", "units": "box", "group": "rods", "energy": True, "zlo": dict(face)},
                        "hi": {"style": "ees", "units": "box", "group": "rods", "zhi": dict(face)}})
        d["output"]["thermo"] = list(SAMPLED_OUT)
        configs.append(d)
    ref, got, _ = sampled_check(monkeypatch, configs, 84 // thermo)
    for r in got:
        assert np.count_nonzero(r.data["wall_force"][:, 0]) > 84 // thermo // 2
        assert np.count_nonzero(r.data["wall_force"][:, 1]) > 84 // thermo // 2
        assert np.ptp(r.data["erot"]) > 1e-5 and np.ptp(r.data["wall_energy"][:, 0]) > 1e-5


@pytest.mark.parametrize("name", sorted(REGIONS))
def test_region_ees_sampled_in_the_kernel(monkeypatch, name):
    """Every region kind (block and cylinder in: several contacts per atom, summed slot by slot)
    sampled every step, two cases; a flat wall/ees face in the block and cylinder scenes too."""
    region, start, boundary = REGIONS[name]
    configs = [region_scene(region, start=start, boundary=boundary, steps=60, thermo=1),
               region_scene(region, start=start, boundary=boundary, eps=0.8, seed=5, steps=60, thermo=1)]
    for d in configs:
        d["output"]["thermo"] = list(SAMPLED_OUT)
        if boundary[2] == "f" and name != "sphere in":
            d["walls"]["floor"] = {"style": "ees", "units": "box", "energy": True,
                                   "zlo": {"coord": 0.3, "epsilon": 1.0, "sigma": 1.0, "cutoff": 5.0}}
    ref, got, _ = sampled_check(monkeypatch, configs, 60)
    for r in got:
        assert np.count_nonzero(r.data["region_force"]) > 60 and np.ptp(r.data["pe"]) > 1e-5


@pytest.mark.slow
def test_trouble_in_a_sampled_call_falls_back_and_fails_as_numpy(monkeypatch):
    """A rod driven into a weak wall while every 5th step is sampled in the kernel: the call with
    the trouble is handed back (its instants one at a time, NumPy reporting the failure with its
    message); the other case runs on, its later samples from the kernel again."""
    fast_rod = slit(n=20, eps=0.05, steps=400, thermo=5)
    fast_rod["atoms"].append({"group": "bullet", "create": {"positions": [[6.0, 6.0, 4.0]]}, **ROD,
                              "velocity": {"values": [[0.0, 0.0, -30.0]]}})
    calm = slit(n=20, eps=0.05, steps=400, thermo=5, seed=8)
    calm["atoms"].append({"group": "bullet", "create": {"positions": [[6.0, 6.0, 4.0]]}, **ROD,
                          "velocity": {"values": [[0.0, 0.0, 0.1]]}})
    monkeypatch.setattr("wallbatch.engine.engine.SAMPLES_PER_CALL", 16)
    ref, got, eng = check(monkeypatch, [fast_rod, calm])
    assert [r.status for r in got] == ["failed", "ok"]
    assert "Particle on or inside fix wall surface" in got[0].error
    assert eng.fast.fallbacks >= 1 and eng.fast.sampled_calls >= 2 and len(eng.samples) > 1
    assert np.isfinite(got[1].data["pe"]).all() and got[1].data["step"][-1] == 400


def test_threads_over_cases_give_the_bits_of_one_thread(monkeypatch):
    """Three cases (different epsilon, sigma, seeds), samples recorded in the kernel: two threads
    take runs of cases, and every output is the one thread's, bit for bit."""
    configs = [slit(n=150, side=18.0, eps=eps, sigma=sig, seed=seed, cutoff=3.0, steps=1200, thermo=200)
               for eps, sig, seed in ((2.0, 1.0, 7), (0.7, 1.2, 8), (3.5, 0.8, 9))]
    one, eng1, split1 = run_with(monkeypatch, configs, 1)
    two, eng2, split2 = run_with(monkeypatch, configs, 2)
    assert split1 == {"cases": 0, "atoms": 0} and split2["cases"] >= 1 and split2["atoms"] == 0
    assert eng2.fast.fallbacks == 0
    assert eng1.fast.sampled_calls >= 1 and eng2.fast.sampled_calls == eng1.fast.sampled_calls
    for a, b in zip(one, two):
        assert a.status == b.status == "ok"
        for name in a.data:
            np.testing.assert_array_equal(a.data[name], b.data[name], err_msg=name)
    assert np.ptp(two[0].data["erot"]) > 1e-5 and two[0].data["pe"][-1] != two[1].data["pe"][-1]


@pytest.mark.slow
def test_threads_over_the_atoms_of_one_case_give_the_bits_of_one_thread(monkeypatch):
    """One case of 600 ellipsoids with enough steps between samples for two threads: each
    interval's steps but the last are split into runs of atoms, and its last step runs in a call
    that records the sample (its sums over all atoms), on one thread as on two (the path does not
    depend on the thread count), so every output is the one thread's bit for bit; they agree with
    the NumPy path to 1e-14."""
    d = slit(n=600, side=35.0, cutoff=3.0, steps=1400, thermo=700)
    one, eng1, split1 = run_with(monkeypatch, [d], 1)
    two, eng2, split2 = run_with(monkeypatch, [d], 2)
    assert split1["atoms"] == 0 and split2["atoms"] == 2 and split2["cases"] == 0  # one split per interval
    assert eng1.fast.sampled_calls == eng2.fast.sampled_calls == 2  # each interval's last step
    assert eng1.fast.compiled_chunks == eng2.fast.compiled_chunks == 4
    assert len(eng2.samples) == 1  # step 0 only from NumPy
    for a, b in zip(one, two):
        for name in a.data:
            np.testing.assert_array_equal(a.data[name], b.data[name], err_msg=name)
    assert np.ptp(two[0].data["erot"]) > 1e-5
    ref, _, _ = check(monkeypatch, [d])  # the NumPy path: to 1e-14
    assert_same(ref, two)


@pytest.mark.parametrize("in_kernel", [True, False])
def test_long_chunks_take_several_kernel_calls_with_the_same_bits(monkeypatch, in_kernel):
    """A chunk longer than its share of compiled.CALL_WORK (an atom-step counted ASPHERE_STEP_COST
    times) runs as several kernel calls, so a Ctrl-C between them stops the run soon: the
    trajectory and every output are those of one call per chunk, bit for bit."""
    from wallbatch.engine import compiled

    configs = [slit(n=20, eps=2.0, seed=7, steps=120, thermo=40), slit(n=20, eps=0.7, seed=8, steps=120, thermo=40)]
    cases = [build_case(config_from_dict(d)) for d in configs]
    monkeypatch.setenv("WALLBATCH_NUMBA", "1")
    if not in_kernel:
        monkeypatch.setattr(ac, "sampled_eligible", lambda plan: False)
    calls = []
    real = AspherePath._chunk
    monkeypatch.setattr(AspherePath, "_chunk", lambda self, at, *a: (calls.append(int(at[-1])), real(self, at, *a))[1])
    whole = Engine(cases)
    got_whole = whole.run()
    assert calls == ([120] if in_kernel else [40, 40, 40]) and whole.fast.fallbacks == 0
    calls.clear()
    monkeypatch.setattr(compiled, "CALL_WORK", compiled.ASPHERE_STEP_COST * 2 * 20 * 7)  # 7 steps a call
    monkeypatch.setattr(AspherePath, "least_steps", 1)  # (not ASPHERE_MIN_CALL_STEPS)
    split = Engine(cases)
    got_split = split.run()
    # calls of 7 steps at most; with samples in the kernel, a sample's call runs the last 7 steps
    # before it, the steps before those go first in calls of their own (Engine.run: `lead_steps`)
    assert calls == (([7] * 4 + [5, 7]) if in_kernel else ([7] * 5 + [5])) * 3
    assert split.fast.sampled_calls == (3 if in_kernel else 0)
    for name in ("x", "v", "f", "quat", "angmom", "torque"):
        np.testing.assert_array_equal(getattr(split.state, name), getattr(whole.state, name), err_msg=name)
    for a, b in zip(got_split, got_whole):
        for name in a.data:
            np.testing.assert_array_equal(a.data[name], b.data[name], err_msg=name)
    assert np.ptp(got_whole[0].data["erot"]) > 1e-4 and got_whole[0].data["pe"][-1] != got_whole[1].data["pe"][-1]


@pytest.mark.slow
def test_trouble_in_a_later_call_of_a_chunk_fails_as_numpy(monkeypatch):
    """The rod driven into a weak wall with calls of 7 steps: the calls before the trouble stay,
    the rest of the chunk runs in NumPy, which fails the case with its message, as the NumPy
    engine does; the other case runs to the end."""
    from wallbatch.engine import compiled

    monkeypatch.setattr(compiled, "CALL_WORK", compiled.ASPHERE_STEP_COST * 2 * 21 * 7)
    monkeypatch.setattr(AspherePath, "least_steps", 1)
    monkeypatch.setattr(ac, "sampled_eligible", lambda plan: False)
    ref, got, eng = check(monkeypatch, rod_into_a_weak_wall())
    assert [r.status for r in got] == ["failed", "ok"]
    assert "Particle on or inside fix wall surface" in got[0].error and got[0].error == ref[0].error
    assert eng.fast.fallbacks >= 1 and eng.fast.compiled_chunks >= 3
