"""Tests for the `wallbatch` command line: `run CONFIG -o OUT` (NetCDF of shared/spec/outputs.md)
and `check CONFIG`."""

from __future__ import annotations

import datetime as dt
import shutil
import subprocess

import numpy as np
import pytest
import xarray as xr
from typer.testing import CliRunner

import wallbatch
from wallbatch.cli import app

runner = CliRunner()

# Two atoms at rest: A at z = 1.0 inside the cut-off of a harmonic zlo wall at EDGE (z = 0),
# B at z = 9.2 inside the cut-off of a harmonic zhi wall at EDGE (z = 10). Each atom is out of
# reach of the other wall. Only `lo` adds its energy to pe.
EPS_LO, RC_LO, R_A = 2.0, 2.5, 1.0
EPS_HI, RC_HI, R_B = 3.0, 1.5, 0.8
SCENE = f"""\
name: two-springs
units: lj
box:
  lo: [0.0, 0.0, 0.0]
  hi: [10.0, 10.0, 10.0]
  boundary: [p, p, f]
atoms:
  - group: near_lo
    create:
      positions: [[5.0, 5.0, {R_A}]]
    mass: 1.0
  - group: near_hi
    create:
      positions: [[2.0, 3.0, {10.0 - R_B}]]
    mass: 2.0
walls:
  lo:
    style: harmonic
    units: box
    energy: true
    zlo: {{coord: EDGE, epsilon: {EPS_LO}, cutoff: {RC_LO}}}
  hi: "fix hi all wall/harmonic zhi EDGE {EPS_HI} 1.0 {RC_HI} units box"
run:
  steps: 10
  thermo: 4
"""

DATA_VARS = ("time", "dt", "temp", "ke", "pe", "etot", "wall_energy", "wall_force", "status", "error", "seconds")
NUMERIC_OUTPUTS = ("time", "dt", "temp", "ke", "pe", "etot", "wall_energy", "wall_force")


def write(tmp_path, text: str, name: str = "cfg.yaml"):
    path = tmp_path / name
    path.write_text(text)
    return path


def run_cli(*args: str):
    return runner.invoke(app, [str(a) for a in args])


def line_of(text: str, needle: str) -> int:
    return next(i + 1 for i, line in enumerate(text.splitlines()) if needle in line)


@pytest.fixture
def scene_run(tmp_path):
    """Run SCENE once; return (result, config path, output path, dataset)."""
    cfg = write(tmp_path, SCENE)
    out = tmp_path / "results" / "out.nc"
    result = run_cli("run", cfg, "-o", out)
    assert result.exit_code == 0, result.output
    with xr.open_dataset(out) as ds:
        ds.load()
    return result, cfg, out, ds


# ============================================================================================
# wallbatch run: layout


def test_run_exits_0_and_reports(scene_run):
    result, _, out, _ = scene_run
    assert out.exists()
    assert "1 of 1 case(s) ok" in result.stdout
    assert str(out) in result.stdout
    assert not out.with_name(out.name + ".tmp").exists()


def test_run_dims_and_coords(scene_run):
    ds = scene_run[3]
    assert dict(ds.sizes) == {"sample": 4, "fix": 2, "face": 2}
    assert ds["step"].dims == ("sample",)
    assert ds["step"].dtype == np.int64
    assert ds["step"].values.tolist() == [0, 4, 8, 10]  # step 0, every thermo steps, the last step
    assert ds["fix"].values.tolist() == ["lo", "hi"]
    assert ds["face"].values.tolist() == ["lo/zlo", "hi/zhi"]
    assert ds["face_fix"].dims == ("face",)
    assert ds["face_fix"].values.tolist() == ["lo", "hi"]
    assert ds["face_name"].values.tolist() == ["zlo", "zhi"]


def test_run_variables_and_their_dims(scene_run):
    ds = scene_run[3]
    for name in DATA_VARS:
        assert name in ds.data_vars, name
    for name in ("time", "dt", "temp", "ke", "pe", "etot"):
        assert ds[name].dims == ("sample",), name
    assert ds["wall_energy"].dims == ("sample", "fix")
    assert ds["wall_force"].dims == ("sample", "face")
    for name in ("status", "error", "seconds"):
        assert ds[name].dims == (), name  # no sweep: no sweep dimensions
    assert ds["status"].item() == "ok"
    assert ds["error"].item() == ""
    assert ds["seconds"].item() >= 0.0


