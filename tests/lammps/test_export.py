"""`wallbatch export-lammps` and `wallbatch validate` (src/wallbatch/export.py, validate.py).

The script/data text is checked against hand-derived lines (golden checks); the data file must
carry every position, velocity and mass bit-exactly (as text, and once LAMMPS has read it); and
`validate` must pass on the shipped configs, fail on a deliberately broken script, and exit 2 with
the install hint when LAMMPS cannot be imported. LAMMPS-needing tests are skipped without it.

Every wallbatch run here takes the NumPy path (WALLBATCH_NUMBA=0, an autouse fixture): compiling
the numba kernels from a cold cache takes about a minute of CPU, far beyond this file's budget,
and tests/engine/test_compiled.py and the pair tests check that the compiled paths give the NumPy results.
"""

from __future__ import annotations

import ctypes
import dataclasses
import math
import sys
from pathlib import Path

import numpy as np
import pytest
from lammps_oracle import requires_lammps
from typer.testing import CliRunner

from wallbatch.lammps import validate as validate_mod
from wallbatch.cli import app
from wallbatch.config.models import Config
from wallbatch.lammps.export import (
    ATOM_WRITERS,
    PAIR_WRITERS,
    WALL_WRITERS,
    ExportError,
    _id_ranges,
    check_exportable,
    export_selected,
    select_case,
)
from wallbatch.config.sweep import load_plan
from wallbatch.lammps.log import last_thermo

runner = CliRunner()


@pytest.fixture(autouse=True)
def _numpy_path(monkeypatch):
    monkeypatch.setenv("WALLBATCH_NUMBA", "0")

CONFIGS = Path(__file__).resolve().parents[2] / "configs"
SPACING = (4.0 / 0.8442) ** (1.0 / 3.0)  # fcc 0.8442 in lj units: 1.6795961913825073

# Four explicit atoms (exact data-file lines) and six random ones in a second group whose name
# is not a LAMMPS ID. Every face acts within ~100 steps; lattice units, a lattice-scaled
# variable coordinate, swiggle under dt_reset, a constant variable morse alpha, lj1043, EDGE,
# energy on and off, a group wall, reflect with frame: wall, dt_reset with INF/null bounds.
GOLDEN = """\
name: golden
units: lj
seed: 3
box: {lo: [0, 0, 0], hi: [10, 10, 12], boundary: [f, f, f]}
lattice: {style: fcc, scale: 0.8442}
regions:
  mid: {style: block, lo: [3, 3, 3], hi: [7, 7, 9], units: box}
atoms:
  - group: gas
    create: {positions: [[2.0, 5.0, 1.6], [8.5, 5.0, 6.0], [5.0, 5.0, 9.5], [2.25, 4.0, 5.0]]}
    mass: 1.0
    velocity: {values: [[0.1, 0.0, -0.5], [0.5, 0.2, 0.0], [0.0, -0.1, 0.6], [-0.7, 0.0, 0.1]]}
  - group: probe-1
    create: {random: {count: 6, region: mid, overlap: 0.8}}
    mass: 2.5
    velocity: {temperature: 1.0}
variables:
  xl: "0.3 + swiggle(0.0, 0.1, 0.4)"
  al: 2.0
  eps: "1.0 + ramp(0.0, 0.5)"
walls:
  zw: {style: lj93, energy: true, zlo: [EDGE, 1.0, 1.0, 2.5], zhi: [6.0, v_eps, 1.0, 2.5]}
  xw: {style: lj1043, energy: true, xlo: [v_xl, 1.0, 1.0, 2.5]}
  xm: {style: morse, units: box, xhi: [EDGE, 1.0, v_al, 1.1, 3.0]}
  pw: {style: harmonic, units: box, group: probe-1, energy: true, zlo: {coord: 2.0, epsilon: 5.0, cutoff: 2.0}}
  mirror: {style: reflect, units: box, frame: wall, ylo: EDGE, yhi: 10.0}
dt_reset: {every: 5, tmin: null, tmax: INF, xmax: 0.01}
run: {steps: 100, thermo: 10}
"""


def write(tmp_path: Path, text: str, name: str = "cfg.yaml") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def export_text(tmp_path: Path, text: str, sel: str | None = None, steps: int | None = None):
    return export_selected(load_plan(write(tmp_path, text)), sel, steps)


def script_lines(script: str) -> list[str]:
    """Commands with runs of spaces collapsed (comments dropped)."""
    return [" ".join(line.split()) for line in script.splitlines() if line.strip() and not line.startswith("#")]


def comment(script: str) -> str:
    return " ".join(line[1:].strip() for line in script.splitlines() if line.startswith("#"))


def data_section(data: str, header: str) -> np.ndarray:
    """A data-file section's rows as float arrays (parsed with float(): exact for repr text)."""
    lines = data.splitlines()
    start = lines.index(header) + 2
    rows = []
    for line in lines[start:]:
        if not line.strip():
            break
        rows.append([float(w) for w in line.split()])
    return np.array(rows)


# ----------------------------------------------------------------------------- golden text


def test_golden_script(tmp_path):
    exp = export_text(tmp_path, GOLDEN)
    cmds = script_lines(exp.script)
    a = SPACING
    assert exp.script_name == "in.golden" and exp.data_name == "data.golden"
    for line in ("units lj", "boundary f f f", "atom_style atomic", "read_data data.golden",
                 "group gas id 1:4", "group probe_1 id 5:10", "timestep 0.005", "fix wb_nve all nve",
                 "fix_modify zw energy yes", "fix_modify xw energy yes", "fix_modify pw energy yes",
                 'thermo_modify norm no format float "%.17g"', "thermo 10", "run 100",
                 f'variable wb_xw_xlo equal "v_xl*{a!r}"',
                 'variable al equal "2.0"',
                 'variable eps equal "(1.0+ramp(0.0,0.5))"',
                 # lattice units -> box: 6.0 lattice spacings; EDGE kept; epsilon variable kept
                 f"fix zw all wall/lj93 zlo EDGE 1.0 1.0 2.5 zhi {6.0 * a!r} v_eps 1.0 2.5 units box",
                 "fix xw all wall/lj1043 xlo v_wb_xw_xlo 1.0 1.0 2.5 units box",
                 # morse alpha: a constant variable is written as its value (LAMMPS ignores v_ alpha)
                 "fix xm all wall/morse xhi EDGE 1.0 2.0 1.1 3.0 units box",
                 "fix pw probe_1 wall/harmonic zlo 2.0 5.0 1.0 2.0 units box",
                 "fix mirror all wall/reflect ylo EDGE yhi 10.0 units box",
                 f"fix wb_dt_reset all dt/reset 5 NULL NULL {0.01 * a!r} units box",
                 ("thermo_style custom step time dt temp ke pe etotal f_zw f_zw[1] f_zw[2] f_xw f_xw[1] "
                  "f_xm f_xm[1] f_pw f_pw[1]")):
        assert line in cmds, f"missing: {line}\n" + "\n".join(cmds)
    assert "fix_modify xm energy yes" not in cmds  # energy: false
    # swiggle under dt_reset: elapsed simulated time, as wallbatch (LAMMPS refuses swiggle there)
    xl = next(c for c in cmds if c.startswith("variable xl "))
    assert xl == f'variable xl equal "(0.3+(0.0+(0.1*sin((((2.0*{math.pi!r})/0.4)*time)))))"'
    assert "swiggle" not in "\n".join(cmds)
    # order: box before atoms before fixes; nve first, dt/reset after every wall
    fixes = [c.split()[1] for c in cmds if c.startswith("fix ")]
    assert fixes == ["wb_nve", "zw", "xw", "xm", "pw", "mirror", "wb_dt_reset"]
    assert cmds.index("read_data data.golden") < cmds.index("group gas id 1:4") < cmds.index("fix wb_nve all nve")
    # what validate compares: every column after step, wall indices in engine order
    assert [c.label for c in exp.columns] == [
        "time", "dt", "temp", "ke", "pe", "etot", "wall_energy[zw]", "wall_force[zw/zlo]", "wall_force[zw/zhi]",
        "wall_energy[xw]", "wall_force[xw/xlo]", "wall_energy[xm]", "wall_force[xm/xhi]", "wall_energy[pw]",
        "wall_force[pw/zlo]"]
    assert [(c.key, c.index) for c in exp.columns[6:]] == [
        ("wall_energy", 0), ("wall_force", 0), ("wall_force", 1), ("wall_energy", 1), ("wall_force", 2),
        ("wall_energy", 2), ("wall_force", 3), ("wall_energy", 3), ("wall_force", 4)]


def test_golden_comment_block_lists_the_decisions_touched(tmp_path):
    exp = export_text(tmp_path, GOLDEN)
    text = comment(exp.script)
    for topic in ("wall/lj1043 atom on or behind the wall", "wall/morse alpha as a variable", "dt/reset at step 0",
                  "vdisplace, swiggle, cwiggle with dt_reset", "dt_reset tmin / tmax", "wall outputs in lj units",
                  "random numbers", "EDGE", "wall/reflect on a moving wall"):
        assert topic in text, topic
        assert any(d.startswith(topic) for d in exp.decisions)
    assert "cannot be expressed in LAMMPS, which does v -> -v" in text
    assert "v_al = 2.0" in text
    assert "group 'probe-1' written as 'probe_1'" in text
    assert "lattice fcc 0.8442" in text
    assert len(exp.decisions) == 9


def test_comment_block_lists_only_what_the_case_touches(tmp_path):
    """metal units, explicit state, numbers only: no decisions-table row applies."""
    text = """\
name: plain
units: metal
box: {lo: [0, 0, 0], hi: [20, 20, 20], boundary: [p, p, f]}
atoms:
  - group: ar
    create: {positions: [[5, 5, 5], [6, 7, 8]]}
    mass: 39.948
walls:
  w: {style: lj126, units: box, zlo: [0.0, 0.01, 3.4, 8.5]}
run: {steps: 5}
"""
    exp = export_text(tmp_path, text)
    assert exp.decisions == ()
    assert "#   - (none)" in exp.script
    cmds = script_lines(exp.script)
    assert "fix w all wall/lj126 zlo 0.0 0.01 3.4 8.5 units box" in cmds
    assert "thermo 0" in cmds and "run 5" in cmds and "timestep 0.001" in cmds
    assert 'thermo_modify norm no format float "%.17g"' in cmds  # written whatever the units
    assert "neigh_modify every 1 delay 0 check no" in cmds


