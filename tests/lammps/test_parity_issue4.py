"""End-to-end LAMMPS parity of issue 4: ellipsoids (fix nve/asphere, wall/ees, wall/region/ees)
and region walls (fix wall/region), through the whole pipeline.

wallbatch side: YAML text -> `config.load_config_text` -> `scene.build_case` -> the engine ->
`CaseResult.data` per sample (ellipsoid scenes run `engine.Engine([case])`, which is what
`run_cases` runs for a batch of one, to read the final quaternions and angular momenta off its
state; the other scenes go through `run_cases` and read the final x, v from a dump frame).

LAMMPS side (22Jul2025, Python module): built from the Case arrays (x, v, mass, radius, shape,
quat, angmom, all written with `repr`, which round-trips a double) in a data file (atom_style
atomic, sphere or ellipsoid; semi-axes a b c become the diameters 2a 2b 2c of the Ellipsoids
section; per-atom masses by `set atom I mass`), `fix nve` or `fix nve/asphere`, the walls written as
their LAMMPS commands, one `run`, thermo every sample with `norm no` and 17 digits.

Every scene is an ideal gas (no pair forces), so trajectories are not chaotic and every sample of
every output must agree to 1e-9 relative (absolute floor FLOOR times the series' largest
magnitude, for values that cross or sit at zero). Observed (22Jul2025): every series within
~2e-14 of its largest magnitude, except the lj1043 sphere-out wall of the lattice scene (6e-13 on
region_force, 2e-13 on the final v): summation order and libm differences, far below 1e-9. (LAMMPS's
closed-form ees torque alone loses ~4e-13 relative far from the wall: tests/styles/test_ellipsoid.py.)

Output mapping: wallbatch `ke` = LAMMPS `ke` + `c_erotate/asphere` (wallbatch's ke includes the
rotational energy); `etot` = `etotal` + erotate; `erot` = erotate/asphere; `temp`, `pe` as is;
`wall_energy[:, k]` = `f_ID` of the k-th wall fix (config order); `wall_force` = `f_ID[i]` of the
flat faces; `region_force[:, k, :]` = `f_ID[1..3]` of the k-th region fix.
"""

from __future__ import annotations

import json
import os
import tempfile
from dataclasses import dataclass

import numpy as np
import pytest
from lammps_oracle import _load_lammps, requires_lammps

from wallbatch.config.models import load_config_text
from wallbatch.engine.engine import CaseResult, Engine, run_cases
from wallbatch.engine.region_walls import lammps_region_colloid
from wallbatch.lammps.log import last_thermo
from wallbatch.scene.case import Case
from wallbatch.scene.build import build_case

pytestmark = requires_lammps

RTOL = 1e-9
FLOOR = 1e-12  # absolute floor, relative to the largest |value| of the series


# ----------------------------------------------------------------------------- LAMMPS side


@dataclass
class LammpsResult:
    """Thermo columns per sample, and the final per-atom state in atom order (id - 1)."""

    thermo: dict[str, np.ndarray]
    final: dict[str, np.ndarray]  # x, v (and quat, angmom for ellipsoids)


def _r(value: float) -> str:
    """A float as text that LAMMPS reads back to the identical double."""
    value = float(value)
    assert np.isfinite(value)
    return repr(value)


def _atom_style(case: Case) -> str:
    if case.shape is not None:
        return "ellipsoid"
    return "sphere" if np.any(case.radius > 0) else "atomic"


def _data_file(case: Case, style: str) -> tuple[str, list[str]]:
    """LAMMPS data-file text for the case's atoms, and the mass commands to issue after read_data.

    atomic: one type per distinct mass (`mass T m`); sphere/ellipsoid: one type, per-atom mass
    (`set atom I mass m`). Ellipsoids: the Ellipsoids section takes diameters (2a 2b 2c) and the
    quaternion (w x y z); Velocities take v and, for ellipsoids, the angular momentum."""
    n = case.natoms
    lines = ["wallbatch issue-4 parity", "", f"{n} atoms"]
    if style == "ellipsoid":
        lines.append(f"{n} ellipsoids")
    if style == "atomic":
        masses, types = np.unique(case.mass, return_inverse=True)
        types = types + 1
        mass_cmds = [f"mass {t + 1} {_r(m)}" for t, m in enumerate(masses)]
    else:
        masses, types = case.mass[:1], np.ones(n, int)
        mass_cmds = [f"set atom {i + 1} mass {_r(m)}" for i, m in enumerate(case.mass)]
    lines.append(f"{len(masses)} atom types")
    for d, name in enumerate("xyz"):
        lines.append(f"{_r(case.box_lo[d])} {_r(case.box_hi[d])} {name}lo {name}hi")
    lines += ["", f"Atoms # {style}", ""]
    for i in range(n):
        xyz = " ".join(_r(c) for c in case.x[i])
        if style == "atomic":
            lines.append(f"{i + 1} {types[i]} {xyz}")
        elif style == "sphere":
            lines.append(f"{i + 1} 1 {_r(2.0 * case.radius[i])} 1.0 {xyz}")
        else:
            lines.append(f"{i + 1} 1 1 1.0 {xyz}")
    if style == "ellipsoid":
        lines += ["", "Ellipsoids", ""]
        lines += [f"{i + 1} " + " ".join(_r(2.0 * s) for s in case.shape[i]) + " "
                  + " ".join(_r(c) for c in case.quat[i]) for i in range(n)]
    lines += ["", "Velocities", ""]
    for i in range(n):
        extra = case.angmom[i] if style == "ellipsoid" else np.zeros(3) if style == "sphere" else ()
        lines.append(f"{i + 1} " + " ".join(_r(c) for c in (*case.v[i], *extra)))
    return "\n".join(lines) + "\n", mass_cmds


