"""LAMMPS quirks (physics.md §13) and decisions-table rows that no other test pinned (issue 5,
item 6; docs/quirks.md lists every quirk with the test that pins it).

Each test pins both sides: wallbatch's value (a closed form or physics.md §15 reference) and
LAMMPS 22Jul2025's, read from the binary (tests/lammps_oracle.py, or a few raw commands through
the `lammps` Python module where the oracle cannot express the scene: ellipsoids, thermo
normalisation).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from factories import atoms, box_scene, run_one
from lammps_oracle import (
    LammpsRunError,
    Scene,
    _load_lammps,
    requires_lammps,
    run_lammps,
)

from wallbatch.config.source import ConfigError
from wallbatch.config.models import config_from_dict
from wallbatch.batch.runner import run_config
from wallbatch.scene.build import build_case

MORSE_E_1_3 = -1.2706050535127498  # §15: morse D0 1.5, alpha 2, r0 1.1, rc 3, xlo r = 1.3
MORSE_FW_1_3 = 1.32594649
LJ93_E_1_2 = -0.48889776297466175  # §15: lj93 eps 1, sigma 1, rc 2.5, r = 1.2
EES_E_2_5 = -0.008385934463405598  # §15: ees xlo r 2.5, diam (2, 1, 1), 30 deg about z, eps 1 sigma 1 rc 4


# ----------------------------------------------------------------------------- helpers


def scene(atoms: list[dict], walls: dict, *, boundary=("f", "p", "p"), steps: int = 0, **extra) -> dict:
    return box_scene(atoms, walls, lo=(0, 0, 0), hi=(10, 10, 10), boundary=boundary, timestep=0.005, steps=steps,
                     seed=1, **extra)


def point(positions, velocities=None, mass=1.0, **extra) -> dict:
    return atoms("a", positions, velocities, mass, **extra)


def oracle(d: dict, fixes: list[str], outputs: list[str], variables: dict | None = None,
           steps: int | None = None) -> dict:
    """The dict scene's initial state in LAMMPS with `fixes`, run for its steps (or `steps`)."""
    case = build_case(config_from_dict(d))
    return run_lammps(Scene(units="lj", box_lo=tuple(case.box_lo), box_hi=tuple(case.box_hi),
                            boundary=tuple(d["box"]["boundary"]), x=case.x, v=case.v, mass=case.mass,
                            radius=case.radius if np.any(case.radius > 0) else None,
                            variables=dict(variables or {}), fixes=fixes, timestep=case.dt,
                            steps=d["run"]["steps"] if steps is None else steps,
                            thermo_every=1, outputs=outputs))


def lammps_commands(commands: list[str]):
    """Run raw LAMMPS commands; return the open instance (the caller closes it)."""
    lmp = _load_lammps().lammps(cmdargs=["-log", "none", "-screen", "none", "-nocite"])
    try:
        for line in commands:
            lmp.command(line)
    except Exception:
        lmp.close()
        raise
    return lmp


def ees_energy(r: float, sn: float, eps: float = 1.0, sigma: float = 1.0) -> float:
    """physics.md §4.7, the unshifted ellipsoid-wall energy."""
    h = r * r - sn * sn
    return eps * (2 * sigma**12 * (7 * r**5 + 14 * r**3 * sn**2 + 3 * r * sn**4) / (945 * h**7)
                  - sigma**6 * (2 * r * sn**3 + sn**2 * h * math.log((r - sn) / (r + sn))) / (12 * sn**5 * h))


# ----------------------------------------------------------------------------- quirk #2


MORSE_ALPHA_VAR = {"coord": 0.0, "D0": 1.5, "alpha": "v_a", "r0": 1.1, "cutoff": 3.0}


def test_morse_alpha_variable_is_evaluated():
    """Decisions table / quirk #2: wallbatch evaluates alpha = v_a (= 2): the §15 values."""
    d = scene([point([(1.3, 5, 5)])], {"w": {"style": "morse", "units": "box", "xlo": MORSE_ALPHA_VAR}},
              variables={"a": "1.0 + 1.0"})
    ds = run_config(config_from_dict(d))
    assert ds.status.item() == "ok", ds.error.item()
    assert ds.wall_energy.values[0, 0] == pytest.approx(MORSE_E_1_3, rel=1e-12)
    assert ds.wall_force.values[0, 0] == pytest.approx(MORSE_FW_1_3, rel=1e-8)


