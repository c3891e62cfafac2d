"""Generate the reference parts of the docs site from the code, so they cannot drift.

* ``config_reference()``: every key of the config language, walked from the Pydantic model
  ``wallbatch.config.Config`` (types, defaults, constraints, descriptions), with the unit kind and
  the LAMMPS equivalent of each key from :data:`KEYS` below; the wall styles from the style
  registry when there is one.
* ``cli_reference()``: every command and option of the ``wallbatch`` Typer app (click introspection).

``docs/hooks.py`` calls these at build time and puts their output where a page says
``<!-- generated: config-keys -->`` (and the other markers below). ``python docs/gen_reference.py``
prints both, and ``undocumented()`` / ``stale()`` list keys without a description or
descriptions of keys that no longer exist (``tests/test_docs.py`` fails on either).
"""

from __future__ import annotations

import enum
import re
import inspect
import sys
import types
import typing
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal, Union, get_args, get_origin

import annotated_types as at
from pydantic import BaseModel
from pydantic_core import PydanticUndefined

ROOT = Path(__file__).resolve().parent.parent
if str(ROOT / "src") not in sys.path:
    sys.path.insert(0, str(ROOT / "src"))

FACES = ("xlo", "xhi", "ylo", "yhi", "zlo", "zhi")

# ------------------------------------------------------------------------------------------------
# What the models do not say: the unit kind of a value, its LAMMPS equivalent and, where the model
# has no Field(description=...), its meaning. Keys are dotted paths as the reference prints them:
# `atoms[].mass`; `walls.ID.FACE.epsilon` for any face of any wall style; `ID`/`NAME` for
# mapping keys the user chooses. A model description wins over `doc` here.
# unit: a kind from UNIT_KINDS ("" = dimensionless or not a quantity).


@dataclass(frozen=True)
class Key:
    doc: str
    unit: str = ""
    lammps: str = ""
    type: str = ""  # overrides the type the walker derives (e.g. for number-or-name values)


NUM_OR_VAR = "number or `v_name`"
COORD = "number, `EDGE` or `v_name`"

