"""`fixes:` and `dimension:` (issue 17) without LAMMPS: frozen groups, batching, bad input,
Langevin statistics, 2-D lattices. LAMMPS parity is in test_thermo_lammps.py."""

from __future__ import annotations

import textwrap

import numpy as np
import pytest
from scipy import stats

from wallbatch import api
from wallbatch.batch.runner import build_cases
from wallbatch.config.ensemble import parse_ensemble_line, to_ensemble_line
from wallbatch.config.fixline import FixLineError
from wallbatch.config.models import config_from_dict, load_config_text
from wallbatch.config.source import ConfigError
from wallbatch.engine import compiled as fast
from wallbatch.engine.engine import Engine, run_cases
from wallbatch.scene.build import build_case
from wallbatch.scene.case import CaseError
from wallbatch.units import lattice_constant

GAS = """\
units: lj
seed: 11
box: {lo: [0, 0, 0], hi: [8, 8, 8], boundary: [p, p, p]}
atoms:
  - group: gas
    create: {random: {count: 150, overlap: 0.5}}
    mass: 1.0
    velocity: {temperature: 1.0}
timestep: 0.005
"""


# ----------------------------------------------------------------------------- fix lines


@pytest.mark.parametrize("line,want", [
    ("fix 1 all nve", {"style": "nve", "group": "all"}),
    ("fix nh fluid nvt temp 1.0 1.5 0.1", {"style": "nvt", "group": "fluid", "temp": [1.0, 1.5], "damp": 0.1}),
    ("fix nh all nvt temp 1 1 0.1 tchain 5 tloop 2 drag 0.2",
     {"style": "nvt", "group": "all", "temp": [1.0, 1.0], "damp": 0.1, "tchain": 5, "tloop": 2, "drag": 0.2}),
    ("fix b mobile langevin 1.5 1.5 0.5 412513 zero yes tally yes",
     {"style": "langevin", "group": "mobile", "temp": [1.5, 1.5], "damp": 0.5, "seed": 412513, "zero": True,
      "tally": True}),
    ("fix t all temp/berendsen 1.0 2.0 0.5", {"style": "temp/berendsen", "group": "all", "temp": [1.0, 2.0],
                                              "damp": 0.5}),
    ("fix t all temp/rescale 100 1.0 1.1 0.02 0.5", {"style": "temp/rescale", "group": "all", "every": 100,
                                                     "temp": [1.0, 1.1], "window": 0.02, "fraction": 0.5}),
    ("fix e all enforce2d", {"style": "enforce2d", "group": "all"}),
])
def test_fix_lines_parse_to_the_mapping_form_and_back(line, want):
    fid = line.split()[1]
    assert parse_ensemble_line(line, fid) == want
    cfg = config_from_dict({**_base(), "dimension": 2 if "enforce2d" in line else 3,
                            "atoms": [{"group": g, "mass": 1.0, "create": {"positions": [[1, 1, 0]]}}
                                      for g in {"gas", want["group"]} - {"all"}] or _base()["atoms"],
                            "fixes": {fid: line}})
    again = parse_ensemble_line(to_ensemble_line(fid, cfg.fixes[fid]), fid)
    assert config_from_dict({**cfg.model_dump(exclude_none=True), "fixes": {fid: again}}).fixes == cfg.fixes


def _base() -> dict:
    return {"units": "lj", "box": {"lo": [0, 0, -0.5], "hi": [5, 5, 0.5], "boundary": ["p", "p", "p"]},
            "atoms": [{"group": "gas", "mass": 1.0, "create": {"positions": [[1, 1, 0], [2, 2, 0]]}}],
            "run": {"steps": 10}}


@pytest.mark.parametrize("line,word", [
    ("fix nh all nvt temp 1.0 1.0", 7), ("fix nh all nvt tmp 1 1 1", 5), ("fix nh all npt temp 1 1 1", 4),
    ("fix nh all langevin 1 1 0.5 9 gjf yes", 9), ("fix nh all temp/rescale 1.5 1 1 0.1 0.5", 5),
])
def test_bad_fix_lines_name_the_word(line, word):
    with pytest.raises(FixLineError, match=f"word {word} "):
        parse_ensemble_line(line, "nh")


# ----------------------------------------------------------------------------- bad input