def run_lammps_case(case: Case, commands: list[str], outputs: list[str], lattice: str | None = None,
                    steps: int | None = None) -> LammpsResult:
    """Run the case's atoms in LAMMPS with `commands` (regions, wall fixes, fix_modify lines, in
    order) after the integrator (fix nve, or nve/asphere with ellipsoids), `steps` steps (default
    `case.steps`), thermo every `case.thermo`; return the thermo `outputs` per sample and the
    final state."""
    steps = case.steps if steps is None else steps
    lammps = _load_lammps()
    from lammps import LMP_STYLE_ATOM, LMP_TYPE_ARRAY

    style = _atom_style(case)
    text, mass_cmds = _data_file(case, style)
    columns = ["step", *outputs]
    ellipsoid = style == "ellipsoid"
    with tempfile.TemporaryDirectory(prefix="wb_issue4_") as tmp:
        data_path = os.path.join(tmp, "atoms.data")
        log_path = os.path.join(tmp, "log.lammps")
        with open(data_path, "w") as fh:
            fh.write(text)
        lmp = lammps.lammps(cmdargs=["-log", log_path, "-screen", "none", "-nocite"])
        try:
            head = [f"units {case.units.name}", f"atom_style {style}", "atom_modify map array",
                    "boundary " + " ".join("p" if p else "f" for p in case.periodic)]
            if lattice is not None:
                head.append(f"lattice {lattice}")
            head += [f"read_data {data_path}", *mass_cmds, "neigh_modify every 1 delay 0 check no",
                     f"timestep {_r(case.dt)}", f"fix wb_int all {'nve/asphere' if ellipsoid else 'nve'}"]
            if ellipsoid:
                head += ["compute wb_erot all erotate/asphere",
                         "compute wb_q all property/atom quatw quati quatj quatk"]
            tail = ["thermo_style custom " + " ".join(columns),
                    'thermo_modify norm no flush yes format float "%.17g"',
                    f"thermo {int(case.thermo)}", f"run {int(steps)}"]
            for line in head + commands + tail:
                lmp.command(line)
            n = case.natoms
            order = np.argsort(np.array(lmp.numpy.extract_atom("id")[:n]))
            final = {k: np.array(lmp.numpy.extract_atom(k)[:n, :3], dtype=np.float64)[order] for k in ("x", "v")}
            if ellipsoid:
                final["angmom"] = np.array(lmp.numpy.extract_atom("angmom")[:n, :3], dtype=np.float64)[order]
                quat = lmp.numpy.extract_compute("wb_q", LMP_STYLE_ATOM, LMP_TYPE_ARRAY)[:n]
                final["quat"] = np.array(quat, dtype=np.float64)[order]
        finally:
            lmp.close()
        with open(log_path, encoding="utf-8", errors="replace") as fh:
            table = last_thermo(fh.read(), len(columns))
    expected = list(range(0, steps + 1, case.thermo))
    assert table[:, 0].tolist() == expected, f"LAMMPS thermo steps {table[:, 0].tolist()}"
    return LammpsResult({c: table[:, j].copy() for j, c in enumerate(columns)}, final)


# ----------------------------------------------------------------------------- wallbatch side


def case_from_yaml(text: str) -> Case:
    return build_case(load_config_text(text, "<issue4>"))