KEYS: dict[str, Key] = {
    "name": Key("Label stored in the results (`title` attribute) and used for exported file names.", "",
                "—"),
    "units": Key("Unit system of every value in the config and in the results.", "", "`units lj|real|metal`"),
    "seed": Key("Master seed: every random stream of every case (positions, velocities, orientations, "
                "flow redraws) derives from it and the case's sweep coordinates.", "", "the seeds of "
                "`create_atoms`, `velocity`, `fix wall/flow`"),
    "box": Key("The simulation box, always in box (distance) units.", "", "`region box block` + "
               "`create_box`, `boundary`"),
    "box.lo": Key("Lower corner [x, y, z].", "distance", "`create_box` bounds"),
    "box.hi": Key("Upper corner [x, y, z]; each component greater than `lo`.", "distance", "`create_box` bounds"),
    "box.boundary": Key("Per dimension `p` (periodic) or `f` (fixed: an atom leaving it fails the case).", "",
                        "`boundary p p f`"),
    "lattice": Key("A lattice, needed by `units: lattice` (the default of walls, regions and dt_reset) "
                   "and by lattice creation.", "", "`lattice STYLE SCALE`"),
    "lattice.style": Key("Lattice type (cubic cells, origin at 0).", "", "`lattice sc|bcc|fcc`"),
    "lattice.scale": Key("In lj units the reduced number density; otherwise the lattice constant.",
                         "density (lj) or distance", "`lattice STYLE SCALE`"),
    "atoms": Key("One entry per group of particles; `all` (every atom) is reserved.", "", "`create_atoms`, "
                 "`group`, `mass`, `velocity`"),
    "atoms[].group": Key("Group name, unique; fix `group:` keys refer to it.", "", "`group NAME`"),
    "atoms[].create": Key("Exactly one way of creating the group's atoms.", "", "`create_atoms`, `read_data`"),
    "atoms[].create.random": Key("Uniform random points in the box or a region, rejecting any closer than "
                                 "`overlap` to an atom already placed.", "", "`create_atoms 1 random N SEED "
                                 "REGION overlap D`"),
    "atoms[].create.random.count": Key("Number of atoms to place.", "", "`create_atoms ... random N`"),
    "atoms[].create.random.region": Key("Name of a region of `regions:` to place them in (default the box).",
                                        "", "`create_atoms ... random N SEED REGION`"),
    "atoms[].create.random.overlap": Key("Minimum distance to atoms already placed (minimum image).",
                                         "distance", "`overlap D`"),
    "atoms[].create.lattice": Key("The points of `lattice:` with lo <= x < hi, in the box or a region.", "",
                                  "`create_atoms 1 box` / `region`"),
    "atoms[].create.lattice.region": Key("Region to fill (default the box).", "", "`create_atoms 1 region R`"),
    "atoms[].create.positions": Key("Explicit positions, one [x, y, z] per atom.", "distance",
                                    "`create_atoms single`, a data file"),
    "atoms[].create.file": Key("An `.npz` file (relative to the YAML file) with `x` (N, 3) and optionally "
                               "`v`, `mass`, `radius`, `shape`, `quat` (N, 4), `angmom`.", "", "`read_data`"),
    "atoms[].mass": Key("Mass of every atom of the group (required unless the `.npz` gives masses).", "mass",
                        "`mass`"),
    "atoms[].radius": Key("Finite-size spheres (needed by wall/colloid).", "distance",
                          "`atom_style sphere`, `set ... diameter 2R`"),
    "atoms[].shape": Key("Ellipsoid semi-axes [a, b, c] (needed by wall/ees); LAMMPS's `set shape` takes "
                         "diameters 2a 2b 2c.", "distance", "`atom_style ellipsoid`, `set ... shape`"),
    "atoms[].orientation": Key("Ellipsoids: `aligned` (identity, default), `random` (uniform on SO(3)) or a "
                               "quaternion [qw, qx, qy, qz], normalised on input.", "", "`set ... quat`"),
    "atoms[].angmom": Key("Ellipsoids: space-frame angular momentum; default 0.", "", "`set ... angmom`"),
    "atoms[].angmom.values": Key("One 3-vector for every atom of the group, or one per atom.",
                                 "mass distance²/time", "`set ... angmom`"),
    "atoms[].velocity": Key("Initial velocities; default at rest.", "", "`velocity`"),
    "atoms[].velocity.temperature": Key("Gaussian components, zero net momentum, scaled to exactly this "
                                        "temperature over 3n - 3 degrees of freedom.", "temperature",
                                        "`velocity G create T SEED dist gaussian mom yes`"),
    "atoms[].velocity.values": Key("One 3-vector for every atom of the group, or one per atom.", "velocity",
                                   "`velocity G set vx vy vz`, a data file"),
    "pair": Key("Particle-particle forces; omitted: none (an ideal gas).", "", "`pair_style`"),
    "pair.style": Key("The only pair style.", "", "`pair_style lj/cut`"),
    "pair.epsilon": Key("Depth of the Lennard-Jones well.", "energy", "`pair_coeff * * EPS SIGMA`"),
    "pair.sigma": Key("Lennard-Jones size.", "distance", "`pair_coeff * * EPS SIGMA`"),
    "pair.cutoff": Key("Pair cut-off, below half the box in periodic dimensions.", "distance",
                       "`pair_style lj/cut RC`"),
    "pair.shift": Key("Shift the pair energy to zero at the cut-off (forces unchanged).", "",
                      "`pair_modify shift yes`"),
    "timestep": Key("Timestep; default the unit system's LAMMPS default (lj 0.005, real 1.0, metal 0.001).",
                    "time", "`timestep`"),
    "variables": Key("Equal-style variables, referenced as `v_name` in wall coordinates and parameters; "
                     "values are numbers or expressions (see the variables section).", "",
                     "`variable NAME equal EXPR`"),
    "regions": Key("Named regions, for random and lattice creation and region walls.", "", "`region`"),
    "regions.NAME.style": Key("Shape.", "", "`region ID block|sphere|cylinder`"),
    "regions.NAME.side": Key("`in`: the inside is the allowed side; `out`: the outside.", "", "`side in|out`"),
    "regions.NAME.units": Key("Units of the geometry (`lattice` scales by the lattice spacings).", "",
                              "`units lattice|box`"),
    "regions.NAME.lo": Key("block: lower corner [x, y, z]; cylinder: lower end along the axis.", "distance",
                           "`block xlo ... zhi`, cylinder `lo`"),
    "regions.NAME.hi": Key("block: upper corner [x, y, z]; cylinder: upper end along the axis.", "distance",
                           "`block xlo ... zhi`, cylinder `hi`"),
    "regions.NAME.center": Key("sphere: [x, y, z]; cylinder: the two coordinates across its axis.", "distance",
                               "`sphere x y z R`, `cylinder AXIS c1 c2 R lo hi`"),
    "regions.NAME.radius": Key("sphere or cylinder radius.", "distance", "`R`"),
    "regions.NAME.axis": Key("cylinder axis.", "", "`cylinder x|y|z ...`"),
    "walls": Key("Wall fixes by fix-ID; the order is kept in the results (`fix` and `face` dimensions). "
                 "A value may also be a LAMMPS fix line (a string) or `{fix: \"fix ...\", energy: true}`.", "",
                 "`fix ID GROUP wall/STYLE ...`"),
    "walls.ID.style": Key("Wall style.", "", "`wall/STYLE`"),
    "walls.ID.group": Key("Group the wall acts on.", "", "`fix ID GROUP ...`"),
    "walls.ID.units": Key("Units of the wall coordinates (`lattice` scales constants and variables, never "
                          "EDGE); epsilon, sigma and cut-offs are always box units.", "", "`units lattice|box`"),
    "walls.ID.energy": Key("Add the wall energy to `pe` and `etot` (and to the minimized energy).", "",
                           "`fix_modify ID energy yes`"),
    "walls.ID.virial": Key("Add the wall virial to `press`.", "", "`fix_modify ID virial yes`"),
    "walls.ID.pbc": Key("Allow a face in a periodic dimension (the wall acts on its group only; no images).",
                        "", "`pbc yes`"),
    "walls.ID.FACE": Key("A face `xlo xhi ylo yhi zlo zhi`: a mapping, or the positional list in LAMMPS's "
                         "order (`[coord, epsilon, sigma, cutoff]`; morse `[coord, D0, alpha, r0, cutoff]`; "
                         "reflect a bare coord).", "", "`xlo ARGS`"),
    "walls.ID.FACE.coord": Key("Wall position: a number, `EDGE` (the box bound) or `v_name`.", "distance",
                               "`COORD`", COORD),
    "walls.ID.FACE.epsilon": Key("Strength: energy for lj93, lj126, lj1043, colloid (a Hamaker-like "
                                 "constant) and ees; for harmonic the spring constant K [energy/distance²].",
                                 "energy", "`EPS`", NUM_OR_VAR),
    "walls.ID.FACE.sigma": Key("Size; harmonic ignores it and may leave it out.", "distance", "`SIGMA`",
                               NUM_OR_VAR),
    "walls.ID.FACE.cutoff": Key("Cut-off distance from the wall (box units).", "distance", "`CUTOFF`"),
    "walls.ID.FACE.D0": Key("Morse well depth.", "energy", "`D0`", NUM_OR_VAR),
    "walls.ID.FACE.alpha": Key("Morse width (LAMMPS ignores it as a variable; wallbatch evaluates it).",
                               "1/distance", "`alpha`", NUM_OR_VAR),
    "walls.ID.FACE.r0": Key("Morse equilibrium distance.", "distance", "`r0`", NUM_OR_VAR),
    "walls.ID.frame": Key("reflect: `lab` negates v (LAMMPS); `wall` reflects in the moving wall's frame, "
                          "v -> 2 v_wall - v.", "", "— (`lab` is LAMMPS's)"),
    "walls.ID.axis": Key("flow: the flow axis (periodic).", "", "`wall/flow AXIS`"),
    "walls.ID.vflow": Key("flow: flow velocity (> 0).", "velocity", "`VFLOW`"),
    "walls.ID.temperature": Key("flow: temperature of the redrawn velocities.", "temperature", "`T`"),
    "walls.ID.seed": Key("flow, reflect/stochastic: the wall's seed, combined with the master seed and the case "
                         "coordinates.",
                         "", "`SEED`"),
    "walls.ID.coords": Key("flow: wall positions along the axis, strictly increasing, inside the box.",
                           "distance", "`N w1 ... wN`"),
    "walls.ID.rule": Key("flow: `exact` (default) does not redraw an atom returning over the wall it has just "
                         "crossed (the requested shifted Maxwellian); `lammps` redraws it again, as LAMMPS.",
                         "", "— (`lammps` is LAMMPS's)"),
    "walls.ID.region": Key("region, region/ees: name of the region whose surface is the wall.", "",
                           "`wall/region REGION-ID`"),
    "walls.ID.potential": Key("region: the potential of the surface (fix wall/colloid physics for colloid).",
                              "", "`wall/region R STYLE`"),
    "walls.ID.epsilon": Key("region, region/ees: strength (harmonic: K [energy/distance²]).", "energy", "`EPS`",
                            NUM_OR_VAR),
    "walls.ID.sigma": Key("region, region/ees: size (harmonic may leave it out).", "distance", "`SIGMA`",
                          NUM_OR_VAR),
    "walls.ID.D0": Key("region with morse: well depth.", "energy", "`D0`", NUM_OR_VAR),
    "walls.ID.alpha": Key("region with morse: width.", "1/distance", "`alpha`", NUM_OR_VAR),
    "walls.ID.r0": Key("region with morse: equilibrium distance.", "distance", "`r0`", NUM_OR_VAR),
    "walls.ID.cutoff": Key("region, region/ees: cut-off distance from the surface (box units).", "distance",
                           "`CUTOFF`"),
    "walls.ID.FACE.expression": Key("lepton: the wall energy E(r) as a Lepton expression of r, the distance "
                                    "from the wall; `;` definitions allowed; F = -dE/dr exactly; shifted to 0 "
                                    "at the cut-off.", "energy", "`wall/lepton FACE COORD EXPRESSION CUTOFF`"),
    "walls.ID.FACE.params": Key("lepton: named numbers used by the expression (sweepable; written as `; "
                                "name=value` definitions for LAMMPS); `cutoff` is reserved.", "",
                                "`; name=value`"),
    "walls.ID.FACE.file": Key("table: a LAMMPS table file, relative to the config file.", "",
                              "`wall/table ... FILE`"),
    "walls.ID.FACE.keyword": Key("table: the section of the file.", "", "`KEYWORD`"),
    "walls.ID.tabstyle": Key("table: `linear` or `spline` interpolation, as LAMMPS.", "",
                             "`wall/table linear|spline`"),
    "walls.ID.N": Key("table: points of the interpolation table (the file is resampled onto them).", "",
                      "`wall/table TABSTYLE N`"),
    "walls.ID.rstyle": Key("reflect/stochastic: `diffusive`, `maxwell` (one accommodation coefficient) or "
                           "`ccl` (Cercignani-Lampis, three).", "", "`wall/reflect/stochastic RSTYLE`"),
    "walls.ID.FACE.temp": Key("reflect/stochastic: wall temperature of the reflected velocities.", "temperature",
                              "`TEMP`"),
    "walls.ID.FACE.vel": Key("reflect/stochastic: wall velocity [vx, vy, vz], in the wall's plane.", "velocity",
                             "`VX VY VZ`"),
    "walls.ID.FACE.accom": Key("reflect/stochastic: accommodation, one number (maxwell: the diffusive "
                               "fraction) or [ax, ay, az] (ccl: tangential velocity and normal energy "
                               "accommodation), each in [0, 1]; none for diffusive.", "", "`ACCOM...`"),
    "dimension": Key("2 or 3 (default). 2-D as LAMMPS: z periodic and thin, no z walls, z velocities and "
                     "forces zeroed (enforce2d), 2 degrees of freedom per atom; lattices sq, sq2, hex.", "",
                     "`dimension 2`"),
    "fixes": Key("Integrators and thermostats, fix-ID -> fix (mapping form or a verbatim LAMMPS fix line), "
                 "applied in LAMMPS order. Absent: `fix nve` on all atoms. Atoms in no integrating group "
                 "never move (static obstacles) but still feel and exert forces.", "", "`fix ID GROUP STYLE ...`"),
    "fixes.NAME.style": Key("nve, nve/asphere, nvt, langevin, temp/berendsen, temp/rescale or enforce2d.", "",
                            "the fix style"),
    "fixes.NAME.group": Key("The atom group the fix acts on (default all).", "", "`GROUP`"),
    "fixes.NAME.temp": Key("[Tstart, Tstop]: the target temperature ramps linearly over the run.", "temperature",
                           "`temp Tstart Tstop` (nvt), `Tstart Tstop` (langevin, berendsen, rescale)"),
    "fixes.NAME.damp": Key("Relaxation time of the thermostat (> 0).", "time", "`Tdamp` / `damp`"),
    "fixes.NAME.tchain": Key("Length of the Nose-Hoover chain (nvt; default 3).", "", "`tchain N`"),
    "fixes.NAME.tloop": Key("Sub-cycles of the chain update per half step (nvt; default 1).", "", "`tloop N`"),
    "fixes.NAME.drag": Key("Drag factor damping the chain (nvt; default 0).", "", "`drag D`"),
    "fixes.NAME.seed": Key("Random seed of the Langevin force (per case and replica the stream derives from it "
                           "and the master seed).", "", "`seed`"),
    "fixes.NAME.zero": Key("Langevin: remove the net random force, so the total momentum is kept.", "",
                           "`zero yes`"),
    "fixes.NAME.tally": Key("Langevin: tally the energy exchanged with the bath into `ecouple`.", "",
                            "`tally yes`"),
    "fixes.NAME.omega": Key("Langevin on ellipsoid rotations: not supported (refused).", "", "`omega yes`"),
    "fixes.NAME.every": Key("temp/rescale: rescale every N steps.", "", "`N`"),
    "fixes.NAME.window": Key("temp/rescale: rescale only when |T - Ttarget| exceeds this.", "temperature",
                             "`window`"),
    "fixes.NAME.fraction": Key("temp/rescale: fraction (0-1] of the difference removed at each rescale.", "",
                               "`fraction`"),
    "dt_reset": Key("Adaptive timestep.", "", "`fix ID GROUP dt/reset N Tmin Tmax Xmax`"),
    "dt_reset.every": Key("Reset every N steps (and at step 0, after all forces).", "", "`N`"),
    "dt_reset.group": Key("Atoms whose motion limits dt.", "", "`GROUP`"),
    "dt_reset.tmin": Key("Lower bound of dt: a number, or `INF`, `NULL`, null for none.", "time", "`Tmin` "
                         "(`NULL` only)", "number, `INF`, `NULL` or null"),
    "dt_reset.tmax": Key("Upper bound of dt: a number, or `INF`, `NULL`, null for none.", "time", "`Tmax` "
                         "(`NULL` only)", "number, `INF`, `NULL` or null"),
    "dt_reset.xmax": Key("Largest distance an atom may move in one step.", "distance", "`Xmax`"),
    "dt_reset.emax": Key("Largest energy an atom may gain in one step.", "energy", "`emax Emax`"),
    "dt_reset.units": Key("Units of `xmax` (`lattice` multiplies it by the x lattice spacing).", "",
                          "`units lattice|box`"),
    "minimize": Key("Energy minimization before the run (pair energy plus walls with `energy: true`).", "",
                    "`min_style`, `min_modify dmax`, `minimize etol ftol maxiter maxeval`"),
    "minimize.style": Key("`cg` (Polak-Ribiere with the quadratic line search) or `fire`.", "",
                          "`min_style cg|fire`"),
    "minimize.etol": Key("Stop when the relative energy change of an iteration is below it.", "", "`etol`"),
    "minimize.ftol": Key("Stop when the 2-norm of the global force vector is below it.", "force", "`ftol`"),
    "minimize.maxiter": Key("Largest number of iterations.", "", "`maxiter`"),
    "minimize.maxeval": Key("Largest number of force/energy evaluations (fire does not check it).", "",
                            "`maxeval`"),
    "minimize.dmax": Key("Largest move of any atom in one line-search step.", "distance",
                         "`min_modify dmax`"),
    "run": Key("Run length and sampling.", "", "`run N`, `thermo N`"),
    "run.steps": Key("Number of steps (give `steps` or `time`).", "", "`run N`"),
    "run.time": Key("Run until this simulated time (the last step is shortened to land on it).", "time",
                    "— (`run N`)"),
    "run.thermo": Key("Sampling interval of every output in steps (0: first and last step only), or "
                      "`{time: t}` for exact simulated times.", "", "`thermo N`"),
    "run.thermo.time": Key("Sample every t of simulated time (dt is clipped to land on the instants).", "time",
                           "—"),
    "output": Key("What the results hold.", "", "`thermo_style custom`, `dump`"),
    "output.thermo": Key("Scalar outputs per sample; `step` and `time` are always written.", "",
                         "`thermo_style custom ...`"),
    "output.dump": Key("Per-atom trajectories (AMBER NetCDF), one file per case.", "", "`dump netcdf`"),
    "output.dump.every": Key("Frame interval in steps (step 0 included).", "", "`dump ID all netcdf N`"),
    "output.dump.fields": Key("Per-atom fields to write.", "", "`x y z vx vy vz`"),
    "output.profiles": Key("Profiles across the box, by name: one binned axis each, sampled and averaged as "
                           "fix ave/chunk (norm all); variables `profile_NAME_QUANTITY` (see the profiles "
                           "how-to).", "", "`compute chunk/atom bin/1d` + `fix ave/chunk`"),
    "output.profiles.NAME.axis": Key("Axis of the bins; they start at the box's lower bound.", "",
                                     "`bin/1d x|y|z lower`"),
    "output.profiles.NAME.bins": Key("Number of equal bins over the box (give `bins` or `delta`).", "",
                                     "`bin/1d z lower 1/N units reduced`"),
    "output.profiles.NAME.delta": Key("Bin width; ceil(L/delta) bins (give `bins` or `delta`).", "distance",
                                      "`bin/1d z lower delta units box`"),
    "output.profiles.NAME.every": Key("Steps between samples.", "", "`Nevery`"),
    "output.profiles.NAME.repeat": Key("Samples per window (repeat * every <= freq).", "", "`Nrepeat`"),
    "output.profiles.NAME.freq": Key("A window closes at every multiple of freq (a multiple of every; step 0 "
                                     "opens none).", "", "`Nfreq`"),
    "output.profiles.NAME.quantities": Key("What is averaged per bin: density/number, density/mass, temp, vx, "
                                           "vy, vz.", "", "`density/number density/mass temp vx vy vz`"),
    "output.profiles.NAME.group": Key("Atoms binned.", "", "the fix's group-ID"),
    "output.averages": Key("Where the time averages (`_mean`, `_sem`) start; default: every sample.", "",
                           "— (`fix ave/time` without error bars)"),
    "output.averages.start": Key("First step averaged (inclusive), for a step-based run.", "", "—"),
    "output.averages.time": Key("First simulated time averaged (inclusive), for a run to a time.", "time",
                                "—"),
    "sweep": Key("Turns the scene into a grid of cases (see the sweep section).", "", "— (a `loop` of runs)"),
    "sweep.product": Key("A full grid: one results dimension per entry, named by the key. An entry is "
                         "`{path, values}` or, as shorthand, `PATH: VALUES` (the dimension is named after "
                         "the path's last part).", "", "—"),
    "sweep.product.NAME.path": Key("Dotted path(s) into the validated model that this dimension sets "
                                   "(`walls.zw.zlo.epsilon`, `box.hi.2`); a list sets several together.", "",
                                   "—"),
    "sweep.product.NAME.values": Key("A list, `{linspace: [a, b, n]}`, `{logspace: [a, b, n]}` (base-10 "
                                     "exponents) or `{range: [a, b, step]}` (b excluded).", "", "—"),
    "sweep.zip": Key("Parameters that move together on one dimension; their values become extra "
                     "coordinates.", "", "—"),
    "sweep.zip.dim": Key("Name of the zip's dimension.", "", "—"),
    "sweep.zip.params": Key("The parameters, each `{path, values}` with values of equal length.", "", "—"),
    "sweep.zip.params.NAME.path": Key("As `product`'s `path`.", "", "—"),
    "sweep.zip.params.NAME.values": Key("As `product`'s `values`; every parameter of the zip has as many.", "",
                                        "—"),
    "sweep.replicas": Key("Independent random streams of every grid point: a last dimension `replica`.", "",
                          "—"),
}