BAD = """\
units: lj
box: {lo: [0, 0, 0], hi: [8, 8, 8], boundary: [p, p, f]}
atoms:
  - group: gas
    create: {random: {count: 10}}
    mass: 1.0
  - group: solid
    create: {positions: [[1, 1, 1]]}
    mass: 1.0
walls:
  zw: "fix zw all wall/lj93 zlo EDGE 1.0 1.0 2.5 zhi EDGE 1.0 1.0 2.5 units box"
fixes:
FIXES
run: {steps: 10}
"""


@pytest.mark.parametrize("fixes,where", [
    ('  a: {style: nvx, group: gas}', r"<config>:13:\d+: fixes.a.style: unknown fix style 'nvx'"),
    ('  a: "fix a gas nvx"', r"<config>:13:\d+: fixes.a: word 4 'nvx': unknown or unsupported fix style"),
    ('  a: {style: nve, group: all}\n  b: {style: nvt, group: gas, temp: [1, 1], damp: 0.1}',
     r"<config>:14:\d+: fixes.b.group: group 'gas' is already integrated by fix 'a'"),
    ('  a: {style: nvt, group: gas, temp: [1, 1], damp: 0}', r"<config>:13:\d+: fixes.a.damp: .*greater than 0"),
    ('  a: "fix a gas nvt temp 1 1 -0.5"', r"<config>:13:\d+: fixes.a.damp: .*greater than 0"),
    ('  a: {style: nve, group: liquid}', r"<config>:13:\d+: fixes.a.group: unknown group 'liquid'"),
    ('  a: {style: langevin, group: gas, temp: [1, 1], damp: 0.5, seed: 0}', r"fixes.a.seed: "),
])
def test_bad_fixes_name_file_line_and_field(fixes, where):
    with pytest.raises(ConfigError, match=where):
        load_config_text(BAD.replace("FIXES", fixes))


def test_thermostats_and_frozen_groups_with_ellipsoids_are_refused():
    base = {"units": "lj", "box": {"lo": [0, 0, 0], "hi": [8, 8, 8]}, "run": {"steps": 1},
            "atoms": [{"group": "e", "mass": 1.0, "shape": [1.0, 0.5, 0.5], "create": {"positions": [[2, 2, 2]]}},
                      {"group": "p", "mass": 1.0, "create": {"positions": [[5, 5, 5]]}}]}
    with pytest.raises(ConfigError, match="fixes.nh.style: fix nvt on ellipsoids is not supported"):
        config_from_dict({**base, "fixes": {"nh": "fix nh all nvt temp 1 1 0.1"}})
    with pytest.raises(ConfigError, match="fixes: group.s. p are integrated by no fix"):
        config_from_dict({**base, "fixes": {"a": "fix a e nve/asphere"}})
    cfg = config_from_dict({**base, "fixes": {"a": "fix a e nve/asphere", "b": "fix b p nve"}})
    assert build_case(cfg).fixes is not None


def test_2d_with_a_z_wall_is_refused_at_the_wall():
    text = BAD.replace("fixes:\nFIXES\n", "dimension: 2\n").replace("[p, p, f]", "[p, p, p]").replace(
        "units box\"", "units box pbc yes\"")
    with pytest.raises(ConfigError, match=r"<config>:11:\d+: walls.zw.zlo: a zlo wall in a 2-D run"):
        load_config_text(text)
    with pytest.raises(ConfigError, match=r"box.boundary: a 2-D run .* periodic z"):
        load_config_text(BAD.replace("fixes:\nFIXES\n", "dimension: 2\n"))
    # without pbc yes: only that error, not the 3-D advice to make z fixed (2-D needs it periodic)
    with pytest.raises(ConfigError) as info:
        load_config_text(text.replace(" pbc yes", ""))
    about = [p.split(": ", 2)[2] for p in info.value.problems if ": walls.zw.zlo: " in p]
    assert about == ["a zlo wall in a 2-D run (dimension: 2): 2-D walls act in x and y only"], info.value.problems


