"""The NumPy step's shortcuts (issue 15, small runs): the kept dt/2m kick array, the in-place wrap
and the lost-atom pre-test give exactly what the plain expressions give."""

from __future__ import annotations

import numpy as np
import pytest
from factories import atoms, box_scene, slab_gas

from wallbatch.config.models import config_from_dict
from wallbatch.engine import backend
from wallbatch.engine.engine import Engine
from wallbatch.scene.build import build_case


def _engine(d: dict, cases: int = 1) -> Engine:
    return Engine([build_case(config_from_dict(d)) for _ in range(cases)])


def _gas(**extra) -> dict:
    lj = {"coord": "EDGE", "epsilon": 1.0, "sigma": 1.0, "cutoff": 2.5}
    return slab_gas({"w": {"style": "lj93", "units": "box", "zlo": lj, "zhi": dict(lj)}}, n=50, hi=(5, 5, 8), margin=1.0,
                    temperature=1.0, seed=4, dt=0.005, steps=10, thermo=5, **extra)


def test_half_kick_is_dt_over_2m_and_follows_dt_and_the_live_cases():
    """dtfm = dt/2 ftm2v / m on all three components, (C, N, 3); kept while dt and the cases stay
    (the same array), rebuilt when dt changes (in place or replaced) or a case leaves the batch."""
    d = box_scene([atoms("a", [(1, 1, 1), (2, 2, 2)], mass=2.0), atoms("b", [(3, 3, 3)], mass=0.5)],
                  units="metal", timestep=0.001)
    eng = _engine(d, cases=2)
    s = eng.state
    want = (0.5 * s.units.ftm2v) * 0.001 / np.array([2.0, 2.0, 0.5])
    k = eng.half_kick(s.dt)
    assert k.shape == (2, 3, 3)
    np.testing.assert_array_equal(k, np.broadcast_to(want[None, :, None], (2, 3, 3)))
    assert eng.half_kick(s.dt) is k  # kept
    s.set_dt(np.array([0.002, 0.001]))
    k2 = eng.half_kick(s.dt)
    np.testing.assert_array_equal(k2[0], 2 * k[0])
    np.testing.assert_array_equal(k2[1], k[1])
    s.dt[1] = 0.004  # changed in place: still noticed
    np.testing.assert_array_equal(eng.half_kick(s.dt)[1], 4 * k[1])
    s.failed = {0: "gone"}
    eng.drop_failed()
    k3 = eng.half_kick(s.dt)
    assert k3.shape == (1, 3, 3)
    np.testing.assert_array_equal(k3[0], 4 * k[1])


def test_wrap_matches_the_masked_update():
    """x -= L where x >= hi, then x += L where x < lo, per periodic dimension, exactly."""
    eng = _engine(_gas(), cases=3)
    s = eng.state
    rng = np.random.default_rng(9)
    s.x[:] = rng.uniform(-6, 11, s.x.shape)
    s.x[0, 0, 0] = s.box_hi[0]  # on hi: wraps to lo
    s.x[1, 0, 1] = s.box_lo[1]  # on lo: stays
    s.x[2, 0, 0] = np.nan  # NaN: left alone
    want = s.x.copy()
    for dim in (0, 1):
        xd = want[:, :, dim]
        length = s.box_hi[dim] - s.box_lo[dim]
        xd[xd >= s.box_hi[dim]] -= length
        xd[xd < s.box_lo[dim]] += length
    eng.wrap()
    np.testing.assert_array_equal(s.x, want)  # NaN in the same place too
    assert s.x[0, 0, 0] == s.box_lo[0] and s.x[1, 0, 1] == s.box_lo[1]


def test_lost_atom_pretest_finds_the_same_atoms():
    """An atom past a fixed face fails its case (first atom named), the others run on; NaN
    positions are not reported as lost here (the sample's NaN check reports them)."""
    eng = _engine(_gas(), cases=3)
    s = eng.state
    s.x[0, 7, 2] = s.box_hi[2] + 0.5
    s.x[0, 3, 2] = s.box_lo[2] - 0.5
    s.x[2, 1, 2] = np.nan
    eng.check_lost()
    assert sorted(s.failed) == [0]
    assert "atom ID 4 left the box through the fixed z boundary" in s.failed[0]
    s.failed = {}
    s.x[0, 7, 2] = s.x[0, 3, 2] = 4.0
    eng.check_lost()
    assert s.failed == {}