def test_run_numeric_variables_have_units_and_long_name(scene_run):
    ds = scene_run[3]
    for name in NUMERIC_OUTPUTS + ("seconds", "step"):
        attrs = ds[name].attrs
        assert isinstance(attrs.get("long_name"), str) and attrs["long_name"], name
        assert isinstance(attrs.get("units"), str) and attrs["units"], name
    for name in NUMERIC_OUTPUTS + ("step",):
        assert ds[name].attrs["units"] == "1", name  # lj: every quantity is reduced
    assert ds["seconds"].attrs["units"] == "s"
    for name in ("status", "error", "fix", "face"):
        assert ds[name].attrs.get("long_name"), name


def test_run_every_variable_has_units_and_long_name(scene_run):
    ds = scene_run[3]
    missing = [(name, key) for name in ds.variables for key in ("units", "long_name")
               if key not in ds[name].attrs]
    assert missing == []


def test_run_global_attributes(scene_run):
    _, cfg, _, ds = scene_run
    assert ds.attrs["Conventions"] == "CF-1.10"
    assert isinstance(ds.attrs["title"], str) and "two-springs" in ds.attrs["title"]
    assert ds.attrs["units_style"] == "lj"
    assert ds.attrs["config"] == cfg.read_text() == SCENE
    assert ds.attrs["sweep"] == ""
    assert ds.attrs["wallbatch_version"] == wallbatch.__version__
    created = dt.datetime.fromisoformat(ds.attrs["created"])
    assert created.tzinfo is not None
    assert abs((dt.datetime.now(dt.timezone.utc) - created).total_seconds()) < 600


# ============================================================================================
# wallbatch run: numbers


def test_run_step0_harmonic_energy_and_force(scene_run):
    ds = scene_run[3]
    s0 = ds.isel(sample=0)
    e_lo = EPS_LO * (R_A - RC_LO) ** 2  # 2 * 1.5^2 = 4.5
    e_hi = EPS_HI * (R_B - RC_HI) ** 2  # 3 * 0.7^2 = 1.47
    assert s0["wall_energy"].sel(fix="lo").item() == pytest.approx(e_lo, rel=1e-12)
    assert s0["wall_energy"].sel(fix="hi").item() == pytest.approx(e_hi, rel=1e-12)
    # force of the atoms on the wall along +dim: a lo wall pushed outward (-z) is negative
    assert s0["wall_force"].sel(face="lo/zlo").item() == pytest.approx(-2 * EPS_LO * (RC_LO - R_A), rel=1e-12)
    assert s0["wall_force"].sel(face="hi/zhi").item() == pytest.approx(+2 * EPS_HI * (RC_HI - R_B), rel=1e-12)
    assert s0["wall_force"].sel(face="lo/zlo").item() == pytest.approx(-6.0, rel=1e-12)
    # at rest; pe holds only the wall with energy: true
    assert s0["ke"].item() == 0.0
    assert s0["temp"].item() == 0.0
    assert s0["pe"].item() == pytest.approx(e_lo, rel=1e-12)
    assert s0["etot"].item() == pytest.approx(e_lo, rel=1e-12)
    assert s0["time"].item() == 0.0


def test_run_later_samples(scene_run):
    ds = scene_run[3]
    dt_lj = 0.005  # LAMMPS default timestep of lj units
    assert ds["dt"].values.tolist() == [dt_lj] * 4
    np.testing.assert_allclose(ds["time"].values, np.array([0, 4, 8, 10]) * dt_lj, rtol=1e-12, atol=0)
    # pushed away from the walls: the springs relax, kinetic energy appears
    assert np.all(np.diff(ds["wall_energy"].sel(fix="lo").values) < 0)
    assert np.all(np.diff(ds["wall_energy"].sel(fix="hi").values) < 0)
    assert np.all(ds["ke"].values[1:] > 0)
    np.testing.assert_allclose(ds["etot"].values, ds["ke"].values + ds["pe"].values, rtol=1e-12)
    # temp: translational, dim*N - dim = 3 degrees of freedom for 2 atoms, k_B = 1
    np.testing.assert_allclose(ds["temp"].values, 2 * ds["ke"].values / 3, rtol=1e-12)


