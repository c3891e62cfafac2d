"""`wallbatch import-lammps` and LAMMPS data files as an atom source (issue 16).

* Round trip: every shipped config, exported with `export-lammps` and imported back, runs
  bit-identically to the original (for a shortened run).
* LAMMPS-style scripts written here import, run in wallbatch and match LAMMPS running the script
  itself within 1e-9 (with --exact where the script draws random numbers).
* Unsupported commands are reported by line; --strict exits non-zero.
* Data files: positions, velocities, image flags, ellipsoid shapes (diameters in the file) and
  quaternions round-trip.
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from wallbatch import api
from wallbatch.cli import app
from wallbatch.config.models import config_from_dict, load_config, load_config_text
from wallbatch.config.sweep import config_to_dict
from wallbatch.lammps.export import (
    export_selected,
    lab_frame,
    lammps_ready,
    write_export,
)
from wallbatch.lammps.importer import LammpsImportError, import_lammps, import_lammps_text
from wallbatch.scene.build import build_case
from wallbatch.scene.case import CaseError
from wallbatch.scene.datafile import DataFileError, read_data_file, write_data_file

ROOT = Path(__file__).resolve().parents[2]
CONFIGS = sorted((ROOT / "configs").glob("*.yaml")) + sorted((ROOT / "configs" / "hard").glob("*.yaml"))
STEPS = 60
NO_LAMMPS = ("reflect_count", "reflect_impulse", "flow_crossings")


def _lammps_ok() -> bool:
    try:
        from wallbatch.lammps.validate import load_lammps

        load_lammps()
        return True
    except Exception:  # noqa: BLE001
        return False


needs_lammps = pytest.mark.skipif(not _lammps_ok(), reason="LAMMPS Python module not usable")


def _same(a, b) -> bool:
    a, b = np.asarray(a), np.asarray(b)
    if a.dtype.kind in "fc":
        return a.shape == b.shape and np.array_equal(a, b, equal_nan=True)
    return a.shape == b.shape and np.array_equal(a, b)


# ----------------------------------------------------------------------------- round trip


@pytest.mark.slow
@pytest.mark.parametrize("path", CONFIGS, ids=[p.stem for p in CONFIGS])
def test_round_trip_every_shipped_config(path: Path, tmp_path: Path) -> None:
    """export-lammps then import-lammps: same atoms, same walls, bit-identical results."""
    plan = api.load(path)
    sc = plan.cases[0]
    # what the export can express: a step-based run, reflection in the lab frame (LAMMPS's rule)
    original, _ = lammps_ready(sc.config, STEPS)
    original, _ = lab_frame(original)
    # outputs without a LAMMPS counterpart (not exported, so not imported back)
    data = config_to_dict(original)
    data.setdefault("output", {})["thermo"] = [k for k in original.output.thermo if k not in NO_LAMMPS]
    data["output"].pop("dump", None)
    original = config_from_dict(data, base=original._base_dir)
    exp = export_selected(api.load(original), None, STEPS)
    script, _ = write_export(exp, tmp_path / "lmp")
    out = tmp_path / "back.yaml"
    result = import_lammps(script, out)
    out.write_text(result.text)
    assert result.complete, result.text
    back = load_config(out)
    case_a, case_b = build_case(original, sc.seed_key), build_case(back)
    for key in ("x", "v", "mass", "radius", "box_lo", "box_hi", "periodic", "shape", "quat", "angmom"):
        assert _same(getattr(case_a, key), getattr(case_b, key)), key
    if original.walls and any(w.style in ("flow", "reflect/stochastic") for w in original.walls.values()) \
            and original.seed != back.seed:
        pytest.skip("flow-wall and thermal-wall random streams derive from the config seed, which a LAMMPS script "
                    "does not carry")
    ds_a, ds_b = api.run(original), api.run(back)
    shared = set(ds_a.data_vars) & set(ds_b.data_vars)
    assert set(ds_a.data_vars) == set(ds_b.data_vars)
    assert {"ke", "pe", "etot"} <= shared
    for name in sorted(shared):
        if name in ("seconds",):  # wall-clock time
            continue
        assert _same(ds_a[name].values, ds_b[name].values), name


# ----------------------------------------------------------------------------- data files


def test_data_file_round_trip_atomic_with_image_flags(tmp_path: Path) -> None:
    rng = np.random.default_rng(1)
    x = rng.random((7, 3)) * [10.0, 8.0, 6.0]
    v = rng.standard_normal((7, 3))
    image = rng.integers(-2, 3, size=(7, 3))
    mass = np.array([1.0, 2.5, 1.0, 1.0, 2.5, 3.25, 1.0])
    p = write_data_file(tmp_path / "a.data", (0, 0, 0), (10, 8, 6), x, mass, v=v, image=image)
    df = read_data_file(p)
    assert df.style == "atomic" and df.natoms == 7
    assert np.array_equal(df.x, x) and np.array_equal(df.v, v) and np.array_equal(df.mass, mass)
    assert np.array_equal(df.image, image) and np.array_equal(df.ids, np.arange(1, 8))
    assert np.array_equal(df.unwrapped(), x + image * np.array([10.0, 8.0, 6.0]))
    # a non-periodic dimension: image flags there are dropped (LAMMPS resets them)
    df2 = read_data_file(p, periodic=(True, True, False))
    assert np.array_equal(df2.image[:, 2], np.zeros(7)) and np.array_equal(df2.image[:, :2], image[:, :2])


def test_data_file_wraps_outside_atoms_and_sorts_ids(tmp_path: Path) -> None:
    text = """title

3 atoms
1 atom types
0 10 xlo xhi
0 10 ylo yhi
0 10 zlo zhi

Masses

1 2.0

Atoms # atomic