def test_pbc_and_virial_keywords(tmp_path):
    text = """\
name: pbc
units: lj
box: {lo: [0, 0, 0], hi: [10, 10, 10], boundary: [p, p, p]}
atoms:
  - group: a
    create: {positions: [[5, 5, 5], [6, 6, 6]]}
    mass: 1.0
walls:
  w: {style: harmonic, units: box, pbc: true, virial: true, zlo: {coord: 1.0, epsilon: 2.0, cutoff: 5.0}}
run: {steps: 5}
"""
    cmds = script_lines(export_text(tmp_path, text).script)
    assert "fix w all wall/harmonic zlo 1.0 2.0 1.0 5.0 units box pbc yes" in cmds
    assert "fix_modify w virial yes" in cmds and "fix_modify w energy yes" not in cmds
    assert "boundary p p p" in cmds


PBC_STOCHASTIC = """\
name: pbc-thermal
units: lj
box: {lo: [0, 0, 0], hi: [10, 10, 10], boundary: [p, p, p]}
atoms:
  - group: a
    create: {positions: [[5, 5, 5], [6, 6, 6]]}
    mass: 1.0
walls:
  th: {style: reflect/stochastic, rstyle: diffusive, seed: 7, units: box, pbc: true, zlo: {coord: 1.0, temp: 1.0}}
run: {steps: 5}
"""


def test_stochastic_wall_with_pbc_is_refused_as_lammps_refuses_it(tmp_path):
    """wallbatch runs a thermal wall in a periodic dimension (pbc: true); LAMMPS has no pbc keyword
    for it and stops, so export says so instead of writing a script LAMMPS refuses."""
    with pytest.raises(ExportError, match=r"walls\.th: wall/reflect/stochastic on a periodic dimension"):
        export_text(tmp_path, PBC_STOCHASTIC)


@pytest.mark.lammps
@requires_lammps
def test_lammps_refuses_a_stochastic_wall_in_a_periodic_dimension():
    from lammps_oracle import LammpsRunError, lammps_log
    with pytest.raises(LammpsRunError, match="Cannot use fix wall/reflect/stochastic in periodic dimension"):
        lammps_log(["units lj", "boundary p p p", "region b block 0 10 0 10 0 10", "create_box 1 b", "mass 1 1.0",
                    "fix th all wall/reflect/stochastic diffusive 7 zlo 1.0 1.0 0 0 0 units box"])


def test_time_based_run_is_converted_to_steps(tmp_path):
    text = GOLDEN.replace("dt_reset: {every: 5, tmin: null, tmax: INF, xmax: 0.01}\n", "").replace(
        "run: {steps: 100, thermo: 10}", "run: {time: 0.5, thermo: {time: 0.125}}")
    exp = export_text(tmp_path, text)
    cmds = script_lines(exp.script)
    assert "run 100" in cmds and "thermo 25" in cmds
    assert "converted to 100 steps" in comment(exp.script)
    # without dt_reset, swiggle stays LAMMPS's own function
    assert 'variable xl equal "(0.3+swiggle(0.0,0.1,0.4))"' in cmds


def test_time_based_run_with_dt_reset_needs_steps(tmp_path):
    cfg = write(tmp_path, (CONFIGS / "dt-reset-rescue.yaml").read_text())
    result = runner.invoke(app, ["export-lammps", str(cfg), "-o", str(tmp_path / "out")])
    assert result.exit_code == 2
    assert "--steps N" in result.output and "dt_reset" in result.output
    result = runner.invoke(app, ["export-lammps", str(cfg), "-o", str(tmp_path / "out"), "--steps", "30"])
    assert result.exit_code == 0, result.output
    cmds = script_lines((tmp_path / "out" / "in.dt-reset-rescue").read_text())
    assert "run 30" in cmds and "thermo 100" in cmds  # 0.5 time units / dt 0.005
    assert "fix wb_dt_reset all dt/reset 1 1e-06 0.005 0.02 units box" in cmds


def test_time_dependent_morse_alpha_is_refused(tmp_path):
    text = GOLDEN.replace("al: 2.0", 'al: "2.0 + ramp(0.0, 0.1)"')
    with pytest.raises(ExportError, match=r"alpha.*LAMMPS ignores a variable alpha"):
        export_text(tmp_path, text)


def test_data_file_is_exact(tmp_path):
    """Every position, velocity and mass reads back (float()) to the identical double."""
    from wallbatch.lammps.export import lammps_ready
    from wallbatch.scene.build import build_case

    plan = load_plan(write(tmp_path, GOLDEN))
    sc = plan.cases[0]
    cfg, _ = lammps_ready(sc.config)
    case = build_case(cfg, sc.seed_key)
    exp = export_selected(plan)
    atoms = data_section(exp.data, "Atoms # atomic")
    vel = data_section(exp.data, "Velocities")
    masses = data_section(exp.data, "Masses")
    np.testing.assert_array_equal(atoms[:, 0], np.arange(1, 11))
    assert atoms[:, 2:].view(np.uint64).tolist() == case.x.view(np.uint64).tolist()
    assert vel[:, 1:].view(np.uint64).tolist() == case.v.view(np.uint64).tolist()
    assert masses.tolist() == [[1.0, 1.0], [2.0, 2.5]]
    np.testing.assert_array_equal(atoms[:, 1], [1, 1, 1, 1, 2, 2, 2, 2, 2, 2])
    assert "0.0 10.0 xlo xhi" in exp.data and "0.0 12.0 zlo zhi" in exp.data and "10 atoms" in exp.data
    # the random group really has non-round numbers (so the round trip is not trivial)
    assert len(repr(float(case.x[5, 0]))) > 15


def test_sphere_data_file(tmp_path):
    exp = export_selected(load_plan(CONFIGS / "colloid-slit.yaml"), steps=10)
    atoms = data_section(exp.data, "Atoms # sphere")
    assert np.all(atoms[:, 2] == 2.0)  # diameter = 2 * radius 1.0
    np.testing.assert_allclose(atoms[:, 3] * 4.0 / 3.0 * np.pi, 10.0, rtol=1e-15)  # density
    assert "set type 1 mass 10.0" in script_lines(exp.script)
    assert data_section(exp.data, "Velocities").shape == (60, 7)  # vx vy vz wx wy wz


@requires_lammps
@pytest.mark.parametrize("source", ["golden", "colloid-slit"])
def test_lammps_reads_the_data_file_bit_exactly(tmp_path, monkeypatch, source):
    """The exported files, run as a user would (in their folder), up to the groups: LAMMPS holds
    the case's positions, velocities and per-atom masses bit for bit."""
    from wallbatch.lammps.export import lammps_ready, write_export
    from wallbatch.scene.build import build_case

    # radius 0.7, mass 3.3: LAMMPS's mass from diameter and density would be 3.3000000000000007
    plan = (load_plan(write(tmp_path, GOLDEN)) if source == "golden" else
            load_plan(CONFIGS / f"{source}.yaml", ["atoms.0.radius=0.7", "atoms.0.mass=3.3"]))
    sc = plan.cases[0]
    case = build_case(lammps_ready(sc.config)[0], sc.seed_key)
    exp = export_selected(plan)
    write_export(exp, tmp_path / "out")
    monkeypatch.chdir(tmp_path / "out")
    lammps = validate_mod.load_lammps()
    lmp = lammps.lammps(cmdargs=["-screen", "none", "-log", "none", "-nocite"])
    try:
        for line in script_lines(exp.script):
            if line.startswith(("group", "variable", "timestep")):
                break
            lmp.command(line)
        n = case.natoms
        x = np.ctypeslib.as_array(lmp.gather_atoms("x", 1, 3)).reshape(n, 3)
        v = np.ctypeslib.as_array(lmp.gather_atoms("v", 1, 3)).reshape(n, 3)
        if source == "golden":
            types = np.ctypeslib.as_array(lmp.gather_atoms("type", 0, 1))
            per_type = np.array([lmp.extract_atom("mass")[t] for t in (1, 2)])
            mass = per_type[types - 1]
        else:
            mass = np.ctypeslib.as_array(lmp.gather_atoms("rmass", 1, 1))
            radius = np.ctypeslib.as_array(lmp.gather_atoms("radius", 1, 1))
            assert radius.view(np.uint64).tolist() == case.radius.view(np.uint64).tolist()
    finally:
        lmp.close()
    assert x.view(np.uint64).tolist() == case.x.view(np.uint64).tolist()
    assert v.view(np.uint64).tolist() == case.v.view(np.uint64).tolist()
    assert np.asarray(mass, float).view(np.uint64).tolist() == case.mass.view(np.uint64).tolist()


@requires_lammps
def test_lammps_reads_the_ellipsoid_data_file(tmp_path, monkeypatch):
    """ellipsoids-ees-slit (random orientations): LAMMPS holds the positions, velocities, masses,
    angular momenta and diameters bit for bit, the quaternions within an ulp (it normalises them
    again)."""
    from lammps import LMP_STYLE_ATOM, LMP_TYPE_ARRAY

    from wallbatch.lammps.export import lammps_ready, write_export
    from wallbatch.scene.build import build_case

    plan = load_plan(CONFIGS / "ellipsoids-ees-slit.yaml")
    sc = plan.cases[0]
    case = build_case(lammps_ready(sc.config)[0], sc.seed_key)
    exp = export_selected(plan)
    write_export(exp, tmp_path / "out")
    monkeypatch.chdir(tmp_path / "out")
    lammps = validate_mod.load_lammps()
    lmp = lammps.lammps(cmdargs=["-screen", "none", "-log", "none", "-nocite"])
    n = case.natoms
    try:
        for line in script_lines(exp.script):
            if line.startswith(("group", "variable", "timestep")):
                break
            lmp.command(line)
        lmp.command("compute q all property/atom quatw quati quatj quatk shapex shapey shapez")
        lmp.command("run 0")
        got = {k: np.ctypeslib.as_array(lmp.gather_atoms(k, 1, w)).reshape(n, w).copy()
               for k, w in (("x", 3), ("v", 3), ("angmom", 3), ("rmass", 1))}
        order = np.argsort(np.array(lmp.numpy.extract_atom("id")[:n]))
        qs = np.array(lmp.numpy.extract_compute("q", LMP_STYLE_ATOM, LMP_TYPE_ARRAY)[:n], dtype=float)[order]
    finally:
        lmp.close()
    for key, want in (("x", case.x), ("v", case.v), ("angmom", case.angmom), ("rmass", case.mass[:, None])):
        assert got[key].view(np.uint64).tolist() == want.view(np.uint64).tolist(), key
    assert qs[:, 4:].view(np.uint64).tolist() == (2.0 * case.shape).view(np.uint64).tolist()  # shapex: diameters
    assert np.abs(qs[:, :4] - case.quat).max() <= 2.3e-16
    assert len(np.unique(case.quat[:, 0])) == n  # random orientations: a real round trip