def run_wallbatch(case: Case, engine: bool = False) -> tuple[CaseResult, dict[str, np.ndarray]]:
    """The case's samples and final state (x, v; with `engine`, also quat and angmom)."""
    if engine:
        eng = Engine([case])
        res = eng.run()[0]
        s = eng.state
        final = {"x": s.x[0].copy(), "v": s.v[0].copy()}
        if s.quat is not None:
            final.update(quat=s.quat[0].copy(), angmom=s.angmom[0].copy())
    else:
        res = run_cases([case])[0]
        final = {"x": res.frames["x"][-1], "v": res.frames["v"][-1]}
        assert res.frames["time"][-1] == pytest.approx(case.steps * case.dt, rel=1e-12)
    assert res.status == "ok", res.error
    return res, final


# ----------------------------------------------------------------------------- comparison


def assert_series(name: str, got, want, steps, rtol: float = RTOL, floor: float = FLOOR) -> None:
    """Every sample within rtol (absolute floor: floor * max|want|); on failure, say where."""
    got, want = np.asarray(got, float), np.asarray(want, float)
    assert got.shape == want.shape, f"{name}: shape {got.shape} vs LAMMPS {want.shape}"
    assert np.all(np.isfinite(want)), f"{name}: LAMMPS gave non-finite values {want}"
    atol = floor * float(np.max(np.abs(want))) if want.size else 0.0
    bad = ~(np.abs(got - want) <= atol + rtol * np.abs(want))
    if bad.any():
        i = int(np.argmax(bad))
        with np.errstate(divide="ignore", invalid="ignore"):
            rel = np.abs(got - want) / np.abs(want)
        raise AssertionError(f"{name}: first mismatch at step {int(steps[i])}: wallbatch {got[i]!r} vs "
                             f"LAMMPS {want[i]!r} (rel {rel[i]:.3g}); {int(bad.sum())}/{bad.size} samples off")


def assert_final(got: dict[str, np.ndarray], want: dict[str, np.ndarray]) -> None:
    """Final per-atom arrays within RTOL (absolute floor FLOOR * max|value| of the array)."""
    for key, ref in want.items():
        val = got[key]
        if key == "quat":  # q and -q are the same rotation; neither code flips sign, but be safe
            val = np.where(np.sum(val * ref, axis=1, keepdims=True) < 0, -val, val)
        atol = FLOOR * float(np.max(np.abs(ref)))
        np.testing.assert_allclose(val, ref, rtol=RTOL, atol=atol, err_msg=f"final {key}")


def compare_samples(res: CaseResult, ref: LammpsResult, pairs: dict[str, np.ndarray]) -> None:
    """`pairs`: label -> LAMMPS series, the label naming the wallbatch series (see `wb_series`)."""
    steps = ref.thermo["step"]
    np.testing.assert_array_equal(res.data["step"], steps)
    for label, want in pairs.items():
        assert_series(label, wb_series(res, label), want, steps)


def wb_series(res: CaseResult, label: str) -> np.ndarray:
    """`name`, or `name[i]` / `name[i,j]` indexing the trailing axes of a data array."""
    if "[" not in label:
        return res.data[label]
    name, idx = label[:-1].split("[")
    return res.data[name][(slice(None), *(int(k) for k in idx.split(",")))]


def rng_rows(rng: np.random.Generator, n: int, scale: float) -> str:
    """n random normal 3-vectors (std `scale`) as a YAML flow list: 12 decimals, no exponent
    (the test checks that the case got exactly the numbers json reads from the same text)."""
    a = np.round(rng.normal(0.0, scale, (n, 3)), 12)
    return "[" + ", ".join("[" + ", ".join(f"{c:.12f}" for c in row) + "]" for row in a) + "]"


def positions_yaml(x: np.ndarray) -> str:
    """(N, 3) positions as a YAML flow list of round-trip (repr) numbers."""
    text = "[" + ", ".join("[" + ", ".join(repr(float(c)) for c in row) + "]" for row in x) + "]"
    assert "e" not in text  # YAML 1.1 would read 1e-05 as text
    return text


# ----------------------------------------------------------------------------- 1. ellipsoids, flat ees


# the zhi face: EDGE in box units, or a wall moving in, in lattice units (sc 0.9: spacing 1.0357)
EES_TOP = {
    "static": ("box", "EDGE", "", None),
    "moving_lattice": ("lattice", "v_top",
                       'lattice: {style: sc, scale: 0.9}\nvariables: {top: "9.5 - ramp(0.0, 1.0)"}', "sc 0.9"),
}