@requires_lammps
def test_morse_alpha_variable_is_ignored_by_lammps():
    """LAMMPS never evaluates a v_ alpha: a variable that does not exist gives no error. alpha
    stays unset, which is uninitialised memory (0 in most runs; CI runs saw E = -2.9e-6, -0.87,
    and once exactly the alpha of an earlier wall of the same process), so nothing is pinned
    about that energy; the same wall with alpha 2.0 written as a number gives the §15 values."""
    d = scene([point([(1.3, 5, 5)])], {"w": {"style": "morse", "units": "box", "xlo": MORSE_ALPHA_VAR}},
              variables={"a": "1.0 + 1.0"})
    out = ["f_w", "f_w[1]"]
    ref = oracle(d, ["fix w all wall/morse xlo 0.0 1.5 v_nothere 1.1 3.0 units box"], out, {"a": "1.0 + 1.0"})
    assert len(ref["f_w"]) >= 1  # ran: the undefined variable was never evaluated
    ref = oracle(d, ["fix w all wall/morse xlo 0.0 1.5 2.0 1.1 3.0 units box"], out)
    assert ref["f_w"][0] == pytest.approx(MORSE_E_1_3, rel=1e-12)
    assert ref["f_w[1]"][0] == pytest.approx(MORSE_FW_1_3, rel=1e-8)


# ----------------------------------------------------------------------------- quirk #13


def test_ees_energy_is_not_shifted_at_the_cutoff():
    """Quirk #13 (kept, as LAMMPS): the ees energy is the raw E(r): the §15 value at r = 2.5, and
    it jumps from E(rc) to 0 when the ellipsoid crosses rc = 4 (every other style is shifted)."""
    c, s = math.cos(math.radians(15)), math.sin(math.radians(15))
    sn = math.sqrt(1.0 * math.cos(math.radians(30)) ** 2 + 0.25 * math.sin(math.radians(30)) ** 2)
    assert sn == pytest.approx(0.9013878188659974, rel=1e-15)
    energies = []
    for x in (2.5, 4.0 - 1e-9, 4.0 + 1e-9):
        d = scene([point([(x, 5, 5)], shape=[1.0, 0.5, 0.5], orientation=[c, 0.0, 0.0, s])],
                  {"w": {"style": "ees", "units": "box", "xlo": {"coord": 0.0, "epsilon": 1.0, "sigma": 1.0,
                                                               "cutoff": 4.0}}})
        ds = run_config(config_from_dict(d))
        assert ds.status.item() == "ok", ds.error.item()
        energies.append(ds.wall_energy.values[0, 0])
    assert energies[0] == pytest.approx(EES_E_2_5, rel=1e-12)
    assert energies[0] == pytest.approx(ees_energy(2.5, sn), rel=1e-12)
    assert energies[1] == pytest.approx(ees_energy(4.0, sn), rel=1e-6)
    assert energies[1] < -1e-3 and energies[2] == 0.0  # a jump of E(rc) = -0.0012 at the cut-off


# ----------------------------------------------------------------------------- quirk #14


def _region_ees_scene(r: float, angle: float) -> tuple[dict, np.ndarray]:
    """An ellipsoid (semi-axes 0.5, 2, 0.5) turned by `angle` degrees about z, inside a sphere of
    radius 5, its centre r from the surface along the diagonal (1, 1, 0)/sqrt 2 (the contact normal
    points back along it). At -45 degrees the long axis lies along the normal (true sigma_n = 2),
    at +45 degrees across it (true sigma_n = 0.5); the per-axis values along x and y are both
    sqrt(0.25/2 + 4/2) = 1.458 either way."""
    center = np.array([10.0, 10.0, 10.0])
    x = center + (5.0 - r) * np.array([1.0, 1.0, 0.0]) / math.sqrt(2.0)
    half = math.radians(angle) / 2
    d = scene([point([tuple(x)], shape=[0.5, 2.0, 0.5], orientation=[math.cos(half), 0.0, 0.0, math.sin(half)])],
              {"shell": {"style": "region/ees", "region": "ball", "epsilon": 1.0, "sigma": 1.0, "cutoff": 2.5}},
              boundary=("f", "f", "f"), regions={"ball": {"style": "sphere", "center": center.tolist(),
                                                          "radius": 5.0, "units": "box"}})
    d["box"]["hi"] = [20, 20, 20]
    return d, x