def test_id_ranges():
    mask = np.array([1, 1, 1, 0, 1, 0, 0, 1, 1], bool)
    assert _id_ranges(mask) == "1:3 5 8:9"
    assert _id_ranges(np.zeros(3, bool)) == ""


# ----------------------------------------------------------------------------- ellipsoids, ees, region/ees

# Two ellipsoids (one group; quaternions and angular momenta given) and a point atom of another
# mass: atom_style ellipsoid with both integrators; a flat ees wall and a region/ees wall on the
# ellipsoids.
ELLIPSOIDS = """\
name: ell
units: lj
box: {lo: [0, 0, 0], hi: [10, 10, 10], boundary: [p, p, f]}
regions:
  ball: {style: sphere, center: [5, 5, 5], radius: 4.5, units: box}
atoms:
  - group: rods
    create: {positions: [[5.0, 5.0, 5.0], [3.0, 4.0, 6.0]]}
    mass: 2.0
    shape: [1.0, 0.5, 0.25]
    orientation: [0.0, 0.0, 0.0, 2.0]
    angmom: {values: [[0.1, 0.0, 0.0], [0.0, 0.0, -0.5]]}
    velocity: {values: [0.5, 0.0, -0.25]}
  - group: dots
    create: {positions: [[7.0, 6.0, 5.5]]}
    mass: 1.0
walls:
  floor: {style: ees, units: box, group: rods, energy: true, virial: true, zlo: [EDGE, 1.5, 1.0, 3.0]}
  shell: {style: region/ees, region: ball, group: rods, epsilon: 2.0, sigma: 1.0, cutoff: 3.0}
run: {steps: 10}
output: {thermo: [step, temp, ke, pe, etot, erot]}
"""


def test_ellipsoid_data_file(tmp_path):
    """atom_style ellipsoid: `id type ellipsoidflag density x y z`, an Ellipsoids section with
    diameters and (normalised) quaternions, angular momenta after the velocities."""
    exp = export_text(tmp_path, ELLIPSOIDS)
    lines = exp.data.splitlines()
    assert "3 atoms" in lines and "2 ellipsoids" in lines and "2 atom types" in lines
    rho = 2.0 / (4.0 / 3.0 * math.pi * 1.0 * 0.5 * 0.25)
    section = lambda h: lines[lines.index(h) + 2: lines.index(h) + 2 + (2 if h == "Ellipsoids" else 3)]
    assert section("Atoms # ellipsoid") == [f"1 2 1 {rho!r} 5.0 5.0 5.0", f"2 2 1 {rho!r} 3.0 4.0 6.0",
                                            "3 1 0 1.0 7.0 6.0 5.5"]
    assert section("Ellipsoids") == ["1 2.0 1.0 0.5 0.0 0.0 0.0 1.0", "2 2.0 1.0 0.5 0.0 0.0 0.0 1.0"]
    assert section("Velocities") == ["1 0.5 0.0 -0.25 0.1 0.0 0.0", "2 0.5 0.0 -0.25 0.0 0.0 -0.5",
                                     "3 0.0 0.0 0.0 0.0 0.0 0.0"]


def test_ellipsoid_script(tmp_path):
    exp = export_text(tmp_path, ELLIPSOIDS)
    cmds = script_lines(exp.script)
    for line in ("atom_style ellipsoid", "set type 1 mass 1.0", "set type 2 mass 2.0",
                 "group wb_ellipsoids id 1:2", "group wb_points id 3",
                 "fix wb_nve wb_points nve", "fix wb_nve_asphere wb_ellipsoids nve/asphere",
                 "fix floor rods wall/ees zlo EDGE 1.5 1.0 3.0 units box", "fix_modify floor energy yes",
                 "region ball sphere 5.0 5.0 5.0 4.5 side in units box",
                 "fix shell rods wall/region/ees ball 2.0 1.0 3.0",
                 "compute wb_erot wb_ellipsoids erotate/asphere",
                 'variable wb_ke equal "ke+c_wb_erot"', 'variable wb_etot equal "etotal+c_wb_erot"',
                 ("thermo_style custom step time dt temp v_wb_ke pe v_wb_etot c_wb_erot f_floor f_floor[1] "
                  "f_shell f_shell[1] f_shell[2] f_shell[3]")):
        assert line in cmds, f"missing: {line}\n" + "\n".join(cmds)
    assert "fix_modify floor virial yes" not in cmds and "fix_modify shell energy yes" not in cmds
    assert "walls.floor: virial: true has no effect on wall/ees" in comment(exp.script)
    assert cmds.index("region ball sphere 5.0 5.0 5.0 4.5 side in units box") < cmds.index(
        "fix shell rods wall/region/ees ball 2.0 1.0 3.0")
    assert [(c.label, c.keyword, c.key, c.index) for c in exp.columns[3:]] == [
        ("ke", "v_wb_ke", "ke", None), ("pe", "pe", "pe", None), ("etot", "v_wb_etot", "etot", None),
        ("erot", "c_wb_erot", "erot", None),
        ("wall_energy[floor]", "f_floor", "wall_energy", 0), ("wall_force[floor/zlo]", "f_floor[1]", "wall_force", 0),
        ("wall_energy[shell]", "f_shell", "wall_energy", 1),
        ("region_force[shell/x]", "f_shell[1]", "region_force", (0, 0)),
        ("region_force[shell/y]", "f_shell[2]", "region_force", (0, 1)),
        ("region_force[shell/z]", "f_shell[3]", "region_force", (0, 2))]
    assert any(d.startswith("wall/region/ees closeness test") for d in exp.decisions)
    assert "quaternions and angular momenta are in the data file" in comment(exp.script)


def test_all_ellipsoids_use_one_integrator(tmp_path):
    exp = export_selected(load_plan(CONFIGS / "ellipsoids-ees-slit.yaml"), steps=10)
    cmds = script_lines(exp.script)
    assert "fix wb_nve all nve/asphere" in cmds and "compute wb_erot all erotate/asphere" in cmds
    assert not any(c.startswith("group wb_") for c in cmds)
    assert "random numbers" in " ".join(exp.decisions)  # orientation: random


# ----------------------------------------------------------------------------- region walls

SPACING_SC = 2.0 ** (1.0 / 3.0)  # lattice sc 0.5 in lj units

# Region walls of every kind interleaved with a flat wall; a region in lattice units, a region
# name that is not a LAMMPS ID, harmonic without sigma, morse with a constant variable alpha.
REGIONS = """\
name: regions
units: lj
box: {lo: [0, 0, 0], hi: [12, 12, 12], boundary: [f, f, f]}
lattice: {style: sc, scale: 0.5}
variables: {al: "2.0"}
regions:
  cage: {style: block, lo: [1, 1, 1], hi: [11, 11, 11], units: box}
  the-post: {style: cylinder, axis: z, center: [6, 6], radius: 1.5, lo: 0, hi: 12, side: out, units: box}
  ball: {style: sphere, center: [3, 3, 3], radius: 2.0}
atoms:
  - group: gas
    create: {positions: [[3.0, 3.0, 3.0], [8.0, 8.0, 8.0]]}
    mass: 1.0
walls:
  cage: {style: region, region: cage, potential: lj93, epsilon: 1.0, sigma: 1.0, cutoff: 2.5, energy: true,
         virial: true}
  xw: {style: lj126, units: box, xlo: [0.0, 1.0, 1.0, 2.5]}
  post: {style: region, region: the-post, potential: harmonic, epsilon: 20.0, cutoff: 1.0, energy: true}
  ball: {style: region, region: ball, potential: morse, D0: 1.0, alpha: v_al, r0: 1.0, cutoff: 2.5}
run: {steps: 10}
output: {thermo: [step, temp, ke, pe, etot, press]}
"""


def test_region_walls_script(tmp_path):
    exp = export_text(tmp_path, REGIONS)
    cmds = script_lines(exp.script)
    a = SPACING_SC
    for line in ("region cage block 1.0 11.0 1.0 11.0 1.0 11.0 side in units box",
                 "region the_post cylinder z 6.0 6.0 1.5 0.0 12.0 side out units box",
                 f"region ball sphere {3 * a!r} {3 * a!r} {3 * a!r} {2 * a!r} side in units box",
                 "fix cage all wall/region cage lj93 1.0 1.0 2.5", "fix_modify cage energy yes",
                 "fix_modify cage virial yes", "fix xw all wall/lj126 xlo 0.0 1.0 1.0 2.5 units box",
                 "fix post all wall/region the_post harmonic 20.0 1.0 1.0", "fix_modify post energy yes",
                 "fix ball all wall/region ball morse 1.0 2.0 1.0 2.5",
                 ("thermo_style custom step time dt temp ke pe etotal press f_cage f_cage[1] f_cage[2] f_cage[3] "
                  "f_xw f_xw[1] f_post f_post[1] f_post[2] f_post[3] f_ball f_ball[1] f_ball[2] f_ball[3]")):
        assert line in cmds, f"missing: {line}\n" + "\n".join(cmds)
    assert "fix_modify ball energy yes" not in cmds and "fix_modify post virial yes" not in cmds
    text = comment(exp.script)
    assert "region 'the-post' written as 'the_post'" in text and "region ball is in lattice units" in text
    assert "walls.ball.alpha: v_al is constant, written as 2.0" in text
    energy = [(c.label, c.index) for c in exp.columns if c.key == "wall_energy"]
    assert energy == [("wall_energy[cage]", 0), ("wall_energy[xw]", 1), ("wall_energy[post]", 2),
                      ("wall_energy[ball]", 3)]  # config order, flat and region fixes interleaved
    assert [c.index for c in exp.columns if c.key == "region_force"] == [(k, d) for k in range(3) for d in range(3)]
    assert [c.index for c in exp.columns if c.key == "wall_force"] == [0]
    assert not any("colloid" in d or "closeness" in d for d in exp.decisions)


