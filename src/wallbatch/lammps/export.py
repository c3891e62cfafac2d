"""`wallbatch export-lammps`: one case as a LAMMPS input script and data file (docs/howto/validate.md).

The export reproduces the case exactly: the data file holds the case's initial positions,
velocities, masses and radii as shortest round-trip floats (`repr`), every value is in box units
(lattice values are converted; variable wall coordinates in lattice units get a scaled helper
variable), walls keep their config order, `fix dt/reset` comes after every wall (wallbatch's step-0
ordering), and `thermo_style custom` lists the outputs wallbatch samples with `thermo_modify norm
no`. A comment block at the top lists every row of the decisions table (docs/deviations.md;
physics in docs/physics.md) the case touches.

Adding a feature is one small function and one registry line:
  * a wall style: every style of the registry (wallbatch.styles.STYLES) is written by
    `_soft_wall` from its entry (fix wall/STYLE, its parameters, its decisions-table rows);
    other walls have a writer in `WALL_WRITERS` (config style name -> writer(fid, wall, spec, s)):
    reflect, region (fix wall/region), region/ees (fix wall/region/ees) and flow (fix wall/flow);
  * a pair style: a writer in `PAIR_WRITERS` (lj/cut);
  * an atom kind: a writer in `ATOM_WRITERS` (chosen by `_atom_style`: atomic, sphere, ellipsoid);
  * `minimize:` is written by `_minimize` (min_style, min_modify dmax, minimize, then
    reset_timestep 0 so the run's samples start at step 0, as wallbatch's).
Anything without a writer is refused by `check_exportable` with "cannot export yet".
Everything here returns text; `write_export` puts it in files.
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from wallbatch.version import __version__
from wallbatch.config.ensemble import to_ensemble_line
from wallbatch.config.fixline import to_fix_line
from wallbatch.config.models import Config, config_from_dict
from wallbatch.config.sweep import SweepCase, SweepPlan, config_to_dict, set_path
from wallbatch.expr import Binary, Call, Keyword, Node, Num, Unary, to_lammps
from wallbatch.scene.build import build_case
from wallbatch.scene.case import Case, ReflectSpec, RegionWallSpec, SoftWallSpec
from wallbatch.styles.cutoff import CutoffStyle
from wallbatch.styles.table import TABLE, TableData, WallTable
from wallbatch.styles import STYLES
from wallbatch.units import UNIT_SYSTEMS

__all__ = [
    "ATOM_WRITERS",
    "DECISIONS",
    "PAIR_WRITERS",
    "WALL_WRITERS",
    "Column",
    "ExportError",
    "LammpsExport",
    "check_exportable",
    "export_case",
    "export_selected",
    "lab_frame",
    "lammps_ready",
    "select_case",
    "write_export",
]


class ExportError(ValueError):
    """The case cannot be written as a LAMMPS input (yet), or the selection is invalid."""


# ----------------------------------------------------------------------------- results of an export


@dataclass(frozen=True)
class Column:
    """One compared output: `label` names the wallbatch output (`ke`, `wall_energy[zw]`,
    `wall_force[zw/zlo]`, `region_force[rod/x]`, `min_energy`), `keyword` the LAMMPS thermo
    keyword (or, for source "min", the `MIN_RESULTS` entry), `key`/`index` where the value sits in
    the engine's per-case results (`CaseResult.data[key][:, index]`; min_* are scalars)."""

    label: str
    keyword: str
    key: str
    index: int | tuple[int, ...] | None = None  # region_force: (fix, x/y/z)
    source: str = "thermo"  # thermo: a thermo_style column; min: a minimization result (`MIN_RESULTS`)


@dataclass(frozen=True)
class LammpsExport:
    """A case as LAMMPS input: the script text, the data file text and what to compare."""

    script: str
    data: str
    script_name: str
    data_name: str
    columns: tuple[Column, ...]  # thermo columns after `step`, in order, then min_* results
    steps: int
    thermo: int
    decisions: tuple[str, ...]  # decisions-table rows this case touches ("topic: what it means here")
    notes: tuple[str, ...]  # other export notes
    expected: dict[str, str] = field(default_factory=dict)  # output label -> why it differs by design
    region_colloid: tuple[str, ...] = ()  # wall/region colloid fix IDs (validate: the force-matched variant)
    force_matched: bool = False  # written with epsilon -> -epsilon on those fixes (see `export_case`)
    files: dict[str, str] = field(default_factory=dict)  # other files beside the data file (name -> text)
    table_rtol: float = 0.0  # interpolation error of the wall/table files (`cutoff_table_error`); 0: none

    @property
    def thermo_columns(self) -> tuple[Column, ...]:
        return tuple(c for c in self.columns if c.source == "thermo")


# ----------------------------------------------------------------------------- decisions table

# The rows of the decisions table (docs/deviations.md) that today's features can touch.
DECISIONS: dict[str, str] = {
    "dt_reset_order": "dt/reset at step 0: wallbatch computes the step-0 dt after all forces; fix dt/reset is "
                      "therefore defined after every wall fix",
    "wiggle_dt_reset": "vdisplace, swiggle, cwiggle with dt_reset: LAMMPS refuses them with fix dt/reset; wallbatch "
                       "uses the elapsed simulated time, so they are written with the thermo keyword time: "
                       "vdisplace(x,y) = x+y*time, swiggle(x,y,z) = x+y*sin(2*PI/z*time), "
                       "cwiggle(x,y,z) = x+y*(1-cos(2*PI/z*time))",
    "dt_bounds": "dt_reset tmin / tmax: no bound (INF, NULL or null in the config) is written as NULL, the only "
                 "form LAMMPS accepts",
    "norm": "wall outputs in lj units: wallbatch reports extensive totals; thermo_modify norm no (LAMMPS's lj "
            "default, norm yes, would divide pe, ke, etotal and f_ID by the atom count)",
    "random": "random numbers: the positions/velocities wallbatch drew (NumPy generators) are in the data file; "
              "this script draws no random numbers",
    "edge": "EDGE: the box bound; this box never changes, so LAMMPS's EDGE (the bound at fix creation) is the "
            "same plane",
    "region_colloid": "wall/region with colloid: wallbatch uses the fix wall/colloid physics on the region surface "
                      "(energy and force consistent); LAMMPS's wall/region colloid flips the force and the sign of "
                      "the energy's log term and subtracts an LJ93-style constant (docs/deviations.md, quirk #1). This script "
                      "runs LAMMPS's own physics, so trajectories differ once a particle feels the wall; written with "
                      "epsilon -> -epsilon, LAMMPS's flipped force is exactly fix wall/colloid's (energies still "
                      "differ): `wallbatch validate` compares that variant",
    "region_ees_sigma": "wall/region/ees closeness test: wallbatch stops when r <= sigma_n along the true contact "
                        "normal; LAMMPS tests a per-axis sigma_n (quirk #14). Both agree while every ellipsoid keeps "
                        "clear of the surface; on curved or diagonal contacts LAMMPS can go on with NaN energies "
                        "where wallbatch stops with an error",
    "flow_wrap": "wall/flow at the periodic boundary: wallbatch wraps positions every step (one redraw per "
                 "crossing); so does this script (neigh_modify every 1 delay 0 check no): LAMMPS's default "
                 "delayed wrapping would redraw twice per boundary crossing",
    "flow_rule": "wall/flow rule: exact (wallbatch's default): an atom redrawn back over the wall it just crossed is "
                 "not redrawn again on its return; LAMMPS redraws again (rule: lammps), so its ideal gas streams "
                 "faster than vflow. This script runs LAMMPS's rule",
    "flow_random": "wall/flow random numbers: wallbatch draws from NumPy generators (one stream per case and flow "
                   "wall), LAMMPS from RANMAR seeded with SEED: the runs agree statistically, not sample by sample "
                   "(`wallbatch validate` refuses flow cases)",
    "stochastic_random": "wall/reflect/stochastic random numbers: wallbatch draws from NumPy generators (one stream "
                         "per case and wall), LAMMPS from its own generator seeded with SEED: the runs agree "
                         "statistically, not sample by sample",
    "reflect_frame": "wall/reflect on a moving wall: frame: wall (v -> 2 v_wall - v) cannot be expressed in LAMMPS, "
                     "which does v -> -v; this script reflects in the lab frame, so velocities differ from "
                     "wallbatch's after the first reflection on a moving wall (`wallbatch validate` compares the "
                     "case with frame: lab and reports the frame: wall difference as expected)",
    "min_norm": "minimize: wallbatch minimizes the extensive energy (pair + walls with energy: true); "
                "thermo_modify norm no comes before minimize here, so LAMMPS does too (its lj default, norm yes, "
                "divides the energy by N, which moves the absolute thresholds of its energy tolerance)",
    "min_forces_zero": "minimize (cg) with every force exactly zero: wallbatch stops with `forces are zero`, LAMMPS "
                       "with `search direction is not downhill` (same state; `wallbatch validate` reports the "
                       "stopping criterion as expected then)",
    "min_fire_velocities": "minimize (fire): wallbatch's run starts from the velocities the config created, as if "
                           "`velocity` came after `minimize`; LAMMPS's fire leaves its own damped velocities in the "
                           "atoms, so this script stores the velocities before minimize (fix store/state) and sets "
                           "them back after it",
}

