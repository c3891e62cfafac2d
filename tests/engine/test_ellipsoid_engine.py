"""Ellipsoids, wall/ees and region walls through the whole pipeline (config -> Case -> engine)."""

from __future__ import annotations

import numpy as np
import pytest
from factories import run_ok as run

from wallbatch.config.models import load_config_text
from wallbatch.engine.engine import run_cases
from wallbatch.scene.case import CaseError
from wallbatch.scene.build import build_case

SLIT = """
units: lj
seed: 3
box: {{lo: [0, 0, 0], hi: [8, 8, 8], boundary: [p, p, f]}}
regions:
  middle: {{style: block, lo: [0, 0, 2.5], hi: [8, 8, 5.5], units: box}}
atoms:
  - group: rods
    create: {{random: {{count: 12, region: middle, overlap: 2.1}}}}
    mass: 1.5
    shape: {shape}
    orientation: {orientation}
    angmom: {{values: [0.1, -0.2, 0.3]}}
    velocity: {{temperature: 1.0}}
walls:
  slit: {{style: ees, units: box, energy: true, zlo: [EDGE, 3.0, 1.0, 7.99], zhi: [EDGE, 3.0, 1.0, 7.99]}}
timestep: {dt}
run: {{steps: {steps}, thermo: {steps}}}
output: {{thermo: [step, time, dt, temp, ke, pe, etot, erot]}}
"""


def drift(dt: float, shape: str = "[1.0, 0.4, 0.6]", orientation: str = "random") -> float:
    steps = int(round(1.5 / dt))
    d = run(SLIT.format(shape=shape, orientation=orientation, dt=dt, steps=steps)).data["etot"]
    return abs(d[-1] - d[0])


@pytest.mark.slow  # 1-3 s: kept out of the fast subset's one-minute budget
def test_tumbling_ellipsoids_between_ees_walls_conserve_energy_to_second_order():
    """nve/asphere + wall/ees: translational + rotational + wall energy, error O(dt^2). The cut-off
    spans the slit, so no atom crosses it (the ees energy is not shifted)."""
    coarse, fine = drift(0.004), drift(0.002)
    assert coarse > 1e-7  # the walls are felt
    assert 3.0 < coarse / fine < 5.5, (coarse, fine)


def test_rotational_energy_enters_ke_and_temp_is_translational():
    res = run(SLIT.format(shape="[1.0, 0.4, 0.6]", orientation="random", dt=0.002, steps=50))
    d = res.data
    assert np.all(d["erot"] > 0)
    n = 12
    ke_trans = d["temp"] * (3 * n - 3) / 2.0
    np.testing.assert_allclose(d["ke"], ke_trans + d["erot"], rtol=1e-12)
    np.testing.assert_allclose(d["etot"], d["ke"] + d["pe"], rtol=1e-12)


def test_initial_rotational_energy_is_half_L_dot_omega():
    text = SLIT.format(shape="[1.0, 0.4, 0.6]", orientation="aligned", dt=0.002, steps=10)
    res = run(text)
    m, (a, b, c) = 1.5, (1.0, 0.4, 0.6)
    inertia = 0.2 * m * np.array([b * b + c * c, a * a + c * c, a * a + b * b])
    L = np.array([0.1, -0.2, 0.3])
    assert res.data["erot"][0] == pytest.approx(12 * 0.5 * np.sum(L * L / inertia), rel=1e-13)