def test_run_single_atom_first_step_matches_velocity_verlet(tmp_path):
    """One atom at rest, one harmonic lo wall, one step: x1 = x0 + dt^2/2 F/m, E(x1) exact."""
    eps, rc, r0, mass, dt_ = 5.0, 2.0, 0.5, 2.0, 0.01
    text = f"""\
units: lj
timestep: {dt_}
box: {{lo: [0, 0, 0], hi: [4, 4, 4], boundary: [p, p, f]}}
atoms:
  - group: a
    create: {{positions: [[2.0, 2.0, {r0}]]}}
    mass: {mass}
walls:
  w: {{style: harmonic, units: box, energy: true, zlo: [EDGE, {eps}, 1.0, {rc}], zhi: [EDGE, {eps}, 1.0, 1.0]}}
run: {{steps: 1}}
"""
    out = tmp_path / "one.nc"
    result = run_cli("run", write(tmp_path, text), "-o", out)
    assert result.exit_code == 0, result.output
    with xr.open_dataset(out) as ds:
        f0 = 2 * eps * (rc - r0)
        r1 = r0 + 0.5 * dt_**2 * f0 / mass
        assert ds["step"].values.tolist() == [0, 1]
        assert ds["wall_energy"].values[:, 0].tolist() == pytest.approx([eps * (r0 - rc) ** 2, eps * (r1 - rc) ** 2],
                                                                         rel=1e-12)
        assert ds["wall_force"].sel(face="w/zlo").values.tolist() == pytest.approx(
            [-2 * eps * (rc - r0), -2 * eps * (rc - r1)], rel=1e-12)
        assert ds["wall_force"].sel(face="w/zhi").values.tolist() == [0.0, 0.0]  # out of reach
        # ke after one full velocity-Verlet step: v1 = dt/2 (F0 + F1)/m
        f1 = 2 * eps * (rc - r1)
        v1 = 0.5 * dt_ * (f0 + f1) / mass
        assert ds["ke"].values[1] == pytest.approx(0.5 * mass * v1**2, rel=1e-12)


def test_run_real_units_attributes(tmp_path):
    text = """\
units: real
box:
  lo: [0.0, 0.0, 0.0]
  hi: [20.0, 20.0, 20.0]
  boundary: [p, p, f]
atoms:
  - group: argon
    create:
      positions: [[10.0, 10.0, 2.0]]
    mass: 39.948
walls:
  floor:
    style: harmonic
    units: box
    zlo: [EDGE, 1.5, 1.0, 3.0]
run:
  steps: 5
"""
    out = tmp_path / "real.nc"
    result = run_cli("run", write(tmp_path, text), "-o", out)
    assert result.exit_code == 0, result.output
    with xr.open_dataset(out) as ds:
        assert ds.attrs["units_style"] == "real"
        expected = {
            "time": "fs", "dt": "fs", "temp": "K", "ke": "kcal/mol", "pe": "kcal/mol", "etot": "kcal/mol",
            "wall_energy": "kcal/mol", "wall_force": "kcal/mol/Angstrom",
        }
        assert {k: ds[k].attrs["units"] for k in expected} == expected
        assert ds["dt"].values[0] == 1.0  # LAMMPS default for real: 1 fs
        assert ds["step"].values.tolist() == [0, 5]
        assert ds["wall_energy"].values[0, 0] == pytest.approx(1.5 * (2.0 - 3.0) ** 2, rel=1e-12)
        assert ds["wall_force"].values[0, 0] == pytest.approx(-2 * 1.5 * (3.0 - 2.0), rel=1e-12)


def test_run_default_output_path_is_config_name_in_current_directory(tmp_path, monkeypatch):
    cfg = write(tmp_path, SCENE, "scene.yaml")
    here = tmp_path / "work"
    here.mkdir()
    monkeypatch.chdir(here)
    result = run_cli("run", cfg)
    assert result.exit_code == 0, result.output
    assert (here / "scene.nc").exists() and not (tmp_path / "scene.nc").exists()
    assert "-> scene.nc" in result.output


# ============================================================================================
# wallbatch run: a bad config, a failing case


def test_run_bad_config_exit_2_names_file_line_and_path(tmp_path):
    text = SCENE.replace("energy: true", "energy: true\n    sigmaa: 1.0")
    cfg = write(tmp_path, text)
    out = tmp_path / "out.nc"
    result = run_cli("run", cfg, "-o", out)
    assert result.exit_code == 2
    line = line_of(text, "sigmaa")
    assert f"{cfg}:{line}:" in result.stderr
    assert "walls.lo.sigmaa" in result.stderr
    assert "Traceback" not in result.output
    assert not out.exists()
    assert not out.with_name(out.name + ".tmp").exists()


