"""The NumPy step's shortcuts (issue 15, small runs): the kept dt/2m kick array, the in-place wrap
and the lost-atom pre-test give exactly what the plain expressions give."""

from __future__ import annotations

import numpy as np
from factories import atoms, box_scene, slab_gas

from wallbatch.config.models import config_from_dict
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
