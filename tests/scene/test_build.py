"""wallbatch.scene.build through the shared factories (tests/factories.py): the Case of a config
dict, YAML text or file is the same; explicit atoms arrive exactly; random creation fills its
region uniformly; thermal velocities have zero momentum and exactly the asked temperature (LAMMPS
`velocity create ... mom yes`: 3N - 3 degrees of freedom); the random stream depends on the
master seed and the case's seed key only."""

from __future__ import annotations

import math
import pickle

import numpy as np
import pytest
from factories import atoms, box_scene, case_of, config_of, slab_gas

from wallbatch.units import UNIT_SYSTEMS

WALLS = {"w": {"style": "lj93", "units": "box",
               "zlo": {"coord": 0.0, "epsilon": 1.0, "sigma": 1.0, "cutoff": 2.5},
               "zhi": {"coord": 8.0, "epsilon": 1.0, "sigma": 1.0, "cutoff": 2.5}}}


def gas(n: int = 400, temperature: float = 1.5, seed: int = 7) -> dict:
    return slab_gas(WALLS, n=n, hi=(6.0, 5.0, 8.0), margin=1.6, temperature=temperature, seed=seed, dt=0.005,
                    steps=10, thermo=5)


def test_explicit_atoms_arrive_bit_exactly_and_dt_defaults_to_the_unit_system():
    x = [(1.0, 2.0, 3.0), (0.1 + 0.2, 9.999999999999998, 5e-324)]
    v = [(0.3, -1e-17, 2.0), (-0.7, 0.0, 1.0 / 3.0)]
    for units in ("lj", "real", "metal"):
        case = case_of(box_scene([atoms("a", x, v, mass=2.5)], units=units, timestep=None))
        assert case.x.tolist() == [list(p) for p in x] and case.v.tolist() == [list(p) for p in v]
        assert case.mass.tolist() == [2.5, 2.5] and case.periodic.tolist() == [False] * 3
        assert case.dt == {"lj": 0.005, "real": 1.0, "metal": 0.001}[units]  # LAMMPS's default timesteps


def test_dict_yaml_text_file_and_config_give_the_same_case(tmp_path):
    text = """\
units: lj
seed: 7
box: {lo: [0, 0, 0], hi: [6.0, 5.0, 8.0], boundary: [p, p, f]}
atoms:
  - group: gas
    create: {random: {count: 400, region: mid}}
    mass: 1.0
    velocity: {temperature: 1.5}
regions:
  mid: {style: block, lo: [0, 0, 1.6], hi: [6.0, 5.0, 6.4], units: box}
walls:
  w: {style: lj93, units: box, zlo: {coord: 0.0, epsilon: 1.0, sigma: 1.0, cutoff: 2.5},
      zhi: {coord: 8.0, epsilon: 1.0, sigma: 1.0, cutoff: 2.5}}
timestep: 0.005
run: {steps: 10, thermo: 5}
"""
    path = tmp_path / "gas.yaml"
    path.write_text(text)
    ref = case_of(gas())
    for scene in (text, path, config_of(gas())):
        case = case_of(scene)
        assert np.array_equal(case.x, ref.x) and np.array_equal(case.v, ref.v)
        assert np.array_equal(case.mass, ref.mass) and case.dt == ref.dt and case.steps == ref.steps


@pytest.mark.parametrize("temperature", [0.5, 1.5])
def test_thermal_velocities_have_zero_momentum_and_the_exact_temperature(temperature):
    case = case_of(gas(temperature=temperature))
    n, m, v = case.natoms, case.mass, case.v
    assert n == 400 and np.all(m == 1.0)
    assert np.abs((m[:, None] * v).sum(axis=0)).max() < 1e-12
    lj = UNIT_SYSTEMS["lj"]
    t = lj.mvv2e * float((m[:, None] * v * v).sum()) / ((3 * n - 3) * lj.boltz)
    assert t == pytest.approx(temperature, rel=1e-13)
    # each component is Gaussian with variance kT/m: the sample variance within 4 standard errors
    # (the variance of a sample variance of n Gaussians is 2 s^4 / (n - 1))
    for d in range(3):
        var = float(v[:, d].var(ddof=1))
        assert abs(var - temperature) < 4 * temperature * math.sqrt(2.0 / (n - 1)), (d, var)


