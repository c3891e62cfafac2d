"""Trajectory parity of wallbatch against LAMMPS 22Jul2025 (the oracle of tests/lammps_oracle.py).

Every scene is an ideal gas (no pair forces), so trajectories are not chaotic: both codes start
from bit-identical positions, velocities and masses, and every thermo sample of ke, pe, etot,
time, dt, the wall fixes' global scalars (`wall_energy`, LAMMPS `f_ID`) and global vectors
(`wall_force`, LAMMPS `f_ID[i]`) must agree to 1e-9 relative (with an absolute floor of 1e-12
times the series' largest magnitude, for values that cross or sit at zero).

Each scene is written once, in a neutral form (`Spec` below), and turned into both a wallbatch
config dict and a LAMMPS `Scene`. The LAMMPS side lists the fixes in the order wallbatch's
decisions table assumes: walls first, `fix dt/reset` last (physics.md, decisions table).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pytest

from lammps_oracle import LammpsRunError, Scene, requires_lammps, run_lammps
from wallbatch.config.models import config_from_dict
from wallbatch.batch.runner import run_config

pytestmark = requires_lammps

RTOL = 1e-9
FLOOR = 1e-12  # absolute floor, relative to the largest |value| of the series


# ----------------------------------------------------------------------------- scene spec


@dataclass
class Atoms:
    """One atom group: explicit per-atom state shared bit-for-bit by both codes."""

    name: str
    x: np.ndarray
    v: np.ndarray
    mass: float
    radius: float | None = None


@dataclass
class Wall:
    """One wall fix. `faces` are (face, coord, *params) in the LAMMPS argument order; coord and
    params are numbers or strings (`EDGE`, `v_name`) written identically to both codes."""

    fix_id: str
    style: str  # lj93 lj126 lj1043 colloid harmonic morse reflect
    faces: list[tuple]
    group: str = "all"
    units: str = "box"
    energy: bool = False
    frame: str | None = None  # reflect only (wallbatch); LAMMPS always reflects in the lab frame

    @property
    def soft(self) -> bool:
        return self.style != "reflect"

    def fix_line(self) -> str:
        args = " ".join(" ".join(_txt(t) for t in face) for face in self.faces)
        return f"fix {self.fix_id} {self.group} wall/{self.style} {args} units {self.units}"


@dataclass
class DtReset:
    every: int
    xmax: float
    tmin: float | None = None
    tmax: float | None = None
    emax: float | None = None
    units: str = "box"


@dataclass
class Spec:
    units: str
    lo: tuple
    hi: tuple
    boundary: tuple
    atoms: list[Atoms]
    walls: list[Wall]
    steps: int
    thermo: int
    timestep: float | None = None
    variables: dict[str, str] = field(default_factory=dict)
    lattice: tuple[str, float] | None = None
    dt_reset: DtReset | None = None

    # -- wallbatch side ------------------------------------------------------------------

    def config(self, fix_lines: bool = False) -> dict:
        """The wallbatch config dict; with `fix_lines`, every wall is written as the LAMMPS fix
        line of `scene()` (`{fix: "...", energy: ...}`), through wallbatch's fix-line parser."""
        d: dict = {
            "name": "parity",
            "units": self.units,
            "box": {"lo": list(self.lo), "hi": list(self.hi), "boundary": list(self.boundary)},
            "atoms": [],
            "walls": {},
            "run": {"steps": self.steps, "thermo": self.thermo},
            "output": {"thermo": ["step", "time", "dt", "temp", "ke", "pe", "etot"]},
        }
        if self.timestep is not None:
            d["timestep"] = self.timestep
        if self.variables:
            d["variables"] = dict(self.variables)
        if self.lattice is not None:
            d["lattice"] = {"style": self.lattice[0], "scale": self.lattice[1]}
        for a in self.atoms:
            g = {
                "group": a.name,
                "create": {"positions": a.x.tolist()},
                "mass": a.mass,
                "velocity": {"values": a.v.tolist()},
            }
            if a.radius is not None:
                g["radius"] = a.radius
            d["atoms"].append(g)
        for w in self.walls:
            if fix_lines:
                entry = {"fix": w.fix_line()}
                if w.soft:
                    entry["energy"] = w.energy
                d["walls"][w.fix_id] = entry
                continue
            entry: dict = {"style": w.style, "group": w.group, "units": w.units}
            if w.soft:
                entry["energy"] = w.energy
                keys = ("coord", "D0", "alpha", "r0", "cutoff") if w.style == "morse" else (
                    "coord", "epsilon", "sigma", "cutoff")
                for face, *args in w.faces:
                    entry[face] = dict(zip(keys, args))
            else:
                if w.frame is not None:
                    entry["frame"] = w.frame
                for face, coord in w.faces:
                    entry[face] = coord
            d["walls"][w.fix_id] = entry
        if self.dt_reset is not None:
            r = self.dt_reset
            d["dt_reset"] = {"every": r.every, "xmax": r.xmax, "units": r.units,
                             "tmin": r.tmin, "tmax": r.tmax}
            if r.emax is not None:
                d["dt_reset"]["emax"] = r.emax
        return d

    def run_wallbatch(self, fix_lines: bool = False):
        ds = run_config(config_from_dict(self.config(fix_lines)))
        assert str(ds.status.values) == "ok", str(ds.error.values)
        return ds

    # -- LAMMPS side ---------------------------------------------------------------------

    def scene(self) -> Scene:
        x = np.concatenate([a.x for a in self.atoms])
        v = np.concatenate([a.v for a in self.atoms])
        mass = np.concatenate([np.full(len(a.x), a.mass) for a in self.atoms])
        radius = None
        if any(a.radius is not None for a in self.atoms):
            radius = np.concatenate([np.full(len(a.x), a.radius or 0.0) for a in self.atoms])
        groups, start = {}, 0
        for a in self.atoms:
            groups[a.name] = np.arange(start, start + len(a.x))
            start += len(a.x)
        fixes: list[str] = []
        outputs = ["step", "time", "dt", "ke", "temp", "pe", "etot"]
        for w in self.walls:
            fixes.append(w.fix_line())
            if w.soft:
                if w.energy:
                    fixes.append(f"fix_modify {w.fix_id} energy yes")
                outputs.append(f"f_{w.fix_id}")
                outputs += [f"f_{w.fix_id}[{i + 1}]" for i in range(len(w.faces))]
        if self.dt_reset is not None:  # defined last: step-0 dt from all forces (decisions table)
            r = self.dt_reset
            line = (f"fix wb_dtr all dt/reset {r.every} {_bound(r.tmin)} {_bound(r.tmax)} "
                    f"{_txt(r.xmax)} units {r.units}")
            if r.emax is not None:
                line += f" emax {_txt(r.emax)}"
            fixes.append(line)
        return Scene(
            units=self.units, box_lo=self.lo, box_hi=self.hi, boundary=self.boundary,
            x=x, v=v, mass=mass, radius=radius, groups=groups,
            lattice=None if self.lattice is None else f"{self.lattice[0]} {self.lattice[1]!r}",
            variables=dict(self.variables), fixes=fixes, timestep=self.timestep,
            steps=self.steps, thermo_every=self.thermo, outputs=outputs,
        )

    def run_lammps(self) -> dict[str, np.ndarray]:
        return run_lammps(self.scene())