def ees_slit_yaml(top: str = "static") -> tuple[str, np.ndarray]:
    units, coord, extra, _ = EES_TOP[top]
    rng = np.random.default_rng(4001)
    angmom = rng_rows(rng, 20, 0.4)
    text = f"""
name: ees-slit
units: lj
seed: 4001
box: {{lo: [0, 0, 0], hi: [8, 8, 10], boundary: [p, p, f]}}
regions:
  slab: {{style: block, lo: [0, 0, 2.2], hi: [8, 8, 7.8], units: box}}
atoms:
  - group: rods
    create: {{random: {{count: 20, region: slab}}}}
    mass: 1.5
    shape: [0.8, 0.4, 0.3]
    orientation: random
    angmom: {{values: {angmom}}}
    velocity: {{temperature: 1.2}}
  - group: discs
    create: {{random: {{count: 12, region: slab}}}}
    mass: 0.75
    shape: [0.6, 0.55, 0.25]
    orientation: [0.9, 0.1, 0.3, 0.2]
    angmom: {{values: [0.2, -0.1, 0.3]}}
    velocity: {{temperature: 1.2}}
walls:
  ees:
    style: ees
    units: {units}
    energy: true
    zlo: [EDGE, 1.5, 1.0, 3.0]
    zhi: {{coord: {coord}, epsilon: 1.5, sigma: 1.0, cutoff: 3.0}}
{extra}
run: {{steps: 500, thermo: 50}}
output: {{thermo: [step, time, dt, temp, ke, pe, etot, erot]}}
"""
    return text, np.array(json.loads(angmom))


ELL_OUTPUTS = ["ke", "c_wb_erot", "pe", "etotal", "temp"]


def ellipsoid_pairs(ref: LammpsResult) -> dict[str, np.ndarray]:
    t = ref.thermo
    return {"ke": t["ke"] + t["c_wb_erot"], "erot": t["c_wb_erot"], "pe": t["pe"],
            "etot": t["etotal"] + t["c_wb_erot"], "temp": t["temp"]}


@pytest.mark.parametrize("top", list(EES_TOP))
def test_ellipsoids_between_flat_ees_walls_match_lammps(top):
    """32 ellipsoids (two shapes and masses; random and fixed orientations; per-atom and shared
    angular momenta; T = 1.2) between wall/ees zlo/zhi (zlo EDGE; zhi EDGE, or moving in from
    9.5 to 8.5 lattice spacings; energy on), x y periodic, 500 steps of nve/asphere: ke
    (+erotate), erot, pe, etot, temp, f_ees, f_ees[1], f_ees[2] every 50 steps; final x, v,
    quat, angmom."""
    units, coord, _, lattice = EES_TOP[top]
    text, angmom = ees_slit_yaml(top)
    case = case_from_yaml(text)
    np.testing.assert_array_equal(case.angmom[:20], angmom)  # the YAML numbers reached the case
    assert case.shape.shape == (32, 3) and case.quat.shape == (32, 4)
    res, final = run_wallbatch(case, engine=True)
    commands = [f"fix ees all wall/ees zlo EDGE 1.5 1.0 3.0 zhi {coord} 1.5 1.0 3.0 units {units}",
                "fix_modify ees energy yes"]
    if lattice is not None:
        commands.insert(0, 'variable top equal "9.5 - ramp(0.0, 1.0)"')
    ref = run_lammps_case(case, commands, ELL_OUTPUTS + ["f_ees", "f_ees[1]", "f_ees[2]"], lattice=lattice)
    pairs = ellipsoid_pairs(ref)
    pairs.update({"wall_energy[0]": ref.thermo["f_ees"], "wall_force[0]": ref.thermo["f_ees[1]"],
                  "wall_force[1]": ref.thermo["f_ees[2]"]})
    compare_samples(res, ref, pairs)
    assert_final(final, ref.final)
    # not vacuous: both faces act (attraction and the repulsive core), the walls torque the ellipsoids
    wf = res.data["wall_force"]  # force on the wall: zlo > 0 when attracting, < 0 when repelling
    assert np.any(wf[:, 0] > 0) and np.any(wf[:, 0] < 0) and np.any(wf[:, 1] < 0) and np.any(wf[:, 1] > 0)
    assert np.max(np.abs(final["angmom"] - case.angmom)) > 0.05
    assert np.ptp(res.data["erot"]) > 0.05
    np.testing.assert_allclose(res.data["pe"], res.data["wall_energy"][:, 0], rtol=1e-15)


# ----------------------------------------------------------------------------- 2. region walls


def gas_positions(rng: np.random.Generator, n: int, lo, hi, keep) -> np.ndarray:
    """n points uniform in the box [lo, hi] that satisfy `keep(points) -> bool mask` (rejection)."""
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    out = np.zeros((0, 3))
    while len(out) < n:
        p = lo + rng.random((4 * n, 3)) * (hi - lo)
        out = np.concatenate([out, p[keep(p)]])
    return out[:n]