OPEN_REGIONS = """\
units: lj
box: {lo: [0, 0, 0], hi: [8, 8, 8], boundary: [p, p, p]}
regions:
  slot: {style: block, lo: [-INF, 1, -INF], hi: [INF, 7, INF], units: box}
  pipe: {style: cylinder, axis: z, center: [4, 4], radius: 3.5, lo: -INF, hi: INF, units: box}
atoms:
  - group: a
    create: {positions: [[3.0, 2.5, 3.0], [5.0, 5.8, 5.0], [4.0, 4.0, 0.5], [5.5, 3.5, 7.5]]}
    mass: 1.0
    velocity: {values: [[0.3, -0.5, 0.1], [-0.2, 0.4, 0.0], [0.0, 0.1, -0.7], [0.5, 0.0, 0.2]]}
walls:
  slot: {style: region, region: slot, potential: lj93, epsilon: 1.0, sigma: 1.0, cutoff: 2.5, energy: true}
  pipe: {style: region, region: pipe, potential: lj126, epsilon: 1.0, sigma: 1.0, cutoff: 2.5, energy: true}
timestep: 0.002
run: {steps: 100, thermo: 10}
"""


def test_region_with_an_open_side_is_written_with_lammps_inf(tmp_path):
    # an infinite block or cylinder bound is LAMMPS's INF (-infinity as a lower bound, +infinity as an
    # upper one; `-INF` is no number to LAMMPS); it was refused ("non-finite number -inf cannot be written")
    cmds = script_lines(export_text(tmp_path, OPEN_REGIONS).script)
    assert "region slot block INF INF 1.0 7.0 INF INF side in units box" in cmds
    assert "region pipe cylinder z 4.0 4.0 3.5 INF INF side in units box" in cmds


@requires_lammps
def test_validate_region_with_an_open_side(tmp_path):
    result = validate(write(tmp_path, OPEN_REGIONS))
    assert result.exit_code == 0, result.output
    assert "region_force[slot/y]" in result.output and "region_force[pipe/x]" in result.output


TABLE_IN_A_FOLDER = """\
units: lj
box: {lo: [0, 0, 0], hi: [6, 6, 6], boundary: [p, p, f]}
atoms:
  - group: a
    create: {positions: [[1.0, 2.0, 1.1], [4.0, 4.5, 5.2]]}
    mass: 1.0
    velocity: {values: [[0.1, 0.0, -0.6], [0.0, 0.2, 0.4]]}
walls:
  tab: {style: table, tabstyle: linear, N: 200, units: box, energy: true,
        zlo: {coord: EDGE, file: w.table, keyword: H, cutoff: 1.5},
        zhi: {coord: EDGE, file: w.table, keyword: H, cutoff: 1.5}}
timestep: 0.002
run: {steps: 100, thermo: 10}
"""


def _table_in(folder: Path) -> Path:
    folder.mkdir()
    result = runner.invoke(app, ["table", "k*(r-1.5)^2", "-p", "k=20", "--lo", "0.1", "--hi", "1.5", "-n", "100",
                                 "-k", "H", "-o", str(folder / "w.table")])
    assert result.exit_code == 0, result.output
    return write(folder, TABLE_IN_A_FOLDER)


def test_table_path_with_a_blank_is_quoted(tmp_path):
    # was "unexpected ValueError: ... a table file path without spaces, quotes or '#' ... this is a
    # wallbatch bug" for a config in a folder with a blank; LAMMPS reads a quoted word as one argument
    cfg = _table_in(tmp_path / "my walls #1")
    path = f'"{tmp_path / "my walls #1" / "w.table"}"'
    cmds = script_lines(export_selected(load_plan(cfg), None, None).script)
    assert f"fix tab all wall/table linear 200 zlo EDGE {path} H 1.5 zhi EDGE {path} H 1.5 units box" in cmds
    bad = _table_in(tmp_path / 'say "hi"')
    with pytest.raises(ExportError, match=r"walls.tab.zlo.file: a table file path without double quotes .* "
                                          r"cannot be written in a LAMMPS script"):
        export_selected(load_plan(bad), None, None)


@requires_lammps
def test_validate_table_path_with_a_blank(tmp_path):
    result = validate(_table_in(tmp_path / "my walls"))
    assert result.exit_code == 0, result.output
    assert "wall_force[tab/zlo]" in result.output


def test_region_wall_with_a_time_dependent_parameter_is_refused(tmp_path):
    text = REGIONS.replace('al: "2.0"', 'al: "2.0 + ramp(0.0, 0.5)"')
    with pytest.raises(ExportError, match=r"walls.ball.alpha: LAMMPS takes a number here and v_al changes"):
        export_text(tmp_path, text)


def test_region_colloid_is_written_as_configured_and_force_matched_for_validate(tmp_path):
    """Decisions table: LAMMPS's wall/region colloid differs; the export keeps epsilon, validate's
    variant negates it (LAMMPS's flipped force is then fix wall/colloid's) and expects the energies
    to differ."""
    from wallbatch.lammps.export import export_case, lammps_ready
    from wallbatch.scene.build import build_case

    sc = load_plan(CONFIGS / "colloid-cavity.yaml").cases[0]
    cfg, _ = lammps_ready(sc.config, 10)
    case = build_case(cfg, sc.seed_key)
    exp = export_case(cfg, case)
    assert "fix cavity all wall/region cavity colloid 1.0 1.0 2.5" in script_lines(exp.script)
    assert "region cavity sphere 5.0 5.0 5.0 3.5 side in units box" in script_lines(exp.script)
    assert any(d.startswith("wall/region with colloid") for d in exp.decisions)
    assert exp.region_colloid == ("cavity",) and exp.expected == {} and not exp.force_matched
    matched = export_case(cfg, case, force_matched=True)
    assert "fix cavity all wall/region cavity colloid -1.0 1.0 2.5" in script_lines(matched.script)
    assert set(matched.expected) == {"wall_energy[cavity]", "pe", "etot"} and matched.force_matched
    assert "validate's variant" in comment(matched.script)
    # minimizing LAMMPS's other energy starts the run elsewhere: then every output is expected to differ
    sc = load_plan(write(tmp_path, (CONFIGS / "colloid-cavity.yaml").read_text() + "minimize: {etol: 1.0e-6}\n")).cases[0]
    cfg, _ = lammps_ready(sc.config, 10)
    both = export_case(cfg, build_case(cfg, sc.seed_key), force_matched=True)
    assert set(both.expected) == {c.label for c in both.columns} and "min_energy" in both.expected


# ----------------------------------------------------------------------------- wall/flow, pair, minimize

FLOW_SCENE = """\
name: flow
units: lj
box: {lo: [0, 0, 0], hi: [10, 6, 6], boundary: [p, p, p]}
lattice: {style: sc, scale: 0.5}
atoms:
  - group: fluid
    create: {positions: [[1.0, 1.0, 1.0], [5.0, 3.0, 3.0]]}
    mass: 1.0
walls:
  fl: {style: flow, axis: x, vflow: 0.4, temperature: 1.5, seed: 593894, coords: [2.0, 4.0], RULE}
run: {steps: 10}
output: {thermo: [step, temp, ke, flow_crossings]}
"""


@pytest.mark.parametrize("rule", ["exact", "lammps"])
def test_flow_wall_script(tmp_path, rule):
    exp = export_text(tmp_path, FLOW_SCENE.replace("RULE", f"rule: {rule}"))
    a = SPACING_SC
    assert f"fix fl all wall/flow x 0.4 1.5 593894 2 {2 * a!r} {4 * a!r} units box" in script_lines(exp.script)
    topics = [d.split(":")[0] for d in exp.decisions]
    assert "wall/flow at the periodic boundary" in topics and "wall/flow random numbers" in topics
    assert ("wall/flow rule" in topics) == (rule == "exact")
    text = comment(exp.script)
    assert "coords [2.0, 4.0] lattice spacings written in box units" in text
    assert "flow_crossings not written (no LAMMPS counterpart)" in text
    assert [c.label for c in exp.columns] == ["time", "dt", "temp", "ke"]


def test_flow_is_refused_by_validate_before_lammps(tmp_path, monkeypatch):
    """No LAMMPS needed to say why: the refusal comes first (exit 2), and names the flow tests."""
    monkeypatch.setitem(sys.modules, "lammps", None)
    result = validate(write(tmp_path, FLOW_SCENE.replace(", RULE", "")))
    assert result.exit_code == 2, result.output
    assert "walls.fl: wall/flow redraws velocities from random numbers" in result.output
    assert "tests/engine/test_flow.py" in result.output and "pip install" not in result.output


def test_pair_and_press_script():
    exp = export_selected(load_plan(CONFIGS / "lj-liquid-slit.yaml"), steps=10)
    cmds = script_lines(exp.script)
    for line in ("pair_style lj/cut 2.5", "pair_coeff * * 1.0 1.0", "pair_modify shift yes", "neighbor 0.3 bin",
                 "fix_modify pore virial yes",
                 "thermo_style custom step time dt temp ke pe etotal press f_pore f_pore[1] f_pore[2]"):
        assert line in cmds, f"missing: {line}\n" + "\n".join(cmds)
    assert cmds.index("read_data data.lj-liquid-slit") < cmds.index("pair_style lj/cut 2.5")


def test_pair_in_metal_units_uses_its_skin(tmp_path):
    text = """\
name: argon
units: metal
box: {lo: [0, 0, 0], hi: [30, 30, 30], boundary: [p, p, p]}
atoms:
  - group: ar
    create: {positions: [[5, 5, 5], [9, 5, 5]]}
    mass: 39.948
pair: {style: lj/cut, epsilon: 0.0104, sigma: 3.4, cutoff: 8.5}
run: {steps: 5}
"""
    cmds = script_lines(export_text(tmp_path, text).script)
    assert "pair_style lj/cut 8.5" in cmds and "pair_coeff * * 0.0104 3.4" in cmds and "neighbor 2.0 bin" in cmds
    assert not any(c.startswith("pair_modify") for c in cmds)