# the wall styles' own rows: STYLE (a style's decision), STYLE_PARAM (a parameter LAMMPS takes as a
# number only)
DECISIONS.update({s.name: s.decision for s in STYLES.values() if s.decision})
DECISIONS.update({f"{s.name}_{p.name}": p.lammps_variable_note for s in STYLES.values() for p in s.parameters
                  if p.lammps_variable_note})

# source "min" columns: wallbatch result -> where the LAMMPS value comes from (validate.run_lammps):
# "Minimization stats" of the log (energy_before: 15 digits, as LAMMPS prints it) or the
# `print "wb_min ..."` line written after minimize (17 digits)
MIN_RESULTS: dict[str, str] = {
    "min_energy_before": "energy_before", "min_energy": "energy", "min_fnorm": "fnorm",
    "min_iterations": "iterations", "min_evaluations": "evaluations", "min_stop_reason": "stop_reason",
}


# ----------------------------------------------------------------------------- selecting and preparing


def _same(value: Any, text: str) -> bool:
    """A sweep coordinate equals the text a user typed (numbers within 1e-9 relative; a list value,
    `[0.7, 1.4]`, element by element)."""
    if str(value) == text:
        return True
    if isinstance(value, (list, tuple)):
        import yaml  # noqa: PLC0415 - only for list-valued coordinates

        try:
            typed = yaml.safe_load(text)
        except yaml.YAMLError:
            return False
        return (isinstance(typed, list) and len(typed) == len(value)
                and all(_same(v, str(t)) for v, t in zip(value, typed)))
    try:
        return math.isclose(float(value), float(text), rel_tol=1e-9, abs_tol=0.0)
    except (TypeError, ValueError):
        return False


def select_case(plan: SweepPlan, sel: str | None) -> SweepCase:
    """One case of a plan: by index (`3`, C order over the sweep dimensions, from 0) or by
    coordinates (`epsilon=1.0,sigma=0.8`; a zip parameter may stand for its dimension). With no
    selection the plan must have exactly one case."""
    cases = plan.cases
    if sel is None or not sel.strip():
        if len(cases) == 1:
            return cases[0]
        dims = ", ".join(f"{d.name} ({len(d.values)})" for d in plan.dims)
        example = ",".join(f"{k}={v}" for k, v in cases[0].coords.items())
        raise ExportError(f"the config has {len(cases)} cases (dimensions {dims}): choose one with --case, "
                          f"e.g. --case {example} or --case 0")
    sel = sel.strip()
    if re.fullmatch(r"-?\d+", sel):
        i = int(sel)
        if not -len(cases) <= i < len(cases):
            raise ExportError(f"--case {sel}: there are {len(cases)} case(s), indexed 0 to {len(cases) - 1} "
                              f"(or -{len(cases)} to -1 from the last)")
        return cases[i]
    extras = {k: d for d in plan.dims for k in d.extra}
    names = [d.name for d in plan.dims] + list(extras)
    wanted: list[tuple[str, str]] = []
    for item in re.split(r",(?![^\[]*\])", sel):  # commas outside a list value [0.7, 1.4]
        key, eq, value = item.partition("=")
        key, value = key.strip(), value.strip()
        if not eq or not key:
            raise ExportError(f"--case {sel}: write name=value[,name=value...] or an index")
        if key not in names:
            raise ExportError(f"--case {sel}: {key} is not a sweep dimension "
                              f"({', '.join(names) if names else 'the config has no sweep'})")
        wanted.append((key, value))

    def coord(sc: SweepCase, key: str) -> Any:
        if key in sc.coords:
            return sc.coords[key]
        d = extras[key]
        return d.extra[key][0][sc.coords[d.name]]

    found = [sc for sc in cases if all(_same(coord(sc, k), v) for k, v in wanted)]
    if not found:
        raise ExportError(f"--case {sel}: no case has these coordinates; e.g. {cases[0].label}")
    if len(found) > 1:
        raise ExportError(f"--case {sel}: {len(found)} cases match (e.g. {found[0].label}; {found[1].label}): "
                          f"give more coordinates")
    return found[0]


def check_exportable(cfg: Config) -> None:
    """Refuse, with "cannot export yet", anything that has no LAMMPS writer in this version."""
    problems = []
    if cfg.pair is not None and cfg.pair.style not in PAIR_WRITERS:
        problems.append(f"pair: {cfg.pair.style} (pair forces)")
    shaped = [i for i, g in enumerate(cfg.atoms) if g.shape is not None]
    for i, g in enumerate(cfg.atoms):
        if (g.shape is not None or g.orientation is not None or g.angmom is not None) and "ellipsoid" not in ATOM_WRITERS:
            problems.append(f"atoms.{i}: ellipsoid atoms (shape, orientation, angmom)")
    sized = [i for i, g in enumerate(cfg.atoms) if g.radius]
    if shaped and sized:
        problems.append(f"atoms.{sized[0]} (radius) with atoms.{shaped[0]} (shape): spheres and ellipsoids together "
                        f"(atom_style hybrid sphere ellipsoid)")
    for fid, wall in cfg.walls.items():
        if wall.style not in WALL_WRITERS:
            problems.append(f"walls.{fid}: wall/{wall.style}")
        elif getattr(wall, "cutoff_mode", "shift") != "shift" and (
                WALL_WRITERS[wall.style] is not _soft_wall or STYLES[wall.style].needs_radius):
            problems.append(f"walls.{fid}: cutoff_mode {wall.cutoff_mode} on wall/{wall.style} (LAMMPS's wall fixes "
                            f"only shift the energy at the cut-off; a flat wall without a particle radius is written "
                            f"as a wall/table, this one cannot be: write it with cutoff_mode: shift to compare "
                            f"with LAMMPS)")
    if problems:
        raise ExportError("cannot export yet: " + "; ".join(problems)
                          + " (no LAMMPS writer in this version of wallbatch export-lammps)")


def _with(cfg: Config, changes: dict[str, Any]) -> Config:
    """The config with dotted paths set to new values, validated again."""
    data = config_to_dict(cfg)
    for path, value in changes.items():
        set_path(data, path, value)
    return config_from_dict(data, base=cfg._base_dir)