def _txt(value) -> str:
    return repr(float(value)) if isinstance(value, (int, float, np.floating)) else str(value)


def _bound(value) -> str:
    return "NULL" if value is None else _txt(value)


# ----------------------------------------------------------------------------- comparison


def assert_series(name: str, got, want, steps, rtol: float = RTOL, floor: float = FLOOR) -> None:
    """Every sample within rtol (absolute floor: floor * max|want|); on failure, say where it
    starts and by how much."""
    got = np.asarray(got, float)
    want = np.asarray(want, float)
    assert got.shape == want.shape, f"{name}: shape {got.shape} vs LAMMPS {want.shape}"
    scale = float(np.max(np.abs(want))) if want.size else 0.0
    atol = floor * scale
    bad = ~(np.abs(got - want) <= atol + rtol * np.abs(want))
    if bad.any():
        i = int(np.argmax(bad))
        with np.errstate(divide="ignore", invalid="ignore"):
            rel = np.abs(got - want) / np.abs(want)
        raise AssertionError(
            f"{name}: first mismatch at step {int(steps[i])} (sample {i}): wallbatch {got[i]!r} vs "
            f"LAMMPS {want[i]!r} (rel {rel[i]:.3g}); {int(bad.sum())}/{bad.size} samples off, "
            f"max rel {np.nanmax(np.where(bad, rel, 0.0)):.3g}"
        )