3 1 1.0 1.0 1.0
1 1 12.5 5.0 5.0 0 0 0
2 1 -1.5 5.0 5.0 1 0 0
"""
    (tmp_path / "w.data").write_text(text.replace("3 1 1.0 1.0 1.0", "3 1 1.0 1.0 1.0 0 0 0"))
    df = read_data_file(tmp_path / "w.data")
    assert df.ids.tolist() == [1, 2, 3]
    assert df.x[0].tolist() == [2.5, 5.0, 5.0] and df.image[0].tolist() == [1, 0, 0]
    assert df.x[1].tolist() == [8.5, 5.0, 5.0] and df.image[1].tolist() == [0, 0, 0]
    assert np.allclose(df.unwrapped(), [[12.5, 5, 5], [-1.5 + 1 * 10.0, 5, 5], [1, 1, 1]])
    (tmp_path / "bad.data").write_text(text)
    with pytest.raises(DataFileError, match="mix rows with and without image flags"):
        read_data_file(tmp_path / "bad.data")


def test_data_file_round_trip_ellipsoids_diameters_and_quaternions(tmp_path: Path) -> None:
    rng = np.random.default_rng(3)
    n = 5
    x = rng.random((n, 3)) * 9 + 0.5
    shape = np.array([[1.0, 0.5, 0.5]] * 3 + [[0.0, 0.0, 0.0]] * 2)  # semi-axes; two point atoms
    q = rng.standard_normal((n, 4))
    q /= np.linalg.norm(q, axis=1)[:, None]
    L = rng.standard_normal((n, 3))
    mass = np.array([1.0, 1.0, 2.0, 0.5, 0.5])
    p = write_data_file(tmp_path / "e.data", (0, 0, 0), (10, 10, 10), x, mass, v=np.ones((n, 3)), shape=shape,
                        quat=q, angmom=L)
    text = p.read_text()
    assert "3 ellipsoids" in text and "Atoms # ellipsoid" in text
    ell_lines = text.split("Ellipsoids\n\n")[1].split("\n\n")[0].splitlines()
    assert ell_lines[0].split()[1:4] == ["2.0", "1.0", "1.0"]  # diameters in the file
    df = read_data_file(p)
    assert df.style == "ellipsoid"
    assert np.array_equal(df.shape, shape)  # semi-axes again
    assert np.array_equal(df.quat[:3], q[:3]) and np.array_equal(df.angmom, L) and np.array_equal(df.x, x)
    assert np.allclose(df.mass, mass, rtol=1e-15, atol=0)


def test_data_file_as_atom_source_with_ids(tmp_path: Path) -> None:
    x = np.array([[1.0, 1, 1], [2, 2, 2], [3, 3, 3], [4, 4, 4]])
    write_data_file(tmp_path / "s.data", (0, 0, 0), (10, 10, 10), x, np.array([1.0, 1.0, 2.0, 2.0]),
                    v=np.arange(12.0).reshape(4, 3))
    cfg = load_config_text("""
box: {lo: [0, 0, 0], hi: [10, 10, 10], boundary: [f, f, f]}
atoms:
  - {group: light, create: {file: s.data, ids: "1:2"}}
  - {group: heavy, create: {file: s.data, ids: "3:4"}, mass: 5.0, velocity: {values: [0, 0, 1]}}
run: {steps: 0}
""", "t.yaml", base=tmp_path)
    case = build_case(cfg)
    assert np.array_equal(case.x, x) and case.mass.tolist() == [1.0, 1.0, 5.0, 5.0]
    assert case.v[:2].tolist() == [[0, 1, 2], [3, 4, 5]] and case.v[2:].tolist() == [[0, 0, 1]] * 2
    bad = load_config_text("""
box: {lo: [0, 0, 0], hi: [10, 10, 10]}
atoms: [{group: g, create: {file: s.data, ids: "9:12"}}]
run: {steps: 0}
""", "t.yaml", base=tmp_path)
    with pytest.raises(CaseError, match=r"atoms\.0\.create\.ids: no atom of .* has an ID in 9:12"):
        build_case(bad)
    with pytest.raises(Exception, match=r"quoted string.*got 184"):  # YAML 1.1 reads 3:4 as 184
        load_config_text("box: {lo: [0,0,0], hi: [10,10,10]}\natoms: [{group: g, create: {file: s.data, ids: 3:4}}]\n"
                         "run: {steps: 0}\n")
    with pytest.raises(Exception, match="ids selects atoms of a LAMMPS data file"):
        load_config_text("box: {lo: [0,0,0], hi: [1,1,1]}\natoms: [{group: g, mass: 1, create: {positions: "
                         "[[0.5,0.5,0.5]], ids: '1'}}]\nrun: {steps: 0}\n")


def test_outside_box_message_names_the_lammps_atom_id(tmp_path: Path) -> None:
    cfg = load_config_text("""