def region_scene(seed: int, n: int, box: float, lo, hi, keep, regions: str, walls: str, boundary: str = "f, f, f",
                 lattice: str = "", temperature: float = 1.0) -> str:
    """YAML of a point-atom ideal gas (explicit positions, thermal velocities) with region walls."""
    x = gas_positions(np.random.default_rng(seed), n, lo, hi, keep)
    return f"""
name: region-parity
units: lj
seed: {seed}
box: {{lo: [0, 0, 0], hi: [{box}, {box}, {box}], boundary: [{boundary}]}}
{lattice}
regions:
{regions}
atoms:
  - group: gas
    create: {{positions: {positions_yaml(x)}}}
    mass: 1.3
    velocity: {{temperature: {temperature}}}
walls:
{walls}
run: {{steps: 500, thermo: 50}}
output: {{thermo: [step, time, dt, temp, ke, pe, etot], dump: {{every: 500, fields: [x, v]}}}}
"""


POINT_OUTPUTS = ["ke", "pe", "etotal", "temp"]


def region_pairs(ref: LammpsResult, fix_ids: list[str]) -> dict[str, np.ndarray]:
    """wallbatch label -> LAMMPS series for point-atom scenes with region fixes (config order)."""
    t = ref.thermo
    pairs = {"ke": t["ke"], "pe": t["pe"], "etot": t["etotal"], "temp": t["temp"]}
    for k, fid in enumerate(fix_ids):
        pairs[f"wall_energy[{k}]"] = t[f"f_{fid}"]
        for d in range(3):
            pairs[f"region_force[{k},{d}]"] = t[f"f_{fid}[{d + 1}]"]
    return pairs


def region_outputs(fix_ids: list[str]) -> list[str]:
    return POINT_OUTPUTS + [f"f_{fid}{s}" for fid in fix_ids for s in ("", "[1]", "[2]", "[3]")]


def check_region_scene(text: str, commands: list[str], fix_ids: list[str], lattice: str | None = None
                       ) -> tuple[CaseResult, LammpsResult]:
    case = case_from_yaml(text)
    res, final = run_wallbatch(case)
    ref = run_lammps_case(case, commands, region_outputs(fix_ids), lattice=lattice)
    assert res.data["wall_energy"].shape == (11, len(fix_ids))
    assert res.data["region_force"].shape == (11, len(fix_ids), 3)
    compare_samples(res, ref, region_pairs(ref, fix_ids))
    assert_final(final, ref.final)
    for k, fid in enumerate(fix_ids):  # every fix acts at some sample (no vacuous parity)
        assert np.any(res.data["region_force"][:, k] != 0.0), fid
    return res, ref


def _rho_z(p: np.ndarray, c1: float, c2: float) -> np.ndarray:
    return np.hypot(p[:, 0] - c1, p[:, 1] - c2)


def test_block_in_lj93_and_cylinder_out_harmonic_match_lammps():
    """40 atoms in a block (side in, lj93, energy on) around a z cylinder (side out, harmonic,
    energy on), box units, fixed box: wall_energy and region_force of both fixes, pe, ke, etot,
    temp every 50 of 500 steps; final x, v."""
    regions = """  cage: {style: block, lo: [1, 1, 1], hi: [11, 11, 11], units: box}
  post: {style: cylinder, axis: z, center: [6, 6], radius: 1.5, lo: 0, hi: 12, side: out, units: box}"""
    walls = """  cage: {style: region, region: cage, potential: lj93, epsilon: 1.0, sigma: 1.0, cutoff: 2.5, energy: true}
  post: {style: region, region: post, potential: harmonic, epsilon: 20.0, cutoff: 1.0, energy: true}"""
    text = region_scene(41, 40, 12, (2.2, 2.2, 2.2), (9.8, 9.8, 9.8), lambda p: _rho_z(p, 6, 6) > 2.7,
                        regions, walls)
    res, _ = check_region_scene(text, [
        "region cage block 1.0 11.0 1.0 11.0 1.0 11.0 side in units box",
        "region post cylinder z 6.0 6.0 1.5 0.0 12.0 side out units box",
        "fix cage all wall/region cage lj93 1.0 1.0 2.5", "fix_modify cage energy yes",
        "fix post all wall/region post harmonic 20.0 1.0 1.0", "fix_modify post energy yes",
    ], ["cage", "post"])
    np.testing.assert_allclose(res.data["pe"], res.data["wall_energy"].sum(axis=1), rtol=1e-14, atol=1e-14)