def test_2d_atoms_are_in_the_plane_z_0(tmp_path):
    """A 2-D run's atoms sit at z = 0, as LAMMPS's: the box's z range must straddle 0, explicit
    positions and atom files with z != 0 are refused at their place (LAMMPS refuses them too)."""
    base = {"units": "lj", "dimension": 2, "box": {"lo": [0, 0, -0.5], "hi": [6, 6, 0.5], "boundary": ["p", "p", "p"]},
            "run": {"steps": 1},
            "atoms": [{"group": "g", "mass": 1.0, "create": {"positions": [[1, 1, 0], [3, 3, 0]]}}]}
    build_case(config_from_dict(base))
    with pytest.raises(ConfigError, match=r"box.lo: a 2-D run .* z range \(0 to 1\) must straddle 0"):
        config_from_dict({**base, "box": {"lo": [0, 0, 0], "hi": [6, 6, 1], "boundary": ["p", "p", "p"]}})
    moved = {**base, "atoms": [{"group": "g", "mass": 1.0, "create": {"positions": [[1, 1, 0], [3, 3, 0.25]]}}]}
    with pytest.raises(ConfigError, match=r"atoms.0.create.positions.1: z = 0.25 in a 2-D run"):
        config_from_dict(moved)
    np.savez(tmp_path / "off.npz", x=np.array([[1.0, 1.0, 0.0], [2.0, 2.0, 0.1]]))
    filed = {**base, "atoms": [{"group": "g", "mass": 1.0, "create": {"file": str(tmp_path / "off.npz")}}]}
    with pytest.raises(CaseError, match=r"atom 2 has z = 0.1 in a 2-D run"):
        build_case(config_from_dict(filed))


def test_nvt_on_a_group_with_no_atoms_is_refused(tmp_path):
    """Only a .npz file can give a group no atoms; the error names file:line:col and the field."""
    np.savez(tmp_path / "empty.npz", x=np.zeros((0, 3)))
    text = textwrap.dedent("""\
        units: lj
        box: {lo: [0, 0, 0], hi: [6, 6, 6]}
        atoms:
          - group: gas
            create: {positions: [[1, 1, 1], [3, 3, 3]]}
            mass: 1.0
          - group: none
            create: {file: empty.npz}
            mass: 1.0
        fixes:
          move: {style: nve, group: gas}
          nh: {style: nvt, group: none, temp: [1, 1], damp: 0.1}
        run: {steps: 1}
        """)
    cfg = load_config_text(text, "scene.yaml", base=tmp_path)
    with pytest.raises(CaseError, match=r"scene.yaml:12:\d+: fixes.nh.group: group 'none' has no atoms"):
        build_case(cfg)


# ----------------------------------------------------------------------------- frozen atoms


def test_a_zero_temperature_names_the_thermostat_s_group():
    """temp/berendsen on a group at rest (LAMMPS stops: computed temperature cannot be 0.0): the
    failed case names the fix, its group and the step."""
    cfg = config_from_dict({
        "units": "lj", "box": {"lo": [0, 0, 0], "hi": [10, 9, 9]},
        "atoms": [{"group": "still", "mass": 1.0, "create": {"positions": [[5.0, 3.0, 3.0], [5.0, 6.0, 6.0]]}},
                  {"group": "ball", "mass": 1.0, "create": {"positions": [[2.0, 4.0, 4.0]]},
                   "velocity": {"values": [1.0, 0.0, 0.0]}}],
        "fixes": {"move": "fix move all nve", "ber": "fix ber still temp/berendsen 1.0 1.0 0.5"},
        "run": {"steps": 10, "thermo": 5}})
    res = run_cases([build_case(cfg)])[0]
    assert res.status == "failed"
    assert res.error.startswith("fixes.ber: the temperature of group 'still' is 0 at step 1 (LAMMPS: computed "
                                "temperature for fix temp/berendsen cannot be 0.0)"), res.error