def lammps_region_ees_energy(r: float, angle: float) -> float:
    """LAMMPS's wall/region/ees energy at setup for the scene above (raises on its error)."""
    _, x = _region_ees_scene(r, angle)
    lmp = lammps_commands([
        "units lj", "atom_style ellipsoid", "boundary f f f",
        "region box block 0 20 0 20 0 20 units box", "create_box 1 box",
        "create_atoms 1 single " + " ".join(repr(float(c)) for c in x) + " units box",
        "set atom 1 mass 1.0", "set atom 1 shape 1.0 4.0 1.0", f"set atom 1 quat 0 0 1 {angle!r}",
        "region ball sphere 10 10 10 5 side in units box",
        "fix w all wall/region/ees ball 1.0 1.0 2.5", "fix i all nve/asphere",
        "thermo_style custom step f_w", "run 0"])
    try:
        return lmp.extract_fix("w", 0, 0)  # global scalar
    finally:
        lmp.close()


def test_region_ees_too_close_uses_the_true_sigma_n():
    """Decisions table / quirk #14, wallbatch's side: "too close" is r <= sigma_n along the
    contact normal. Long axis along the normal, r = 1.8 < 2: the ellipsoid pokes through the
    surface, the case fails. Long axis across it, r = 1.0 > 0.5: a finite energy, equal to the
    flat-wall ees energy at that r and sigma_n (the sphere's curvature does not enter)."""
    ds = run_config(config_from_dict(_region_ees_scene(1.8, -45.0)[0]))
    assert ds.status.item() == "failed"
    msg = ds.error.item()
    assert "walls.shell (wall/region/ees ball)" in msg and "atom ID 1" in msg and "step 0" in msg
    assert "Particle on or inside surface of region used in fix wall/region/ees" in msg
    ds = run_config(config_from_dict(_region_ees_scene(1.0, 45.0)[0]))
    assert ds.status.item() == "ok", ds.error.item()
    assert ds.wall_energy.values[0, 0] == pytest.approx(ees_energy(1.0, 0.5), rel=1e-12)


@requires_lammps
def test_region_ees_lammps_per_axis_threshold():
    """LAMMPS's side: its threshold here is the per-axis 1.458 (observed: the largest sigma_n
    along x, y, z over the non-zero components of the contact vector), not the true sigma_n.
    Long axis along the normal, r = 1.8: no error and a NaN energy (log of a negative number).
    Long axis across it, r = 1.0: an error although the ellipsoid is 0.5 clear of the surface.
    At r = 2.2 (beyond both) the two codes agree."""
    assert math.isnan(lammps_region_ees_energy(1.8, -45.0))
    with pytest.raises(Exception, match="Particle on or inside surface of region used in fix wall/region/ees"):
        lammps_region_ees_energy(1.0, 45.0)
    ds = run_config(config_from_dict(_region_ees_scene(2.2, -45.0)[0]))
    assert ds.wall_energy.values[0, 0] == pytest.approx(lammps_region_ees_energy(2.2, -45.0), rel=1e-12)
    assert ds.wall_energy.values[0, 0] == pytest.approx(ees_energy(2.2, 2.0), rel=1e-12)


@requires_lammps
def test_validate_names_quirk_14_when_lammps_stops_on_region_ees():
    """validate on the scene where LAMMPS's per-axis test stops (long axis across the normal, 0.5
    clear of the surface): wallbatch runs, and the LAMMPS error row points to quirk #14 instead
    of looking like a wallbatch defect."""
    from wallbatch.config.sweep import SweepCase  # noqa: PLC0415
    from wallbatch.lammps.validate import validate_case  # noqa: PLC0415

    d, _ = _region_ees_scene(1.0, 45.0)
    d["run"] = {"steps": 2, "thermo": 1}
    report = validate_case(SweepCase((), {}, config_from_dict(d), ()), steps=2)
    err = [e for e in report.errors if e.startswith("LAMMPS:")]
    assert len(err) == 1 and "Particle on or inside surface of region used in fix wall/region/ees" in err[0]
    assert "quirk #14 in docs/deviations.md" in err[0]
    assert not [e for e in report.errors if e.startswith("wallbatch:")]


# ----------------------------------------------------------------------------- quirk #18


