"""Thermostats, integrator groups and 2-D against LAMMPS 22Jul2025 (issue 17).

Both codes start from bit-identical positions, velocities and masses (explicit in the config,
`create_atoms` in LAMMPS). The scenes are ideal gases between walls (no pair forces), so the
trajectories are not chaotic and every thermo sample of ke, pe, etot, ecouple, econserve and
the wall energy must agree to 1e-9 relative. The Langevin parity scene runs at T = 0, where the
random force vanishes and only the drag, `zero yes` and the `tally yes` bookkeeping act.
"""

from __future__ import annotations

import os
import tempfile

import numpy as np
import pytest
from lammps_oracle import _load_lammps, requires_lammps

from wallbatch.batch.runner import run_config
from wallbatch.config.models import config_from_dict
from wallbatch.lammps.log import last_thermo

pytestmark = [requires_lammps, pytest.mark.lammps]

RTOL = 1e-9


def run_lammps_script(x, v, mass, head: list[str], fixes: list[str], steps: int, every: int,
                      columns: list[str], groups: dict[str, np.ndarray] | None = None) -> dict[str, np.ndarray]:
    """Run LAMMPS: `head` up to create_box, one atom type of `mass`, atoms created bit-exactly,
    `fixes` in order, `run steps`; return each thermo column at every sample."""
    lammps = _load_lammps()
    n = len(x)
    with tempfile.TemporaryDirectory(prefix="wb_thermo_") as tmp:
        log = os.path.join(tmp, "log.lammps")
        lmp = lammps.lammps(cmdargs=["-log", log, "-screen", "none", "-nocite"])
        try:
            for c in head:
                lmp.command(c)
            lmp.command(f"mass 1 {float(mass)!r}")
            lmp.create_atoms(n, list(range(1, n + 1)), [1] * n, np.ravel(x).tolist(), np.ravel(v).tolist())
            assert lmp.get_natoms() == n
            for name, idx in (groups or {}).items():
                lmp.command(f"group {name} id " + " ".join(str(i + 1) for i in np.nonzero(idx)[0]))
            lmp.command("neigh_modify every 1 delay 0 check no")
            for c in fixes:
                lmp.command(c)
            lmp.command("thermo_style custom step " + " ".join(columns))
            lmp.command('thermo_modify norm no format float "%.17g"')
            lmp.command(f"thermo {every}")
            lmp.command(f"run {steps}")
        finally:
            lmp.close()
        with open(log, encoding="utf-8") as fh:
            rows = last_thermo(fh.read(), len(columns) + 1)
    return {c: rows[:, j + 1] for j, c in enumerate(columns)}


def assert_close(name: str, ours: np.ndarray, ref: np.ndarray, rtol: float = RTOL) -> None:
    ours, ref = np.asarray(ours, float), np.asarray(ref, float)
    assert ours.shape == ref.shape, name
    floor = 1e-12 * max(1.0, float(np.max(np.abs(ref))))
    err = np.abs(ours - ref) / np.maximum(np.abs(ref), floor)
    assert np.all(err <= rtol), f"{name}: max relative error {err.max():.3e} at sample {int(np.argmax(err))}"


def slit_gas(n=200, L=10.0, H=12.0, T=1.5, seed=7):
    """n point atoms of mass 1 in a slit: periodic x, y; z in [1, H-1]; Gaussian velocities."""
    rng = np.random.default_rng(seed)
    x = np.column_stack([rng.uniform(0, L, n), rng.uniform(0, L, n), rng.uniform(1.5, H - 1.5, n)])
    v = rng.normal(0.0, np.sqrt(T), (n, 3))
    v -= v.mean(axis=0)
    return x, v


SLIT_HEAD = ["units lj", "dimension 3", "atom_style atomic", "atom_modify map array", "boundary p p f",
             "region box block 0 10 0 10 0 12 units box", "create_box 1 box"]
WALL_LINE = "fix zw all wall/lj93 zlo EDGE 1.0 1.0 2.5 zhi EDGE 1.5 1.0 2.5 units box"