def test_sphere_in_morse_cube_out_and_a_flat_wall_match_lammps():
    """30 atoms in a sphere (side in, morse D0 1.0 alpha 2.0 r0 1.0 rc 2.5, energy on) around a
    cube (block side out: faces, edges and corners, lj126, energy on), over a flat lj93 zlo wall
    at z = 1.8 cutting the sphere's bottom cap. Config order ball, floor, cube: wall_energy holds
    the three fixes in that order (flat and region fixes interleaved), region_force the two
    region fixes, wall_force the flat face."""
    regions = """  ball: {style: sphere, center: [6, 6, 6], radius: 5.0, units: box}
  cube: {style: block, lo: [5.2, 5.2, 5.2], hi: [6.8, 6.8, 6.8], side: out, units: box}"""
    walls = """  ball: {style: region, region: ball, potential: morse, D0: 1.0, alpha: 2.0, r0: 1.0, cutoff: 2.5, energy: true}
  floor: {style: lj93, units: box, energy: true, zlo: [1.8, 1.0, 1.0, 2.5]}
  cube: {style: region, region: cube, potential: lj126, epsilon: 1.0, sigma: 1.0, cutoff: 2.0, energy: true}"""

    def keep(p):
        outside_cube = np.linalg.norm(p - np.clip(p, 5.2, 6.8), axis=1) > 1.2
        return (np.linalg.norm(p - 6.0, axis=1) < 3.6) & outside_cube & (p[:, 2] > 3.0)

    text = region_scene(42, 30, 12, (2.0, 2.0, 2.0), (10.0, 10.0, 10.0), keep, regions, walls, temperature=1.5)
    case = case_from_yaml(text)
    res, final = run_wallbatch(case)
    ref = run_lammps_case(case, [
        "region ball sphere 6.0 6.0 6.0 5.0 side in units box",
        "region cube block 5.2 6.8 5.2 6.8 5.2 6.8 side out units box",
        "fix ball all wall/region ball morse 1.0 2.0 1.0 2.5", "fix_modify ball energy yes",
        "fix floor all wall/lj93 zlo 1.8 1.0 1.0 2.5 units box", "fix_modify floor energy yes",
        "fix cube all wall/region cube lj126 1.0 1.0 2.0", "fix_modify cube energy yes",
    ], region_outputs(["ball", "cube"]) + ["f_floor", "f_floor[1]"])
    assert res.data["wall_energy"].shape == (11, 3) and res.data["region_force"].shape == (11, 2, 3)
    pairs = region_pairs(ref, ["ball", "cube"])
    pairs["wall_energy[2]"] = pairs.pop("wall_energy[1]")  # cube is the third fix in config order
    pairs.update({"wall_energy[1]": ref.thermo["f_floor"], "wall_force[0]": ref.thermo["f_floor[1]"]})
    compare_samples(res, ref, pairs)
    assert_final(final, ref.final)
    assert np.all(np.any(res.data["region_force"] != 0.0, axis=(0, 2)))
    assert np.any(res.data["wall_force"] != 0.0)
    np.testing.assert_allclose(res.data["pe"], res.data["wall_energy"].sum(axis=1), rtol=1e-14, atol=1e-14)


def test_lattice_unit_regions_match_lammps():
    """lattice fcc 0.8442 (spacing 1.6796), regions in lattice units (the default): atoms inside
    a z cylinder (side in, curved wall and both caps, lj126) around a sphere (side out, lj1043);
    the lj1043 fix's energy stays out of pe (energy: false, as LAMMPS without fix_modify)."""
    a = (4 / 0.8442) ** (1 / 3)
    regions = """  can: {style: cylinder, axis: z, center: [4.75, 4.75], radius: 4.0, lo: 0.75, hi: 8.75}
  ball: {style: sphere, center: [4.75, 4.75, 4.75], radius: 1.0, side: out}"""
    walls = """  can: {style: region, region: can, potential: lj126, epsilon: 1.0, sigma: 1.0, cutoff: 2.5, energy: true}
  ball: {style: region, region: ball, potential: lj1043, epsilon: 1.5, sigma: 1.0, cutoff: 2.0}"""
    c = 4.75 * a

    def keep(p):
        rho = _rho_z(p, c, c)
        return (rho < 4.0 * a - 1.2) & (np.linalg.norm(p - c, axis=1) > 1.0 * a + 1.2)

    text = region_scene(43, 40, 16, (1.0, 1.0, 0.75 * a + 1.2), (15.0, 15.0, 8.75 * a - 1.2), keep, regions,
                        walls, lattice="lattice: {style: fcc, scale: 0.8442}")
    res, _ = check_region_scene(text, [
        "region can cylinder z 4.75 4.75 4.0 0.75 8.75 side in",
        "region ball sphere 4.75 4.75 4.75 1.0 side out",
        "fix can all wall/region can lj126 1.0 1.0 2.5", "fix_modify can energy yes",
        "fix ball all wall/region ball lj1043 1.5 1.0 2.0",
    ], ["can", "ball"], lattice="fcc 0.8442")
    np.testing.assert_allclose(res.data["pe"], res.data["wall_energy"][:, 0], rtol=1e-14, atol=1e-14)
    assert np.any(np.abs(res.data["wall_energy"][:, 1]) > 1e-3)
    # the caps act too: some sample has a z force on the cylinder
    assert np.any(np.abs(res.data["region_force"][:, 0, 2]) > 1e-3)