def lammps_ready(cfg: Config, steps: int | None = None) -> tuple[Config, list[str]]:
    """The config as a step-based run LAMMPS can do exactly, and notes on what changed.

    `steps` overrides the run length. A run to a simulated time (`run: {time: T}`) becomes
    round(T/dt) steps, and time-based sampling every round(t/dt) steps (dt = the timestep); with
    dt_reset (dt varies) a time-based run needs `steps`, and time-based sampling is converted
    with the initial timestep."""
    notes: list[str] = []
    run = cfg.run
    dt = cfg.timestep if cfg.timestep is not None else UNIT_SYSTEMS[cfg.units].dt
    if run.time is not None and steps is None:
        if cfg.dt_reset is not None:
            raise ExportError(f"run: {{time: {run.time}}} with dt_reset cannot be reproduced in LAMMPS, whose runs "
                              f"count steps while dt varies: give --steps N for a step-based run")
        steps = max(0, round(run.time / dt))
        exact = math.isclose(steps * dt, run.time, rel_tol=1e-9)
        notes.append(f"run: {{time: {run.time}}} converted to {steps} steps of dt {dt!r}"
                     + ("" if exact else f" (time {steps * dt!r}: not a whole number of steps)")
                     + " (LAMMPS runs count steps)")
    elif steps is not None and steps != run.steps:
        notes.append(f"run length {steps} steps (--steps; the config says "
                     f"{'steps: ' + str(run.steps) if run.steps is not None else 'time: ' + str(run.time)})")
    if steps is None:
        return cfg, notes
    if steps < 0:
        raise ExportError(f"--steps {steps}: must be >= 0")
    thermo = run.thermo
    if not isinstance(thermo, int):
        thermo = max(1, round(thermo.time / dt))
        notes.append(f"sampling every {run.thermo.time} time units converted to every {thermo} steps "
                     f"(interval / timestep {dt!r})")
    changes: dict[str, Any] = {"run": {"steps": int(steps), "thermo": int(thermo)}}
    if cfg.output.profiles or cfg.output.averages is not None:  # their windows/start need the full run
        changes["output.profiles"], changes["output.averages"] = {}, None
        notes.append("output.profiles and output.averages left out (not exported; the run length changed)")
    return _with(cfg, changes), notes


def lab_frame(cfg: Config) -> tuple[Config, list[str]]:
    """Reflect walls with `frame: wall` turned into `frame: lab` (LAMMPS's v -> -v), and a note;
    the config itself when it has none."""
    walled = [fid for fid, w in cfg.walls.items() if w.style == "reflect" and w.frame == "wall"]
    if not walled:
        return cfg, []
    note = (f"reflect wall(s) {', '.join(walled)} compared with frame: lab (LAMMPS's v -> -v): frame: wall "
            f"cannot be expressed in LAMMPS")
    return _with(cfg, {f"walls.{fid}.frame": "lab" for fid in walled}), [note]


# ----------------------------------------------------------------------------- the script builder


def _num(value: float) -> str:
    """A float as the shortest text that reads back to the same double."""
    value = float(value)
    if not math.isfinite(value):
        raise ExportError(f"non-finite number {value!r} cannot be written for LAMMPS")
    return repr(value)


def _lammps_id(name: str, taken: set[str]) -> str:
    """A LAMMPS ID (letters, digits, underscores) for a wallbatch name, unique among `taken`."""
    base = re.sub(r"[^A-Za-z0-9_]", "_", name) or "id"
    out, k = base, 1
    while out in taken:
        out, k = f"{base}_{k}", k + 1
    taken.add(out)
    return out


@dataclass
class _Script:
    """What the writers fill in: commands per section, thermo columns, decisions and notes."""

    cfg: Config
    case: Case
    groups: dict[str, str] = field(default_factory=dict)  # wallbatch group -> LAMMPS group ID
    fix_ids: set[str] = field(default_factory=set)
    variables: dict[str, str] = field(default_factory=dict)  # LAMMPS name -> expression text
    fixes: list[str] = field(default_factory=list)
    columns: list[Column] = field(default_factory=list)
    decisions: dict[str, str] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)
    expected: dict[str, str] = field(default_factory=dict)
    soft_written: list[SoftWallSpec] = field(default_factory=list)  # wall_force indices
    regions: dict[str, str] = field(default_factory=dict)  # wallbatch region name -> `region ...` command
    region_ids: set[str] = field(default_factory=set)
    pair: list[str] = field(default_factory=list)  # pair_style, pair_coeff, ... (after read_data)
    force_matched: bool = False  # wall/region colloid written with -epsilon (validate's variant)
    region_colloid: list[str] = field(default_factory=list)
    minimized_dump: str | Path | None = None  # validate: write_dump of the minimized positions
    table_dir: Path | None = None  # the data file's folder (None: the folder LAMMPS runs in)
    table_name: str = "table.wallbatch"  # the wall/table file of non-shift cut-off walls
    table_text: list[str] = field(default_factory=list)
    table_rtol: float = 0.0

    def decide(self, key: str, text: str | None = None) -> None:
        self.decisions.setdefault(key, text or DECISIONS[key])

    def group(self, name: str) -> str:
        return "all" if name == "all" else self.groups[name]

    def fix_id(self, fid: str) -> str:
        out = _lammps_id(fid, self.fix_ids)
        if out != fid:
            self.notes.append(f"fix ID {fid!r} written as {out!r} (LAMMPS IDs: letters, digits, underscores)")
        return out

    def number(self, value: Any, what: str) -> str:
        """A parameter LAMMPS takes as a number only: a number, or a variable that is constant
        (written as its value, with a note); a time-dependent variable cannot be exported."""
        if not isinstance(value, str):
            return _num(value)
        const = self.case.variables.constant_value(value)
        if const is None:
            raise ExportError(f"{what}: LAMMPS takes a number here and v_{value} changes during the run: cannot "
                              f"export")
        self.notes.append(f"{what}: v_{value} is constant, written as {_num(const)} (LAMMPS takes a number here)")
        return _num(const)

    def energy_column(self, fid: str, lid: str) -> None:
        """f_ID, the fix's global scalar: wall_energy in config order of the fixes that have one."""
        self.columns.append(Column(f"wall_energy[{fid}]", f"f_{lid}", "wall_energy", self.case.fix_order.index(fid)))

    def soft_fix(self, fid: str, lid: str, mapping: dict, spec: SoftWallSpec, force_sign: int = 1) -> None:
        """Write a soft wall fix: its fix line from `mapping`, fix_modify energy/virial as the spec
        asks, its wall_energy column and one wall_force column per face (indices after the soft walls
        written before). `force_sign` -1: LAMMPS's vector is the force on the atoms, so each column
        reads a helper variable of the opposite sign."""
        try:
            self.fixes.append(to_fix_line(lid, mapping))
        except ValueError as exc:  # a value no LAMMPS word can hold (a table path with a double quote)
            raise ExportError(f"{str(exc).replace(f'walls.{lid}', f'walls.{fid}', 1)}: it cannot be written "
                              "in a LAMMPS script") from None
        if spec.energy:
            self.fixes.append(f"fix_modify {lid} energy yes")
        if spec.virial:
            self.fixes.append(f"fix_modify {lid} virial yes")
        self.energy_column(fid, lid)
        first = sum(len(w.faces) for w in self.soft_written)
        self.soft_written.append(spec)
        for i, face in enumerate(spec.faces):
            keyword = f"f_{lid}[{i + 1}]"
            if force_sign < 0:
                helper = _lammps_id(f"wb_{lid}_{face.name}_force", set(self.variables) | set(self.case.variables.names()))
                self.variables[helper] = f"-{keyword}"
                keyword = f"v_{helper}"
            self.columns.append(Column(f"wall_force[{face.label}]", keyword, "wall_force", first + i))

    def scaled_variable(self, name: str, scale: float, label: str) -> str:
        """A helper variable `name * scale` (a variable wall coordinate in lattice units)."""
        helper = _lammps_id(f"wb_{label.replace('/', '_')}", set(self.variables) | set(self.case.variables.names()))
        self.variables[helper] = f"v_{name}*{_num(scale)}"
        self.notes.append(f"{label}: coordinate v_{name} is in lattice units: v_{helper} = v_{name}*{_num(scale)} "
                          f"(the lattice spacing) is used with units box")
        return helper


WallWriter = Callable[[str, Any, Any, _Script], None]


def _coord_word(face: Any, written: Any, s: _Script) -> str:
    """A face's coordinate: EDGE as written, a number in box units, or v_name (scaled when the
    wall is in lattice units)."""
    if written == "EDGE":
        s.decide("edge")
        return "EDGE"
    if isinstance(face.coord, str):
        return f"v_{face.coord}" if face.scale == 1.0 else f"v_{s.scaled_variable(face.coord, face.scale, face.label)}"
    return _num(face.coord)