def test_frozen_group_does_not_move_and_still_pushes():
    """A 3x3 patch of atoms nobody integrates; one mobile atom flies at it and bounces back
    (lj/cut), while the patch keeps its positions to the bit."""
    patch = [[5.0, 3.0 + i, 3.0 + j] for i in range(3) for j in range(3)]
    cfg = config_from_dict({
        "units": "lj", "box": {"lo": [0, 0, 0], "hi": [10, 9, 9]},
        "pair": {"style": "lj/cut", "epsilon": 1.0, "sigma": 1.0, "cutoff": 2.5, "shift": True},
        "atoms": [{"group": "wall", "mass": 1.0, "create": {"positions": patch}, "velocity": {"values": [0.3, 0, 0]}},
                  {"group": "ball", "mass": 1.0, "create": {"positions": [[2.0, 4.0, 4.0]]},
                   "velocity": {"values": [1.0, 0.0, 0.0]}}],
        "fixes": {"move": {"style": "nve", "group": "ball"}},
        "timestep": 0.002, "run": {"steps": 2000, "thermo": 500},
        "output": {"thermo": ["step", "ke", "pe", "etot"], "dump": {"every": 500, "fields": ["x", "v"]}},
    })
    case = build_case(cfg)
    res = run_cases([case])[0]
    assert res.status == "ok"
    x, v = res.frames["x"], res.frames["v"]
    assert np.array_equal(x[:, :9], np.broadcast_to(case.x[:9], x[:, :9].shape))  # not one bit
    assert np.array_equal(v[:, :9], np.broadcast_to(case.v[:9], v[:, :9].shape))  # unintegrated: v kept
    assert v[-1, 9, 0] < -0.9  # bounced off the frozen patch
    assert x[-1, 9, 0] < 3.5  # on its way back, never through the patch
    # the energy of the mobile atom in the static field is conserved (frozen KE is constant)
    etot = res.data["etot"]
    assert np.ptp(etot) < 1e-3


# ----------------------------------------------------------------------------- batching


def _plan(fixes: str, sweep: str):
    text = GAS + "walls: {}\nfixes:\n" + textwrap.indent(fixes, "  ") + "\nrun: {steps: 200, thermo: 50}\n" + \
        "output: {thermo: [step, temp, ke, etot, ecouple, econserve]}\nsweep:\n" + textwrap.indent(sweep, "  ")
    import yaml
    return api.load(yaml.safe_load(text))


@pytest.mark.parametrize("fixes,sweep", [
    ('nh: "fix nh all nvt temp 1.0 1.0 0.1"',
     ("product:\n  T: {path: fixes.nh.temp, values: [[0.8, 0.8], [1.6, 1.6]]}\n"
     "  damp: {path: fixes.nh.damp, values: [0.05, 0.5]}\n")),
    ('nve: {style: nve}\nbath: "fix bath all langevin 1.0 1.0 0.5 4242 zero yes tally yes"',
     ("product:\n  T: {path: fixes.bath.temp, values: [[0.8, 0.8], [1.6, 1.6]]}\n"
     "  damp: {path: fixes.bath.damp, values: [0.1, 1.0]}\n")),
    ('nve: {style: nve}\nber: "fix ber all temp/berendsen 1.0 1.0 0.5"\nres: "fix res all temp/rescale 10 1 1 0.1 0.5"',
     ("product:\n  T: {path: [fixes.ber.temp, fixes.res.temp], values: [[0.8, 0.8], [1.6, 1.6]]}\n"
     "  damp: {path: fixes.ber.damp, values: [0.1, 1.0]}\n")),
])
def test_temperature_by_damp_sweep_is_one_batch_and_bit_identical_to_single_runs(fixes, sweep):
    plan = _plan(fixes, sweep)
    cases, errors = build_cases(plan)
    assert not errors and len(cases) == 4
    engine = Engine(cases)  # raises nothing: all four share one structure
    assert engine.ensemble is not None  # the thermostats run in the compiled chunks when numba is on
    assert (engine.fast is not None) == fast.enabled()
    together = engine.run()
    for c, res in zip(cases, together):
        alone = run_cases([c])[0]
        assert res.status == alone.status == "ok"
        for k in ("temp", "ke", "etot", "ecouple", "econserve"):
            assert np.array_equal(res.data[k], alone.data[k]), k
    temps = np.array([r.data["temp"][-1] for r in together])
    assert temps[0] < 1.2 < temps[3]  # the thermostats pull toward their own targets