@requires_lammps
def test_lj_wall_outputs_are_extensive_lammps_thermo_divides_by_n():
    """Decisions table / quirk #18: two atoms, one at r = 1.2 from an lj93 wall. wallbatch reports
    the extensive E = -0.48890; LAMMPS's thermo in lj units (norm yes by default) prints E/2."""
    d = scene([point([(1.2, 5, 5), (6.0, 5, 5)])],
              {"w": {"style": "lj93", "units": "box", "energy": True,
                     "xlo": {"coord": 0.0, "epsilon": 1.0, "sigma": 1.0, "cutoff": 2.5}}})
    ds = run_config(config_from_dict(d))
    assert ds.wall_energy.values[0, 0] == pytest.approx(LJ93_E_1_2, rel=1e-14)
    assert ds.pe.values[0] == pytest.approx(LJ93_E_1_2, rel=1e-14)
    printed = {}
    for norm in ("", "thermo_modify norm no"):
        lmp = lammps_commands([
            "units lj", "atom_style atomic", "boundary f p p", "region box block 0 10 0 10 0 10 units box",
            "create_box 1 box", "create_atoms 1 single 1.2 5 5 units box", "create_atoms 1 single 6.0 5 5 units box",
            "mass 1 1.0", "fix w all wall/lj93 xlo 0.0 1.0 1.0 2.5 units box", "fix_modify w energy yes",
            "thermo_style custom step f_w pe", norm, "run 0"])
        try:
            printed[norm or "default"] = dict(lmp.last_thermo())
        finally:
            lmp.close()
    assert printed["default"]["f_w"] == pytest.approx(LJ93_E_1_2 / 2, rel=1e-14)
    assert printed["default"]["PotEng"] == pytest.approx(LJ93_E_1_2 / 2, rel=1e-14)
    assert printed["thermo_modify norm no"]["f_w"] == pytest.approx(LJ93_E_1_2, rel=1e-14)


# ----------------------------------------------------------------------------- quirk #17


@requires_lammps
def test_lattice_units_without_a_lattice():
    """Decisions table / quirk #17: wallbatch refuses `units: lattice` without `lattice:`;
    LAMMPS silently uses spacing 1 (wall at 1.0 lattice = 1.0 box: E = (2.5 - 2.0)^2 = 0.25)."""
    d = scene([point([(3.0, 5, 5)])], {"w": {"style": "harmonic", "xlo": {"coord": 1.0, "epsilon": 1.0,
                                                                           "cutoff": 2.5}}})
    with pytest.raises(ConfigError, match="units: box"):
        config_from_dict(d)
    edge = {"w": {"style": "harmonic", "xlo": {"coord": "EDGE", "epsilon": 1.0, "cutoff": 2.5}, "pbc": True},
            "r": {"style": "reflect", "xhi": "EDGE", "pbc": True}}
    config_from_dict(scene([point([(3.0, 5, 5)])], edge))  # every face at EDGE: nothing to scale, accepted
    d["walls"]["w"]["units"] = "box"
    for units in ("", " units lattice", " units box"):
        ref = oracle(d, [f"fix w all wall/harmonic xlo 1.0 1.0 1.0 2.5{units}"], ["f_w"])
        assert ref["f_w"][0] == pytest.approx(0.25, rel=1e-14)


# ----------------------------------------------------------------------------- dt/reset bounds


@requires_lammps
def test_dt_reset_inf_bound_is_no_bound_lammps_refuses_inf():
    """Decisions table, dt_reset tmin/tmax: wallbatch takes INF (and NULL, null) as no bound: one
    atom at v = 1 with no force and xmax 0.1 gets dt = 0.1, LAMMPS's value with NULL; LAMMPS
    refuses INF."""
    d = scene([point([(5, 5, 5)], [(1.0, 0, 0)])], {}, steps=2,
              dt_reset={"every": 1, "tmin": "INF", "tmax": "INF", "xmax": 0.1, "units": "box"})
    d["dt_reset"]["tmin"] = "NULL"
    ds = run_config(config_from_dict(d))
    assert ds.dt.values.tolist() == [0.1, 0.1, 0.1]
    d["dt_reset"]["tmin"] = 0.01
    ds = run_config(config_from_dict(d))
    assert ds.dt.values.tolist() == [0.1, 0.1, 0.1]
    ref = oracle(d, ["fix dtr all dt/reset 1 NULL NULL 0.1 units box"], ["dt"])
    assert ref["dt"].tolist() == [0.1, 0.1, 0.1]
    with pytest.raises(LammpsRunError, match="Expected floating point parameter instead of 'INF'"):
        oracle(d, ["fix dtr all dt/reset 1 NULL INF 0.1 units box"], ["dt"])


