"""The LAMMPS oracle harness reproduces the reference numbers of physics.md §9, §10 and §15."""

import numpy as np
import pytest

from lammps_oracle import LammpsRunError, Scene, requires_lammps, run_lammps

pytestmark = requires_lammps

CENTER = 5.0
LATTICE_FCC_08442 = 1.6795961913825073  # physics.md §2.1


def one_atom(x=1.2, v=(0.0, 0.0, 0.0), m=1.0, units="lj", boundary=("f", "p", "p"), **kw):
    return Scene(
        units=units,
        box_lo=(0.0, 0.0, 0.0),
        box_hi=(10.0, 10.0, 10.0),
        boundary=boundary,
        x=np.array([[x, CENTER, CENTER]]),
        v=np.array([v], dtype=float),
        mass=np.array([m]),
        **kw,
    )


def test_lj93_xlo_run0_matches_reference():
    scene = one_atom(
        fixes=["fix w all wall/lj93 xlo 0.0 1.0 1.0 2.5 units box"],
        outputs=["f_w", "f_w[1]", "pe", "ke"],
    )
    out = run_lammps(scene)
    assert out["step"].tolist() == [0.0]
    assert out["f_w"][0] == -0.48889776297466175
    assert out["f_w[1]"][0] == 1.2529525597914448
    assert out["pe"][0] == 0.0  # no fix_modify energy: the wall is not in pe
    assert out["ke"][0] == 0.0
    assert all(a.dtype == np.float64 for a in out.values())


def test_lj93_xhi_run0_matches_reference():
    scene = one_atom(
        x=10.0 - 1.2,
        fixes=["fix w all wall/lj93 xhi 10.0 1.0 1.0 2.5 units box"],
        outputs=["f_w", "f_w[1]"],
    )
    out = run_lammps(scene)
    assert out["f_w"][0] == pytest.approx(-0.48889776297466253, rel=1e-14)
    assert out["f_w[1]"][0] == pytest.approx(-1.2529525597914466, rel=1e-14)


def test_dt_reset_reference_sequence():
    scene = one_atom(
        v=(1.0, 0.0, 0.0),
        boundary=("p", "p", "p"),
        fixes=[
            "fix f all addforce 2.0 0.0 0.0",
            "fix d all dt/reset 1 NULL NULL 0.1 units box",
        ],
        steps=3,
        thermo_every=1,
        outputs=["step", "time", "dt", "f_d"],
    )
    out = run_lammps(scene)
    assert out["step"].tolist() == [0, 1, 2, 3]
    assert out["dt"][:3].tolist() == [
        0.09090909090909091,
        0.07896189950303702,
        0.07070219631545765,
    ]
    np.testing.assert_allclose(
        out["time"], [0.0, 0.09090909090909091, 0.16987099041212794, 0.2405731867275856], rtol=1e-15
    )
    # time at step n = sum of the dt used by the previous steps
    np.testing.assert_allclose(out["time"][1:], np.cumsum(out["dt"][:-1]), rtol=1e-15)
    # the scalar is the step at which dt last changed
    assert out["f_d"].tolist() == [0, 1, 2, 3]


def test_dt_reset_metal_emax_setup():
    scene = one_atom(
        units="metal",
        m=10.0,
        v=(5.0, 0.0, 0.0),
        boundary=("p", "p", "p"),
        fixes=[
            "fix f all addforce 3.0 0.0 0.0",
            "fix d all dt/reset 1 NULL NULL 0.05 units box emax 0.5",
        ],
        outputs=["dt"],
    )
    out = run_lammps(scene)
    assert out["dt"][0] == pytest.approx(0.003701865534094182, rel=1e-15)


def test_ramp_variable_every_step_equals_formula():
    x0, x1, steps = 1.5, 3.25, 7
    scene = one_atom(
        boundary=("p", "p", "p"),
        variables={"r": f"ramp({x0},{x1})"},
        timestep=0.1,
        steps=steps,
        thermo_every=1,
        outputs=["v_r", "time", "dt"],
    )
    out = run_lammps(scene)
    n = np.arange(steps + 1, dtype=float)
    np.testing.assert_array_equal(out["step"], n)
    expected = x0 + (n - 0) / (steps - 0) * (x1 - x0)
    np.testing.assert_allclose(out["v_r"], expected, rtol=1e-15, atol=0)
    assert out["v_r"][0] == x0 and out["v_r"][-1] == x1
    np.testing.assert_allclose(out["time"], 0.1 * n, rtol=1e-15)
    assert np.all(out["dt"] == 0.1)


def test_sampling_first_every_and_last_step():
    scene = one_atom(boundary=("p", "p", "p"), steps=7, thermo_every=3, outputs=["step"])
    assert run_lammps(scene)["step"].tolist() == [0, 3, 6, 7]
    scene = one_atom(boundary=("p", "p", "p"), steps=5, thermo_every=0, outputs=["step"])
    assert run_lammps(scene)["step"].tolist() == [0, 5]