# unit kinds -> attribute of wallbatch.units.UnitSystem (or a formula of them)
_KIND_ATTR = {"distance": "distance", "energy": "energy", "time": "time", "mass": "mass",
              "temperature": "temperature", "velocity": "velocity", "force": "force", "pressure": "pressure"}


_BASE_KINDS = ("temperature", "distance", "velocity", "pressure", "energy", "force", "time", "mass")


def unit_text(kind: str, u: Any) -> str:
    """A unit kind (`energy/distance^2`, `1/distance`, `mass distance²/time`) in unit system u."""
    if u.name == "lj":
        return "reduced"
    if kind == "density (lj) or distance":
        return u.distance
    return _kind(re.sub("|".join(_BASE_KINDS), lambda m: getattr(u, m.group(0)), kind))


def _kind(kind: str) -> str:
    """A unit kind as the docs print it (`energy/distance^2` -> `energy/distance²`)."""
    return kind.replace("^2", "²").replace("^3", "³")


def _kinds_in_use() -> list[str]:
    kinds = {_kind(k.unit) for k in KEYS.values() if k.unit}
    kinds |= {_kind(r.unit) for r in all_rows() if r.unit}
    return sorted(kinds - set(_KIND_ATTR), key=lambda k: (len(k), k))


def _unit_systems() -> dict[str, Any]:
    from wallbatch.units import UNIT_SYSTEMS

    return UNIT_SYSTEMS