def test_a_sweep_of_temp_pairs_writes_its_results_file(tmp_path):
    """`fixes.ID.temp` is a pair [Tstart, Tstop]: swept, each value is a list. The results file
    holds it as the text of the pair (a 1-d coordinate needs one scalar per case; writing the file
    used to fail with a ValueError after every case had run), and each case's outputs are those of
    its single run."""
    from wallbatch.batch.runner import run_plan
    from wallbatch.io.report import select
    import xarray as xr
    plan = _plan('nh: "fix nh all nvt temp 1.0 1.0 0.1"',
                 "product:\n  T: {path: fixes.nh.temp, values: [[0.8, 0.8], [1.0, 1.6]]}\n")
    run_plan(plan, tmp_path / "out.nc", jobs=1)
    with xr.open_dataset(tmp_path / "out.nc") as ds:
        assert list(ds["T"].values) == ["[0.8, 0.8]", "[1.0, 1.6]"]
        assert ds["T"].attrs["path"] == "fixes.nh.temp"
        assert list(ds["status"].values) == ["ok", "ok"]
        cases, _ = build_cases(plan)
        alone = run_cases([cases[1]])[0]
        assert np.array_equal(select(ds, {"T": "[1.0, 1.6]"})["ecouple"].values, alone.data["ecouple"])


# ----------------------------------------------------------------------------- Langevin statistics


@pytest.mark.slow
def test_langevin_temperature_maxwellian_momentum_and_econserve():
    """Ideal gas in a periodic box, fix langevin T = 1.5 zero yes tally yes, 8 replicas:
    the mean temperature is within 3 standard errors of 1.5; velocity components pass a KS test
    against the Maxwellian N(0, sqrt(kT/m)); the total momentum stays zero to round-off; and
    econserve = etot + ecouple drifts by less than 1% of the energy exchanged."""
    import yaml
    text = GAS.replace("count: 150", "count: 200") + textwrap.dedent("""\
        fixes:
          nve: {style: nve}
          bath: {style: langevin, temp: [1.5, 1.5], damp: 0.5, seed: 412513, zero: true, tally: true}
        run: {steps: 6000, thermo: 100}
        output: {thermo: [step, temp, ke, etot, ecouple, econserve], dump: {every: 500, fields: [v]}}
        sweep: {replicas: 8}
        """)
    plan = api.load(yaml.safe_load(text))
    cases, _ = build_cases(plan)
    results = run_cases(cases)
    means = np.array([r.data["temp"][20:].mean() for r in results])  # after 10 damping times
    se = means.std(ddof=1) / np.sqrt(len(means))
    assert abs(means.mean() - 1.5) < 3 * se, (means.mean(), se)
    assert se < 0.02
    v = np.concatenate([r.frames["v"][2:] for r in results])  # frames 1000 steps apart
    p = v.sum(axis=1)  # total momentum per frame (m = 1)
    assert np.abs(p).max() < 1e-10
    comps = v.reshape(-1)
    assert stats.kstest(comps, "norm", args=(0.0, np.sqrt(1.5))).pvalue > 1e-3
    assert stats.kstest(comps, "norm", args=(0.0, np.sqrt(1.5) * 1.05)).pvalue < 1e-3  # the test has power
    for r in results:
        drift = np.abs(r.data["econserve"] - r.data["econserve"][0]).max()
        assert drift < 0.01 * np.abs(r.data["ecouple"]).max(), drift
        assert np.abs(r.data["ecouple"]).max() > 10.0


def test_langevin_without_walls_keeps_zero_momentum():
    import yaml
    cfg = config_from_dict(yaml.safe_load(GAS + textwrap.dedent("""\
        fixes:
          nve: {style: nve}
          bath: {style: langevin, temp: [1.5, 1.5], damp: 0.2, seed: 99, zero: true}
        run: {steps: 500, thermo: 100}
        output: {dump: {every: 100, fields: [v]}}
        """)))
    case = build_case(cfg)
    assert np.abs(case.v.sum(axis=0)).max() < 1e-12
    res = run_cases([case])[0]
    assert np.abs(res.frames["v"].sum(axis=1)).max() < 1e-11
    assert abs(res.data["temp"][-1] - 1.0) > 0.05  # it did act


# ----------------------------------------------------------------------------- 2-D


@pytest.mark.parametrize("style,rho,want", [
    ("sq", 0.8, 1.118033988749895), ("sq2", 0.8, 1.5811388300841898), ("hex", 0.8, 1.2014057070673771),
])
def test_2d_lattice_constants_equal_lammps(style, rho, want):
    assert lattice_constant(style, rho, "lj") == pytest.approx(want, rel=1e-15)