# ----------------------------------------------------------------------------- flow temperature


FLOW = {"style": "flow", "axis": "x", "vflow": 0.4, "seed": 593894, "coords": [5.0], "units": "box"}


@requires_lammps
def test_flow_temperature_not_positive():
    """Decisions table, wall/flow temperature <= 0: wallbatch refuses it; LAMMPS accepts T = -1,
    the first redraw (an atom crossing x = 5 in step 1) gives a NaN velocity, and the next step
    stops on NaN coordinates."""
    d = scene([point([(4.998, 5, 5)], [(1.0, 0, 0)])], {"f": dict(FLOW, temperature=-1.0)},
              boundary=("p", "p", "p"), steps=2)
    with pytest.raises(ConfigError, match="walls.f.temperature"):
        config_from_dict(d)
    d["walls"]["f"]["temperature"] = 1.5  # a valid scene, to hand LAMMPS the same atom
    ds = run_config(config_from_dict(d))
    assert ds.status.item() == "ok" and ds.flow_crossings.values.tolist() == [0.0, 1.0, 0.0]
    bad = ["fix f all wall/flow x 0.4 -1.0 593894 1 5.0 units box"]
    ref = oracle(d, bad, ["v_vx"], {"vx": "vx[1]"}, steps=1)
    assert ref["v_vx"][0] == 1.0 and np.isnan(ref["v_vx"][1])
    with pytest.raises(LammpsRunError, match="Non-numeric atom coords"):
        oracle(d, bad, ["v_vx"], {"vx": "vx[1]"}, steps=2)


THERMAL = {"style": "reflect/stochastic", "seed": 77, "units": "box"}


@requires_lammps
def test_stochastic_temperature_and_accommodation_out_of_range():
    """Decisions table, wall/reflect/stochastic temperature <= 0 or accommodation outside [0, 1]:
    wallbatch refuses them; LAMMPS takes them and fails at the first reflection (an atom 0.001
    from xlo at vx = -1 crosses in step 1: T = 0 'Invalid Rayleigh parameter', T = -1 NaN
    coordinates, a ccl normal coefficient 1.5 'Invalid Bessel exponential distribution
    parameters') or runs on (maxwell accom 1.5 acts as 1: every reflection diffusive)."""
    d = scene([point([(0.001, 5, 5)], [(-1.0, 0, 0)])], {}, steps=2)
    refused = [("diffusive", {"temp": 0.0}, "temp"), ("diffusive", {"temp": -1.0}, "temp"),
               ("maxwell", {"temp": 1.5, "accom": 1.5}, "between 0 and 1"),
               ("ccl", {"temp": 1.5, "accom": [0.5, 0.5, -0.2]}, "between 0 and 1")]
    for rstyle, face, match in refused:
        d["walls"] = {"t": dict(THERMAL, rstyle=rstyle, xlo=dict(face, coord=0.0))}
        with pytest.raises(ConfigError, match=match):
            config_from_dict(d)
    d["walls"] = {}
    line = "fix t all wall/reflect/stochastic {} 77 xlo 0.0 {} units box"
    for rstyle, args, message in (("diffusive", "0.0 0 0 0", "Invalid Rayleigh parameter"),
                                  ("diffusive", "-1.0 0 0 0", "Non-numeric atom coords"),
                                  ("ccl", "1.5 0 0 0 1.5 0.5 0.5", "Invalid Bessel exponential")):
        with pytest.raises(LammpsRunError, match=message):
            oracle(d, [line.format(rstyle, args)], ["v_vx"], {"vx": "vx[1]"}, steps=2)
    ref = oracle(d, [line.format("maxwell", "1.5 0 0 0 1.5")], ["v_vx"], {"vx": "vx[1]"}, steps=2)
    assert ref["v_vx"][0] == -1.0 and 0.0 < ref["v_vx"][1] != 1.0  # left diffusively, not mirrored
    text = (Path(__file__).parents[2] / "docs" / "deviations.md").read_text()
    assert "test_stochastic_temperature_and_accommodation_out_of_range" in text


# ----------------------------------------------------------------------------- colloid R >= rc (§4.6)