def unit_kinds_table() -> str:
    """Markdown table: unit kind -> its unit in each unit system (from wallbatch.units)."""
    systems = _unit_systems()
    names = list(systems)
    rows = ["| kind | " + " | ".join(f"`units: {n}`" for n in names) + " |",
            "| --- | " + " | ".join("---" for _ in names) + " |"]
    for kind, attr in _KIND_ATTR.items():
        vals = [getattr(systems[n], attr) for n in names]
        rows.append(f"| {kind} | " + " | ".join("reduced" if v == "1" else v for v in vals) + " |")
    for kind in _kinds_in_use():
        rows.append(f"| {kind} | " + " | ".join(unit_text(kind, systems[n]) for n in names) + " |")
    return "\n".join(rows)


# ------------------------------------------------------------------------------------------------
# walking the models


@dataclass
class Row:
    path: str
    type: str
    default: str
    required: bool
    constraints: str
    description: str
    unit: str = ""
    lammps: str = ""


@dataclass
class Section:
    path: str
    title: str
    doc: str
    rows: list[Row] = field(default_factory=list)
    model: Any = None


def _strip(ann: Any) -> tuple[Any, list[Any]]:
    """(bare annotation, metadata) of a possibly Annotated annotation."""
    meta: list[Any] = []
    while get_origin(ann) is typing.Annotated:
        args = get_args(ann)
        ann, meta = args[0], meta + list(args[1:])
    return ann, meta