def slit_config(x, v, fixes, steps=1000, every=100, groups=None, outputs=None) -> dict:
    atoms = []
    if groups is None:
        groups = {"gas": np.ones(len(x), bool)}
    for name, sel in groups.items():
        atoms.append({"group": name, "mass": 1.0, "create": {"positions": x[sel].tolist()},
                      "velocity": {"values": v[sel].tolist()}})
    return {
        "units": "lj", "box": {"lo": [0, 0, 0], "hi": [10, 10, 12], "boundary": ["p", "p", "f"]},
        "atoms": atoms, "timestep": 0.005,
        "walls": {"zw": {"fix": WALL_LINE, "energy": True}},
        "fixes": fixes,
        "run": {"steps": steps, "thermo": every},
        "output": {"thermo": outputs or ["step", "temp", "ke", "pe", "etot", "ecouple", "econserve"]},
    }


COLUMNS = ["temp", "ke", "pe", "etotal", "ecouple", "econserve", "f_zw"]


def compare(ds, ref, keys=("temp", "ke", "pe", "etot", "ecouple", "econserve")):
    for k in keys:
        lk = "etotal" if k == "etot" else k
        assert_close(k, ds[k].values, ref[lk])
    assert_close("wall_energy", ds.wall_energy.sel(fix="zw").values, ref["f_zw"])


@pytest.mark.parametrize("line", [
    "fix nh all nvt temp 1.0 1.0 0.1",
    "fix nh all nvt temp 2.0 0.8 0.2 tchain 5",
    "fix nh all nvt temp 1.5 1.5 0.3 tchain 2 tloop 3 drag 0.5",
])
def test_nvt_slit_matches_lammps(line):
    x, v = slit_gas()
    ds = run_config(config_from_dict(slit_config(x, v, {"nh": line})))
    ref = run_lammps_script(x, v, 1.0, SLIT_HEAD, ["timestep 0.005", line, WALL_LINE, "fix_modify zw energy yes"],
                            1000, 100, COLUMNS)
    compare(ds, ref)
    assert abs(ref["ecouple"][-1]) > 1.0  # the thermostat did work


@pytest.mark.parametrize("fixes,lines", [
    ({"nve": {"style": "nve", "group": "all"},
      "ber": {"style": "temp/berendsen", "group": "all", "temp": [1.0, 2.0], "damp": 0.5}},
     ["fix nve all nve", "fix ber all temp/berendsen 1.0 2.0 0.5"]),
    ({"nve": "fix nve all nve", "res": "fix res all temp/rescale 7 1.0 1.2 0.05 0.5"},
     ["fix nve all nve", "fix res all temp/rescale 7 1.0 1.2 0.05 0.5"]),
])
def test_rescaling_thermostats_match_lammps(fixes, lines):
    x, v = slit_gas()
    ds = run_config(config_from_dict(slit_config(x, v, fixes)))
    ref = run_lammps_script(x, v, 1.0, SLIT_HEAD, ["timestep 0.005", WALL_LINE, "fix_modify zw energy yes"] + lines,
                            1000, 100, COLUMNS)
    compare(ds, ref)
    assert abs(ref["ecouple"][-1]) > 1.0


@pytest.mark.parametrize("numba", ["0", "1"])
def test_nvt_and_berendsen_on_subgroups_with_frozen_atoms_match_lammps(monkeypatch, numba):
    """nvt on one group, nve + berendsen on another, a third group integrated by nobody (frozen);
    each thermostat uses its own group's temperature (dof 3 n - 3). On the NumPy path and on the
    compiled one (the kernel with frozen atoms, `_K_FROZEN`)."""
    monkeypatch.setenv("WALLBATCH_NUMBA", numba)
    x, v = slit_gas(n=90)
    sel = np.arange(90) % 3
    groups = {"hot": sel == 0, "cold": sel == 1, "still": sel == 2}
    fixes = {"nh": "fix nh hot nvt temp 2.0 2.0 0.2", "nve": "fix nve cold nve",
             "ber": "fix ber cold temp/berendsen 0.5 0.5 0.3"}
    ds = run_config(config_from_dict(slit_config(x, v, fixes, steps=300, every=50, groups=groups)))
    order = np.concatenate([np.nonzero(groups[g])[0] for g in groups])  # wallbatch atom order
    ref = run_lammps_script(x[order], v[order], 1.0, SLIT_HEAD,
                            ["timestep 0.005", WALL_LINE, "fix_modify zw energy yes"] +
                            [fixes["nh"], fixes["nve"], fixes["ber"]], 300, 50, COLUMNS,
                            groups={g: np.repeat([k == j for j in range(3)], 30) for k, g in enumerate(groups)})
    compare(ds, ref)