@requires_lammps
def test_colloid_larger_than_the_cutoff_is_skipped_in_both():
    """§4.6 quirk, kept: the cut-off test comes before the contact test, so a colloid of radius 2
    whose centre is 1.8 from the wall (surface through it) but beyond rc = 1.5 feels nothing and
    raises nothing, in LAMMPS and in wallbatch."""
    d = scene([point([(1.8, 5, 5)], radius=2.0)],
              {"w": {"style": "colloid", "units": "box", "energy": True,
                     "xlo": {"coord": 0.0, "epsilon": 1.0, "sigma": 1.0, "cutoff": 1.5}}}, steps=3)
    res = run_one(d)
    assert res.status == "ok", res.error
    assert not np.any(res.data["wall_energy"]) and not np.any(res.data["wall_force"])
    ref = oracle(d, ["fix w all wall/colloid xlo 0.0 1.0 1.0 1.5 units box"], ["f_w", "f_w[1]"])
    assert not np.any(ref["f_w"]) and not np.any(ref["f_w[1]"])
    d["atoms"][0]["create"]["positions"] = [[1.4, 5, 5]]  # within rc: the contact error, in both
    res = run_one(d)
    assert res.status == "failed" and "Particle on or inside fix wall surface" in res.error
    with pytest.raises(LammpsRunError, match="Particle on or inside fix wall surface"):
        oracle(d, ["fix w all wall/colloid xlo 0.0 1.0 1.0 1.5 units box"], ["f_w"])


# ----------------------------------------------------------------------------- refused features


def test_features_without_a_wallbatch_counterpart_are_refused():
    """Quirk #6 (region ellipsoid surfaces): wallbatch has block, sphere and cylinder regions only.
    Quirk #25 (wall/reflect with rigid bodies, a warning in LAMMPS): wallbatch has no rigid
    bodies; a rigid fix line is refused. Quirk #15: `fld yes` is refused (tests/config/test_config.py)."""
    base = scene([point([(5, 5, 5)])], {})
    with pytest.raises(ConfigError, match="regions.e.style"):
        config_from_dict(dict(base, regions={"e": {"style": "ellipsoid", "center": [5, 5, 5], "units": "box"}}))
    with pytest.raises(ConfigError, match="'rigid': unknown or unsupported fix style"):
        config_from_dict(dict(base, walls={"r": "fix r all rigid single"}))


# ----------------------------------------------------------------------------- docs/quirks.md


def test_quirks_page_names_real_tests_and_every_section_13_quirk():
    """docs/quirks.md: every test it names is defined in the file it names, and the §13 table has
    a row for each of the 26 quirks."""
    import re
    from pathlib import Path

    root = Path(__file__).resolve().parents[2]
    text = (root / "docs" / "deviations.md").read_text()
    refs = set(re.findall(r"`(tests/[\w/]+\.py)::(\w+)`", text))
    assert len(refs) > 50
    missing = [f"{f}::{name}" for f, name in sorted(refs)
               if not (root / f).exists() or f"def {name}(" not in (root / f).read_text()]
    assert not missing, missing
    section = text.split("## Quirk by quirk")[1].split("## ")[0]
    numbers = [int(m) for m in re.findall(r"^\| (\d+) \|", section, flags=re.MULTILINE)]
    assert numbers == list(range(1, 27))


@requires_lammps
@pytest.mark.lammps
@pytest.mark.parametrize("rstyle", ["cercignanilampis", "CCL"])
def test_stochastic_rstyle_is_spelled_ccl_in_lammps_too(rstyle):
    """wall/reflect/stochastic: LAMMPS accepts only the short names diffusive, maxwell, ccl (not
    the long cercignanilampis, nor upper case); wallbatch refuses the same words, with a hint."""
    base = ["units lj", "boundary p p f", "region b block 0 5 0 5 0 5", "create_box 1 b", "mass 1 1.0",
            "create_atoms 1 single 1 1 1"]
    lammps_commands(base + ["fix 1 all wall/reflect/stochastic ccl 123 zlo EDGE 1.0 0 0 0 0.5 0.5 0.5",
                            "run 0"]).close()
    with pytest.raises(Exception, match="Illegal fix wall/reflect/stochastic"):
        lammps_commands(base + [f"fix 1 all wall/reflect/stochastic {rstyle} 123 zlo EDGE 1.0 0 0 0 0.5 0.5 0.5"])
    walls = {"w": f"fix w all wall/reflect/stochastic {rstyle} 123 zlo EDGE 1.0 0 0 0 0.5 0.5 0.5 units box"}
    with pytest.raises(ConfigError, match="diffusive, maxwell or ccl"):
        config_from_dict(scene([point([(5, 5, 5)])], walls, boundary=("p", "p", "f")))