def _is_model(ann: Any) -> bool:
    return inspect.isclass(ann) and issubclass(ann, BaseModel)


def _union_args(ann: Any) -> tuple[Any, ...] | None:
    if get_origin(ann) in (Union, types.UnionType):
        return get_args(ann)
    return None


def _constraints(meta: list[Any]) -> list[str]:
    out = []
    for m in meta:
        if type(m).__name__ == "FieldInfo":  # Annotated[..., Field(...)] inside a Union or list
            out += _constraints(list(m.metadata))
            continue
        for cls, sym in ((at.Gt, ">"), (at.Ge, ">="), (at.Lt, "<"), (at.Le, "<=")):
            if isinstance(m, cls):
                out.append(f"{sym} {getattr(m, sym_attr(cls))}")
        if isinstance(m, at.MinLen) and m.min_length:
            out.append(f"at least {m.min_length} item{'s' if m.min_length > 1 else ''}")
        if isinstance(m, at.MaxLen):
            out.append(f"at most {m.max_length} items")
        pattern = getattr(m, "pattern", None)
        if isinstance(pattern, str):
            out.append(f"matches `{pattern}`")
        # pydantic's FieldInfo metadata may hold a grouped annotated_types.Interval etc.
        if isinstance(m, at.Interval):
            for name, sym in (("gt", ">"), ("ge", ">="), ("lt", "<"), ("le", "<=")):
                if getattr(m, name) is not None:
                    out.append(f"{sym} {getattr(m, name)}")
    return out