def _soft_wall(fid: str, wall: Any, spec: SoftWallSpec, s: _Script) -> None:
    """fix wall/lj93 | lj126 | lj1043 | colloid | harmonic | morse | ees, in box units; fix_modify
    energy yes for `energy: true` (virial yes for `virial: true`; wall/ees has no virial); columns
    f_ID and f_ID[i]."""
    if spec.cutoff_mode != "shift":
        _cutoff_table_wall(fid, wall, spec, s)
        return
    lid = s.fix_id(fid)
    written = dict(wall.faces())
    mapping: dict[str, Any] = {"style": wall.style, "group": s.group(wall.group), "units": "box"}
    if wall.pbc:
        mapping["pbc"] = True
    style = spec.style
    for face in spec.faces:
        values: dict[str, Any] = {"coord": _coord_word(face, written[face.name].coord, s)}
        for key, v in face.params.items():
            note = style.param(key).lammps_variable_note
            if isinstance(v, str) and note:
                const = s.case.variables.constant_value(v)
                if const is None:
                    raise ExportError(f"walls.{fid}.{face.name}.{key}: LAMMPS ignores a variable {key} ({key} = 0, "
                                      f"docs/deviations.md, decisions table) and v_{v} changes during the run: cannot export")
                s.decide(f"{style.name}_{key}", note + f" ({face.label}: v_{v} = {_num(const)})")
                v = const
            values[key] = f"v_{v}" if isinstance(v, str) else float(v)
        mapping[face.name] = values
    if style.decision:
        s.decide(style.name, style.decision)
    if not spec.virial and getattr(wall, "virial", False):
        s.notes.append(f"walls.{fid}: virial: true has no effect on wall/{wall.style} (it has no virial)")
    s.soft_fix(fid, lid, mapping, spec)


# wall/table of a non-shift cut-off: N grid points per mode (smooth's force has a jump of d2F/dr2 at
# switch_on and rc, where a cubic spline's error is O(h^2), hence more points), the first at
# TABLE_LO_FRACTION sigma (r0 for morse; see `_table_lo`), error measured at TABLE_PROBES points
TABLE_N: dict[str, int] = {"force-shift": 4000, "smooth": 16000}
TABLE_LO_FRACTION = 0.5
TABLE_PROBES = 20011


def _table_lo(p: dict[str, float]) -> float:
    """The table's first distance: half of sigma (r0 for morse), where the wall's energy is large
    (lj93: 60 eps) but finite; 1e-3 of the cut-off for a style with neither (harmonic: finite
    everywhere). [distance]"""
    scale = p.get("sigma", p.get("r0"))
    if scale is None:
        return 1e-3 * float(p["cutoff"])
    return TABLE_LO_FRACTION * min(float(scale), float(p["cutoff"]))


def cutoff_table_error(table: WallTable, energy_force: Callable, lo: float, hi: float) -> float:
    """The interpolation error of a spline wall/table against the function it samples, relative:
    the largest |F_tab - F| / (|F| + F_s) and |E_tab - E| / (|E| + E_s) over TABLE_PROBES points of
    [lo, hi] (E_tab the energy LAMMPS uses: minus its linear lookup at the cut-off), with F_s, E_s
    the largest |F|, |E| from 2 lo (sigma or r0) to hi: relative where the wall is steep, relative
    to the wall's typical size where F or E is small. [-]"""
    r = np.linspace(lo, hi, TABLE_PROBES)
    e, f = energy_force(r)
    et, ft = table.shifted_energy_force(r, hi)
    typical = r >= 2.0 * lo
    es, fs = np.max(np.abs(e[typical])), np.max(np.abs(f[typical]))
    return float(max(np.max(np.abs(et - e) / (np.abs(e) + es)), np.max(np.abs(ft - f) / (np.abs(f) + fs))))


def _cutoff_table_wall(fid: str, wall: Any, spec: SoftWallSpec, s: _Script) -> None:
    """A flat soft wall with cutoff_mode force-shift or smooth as `fix wall/table spline N`: each
    face's treated energy and force (styles.cutoff) sampled on N = TABLE_N[mode] points from `_table_lo` to
    the cut-off into one table file beside the data file (a keyword per face, FP from the force's
    central difference), with a decisions-table row; its interpolation error joins `table_rtol`."""
    lid = s.fix_id(fid)
    written = dict(wall.faces())
    treated = CutoffStyle(spec.style, spec.cutoff_mode)
    n = TABLE_N[spec.cutoff_mode]
    mapping: dict[str, Any] = {"style": TABLE.name, "group": s.group(wall.group), "units": "box",
                               "tabstyle": "spline", "N": n}
    if wall.pbc:
        mapping["pbc"] = True
    path = s.table_name if s.table_dir is None else str(Path(s.table_dir) / s.table_name)
    ranges, error = [], 0.0
    for face in spec.faces:
        p = {}
        for key, v in face.params.items():
            if isinstance(v, str):
                const = s.case.variables.constant_value(v)
                if const is None:
                    raise ExportError(f"walls.{fid}.{face.name}.{key}: v_{v} changes during the run and cutoff_mode "
                                      f"{spec.cutoff_mode} is exported as a LAMMPS wall/table sampled once: cannot "
                                      f"export (use a number, or cutoff_mode: shift)")
                s.notes.append(f"walls.{fid}.{face.name}.{key}: v_{v} is constant: its value {_num(const)} is in "
                               f"the wall/table")
                v = const
            p[key] = float(v)
        lo, hi = _table_lo(p), p["cutoff"]
        if spec.cutoff_mode == "smooth" and p["switch_on"] > lo:  # a grid point on r_on (d2F/dr2 jumps there)
            m = max(1, round((hi - p["switch_on"]) / (hi - lo) * (n - 1)))
            lo = hi - (n - 1) * ((hi - p["switch_on"]) / m)
            if lo <= 0.0:
                lo = hi - (n - 1) * ((hi - p["switch_on"]) / (m + 1))
        r = lo + np.arange(n) * ((hi - lo) / (n - 1))
        r[-1] = hi
        energy_force = lambda x, p=p: treated.energy_force(x, p)
        e, f = (np.asarray(a, dtype=np.float64) for a in energy_force(r))
        if not (np.all(np.isfinite(e)) and np.all(np.isfinite(f))):
            raise ExportError(f"walls.{fid}.{face.name}: the wall is not finite at r = {lo!r}: cannot tabulate")
        h = 1e-5 * (hi - lo)
        fp = tuple(float((energy_force(np.float64(x + h))[1] - energy_force(np.float64(x - h))[1]) / (2 * h))
                   for x in (lo, hi))
        keyword = f"{lid}_{face.name}"
        table = WallTable.build(TableData(keyword, r, e, f, fp[0], fp[1]), "spline", n)
        error = max(error, cutoff_table_error(table, energy_force, lo, hi))
        about = ", ".join(f"{k}={v!r}" for k, v in p.items())
        title = f"# {face.label}: wall/{spec.style.name} cutoff_mode {spec.cutoff_mode} ({about}), {n} points"
        s.table_text += [f"{title} on [{lo!r}, {hi!r}]", "", keyword, f"N {n} FP {fp[0]!r} {fp[1]!r}", ""]
        s.table_text += [f"{k} {ri!r} {ei!r} {fi!r}" for k, (ri, ei, fi)
                         in enumerate(zip(r.tolist(), e.tolist(), f.tolist()), start=1)]
        s.table_text.append("")
        mapping[face.name] = {"coord": _coord_word(face, written[face.name].coord, s), "file": path,
                              "keyword": keyword, "cutoff": hi}
        ranges.append(f"{face.label} [{lo!r}, {hi!r}]")
    s.decide(f"cutoff_table_{fid}",
             f"walls.{fid} has cutoff_mode {spec.cutoff_mode} (docs/physics.md §17), which no LAMMPS wall fix "
             f"offers: it is written as fix wall/table spline {n} reading {s.table_name}, the treated energy "
             f"and force sampled on {n} points over {', '.join(ranges)} (an atom nearer to the wall than the "
             f"first point stops LAMMPS). LAMMPS interpolates the table, so it agrees with wallbatch only to the "
             f"interpolation error of the table ({error:.2g} relative: docs/howto/validate.md)")
    s.table_rtol = max(s.table_rtol, error)
    s.soft_fix(fid, lid, mapping, spec)