def test_constant_faces_skip_evaluation_but_variable_faces_do_not():
    """FaceValues.constant: numbers only; a face with a variable is evaluated (and checked) each
    step: a variable epsilon below 0 fails its case."""
    lj = {"coord": "EDGE", "epsilon": 1.0, "sigma": 1.0, "cutoff": 2.5}
    eng = _engine(_gas())
    assert all(f.constant for f in eng.soft[0].faces)
    d = slab_gas({"w": {"style": "lj93", "units": "box", "zlo": {**lj, "epsilon": "v_eps"}, "zhi": dict(lj)}}, n=50,
                 hi=(5, 5, 8), margin=1.0, temperature=1.0, seed=4, dt=0.005, steps=10, thermo=5,
                 variables={"eps": "1.0 - step"})
    eng = _engine(d)
    lo, hi = eng.soft[0].faces
    assert not lo.constant and hi.constant
    eng.setup()
    assert eng.state.failed == {}
    eng.advance_numpy(2, sample=False)
    assert eng.errors and "variable epsilon evaluated to" in next(iter(eng.errors.values()))


def _fingerprint(eng: Engine) -> str:
    """sha256 of the final positions, velocities and forces of every case and of every sample."""
    import hashlib

    s = eng.state
    h = hashlib.sha256()
    for a in (s.x, s.v, s.f, s.step, s.time):
        h.update(np.ascontiguousarray(a).tobytes())
    for rec in eng.samples:
        for key in sorted(rec):
            h.update(key.encode())
            h.update(np.ascontiguousarray(rec[key]).tobytes())
    return h.hexdigest()


def _numpy_exp_avx512() -> bool:
    """Whether NumPy's np.exp runs its AVX-512 loop on this CPU: its results differ from the AVX2
    loop's in the last bits, so morse (exp) has one digest per loop."""
    try:
        from numpy._core._multiarray_umath import __cpu_features__
    except ImportError:  # NumPy 1.x
        from numpy.core._multiarray_umath import __cpu_features__
    return bool(__cpu_features__.get("AVX512F"))


_AVX512 = _numpy_exp_avx512()

PINNED = {  # the NumPy step's results before the step was fused (issue 15): bit for bit
    "lj93": "f9b3018acc22192ba4fc7e35e24bdc2b14ec6640ec5c03e6063ff739113c3609",
    "harmonic-virial": "05294ba7b0ab9020da2b8073f215bc0c4a83b748bdae4e5131077d776e3fb554",
    # taken on an AVX-512 machine; the other, on an AVX2 one (Zen 3), by the code before the fused
    # step (commit a5ad00c) as by today's
    "morse-group-reflect": ("ce18e8a4538362c4f3bcf0adbd13b345d3f72f9e4d50817b5c4a2e9f1b77afdd" if _AVX512
                            else "04c777be2296ce35e882e6f190be25dcf3fce9b5435b92bd24438a4b1306631a"),
}


PINNED_ONE = {  # the same, one case (seed 11)
    "lj93": "fd3494bdf7d4905ce8e25c0fcfb97f5f592eea8364157485abc24cc282550f7c",
    "harmonic-virial": "8bd62941fd16b7fd8500a9bfbe1f5ece42ef955328a4f5349a1320c3bada1e45",
    "morse-group-reflect": ("754cea9c9ee73b6b02bbb692bfd27284cd668bb57ce03ccf785dcfa90ced2347" if _AVX512
                            else "eaf3a27f898bdc7c26fefbf04edae007022f5f1ee294b413f3a48df5ed2acb36"),
}