def sym_attr(cls: type) -> str:
    return {at.Gt: "gt", at.Ge: "ge", at.Lt: "lt", at.Le: "le"}[cls]


def type_text(ann: Any) -> str:
    """A short, readable rendering of a type annotation for the reference tables."""
    ann, meta = _strip(ann)
    cons = _constraints(meta)
    suffix = f" ({', '.join(cons)})" if cons else ""
    if ann is type(None):
        return "null"
    args = _union_args(ann)
    if args is not None:
        parts = [type_text(a) for a in args if a is not type(None)]
        return " or ".join(dict.fromkeys(parts)) + suffix
    origin = get_origin(ann)
    if origin is Literal:
        return " \\| ".join(f"`{v}`" for v in get_args(ann)) + suffix
    if origin is tuple:
        inner = get_args(ann)
        if len(inner) == 2 and inner[1] is Ellipsis:
            return f"list of {type_text(inner[0])}" + suffix
        texts = [type_text(a) for a in inner]
        if len(set(texts)) == 1:
            return f"[{len(texts)} × {texts[0]}]" + suffix
        return "[" + ", ".join(texts) + "]" + suffix
    if origin is list:
        return f"list of {type_text(get_args(ann)[0])}" + suffix
    if origin is dict:
        k, v = get_args(ann)
        return f"mapping {type_text(k)} → {type_text(v)}" + suffix
    if _is_model(ann):
        return "mapping" + suffix
    if inspect.isclass(ann) and issubclass(ann, enum.Enum):
        return " \\| ".join(f"`{m.value}`" for m in ann) + suffix
    names = {float: "number", int: "integer", str: "text", bool: "true \\| false", Any: "any", Path: "path"}
    return names.get(ann, getattr(ann, "__name__", str(ann))) + suffix


def _default_text(info: Any) -> tuple[str, bool]:
    if info.is_required():
        return "required", True
    d = info.get_default(call_default_factory=True)
    if d is None:
        return "—", False
    if isinstance(d, BaseModel):
        return "see below", False
    if isinstance(d, (dict, list, tuple)) and not d:
        return "none", False
    if isinstance(d, bool):
        return f"`{str(d).lower()}`", False
    if isinstance(d, tuple):
        d = list(d)
    if isinstance(d, list):
        return "`[" + ", ".join(str(v) for v in d) + "]`", False
    return f"`{d}`", False


def _models_in(ann: Any) -> list[type[BaseModel]]:
    """Models reachable directly in an annotation (through Optional, Union, list, dict values)."""
    ann, _ = _strip(ann)
    if _is_model(ann):
        return [ann]
    args = _union_args(ann)
    if args is not None:
        return [m for a in args for m in _models_in(a)]
    origin = get_origin(ann)
    if origin is list:
        return _models_in(get_args(ann)[0])
    if origin is dict:
        return _models_in(get_args(ann)[1])
    return []


def _child_path(path: str, name: str, ann: Any) -> str:
    ann, _ = _strip(ann)
    args = _union_args(ann)
    if args is not None:
        non_none = [a for a in args if a is not type(None)]
        ann = _strip(non_none[0])[0] if len(non_none) == 1 else ann
    p = f"{path}.{name}" if path else name
    origin = get_origin(ann)
    if origin is list and _models_in(ann):
        return p + "[]"
    if origin is dict and _models_in(ann):
        return p + "." + ("ID" if name == "walls" else "NAME")
    return p


def _style_values(model: type[BaseModel]) -> list[str]:
    f = model.model_fields.get("style")
    if f is None:
        return []
    ann, _ = _strip(f.annotation)
    return [str(v) for v in get_args(ann)] if get_origin(ann) is Literal else []