def _reflect_wall(fid: str, wall: Any, spec: ReflectSpec, s: _Script) -> None:
    """fix wall/reflect in box units (no outputs in LAMMPS). frame: wall is written as LAMMPS's
    lab-frame reflection, with the decisions-table note."""
    lid = s.fix_id(fid)
    if wall.pbc and any(s.case.periodic[f.dim] for f in spec.faces):
        raise ExportError(f"walls.{fid}: wall/reflect on a periodic dimension (pbc: true) is refused by LAMMPS")
    written = dict(wall.faces())
    mapping: dict[str, Any] = {"style": "reflect", "group": s.group(wall.group), "units": "box"}
    for face in spec.faces:
        mapping[face.name] = _coord_word(face, written[face.name].coord, s)
    if spec.frame == "wall":
        s.decide("reflect_frame")
    s.fixes.append(to_fix_line(lid, mapping))
    if "reflect_count" in s.case.outputs or "reflect_impulse" in s.case.outputs:
        s.notes.append(f"reflect_count / reflect_impulse of {fid} are wallbatch outputs with no LAMMPS counterpart")


def _bound(value: float, lo: bool) -> str:
    """A block or cylinder bound: an infinite one (an open side, -inf for a lower bound, +inf for an
    upper one) as LAMMPS's `INF`, which means -infinity as a lower bound and +infinity as an upper
    one (`-INF` is no number to LAMMPS)."""
    value = float(value)
    if value == (-math.inf if lo else math.inf):
        return "INF"
    return _num(value)


def _region_command(name: str, geom: Any, s: _Script) -> str:
    """The LAMMPS region of a wall (defined once per region), in box units: `region ID block xlo
    xhi ylo yhi zlo zhi`, `sphere xc yc zc R` or `cylinder dim c1 c2 R lo hi`, with its side."""
    if name not in s.regions:
        rid = _lammps_id(name, s.region_ids)
        if rid != name:
            s.notes.append(f"region {name!r} written as {rid!r} (LAMMPS IDs: letters, digits, underscores)")
        if geom.style == "block":
            args = " ".join(f"{_bound(lo, True)} {_bound(hi, False)}" for lo, hi in zip(geom.lo, geom.hi))
        elif geom.style == "sphere":
            args = " ".join(_num(c) for c in (*geom.center, geom.radius))
        else:
            args = ("xyz"[geom.axis] + " " + " ".join(_num(c) for c in (*geom.center, geom.radius))
                    + f" {_bound(geom.lo, True)} {_bound(geom.hi, False)}")
        s.regions[name] = f"region {rid} {geom.style} {args} side {geom.side} units box"
        if s.cfg.regions[name].units == "lattice":
            s.notes.append(f"region {name} is in lattice units: written in box units")
    return s.regions[name].split()[1]


def _region_wall(fid: str, wall: Any, spec: RegionWallSpec, s: _Script) -> None:
    """fix wall/region RID STYLE eps sigma rc (morse: D0 alpha r0 rc) or fix wall/region/ees RID
    eps sigma rc, after its `region` (box units); fix_modify energy / virial; columns f_ID (energy)
    and f_ID[1..3] (region_force: the force of the atoms on the wall). Colloid: the decisions
    table; with `s.force_matched` epsilon is written negated (LAMMPS's flipped force is then
    exactly fix wall/colloid's, so trajectories agree and only the energies differ)."""
    lid = s.fix_id(fid)
    rid = _region_command(spec.region_name, spec.region, s)
    what = f"walls.{fid}"
    if spec.kind == "region/ees":
        head, keys = f"wall/region/ees {rid}", ("epsilon", "sigma", "cutoff")
        s.decide("region_ees_sigma")
    else:
        name = spec.potential.name
        head = f"wall/region {rid} {name}"
        keys = spec.potential.params
    params = dict(spec.params)
    for p in spec.potential.parameters if spec.potential is not None else ():
        if p.name not in params and p.placeholder is not None:
            params[p.name] = p.placeholder  # ignored by the style; LAMMPS still reads a number there
    words = {k: s.number(params[k], f"{what}.{k}") for k in keys}
    if spec.kind == "region" and spec.potential.region_quirk:
        s.decide("region_colloid")
        s.region_colloid.append(fid)
        if s.force_matched:
            words["epsilon"] = _num(-float(words["epsilon"]))
            why = ("wall/region colloid written with -epsilon: LAMMPS's flipped force equals fix wall/colloid's, "
                   "its energy is a different formula (decisions table, docs/deviations.md quirk #1)")
            s.expected[f"wall_energy[{fid}]"] = why
            if spec.energy:
                s.expected.update({"pe": why, "etot": why})
    s.fixes.append(f"fix {lid} {s.group(wall.group)} {head} " + " ".join(words[k] for k in keys))
    if spec.energy:
        s.fixes.append(f"fix_modify {lid} energy yes")
    if spec.virial:
        s.fixes.append(f"fix_modify {lid} virial yes")
    s.energy_column(fid, lid)
    k = [w.fix_id for w in s.case.region_walls].index(fid)
    s.columns += [Column(f"region_force[{fid}/{a}]", f"f_{lid}[{d + 1}]", "region_force", (k, d))
                  for d, a in enumerate("xyz")]


def _flow_wall(fid: str, wall: Any, spec: Any, s: _Script) -> None:
    """fix wall/flow AXIS VFLOW T SEED N w1 .. wN units box (coordinates in box units). LAMMPS's
    rule is `rule: lammps`; `rule: exact` and the random numbers are decisions-table rows; the
    crossings count (flow_crossings) has no LAMMPS counterpart."""
    lid = s.fix_id(fid)
    coords = " ".join(_num(c) for c in spec.walls)
    s.fixes.append(f"fix {lid} {s.group(wall.group)} wall/flow {'xyz'[spec.axis]} {_num(spec.vflow)} "
                   f"{_num(spec.temperature)} {int(wall.seed)} {len(spec.walls)} {coords} units box")
    s.decide("flow_wrap")
    if spec.rule == "exact":
        s.decide("flow_rule")
    s.decide("flow_random")
    if wall.units == "lattice":
        s.notes.append(f"walls.{fid}: coords {list(wall.coords)} lattice spacings written in box units")


def _per_face_wall(fid: str, wall: Any, spec: Any, s: _Script) -> None:
    """A style built per face (fix wall/lepton: the face's expression, its parameters as Lepton
    `;` definitions with this case's values; fix wall/table: the table file by absolute path), in
    box units, each face's words from the registry entry's lammps_face; energy and wall_force
    columns as for the other soft walls. Where LAMMPS's vector is the force on the atoms
    (entry.lammps_force_sign -1, wall/lepton) the wall_force column compares with its negative."""
    entry = STYLES[wall.style]
    lid = s.fix_id(fid)
    written = dict(wall.faces())
    mapping: dict[str, Any] = {"style": wall.style, "group": s.group(wall.group), "units": "box",
                               **{p.name: getattr(wall, p.name) for p in entry.wall_parameters}}
    if wall.pbc:
        mapping["pbc"] = True
    for face, sig in zip(spec.faces, spec.signature):
        values = {**written[face.name].model_dump(), "coord": _coord_word(face, written[face.name].coord, s)}
        mapping[face.name] = entry.lammps_face(values, face.params, sig)
    s.soft_fix(fid, lid, mapping, spec, entry.lammps_force_sign)
    if entry.lammps_force_sign < 0:
        s.notes.append(f"walls.{fid}: LAMMPS's {entry.lammps} vector is the force on the atoms, the opposite of "
                       "wallbatch's wall_force (the force on the wall): compared through v_wb_..._force = -f_ID[i]")
        if spec.virial:
            s.expected["press"] = (f"walls.{fid}: LAMMPS's {entry.lammps} adds its virial with the sign of its vector, "
                                   "the opposite of every other wall's; wallbatch adds the virial of the wall's force, "
                                   "as for every style (decisions table)")