def test_groups_and_fix_modify_energy():
    # §15: 2 atoms, one of them in the wall's group; pe counts only that one
    scene = Scene(
        units="lj",
        box_lo=(0.0, 0.0, 0.0),
        box_hi=(10.0, 10.0, 10.0),
        boundary=("f", "p", "p"),
        x=np.array([[1.2, 5.0, 5.0], [1.2, 2.0, 2.0]]),
        v=np.zeros((2, 3)),
        mass=np.array([1.0, 1.0]),
        groups={"g": np.array([0])},
        fixes=[
            "fix w g wall/lj93 xlo 0.0 1.0 1.0 2.5 units box",
            "fix_modify w energy yes",
        ],
        outputs=["pe", "f_w", "etot"],
    )
    out = run_lammps(scene)
    assert out["f_w"][0] == -0.48889776297466175
    assert out["pe"][0] == -0.48889776297466175  # thermo norm no
    assert out["etot"][0] == -0.48889776297466175


def test_lattice_scales_wall_position():
    # wall at 1.0 lattice spacing; the atom sits 1.2 away from it
    xw = LATTICE_FCC_08442
    scene = one_atom(
        x=xw + 1.2,
        lattice="fcc 0.8442",
        fixes=["fix w all wall/lj93 xlo 1.0 1.0 1.0 2.5"],
        outputs=["f_w", "f_w[1]"],
    )
    out = run_lammps(scene)
    assert out["f_w"][0] == pytest.approx(-0.48889776297466175, rel=1e-12)
    assert out["f_w[1]"][0] == pytest.approx(1.2529525597914448, rel=1e-12)


@pytest.mark.parametrize("with_radius", [False, True])
def test_per_atom_masses_and_velocities_are_exact(with_radius):
    rng = np.random.default_rng(7)
    n = 20
    mass = rng.uniform(0.5, 3.0, n)  # all distinct
    v = rng.normal(0.0, 1.0, (n, 3))
    scene = Scene(
        units="real",
        box_lo=(-5.0, -5.0, -5.0),
        box_hi=(5.0, 5.0, 5.0),
        boundary=("p", "p", "p"),
        x=rng.uniform(-4.0, 4.0, (n, 3)),
        v=v,
        mass=mass,
        radius=np.full(n, 0.5) if with_radius else None,
        outputs=["ke", "temp"],
    )
    out = run_lammps(scene)
    mvv2e = 48.88821291**2
    boltz = 0.0019872067
    ke = 0.5 * mvv2e * np.sum(mass[:, None] * v**2)
    assert out["ke"][0] == pytest.approx(ke, rel=1e-13)
    assert out["temp"][0] == pytest.approx(2 * ke / ((3 * n - 3) * boltz), rel=1e-13)


def test_free_flight_and_periodic_wrap():
    # 2 atoms crossing the periodic x boundary several times: KE constant, time = n dt
    scene = Scene(
        units="lj",
        box_lo=(0.0, 0.0, 0.0),
        box_hi=(10.0, 10.0, 10.0),
        boundary=("p", "p", "p"),
        x=np.array([[9.0, 5.0, 5.0], [1.0, 2.0, 2.0]]),
        v=np.array([[1.5, 0.0, 0.0], [-2.0, 0.5, 0.0]]),
        mass=np.array([1.0, 2.0]),
        timestep=0.5,
        steps=40,
        thermo_every=4,
        outputs=["ke", "time"],
    )
    out = run_lammps(scene)
    assert np.all(out["ke"] == 0.5 * 1.5**2 + 0.5 * 2.0 * (4.0 + 0.25))
    np.testing.assert_allclose(out["time"], 0.5 * out["step"], rtol=1e-15)


def test_single_atom_thermo_ke_is_zero():
    # LAMMPS quirk: thermo ke = dof/2 * kB * T and one atom has 3N - 3 = 0 dof
    out = run_lammps(one_atom(v=(1.0, 0.0, 0.0), boundary=("p", "p", "p"), outputs=["ke", "temp"]))
    assert out["ke"][0] == 0.0 and out["temp"][0] == 0.0


def test_bad_fix_raises_with_lammps_message():
    scene = one_atom(fixes=["fix d all dt/reset 1 NULL NULL INF"])
    with pytest.raises(LammpsRunError, match="INF"):
        run_lammps(scene)


def test_many_calls_in_one_process():
    scene = one_atom(
        fixes=["fix w all wall/lj93 xlo 0.0 1.0 1.0 2.5 units box"], outputs=["f_w"]
    )
    values = {run_lammps(scene)["f_w"][0] for _ in range(5)}
    assert values == {-0.48889776297466175}