# ----------------------------------------------------------------------------- 3. region/ees


# name -> (boundary, YAML of the wall region, YAML of the creation region, LAMMPS region command,
#          distance of a centre (F, N, 3) to the wall region's surface)
EES_REGIONS = {
    "sphere_in": (
        "f, f, f",
        "{style: sphere, center: [7, 7, 7], radius: 6.0, units: box}",
        "{style: sphere, center: [7, 7, 7], radius: 3.6, units: box}",
        "region wall sphere 7.0 7.0 7.0 6.0 side in units box",
        lambda x: 6.0 - np.linalg.norm(x - 7.0, axis=-1),
    ),
    "block_in": (
        "f, f, f",
        "{style: block, lo: [1, 1, 1], hi: [13, 13, 13], units: box}",
        "{style: block, lo: [3.5, 3.5, 3.5], hi: [10.5, 10.5, 10.5], units: box}",
        "region wall block 1.0 13.0 1.0 13.0 1.0 13.0 side in units box",
        lambda x: np.minimum(x - 1.0, 13.0 - x).min(axis=-1),
    ),
    "cylinder_out": (  # a post along x through the periodic box: radial contacts only (in y z)
        "p, p, p",
        "{style: cylinder, axis: x, center: [7, 7], radius: 2.0, lo: -1, hi: 15, side: out, units: box}",
        "{style: cylinder, axis: x, center: [7, 7], radius: 3.3, lo: -1, hi: 15, side: out, units: box}",
        "region wall cylinder x 7.0 7.0 2.0 -1.0 15.0 side out units box",
        lambda x: np.hypot(x[..., 1] - 7.0, x[..., 2] - 7.0) - 2.0,
    ),
}


@pytest.mark.parametrize("geometry", list(EES_REGIONS))
def test_ellipsoids_with_region_ees_match_lammps(geometry):
    """30 ellipsoids (semi-axes 0.5 0.35 0.25, random orientations and angular momenta, T 1.0)
    with wall/region/ees (eps 2, sigma 1, rc 3, energy on) on a sphere (side in), a block (side
    in) or an x cylinder (side out, diagonal normals in y z), 300 steps of nve/asphere: ke
    (+erotate), erot, pe, etot, temp, f_ID, f_ID[1..3] every 50 steps; final x, v, quat, angmom.

    Gentle on purpose: every contact distance stays above the largest semi-axis (checked at every
    step from a dump), so neither LAMMPS's per-axis sigma_n "too close" test (quirk #14) nor
    wallbatch's true-sigma_n test can fire, and LAMMPS never reaches its NaN branch; the two codes
    then compute the same physics. Atoms still enter the repulsive range: the ees force changes
    sign at r = 0.95 .. 1.15 for sigma_n = 0.25 .. 0.5 (eps 2, sigma 1)."""
    boundary, wall_region, core_region, lammps_region, distance = EES_REGIONS[geometry]
    rng = np.random.default_rng(4003)
    angmom = rng_rows(rng, 30, 0.15)
    text = f"""
name: region-ees
units: lj
seed: 4003
box: {{lo: [0, 0, 0], hi: [14, 14, 14], boundary: [{boundary}]}}
regions:
  wall: {wall_region}
  core: {core_region}
atoms:
  - group: ell
    create: {{random: {{count: 30, region: core}}}}
    mass: 1.0
    shape: [0.5, 0.35, 0.25]
    orientation: random
    angmom: {{values: {angmom}}}
    velocity: {{temperature: 1.0}}
walls:
  shell: {{style: region/ees, region: wall, epsilon: 2.0, sigma: 1.0, cutoff: 3.0, energy: true}}
run: {{steps: 300, thermo: 50}}
output: {{thermo: [step, time, dt, temp, ke, pe, etot, erot], dump: {{every: 1, fields: [x]}}}}
"""
    case = case_from_yaml(text)
    res, final = run_wallbatch(case, engine=True)
    ref = run_lammps_case(case, [lammps_region, "fix shell all wall/region/ees wall 2.0 1.0 3.0",
                                 "fix_modify shell energy yes"],
                          ELL_OUTPUTS + ["f_shell", "f_shell[1]", "f_shell[2]", "f_shell[3]"])
    pairs = ellipsoid_pairs(ref)
    pairs["wall_energy[0]"] = ref.thermo["f_shell"]
    pairs.update({f"region_force[0,{d}]": ref.thermo[f"f_shell[{d + 1}]"] for d in range(3)})
    compare_samples(res, ref, pairs)
    assert_final(final, ref.final)
    assert res.frames["x"].shape == (301, 30, 3)  # every step
    gap = distance(res.frames["x"])
    assert gap.min() > 0.5 * 1.2, gap.min()  # > the largest semi-axis, with margin
    assert gap.min() < 0.9, gap.min()  # yet inside the repulsive range
    assert np.max(np.abs(final["angmom"] - case.angmom)) > 0.02  # the wall torqued them