def test_sphere_shaped_ellipsoids_move_like_point_particles():
    """Equal semi-axes: no torque, the orientation plays no part; positions and velocities equal
    those of point atoms against a wall with the same force law (ees with sigma_n = R)."""
    text = SLIT.format(shape="[0.5, 0.5, 0.5]", orientation="[0.3, 0.5, -0.2, 0.7]", dt=0.002, steps=400)
    case = build_case(load_config_text(text))
    other = build_case(load_config_text(text.replace("orientation: [0.3, 0.5, -0.2, 0.7]", "orientation: aligned")))
    from wallbatch.engine.engine import Engine

    e1, e2 = Engine([case]), Engine([other])
    e1.run()
    e2.run()
    np.testing.assert_allclose(e1.state.x, e2.state.x, rtol=0, atol=1e-12)
    np.testing.assert_allclose(e1.state.v, e2.state.v, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(e1.state.angmom, e2.state.angmom)  # no torque: L never changes
    np.testing.assert_allclose(e1.state.angmom[0], np.tile([0.1, -0.2, 0.3], (12, 1)), rtol=0, atol=0)


def test_point_atoms_carry_no_orientation_state():
    text = SLIT.format(shape="[1.0, 0.4, 0.6]", orientation="random", dt=0.002, steps=10)
    plain = text.replace("    shape: [1.0, 0.4, 0.6]\n    orientation: random\n    angmom: {values: [0.1, -0.2, 0.3]}\n",
                         "").replace("style: ees", "style: lj93").replace(", erot]", "]")
    case = build_case(load_config_text(plain))
    assert case.shape is None and case.quat is None and case.angmom is None
    from wallbatch.engine.engine import Engine

    assert Engine([case]).state.quat is None


def test_ees_atom_inside_the_wall_fails_the_case_with_the_lammps_meaning():
    text = SLIT.format(shape="[1.0, 0.4, 0.6]", orientation="aligned", dt=0.002, steps=10)
    text = text.replace("create: {random: {count: 12, region: middle, overlap: 2.1}}",
                        "create: {positions: [[4, 4, 0.45], [4, 4, 4]]}")
    res = run_cases([build_case(load_config_text(text))])[0]
    assert res.status == "failed"
    assert "walls.slit (wall/ees zlo): atom ID 1 " in res.error and "Particle on or inside fix wall surface" in res.error


def test_ees_wall_on_point_atoms_is_an_error():
    text = SLIT.format(shape="[1.0, 0.4, 0.6]", orientation="aligned", dt=0.002, steps=10)
    text = text.replace("    velocity: {temperature: 1.0}\n", "    velocity: {temperature: 1.0}\n"
                        "  - group: dots\n    create: {positions: [[1, 1, 4]]}\n    mass: 1.0\n")
    from wallbatch.config.source import ConfigError

    with pytest.raises(ConfigError, match="walls.slit.group: wall/ees requires ellipsoids"):
        load_config_text(text)


def test_quaternions_are_normalised_and_read_from_npz(tmp_path):
    q = np.array([[2.0, 0.0, 0.0, 0.0], [1.0, 1.0, 0.0, 0.0]])
    np.savez(tmp_path / "s.npz", x=np.array([[4.0, 4.0, 3.0], [4.0, 4.0, 5.0]]), shape=np.array([[1, .5, .5]] * 2),
             quat=q, angmom=np.zeros((2, 3)), mass=np.ones(2))
    text = SLIT.format(shape="[1.0, 0.4, 0.6]", orientation="aligned", dt=0.002, steps=10)
    text = text.replace("""    create: {random: {count: 12, region: middle, overlap: 2.1}}
    mass: 1.5
    shape: [1.0, 0.4, 0.6]
    orientation: aligned
    angmom: {values: [0.1, -0.2, 0.3]}
""", "    create: {file: s.npz}\n")
    from pathlib import Path

    case = build_case(load_config_text(text, base=Path(tmp_path)))
    np.testing.assert_allclose(case.quat, [[1, 0, 0, 0], [2 ** -0.5, 2 ** -0.5, 0, 0]], rtol=1e-15)
    with pytest.raises(CaseError, match="orientation"):
        np.savez(tmp_path / "s.npz", x=np.array([[4.0, 4.0, 3.0]]), shape=np.array([[1, .5, .5]]),
                 quat=np.zeros((1, 4)), mass=np.ones(1))
        build_case(load_config_text(text, base=Path(tmp_path)))


REGION = """
units: lj
seed: 4
box: {{lo: [0, 0, 0], hi: [10, 10, 10], boundary: [f, f, f]}}
regions:
  cage: {{style: {style}, {geometry}, side: {side}, units: box}}
  start: {{style: sphere, center: [5, 5, 5], radius: {start}, side: {side}, units: box}}
atoms:
  - group: gas
    create: {{random: {{count: 30, region: start}}}}
    mass: 1.0
    radius: 0.3
    velocity: {{temperature: 1.0}}
walls:
  cage: {{style: region, region: cage, potential: {potential}, {params}, cutoff: {cutoff}, energy: true}}
timestep: {dt}
run: {{steps: {steps}, thermo: {steps}}}
"""

REGION_CASES = {
    "block-in-lj93": dict(style="block", geometry="lo: [1, 1, 1], hi: [9, 9, 9]", side="in", start=3.5,
                          potential="lj93", params="epsilon: 1.0, sigma: 1.0", cutoff=8.5),
    "sphere-in-colloid": dict(style="sphere", geometry="center: [5, 5, 5], radius: 4.5", side="in", start=3.5,
                              potential="colloid", params="epsilon: 1.0, sigma: 1.0", cutoff=5.0),
    "cylinder-in-morse": dict(style="cylinder", geometry="axis: z, center: [5, 5], radius: 4.5, lo: 0.5, hi: 9.5",
                              side="in", start=3.5, potential="morse", params="D0: 1.0, alpha: 2.0, r0: 1.2",
                              cutoff=9.5),
}


@pytest.mark.parametrize("name", list(REGION_CASES))
def test_region_walls_conserve_energy_to_second_order(name):
    """The cut-offs reach every point of the region, so no contact crosses its cut-off (where the
    force jumps and energy conservation drops to first order, as in LAMMPS)."""
    def err(dt: float) -> float:
        steps = int(round(2.0 / dt))
        d = run(REGION.format(**REGION_CASES[name], dt=dt, steps=steps)).data
        return abs(d["etot"][-1] - d["etot"][0])

    coarse, fine = err(0.004), err(0.002)
    assert coarse > 1e-9
    assert 3.0 < coarse / fine < 5.5, (coarse, fine)


def test_region_force_is_the_reaction_of_the_wall_forces():
    """At rest, every atom's force is its wall force: region_force = -(sum of atom forces)."""
    text = REGION.format(**REGION_CASES["block-in-lj93"], dt=0.002, steps=1).replace(
        "velocity: {temperature: 1.0}", "velocity: {values: [0, 0, 0]}")
    from wallbatch.engine.engine import Engine

    eng = Engine([build_case(load_config_text(text))])
    out = eng.compute_forces(True)
    energy, vector = out["cage"]
    np.testing.assert_allclose(vector[0], -eng.state.f[0].sum(axis=0), rtol=1e-13, atol=1e-15)
    assert energy[0] != 0.0