def two_groups(shared: tuple = ("all", "all"), temps: tuple = (0.5, 0.5), n: tuple = (30, 50)) -> dict:
    """Two groups of different masses in a periodic box, each velocity drawn at temps[k], with
    the label shared[k] (None: no label)."""
    rng = np.random.default_rng(3)
    groups = []
    for k, (name, mass) in enumerate((("light", 1.0), ("heavy", 3.0))):
        vel = {"temperature": temps[k]} | ({"shared": shared[k]} if shared[k] else {})
        groups.append({"group": name, "create": {"positions": (rng.random((n[k], 3)) * 10.0).tolist()},
                       "mass": mass, "velocity": vel})
    return {"units": "lj", "seed": 11, "box": {"lo": [0, 0, 0], "hi": [10.0, 10.0, 10.0], "boundary": ["p"] * 3},
            "atoms": groups, "timestep": 0.005, "run": {"steps": 1, "thermo": 1}}


def test_a_shared_velocity_set_has_zero_momentum_and_the_temperature_over_all_its_atoms():
    """Two groups sharing one label are drawn as one set (LAMMPS `velocity all create`): zero net
    momentum and exactly T over their 80 atoms (3 n - 3 dof), while each group alone has neither;
    without the label each group has both on its own, so the whole's temperature is lower, by
    the 3 dof the second group's momentum removes."""
    lj, T = UNIT_SYSTEMS["lj"], 0.5

    def temp(m, v, dof):
        return lj.mvv2e * float((m[:, None] * v * v).sum()) / (dof * lj.boltz)

    case = case_of(two_groups())
    m, v = case.mass, case.v  # the groups' atoms in order: 30 light, then 50 heavy
    assert len(m) == 80 and m[29] == 1.0 and m[30] == 3.0
    assert np.abs((m[:, None] * v).sum(axis=0)).max() < 1e-13
    assert temp(m, v, 3 * 80 - 3) == pytest.approx(T, rel=1e-13)
    light = slice(0, 30)
    assert np.abs((m[light, None] * v[light]).sum(axis=0)).max() > 1e-3  # a part of the set only
    apart = case_of(two_groups(shared=(None, None)))
    for sel in (slice(0, 30), slice(30, 80)):
        n = sel.stop - sel.start
        assert np.abs((apart.mass[sel, None] * apart.v[sel]).sum(axis=0)).max() < 1e-13
        assert temp(apart.mass[sel], apart.v[sel], 3 * n - 3) == pytest.approx(T, rel=1e-13)
    assert temp(apart.mass, apart.v, 3 * 80 - 3) == pytest.approx(T * (3 * 80 - 6) / (3 * 80 - 3), rel=1e-13)


def test_a_shared_set_of_one_group_draws_what_a_group_without_the_label_draws():
    """The label changes nothing for a group alone in its set (the same draws, the same bits), and
    the groups after it draw the same numbers."""
    alone = case_of(two_groups(shared=("a", "b")))
    plain = case_of(two_groups(shared=(None, None)))
    assert np.array_equal(alone.v, plain.v) and np.array_equal(alone.x, plain.x)


def test_groups_of_one_shared_set_must_give_the_same_temperature():
    with pytest.raises(Exception) as err:
        config_of(two_groups(temps=(0.5, 0.7)))
    text = str(err.value)
    assert "atoms.1.velocity.temperature" in text and "shares the velocity set 'all'" in text
    assert "group light" in text and "0.5" in text and "0.7" in text
    with pytest.raises(Exception, match="needs a temperature, not values"):
        config_of(box_scene([{"group": "a", "create": {"positions": [[1.0, 1.0, 1.0], [2.0, 2.0, 2.0]]},
                              "mass": 1.0, "velocity": {"values": [0.0, 0.0, 1.0], "shared": "s"}}]))