def test_langevin_zero_temperature_drag_and_tally_match_lammps():
    """At T = 0 the random force is zero: drag, zero yes and the tally's ecouple are deterministic."""
    x, v = slit_gas(n=120)
    line = "fix bath all langevin 0.0 0.0 0.7 4321 zero yes tally yes"
    ds = run_config(config_from_dict(slit_config(x, v, {"nve": "fix nve all nve", "bath": line}, steps=400,
                                                 every=50)))
    ref = run_lammps_script(x, v, 1.0, SLIT_HEAD, ["timestep 0.005", "fix nve all nve", line, WALL_LINE,
                                                    "fix_modify zw energy yes"], 400, 50, COLUMNS)
    compare(ds, ref)
    assert ref["ecouple"][-1] > 10.0


# ----------------------------------------------------------------------------- 2-D


def test_2d_sq2_lattice_harmonic_walls_nvt_match_lammps():
    """dimension 2, lattice sq2 (lj density 0.7), harmonic walls on x and y, fix nvt: positions
    from wallbatch's lattice equal LAMMPS create_atoms; thermo (2 dof per atom) agrees."""
    from wallbatch.scene.build import build_case

    cfg = {
        "units": "lj", "dimension": 2, "lattice": {"style": "sq2", "scale": 0.7},
        "box": {"lo": [0, 0, -0.5], "hi": [12, 10, 0.5], "boundary": ["f", "f", "p"]},
        "regions": {"inner": {"style": "block", "lo": [1.5, 1.5, -0.5], "hi": [10.5, 8.5, 0.5], "units": "box"}},
        "atoms": [{"group": "gas", "mass": 1.0, "create": {"lattice": {"region": "inner"}},
                   "velocity": {"temperature": 1.2}}],
        "timestep": 0.004,
        "walls": {"w": {"fix": "fix w all wall/harmonic xlo EDGE 5.0 1.0 1.2 xhi EDGE 5.0 1.0 1.2 "
                               "ylo EDGE 5.0 1.0 1.2 yhi EDGE 5.0 1.0 1.2 units box", "energy": True}},
        "fixes": {"nh": "fix nh all nvt temp 1.0 1.0 0.2", "e2": "fix e2 all enforce2d"},
        "run": {"steps": 500, "thermo": 50},
        "output": {"thermo": ["step", "temp", "ke", "pe", "etot", "ecouple", "econserve"]},
    }
    conf = config_from_dict(cfg)
    case = build_case(conf)
    assert np.all(case.v[:, 2] == 0.0) and np.all(case.x[:, 2] == 0.0)
    ds = run_config(conf)
    head = ["units lj", "dimension 2", "atom_style atomic", "atom_modify map array", "boundary f f p",
            "lattice sq2 0.7", "region box block 0 12 0 10 -0.5 0.5 units box", "create_box 1 box"]
    # the lattice itself: LAMMPS create_atoms in the same region gives the same points
    lammps = _load_lammps()
    lmp = lammps.lammps(cmdargs=["-log", "none", "-screen", "none", "-nocite"])
    for c in head + ["mass 1 1.0", "region inner block 1.5 10.5 1.5 8.5 -0.5 0.5 units box",
                     "create_atoms 1 region inner"]:
        lmp.command(c)
    pts = np.ctypeslib.as_array(lmp.gather_atoms("x", 1, 3)).reshape(-1, 3).copy()
    lmp.close()
    key = lambda p: np.lexsort(np.round(p, 9).T[::-1])
    np.testing.assert_allclose(pts[key(pts)], case.x[key(case.x)], atol=1e-12)
    ref = run_lammps_script(case.x, case.v, 1.0, head,
                            ["timestep 0.004", cfg["walls"]["w"]["fix"], "fix_modify w energy yes",
                             "fix nh all nvt temp 1.0 1.0 0.2", "fix e2 all enforce2d"],
                            500, 50, ["temp", "ke", "pe", "etotal", "ecouple", "econserve", "f_w"])
    for k in ("temp", "ke", "pe", "etot", "ecouple", "econserve"):
        assert_close(k, ds[k].values, ref["etotal" if k == "etot" else k])
    assert_close("wall_energy", ds.wall_energy.sel(fix="w").values, ref["f_w"])
    np.testing.assert_allclose(ds.temp.values[0], 1.2, rtol=1e-12)  # created at T over 2N - 2 dof