def _stochastic_wall(fid: str, wall: Any, spec: Any, s: _Script) -> None:
    """fix wall/reflect/stochastic rstyle seed face pos temp vx vy vz [accom ...] units box. The
    random numbers differ (decisions table): LAMMPS and wallbatch agree statistically only."""
    lid = s.fix_id(fid)
    if wall.pbc and any(s.case.periodic[f.dim] for f in spec.faces):
        raise ExportError(f"walls.{fid}: wall/reflect/stochastic on a periodic dimension (pbc: true) is refused by "
                          "LAMMPS ('Cannot use fix wall/reflect/stochastic in periodic dimension')")
    written = dict(wall.faces())
    mapping: dict[str, Any] = {"style": "reflect/stochastic", "group": s.group(wall.group), "rstyle": wall.rstyle,
                               "seed": int(wall.seed), "units": "box"}
    for face in spec.faces:
        f = written[face.name]
        mapping[face.name] = {"coord": _coord_word(face, f.coord, s), "temp": f.temp, "vel": list(f.vel)}
        if f.accom is not None:
            mapping[face.name]["accom"] = f.accom if isinstance(f.accom, float) else list(f.accom)
    s.fixes.append(to_fix_line(lid, mapping))
    s.decide("stochastic_random")
    if "reflect_count" in s.case.outputs or "reflect_impulse" in s.case.outputs:
        s.notes.append(f"reflect_count / reflect_impulse of {fid} are wallbatch outputs with no LAMMPS counterpart")


WALL_WRITERS: dict[str, WallWriter] = {
    "reflect/stochastic": _stochastic_wall,
    **{name: _per_face_wall if style.per_face else _soft_wall for name, style in STYLES.items()},
    "reflect": _reflect_wall,
    "region": _region_wall,
    "region/ees": _region_wall,
    "flow": _flow_wall,
}


def _pair_lj_cut(pair: Any, s: _Script) -> None:
    """pair_style lj/cut rc, pair_coeff * * eps sigma (one set for every type), pair_modify shift
    yes for `shift: true`, and the neighbor skin of wallbatch's list (results do not depend on it:
    the list is rebuilt every step here)."""
    p = s.case.pair
    s.pair += [f"pair_style      lj/cut {_num(p.cutoff)}", f"pair_coeff      * * {_num(p.epsilon)} {_num(p.sigma)}"]
    if p.shift:
        s.pair.append("pair_modify     shift yes")
    s.pair.append(f"neighbor        {_num(p.skin)} bin")


# pair style name -> writer(pair model, s)
PAIR_WRITERS: dict[str, Callable[[Any, _Script], None]] = {"lj/cut": _pair_lj_cut}


# ----------------------------------------------------------------------------- atoms and the data file


def _id_ranges(mask: np.ndarray) -> str:
    """Atom IDs (1-based) of a mask as LAMMPS `id` ranges: `1:200 305:310`."""
    idx = np.flatnonzero(mask) + 1
    if idx.size == 0:
        return ""
    breaks = np.flatnonzero(np.diff(idx) != 1)
    starts = np.concatenate([idx[:1], idx[breaks + 1]])
    ends = np.concatenate([idx[breaks], idx[-1:]])
    return " ".join(f"{a}:{b}" if a != b else f"{a}" for a, b in zip(starts.tolist(), ends.tolist()))


def _rows(*cols: np.ndarray) -> list[str]:
    """Text rows of columns: integers as such, floats as repr (exact round trip)."""
    lists = [c.tolist() for c in cols]
    return [" ".join(str(v) if isinstance(v, int) else repr(v) for v in row) for row in zip(*lists)]


@dataclass(frozen=True)
class AtomSections:
    """What an atom kind adds: the atom_style, data-file sections (and header counts), commands
    after read_data, the integrators, computes/variables after the fixes, and thermo keywords
    that replace the default ones for some outputs (ellipsoids: ke and etot with erotate)."""

    style: str
    sections: list[tuple[str, list[str]]]  # (header, rows)
    after_read: list[str]
    ntypes: int
    counts: list[str] = field(default_factory=list)  # extra header lines (`30 ellipsoids`)
    integrate: list[tuple[str, str, str]] = field(default_factory=lambda: [("wb_nve", "all", "nve")])  # ID group style
    extra: list[str] = field(default_factory=list)
    keywords: dict[str, str] = field(default_factory=dict)


def _types(case: Case) -> tuple[np.ndarray, np.ndarray]:
    """One atom type per distinct mass: (masses of the types, type of each atom, 1-based)."""
    masses, inverse = np.unique(case.mass, return_inverse=True)
    return masses, inverse.astype(np.int64) + 1


def _atoms_atomic(case: Case, taken: set[str]) -> AtomSections:
    """atom_style atomic: per-type masses (exact), `id type x y z`, `id vx vy vz`."""
    masses, types = _types(case)
    ids = np.arange(1, case.natoms + 1)
    x, v = case.x, case.v
    return AtomSections("atomic", [
        ("Masses", _rows(np.arange(1, len(masses) + 1), masses)),
        ("Atoms # atomic", _rows(ids, types, x[:, 0], x[:, 1], x[:, 2])),
        ("Velocities", _rows(ids, v[:, 0], v[:, 1], v[:, 2])),
    ], [], len(masses))


def _atoms_sphere(case: Case, taken: set[str]) -> AtomSections:
    """atom_style sphere (finite-size atoms): `id type diameter density x y z`. LAMMPS derives
    the mass from diameter and density with its own rounding, so `set type T mass M` then makes
    every per-atom mass exact."""
    masses, types = _types(case)
    ids = np.arange(1, case.natoms + 1)
    r = case.radius
    density = np.where(r > 0, case.mass / np.where(r > 0, 4.0 / 3.0 * np.pi * r ** 3, 1.0), case.mass)
    x, v = case.x, case.v
    zero = np.zeros(case.natoms)
    return AtomSections("sphere", [
        ("Atoms # sphere", _rows(ids, types, 2.0 * r, density, x[:, 0], x[:, 1], x[:, 2])),
        ("Velocities", _rows(ids, v[:, 0], v[:, 1], v[:, 2], zero, zero, zero)),
    ], [f"set type {t} mass {_num(m)}" for t, m in enumerate(masses.tolist(), start=1)], len(masses))


def _atoms_ellipsoid(case: Case, taken: set[str]) -> AtomSections:
    """atom_style ellipsoid: `id type ellipsoidflag density x y z`; an Ellipsoids section `id 2a
    2b 2c qw qx qy qz` (LAMMPS takes diameters; it normalises q again, a change of at most an
    ulp); Velocities `id vx vy vz Lx Ly Lz` (space-frame angular momentum). `set type T mass M`
    makes every mass exact (LAMMPS computes it from density and volume). Ellipsoids integrate
    with fix nve/asphere, point atoms (shape 0) with fix nve; compute erotate/asphere joins
    LAMMPS's ke and etotal in the variables v_wb_ke and v_wb_etot (wallbatch's ke includes the
    rotational energy), and is erot itself."""
    if np.any(case.radius > 0):
        raise ExportError("cannot export yet: atoms with a radius and ellipsoids together (atom_style hybrid "
                          "sphere ellipsoid)")
    masses, types = _types(case)
    n = case.natoms
    ids = np.arange(1, n + 1)
    shape, q, L = case.shape, case.quat, case.angmom
    ell = np.all(shape > 0, axis=1)
    volume = 4.0 / 3.0 * np.pi * np.prod(np.where(ell[:, None], shape, 1.0), axis=1)
    density = np.where(ell, case.mass / volume, case.mass)
    x, v = case.x, case.v
    sections = [
        ("Atoms # ellipsoid", _rows(ids, types, ell.astype(np.int64), density, x[:, 0], x[:, 1], x[:, 2])),
        ("Ellipsoids", _rows(ids[ell], *(2.0 * shape[ell].T), *q[ell].T)),
        ("Velocities", _rows(ids, v[:, 0], v[:, 1], v[:, 2], L[:, 0], L[:, 1], L[:, 2])),
    ]
    after = [f"set type {t} mass {_num(m)}" for t, m in enumerate(masses.tolist(), start=1)]
    if ell.all():
        group, integrate = "all", [("wb_nve", "all", "nve/asphere")]
    else:
        group, points = _lammps_id("wb_ellipsoids", taken), _lammps_id("wb_points", taken)
        after += [f"group           {group} id {_id_ranges(ell)}", f"group           {points} id {_id_ranges(~ell)}"]
        integrate = [("wb_nve", points, "nve"), ("wb_nve_asphere", group, "nve/asphere")]
    erot, ke, etot = (_lammps_id(name, taken) for name in ("wb_erot", "wb_ke", "wb_etot"))
    extra = [f"compute         {erot} {group} erotate/asphere",
             f'variable        {ke} equal "ke+c_{erot}"',
             f'variable        {etot} equal "etotal+c_{erot}"']
    return AtomSections("ellipsoid", sections, after, len(masses), [f"{int(ell.sum())} ellipsoids"], integrate,
                        extra, {"ke": f"v_{ke}", "etot": f"v_{etot}", "erot": f"c_{erot}"})