def test_random_creation_fills_the_region_uniformly():
    case = case_of(gas(n=3000))
    x = case.x
    assert np.all(x >= [0.0, 0.0, 1.6]) and np.all(x <= [6.0, 5.0, 6.4])
    # uniform on [a, b]: mean (a + b)/2, variance (b - a)^2/12; mean within 4 standard errors,
    # variance within 4 of its standard errors ((b - a)^4 / 180 / n for the uniform's 4th moment)
    for d, (a, b) in enumerate([(0.0, 6.0), (0.0, 5.0), (1.6, 6.4)]):
        mean, var, n = float(x[:, d].mean()), float(x[:, d].var(ddof=1)), len(x)
        length = b - a
        assert abs(mean - (a + b) / 2) < 4 * length / math.sqrt(12 * n), (d, mean)
        assert abs(var - length**2 / 12) < 4 * length**2 * math.sqrt(1 / 180 / n), (d, var)


def test_random_stream_depends_on_seed_and_seed_key_only():
    a, again = case_of(gas()), case_of(gas())
    assert np.array_equal(a.x, again.x) and np.array_equal(a.v, again.v)  # bit-identical
    b = case_of(gas(seed=8))
    k0, k1, k1_again = case_of(gas(), (0,)), case_of(gas(), (1,)), case_of(gas(), (1,))
    assert np.array_equal(k1.x, k1_again.x) and np.array_equal(k1.v, k1_again.v)
    for other in (b, k1):
        assert not np.any(np.all(other.x == a.x, axis=1))  # no atom at the same place
    assert not np.any(np.all(k0.x == k1.x, axis=1))
    # (key (0,) is key () again: NumPy's SeedSequence([seed, 0]) is SeedSequence([seed]))


def test_point_atoms_beside_ellipsoids_are_unrotated_and_still():
    """A group without a shape is point atoms: semi-axes 0, the identity quaternion, no angular
    momentum, and it draws nothing from the stream (an ellipsoid group's random orientations are
    the same whether a point group comes first or not)."""
    ell = {"group": "e", "create": {"random": {"count": 5}}, "mass": 1.0, "shape": [0.5, 0.3, 0.2],
           "orientation": "random"}
    point = {"group": "p", "create": {"positions": [[1.0, 1.0, 1.0], [2.0, 2.0, 2.0], [3.0, 3.0, 3.0]]},
             "mass": 1.0}
    base = slab_gas(WALLS, n=4, hi=(6.0, 5.0, 8.0), margin=1.6, temperature=1.0, seed=3, dt=0.005, steps=1, thermo=1)
    both = case_of({**base, "atoms": [point, ell]})
    alone = case_of({**base, "atoms": [ell]})
    assert np.array_equal(both.shape[:3], np.zeros((3, 3)))
    assert np.array_equal(both.quat[:3], np.tile([1.0, 0.0, 0.0, 0.0], (3, 1)))
    assert np.array_equal(both.angmom[:3], np.zeros((3, 3)))
    assert np.array_equal(both.quat[3:], alone.quat) and not np.array_equal(alone.quat[0], [1.0, 0.0, 0.0, 0.0])
    assert np.allclose(np.linalg.norm(alone.quat, axis=1), 1.0, rtol=0, atol=1e-15)


def test_a_pair_cutoff_of_half_the_periodic_box_is_a_case_error_naming_pair_cutoff():
    """A cutoff of half a periodic length or more (a real-units script: lj/cut 8.5 in a 15.78 box,
    which LAMMPS runs with ghost images) failed the run as an "internal error (ValueError ...);
    please report it". It is now the case's error, naming pair.cutoff and what to change."""
    from wallbatch.scene.case import CaseError

    cfg = gas()
    cfg["pair"] = {"style": "lj/cut", "epsilon": 1.0, "sigma": 1.0, "cutoff": 2.4999999}
    case_of(cfg)  # 2 x 2.4999999 < 5 and 6: builds
    cfg["pair"]["cutoff"] = 2.5
    with pytest.raises(CaseError) as err:
        case_of(cfg)
    assert str(err.value).endswith(
        "pair.cutoff: 2.5 must be less than half the periodic box length 5 along y (wallbatch takes each "
        "pair's nearest image; LAMMPS would use more than one): make the box longer than 5 along y or the cutoff "
        "shorter"), str(err.value)
    assert err.value.key == "pair.cutoff"  # (placed by it in a run: file:line:col of pair.cutoff)
    copy = pickle.loads(pickle.dumps(err.value))  # (as a case built in another process)
    assert (str(copy), copy.key) == (str(err.value), "pair.cutoff")