def test_2d_lj_fluid_with_pair_forces_matches_lammps():
    """dimension 2 with pair lj/cut: the thin periodic z (length 1 < 2 rc) does not limit the cut-off,
    as in LAMMPS; an sq2 LJ fluid between harmonic walls agrees with LAMMPS at every sample."""
    cfg = {
        "units": "lj", "dimension": 2, "lattice": {"style": "sq2", "scale": 0.7},
        "box": {"lo": [0, 0, -0.5], "hi": [12, 10, 0.5], "boundary": ["f", "p", "p"]},
        "regions": {"inner": {"style": "block", "lo": [1.5, 0, -0.5], "hi": [10.5, 10, 0.5], "units": "box"}},
        "atoms": [{"group": "gas", "mass": 1.0, "create": {"lattice": {"region": "inner"}},
                   "velocity": {"temperature": 1.0}}],
        "pair": {"style": "lj/cut", "epsilon": 1.0, "sigma": 1.0, "cutoff": 2.5},
        "timestep": 0.004,
        "walls": {"w": {"fix": "fix w all wall/harmonic xlo EDGE 5.0 1.0 1.2 xhi EDGE 5.0 1.0 1.2 units box",
                        "energy": True}},
        "fixes": {"nv": "fix nv all nve", "e2": "fix e2 all enforce2d"},
        "run": {"steps": 200, "thermo": 50},
        "output": {"thermo": ["step", "temp", "ke", "pe", "etot"]},
    }
    conf = config_from_dict(cfg)
    from wallbatch.scene.build import build_case

    case = build_case(conf)
    ds = run_config(conf)
    head = ["units lj", "dimension 2", "atom_style atomic", "atom_modify map array", "boundary f p p",
            "lattice sq2 0.7", "region box block 0 12 0 10 -0.5 0.5 units box", "create_box 1 box",
            "pair_style lj/cut 2.5", "pair_coeff 1 1 1.0 1.0 2.5"]
    ref = run_lammps_script(case.x, case.v, 1.0, head,
                            ["timestep 0.004", cfg["walls"]["w"]["fix"], "fix_modify w energy yes",
                             "fix nv all nve", "fix e2 all enforce2d"],
                            200, 50, ["temp", "ke", "pe", "etotal"])
    for k in ("temp", "ke", "pe", "etot"):
        assert_close(k, ds[k].values, ref["etotal" if k == "etot" else k])


# ----------------------------------------------------------------------------- export / validate


def test_example_exports_its_fix_lines_and_validates_against_lammps():
    """sweeps/lj-adsorption-epsilon.yaml over configs/lj-adsorption-nvt.yaml (LJ fluid, lj93
    substrate, fix nvt written as a LAMMPS line): one batch; the export carries the fix line and
    `validate` agrees with LAMMPS over 100 steps."""
    from pathlib import Path

    import wallbatch
    from wallbatch.lammps.export import export_case
    from wallbatch.lammps.validate import validate_case
    from wallbatch.scene.build import build_case

    root = Path(__file__).resolve().parents[2]
    plan = wallbatch.load(root / "sweeps/lj-adsorption-epsilon.yaml", sets=["run.steps=100", "run.thermo=20"])
    assert len(plan.cases) == 4
    assert len(wallbatch.check(plan).batches) == 1
    sc = plan.cases[3]
    exp = export_case(sc.config, build_case(sc.config, sc.seed_key))
    assert "fix             nh fluid nvt temp 1.0 1.0 0.5 tchain 3 tloop 1 drag 0.0" in exp.script
    report = validate_case(sc)
    assert not report.errors, report.errors
    rows = {r.output: r for r in report.rows}
    for key in ("temp", "pe", "ecouple", "econserve"):
        assert rows[key].status == "ok", (key, rows[key])