def walk(model: type[BaseModel], path: str = "", title: str = "", note: str = "") -> list[Section]:
    """Sections (one per model, depth first) with one row per field; `note` qualifies the titles of
    nested sections (the wall style they belong to)."""
    doc = inspect.cleandoc(model.__doc__ or "") if model.__doc__ and model.__doc__ != BaseModel.__doc__ else ""
    sec = Section(path, title or ((f"`{path}`" + note) if path else "Top level"), doc, model=model)
    out = [sec]
    names = list(model.model_fields)
    faces = [n for n in names if n in FACES]
    collapsed = set()
    if len(faces) == 6 and len({repr(model.model_fields[f].annotation) for f in faces}) == 1:
        collapsed = set(faces)
    seen_face = False
    for name in names:
        info = model.model_fields[name]
        if name in collapsed:
            if seen_face:
                continue
            seen_face = True
            shown, key = " ".join(f"`{f}`" for f in FACES), f"{_wall_prefix(path)}.FACE"
        else:
            shown, key = f"`{name}`", (f"{_wall_prefix(path)}.{name}" if _wall_prefix(path) else
                                       (f"{path}.{name}" if path else name))
        default, required = _default_text(info)
        ann = info.annotation
        cons = ", ".join(_constraints(list(info.metadata)))
        k = KEYS.get(key)
        reg = _registry_param(path, note, name)
        desc = (info.description or getattr(reg, "doc", "") or (k.doc if k else "")).strip()
        typ = (k.type if k and k.type else type_text(ann))
        unit = getattr(reg, "unit", "") or (k.unit if k else "")
        sec.rows.append(Row(shown, typ, default, required, cons, desc, unit, k.lammps if k else ""))
        sec.rows[-1].key = key  # type: ignore[attr-defined]
        child = key if name in collapsed else _child_path(path, name, ann)
        models = _models_in(ann)
        if len(models) == 1:
            out += walk(models[0], child, note=note)
        elif len(models) > 1:
            for m in models:
                styles = _style_values(m)
                label = " \\| ".join(f"`{s}`" for s in styles) if styles else m.__name__
                sub = f" (`style:` {label})" if styles else note
                out += walk(m, child, title=f"`{child}`{sub}", note=sub)
    return out


def _registry() -> dict[str, Any]:
    try:
        from wallbatch.styles import STYLES  # type: ignore[attr-defined]
    except ImportError:
        return {}
    return {getattr(st, "name", str(st)): st for st in (STYLES.values() if isinstance(STYLES, dict) else STYLES)}


def _registry_param(path: str, note: str, name: str) -> Any:
    """The style registry's entry for a face parameter (unit kind, doc), when the face section
    belongs to exactly one registered style."""
    if path != "walls.ID.FACE":
        return None
    styles = [x for x in re.findall(r"`([^`]+)`", note) if x != "style:"]
    style = _registry().get(styles[0]) if len(styles) == 1 else None
    for prm in getattr(style, "parameters", None) or ():
        if getattr(prm, "name", None) == name:
            return prm
    return None


def _wall_prefix(path: str) -> str:
    """`walls.ID` (or `walls.ID.FACE`) for any path inside a wall, so one KEYS entry covers every style."""
    if path.startswith("walls.ID.FACE"):
        return "walls.ID.FACE"
    if path.startswith("walls.ID"):
        return "walls.ID"
    return ""


def sweep_sections() -> list[Section]:
    """The sweep grammar (`sweep:` of a config or a sweep file): the Sweep, Param and Zip models;
    the value forms (linspace, logspace, range) are described in the `values` row."""
    from wallbatch.config import sweep as sw

    keep = {getattr(sw, n) for n in ("Sweep", "Param", "Zip") if hasattr(sw, n)}
    return [sec for sec in walk(sw.Sweep, "sweep") if sec.model in keep]


def all_rows(sections: list[Section] | None = None) -> list[Row]:
    return [r for s in (sections or walk(_config_model()) + sweep_sections()) for r in s.rows]


def _config_model() -> type[BaseModel]:
    from wallbatch.config.models import Config

    return Config


def undocumented() -> list[str]:
    """Config keys with neither a model description nor a KEYS entry."""
    return sorted({r.key for r in all_rows() if not r.description})  # type: ignore[attr-defined]


def stale() -> list[str]:
    """KEYS entries that name no key of the models (a removed or renamed key)."""
    keys = {r.key for r in all_rows()}  # type: ignore[attr-defined]
    # parents of keys (e.g. `walls.ID`) exist as rows of their parent section
    return sorted(k for k in KEYS if k not in keys)


# ------------------------------------------------------------------------------------------------
# rendering


def _cell(text: str) -> str:
    """A table cell: newlines joined, pipes outside code spans escaped."""
    parts = text.replace("\n", " ").split("`")
    return "`".join(re.sub(r"(?<!\\)\|", r"\\|", p) if i % 2 == 0 else p for i, p in enumerate(parts))


def _link_sections(text: str) -> str:
    """`docs/physics.md §8.6` (or `physics.md §8.6`) as a link to that section of the Physics page
    (the reference pages live in docs/reference/)."""
    return re.sub(r"(?:docs/)?physics\.md §(\d+(?:\.\d+)?[a-z]?)",
                  lambda m: f"[Physics §{m.group(1)}](../physics.md#s{m.group(1).replace('.', '-')})", text)


def config_keys(sections: list[Section] | None = None) -> str:
    """The generated key tables, one section per model."""
    sections = walk(_config_model()) if sections is None else sections
    out = []
    for sec in sections:
        if not sec.rows:
            continue
        out.append(f"### {sec.title}\n")
        if sec.doc:
            out.append(_link_sections(sec.doc.replace("\n", " ")) + "\n")
        out.append("| key | type | default | unit | LAMMPS | meaning |")
        out.append("| --- | --- | --- | --- | --- | --- |")
        for r in sec.rows:
            typ = r.type + (f" ({r.constraints})" if r.constraints and r.constraints not in r.type else "")
            out.append(f"| {r.path} | {_cell(typ)} | {r.default} | {_kind(r.unit) or '—'} | {r.lammps or '—'} | "
                       f"{_cell(r.description) or '—'} |")
        out.append("")
    return "\n".join(out)