box: {lo: [0, 0, 0], hi: [10, 10, 10], boundary: [f, f, f]}
atoms: [{group: g, mass: 1.0, create: {positions: [[1, 1, 1], [5, 5, 11]]}}]
run: {steps: 0}
""")
    with pytest.raises(CaseError, match=r"atom ID 2 at \[5\.0, 5\.0, 11\.0\]"):
        build_case(cfg)


# ----------------------------------------------------------------------------- unsupported commands


UNSUPPORTED = """# a script with things the importer cannot express
units lj
atom_style atomic
region box block 0 10 0 10 0 10 units box
create_box 1 box
create_atoms 1 single 5 5 5 units box
mass 1 1.0
pair_style lj/cut/coul/long 2.5
compute myT all temp/partial 0 1 1
fix 1 all nve
fix 2 all npt temp 1.0 1.0 0.5 iso 1.0 1.0 5.0
dump d1 all xyz 100 dump.xyz
thermo 10
thermo_modify norm no
run 100
"""


def test_unsupported_commands_are_listed_by_line(tmp_path: Path) -> None:
    result = import_lammps_text(UNSUPPORTED, tmp_path)
    lines = {i.line: i.reason for i in result.unsupported}
    assert set(lines) == {8, 9, 11, 12}, lines
    assert "pair_style lj/cut/coul/long" in lines[8] and "temp/partial" in lines[9] and "npt" in lines[11]
    assert not result.complete
    tail = result.text.split("NOT IMPORTED (4)")[1]
    for n in (8, 9, 11, 12):
        assert re.search(rf"line {n}: ", tail)
    assert "line 14: thermo_modify norm no" in result.text.split("Ignored")[1]
    runner = CliRunner()
    script = tmp_path / "in.script"
    res = runner.invoke(app, ["import-lammps", str(script), "-o", str(tmp_path / "c.yaml")])
    assert res.exit_code == 0
    res = runner.invoke(app, ["import-lammps", str(script), "-o", str(tmp_path / "c.yaml"), "--strict", "--force"])
    assert res.exit_code == 1 and "in.script:11: fix 2 all npt" in res.output


MALFORMED = """units lj
region box block 0 10 0 10 0 10 units box
create_box 1 box
create_atoms 1 single 5 5 5 units box
mass 1 1.0
lattice fcc 0
lattice fcc -0.8
timestep
fix 1 all nve
fix w all wall/lj93 zlo EDGE 1.0 1.0 2.5 units box
fix_modify
run
"""


def test_malformed_commands_are_listed_by_line_not_raised(tmp_path: Path) -> None:
    """A command with too few words or unusable values is one NOT IMPORTED line naming the command
    (found by fuzzing the shipped example script: these raised IndexError and ZeroDivisionError)."""
    result = import_lammps_text(MALFORMED, tmp_path)
    got = [(i.line, i.reason) for i in result.unsupported]
    assert got == [(6, "the lattice scale must be a positive number, got 0"),
                   (7, "the lattice scale must be a positive number, got -0.8"),
                   (8, "timestep: too few arguments (LAMMPS would stop here too)"),
                   (11, "fix_modify: too few arguments (LAMMPS would stop here too)"),
                   (12, "run: too few arguments (LAMMPS would stop here too)"),
                   (12, "no run command: imported as a run of 0 steps")]
    res = CliRunner().invoke(app, ["import-lammps", str(tmp_path / "in.script"), "-o", str(tmp_path / "c.yaml")])
    assert res.exit_code == 0 and "Traceback" not in res.output


def test_velocity_and_set_lines_not_imported_say_to_use_exact(tmp_path: Path) -> None:
    """`velocity ... sum yes`, `velocity ... NULL`, `velocity scale` and `set ... type`: the reasons
    said only "not supported"; --exact (LAMMPS builds the state) imports such scripts."""
    script = MALFORMED.split("lattice fcc 0")[0] + ("velocity all set 0.1 0.0 0.0 sum yes\n"
                                                    "velocity all set NULL 0.0 0.0\nvelocity all scale 1.5\n"
                                                    "set type 1 type 1\nfix 1 all nve\nrun 10\n")
    got = [(i.line, i.reason) for i in import_lammps_text(script, tmp_path).unsupported]
    hint = "; import with --exact to start from the velocities LAMMPS gives the atoms"
    assert got == [(6, "velocity set keywords {'sum': 'yes'} are not supported" + hint),
                   (7, "velocity set with NULL components is not supported" + hint),
                   (8, "velocity scale is not supported (create, set)" + hint),
                   (9, "set keyword 'type' is not supported (mass; diameter for spheres); import with --exact to "
                       "start from the atoms LAMMPS sets")], got


def test_an_undefined_variable_is_reported_at_the_line_that_uses_it(tmp_path: Path) -> None:
    """A wall coordinate v_top with no `variable top` (and a variable using an undefined one): the
    issue points at the wall fix (and at that variable), not at line 0 (found by fuzzing)."""
    script = MALFORMED.split("lattice fcc 0")[0] + (
        "variable lift equal v_nowhere+1\n"
        "fix w all wall/lj93 zlo EDGE 1.0 1.0 2.5 zhi v_top 1.0 1.0 2.5 units box\n"
        "fix v all wall/lj93 ylo v_lift 1.0 1.0 2.5 units box\n"
        "run 10\n")
    got = [(i.line, i.reason) for i in import_lammps_text(script, tmp_path).unsupported]
    assert (7, "variable top is not defined") in got and (6, "variable nowhere is not defined") in got, got
    assert all(line >= 1 for line, _ in got)


def test_a_script_that_includes_itself_is_not_followed_forever(tmp_path: Path) -> None:
    """`include in.script` inside in.script: the importer follows it 32 levels deep, then lists the
    include line as not imported (it raised RecursionError before; found by hand after the fuzz test)."""
    script = MALFORMED.split("lattice fcc 0")[0] + "include in.script\nrun 10\n"
    result = import_lammps_text(script, tmp_path)
    nested = [i for i in result.unsupported if "include nested more than 32 deep" in i.reason]
    assert len(nested) == 1 and nested[0].line == 6, result.unsupported


def test_a_type_without_mass_stops_the_import_with_the_script_named(tmp_path: Path) -> None:
    """LAMMPS refuses to run with a type that has no mass; the import says so instead of raising an
    internal error (found by fuzzing)."""
    script = MALFORMED.replace("mass 1 1.0\n", "")
    with pytest.raises(LammpsImportError, match=r"in\.script: atom type 1 has no mass \(mass 1 VALUE\)"):
        import_lammps_text(script, tmp_path)
    res = CliRunner().invoke(app, ["import-lammps", str(tmp_path / "in.script"), "-o", str(tmp_path / "c.yaml")])
    assert res.exit_code == 2 and "atom type 1 has no mass" in res.output and "Traceback" not in res.output


@pytest.mark.lammps
@needs_lammps
def test_set_mass_on_atomic_atoms_is_refused_as_lammps_stops_there(tmp_path: Path) -> None:
    """`set type 2 mass 5.0` with atom_style atomic: LAMMPS stops ("Cannot set attribute mass"); the
    import gave the atoms mass 5 silently. Now the line is listed, with what to do; sphere atoms
    keep their per-atom masses."""
    script = MALFORMED.split("lattice fcc 0")[0] + "set type 1 mass 5.0\nfix 1 all nve\nrun 10\n"
    got = [(i.line, i.reason) for i in import_lammps_text(script, tmp_path).unsupported]
    assert got == [(6, "set mass: LAMMPS stops here (atom_style atomic has per-type masses only): give the "
                       "atoms their own type and use 'mass TYPE VALUE', or use atom_style sphere")], got
    from wallbatch.lammps.validate import load_lammps

    lmp = load_lammps().lammps(cmdargs=["-screen", "none", "-log", "none", "-nocite"])
    with pytest.raises(Exception, match="Cannot set attribute mass for atom style atomic"):
        lmp.commands_string(script.replace("run 10\n", ""))
    lmp.close()
    sphere = script.replace("units lj\n", "units lj\natom_style sphere\n")
    r = import_lammps_text(sphere, tmp_path)
    assert r.unsupported == [] and "mass: 5.0" in r.text


def test_no_box_names_the_commands_it_could_not_import(tmp_path: Path) -> None:
    """A script whose box region cannot be imported (a prism), so neither can create_box: the
    import stops with "no box", and says why, line by line (it said only "no box")."""
    script = ("dimension 2\nunits lj\nboundary p f p\nlattice hex 0.7\n"
              "region box prism 0 20 0 10 -0.25 0.25 1 0 0\ncreate_box 1 box\ncreate_atoms 1 box\n"
              "mass 1 1.0\nfix 1 all nve\nfix 2 all enforce2d\nrun 10\n")
    with pytest.raises(LammpsImportError) as err:
        import_lammps_text(script, tmp_path)
    text = str(err.value)
    assert "in.script: no box (create_box or read_data) in the script; not imported:\n" in text, text
    assert "in.script:5: region box prism 0 20 0 10 -0.25 0.25 1 0 0  ->  region style prism" in text
    assert "in.script:6: create_box 1 box  ->  create_box needs a block region (got 'box')" in text
    res = CliRunner().invoke(app, ["import-lammps", str(tmp_path / "in.script")])
    assert res.exit_code == 2 and "in.script:5: region" in res.output and "Traceback" not in res.output


def test_no_atoms_names_the_creation_commands_it_could_not_import(tmp_path: Path) -> None:
    """`create_atoms ... basis 1 1` is not imported, so the script creates no atoms: the import
    stopped with "the script creates no atoms" only, not saying which line or why."""
    script = ("units lj\nboundary p p f\nlattice fcc 0.8442\nregion box block 0 4 0 4 0 6\ncreate_box 1 box\n"
              "create_atoms 1 box basis 1 1\nmass 1 1.0\nfix 1 all nve\nrun 10\n")
    with pytest.raises(LammpsImportError) as err:
        import_lammps_text(script, tmp_path)
    text = str(err.value).replace(f"{tmp_path}/", "")
    assert text == ("in.script: the script creates no atoms (create_atoms or read_data); not imported:\n"
                    "  in.script:6: create_atoms 1 box basis 1 1  ->  create_atoms keywords basis 1 1 are "
                    "not supported"), text
    res = CliRunner().invoke(app, ["import-lammps", str(tmp_path / "in.script")])
    assert res.exit_code == 2 and "in.script:6: create_atoms" in res.output and "Traceback" not in res.output


# ----------------------------------------------------------------------------- scripts vs LAMMPS


def _import_script(tmp_path: Path, text: str, name: str):
    """Write `text` as tmp_path/in.NAME, import it (complete) into NAME.yaml beside it and load
    that: (the script's path, the import result, the loaded config)."""
    script = tmp_path / f"in.{name}"
    script.write_text(text)
    result = import_lammps(script, tmp_path / f"{name}.yaml")
    assert result.complete, result.text
    (tmp_path / f"{name}.yaml").write_text(result.text)
    return script, result, load_config(tmp_path / f"{name}.yaml")


def _run_lammps_script(script: Path, columns: list[str], variables: dict[str, str] | None = None) -> np.ndarray:
    """Run a script in LAMMPS (its folder as working directory); the last thermo table (columns
    `step` + `columns`, 17 digits via thermo_modify)."""
    import os

    from wallbatch.lammps.log import last_thermo
    from wallbatch.lammps.validate import load_lammps

    module = load_lammps()
    args = ["-screen", "none", "-log", "none", "-nocite"]
    for k, v in (variables or {}).items():
        args += ["-var", k, v]
    lmp = module.lammps(cmdargs=args)
    here = os.getcwd()
    log = script.parent / "log.lammps"
    try:
        os.chdir(script.parent)
        lmp.command(f'log "{log}"')
        lmp.file(str(script))
    finally:
        os.chdir(here)
        lmp.close()
    return last_thermo(log.read_text(), len(columns) + 1)


THERMO = "thermo_style custom step temp ke pe etotal\nthermo_modify norm no format float %.17g\n"

LATTICE_SLIT = """# an fcc gas slab between lj93 walls, built from a lattice
variable        rho index 0.5
variable        zw equal 6.0
units           lj
dimension       3
boundary        p p f
atom_style      atomic
lattice         fcc ${rho}
region          box block 0 4 0 4 0 ${zw}
create_box      1 box
region          slab block INF INF INF INF 1.2 4.6
create_atoms    1 region slab
mass            1 1.0
velocity        all set 0.1 -0.2 0.3 units box
pair_style      lj/cut 2.5
pair_coeff      1 1 1.0 1.0
pair_modify     shift yes
variable        top equal $(zhi)-ramp(0.0,1.5)
fix             1 all nve
fix             walls all wall/lj93 zlo EDGE 1.0 1.0 2.5 zhi v_top 1.0 1.0 $(2.5*1.0) units box
fix_modify      walls energy yes
timestep        0.004
""" + THERMO + """thermo          20
run             200
"""


@pytest.mark.lammps
@needs_lammps
def test_lattice_region_create_atoms_variables_match_lammps(tmp_path: Path) -> None:
    script, result, cfg = _import_script(tmp_path, LATTICE_SLIT, "slit")
    assert cfg.lattice.scale == 0.5 and cfg.atoms[0].create.lattice is not None
    assert cfg.walls["walls"].zhi.cutoff == 2.5 and cfg.variables["top"] == "12-ramp(0.0,1.5)"
    ref = _run_lammps_script(script, ["temp", "ke", "pe", "etotal"])
    ds = api.run(cfg)
    assert int(ds.sizes.get("atom", 0) or build_case(cfg).natoms) == _count_atoms(tmp_path, LATTICE_SLIT)
    for j, key in enumerate(["temp", "ke", "pe", "etot"], start=1):
        np.testing.assert_allclose(ds[key].values.ravel(), ref[:, j], rtol=1e-9, atol=1e-12)


HEX_CHANNEL = """# a 2-D hex crystal between walls, every length in lattice units (x and y spacings differ)
dimension       2
units           lj
boundary        p f p
atom_style      atomic
lattice         hex 0.7
region          box block 0 12 0 8 -0.25 0.25
create_box      1 box
region          film block INF INF 1.2 4.8 INF INF
create_atoms    1 region film
region          ball sphere 6 3 0 1.45
create_atoms    1 region ball
region          rod cylinder z 9.5 3.5 1.2 INF INF
create_atoms    1 region rod
mass            1 1.0
velocity        all set 0.3 -0.4 0.0
create_atoms    1 single 3.3 6.5 0.0
fix             1 all nve
fix             2 all enforce2d
fix             walls all wall/lj93 ylo 0.3 1.0 1.0 2.5 yhi 7.5 1.0 1.0 2.5
fix_modify      walls energy yes
""" + THERMO + """thermo          10
run             60
"""


@pytest.mark.lammps
@needs_lammps
def test_hex_lattice_units_import_with_each_axis_spacing(tmp_path: Path) -> None:
    """A 2-D script on a hex lattice with its box, regions, a single atom, velocities and walls in
    lattice units (LAMMPS's default), whose x and y spacings differ (a, sqrt(3) a): imported in
    box units, each length scaled as LAMMPS scales it (a sphere's radius and a z cylinder's by
    xlattice); the import was refused. The same box, atoms (the ball and rod regions add atoms on
    top of the film's: an ideal gas) and thermo as LAMMPS."""
    script = tmp_path / "in.hex"
    script.write_text(HEX_CHANNEL)
    result = import_lammps(script, tmp_path / "hex.yaml")
    assert result.complete, result.text
    cfg = load_config_text(result.text, str(tmp_path / "hex.yaml"))
    a = (2.0 / (3.0 ** 0.5 * 0.7)) ** 0.5  # hex: 2 atoms per a x sqrt(3) a cell at reduced density 0.7
    assert cfg.box.hi[0] == pytest.approx(12 * a, rel=1e-14) and cfg.box.hi[1] == pytest.approx(8 * 3 ** 0.5 * a)
    assert cfg.walls["walls"].yhi.coord == pytest.approx(7.5 * 3 ** 0.5 * a) and cfg.walls["walls"].units == "box"
    assert build_case(cfg).natoms == _count_atoms(tmp_path, HEX_CHANNEL) == 99  # ball, rod: scaled as LAMMPS
    ref = _run_lammps_script(script, ["temp", "ke", "pe", "etotal"])
    ds = api.run(cfg)
    for j, key in enumerate(["temp", "ke", "pe", "etot"], start=1):
        np.testing.assert_allclose(ds[key].values.ravel(), ref[:, j], rtol=1e-9, atol=1e-12)


NO_LATTICE = """# lattice units (LAMMPS's default) with no lattice command: LAMMPS's lattice none 1.0
units           lj
boundary        p p f
region          box block 0 10 0 10 0 10
create_box      1 box
create_atoms    1 single 4.0 5.0 5.0
create_atoms    1 single 6.0 5.0 5.5
mass            1 1.0
velocity        all set 0.5 0.0 0.0
region          cav sphere 5 5 5 3.0 side in
fix             1 all nve
fix             w all wall/region cav harmonic 1.0 1.0 2.0
fix_modify      w energy yes
""" + THERMO + """thermo          20
run             200
"""


@pytest.mark.lammps
@needs_lammps
def test_lattice_units_without_a_lattice_command_are_box_units_as_in_lammps(tmp_path: Path) -> None:
    script = tmp_path / "in.nolat"
    script.write_text(NO_LATTICE)
    result = import_lammps(script, tmp_path / "nolat.yaml")
    assert result.complete, result.text
    assert "line 4: units lattice (the LAMMPS default) before any lattice command" in result.text
    cfg = load_config_text(result.text, tmp_path / "nolat.yaml")
    assert cfg.regions["cav"].radius == 3.0
    ref = _run_lammps_script(script, ["temp", "ke", "pe", "etotal"])
    assert ref[-1, 3] > 0  # the atoms reach the wall
    ds = api.run(cfg)
    for j, key in enumerate(["temp", "ke", "pe", "etot"], start=1):
        np.testing.assert_allclose(ds[key].values.ravel(), ref[:, j], rtol=1e-9, atol=1e-12)


def _count_atoms(folder: Path, text: str) -> int:
    from wallbatch.lammps.validate import load_lammps

    module = load_lammps()
    lmp = module.lammps(cmdargs=["-screen", "none", "-log", "none", "-nocite"])
    try:
        for line in text.splitlines():
            if line.startswith("run"):
                break
            lmp.command(line)
        return int(lmp.get_natoms())
    finally:
        lmp.close()


RANDOM_DTRESET = """# random gas near a wall, rescued by dt/reset; velocities from LAMMPS's generator
units           lj
boundary        p p f
atom_style      atomic
region          box block 0 8 0 8 0 8 units box
create_box      1 box
region          mid block EDGE EDGE EDGE EDGE 1.5 6.5 units box
create_atoms    1 random 120 4821 mid overlap 0.9 maxtry 100
create_atoms    1 single 4.0 4.0 0.6 units box
mass            1 1.0
velocity        all create 1.2 87287 loop geom
variable        wig equal "8.0 - 0.5*time"
fix             1 all nve
fix             lo all wall/lj126 zlo EDGE 1.0 1.0 2.5 units box
fix             hi all wall/harmonic zhi v_wig 5.0 1.0 1.5 units box
fix_modify      lo energy yes
fix             dt all dt/reset 1 1.0e-5 0.004 0.02 units box
""" + THERMO.replace("etotal", "etotal dt") + """thermo          10
run             150
"""


@pytest.mark.lammps
@needs_lammps
def test_random_script_with_exact_and_dt_reset_matches_lammps(tmp_path: Path) -> None:
    script = tmp_path / "in.rand"
    script.write_text(RANDOM_DTRESET)
    plain = import_lammps(script, tmp_path / "plain.yaml")
    assert plain.complete and "create_atoms random" in plain.text  # reported as a random draw
    result = import_lammps(script, tmp_path / "rand.yaml", exact=True)
    assert result.complete, result.text
    assert result.written == [tmp_path / "rand.data"] and (tmp_path / "rand.data").exists()
    (tmp_path / "rand.yaml").write_text(result.text)
    cfg = load_config(tmp_path / "rand.yaml")
    assert cfg.atoms[0].create.file == "rand.data" and cfg.dt_reset.xmax == 0.02
    ref = _run_lammps_script(script, ["temp", "ke", "pe", "etotal", "dt"])
    ds = api.run(cfg)
    for j, key in enumerate(["temp", "ke", "pe", "etot", "dt"], start=1):
        np.testing.assert_allclose(ds[key].values.ravel(), ref[:, j], rtol=1e-9, atol=1e-12)


TWO_TYPES_ONE_DRAW = """# two atom types, only one walled: velocity all create spans two wallbatch groups
units           lj
boundary        p p f
atom_style      atomic
region          box block 0 6 0 6 0 6 units box
create_box      2 box
region          mid block EDGE EDGE EDGE EDGE 1.5 4.5 units box
create_atoms    1 random 24 4821 mid
create_atoms    2 random 16 3907 mid
mass            1 1.0
mass            2 3.0
group           heavy type 2
velocity        all create 0.5 4928459
fix             1 all nve
fix             w heavy wall/lj93 zlo EDGE 1.0 1.0 2.5 zhi EDGE 1.0 1.0 2.5 units box
""" + THERMO + """thermo          5
run             10
"""


def test_velocity_create_over_several_groups_is_one_draw(tmp_path: Path) -> None:
    """`velocity all create T` over atoms the importer splits into two groups (the walled type and
    the other): both velocity entries share the label `all`, so the start has zero momentum and
    exactly T over all 40 atoms, as LAMMPS's; each group apart would lose 3 dof (T 0.487)."""
    script = tmp_path / "in.two"
    script.write_text(TWO_TYPES_ONE_DRAW)
    result = import_lammps(script, tmp_path / "two.yaml")
    assert result.complete, result.text
    cfg = load_config_text(result.text, tmp_path / "two.yaml")
    vels = [g.velocity for g in cfg.atoms]
    assert len(vels) == 2 and all(v is not None and v.temperature == 0.5 and v.shared == "all" for v in vels)
    assert "over the LAMMPS group all" in result.text
    case = build_case(cfg)
    m, v = case.mass, case.v
    assert np.abs((m[:, None] * v).sum(axis=0)).max() < 1e-13
    assert float((m[:, None] * v * v).sum()) / (3 * 40 - 3) == pytest.approx(0.5, rel=1e-13)


@pytest.mark.lammps
@needs_lammps
def test_velocity_create_over_several_groups_starts_at_lammps_temperature(tmp_path: Path) -> None:
    """The imported config's step-0 temperature is LAMMPS's (both exactly T over the LAMMPS group;
    the draws differ)."""
    script, _, cfg = _import_script(tmp_path, TWO_TYPES_ONE_DRAW, "two")
    ref = _run_lammps_script(script, ["temp", "ke", "pe", "etotal"])
    ds = api.run(cfg)
    assert ref[0, 0] == 0 and ref[0, 1] == pytest.approx(0.5, rel=1e-12)
    assert float(ds["temp"].values.ravel()[0]) == pytest.approx(ref[0, 1], rel=1e-10)


READ_DATA_MIN = """# read_data, groups by type and region, a minimize, then a run
units           lj
boundary        p p f
atom_style      atomic
read_data       start.data
group           heavy type 2
group           low region lowz
region          lowz block INF INF INF INF INF 3.0 units box
group           low region lowz
pair_style      lj/cut 2.5
pair_coeff      * * 1.0 1.0
fix             1 all nve
fix             zw all wall/lj93 zlo EDGE 1.0 1.0 2.5 zhi EDGE 1.0 1.0 2.5 units box
fix_modify      zw energy yes
min_style       cg
min_modify      dmax 0.05
minimize        1.0e-8 1.0e-10 50 500
reset_timestep  0
""" + THERMO + """thermo          25
run             100
"""


@pytest.mark.lammps
@needs_lammps
def test_read_data_groups_minimize_match_lammps(tmp_path: Path) -> None:
    rng = np.random.default_rng(5)
    side = np.arange(4) * 1.6 + 0.9
    x = np.stack(np.meshgrid(side, side, side, indexing="ij"), -1).reshape(-1, 3) + rng.normal(0, 0.05, (64, 3))
    mass = np.where(np.arange(64) % 3 == 0, 2.0, 1.0)
    types = np.where(mass == 2.0, 2, 1)
    write_data_file(tmp_path / "start.data", (0, 0, 0), (6.4, 6.4, 6.4), x, mass, types=types,
                    v=rng.normal(0, 0.5, (64, 3)))
    text = READ_DATA_MIN.replace("group           low region lowz\nregion", "region")
    script, result, cfg = _import_script(tmp_path, text, "min")
    assert cfg.minimize.dmax == 0.05 and cfg.minimize.maxiter == 50
    # heavy/light x low/high: four groups of atom IDs in the data file
    assert sorted(g.group for g in cfg.atoms) == ["heavy_low", "heavy_only", "low_only", "type1"]
    heavy = next(g for g in cfg.atoms if g.group == "heavy_low").create
    assert heavy.file == "start.data" and heavy.ids.split()[0] == "1"
    ref = _run_lammps_script(script, ["temp", "ke", "pe", "etotal"])
    ds = api.run(cfg)
    assert ds["min_iterations"].item() == 50
    for j, key in enumerate(["temp", "ke", "pe", "etot"], start=1):
        np.testing.assert_allclose(ds[key].values.ravel(), ref[:, j], rtol=1e-9, atol=1e-12)


@pytest.mark.lammps
@needs_lammps
def test_a_run_after_minimize_without_reset_timestep_is_listed(tmp_path: Path) -> None:
    """After `minimize` LAMMPS's run starts at the minimizer's last step, wallbatch's at step 0; the
    import said nothing (thermo samples and `step` in a wall's variable then differ). The run line is
    now listed, saying to add `reset_timestep 0`; with it nothing is listed."""
    base = ("units lj\nboundary p p f\nregion box block 0 6 0 6 0 6 units box\ncreate_box 1 box\n"
            "create_atoms 1 single 3 3 1.5 units box\nmass 1 1.0\nfix 1 all nve\n"
            "fix w all wall/lj93 zlo EDGE 1.0 1.0 2.5 units box\nminimize 0.0 1.0e-12 20 200\n")
    from wallbatch.lammps.validate import load_lammps

    lmp = load_lammps().lammps(cmdargs=["-screen", "none", "-log", "none", "-nocite"])
    lmp.commands_string(base)
    assert lmp.extract_global("ntimestep") > 0  # where LAMMPS's next run starts
    lmp.close()
    got = [(i.line, i.reason) for i in import_lammps_text(base + "run 10\n", tmp_path).unsupported]
    assert got == [(10, "after minimize, LAMMPS's run starts at the step the minimizer stopped at, so its thermo "
                        "samples and 'step' in variables differ from wallbatch's run, which starts at step 0: add "
                        "'reset_timestep 0' after minimize (as export-lammps writes)")], got
    assert import_lammps_text(base + "reset_timestep 0\nrun 10\n", tmp_path).unsupported == []


def test_substitutions_and_var_override(tmp_path: Path) -> None:
    text = """variable a index 2.0
variable b equal 1/3
variable c internal 0.25
variable n string box
units lj
boundary f f f
region ${n} block 0 $(10*v_a) 0 10 0 10 units box
create_box 1 box
create_atoms 1 single ${b} $c 5 units box
mass 1 $(v_b:%.3f)
fix 1 all nve
fix w all wall/reflect xlo EDGE xhi $(lx - 0.5) units box
run 10
"""
    r = import_lammps_text(text, tmp_path)
    assert r.complete, r.text
    assert r.data["box"]["hi"] == [20.0, 10.0, 10.0]
    assert r.data["atoms"][0]["create"]["positions"] == [[0.333333333333333, 0.25, 5.0]]
    assert r.data["atoms"][0]["mass"] == 0.333
    assert r.data["walls"]["w"]["xhi"] == 19.5
    r2 = import_lammps_text(text, tmp_path, variables={"a": "3"})
    assert r2.data["box"]["hi"] == [30.0, 10.0, 10.0]
    assert float("%.20g" % (1 / 3)) == 1 / 3  # $() keeps every bit
    assert math.isclose(r2.data["walls"]["w"]["xhi"], 29.5)


@pytest.mark.lammps
@needs_lammps
@pytest.mark.parametrize("style", ["sphere", "ellipsoid"])
def test_data_file_masses_bitwise_as_lammps_read_data(style: str, tmp_path: Path) -> None:
    """Masses from density * volume (and density alone for point particles) in LAMMPS's order of
    operations: the same doubles as LAMMPS's rmass after read_data."""
    from wallbatch.lammps.validate import load_lammps

    rng = np.random.default_rng(2)
    n = 20
    x = rng.random((n, 3)) * 9 + 0.5
    m = rng.random(n) * 3 + 0.5
    kw = {"radius": np.r_[np.zeros(3), rng.random(n - 3) * 0.5 + 0.2]} if style == "sphere" else {
        "shape": np.r_[np.zeros((2, 3)), rng.random((n - 2, 3)) * 0.5 + 0.2], "quat": rng.normal(size=(n, 4))}
    path = write_data_file(tmp_path / "a.data", (0, 0, 0), (10, 10, 10), x, m, v=rng.normal(size=(n, 3)), **kw)
    lmp = load_lammps().lammps(cmdargs=["-screen", "none", "-log", "none", "-nocite"])
    try:
        for cmd in (f"atom_style {style}", "atom_modify map yes", f"read_data {path}"):
            lmp.command(cmd)
        rmass = np.ctypeslib.as_array(lmp.extract_atom("rmass"), shape=(n,)).copy()
        ids = np.ctypeslib.as_array(lmp.extract_atom("id"), shape=(n,)).copy()
    finally:
        lmp.close()
    df = read_data_file(path)
    assert np.array_equal(df.mass[ids - 1], rmass)
    np.testing.assert_allclose(df.mass, m, rtol=1e-15)  # the written density gives the mass back


def test_shipped_example_imports_and_sweeps(tmp_path: Path) -> None:
    """The docs' path: import examples/lammps/in.wall, add a sweep:, run every case."""
    out = tmp_path / "wall.yaml"
    res = CliRunner().invoke(app, ["import-lammps", str(ROOT / "examples" / "lammps" / "in.wall"), "-o", str(out),
                                   "--strict", "--var", "rho=0.4"])
    assert res.exit_code == 0, res.output
    out.write_text(out.read_text() + "sweep:\n  product:\n    epsilon: {path: [walls.walls.zlo.epsilon, "
                   "walls.walls.zhi.epsilon], values: [0.5, 2.0]}\n")
    plan = api.load(out, ["run.steps=20"])
    assert len(plan.cases) == 2 and plan.cases[0].config.lattice.scale == 0.4  # --var beats `variable index`
    ds = api.run(plan)
    assert (ds["status"] == "ok").all()
    e = ds["wall_energy"].values  # (epsilon, sample, fix): the stronger wall binds more
    assert np.all(e[1, -1] < e[0, -1]) and e[1, -1, 0] < 0


def test_end_of_import_issues_point_at_their_lines(tmp_path: Path) -> None:
    text = """units lj
boundary f f f
region box block 0 10 0 10 0 10 units box
create_box 2 box
create_atoms 1 single 2 2 2 units box
create_atoms 2 single 5 5 5 units box
mass * 1.0
pair_style lj/cut 2.5
pair_coeff 1 1 1.0 1.0
pair_coeff 2 2 0.5 1.0
group one type 1
fix 1 one nve
fix 2 one nve
fix w all wall/lj93 zlo v_nowhere 1.0 1.0 2.5 units box
"""
    r = import_lammps_text(text, tmp_path)
    got = {i.line: i.reason for i in r.unsupported}
    assert got[10] == ("several lj/cut coefficient sets (types 1 1: 1 1, types 2 2: 0.5 1): wallbatch has one "
                       "epsilon and sigma for all atom pairs (per-type coefficients are not supported yet); the "
                       "config uses epsilon 1 sigma 1 (types 1 1) for every pair")
    assert r.data["pair"]["epsilon"] == 1.0
    assert "no run command" in got[14]
    assert any(p.startswith("line 13: fix 2 one nve") for p in r.problems), r.problems  # integrated twice
    assert any("v_nowhere" in i.text and "not defined" in i.reason for i in r.unsupported)


NVT_FROZEN = """# an LJ fluid under fix nvt above a frozen lattice layer (a static obstacle)
units           lj
boundary        p p f
lattice         fcc 0.6
region          box block 0 4 0 4 0 5
create_box      2 box
region          low block INF INF INF INF INF 0.9
region          mid block INF INF INF INF 1.4 3.6
create_atoms    2 region low
create_atoms    1 region mid
mass            * 1.0
group           solid type 2
group           fluid type 1
velocity        fluid set 0.3 0.1 -0.2 units box
pair_style      lj/cut 2.5
pair_coeff      * * 1.0 1.0
fix             1 fluid nvt temp 1.5 1.5 0.1
fix             w fluid wall/lj93 zhi EDGE 1.0 1.0 2.5 units box
fix_modify      w energy yes
thermo_style    custom step temp ke pe etotal ecouple
thermo_modify   norm no format float %.17g
thermo          25
run             200
"""


def test_a_config_problem_points_at_its_line_in_the_written_config(tmp_path: Path) -> None:
    """`fix nve` on all and `fix nvt` on a group integrate some atoms twice: the problem names the
    config's line and column. It named those of the config without its comments (c.yaml:14:34 for
    a `fixes:` line that is line 29 of the file written)."""
    script = NVT_FROZEN.replace("fix             1 fluid nvt", "fix             0 all nve\nfix             1 fluid nvt")
    r = import_lammps_text(script, tmp_path, output=tmp_path / "c.yaml")
    lines = r.text.splitlines()
    row = next(i for i, line in enumerate(lines) if line.startswith("fixes:")) + 1
    col = lines[row - 1].index("'1': fix 1 fluid nvt") + 6
    where = f"{tmp_path / 'c.yaml'}:{row}:{col}"
    assert r.problems == [f"line 18: fix             1 fluid nvt temp 1.5 1.5 0.1  ->  {where}: "
                          "fixes.1.group: group 'fluid' is already integrated by fix '0': an atom integrated twice "
                          "moves twice per step (LAMMPS only warns); give each atom one integrator"], r.problems


def test_thermostats_and_frozen_groups_go_to_fixes(tmp_path: Path) -> None:
    r = import_lammps_text(NVT_FROZEN, tmp_path)
    assert r.complete, r.text
    assert r.data["fixes"] == {"1": "fix 1 fluid nvt temp 1.5 1.5 0.1"}
    assert [g["group"] for g in r.data["atoms"]] == ["solid", "fluid"]
    assert r.data["walls"]["w"]["group"] == "fluid"
    assert r.data["output"]["thermo"] == ["step", "temp", "ke", "pe", "etot", "ecouple"]
    bad = import_lammps_text(NVT_FROZEN.replace("nvt temp 1.5 1.5 0.1", "nvt temp 1.5 1.5 -0.1"), tmp_path)
    assert not bad.complete and bad.problems[0].startswith("line 17: fix             1 fluid nvt temp 1.5 1.5 -0.1")
    assert "fixes.1.damp" in bad.problems[0]


@pytest.mark.lammps
@needs_lammps
def test_nvt_with_a_frozen_layer_matches_lammps(tmp_path: Path) -> None:
    script, result, cfg = _import_script(tmp_path, NVT_FROZEN, "nvt")
    ref = _run_lammps_script(script, ["temp", "ke", "pe", "etotal", "ecouple"])
    ds = api.run(cfg)
    assert (ds["status"] == "ok").all(), ds["error"].values
    for j, key in enumerate(["temp", "ke", "pe", "etot", "ecouple"], start=1):
        np.testing.assert_allclose(ds[key].values.ravel(), ref[:, j], rtol=1e-9, atol=1e-12)
    assert abs(ref[-1, 5]) > 1e-3  # the thermostat did work


def test_include_and_continuation_lines(tmp_path: Path) -> None:
    (tmp_path / "walls.in").write_text("fix w all wall/harmonic zlo EDGE ${k} 1.0 2.0 &\n    zhi EDGE ${k} 1.0 2.0 units box\n")
    text = """variable k equal 20.0
units lj
boundary p p f
region box block 0 10 0 10 0 10 units box
create_box 1 box
create_atoms 1 single 5 5 5 units box
mass 1 1.0
fix 1 all nve
include walls.in
include missing.in
run 10
"""
    r = import_lammps_text(text, tmp_path)
    assert r.data["walls"]["w"]["zhi"] == {"coord": "EDGE", "epsilon": 20.0, "sigma": 1.0, "cutoff": 2.0}
    assert [(i.line, "missing.in" in i.reason) for i in r.unsupported] == [(10, True)]


def test_lines_of_an_include_file_are_named_with_that_file(tmp_path: Path) -> None:
    """Comments, notes and config problems of commands read from an include file named only the line, so
    `# 1: fix w ...` and `line 2: fix bad ...` pointed at lines of the main script."""
    (tmp_path / "walls.in").write_text("fix w all wall/harmonic zlo EDGE 20.0 1.0 2.0 units box\n"
                                       "fix bad all nvt temp 1.0 1.0 -0.1\nvelocity all create 1.0 4242\n")
    text = ("units lj\nboundary p p f\nregion box block 0 10 0 10 0 10 units box\ncreate_box 1 box\n"
            "create_atoms 1 single 5 5 5 units box\nmass 1 1.0\ninclude walls.in\nrun 10\n")
    r = import_lammps_text(text, tmp_path)
    assert "  # walls.in:1: fix w all wall/harmonic zlo EDGE 20.0 1.0 2.0 units box\n" in r.text, r.text
    assert len(r.problems) == 1 and r.problems[0].startswith(
        f"{tmp_path / 'walls.in'}:2: fix bad all nvt temp 1.0 1.0 -0.1  ->  <imported config>:"), r.problems
    assert r.problems[0].endswith(": fixes.bad.damp: Input should be greater than 0"), r.problems
    assert r.notes[0].startswith(f"{tmp_path / 'walls.in'}:3: velocity create: wallbatch draws"), r.notes


TWO_D = """# 2-D: an sq2 lattice between harmonic walls
dimension       2
units           lj
boundary        p f p
atom_style      atomic
lattice         sq2 0.7
region          box block 0 6 0 6 -0.5 0.5
create_box      1 box
region          inner block INF INF 1.1 4.9 INF INF
create_atoms    1 region inner
mass            1 1.0
velocity        all set 0.2 -0.4 0.0 units box
fix             1 all nve
fix             2d all enforce2d
fix             w all wall/harmonic ylo EDGE 5.0 1.0 1.5 yhi EDGE 5.0 1.0 1.5 units box
fix_modify      w energy yes
thermo_style    custom step temp ke pe etotal
thermo_modify   norm no format float %.17g
thermo          20
run             200
"""


@pytest.mark.lammps
@needs_lammps
def test_two_dimensional_script_matches_lammps(tmp_path: Path) -> None:
    script, result, cfg = _import_script(tmp_path, TWO_D, "2d")
    assert result.data["dimension"] == 2 and result.data["lattice"]["style"] == "sq2"
    ref = _run_lammps_script(script, ["temp", "ke", "pe", "etotal"])
    assert build_case(cfg).natoms == _count_atoms(tmp_path, TWO_D)
    ds = api.run(cfg)
    assert (ds["status"] == "ok").all(), ds["error"].values
    for j, key in enumerate(["temp", "ke", "pe", "etot"], start=1):
        np.testing.assert_allclose(ds[key].values.ravel(), ref[:, j], rtol=1e-9, atol=1e-12)


def test_cli_output_paths_of_import_export_and_validate(tmp_path: Path) -> None:
    """import-lammps -o overwrote an existing config silently (a hand-edited one lost) and gave
    "unexpected IsADirectoryError ... a wallbatch bug" for a folder; export-lammps -o naming a file
    was a bug report too; validate took a negative --rtol. Now: --force to overwrite, the script
    itself refused, missing folders made, and each refusal names its argument."""
    script = tmp_path / "in.script"
    script.write_text(HEX_CHANNEL)
    out = tmp_path / "c.yaml"
    runner = CliRunner()
    assert runner.invoke(app, ["import-lammps", str(script), "-o", str(out)]).exit_code == 0
    out.write_text("# edited by hand\n" + out.read_text())
    res = runner.invoke(app, ["import-lammps", str(script), "-o", str(out)])
    assert res.exit_code == 2 and f"{out} exists: add --force to overwrite it" in res.output
    assert out.read_text().startswith("# edited by hand")
    assert runner.invoke(app, ["import-lammps", str(script), "-o", str(out), "--force"]).exit_code == 0
    assert not out.read_text().startswith("# edited by hand")
    res = runner.invoke(app, ["import-lammps", str(script), "-o", str(tmp_path)])
    assert res.exit_code == 2 and f"-o {tmp_path} is a folder: give the config's file name" in res.output
    res = runner.invoke(app, ["import-lammps", str(script), "-o", str(script)])
    assert res.exit_code == 2 and "is the script itself" in res.output and script.read_text() == HEX_CHANNEL
    deep = tmp_path / "a" / "b" / "c.yaml"
    assert runner.invoke(app, ["import-lammps", str(script), "-o", str(deep)]).exit_code == 0 and deep.exists()
    res = runner.invoke(app, ["export-lammps", str(out), "-o", str(out)])
    assert res.exit_code == 2 and f"-o {out} is a file: give a folder for in.NAME and data.NAME" in res.output
    for bad in ("-1", "nan"):
        res = runner.invoke(app, ["validate", str(out), "--rtol", bad])
        assert res.exit_code == 2 and f"--rtol {float(bad):g}: give a relative tolerance >= 0" in res.output


TWO_TYPES = """# two atom types, one velocity create over all: the heavy type is walled, the light one not
units           lj
boundary        p p f
atom_style      atomic
lattice         fcc 0.8442
region          box block 0 3 0 3 0 4
create_box      2 box
region          low block INF INF INF INF 0.2 1.9
region          high block INF INF INF INF 2 INF
create_atoms    1 region low
create_atoms    2 region high
mass            1 1.0
mass            2 2.0
group           heavy type 2
velocity        all create 0.5 4928459
fix             1 all nve
fix             w heavy wall/lj93 zhi EDGE 1.0 1.0 2.5
fix_modify      w energy yes
""" + THERMO + """thermo          10
run             10
"""


@pytest.mark.lammps
@needs_lammps
@pytest.mark.parametrize("dimension", [3, 2])
def test_shared_velocity_draw_starts_at_lammps_temperature(dimension: int, tmp_path: Path) -> None:
    """The imported config of `velocity all create 0.5 SEED` over two atom groups starts at LAMMPS's
    thermo temp (step 0) within 1e-10, with zero total momentum: one draw over all atoms. With a draw
    per group (before `shared:`) it started at 0.5 (3N - 6) / (3N - 3) (0.4828 on a small scene)."""
    text = TWO_TYPES
    if dimension == 2:  # the same in the x-y plane: y fixed, the wall at yhi, enforce2d
        for old, new in (("units           lj\n", "dimension       2\nunits           lj\n"),
                         ("boundary        p p f", "boundary        p f p"), ("fcc 0.8442", "sq2 0.7"),
                         ("0 3 0 3 0 4", "0 4 0 4 -0.5 0.5"),
                         ("INF INF INF INF 0.2 1.9", "INF INF 0.2 1.9 INF INF"),
                         ("INF INF INF INF 2 INF", "INF INF 2 INF INF INF"),
                         ("heavy wall/lj93 zhi", "heavy wall/lj93 yhi"),
                         ("fix             1 all nve\n", "fix             1 all nve\nfix 2d all enforce2d\n")):
            text = text.replace(old, new)
    script, result, cfg = _import_script(tmp_path, text, "two")
    assert [g.velocity.shared for g in cfg.atoms] == ["all", "all"] and cfg.dimension == dimension
    case = build_case(cfg)
    n = case.natoms
    assert n == _count_atoms(tmp_path, text) and len(set(case.mass.tolist())) == 2
    assert np.abs((case.mass[:, None] * case.v).sum(axis=0)).max() < 1e-12
    ref = _run_lammps_script(script, ["temp", "ke", "pe", "etotal"])
    ds = api.run(cfg)
    assert (ds["status"] == "ok").all(), ds["error"].values
    t0 = float(ds["temp"].values.ravel()[0])
    assert ref[0, 0] == 0 and abs(t0 - ref[0, 1]) < 1e-10, (t0, ref[0, 1])
    # the draw per group (no label) is what LAMMPS does not do: it starts colder
    d = dimension
    apart = config_from_dict({**config_to_dict(cfg), "atoms": [
        {**config_to_dict(cfg)["atoms"][i], "velocity": {"temperature": 0.5}} for i in range(2)]})
    m, v = build_case(apart).mass, build_case(apart).v
    t_apart = float((m[:, None] * v * v).sum()) / (d * n - d)
    assert t_apart == pytest.approx(0.5 * (d * n - 2 * d) / (d * n - d), rel=1e-12)
    assert abs(t_apart - ref[0, 1]) > 1e-4