def compare(spec: Spec, ds=None, ref=None, keys=("ke", "temp", "pe", "etot", "time", "dt")) -> tuple:
    """Run both codes (unless given) and compare every sample of every output."""
    ds = spec.run_wallbatch() if ds is None else ds
    ref = spec.run_lammps() if ref is None else ref
    steps = ref["step"]
    np.testing.assert_array_equal(ds.step.values, steps.astype(np.int64))
    for key in keys:
        assert_series(key, ds[key].values, ref[key], steps)
    for w in spec.walls:
        if not w.soft:
            continue
        assert_series(f"wall_energy[{w.fix_id}]", ds.wall_energy.sel(fix=w.fix_id).values,
                      ref[f"f_{w.fix_id}"], steps)
        for i, (face, *_rest) in enumerate(w.faces):
            label = f"{w.fix_id}/{face}"
            assert_series(f"wall_force[{label}]", ds.wall_force.sel(face=label).values,
                          ref[f"f_{w.fix_id}[{i + 1}]"], steps)
    return ds, ref


def assert_walls_active(ref: dict, spec: Spec) -> None:
    """Guard against vacuous parity: every soft face exerts a force at some sample."""
    for w in spec.walls:
        if w.soft:
            for i, (face, *_r) in enumerate(w.faces):
                assert np.any(ref[f"f_{w.fix_id}[{i + 1}]"] != 0.0), f"{w.fix_id}/{face} never acts"


# ----------------------------------------------------------------------------- atoms


def gas(rng, n, lo, hi, vscale, name="gas", mass=1.0, radius=None) -> Atoms:
    """n atoms uniformly inside [lo, hi] (per dim) with Gaussian velocities (zero net momentum)."""
    lo = np.asarray(lo, float)
    hi = np.asarray(hi, float)
    x = lo + rng.random((n, 3)) * (hi - lo)
    v = rng.standard_normal((n, 3)) * vscale
    v -= v.mean(axis=0)
    return Atoms(name, x, v, mass, radius)


# ----------------------------------------------------------------------------- 1. main scene


def main_scene() -> Spec:
    """~100 atoms; y periodic, x and z fixed. lj93 on both z faces (EDGE, energy on); a lj126
    wall on xhi moving in with a ramp; a reflect wall at x = 0.5; dt_reset every 10 (box)."""
    rng = np.random.default_rng(20260101)
    atoms = gas(rng, 100, (1.0, 0.0, 1.2), (7.5, 10.0, 10.8), 1.0)
    return Spec(
        units="lj", lo=(0.0, 0.0, 0.0), hi=(10.0, 10.0, 12.0), boundary=("f", "p", "f"),
        atoms=[atoms],
        variables={"xw": "9.0 - ramp(0.0, 1.0)"},
        walls=[
            Wall("zw", "lj93", [("zlo", "EDGE", 1.0, 1.0, 2.5), ("zhi", "EDGE", 1.0, 1.0, 2.5)],
                 energy=True),
            Wall("xw", "lj126", [("xhi", "v_xw", 1.0, 1.0, 2.5)], energy=True),
            Wall("xr", "reflect", [("xlo", 0.5)]),
        ],
        dt_reset=DtReset(every=10, xmax=0.05),
        steps=1000, thermo=50,
    )


