"""What the config models do not say about each key: its meaning where the model has no
description, its unit kind and its LAMMPS equivalent. Read by the JSON schema (config/schema.py:
descriptions on every key) and by the docs site's config reference (docs/gen_reference.py).
"""

from __future__ import annotations

from dataclasses import dataclass

from wallbatch.styles import LEPTON, TABLE
from wallbatch.styles.base import WallStyle

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
    "atoms[].create.file": Key("A file relative to the YAML file: an `.npz` archive with `x` (N, 3) and "
                               "optionally `v`, `mass`, `radius`, `shape`, `quat` (N, 4), `angmom`, or (any other "
                               "name) a LAMMPS data file, atom_style atomic, sphere or ellipsoid (its diameters "
                               "become semi-axes); see How-tos: Import a LAMMPS script.", "", "`read_data`"),
    "atoms[].create.ids": Key("LAMMPS data files only: the atom IDs of this group, as ranges in quotes "
                              "(`\"1:200 305\"`); default every atom of the file.", "",
                              "`group ID id 1:200 305`"),
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
    "atoms[].velocity.shared": Key("A label: the groups whose velocities give the same label (and the same "
                                   "temperature) are drawn as one set, zero net momentum and exactly the "
                                   "temperature over all their atoms.", "",
                                   "`velocity G create` on a group spanning several wallbatch groups"),
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
    "walls.ID.cutoff_mode": Key("Cut-off treatment of a soft wall (flat or region): `shift`, `force-shift` or "
                                "`smooth`.", "", "— (`shift` is LAMMPS's; the others cannot be exported)"),
    "walls.ID.switch_on": Key("`cutoff_mode: smooth`: where the switch starts, 0 <= switch_on < cutoff.",
                              "distance", "—"),
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
    "walls.ID.seed": Key("flow, reflect/stochastic: the wall's seed, combined with the master seed and the case coordinates.",
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
    "walls.ID.rstyle": Key("reflect/stochastic: `diffusive`, `maxwell` (one accommodation coefficient) or "
                           "`ccl` (Cercignani-Lampis, three).", "", "`wall/reflect/stochastic RSTYLE`"),
    "walls.ID.FACE.temp": Key("reflect/stochastic: wall temperature of the reflected velocities.", "temperature",
                              "`TEMP`"),
    "walls.ID.FACE.vel": Key("reflect/stochastic: wall velocity [vx, vy, vz], in the wall's plane.", "velocity",
                             "`VX VY VZ`"),
    "walls.ID.FACE.accom": Key("reflect/stochastic: accommodation, one number (maxwell: the diffusive "
                               "fraction) or [ax, ay, az] (ccl: tangential velocity and normal energy "
                               "accommodation), each in [0, 1]; none for diffusive.", "", "`ACCOM...`"),
}


def _registry_keys(style: WallStyle) -> dict[str, Key]:
    """The config keys of a per-face registry entry (wall/lepton, wall/table) from the entry's own
    parameters (their doc and unit: one place), the cut-off left to the common key: each face's
    `walls.ID.FACE.NAME` and each wall's `walls.ID.NAME`, with the fix line they are words of."""
    line = " ".join([style.lammps, *(p.name.upper() for p in style.wall_parameters), "FACE COORD",
                     *(p.name.upper() for p in style.parameters if p.kind != "mapping")])
    out: dict[str, Key] = {}
    for prefix, params in (("walls.ID.FACE.", style.parameters), ("walls.ID.", style.wall_parameters)):
        for p in params:
            if p.name == "cutoff":
                continue
            # a mapping (wall/lepton's params) has no word: it is folded into the quoted expression
            word = (f"in {next(q.name.upper() for q in style.parameters if q.quoted)}" if p.kind == "mapping"
                    else p.name.upper())
            out[prefix + p.name] = Key(f"{style.name}: {p.doc}.", p.unit, f"`{line}`: {word}")
    return out


KEYS.update(_registry_keys(LEPTON))
KEYS.update(_registry_keys(TABLE))