@pytest.mark.parametrize("style", ["cg", "fire"])
def test_minimize_script(style):
    plan = load_plan(CONFIGS / "lj-liquid-slit.yaml", [f"minimize.style={style}", "minimize.dmax=0.05"])
    exp = export_selected(plan, steps=10)
    cmds = script_lines(exp.script)
    tail = cmds[cmds.index('thermo_modify norm no format float "%.17g"'):]
    keep, restore = [], []
    if style == "fire":  # the created velocities kept for the run (the decisions table)
        keep = ["fix wb_v0 all store/state 0 vx vy vz"]
        restore = ["variable wb_vx atom f_wb_v0[1]", "variable wb_vy atom f_wb_v0[2]", "variable wb_vz atom f_wb_v0[3]",
                   "velocity all set v_wb_vx v_wb_vy v_wb_vz units box", "unfix wb_v0"]
    assert tail == ['thermo_modify norm no format float "%.17g"', "thermo 100", *keep, f"min_style {style}",
                    "min_modify dmax 0.05", "minimize 0.0001 0.0001 200 10000",
                    'print "wb_min $(pe:%.17g) $(fnorm:%.17g)"', *restore, "reset_timestep 0 time 0.0", "run 10"]
    mins = [(c.label, c.keyword, c.source) for c in exp.columns if c.source == "min"]
    assert mins == [("min_energy_before", "energy_before", "min"), ("min_energy", "energy", "min"),
                    ("min_fnorm", "fnorm", "min"), ("min_iterations", "iterations", "min"),
                    ("min_evaluations", "evaluations", "min"), ("min_stop_reason", "stop_reason", "min")]
    assert not any(c.keyword in cmds[-1] for c in exp.columns if c.source == "min")
    assert "min_" not in next(c for c in cmds if c.startswith("thermo_style"))
    topics = [d.split(":")[0] for d in exp.decisions]
    assert "minimize" in topics  # norm no before minimize
    assert ("minimize (cg) with every force exactly zero" in topics) == (style == "cg")
    assert ("fire leaves its own damped velocities" in comment(exp.script)) == (style == "fire")


# ----------------------------------------------------------------------------- validate's parsers and comparison

MIN_LOG = """\
   Step          PotEng
         0  -0.028861443017473702
        86  -0.081622382197368323
Loop time of 0.0001 on 1 procs for 86 steps with 2 atoms

Minimization stats:
  Stopping criterion = force tolerance
  Energy initial, next-to-last, final = 
    -0.0288614430174737 -0.081622382170374 -0.0816223821973683
  Force two-norm initial, final = 0.0082885234 5.0340628e-11
  Force max component initial, final = 0.0058608711 3.5596318e-11
  Final line search alpha, max atom move = 1 3.5596318e-11
  Iterations, force evaluations = 86 87

print "wb_min $(pe:%.17g) $(fnorm:%.17g)"
wb_min -0.081622382197368323 5.034062824216522e-11
reset_timestep 0 time 0.0
run 10
   Step          PotEng
         0  -0.081622382197368323
        10  -0.081622382197381965
Loop time of 8.673e-06 on 1 procs for 10 steps with 2 atoms
"""


def test_log_parsers():
    table = last_thermo(MIN_LOG, 2)  # the run's table, not the minimizer's
    assert table.tolist() == [[0.0, -0.081622382197368323], [10.0, -0.081622382197381965]]
    res = validate_mod._min_results(MIN_LOG)
    assert res["stop_reason"].tolist() == ["force tolerance"]
    assert (res["iterations"][0], res["evaluations"][0]) == (86.0, 87.0)
    assert res["energy_before"][0] == -0.0288614430174737
    assert (res["energy"][0], res["fnorm"][0]) == (-0.081622382197368323, 5.034062824216522e-11)
    assert res["fnorm:scale"][0] == 0.0082885234
    with pytest.raises(validate_mod.LammpsRunError, match="no minimization results"):
        validate_mod._min_results(MIN_LOG.split("Minimization stats")[0])


def test_compare_region_force_and_min_results():
    """Indices (fix, x/y/z) pick region_force; min_* are scalars; the stopping criterion compares
    text (the all-zero-forces pair of names is expected); min_fnorm ~0 uses the initial norm as
    its scale; min_energy gets MIN_RTOL."""
    from wallbatch.engine.engine import CaseResult
    from wallbatch.lammps.export import Column, LammpsExport

    cols = (Column("region_force[w/y]", "f_w[2]", "region_force", (1, 1)),
            Column("min_fnorm", "fnorm", "min_fnorm", source="min"),
            Column("min_energy", "energy", "min_energy", source="min"),
            Column("min_stop_reason", "stop_reason", "min_stop_reason", source="min"))
    exp = LammpsExport("", "", "in.x", "data.x", cols, 10, 10, (), ())
    rf = np.zeros((2, 2, 3))
    rf[:, 1, 1] = [1.0, -2.0]
    data = {"region_force": rf, "min_fnorm": np.float64(3e-11), "min_energy": np.float64(-5.0 * (1 + 4e-7)),
            "min_stop_reason": np.str_("forces are zero")}
    ref = {"f_w[2]": np.array([1.0, -2.0 + 1e-13]), "min:fnorm": np.array([2e-11]),
           "min:fnorm:scale": np.array([1e3]), "min:energy": np.array([-5.0]),
           "min:stop_reason": np.array(["search direction is not downhill"])}
    rows = validate_mod.compare(exp, CaseResult("ok", "", 0.0, data), ref)
    assert [(r.output, r.status) for r in rows] == [("region_force[w/y]", "ok"), ("min_fnorm", "ok"),
                                                     ("min_energy", "ok"), ("min_stop_reason", "expected")]
    assert rows[0].max_abs == pytest.approx(1e-13, rel=1e-3)
    assert rows[1].max_rel == pytest.approx(0.01)  # 1e-11 / (1e-12 * the initial norm 1e3)
    assert "wallbatch 'forces are zero', LAMMPS 'search direction is not downhill'" in rows[3].detail
    data.update(min_energy=np.float64(-5.0 * (1 + 2e-6)), min_stop_reason=np.str_("energy tolerance"))
    ref["min:fnorm:scale"] = np.array([1.0])
    rows = validate_mod.compare(exp, CaseResult("ok", "", 0.0, data), ref)
    assert [r.status for r in rows] == ["ok", "FAIL", "FAIL", "FAIL"]


# ----------------------------------------------------------------------------- refusals and selection


def _model(extra: dict) -> Config:
    """A Config model with no cross-field checks (they may still refuse features being built)."""
    data = {"box": {"lo": [0, 0, 0], "hi": [10, 10, 10], "boundary": ["p", "p", "f"]},
            "atoms": [{"group": "g", "create": {"positions": [[5, 5, 5]]}, "mass": 1.0}],
            "run": {"steps": 10}}
    data.update(extra)
    return Config.model_validate(data)


def test_every_wall_style_pair_and_minimize_have_a_writer():
    """What was "cannot export yet" before issue 4/7/8 is exportable now."""
    region = {"regions": {"r": {"style": "sphere", "center": [5, 5, 5], "radius": 4.0, "units": "box"}}}
    for extra in ({"pair": {"style": "lj/cut", "epsilon": 1.0, "sigma": 1.0, "cutoff": 2.5}},
                  {"walls": {"fl": {"style": "flow", "axis": "x", "vflow": 0.4, "temperature": 1.5, "seed": 1,
                                    "coords": [5.0], "units": "box"}}},
                  {"walls": {"e": {"style": "ees", "units": "box", "zlo": [0.0, 1.0, 1.0, 2.5]}}},
                  {**region, "walls": {"rw": {"style": "region", "region": "r", "potential": "lj93",
                                              "epsilon": 1.0, "sigma": 1.0, "cutoff": 2.5}}},
                  {**region, "walls": {"re": {"style": "region/ees", "region": "r", "epsilon": 1.0, "sigma": 1.0,
                                              "cutoff": 2.5}}},
                  {"minimize": {"etol": 0.0, "ftol": 1e-8}}):
        check_exportable(_model(extra))
    assert set(WALL_WRITERS) == {"lj93", "lj126", "lj1043", "colloid", "harmonic", "morse", "ees", "reflect",
                                 "region", "region/ees", "flow", "lepton", "table", "reflect/stochastic"}
    assert set(PAIR_WRITERS) == {"lj/cut"} and set(ATOM_WRITERS) == {"atomic", "sphere", "ellipsoid"}


def test_spheres_with_ellipsoids_are_refused():
    cfg = _model({"atoms": [{"group": "g", "create": {"positions": [[5, 5, 5]]}, "mass": 1.0, "radius": 0.5},
                            {"group": "h", "create": {"positions": [[4, 4, 4]]}, "mass": 1.0,
                             "shape": [1.0, 0.5, 0.5]}]})
    with pytest.raises(ExportError, match=r"cannot export yet: atoms.0 \(radius\) with atoms.1 \(shape\)"):
        check_exportable(cfg)


SWEEP = """\
name: sw
units: lj
box: {lo: [0, 0, 0], hi: [10, 10, 10], boundary: [p, p, f]}
atoms:
  - group: g
    create: {positions: [[5, 5, 1.5], [4, 4, 8.5]]}
    mass: 1.0
    velocity: {values: [0.0, 0.0, -0.3]}
walls:
  w: {style: lj93, units: box, energy: true, zlo: [EDGE, 1.0, 1.0, 2.5], zhi: [EDGE, 1.0, 1.0, 2.5]}
run: {steps: 40, thermo: 10}
sweep:
  product:
    epsilon: {path: [walls.w.zlo.epsilon, walls.w.zhi.epsilon], values: [0.5, 1.0]}
    sigma: {path: walls.w.zlo.sigma, values: {linspace: [0.8, 1.0, 3]}}
"""