def test_main_scene_matches_lammps():
    spec = main_scene()
    ds, ref = compare(spec)
    assert_walls_active(ref, spec)
    assert len(np.unique(ref["dt"])) > 5  # dt/reset really changes dt
    # pe = sum of the walls with energy: true
    np.testing.assert_allclose(ds.pe.values, ds.wall_energy.sum("fix").values, rtol=1e-14, atol=1e-14)


# ----------------------------------------------------------------------------- 2. one scene per soft style


STYLE_FACES = {
    "lj93": (1.0, 1.0, 2.5),
    "lj126": (1.0, 1.0, 2.5),
    "lj1043": (1.0, 1.0, 2.5),
    "colloid": (5.0, 1.0, 3.5),
    "harmonic": (5.0, 1.0, 2.5),
    "morse": (1.5, 2.0, 1.1, 3.0),  # D0 alpha r0 cutoff
}


def style_scene(style: str) -> Spec:
    rng = np.random.default_rng(sum(map(ord, style)))
    radius = 0.5 if style == "colloid" else None
    zmin = 1.8 if style == "colloid" else 1.1
    atoms = gas(rng, 20, (0.0, 0.0, zmin), (10.0, 10.0, 10.0 - zmin), 1.5, radius=radius)
    params = STYLE_FACES[style]
    return Spec(
        units="lj", lo=(0.0, 0.0, 0.0), hi=(10.0, 10.0, 10.0), boundary=("p", "p", "f"),
        atoms=[atoms],
        walls=[Wall("w", style, [("zlo", "EDGE", *params), ("zhi", "EDGE", *params)], energy=True)],
        timestep=0.005, steps=200, thermo=20,
    )


@pytest.mark.parametrize("style", list(STYLE_FACES))
def test_soft_style_matches_lammps(style):
    spec = style_scene(style)
    _ds, ref = compare(spec)
    assert_walls_active(ref, spec)


# ----------------------------------------------------------------------------- 3. lattice units


def test_lattice_units_match_lammps():
    """lattice fcc 0.8442 (spacing 1.6796): constant and variable wall coords scaled, EDGE not,
    dt_reset xmax scaled by xlattice."""
    rng = np.random.default_rng(3)
    atoms = gas(rng, 40, (2.5, 0.0, 2.0), (8.0, 10.0, 8.5), 1.2)
    spec = Spec(
        units="lj", lo=(0.0, 0.0, 0.0), hi=(10.0, 10.0, 12.0), boundary=("f", "p", "f"),
        atoms=[atoms], lattice=("fcc", 0.8442),
        variables={"xl": "0.3 + ramp(0.0, 0.3)"},
        walls=[
            Wall("zw", "lj93", [("zlo", "EDGE", 1.0, 1.0, 2.5), ("zhi", 6.0, 1.0, 1.0, 2.5)],
                 units="lattice", energy=True),
            Wall("xw", "lj126", [("xlo", "v_xl", 1.0, 1.0, 2.5)], units="lattice", energy=True),
            Wall("xh", "harmonic", [("xhi", "EDGE", 5.0, 1.0, 2.0)], units="lattice", energy=True),
        ],
        dt_reset=DtReset(every=5, xmax=0.03, units="lattice"),
        steps=400, thermo=20,
    )
    _ds, ref = compare(spec)
    assert_walls_active(ref, spec)


# ----------------------------------------------------------------------------- 4. real and metal