def test_run_several_config_errors_all_printed(tmp_path):
    text = SCENE.replace("epsilon: 2.0", "epsilon: abc").replace("steps: 10", "steps: -1")
    cfg = write(tmp_path, text)
    out = tmp_path / "out.nc"
    result = run_cli("run", cfg, "-o", out)
    assert result.exit_code == 2
    assert f"{cfg}:{line_of(text, 'epsilon: abc')}:" in result.stderr
    assert "walls.lo.zlo.epsilon" in result.stderr
    assert f"{cfg}:{line_of(text, 'steps: -1')}:" in result.stderr
    assert "run.steps" in result.stderr
    assert not out.exists()


def test_run_yaml_syntax_error_exit_2(tmp_path):
    text = SCENE.replace("  thermo: 4\n", "   thermo: 4\n")
    cfg = write(tmp_path, text)
    out = tmp_path / "out.nc"
    result = run_cli("run", cfg, "-o", out)
    assert result.exit_code == 2
    assert f"{cfg}:{line_of(text, 'thermo: 4')}:" in result.stderr
    assert "YAML" in result.stderr
    assert not out.exists()


def test_run_scene_error_exit_2_without_traceback(tmp_path):
    text = SCENE + "regions:\n  ball: {style: sphere, center: [5, 5, 5], radius: 2.0, units: box, side: up}\n"
    cfg = write(tmp_path, text)
    out = tmp_path / "out.nc"
    result = run_cli("run", cfg, "-o", out)
    assert result.exit_code == 2
    assert f"{cfg}:{line_of(text, 'ball:')}:" in result.stderr
    assert "regions.ball.side" in result.stderr
    assert "Traceback" not in result.output
    assert not out.exists()


def test_run_missing_config_file_exit_2(tmp_path):
    out = tmp_path / "out.nc"
    result = run_cli("run", tmp_path / "nope.yaml", "-o", out)
    assert result.exit_code == 2
    assert "nope.yaml" in result.stderr
    assert not out.exists()


BEHIND = SCENE.replace("zlo: {coord: EDGE,", "zlo: {coord: 1.5,")  # atom A (z = 1.0) is behind it


def test_run_failing_case_exit_1_and_file_written(tmp_path):
    cfg = write(tmp_path, BEHIND)
    out = tmp_path / "out.nc"
    result = run_cli("run", cfg, "-o", out)
    assert isinstance(result.exception, SystemExit), repr(result.exception)
    assert result.exit_code == 1
    assert "0 of 1 case(s) ok" in result.stdout
    assert "walls.lo" in result.stderr and "behind the wall" in result.stderr
    assert out.exists()
    with xr.open_dataset(out) as ds:
        assert ds["status"].item() == "failed"
        err = ds["error"].item()
        assert "walls.lo" in err and "zlo" in err and "atom ID 1" in err and "step 0" in err
        assert "behind the wall" in err
        for name in NUMERIC_OUTPUTS:
            assert np.all(np.isnan(ds[name].values)), name
        # the layout is kept
        assert ds["step"].values.tolist() == [0, 4, 8, 10]
        assert ds["face"].values.tolist() == ["lo/zlo", "hi/zhi"]
        assert ds.attrs["config"] == BEHIND


def test_run_case_that_fails_later_keeps_nan_outputs(tmp_path):
    # an atom flying into a hi wall fast enough to cross it within one step
    text = """\
units: lj
box: {lo: [0, 0, 0], hi: [10, 10, 10], boundary: [p, p, f]}
atoms:
  - group: bullet
    create: {positions: [[5.0, 5.0, 9.0]]}
    velocity: {values: [0.0, 0.0, 500.0]}
    mass: 1.0
walls:
  top: {style: lj93, units: box, zhi: [EDGE, 1.0, 1.0, 2.5]}
run: {steps: 20, thermo: 5}
"""
    out = tmp_path / "out.nc"
    result = run_cli("run", write(tmp_path, text), "-o", out)
    assert isinstance(result.exception, SystemExit), repr(result.exception)
    assert result.exit_code == 1
    with xr.open_dataset(out) as ds:
        assert ds["status"].item() == "failed"
        err = ds["error"].item()
        assert "walls.top" in err and "zhi" in err and "step 1" in err and "behind the wall" in err
        assert np.all(np.isnan(ds["wall_energy"].values))
        assert np.all(np.isnan(ds["time"].values))