def test_2d_hex_lattice_density_and_velocities():
    cfg = config_from_dict({
        "units": "lj", "dimension": 2, "lattice": {"style": "hex", "scale": 0.8},
        "box": {"lo": [0, 0, -0.5], "hi": [1.2014057070673771 * 6, 2.0808957251439084 * 4, 0.5]},
        "atoms": [{"group": "gas", "mass": 1.0, "create": {"lattice": {}}, "velocity": {"temperature": 0.7}}],
        "run": {"steps": 50, "thermo": 50}, "output": {"thermo": ["step", "temp", "ke", "etot"]}})
    case = build_case(cfg)
    assert case.natoms == 6 * 4 * 2
    area = (case.box_hi - case.box_lo)[:2].prod()
    assert case.natoms / area == pytest.approx(0.8, rel=1e-12)
    assert np.all(case.v[:, 2] == 0) and np.all(case.x[:, 2] == 0)
    ke = 0.5 * (case.v ** 2).sum()
    assert 2 * ke / (2 * case.natoms - 2) == pytest.approx(0.7, rel=1e-12)
    res = run_cases([case])[0]
    np.testing.assert_allclose(res.data["temp"], 0.7, rtol=1e-12)  # free flight in 2-D, dof 2N - 2


def test_2d_lattice_in_3d_and_3d_lattice_in_2d_are_refused():
    base = {"units": "lj", "box": {"lo": [0, 0, -0.5], "hi": [5, 5, 0.5]},
            "atoms": [{"group": "g", "mass": 1.0, "create": {"lattice": {}}}], "run": {"steps": 1}}
    with pytest.raises(ConfigError, match="lattice.style: lattice sq is 2-D"):
        config_from_dict({**base, "lattice": {"style": "sq", "scale": 0.8}})
    with pytest.raises(ConfigError, match="lattice.style: lattice fcc is 3-D"):
        config_from_dict({**base, "dimension": 2, "lattice": {"style": "fcc", "scale": 0.8}})
    with pytest.raises(ConfigError, match=r"walls.w.units: lattice hex has different x and y spacings"):
        config_from_dict({**base, "dimension": 2, "lattice": {"style": "hex", "scale": 0.8},
                          "box": {**base["box"], "boundary": ["f", "p", "p"]},
                          "walls": {"w": "fix w all wall/harmonic xlo 0.0 1.0 1.0 1.0"}})


@pytest.mark.slow  # 1-3 s: kept out of the fast subset's one-minute budget
def test_time_based_run_with_dt_reset_batches_thermostats_bit_identically():
    """run: {time: ...} with dt_reset: cases take different timesteps, so in a batch some sit idle
    while the others land on the sample time. Idle cases draw no Langevin numbers and keep their
    chain state: each case equals its single run bit for bit."""
    import yaml
    text = GAS.replace("count: 150", "count: 60") + textwrap.dedent("""\
        walls: {zw: "fix zw all wall/harmonic zlo EDGE 5.0 1.0 1.0 zhi EDGE 5.0 1.0 1.0 units box pbc yes"}
        dt_reset: {every: 1, xmax: 0.01, units: box}
        fixes:
          nh: "fix nh gas nvt temp 1.2 1.2 0.2"
        run: {time: 0.5}
        output: {thermo: [step, time, dt, temp, ke, etot, ecouple, econserve]}
        sweep:
          product:
            xmax: {path: dt_reset.xmax, values: [0.004, 0.01]}
        """)
    for fixes in ('  nh: "fix nh gas nvt temp 1.2 1.2 0.2"',
                  '  nve: {style: nve}\n  bath: "fix bath all langevin 1.2 1.2 0.2 5 tally yes"'):
        plan = api.load(yaml.safe_load(text.replace('  nh: "fix nh gas nvt temp 1.2 1.2 0.2"', fixes)))
        cases, _ = build_cases(plan)
        together = run_cases(cases)
        steps = [r.data["step"][-1] for r in together]
        assert steps[0] > steps[1]  # different timesteps
        for c, res in zip(cases, together):
            alone = run_cases([c])[0]
            assert res.status == alone.status == "ok", res.error
            for k in ("step", "time", "temp", "etot", "ecouple", "econserve"):
                assert np.array_equal(res.data[k], alone.data[k]), k