def _pinned_scene(kind: str) -> dict:
    if kind == "lj93":
        lj = {"coord": "EDGE", "epsilon": 1.0, "sigma": 1.0, "cutoff": 2.5}
        walls = {"w": {"style": "lj93", "units": "box", "energy": True, "zlo": lj, "zhi": dict(lj)}}
    elif kind == "harmonic-virial":
        h = {"coord": 7.8, "epsilon": 10.0, "sigma": 1.0, "cutoff": 1.5}
        walls = {"w": {"style": "harmonic", "units": "box", "energy": True, "virial": True, "zhi": h, "zlo": dict(h, coord=0.1)}}
    else:
        m = {"coord": "EDGE", "D0": 1.0, "alpha": 1.5, "r0": 1.0, "cutoff": 2.0}
        walls = {"m": {"style": "morse", "units": "box", "energy": True, "group": "gas", "zlo": m, "zhi": dict(m, D0=2.0)},
                 "r": {"style": "reflect", "units": "box", "zlo": 0.05, "zhi": 7.95}}
    return slab_gas(walls, n=200, hi=(6, 6, 8), margin=1.0, temperature=1.5, seed=11, dt=0.005, steps=300,
                    thermo=60, output=["step", "time", "ke", "pe", "etot", "press"] if kind != "lj93" else None)


@pytest.mark.parametrize("ncases", [1, 3])
@pytest.mark.parametrize("kind", sorted(PINNED))
def test_numpy_step_results_pinned_bit_for_bit(kind, ncases):
    """One or three cases of a wall scene (differently seeded) over 300 NumPy steps: final x, v,
    f and every sample hash to the digest taken before the step was rewritten for speed."""
    cases = []
    for seed in (11, 12, 13)[:ncases]:
        d = _pinned_scene(kind)
        d["seed"] = seed
        cases.append(build_case(config_from_dict(d)))
    with backend.plan_path(False):  # the NumPy path (a plan this small runs it anyway)
        eng = Engine(cases)
    assert eng.fast is None
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        eng.setup()
        for _ in range(5):
            eng.advance_numpy(60)
    assert eng.state.ncases == ncases and not eng.state.failed
    assert all(np.any(rec["pe"] != 0.0) for rec in eng.samples[1:])  # atoms feel the walls
    assert _fingerprint(eng) == (PINNED[kind] if ncases == 3 else PINNED_ONE[kind])


def test_wrap_leaves_a_batch_inside_the_box_alone_and_still_wraps_beside_a_nan():
    """The wrap's pre-test: nothing inside the box moves (bit for bit); a NaN does not hide an
    atom that crossed in the same dimension."""
    eng = _engine(_gas(), cases=2)
    s = eng.state
    inside = s.x.copy()
    eng.wrap()
    np.testing.assert_array_equal(s.x, inside)
    s.x[1, 4, 0] = np.nan
    s.x[1, 5, 0] = s.box_hi[0] + 0.25
    s.x[0, 6, 1] = s.box_lo[1] - 0.25
    eng.wrap()
    assert s.x[1, 5, 0] == s.box_hi[0] + 0.25 - (s.box_hi[0] - s.box_lo[0])
    assert s.x[0, 6, 1] == s.box_lo[1] - 0.25 + (s.box_hi[1] - s.box_lo[1])
    assert np.isnan(s.x[1, 4, 0])


@pytest.mark.parametrize("ncases", [1, 3])
def test_an_atom_on_or_behind_a_flat_wall_fails_its_case_only(ncases):
    """The "on or behind the wall" test of a flat soft wall (one reduction when the limit is one
    number): an atom at distance <= 0 from zlo fails its case, named by atom ID and distance; an
    atom just in front does not; the other cases run on."""
    eng = _engine(_gas(), cases=ncases)
    s = eng.state
    zlo = s.box_lo[2]
    bad = ncases - 1  # the last case
    s.x[bad, 4, 2] = zlo - 0.25  # behind the wall: distance -0.25
    s.x[0, 9, 2] = zlo + 1e-9  # just in front: a large force, no failure
    eng.compute_forces(False)
    assert sorted(s.failed) == [bad]
    assert "atom ID 5 at distance -0.25 from the wall" in s.failed[bad]
    assert "on or behind the wall" in s.failed[bad]
    if ncases > 1:
        assert s.f[0, 9, 2] > 1e60  # the atom in front felt the wall (lj93 repulsion ~ r^-10)