def test_case_selection(tmp_path):
    plan = load_plan(write(tmp_path, SWEEP))
    assert select_case(plan, "epsilon=1.0,sigma=0.9").coords == {"epsilon": 1.0, "sigma": 0.9}
    assert select_case(plan, " sigma = 0.8 , epsilon = 0.5 ").coords == {"epsilon": 0.5, "sigma": 0.8}
    assert select_case(plan, "3").coords == {"epsilon": 1.0, "sigma": 0.8}  # C order: epsilon outer
    assert select_case(plan, "-1").coords == {"epsilon": 1.0, "sigma": 1.0}
    for sel, msg in ((None, "6 cases"), ("epsilon=1.0", "3 cases match"), ("eps=1.0", "not a sweep dimension"),
                     ("epsilon=3.0,sigma=0.8", "no case has these coordinates"),
                     ("6", r"indexed 0 to 5 \(or -6 to -1 from the last\)"), ("-7", "indexed 0 to 5"),
                     ("epsilon", "name=value")):
        with pytest.raises(ExportError, match=msg):
            select_case(plan, sel)
    zipped = load_plan(Path(__file__).resolve().parents[2] / "sweeps" / "box-height-atoms-zip.yaml")
    assert select_case(zipped, "lz=16.0").coords == {"geometry": 1}  # a zip parameter names its dimension
    assert select_case(zipped, "geometry=2").coords == {"geometry": 2}
    exp = export_selected(plan, "epsilon=1.0,sigma=0.8")
    assert "fix w all wall/lj93 zlo EDGE 1.0 0.8 2.5 zhi EDGE 1.0 1.0 2.5 units box" in script_lines(exp.script)
    assert "case epsilon=1.0, sigma=0.8" in exp.script


def test_case_selection_by_a_list_valued_coordinate(tmp_path):
    """A sweep of list values (a wall face's [coord, epsilon, sigma, cutoff]) is selected by the
    list as typed: --case split at every comma, so `face=[EDGE, 2.0, 1.0, 2.5]` was "write
    name=value"; now commas inside brackets stay in the value, compared element by element."""
    text = SWEEP.split("sweep:")[0] + ("sweep:\n  product:\n    low: {path: walls.w.zlo, values: "
                                       "[[EDGE, 1.0, 1.0, 2.5], [EDGE, 2.0, 1.0, 2.5]]}\n"
                                       "    sigma: {path: walls.w.zhi.sigma, values: [0.8, 1.0]}\n")
    plan = load_plan(write(tmp_path, text))
    got = select_case(plan, "low=[EDGE, 2.0, 1.0, 2.5],sigma=0.8")
    assert got.coords["low"] == ["EDGE", 2.0, 1.0, 2.5] and got.coords["sigma"] == 0.8
    assert select_case(plan, "sigma=1.0, low=[EDGE,1,1,2.5]").coords["low"][1] == 1.0
    with pytest.raises(ExportError, match="no case has these coordinates"):
        select_case(plan, "low=[EDGE, 3.0, 1.0, 2.5],sigma=0.8")
    exp = export_selected(plan, "low=[EDGE, 2.0, 1.0, 2.5],sigma=0.8")
    assert "fix w all wall/lj93 zlo EDGE 2.0 1.0 2.5 zhi EDGE 1.0 0.8 2.5 units box" in script_lines(exp.script)


def test_export_command_writes_files(tmp_path):
    cfg = write(tmp_path, SWEEP)
    out = tmp_path / "lmp"
    result = runner.invoke(app, ["export-lammps", str(cfg), "--case", "1", "-o", str(out)])
    assert result.exit_code == 0, result.output
    exp = export_selected(load_plan(cfg), "1")
    assert (out / "in.sw").read_text() == exp.script
    assert (out / "data.sw").read_text() == exp.data
    result = runner.invoke(app, ["export-lammps", str(cfg), "-o", str(out)])
    assert result.exit_code == 2 and "choose one with --case" in result.output


# ----------------------------------------------------------------------------- validate (LAMMPS)


def validate(*args: str):
    return runner.invoke(app, ["validate", *map(str, args)])


# shipped configs that `validate` must pass with --steps 200 (every feature but wall/flow)
EXPORTABLE = {"colloid-slit", "dt-reset-rescue", "harmonic-confinement", "lj1043-graphite", "lj126-piston",
              "lj93-slit", "morse-metal", "quickstart", "reflect-piston", "reflect-swiggle",
              "ellipsoids-ees-slit", "colloid-cavity", "cylinder-obstacle", "lj-liquid-slit", "lj-adsorption-nvt",
              "lj-slit-profiles",
              "lepton-slit", "table-slit"}
FLOW = {"flow-seed"}  # exported, but compared with LAMMPS only statistically (tests/engine/test_flow.py)
THERMAL = {"thermal-walls"}  # wall/reflect/stochastic: statistically only (tests/engine/test_stochastic.py)


LANGEVIN_HOT = """\
units: lj
box: {lo: [0, 0, 0], hi: [6, 6, 6], boundary: [p, p, f]}
atoms:
  - group: a
    create: {positions: [[1.0, 2.0, 1.9], [4.0, 4.5, 3.0]]}
    mass: 1.0
walls:
  zw: {style: lj93, units: box, zlo: [EDGE, 1.0, 1.0, 2.5], zhi: [EDGE, 1.0, 1.0, 2.5]}
fixes:
  nve: {style: nve}
  l: "fix l all langevin TEMP 0.5 4242"
run: {steps: 40, thermo: 20}
"""


@requires_lammps
@pytest.mark.parametrize("temp", ["1.0 1.0", "0.0 0.0"])
def test_validate_refuses_langevin_above_zero_temperature(tmp_path, temp):
    """fix langevin above temp 0 draws random forces from wallbatch's own streams: validate stops
    with exit 2 and says where the thermostat is checked instead; at temp 0 (drag only) the case
    is compared, every row ok."""
    result = validate(write(tmp_path, LANGEVIN_HOT.replace("TEMP", temp)))
    if temp == "0.0 0.0":
        assert result.exit_code == 0, result.output
        assert all(r[3] == "ok" for r in report_rows(result.output).values())
        return
    assert result.exit_code == 2, result.output
    assert "fixes.l: fix langevin at a temperature above 0 adds random forces" in result.output
    assert "tests/engine/test_ensemble.py" in result.output


LEPTON_VIRIAL = """\
units: lj
seed: 5
box: {lo: [0, 0, 0], hi: [8, 8, 10], boundary: [p, p, f]}
regions:
  sl: {style: block, lo: [0, 0, 1.3], hi: [8, 8, 8.7], units: box}
atoms:
  - group: a
    create: {random: {count: 200, region: sl, overlap: 0.9}}
    mass: 1.0
    velocity: {temperature: 1.0}
walls:
  floor:
    style: lepton
    units: box
    energy: true
    virial: true
    zlo: {coord: EDGE, cutoff: 2.5, expression: "4*((1/r)^12-(1/r)^6)"}
    zhi: {coord: EDGE, cutoff: 2.5, expression: "4*((1/r)^12-(1/r)^6)"}
run: {steps: 60, thermo: 20}
output: {thermo: [step, time, temp, ke, pe, etot, press]}
"""


@requires_lammps
def test_lepton_virial_sign_is_lammps_s_vector_sign(tmp_path):
    """Decision: LAMMPS's wall/lepton adds its virial with the sign of its vector (the force on
    the atoms), the opposite of every other wall. wallbatch adds the virial of the wall's force:
    the lepton wall's press equals the same wall written as lj126 (in wallbatch, and in LAMMPS's
    wall/lj126), while LAMMPS's wall/lepton gives the kinetic part minus the wall's share.
    validate reports press as expected, every other output ok."""
    from wallbatch.config.models import load_config_text
    from wallbatch.engine.engine import run_cases
    from wallbatch.scene.build import build_case

    lj126 = LEPTON_VIRIAL.replace("style: lepton", "style: lj126").replace(
        'cutoff: 2.5, expression: "4*((1/r)^12-(1/r)^6)"', "epsilon: 1.0, sigma: 1.0, cutoff: 2.5")
    press, lmp = {}, {}
    for name, text in (("lepton", LEPTON_VIRIAL), ("lj126", lj126)):
        cfg = load_config_text(text)
        case = build_case(cfg)
        res = run_cases([case])[0]
        press[name], ke = res.data["press"], res.data["ke"]
        exp = validate_mod.export_case(cfg, case, data_dir=tmp_path / name)
        lmp[name] = validate_mod.run_lammps(exp, tmp_path / name)["press"]
    np.testing.assert_allclose(press["lepton"], press["lj126"], rtol=1e-12)
    np.testing.assert_allclose(lmp["lj126"], press["lj126"], rtol=1e-10)
    kinetic = 2.0 * ke / (3.0 * 8 * 8 * 10)  # LAMMPS press: (2 ke + W) / (3 V), lj units
    assert np.all(np.abs(press["lepton"] - kinetic) > 1e-3)  # the walls' virial is not negligible
    np.testing.assert_allclose(lmp["lepton"] - kinetic, -(press["lepton"] - kinetic), rtol=1e-9)
    result = validate(write(tmp_path, LEPTON_VIRIAL))
    assert result.exit_code == 0, result.output
    rows = report_rows(result.output)
    assert rows["press"][3] == "expected" and all(r[3] == "ok" for k, r in rows.items() if k != "press")


@requires_lammps
@pytest.mark.parametrize("name", sorted(p.stem for p in CONFIGS.glob("*.yaml")))
def test_validate_shipped_configs(name):
    """Every shipped config passes with --steps 200, but wall/flow configs: those stop with exit 2
    and say why (random numbers) and where they are checked instead."""
    path = CONFIGS / f"{name}.yaml"
    cfg = load_plan(path).cases[0].config
    check_exportable(cfg)
    result = validate(path, "--steps", 200)
    if any(w.style == "flow" for w in cfg.walls.values()):
        assert name in FLOW
        assert result.exit_code == 2, result.output
        assert "cannot be compared sample by sample" in result.output and "tests/engine/test_flow.py" in result.output
        return
    if any(w.style == "reflect/stochastic" for w in cfg.walls.values()):
        assert name in THERMAL
        assert result.exit_code == 2, result.output
        assert "checked statistically instead" in result.output and "tests/engine/test_stochastic.py" in result.output
        return
    assert name in EXPORTABLE
    assert result.exit_code == 0, result.output
    assert "ok: all" in result.output and "FAIL" not in result.output
    if "reflect" in name:  # frame: wall: compared with frame: lab, the configured run reported apart
        assert "differs by design" in result.output and "expected" in result.output