def _atom_style(case: Case) -> str:
    if case.shape is not None:
        return "ellipsoid"
    return "sphere" if np.any(case.radius > 0) else "atomic"


# atom kind -> writer(case, taken IDs) (the writer takes the group/compute/variable IDs it adds)
ATOM_WRITERS: dict[str, Callable[[Case, set[str]], AtomSections]] = {
    "atomic": _atoms_atomic, "sphere": _atoms_sphere, "ellipsoid": _atoms_ellipsoid}


def _data_file(case: Case, atoms: AtomSections, title: str) -> str:
    lo, hi = case.box_lo.tolist(), case.box_hi.tolist()
    out = [f"LAMMPS data file: {title}", "", f"{case.natoms} atoms", *atoms.counts, f"{atoms.ntypes} atom types", ""]
    out += [f"{_num(lo[d])} {_num(hi[d])} {a}lo {a}hi" for d, a in enumerate("xyz")]
    for header, rows in atoms.sections:
        out += ["", header, ""] + rows
    return "\n".join(out) + "\n"


# ----------------------------------------------------------------------------- variables


def _time_based(node: Node) -> Node:
    """vdisplace/swiggle/cwiggle rewritten with the thermo keyword `time` (wallbatch's meaning
    under dt_reset: elapsed simulated time); the same operations as wallbatch's evaluator."""
    if isinstance(node, Unary):
        return Unary(node.op, _time_based(node.operand))
    if isinstance(node, Binary):
        return Binary(node.op, _time_based(node.left), _time_based(node.right))
    if not isinstance(node, Call):
        return node
    args = tuple(_time_based(a) for a in node.args)
    t = Keyword("time")
    if node.func == "vdisplace":
        return Binary("+", args[0], Binary("*", args[1], t))
    if node.func in ("swiggle", "cwiggle"):
        phase = Binary("*", Binary("/", Binary("*", Num(2.0), Num(math.pi)), args[2]), t)
        wave = Call("sin", (phase,)) if node.func == "swiggle" else Binary("-", Num(1.0), Call("cos", (phase,)))
        return Binary("+", args[0], Binary("*", args[1], wave))
    return Call(node.func, args)


def _variables(s: _Script) -> None:
    var = s.case.variables
    rewrite = s.case.dt_reset is not None
    for name in var.names():
        uses = var.uses(name)
        node = var.ast(name)
        if rewrite and uses & {"vdisplace", "swiggle", "cwiggle"}:
            node = _time_based(node)
            s.decide("wiggle_dt_reset")
        s.variables[name] = to_lammps(node)


# ----------------------------------------------------------------------------- the export


THERMO_KEYWORDS = {"step": "step", "time": "time", "dt": "dt", "temp": "temp", "ke": "ke", "pe": "pe",
                   "etot": "etotal", "atoms": "atoms", "press": "press", "ecouple": "ecouple",
                   "econserve": "econserve"}


def _minimize(s: _Script) -> list[str]:
    """min_style, min_modify dmax, minimize etol ftol maxiter maxeval (thermo_modify norm no is
    already set: the decisions table), a `print "wb_min PE FNORM"` line (17 digits: the minimized
    energy and force norm, what validate reads), and reset_timestep 0 (time 0.0) so the run's
    samples start at step 0 and time 0 like wallbatch's (LAMMPS's minimize advances the step by
    its iterations). Columns: the min_* results (`MIN_RESULTS`)."""
    m = s.case.minimize
    s.decide("min_norm")
    if m.style == "cg":
        s.decide("min_forces_zero")
    keep, restore = [], []
    if m.style == "fire":
        s.decide("min_fire_velocities")
        keep = ["fix             wb_v0 all store/state 0 vx vy vz"]
        restore = [*(f"variable        wb_v{c} atom f_wb_v0[{k}]" for k, c in enumerate("xyz", 1)),
                   "velocity        all set v_wb_vx v_wb_vy v_wb_vz units box", "unfix           wb_v0"]
    s.columns += [Column(label, where, label, source="min") for label, where in MIN_RESULTS.items()]
    return [*keep, f"min_style       {m.style}", f"min_modify      dmax {_num(m.dmax)}",
            f"minimize        {_num(m.etol)} {_num(m.ftol)} {int(m.maxiter)} {int(m.maxeval)}",
            'print           "wb_min $(pe:%.17g) $(fnorm:%.17g)"',
            *([f"write_dump      all custom {_quoted(s.minimized_dump)} id x y z modify sort id format float %.17g"]
              if s.minimized_dump else []),
            *restore, "reset_timestep  0 time 0.0"]


def _quoted(path: str | Path) -> str:
    """A file path as a LAMMPS word (quoted when it has blanks)."""
    text = str(path)
    return f'"{text}"' if re.search(r"\s", text) else text