def styles_table() -> str:
    """Wall styles: one row per `style:` value of the wall models, with the face arguments of the
    style registry (``wallbatch.styles.STYLES``: LAMMPS fix name, parameters and their unit kinds)
    where it has an entry, else of the face model."""
    registry = _registry()
    rows = ["| style | LAMMPS fix | face arguments (positional order) | other keys |", "| --- | --- | --- | --- |"]
    sections = walk(_config_model())
    for sec in sections:
        if sec.path != "walls.ID" or "(`style:`" not in sec.title:
            continue
        note = sec.title[len("`walls.ID`"):]
        face = next((f for f in sections if f.path == "walls.ID.FACE" and f.title.endswith(note)), None)
        args = ", ".join(r.path for r in face.rows) if face else "—"
        other = ", ".join(r.path for r in sec.rows if r.path != "`style`" and not r.path.startswith("`xlo`"))
        for style in note.split("`style:`", 1)[1].rstrip(")").replace("\\|", " ").split():
            name = style.strip("`")
            fix = {"region": "wall/region", "region/ees": "wall/region/ees"}.get(name, f"wall/{name}")
            entry_args = args
            if name in registry:
                st = registry[name]
                fix = getattr(st, "lammps", None) or fix
                ptxt = []
                for prm in getattr(st, "parameters", None) or getattr(st, "params", None) or ():
                    pname = getattr(prm, "name", str(prm))
                    kind = getattr(prm, "unit", None) or getattr(prm, "kind", None)
                    ptxt.append(f"`{pname}`" + (f" [{_kind(kind)}]" if isinstance(kind, str) and kind else ""))
                if ptxt:
                    entry_args = ", ".join(["`coord`"] + ptxt)
            rows.append(f"| `{name}` | `fix {fix}` | {entry_args} | {other} |")
    return "\n".join(rows)


# ------------------------------------------------------------------------------------------------
# results variables


def _output_module() -> Any:
    import importlib

    for name in ("wallbatch.io.netcdf", "wallbatch.output"):
        try:
            return importlib.import_module(name)
        except ImportError:
            continue
    raise ImportError("no results writer module (wallbatch.io.netcdf)")


def output_variables() -> str:
    """Results variables with their `long_name` attribute (the writer's own table) and units."""
    mod = _output_module()
    long_names = dict(getattr(mod, "LONG_NAMES", {}))
    long_names.update(getattr(mod, "MIN_OUTPUTS", {}))
    systems = _unit_systems()
    units: dict[str, dict[str, str]] = {}
    unit_fn = getattr(mod, "_units", None)
    for n, u in systems.items():
        try:
            units[n] = unit_fn(types.SimpleNamespace(units=u)) if unit_fn else {}
        except Exception:  # noqa: BLE001 - a changed private helper only costs the units column
            units[n] = {}
        units[n].update({"min_energy_before": u.energy, "min_energy": u.energy, "min_fnorm": u.force})
    names = list(systems)
    rows = ["| variable | long_name | " + " | ".join(f"units ({n})" for n in names) + " |",
            "| --- | --- | " + " | ".join("---" for _ in names) + " |"]
    for var, long_name in long_names.items():
        cells = [units[n].get(var, "1") for n in names]
        rows.append(f"| `{var}` | {_cell(long_name)} | " + " | ".join(f"`{c}`" for c in cells) + " |")
    return "\n".join(rows)


# ------------------------------------------------------------------------------------------------
# CLI


def cli_reference() -> str:
    """Every command of the `wallbatch` Typer app: usage, help, arguments and options."""
    import typer

    from wallbatch.cli import app

    group = typer.main.get_command(app)
    ctx = typer.Context(group, info_name="wallbatch")
    out = []
    for name in group.list_commands(ctx):
        cmd = group.get_command(ctx, name)
        if cmd is None or getattr(cmd, "hidden", False):
            continue
        params = [p for p in cmd.params if not getattr(p, "hidden", False)]
        args = [p for p in params if p.param_type_name == "argument"]
        opts = [p for p in params if p.param_type_name != "argument"]
        usage = " ".join([f"wallbatch {name}"] + [p.name.upper() for p in args] + (["[OPTIONS]"] if opts else []))
        out += [f"## `wallbatch {name}`", "", "```", usage, "```", ""]
        if cmd.help:
            out += [inspect.cleandoc(cmd.help).replace("\n", " "), ""]
        if not params:
            continue
        out += ["| argument / option | type | default | meaning |", "| --- | --- | --- | --- |"]
        for p in params:
            ann = getattr(getattr(p, "type_descriptor", None), "annotation", str)
            is_flag = bool(getattr(p, "is_flag", False))
            if p.param_type_name == "argument":
                shown = f"`{p.name.upper()}`"
                default = "required" if p.required else "—"
            else:
                shown = ", ".join(f"`{n}`" for n in list(p.opts) + list(p.secondary_opts))
                if p.required:
                    default = "required"
                elif is_flag:
                    default = f"`{'--' + p.name if p.default else (p.secondary_opts or ['off'])[0]}`"
                elif p.name == "jobs":
                    default = "the machine's cores"
                else:
                    default = "—" if p.default in (None, (), []) else f"`{p.default}`"
            typ = "flag" if is_flag else type_text(ann)
            if getattr(p, "multiple", False):
                typ = type_text(get_args(ann)[0]) if get_args(ann) else typ
                typ += ", repeatable"
            out.append(f"| {shown} | {typ} | {default} | {_cell(p.help or '') or '—'} |")
        out.append("")
    return "\n".join(out)


GENERATORS = {
    "config-keys": config_keys,
    "unit-kinds": unit_kinds_table,
    "wall-styles": styles_table,
    "cli": cli_reference,
    "output-variables": output_variables,
    "sweep-keys": lambda: config_keys(sweep_sections()),
}


if __name__ == "__main__":
    for name, fn in GENERATORS.items():
        print(f"<!-- {name} -->\n{fn()}\n")
    missing, old = undocumented(), stale()
    if missing:
        print("undocumented keys:", ", ".join(missing), file=sys.stderr)
    if old:
        print("KEYS entries for keys that do not exist:", ", ".join(old), file=sys.stderr)