def test_shipped_configs_are_listed():
    """A new shipped config must be added to EXPORTABLE or FLOW (so the test above knows it)."""
    assert EXPORTABLE | FLOW | THERMAL == {p.stem for p in CONFIGS.glob("*.yaml")}
    for name in sorted(EXPORTABLE | FLOW | THERMAL):
        check_exportable(load_plan(CONFIGS / f"{name}.yaml").cases[0].config)
    assert (CONFIGS.parent / validate_mod.FLOW_TESTS).exists()  # where validate's refusal points


@requires_lammps
def test_validate_golden_scene(tmp_path):
    """Every converter at once (lattice, helper variable, swiggle under dt_reset, morse alpha,
    groups, reflect, dt/reset with NULL bounds) against LAMMPS, every face active."""
    result = validate(write(tmp_path, GOLDEN))
    assert result.exit_code == 0, result.output
    first = result.output.split("as configured")[0]  # the frame: lab comparison
    rows = {line.split()[0]: line.split() for line in first.splitlines() if line.endswith((" ok", " FAIL"))}
    assert len(rows) == 15
    for label in ("wall_force[zw/zlo]", "wall_force[zw/zhi]", "wall_force[xw/xlo]", "wall_force[xm/xhi]",
                  "wall_force[pw/zlo]"):
        assert float(rows[label][2]) < 1e-12 and rows[label][3] == "ok"


@requires_lammps
def test_validate_faces_really_act(tmp_path):
    """Guard against a vacuous golden comparison: LAMMPS sees a force on every face."""
    from wallbatch.lammps.export import lab_frame, lammps_ready
    from wallbatch.scene.build import build_case

    plan = load_plan(write(tmp_path, GOLDEN))
    sc = plan.cases[0]
    cfg, _ = lammps_ready(sc.config)
    lab, _ = lab_frame(cfg)
    exp = validate_mod.export_case(lab, build_case(lab, sc.seed_key), data_dir=tmp_path)
    ref = validate_mod.run_lammps(exp, tmp_path)
    for col in exp.columns:
        if col.key == "wall_force":
            assert np.any(ref[col.keyword] != 0.0), col.label
    assert len(np.unique(ref["dt"])) > 3  # dt/reset changes dt


@requires_lammps
def test_validate_sweep_case(tmp_path):
    result = validate(write(tmp_path, SWEEP), "--case", "epsilon=0.5,sigma=1.0")
    assert result.exit_code == 0, result.output
    assert "case epsilon=0.5, sigma=1.0: 40 steps, 5 samples" in result.output


@requires_lammps
def test_validate_fails_on_a_mismatch(tmp_path, monkeypatch):
    """A wall epsilon changed in the LAMMPS script only: the wall outputs must FAIL, exit 1."""
    real = validate_mod.export_case

    def broken(*args, **kwargs):
        exp = real(*args, **kwargs)
        line = "zlo EDGE 1.0 1.0 2.5 zhi EDGE 1.0 1.0 2.5"
        assert line in exp.script
        return dataclasses.replace(exp, script=exp.script.replace(line, line.replace("zhi EDGE 1.0", "zhi EDGE 1.001")))

    monkeypatch.setattr(validate_mod, "export_case", broken)
    result = validate(CONFIGS / "quickstart.yaml", "--steps", 100, "--set", "walls.zwalls.zhi.coord=EDGE")
    assert result.exit_code == 1, result.output
    fails = [line.split()[0] for line in result.output.splitlines() if line.endswith("FAIL")]
    assert "wall_force[zwalls/zhi]" in fails and "wall_energy[zwalls]" in fails
    assert "time" not in fails and "FAILED:" in result.output


@requires_lammps
def test_validate_rtol_option(tmp_path):
    """A tolerance below round-off fails the same (correct) run: the table is not vacuous."""
    result = validate(CONFIGS / "morse-metal.yaml", "--steps", 100, "--rtol", "1e-18")
    assert result.exit_code == 1, result.output
    assert "FAIL" in result.output and "rtol 1e-18" in result.output


@requires_lammps
def test_validate_lj1043_behind_the_wall(tmp_path):
    """Decisions table: wallbatch fails an lj1043 atom behind the wall, LAMMPS skips it."""
    text = SWEEP.split("sweep:")[0].replace("lj93", "lj1043").replace(
        "zlo: [EDGE, 1.0, 1.0, 2.5], zhi: [EDGE, 1.0, 1.0, 2.5]", "zlo: [2.0, 1.0, 1.0, 2.5]")
    cfg = write(tmp_path, text)
    assert "wall/lj1043 atom on or behind the wall" in export_selected(load_plan(cfg)).script
    result = validate(cfg)
    assert result.exit_code == 1, result.output
    assert "error: wallbatch:" in result.output and "Particle on or inside fix wall surface" in result.output
    assert "error: LAMMPS" not in result.output  # LAMMPS ran on


@requires_lammps
def test_validate_one_atom_ke_is_expected(tmp_path):
    text = SWEEP.split("sweep:")[0].replace(", [4, 4, 8.5]", "")
    result = validate(write(tmp_path, text))
    assert result.exit_code == 0, result.output
    status = {line.split()[0]: line.split()[-1] for line in result.output.splitlines()
              if line.split()[:1] in (["ke"], ["etot"], ["pe"])}
    assert status == {"ke": "expected", "etot": "expected", "pe": "ok"}


def test_validate_without_lammps(tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "lammps", None)  # `import lammps` now raises ImportError
    monkeypatch.setattr(ctypes, "CDLL", lambda *a, **k: None)
    result = validate(CONFIGS / "quickstart.yaml", "--steps", 10)
    assert result.exit_code == 2, result.output
    assert "install it with:  pip install lammps mpich" in result.output


# ----------------------------------------------------------------------------- validate: issue 4, 7, 8 features

# Ellipsoids and point atoms with pair forces, wall/region/ees on a sphere and wall/ees on a flat
# face (ellipsoids only), wall/region harmonic on a block and wall/morse (points only, virial on),
# erot, press and atoms: every new column in one run.
MIXED = """\
name: mixed
units: lj
seed: 21
box: {lo: [0, 0, 0], hi: [10, 10, 10], boundary: [p, f, f]}
regions:
  core: {style: sphere, center: [5, 5, 5], radius: 2.8, units: box}
  shell: {style: sphere, center: [5, 5, 5], radius: 4.6, units: box}
  bowl: {style: block, lo: [-1, 0.2, 0.2], hi: [11, 9.8, 9.8], units: box}
atoms:
  - group: rods
    create: {random: {count: 12, region: core, overlap: 1.6}}
    mass: 1.5
    shape: [0.6, 0.35, 0.3]
    orientation: random
    angmom: {values: [0.1, -0.2, 0.3]}
    velocity: {temperature: 1.5}
  - group: dots
    create: {random: {count: 10, region: core, overlap: 1.0}}
    mass: 0.5
    velocity: {temperature: 1.5}
pair: {style: lj/cut, epsilon: 0.5, sigma: 0.8, cutoff: 2.0}
walls:
  shell: {style: region/ees, region: shell, group: rods, epsilon: 2.0, sigma: 1.0, cutoff: 3.0, energy: true}
  box: {style: region, region: bowl, group: dots, potential: harmonic, epsilon: 5.0, cutoff: 1.5, energy: true,
        virial: true}
  ym: {style: morse, units: box, group: dots, energy: true, virial: true, ylo: [0.0, 1.0, 1.5, 1.2, 3.0]}
  zees: {style: ees, units: box, group: rods, energy: true, zlo: [EDGE, 1.0, 1.0, 3.0]}
run: {steps: 300, thermo: 50}
output: {thermo: [step, time, dt, temp, ke, pe, etot, erot, press, atoms]}
"""


def report_rows(output: str) -> dict[str, list[str]]:
    """label -> [label, max abs, max rel, status, detail...] of the compared run's table."""
    part = output.split("differs by design\n")[0]
    rows = {}
    for line in part.splitlines():
        words = line.split()
        if len(words) >= 4 and words[3] in ("ok", "FAIL", "expected"):
            rows[words[0]] = words
    return rows


@requires_lammps
def test_validate_mixed_scene_with_every_new_column(tmp_path):
    cfg = write(tmp_path, MIXED)
    result = validate(cfg)
    assert result.exit_code == 0, result.output
    rows = report_rows(result.output)
    assert len(rows) == 21 and all(r[3] == "ok" for r in rows.values())
    for label in ("erot", "press", "atoms", "region_force[shell/x]", "region_force[box/y]", "wall_force[ym/ylo]",
                  "wall_force[zees/zlo]"):
        assert label in rows and float(rows[label][2]) < 1e-12
    # not vacuous: in LAMMPS every fix acts at some sample, the walls torque the ellipsoids
    from wallbatch.lammps.export import lammps_ready
    from wallbatch.scene.build import build_case

    sc = load_plan(cfg).cases[0]
    c, _ = lammps_ready(sc.config)
    exp = validate_mod.export_case(c, build_case(c, sc.seed_key), data_dir=tmp_path)
    ref = validate_mod.run_lammps(exp, tmp_path)
    for key in ("f_shell", "f_box", "f_ym", "f_zees", "f_box[2]", "f_shell[3]", "f_ym[1]", "f_zees[1]"):
        assert np.any(ref[key] != 0.0), key
    assert np.ptp(ref["c_wb_erot"]) > 0.01 and np.all(ref["press"] != 0.0)


@requires_lammps
def test_validate_colloid_cavity_statuses():
    """Decisions table: the force-matched comparison agrees on forces (region_force, ke, temp) and
    reports the energies as expected; the script as exported runs LAMMPS's own physics."""
    result = validate(CONFIGS / "colloid-cavity.yaml", "--steps", 200)
    assert result.exit_code == 0, result.output
    rows = report_rows(result.output)
    status = {k: v[3] for k, v in rows.items()}
    assert status == {"time": "ok", "dt": "ok", "temp": "ok", "ke": "ok", "pe": "expected", "etot": "expected",
                      "wall_energy[cavity]": "expected", "region_force[cavity/x]": "ok",
                      "region_force[cavity/y]": "ok", "region_force[cavity/z]": "ok"}
    assert float(rows["wall_energy[cavity]"][2]) > 0.01  # the energies really differ
    assert "compared with LAMMPS run with -epsilon" in result.output
    # LAMMPS's own physics pulls the colloids into the cavity wall: that run stops (or differs)
    assert ("stopped in LAMMPS, by design: ERROR on proc 0: Particle outside surface of region" in result.output
            or "as exported (wall/region colloid" in result.output)