def export_case(cfg: Config, case: Case, *, data_dir: str | Path | None = None, source: str = "",
                notes: list[str] | tuple[str, ...] = (), force_matched: bool = False,
                minimized_dump: str | Path | None = None) -> LammpsExport:
    """The LAMMPS script and data file of a step-based case (see `lammps_ready`) built from `cfg`.

    The script's read_data names the data file in `data_dir` (default: no folder, so the data
    file is read from the folder LAMMPS runs in); `source` labels the comment block; `notes` are
    added to its notes. `force_matched` (validate) writes wall/region colloid fixes with -epsilon,
    whose flipped LAMMPS force is exactly wallbatch's; their energies (and pe, etot with energy:
    true) are then marked expected (decisions table). `minimized_dump` (validate) adds a
    `write_dump` of the minimized positions (id x y z, 17 digits) after minimize."""
    check_exportable(cfg)
    if case.steps is None:
        raise ExportError("a run to a simulated time must be converted to steps first (lammps_ready)")
    name = re.sub(r"[^A-Za-z0-9_.\-]", "_", cfg.name) or "wallbatch"
    script_name, data_name = f"in.{name}", f"data.{name}"
    s = _Script(cfg, case, notes=list(notes), force_matched=force_matched, minimized_dump=minimized_dump,
                table_dir=None if data_dir is None else Path(data_dir), table_name=f"table.{name}")
    taken: set[str] = {"all"}
    for g in case.group_names:
        s.groups[g] = _lammps_id(g, taken)
        if s.groups[g] != g:
            s.notes.append(f"group {g!r} written as {s.groups[g]!r} (LAMMPS IDs: letters, digits, underscores)")
    atoms = ATOM_WRITERS[_atom_style(case)](case, taken | set(case.variables.names()))
    integrate = []
    for fid, group, style in atoms.integrate if cfg.fixes is None else ():
        lid = _lammps_id(fid, s.fix_ids | set(cfg.walls))
        s.fix_ids.add(lid)
        integrate.append(f"fix             {lid} {group} {style}")
    enforce2d = []  # after every force fix, so it zeroes their z forces
    for fid, fix in (cfg.fixes or {}).items():  # integrators and thermostats, as written (config order)
        line = to_ensemble_line(s.fix_id(fid), fix.model_copy(update={"group": s.group(fix.group)}))
        s.fix_ids.add(line.split()[1])
        (enforce2d if fix.style == "enforce2d" else integrate).append(_pad(line))
    if cfg.dimension == 2 and not enforce2d:
        enforce2d.append(_pad(f"fix {s.fix_id('wb_enforce2d')} all enforce2d"))

    # decisions that depend on the whole case
    if cfg.units == "lj":
        s.decide("norm")
    if any(g.create.random is not None or g.orientation == "random"
           or (g.velocity is not None and g.velocity.temperature is not None) for g in cfg.atoms):
        s.decide("random")
    _variables(s)
    for fid, wall in cfg.walls.items():
        spec = _spec(case, fid)
        WALL_WRITERS[wall.style](fid, wall, spec, s)
    if cfg.pair is not None:
        PAIR_WRITERS[cfg.pair.style](cfg.pair, s)
    if case.dt_reset is not None:
        _dt_reset(s)
    if case.natoms < 2:
        why = ("one atom: LAMMPS's thermo ke comes from the temperature, 0 with 3N-3 = 0 degrees of freedom; "
               "wallbatch reports 1/2 m v^2 (docs/physics.md §14.1)")
        s.notes.append(why)
        s.expected.update({"ke": why, "etot": why})
    if cfg.lattice is not None:
        s.notes.append(f"lattice {cfg.lattice.style} {cfg.lattice.scale!r}: every value is written in box units")
    if case.periodic.any():
        s.notes.append("periodic positions are wrapped every step, as wallbatch does "
                       "(neigh_modify every 1 delay 0 check no)")

    keywords = {**THERMO_KEYWORDS, **atoms.keywords}
    outputs = ["time", "dt"] + [o for o in case.outputs if o not in ("step", "time", "dt")]
    thermo_cols = [Column(o, keywords[o], o) for o in outputs if o in keywords]
    skipped = [o for o in outputs if o not in keywords and not o.startswith("reflect_")]
    if skipped:
        s.notes.append(f"output(s) {', '.join(skipped)} not written (no LAMMPS counterpart)")
    wall_cols = s.columns
    s.columns = []
    minimize = _minimize(s) if case.minimize is not None else []
    columns = tuple(thermo_cols + wall_cols + s.columns)
    if force_matched and s.region_colloid and minimize:
        why = ("minimize with a wall/region colloid: LAMMPS minimizes its own (different) energy, so the run starts "
               "from a different state (decisions table)")
        s.expected.update({c.label: why for c in columns})

    title = f"wallbatch {__version__} export of {cfg.name}" + (f", case {source}" if source else "")
    data = _data_file(case, atoms, title)
    read = _quoted(data_name if data_dir is None else Path(data_dir) / data_name)

    lines = [f"# LAMMPS input written by {title}",
             f"# Run it next to {data_name}:  lmp -in {script_name}",
             "#",
             "# Where wallbatch decides differently from LAMMPS (decisions table: docs/deviations.md,",
             "# physics: docs/physics.md), as far as this case is concerned:"]
    s.decisions = {k: s.decisions[k] for k in [*DECISIONS, *s.decisions] if k in s.decisions}  # table order
    lines += _bullets(list(s.decisions.values()) or ["(none)"])
    lines += ["#", "# Export notes:"]
    exact = ("positions, velocities, masses and radii are in the data file as shortest round-trip decimals: "
             "LAMMPS reads the same doubles")
    if atoms.style == "ellipsoid":
        exact = ("positions, velocities, masses, shapes (as diameters), quaternions and angular momenta are in the "
                 "data file as shortest round-trip decimals: LAMMPS reads the same doubles (it normalises each "
                 "quaternion again, a change of at most an ulp)")
    if force_matched and s.region_colloid:
        s.notes.insert(0, f"validate's variant: wall/region colloid fix(es) {', '.join(s.region_colloid)} written "
                          f"with -epsilon (LAMMPS's flipped force is then exactly wallbatch's)")
    lines += _bullets([exact, *s.notes])
    lines += ["", f"units           {cfg.units}", f"dimension       {cfg.dimension}",
              "boundary        " + " ".join("p" if p else "f" for p in case.periodic),
              f"atom_style      {atoms.style}", "atom_modify     map yes"]
    if cfg.lattice is not None:
        lines.append(f"lattice         {cfg.lattice.style} {_num(cfg.lattice.scale)}   # all values below are in box units")
    lines.append(f"read_data       {read}")
    lines += atoms.after_read
    for g, lid in s.groups.items():
        lines.append(f"group           {lid} id {_id_ranges(case.atom_group == case.group_names.index(g))}")
    lines += s.pair
    lines += [f"region          {r.partition(' ')[2]}" for r in s.regions.values()]
    for vname, text in s.variables.items():
        lines.append(f'variable        {vname} equal "{text}"')
    lines += ["", f"timestep        {_num(case.dt)}", "neigh_modify    every 1 delay 0 check no", *integrate]
    lines += [_pad(f) for f in s.fixes] + enforce2d
    lines += atoms.extra
    lines += ["", "thermo_style    custom step " + " ".join(c.keyword for c in columns if c.source == "thermo"),
              'thermo_modify   norm no format float "%.17g"',
              f"thermo          {int(case.thermo)}", *minimize,
              f"run             {int(case.steps)}", ""]
    return LammpsExport("\n".join(lines), data, script_name, data_name, columns, int(case.steps),
                        int(case.thermo), tuple(s.decisions.values()), tuple(s.notes), dict(s.expected),
                        tuple(s.region_colloid), force_matched,
                        {s.table_name: "\n".join(s.table_text)} if s.table_text else {}, s.table_rtol)


def _pad(command: str) -> str:
    """`fix ID ...` as `fix             ID ...` (the layout of the other commands)."""
    word, _, rest = command.partition(" ")
    return f"{word:<15} {rest}"


def _bullets(items: list[str], width: int = 100) -> list[str]:
    """Comment lines: `#   - item`, wrapped."""
    import textwrap

    out = []
    for item in items:
        out += textwrap.wrap(item, width, initial_indent="#   - ", subsequent_indent="#     ")
    return out


def _spec(case: Case, fid: str) -> Any:
    """The resolved spec of fix `fid`, from whichever tuple of specs on the Case holds it."""
    for value in vars(case).values():
        if isinstance(value, tuple):
            for item in value:
                if getattr(item, "fix_id", None) == fid:
                    return item
    raise ExportError(f"walls.{fid}: the case has no resolved spec for this fix")


def _dt_reset(s: _Script) -> None:
    """fix dt/reset, defined after every wall (step-0 dt from all forces), in box units."""
    d, cfg = s.case.dt_reset, s.cfg.dt_reset
    bound = lambda v: "NULL" if v is None else _num(v)
    lid = _lammps_id("wb_dt_reset", s.fix_ids | set(s.cfg.walls))
    line = (f"fix {lid} {s.group(cfg.group)} dt/reset {d.every} {bound(d.tmin)} {bound(d.tmax)} "
            f"{_num(d.xmax)} units box")
    if d.emax is not None:
        line += f" emax {_num(d.emax)}"
    s.fixes.append(line)
    s.decide("dt_reset_order")
    if d.tmin is None or d.tmax is None:
        s.decide("dt_bounds")
    if cfg.units == "lattice":
        s.notes.append(f"dt_reset xmax {cfg.xmax!r} lattice spacings written as {_num(d.xmax)} (box units)")


def write_export(exp: LammpsExport, folder: str | Path) -> tuple[Path, Path]:
    """Write the script and data file (and any table file, beside it) into `folder` (created);
    return the paths of the script and the data file."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    script, data = folder / exp.script_name, folder / exp.data_name
    script.write_text(exp.script)
    data.write_text(exp.data)
    for name, text in exp.files.items():
        (folder / name).write_text(text)
    return script, data


def export_selected(plan: SweepPlan, sel: str | None = None, steps: int | None = None,
                    data_dir: str | Path | None = None) -> LammpsExport:
    """Select a case of a plan (`select_case`), make it step-based (`lammps_ready`), build and
    export it. Raises ExportError, CaseError (the case cannot be built) or ConfigError."""
    sc = select_case(plan, sel)
    check_exportable(sc.config)
    cfg, notes = lammps_ready(sc.config, steps)
    case = build_case(cfg, sc.seed_key)
    return export_case(cfg, case, data_dir=data_dir, source=sc.label if sc.coords else "", notes=notes)