# ----------------------------------------------------------------------------- 4. colloid on a region


def test_region_colloid_uses_the_wall_colloid_physics():
    """wallbatch's wall/region colloid is the fix wall/colloid physics (decisions table, quirk #1).

    A block region (side in) whose x and y faces lie 50 beyond the periodic box, so only its z
    faces act, against LAMMPS fix wall/colloid zlo 0 / zhi 10 (the same physics): 24 spheres of
    radius 0.5, eps 5, sigma 1, rc 3.5, energy on, 500 steps: wall_energy = f_w, region_force z
    = f_w[1] + f_w[2] (x, y exactly 0), pe, ke, etot, temp every 50 steps and final x, v to 1e-9.

    LAMMPS's own wall/region colloid on the same region differs (pinned at step 0): its energy
    is `regions.lammps_region_colloid` summed over the contacts (not wallbatch's), and its force
    vector is exactly the negative of wallbatch's."""
    rng = np.random.default_rng(4004)
    x = np.column_stack([rng.uniform(0, 10, (24, 2)), rng.uniform(1.8, 8.2, 24)])
    text = f"""
name: region-colloid
units: lj
seed: 4004
box: {{lo: [0, 0, 0], hi: [10, 10, 10], boundary: [p, p, f]}}
regions:
  slab: {{style: block, lo: [-50, -50, 0], hi: [60, 60, 10], units: box}}
atoms:
  - group: colloids
    create: {{positions: {positions_yaml(x)}}}
    mass: 2.0
    radius: 0.5
    velocity: {{temperature: 1.0}}
walls:
  slab: {{style: region, region: slab, potential: colloid, epsilon: 5.0, sigma: 1.0, cutoff: 3.5, energy: true}}
run: {{steps: 500, thermo: 50}}
output: {{thermo: [step, time, dt, temp, ke, pe, etot], dump: {{every: 500, fields: [x, v]}}}}
"""
    case = case_from_yaml(text)
    res, final = run_wallbatch(case)
    ref = run_lammps_case(case, ["fix w all wall/colloid zlo 0.0 5.0 1.0 3.5 zhi 10.0 5.0 1.0 3.5 units box",
                                 "fix_modify w energy yes"], POINT_OUTPUTS + ["f_w", "f_w[1]", "f_w[2]"])
    t = ref.thermo
    compare_samples(res, ref, {"ke": t["ke"], "pe": t["pe"], "etot": t["etotal"], "temp": t["temp"],
                               "wall_energy[0]": t["f_w"], "region_force[0,2]": t["f_w[1]"] + t["f_w[2]"]})
    np.testing.assert_array_equal(res.data["region_force"][:, 0, :2], 0.0)
    assert_final(final, ref.final)
    assert np.all(t["f_w[1]"] != 0.0) and np.all(t["f_w[2]"] != 0.0)
    assert np.any(t["f_w[1]"] < 0) and np.any(t["f_w[1]"] > 0)  # attractive and repulsive samples

    # LAMMPS's wall/region colloid (quirk #1) at step 0 on the same atoms and region
    quirk = run_lammps_case(case, ["region slab block -50.0 60.0 -50.0 60.0 0.0 10.0 side in units box",
                                   "fix rw all wall/region slab colloid 5.0 1.0 3.5"],
                            ["f_rw", "f_rw[1]", "f_rw[2]", "f_rw[3]"], steps=0).thermo
    z = case.x[:, 2]
    r = np.concatenate([z[z < 3.5], 10.0 - z[10.0 - z < 3.5]])  # contact distances to the z faces
    params = {"epsilon": 5.0, "sigma": 1.0, "radius": 0.5, "cutoff": 3.5}
    e_quirk = lammps_region_colloid(r, {k: np.full(r.size, v) for k, v in params.items()})[0].sum()
    assert quirk["f_rw"][0] == pytest.approx(e_quirk, rel=1e-12)
    e_wb = res.data["wall_energy"][0, 0]
    assert abs(quirk["f_rw"][0] - e_wb) > 0.1 * abs(e_wb)  # the energies really differ
    np.testing.assert_allclose([quirk[f"f_rw[{d}]"][0] for d in (1, 2, 3)], -res.data["region_force"][0, 0],
                               rtol=1e-12, atol=1e-14 * np.abs(res.data["region_force"][0, 0]).max())