WALLMIN = """\
name: wallmin
units: lj
box: {lo: [0, 0, 0], hi: [8, 8, 6], boundary: [p, p, f]}
atoms:
  - group: a
    create: {positions: [[1.0, 2.0, 0.9], [4.0, 4.5, 2.0], [6.5, 1.0, 4.6], [2.5, 6.0, 3.3]]}
    mass: 1.0
    velocity: {values: [[0.3, 0.0, -0.2], [0.0, 0.4, 0.1], [-0.2, 0.1, 0.3], [0.1, -0.3, 0.0]]}
walls:
  zw: {style: lj93, units: box, energy: true, zlo: [EDGE, 1.0, 1.0, 2.5], zhi: [EDGE, 1.5, 1.2, 3.0]}
minimize: {style: cg, etol: 0.0, ftol: 1.0e-10, maxiter: 1000, maxeval: 10000}
run: {steps: 100, thermo: 20}
"""


@requires_lammps
def test_validate_minimize_walls_only(tmp_path):
    """Independent atoms at two lj93 walls: the cg path is the same in both codes, so every min_*
    result agrees (counts exactly), and so does the run after it."""
    result = validate(write(tmp_path, WALLMIN))
    assert result.exit_code == 0, result.output
    rows = report_rows(result.output)
    assert all(r[3] == "ok" for r in rows.values()) and len(rows) == 15
    for label in ("min_energy_before", "min_energy", "min_fnorm", "min_iterations", "min_evaluations",
                  "min_stop_reason"):
        assert label in rows
    assert float(rows["min_iterations"][1]) == 0.0 and float(rows["min_energy"][2]) < 1e-12
    assert "the run is compared from LAMMPS's minimized positions" in result.output


@requires_lammps
@pytest.mark.parametrize(("style", "zw"), [("cg", "6.0 - 0.02*step"), ("fire", "6.0 - 0.02*step"),
                                           ("cg", "ramp(6.0,5.7) - 0.4*time")])
def test_validate_minimize_with_a_wall_moved_by_step(tmp_path, style, zw):
    """A wall whose variable uses step (or ramp and time) moves during minimize in LAMMPS: its
    minimizer advances the step once per iteration, ramp runs over maxiter and time with the
    step. wallbatch evaluates the wall at the same steps (and, where cg's line search gives up,
    evaluates its start again at that step, as LAMMPS): every min_* result agrees, counts
    exactly. Before, the wall stood still: 15 iterations (the most) against LAMMPS's 5, min_energy
    off by 27%."""
    text = WALLMIN.replace("energy: true, zlo: [EDGE, 1.0, 1.0, 2.5], zhi: [EDGE, 1.5, 1.2, 3.0]",
                           "energy: true, zlo: [EDGE, 1.0, 1.0, 2.5], zhi: [v_zw, 1.5, 1.2, 3.0]")
    text = text.replace("minimize: {style: cg, etol: 0.0, ftol: 1.0e-10, maxiter: 1000,",
                        f"variables: {{zw: \"{zw}\"}}\nminimize: {{style: {style}, etol: 0.0, ftol: 1.0e-10, "
                        f"maxiter: 15,")
    assert "v_zw" in text and "maxiter: 15" in text
    result = validate(write(tmp_path, text))
    assert result.exit_code == 0, result.output
    rows = report_rows(result.output)
    assert all(r[3] == "ok" for r in rows.values()) and len(rows) == 15, result.output
    assert float(rows["min_iterations"][1]) == 0.0 and float(rows["min_energy"][1]) < 1e-12


@requires_lammps
def test_validate_minimize_forces_are_zero(tmp_path):
    """Atoms beyond every cut-off: wallbatch says `forces are zero`, LAMMPS `search direction is
    not downhill` (decisions table): the stopping criterion is expected to differ, not a failure."""
    text = WALLMIN.replace("0.9], [4.0, 4.5, 2.0], [6.5, 1.0, 4.6], [2.5, 6.0, 3.3]]", "3.0]]").replace(
        "[[0.3, 0.0, -0.2], [0.0, 0.4, 0.1], [-0.2, 0.1, 0.3], [0.1, -0.3, 0.0]]", "[0.0, 0.0, 0.1]")
    text = text.replace("zhi: [EDGE, 1.5, 1.2, 3.0]", "zhi: [EDGE, 1.5, 1.2, 2.5]")
    result = validate(write(tmp_path, text))
    assert result.exit_code == 0, result.output
    row = report_rows(result.output)["min_stop_reason"]
    assert row[3] == "expected"
    assert "wallbatch 'forces are zero', LAMMPS 'search direction is not downhill'" in result.output


@requires_lammps
def test_validate_minimize_with_pair_forces_that_part_ways(tmp_path):
    """60 random LJ atoms minimized to a tight force tolerance: the two cg paths part (forces summed
    in another order) and end in different local minima. validate fails the min_* rows and says
    why; the run, compared from LAMMPS's minimized positions, still agrees."""
    text = """\
name: parting
units: lj
seed: 9
box: {lo: [0, 0, 0], hi: [8, 8, 8], boundary: [p, p, f]}
regions:
  mid: {style: block, lo: [0, 0, 1.5], hi: [8, 8, 6.5], units: box}
atoms:
  - group: fluid
    create: {random: {count: 60, region: mid, overlap: 1.0}}
    mass: 1.0
    velocity: {temperature: 1.0}
pair: {style: lj/cut, epsilon: 1.0, sigma: 1.0, cutoff: 2.5, shift: true}
walls:
  zw: {style: lj93, units: box, energy: true, zlo: [EDGE, 1.0, 1.0, 2.5], zhi: [EDGE, 1.0, 1.0, 2.5]}
minimize: {style: cg, etol: 0.0, ftol: 1.0e-8, maxiter: 5000, maxeval: 50000}
run: {steps: 100, thermo: 50}
"""
    result = validate(write(tmp_path, text))
    assert result.exit_code == 1, result.output
    rows = report_rows(result.output)
    failed = {k for k, r in rows.items() if r[3] == "FAIL"}
    assert failed and failed <= {"min_energy", "min_fnorm", "min_iterations", "min_evaluations"}
    assert rows["min_energy_before"][3] == "ok" and rows["pe"][3] == "ok" and rows["ke"][3] == "ok"
    assert "the minimizations differ: with pair forces" in result.output


@requires_lammps
def test_minimize_fire_keeps_the_created_velocities_lammps_does_not(tmp_path):
    """Decision (the decisions table): after `minimize: {style: fire}` wallbatch's dynamics starts
    with the velocities the config created, as if LAMMPS's `velocity` came after `minimize` (a
    config has no other way to set them). LAMMPS's fire leaves its own damped velocities in the
    atoms: the exported script stores the velocities before minimize (fix store/state) and sets
    them back after it, so validate passes, every row; without those lines LAMMPS's run starts
    from fire's velocities. With velocities zero too (fire's are not)."""
    from wallbatch.config.models import load_config_text
    from wallbatch.engine.engine import run_cases
    from wallbatch.scene.build import build_case

    v0 = np.array([[0.3, 0.0, -0.2], [0.0, 0.4, 0.1], [-0.2, 0.1, 0.3], [0.1, -0.3, 0.0]])
    moving = WALLMIN.replace("style: cg", "style: fire")
    created = ("    velocity: {values: [[0.3, 0.0, -0.2], [0.0, 0.4, 0.1], [-0.2, 0.1, 0.3], "
               "[0.1, -0.3, 0.0]]}\n")
    resting = moving.replace("maxiter: 1000", "maxiter: 12").replace(created, "")
    assert resting != moving
    for text, ke0 in ((moving, 0.5 * np.sum(v0 * v0)), (resting, 0.0)):
        res = run_cases([build_case(load_config_text(text))])[0]
        assert res.data["ke"][0] == pytest.approx(ke0, rel=1e-14, abs=1e-300)
        result = validate(write(tmp_path, text))
        assert result.exit_code == 0, result.output
        assert all(r[3] == "ok" for r in report_rows(result.output).values())
        cfg = load_config_text(text)
        exp = validate_mod.export_case(cfg, build_case(cfg), data_dir=tmp_path / "plain")
        lines = script_lines(exp.script)
        assert "fix wb_v0 all store/state 0 vx vy vz" in lines
        assert "velocity all set v_wb_vx v_wb_vy v_wb_vz units box" in lines
        assert any("fix store/state" in d for d in exp.decisions)
        kept = [ln for ln in exp.script.splitlines() if "wb_v" not in ln]  # LAMMPS's own fire velocities
        ref = validate_mod.run_lammps(dataclasses.replace(exp, script="\n".join(kept) + "\n"), tmp_path / "plain")
        assert abs(ref["ke"][0] - ke0) > 1e-6  # fire's velocities, not the created ones


@requires_lammps
def test_flow_export_runs_in_lammps(tmp_path):
    """validate refuses wall/flow, but the exported script is a valid LAMMPS input (wall/flow
    after the pair style, minimize, then the run) that samples the same steps."""
    plan = load_plan(CONFIGS / "flow-seed.yaml")
    sc = plan.cases[0]
    from wallbatch.lammps.export import lammps_ready
    from wallbatch.scene.build import build_case

    cfg, _ = lammps_ready(sc.config, 40)
    exp = validate_mod.export_case(cfg, build_case(cfg, sc.seed_key), data_dir=tmp_path)
    assert "fix 1 all wall/flow x 0.4 1.5 593894 4 2.0 4.0 6.0 8.0 units box" in script_lines(exp.script)
    ref = validate_mod.run_lammps(exp, tmp_path)
    assert ref["step"].tolist() == [0.0, 40.0] and np.all(ref["temp"] > 0)
    assert ref["min:stop_reason"][0] in ("energy tolerance", "force tolerance", "max iterations")