def test_real_units_match_lammps():
    """Argon and neon in kcal/mol, Angstrom, fs; walls in box units; dt_reset with tmin/tmax."""
    rng = np.random.default_rng(4)
    # thermal speed sqrt(kT/m) at ~600 K: about 0.0035 A/fs for argon
    ar = gas(rng, 15, (4.0, 0.0, 4.0), (26.0, 30.0, 26.0), 0.0035, name="ar", mass=39.948)
    ne = gas(rng, 10, (4.0, 0.0, 4.0), (26.0, 30.0, 26.0), 0.005, name="ne", mass=20.1797)
    spec = Spec(
        units="real", lo=(0.0, 0.0, 0.0), hi=(30.0, 30.0, 30.0), boundary=("f", "p", "f"),
        atoms=[ar, ne],
        walls=[
            Wall("zw", "lj93", [("zlo", "EDGE", 0.5, 3.4, 8.5), ("zhi", "EDGE", 0.5, 3.4, 8.5)],
                 energy=True),
            Wall("xw", "lj126", [("xlo", 0.0, 0.3, 3.4, 8.5), ("xhi", 30.0, 0.3, 3.4, 8.5)],
                 energy=True),
        ],
        dt_reset=DtReset(every=10, xmax=0.02, tmin=1.262, tmax=1.27),
        steps=600, thermo=50,
    )
    _ds, ref = compare(spec)
    assert_walls_active(ref, spec)
    # both bounds bind at some sample, and neither always
    assert np.any(ref["dt"] == 1.27) and np.any(ref["dt"] == 1.262)
    assert np.any((ref["dt"] > 1.262) & (ref["dt"] < 1.27))


def test_metal_units_match_lammps():
    """Argon in eV, Angstrom, ps; walls in box units; dt_reset with emax."""
    rng = np.random.default_rng(5)
    ar = gas(rng, 25, (3.5, 3.5, 3.5), (21.5, 21.5, 21.5), 3.0, name="ar", mass=39.948)
    spec = Spec(
        units="metal", lo=(0.0, 0.0, 0.0), hi=(25.0, 25.0, 25.0), boundary=("f", "f", "f"),
        atoms=[ar],
        walls=[
            Wall("zw", "lj126", [("zlo", "EDGE", 0.0104, 3.4, 8.5), ("zhi", "EDGE", 0.0104, 3.4, 8.5)],
                 energy=True),
            Wall("xw", "morse", [("xlo", "EDGE", 0.02, 1.2, 3.8, 9.0), ("xhi", "EDGE", 0.02, 1.2, 3.8, 9.0)],
                 energy=True),
            Wall("yr", "reflect", [("ylo", "EDGE"), ("yhi", "EDGE")]),
        ],
        dt_reset=DtReset(every=10, xmax=0.02, tmax=0.004, emax=3e-4),
        steps=600, thermo=50,
    )
    _ds, ref = compare(spec)
    assert_walls_active(ref, spec)
    assert ref["dt"][0] < 0.0019  # emax binds (xmax alone gives 0.00266 at step 0)


# ----------------------------------------------------------------------------- 5. variables, groups, energy


def variables_scene() -> Spec:
    """Walls driven by ramp, vdisplace, swiggle and cwiggle (and an epsilon variable); a wall on
    a group only; a wall with energy: false."""
    rng = np.random.default_rng(6)
    gas_atoms = gas(rng, 24, (2.5, 1.0, 3.0), (7.5, 9.0, 9.0), 1.5)
    probe = gas(rng, 6, (2.5, 2.2, 3.0), (7.5, 3.8, 9.0), 1.5, name="probe")
    return Spec(
        units="lj", lo=(0.0, 0.0, 0.0), hi=(10.0, 10.0, 12.0), boundary=("f", "f", "f"),
        atoms=[gas_atoms, probe],
        variables={
            "zl": "ramp(0.0, 1.0)",
            "zh": "vdisplace(12.0, -0.5)",
            "xl": "swiggle(0.8, 0.3, 0.4)",
            "xh": "cwiggle(9.2, -0.4, 0.5)",
            "eps": "1.0 + ramp(0.0, 1.0)",
        },
        walls=[
            Wall("zw", "lj93", [("zlo", "v_zl", 1.0, 1.0, 2.5)], energy=True),
            Wall("zh", "harmonic", [("zhi", "v_zh", 10.0, 1.0, 2.5)], energy=True),
            Wall("xw", "lj126", [("xlo", "v_xl", "v_eps", 1.0, 2.5)], energy=True),
            Wall("xm", "morse", [("xhi", "v_xh", 1.0, 2.0, 1.1, 3.0)], energy=False),
            Wall("gw", "lj93", [("ylo", 1.5, 2.0, 1.0, 2.5)], group="probe", energy=True),
            Wall("yr", "reflect", [("ylo", "EDGE"), ("yhi", "EDGE")]),
        ],
        timestep=0.005, steps=400, thermo=10,
    )