def test_run_case_that_fails_after_several_samples(tmp_path):
    # no wall on zhi: the atom drifts out through the fixed z boundary after ~50 steps (lost atom)
    text = """\
units: lj
box: {lo: [0, 0, 0], hi: [10, 10, 10], boundary: [p, p, f]}
atoms:
  - group: drifter
    create: {positions: [[5.0, 5.0, 5.0]]}
    velocity: {values: [0.0, 0.0, 20.0]}
    mass: 1.0
walls:
  floor: {style: harmonic, units: box, zlo: [EDGE, 1.0, 1.0, 1.0]}
run: {steps: 100, thermo: 10}
"""
    out = tmp_path / "out.nc"
    result = run_cli("run", write(tmp_path, text), "-o", out)
    assert isinstance(result.exception, SystemExit), repr(result.exception)  # not a traceback
    assert result.exit_code == 1
    with xr.open_dataset(out) as ds:
        assert ds["step"].values.tolist() == list(range(0, 101, 10))
        assert ds["status"].item() == "failed"
        assert "left the box" in ds["error"].item()
        for name in NUMERIC_OUTPUTS:
            assert np.all(np.isnan(ds[name].values)), name


# ============================================================================================
# wallbatch check


def test_check_prints_kernels_and_atoms(tmp_path):
    text = SCENE.replace(
        "run:\n", '  mirror: "fix mirror all wall/reflect zlo EDGE units box"\nrun:\n'
    )
    cfg = write(tmp_path, text)
    result = run_cli("check", cfg)
    assert result.exit_code == 0, result.output
    out = result.stdout
    assert f"{cfg}: valid" in out
    assert "atoms: 2" in out
    assert "units: lj" in out
    kernels = next(line for line in out.splitlines() if "kernels:" in line)
    assert kernels.split("kernels:")[1].strip() == "nve, wall/reflect mirror, wall/harmonic lo, wall/harmonic hi"
    assert "steps: 10" in out
    assert "samples: 4" in out
    assert not list(tmp_path.glob("*.nc"))  # check runs nothing
    thermal = text.replace('"fix mirror all wall/reflect zlo EDGE units box"',
                           '"fix mirror all wall/reflect/stochastic diffusive 3 zlo EDGE 1.0 0 0 0 units box"')
    result = run_cli("check", write(tmp_path, thermal, "thermal.yaml"))
    kernels = next(line for line in result.stdout.splitlines() if "kernels:" in line)
    assert kernels.split("kernels:")[1].strip() == ("nve, wall/reflect/stochastic mirror, wall/harmonic lo, "
                                                    "wall/harmonic hi")


def test_check_bad_config_exit_2(tmp_path):
    text = SCENE.replace("fix hi all", "fix hi nobody")
    cfg = write(tmp_path, text)
    result = run_cli("check", cfg)
    assert result.exit_code == 2
    assert f"{cfg}:{line_of(text, 'fix hi nobody')}:" in result.stderr
    assert "walls.hi" in result.stderr and "unknown group 'nobody'" in result.stderr


# ============================================================================================
# end to end through the installed console script


@pytest.mark.skipif(shutil.which("wallbatch") is None, reason="console script not installed")
@pytest.mark.slow  # starts the installed `wallbatch` in fresh processes: 4-9 s
def test_console_script_end_to_end(tmp_path):
    cfg = write(tmp_path, SCENE)
    out = tmp_path / "e2e.nc"
    proc = subprocess.run(["wallbatch", "run", str(cfg), "-o", str(out)], capture_output=True, text=True,
                          timeout=300)
    assert proc.returncode == 0, proc.stderr
    assert "1 of 1 case(s) ok" in proc.stdout
    with xr.open_dataset(out) as ds:
        assert ds.attrs["Conventions"] == "CF-1.10"
        assert ds["wall_energy"].sel(fix="lo").values[0] == pytest.approx(EPS_LO * (R_A - RC_LO) ** 2)

    bad = write(tmp_path, SCENE.replace("steps: 10", "steps: ten"), "bad.yaml")
    proc = subprocess.run(["wallbatch", "run", str(bad), "-o", str(tmp_path / "bad.nc")], capture_output=True,
                          text=True, timeout=300)
    assert proc.returncode == 2
    assert f"{bad}:{line_of(SCENE, 'steps: 10')}:" in proc.stderr and "run.steps" in proc.stderr
    assert "Traceback" not in proc.stderr
    assert not (tmp_path / "bad.nc").exists()