def _two_groups(velocity_a: dict, velocity_b: dict, *, dimension: int = 3, seed: int = 7) -> dict:
    """A light and a heavy group (7 and 5 atoms) created at random, then a third group without
    velocities created after them (its positions come later in the random stream)."""
    hi = [6.0, 5.0, 8.0] if dimension == 3 else [6.0, 5.0, 0.5]
    lo = [0.0, 0.0, 0.0] if dimension == 3 else [0.0, 0.0, -0.5]
    boundary = ["p", "p", "f" if dimension == 3 else "p"]
    d = {"units": "lj", "seed": seed, "box": {"lo": lo, "hi": hi, "boundary": boundary},
         "atoms": [{"group": "a", "create": {"random": {"count": 7}}, "mass": 1.0, "velocity": velocity_a},
                   {"group": "b", "create": {"random": {"count": 5}}, "mass": 3.0, "velocity": velocity_b},
                   {"group": "c", "create": {"random": {"count": 4}}, "mass": 1.0}],
         "run": {"steps": 1, "thermo": 1}}
    if dimension == 2:
        d["dimension"] = 2
    return d


def _set_temperature(case, dimension: int = 3) -> tuple[np.ndarray, float]:
    """Net momentum and kinetic temperature (d N - d degrees of freedom) of groups a and b."""
    lj = UNIT_SYSTEMS["lj"]
    m, v = case.mass[:12], case.v[:12]
    t = lj.mvv2e * float((m[:, None] * v * v).sum()) / ((dimension * 12 - dimension) * lj.boltz)
    return (m[:, None] * v).sum(axis=0), t


@pytest.mark.parametrize("dimension", [3, 2])
def test_a_shared_velocity_set_has_zero_momentum_and_exactly_its_temperature(dimension):
    """Two groups with `shared: all` are one draw (LAMMPS's `velocity all create 0.5 SEED` over
    two atom types): zero net momentum of the set and exactly T over d N - d degrees of freedom of
    the set. Without the key each group is scaled on its own, so the set's temperature is
    T (d N - 2d) / (d N - d) (0.4545... for 12 atoms in 3-D): not LAMMPS's start temperature."""
    shared = {"temperature": 0.5, "shared": "all"}
    case = case_of(_two_groups(shared, shared, dimension=dimension))
    p, t = _set_temperature(case, dimension)
    assert np.abs(p).max() < 1e-13 and abs(t - 0.5) < 1e-12, (p, t)
    if dimension == 2:
        assert np.all(case.v[:, 2] == 0.0)
    assert np.all(case.v[12:] == 0.0)  # group c: at rest
    # the groups' own momenta are not zero (one draw, not two)
    assert np.abs(case.v[:7].sum(axis=0)).max() > 1e-3
    alone = case_of(_two_groups({"temperature": 0.5}, {"temperature": 0.5}, dimension=dimension))
    _, t_alone = _set_temperature(alone, dimension)
    assert t_alone == pytest.approx(0.5 * (dimension * 12 - 2 * dimension) / (dimension * 12 - dimension), rel=1e-13)
    # the draws take the same numbers from the stream: the later group's positions are unchanged
    assert np.array_equal(case.x, alone.x)
    again = case_of(_two_groups(shared, shared, dimension=dimension))
    assert np.array_equal(case.v, again.v)  # bit-identical for the same config and seed
    other = case_of(_two_groups(shared, shared, dimension=dimension), (1,))
    assert np.array_equal(other.v, case_of(_two_groups(shared, shared, dimension=dimension), (1,)).v)
    assert not np.array_equal(other.v, case.v)
