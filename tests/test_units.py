"""Tests for wallbatch.units and their use by the engine: LAMMPS constants and default timesteps
(physics.md §2), lattice spacings (§2.1), temperature / kinetic energy / acceleration in real and
metal units. Expected values are the numbers printed in physics.md, not the module's own."""

from __future__ import annotations

import numpy as np
import pytest

from wallbatch.config.models import config_from_dict
from wallbatch.engine.engine import Engine
from wallbatch.batch.runner import run_config
from wallbatch.scene.build import build_case
from wallbatch.units import UNIT_SYSTEMS, lattice_constant

# physics.md §2: (boltz, mvv2e, ftm2v, default dt)
CONSTANTS = {
    "lj": (1.0, 1.0, 1.0, 0.005),
    "real": (0.0019872067, 2390.0573615334906, 4.1839999997e-4, 1.0),
    "metal": (8.617343e-5, 1.0364269e-4, 9648.533823273016, 0.001),
}


@pytest.mark.parametrize("name", sorted(CONSTANTS))
def test_unit_constants(name):
    boltz, mvv2e, ftm2v, dt = CONSTANTS[name]
    u = UNIT_SYSTEMS[name]
    assert u.boltz == pytest.approx(boltz, rel=1e-15)
    assert u.mvv2e == pytest.approx(mvv2e, rel=1e-15)
    # real's ftm2v is printed with 11 digits in the table
    assert u.ftm2v == pytest.approx(ftm2v, rel=1e-15 if name != "real" else 1e-10)
    assert u.ftm2v * u.mvv2e == pytest.approx(1.0, rel=1e-15)
    assert u.dt == dt


@pytest.mark.parametrize("style, scale, units, spacing", [
    ("sc", 0.8442, "lj", 1.0580792984230394),
    ("bcc", 0.8442, "lj", 1.3330963805411866),
    ("fcc", 0.8442, "lj", 1.6795961913825073),
    ("fcc", 1.0, "lj", 1.5874010519681994),
    ("fcc", 3.52, "real", 3.52),
    ("bcc", 3.52, "metal", 3.52),
])
def test_lattice_spacing_table(style, scale, units, spacing):
    assert lattice_constant(style, scale, units) == pytest.approx(spacing, rel=1e-15)


def _scene(units, positions, velocities, masses, timestep=None, steps=0, walls=None):
    d = {"units": units,
         "box": {"lo": [0, 0, 0], "hi": [10, 10, 10], "boundary": ["f", "f", "f"]},
         "atoms": [{"group": f"g{i}", "create": {"positions": [list(p)]}, "mass": m,
                    "velocity": {"values": [list(v)]}}
                   for i, (p, v, m) in enumerate(zip(positions, velocities, masses))],
         "walls": walls or {}, "run": {"steps": steps}}
    if timestep is not None:
        d["timestep"] = timestep
    return d


@pytest.mark.parametrize("name", sorted(CONSTANTS))
def test_default_timestep_in_force(name):
    ds = run_config(config_from_dict(_scene(name, [(5, 5, 5)], [(0, 0, 0)], [1.0], steps=2)))
    assert ds.dt.values.tolist() == [CONSTANTS[name][3]] * 2
    assert ds.time.values[-1] == pytest.approx(2 * CONSTANTS[name][3], rel=1e-15)


@pytest.mark.parametrize("name", ["real", "metal"])
def test_temperature_and_kinetic_energy_of_known_velocities(name):
    boltz, mvv2e, _, _ = CONSTANTS[name]
    masses = [12.011, 15.999, 1.008]
    vels = [(0.01, 0.002, 0.0), (-0.0075, 0.0, 0.001), (0.003, -0.02, 0.015)]
    if name == "metal":  # Angstrom/ps
        vels = [tuple(100 * c for c in v) for v in vels]
    ds = run_config(config_from_dict(_scene(name, [(2, 2, 2), (5, 5, 5), (8, 8, 8)], vels, masses)))
    ke = 0.5 * mvv2e * sum(m * np.dot(v, v) for m, v in zip(masses, vels))
    temp = 2.0 * ke / ((3 * 3 - 3) * boltz)
    assert ds.ke.values[0] == pytest.approx(ke, rel=1e-14)
    assert ds.temp.values[0] == pytest.approx(temp, rel=1e-14)
    assert ds.ke.attrs["units"] == ("kcal/mol" if name == "real" else "eV")
    assert ds.temp.attrs["units"] == "K"


@pytest.mark.parametrize("name", ["lj", "real", "metal"])
def test_acceleration_uses_ftm2v(name):
    # one atom at rest in a harmonic xlo spring: after one velocity-Verlet step
    # x1 = x0 + dt^2/2 ftm2v F0/m and v1 = dt/2 ftm2v (F0 + F1)/m
    _, _, ftm2v, dt = CONSTANTS[name]
    ftm2v = UNIT_SYSTEMS[name].ftm2v  # full precision for real
    eps, rc, x0, m = 0.7, 3.0, 1.0, 4.0
    force = lambda x: 2.0 * eps * (rc - x)  # noqa: E731
    walls = {"w": {"style": "harmonic", "units": "box", "xlo": {"coord": 0.0, "epsilon": eps, "cutoff": rc}}}
    eng = Engine([build_case(config_from_dict(_scene(name, [(x0, 5, 5)], [(0, 0, 0)], [m], steps=1,
                                                     walls=walls)))])
    eng.setup()
    eng.advance(1)
    x1 = x0 + 0.5 * dt * dt * ftm2v * force(x0) / m
    v1 = 0.5 * dt * ftm2v * (force(x0) + force(x1)) / m
    assert eng.state.x[0, 0, 0] == pytest.approx(x1, rel=1e-14)
    assert eng.state.v[0, 0, 0] == pytest.approx(v1, rel=1e-14)
    assert x1 - x0 > 1e-6  # the test sees the acceleration