def test_2d_export_writes_dimension_and_enforce2d():
    from wallbatch.lammps.export import export_case
    from wallbatch.scene.build import build_case

    cfg = config_from_dict({
        "units": "lj", "dimension": 2, "box": {"lo": [0, 0, -0.5], "hi": [10, 10, 0.5], "boundary": ["f", "p", "p"]},
        "atoms": [{"group": "gas", "mass": 1.0, "create": {"random": {"count": 20}}, "velocity": {"temperature": 1}}],
        "walls": {"w": "fix w all wall/harmonic xlo EDGE 5.0 1.0 1.2 xhi EDGE 5.0 1.0 1.2 units box"},
        "fixes": {"bath": "fix bath all langevin 1.0 1.0 0.5 77 zero yes"},
        "run": {"steps": 10}})
    script = export_case(cfg, build_case(cfg)).script
    assert "dimension       2" in script
    assert "fix             bath all langevin 1.0 1.0 0.5 77 zero yes tally no" in script
    assert script.index("wall/harmonic") < script.index("enforce2d")  # after every force fix
    assert "fix             wb_nve" not in script  # fixes: replaces the default integrator


@pytest.mark.parametrize("units,T,lines", [
    ("real", 300.0, ["fix nh all nvt temp 300.0 250.0 100.0"]),
    ("metal", 300.0, ["fix nve all nve", "fix ber all temp/berendsen 300.0 300.0 0.5"]),
    ("real", 300.0, ["fix nve all nve", "fix bath all langevin 0.0 0.0 200.0 9 zero yes tally yes"]),
])
def test_thermostats_in_real_and_metal_units_match_lammps(units, T, lines):
    """Argon-like gas (m = 39.948 g/mol) between lj93 walls: boltz, mvv2e and ftm2v enter the
    chain masses, the Berendsen energy and the Langevin drag as in LAMMPS."""
    from wallbatch.units import UNIT_SYSTEMS

    u = UNIT_SYSTEMS[units]
    rng = np.random.default_rng(5)
    n, m = 150, 39.948
    x = np.column_stack([rng.uniform(0, 30, n), rng.uniform(0, 30, n), rng.uniform(5, 31, n)])
    v = rng.normal(0.0, np.sqrt(u.boltz * T / (u.mvv2e * m)), (n, 3))
    dt = 2.0 if units == "real" else 0.002
    wall = "fix zw all wall/lj93 zlo EDGE 0.2 3.4 8.5 zhi EDGE 0.2 3.4 8.5 units box"
    cfg = {"units": units, "box": {"lo": [0, 0, 0], "hi": [30, 30, 36], "boundary": ["p", "p", "f"]},
           "atoms": [{"group": "gas", "mass": m, "create": {"positions": x.tolist()},
                      "velocity": {"values": v.tolist()}}],
           "timestep": dt, "walls": {"zw": {"fix": wall, "energy": True}},
           "fixes": {ln.split()[1]: ln for ln in lines}, "run": {"steps": 500, "thermo": 50},
           "output": {"thermo": ["step", "temp", "ke", "pe", "etot", "ecouple", "econserve"]}}
    ds = run_config(config_from_dict(cfg))
    head = [f"units {units}", "atom_style atomic", "atom_modify map array", "boundary p p f",
            "region box block 0 30 0 30 0 36 units box", "create_box 1 box"]
    ref = run_lammps_script(x, v, m, head, [f"timestep {dt!r}", wall, "fix_modify zw energy yes"] + lines, 500, 50,
                            COLUMNS)
    compare(ds, ref)
    assert abs(ref["ecouple"][-1]) > 1e-3 * abs(ref["ke"][0])