@pytest.mark.parametrize("form", ["mapping", "fix_lines"])
def test_variable_walls_group_and_energy_flag_match_lammps(form):
    """Also with every wall written as its LAMMPS fix line in the config (the parser's path)."""
    spec = variables_scene()
    ds, ref = compare(spec, ds=spec.run_wallbatch(fix_lines=form == "fix_lines"))
    assert_walls_active(ref, spec)
    # energy: false keeps the morse wall out of pe (in both codes)
    with_energy = ds.wall_energy.sel(fix=["zw", "zh", "xw", "gw"]).sum("fix").values
    np.testing.assert_allclose(ds.pe.values, with_energy, rtol=1e-13, atol=1e-13)
    assert np.any(np.abs(ds.wall_energy.sel(fix="xm").values) > 1e-6)


def group_scene(group: str) -> Spec:
    """A wall at y = 1.5 on the probe group only; gas atom 0 starts behind it (y = 1.2)."""
    spec = variables_scene()
    spec.walls = [w for w in spec.walls if w.fix_id in ("gw", "yr")]
    for w in spec.walls:
        if w.fix_id == "gw":
            w.group = group
    spec.variables = {}
    spec.atoms[0].x[0, 1] = 1.2
    spec.atoms[0].v[0, 1] = -1.0
    spec.steps, spec.thermo = 200, 10
    return spec


def test_group_wall_ignores_other_atoms():
    """Only the group feels the wall: a non-group atom behind it is no error and feels nothing.
    The same wall on `all` fails in both codes (atom on or behind the wall)."""
    spec = group_scene("probe")
    _ds, ref = compare(spec)
    assert_walls_active(ref, spec)
    spec_all = group_scene("all")
    ds_all = run_config(config_from_dict(spec_all.config()))
    assert str(ds_all.status.values) == "failed"
    assert "Particle on or inside fix wall surface" in str(ds_all.error.values)
    with pytest.raises(LammpsRunError, match="Particle on or inside fix wall surface"):
        spec_all.run_lammps()


# ----------------------------------------------------------------------------- 6. reflect frame


def reflect_scene(frame: str | None) -> Spec:
    """A reflect wall on zhi moving in (ramp 10 -> 8) over a harmonic zlo wall."""
    rng = np.random.default_rng(7)
    atoms = gas(rng, 30, (0.0, 0.0, 1.0), (10.0, 10.0, 7.5), 1.5)
    return Spec(
        units="lj", lo=(0.0, 0.0, 0.0), hi=(10.0, 10.0, 10.0), boundary=("p", "p", "f"),
        atoms=[atoms],
        variables={"zr": "10.0 - ramp(0.0, 2.0)"},
        walls=[
            Wall("zh", "harmonic", [("zlo", "EDGE", 5.0, 1.0, 2.5)], energy=True),
            Wall("zr", "reflect", [("zhi", "v_zr")], frame=frame),
        ],
        timestep=0.005, steps=400, thermo=20,
    )


@pytest.mark.parametrize("frame", [None, "lab"])
def test_reflect_frame_lab_matches_lammps(frame):
    spec = reflect_scene(frame)
    ds, ref = compare(spec)
    assert_walls_active(ref, spec)
    # the moving mirror was hit: frame wall (a wallbatch-only deviation) gives another trajectory
    if frame == "lab":
        other = reflect_scene("wall").run_wallbatch()
        assert not np.allclose(other.ke.values, ds.ke.values, rtol=1e-6)
