"""`wallbatch export-lammps`: one case as a LAMMPS input script and data file (docs/validate.md).

The export reproduces the case exactly: the data file holds the case's initial positions,
velocities, masses and radii as shortest round-trip floats (`repr`), every value is in box units
(lattice values are converted; variable wall coordinates in lattice units get a scaled helper
variable), walls keep their config order, `fix dt/reset` comes after every wall (wallbatch's step-0
ordering), and `thermo_style custom` lists the outputs wallbatch samples with `thermo_modify norm
no`. A comment block at the top lists every row of the decisions table (shared/spec/physics.md,
docs/physics.md) the case touches.

Adding a feature is one small function and one registry line:
  * a wall style: a writer in `WALL_WRITERS` (config style name -> writer(fid, wall, spec, s));
  * a pair style: a writer in `PAIR_WRITERS`;
  * an atom kind: a writer in `ATOM_WRITERS` (chosen by `_atom_style`).
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

from . import __version__
from .config import Config, config_from_dict
from .expr import Binary, Call, Keyword, Node, Num, Unary, to_lammps
from .fixline import to_fix_line
from .scene import Case, ReflectSpec, SoftWallSpec, build_case
from .sweep import SweepCase, SweepPlan, config_to_dict, set_path
from .units import UNIT_SYSTEMS

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
    """One thermo column: `label` names the wallbatch output (`ke`, `wall_energy[zw]`,
    `wall_force[zw/zlo]`), `keyword` the LAMMPS thermo keyword, `key`/`index` where the value
    sits in the engine's per-case samples (`CaseResult.data[key][:, index]`)."""

    label: str
    keyword: str
    key: str
    index: int | None = None


@dataclass(frozen=True)
class LammpsExport:
    """A case as LAMMPS input: the script text, the data file text and what to compare."""

    script: str
    data: str
    script_name: str
    data_name: str
    columns: tuple[Column, ...]  # thermo columns after `step`, in order
    steps: int
    thermo: int
    decisions: tuple[str, ...]  # decisions-table rows this case touches ("topic: what it means here")
    notes: tuple[str, ...]  # other export notes
    expected: dict[str, str] = field(default_factory=dict)  # output label -> why it differs by design


# ----------------------------------------------------------------------------- decisions table

# The rows of the decisions table (shared/spec/physics.md) that today's features can touch.
DECISIONS: dict[str, str] = {
    "lj1043": "wall/lj1043 atom on or behind the wall: wallbatch stops the case with an error, like every other "
              "style; LAMMPS silently skips the atom (and includes one exactly at the cut-off with E = 0, F != 0). "
              "A run that reaches such a state differs: wallbatch fails, LAMMPS goes on",
    "morse_alpha": "wall/morse alpha as a variable: LAMMPS ignores a variable alpha (alpha = 0, no force); the "
                   "variable is constant here, so its value is written as a number",
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
    "reflect_frame": "wall/reflect on a moving wall: frame: wall (v -> 2 v_wall - v) cannot be expressed in LAMMPS, "
                     "which does v -> -v; this script reflects in the lab frame, so velocities differ from "
                     "wallbatch's after the first reflection on a moving wall (`wallbatch validate` compares the "
                     "case with frame: lab and reports the frame: wall difference as expected)",
}

# Not yet exportable: config style name -> what it is (features being built by other issues).
NOT_YET: dict[str, str] = {
    "flow": "wall/flow",
    "ees": "wall/ees (ellipsoids)",
    "region": "wall/region",
    "region/ees": "wall/region/ees",
}


# ----------------------------------------------------------------------------- selecting and preparing


def _same(value: Any, text: str) -> bool:
    """A sweep coordinate equals the text a user typed (numbers within 1e-9 relative)."""
    if str(value) == text:
        return True
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
            raise ExportError(f"--case {sel}: there are {len(cases)} case(s), indexed 0 to {len(cases) - 1}")
        return cases[i]
    extras = {k: d for d in plan.dims for k in d.extra}
    names = [d.name for d in plan.dims] + list(extras)
    wanted: list[tuple[str, str]] = []
    for item in sel.split(","):
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
    for i, g in enumerate(cfg.atoms):
        if (g.shape is not None or g.orientation is not None or g.angmom is not None) and "ellipsoid" not in ATOM_WRITERS:
            problems.append(f"atoms.{i}: ellipsoid atoms (shape, orientation, angmom)")
    for fid, wall in cfg.walls.items():
        if wall.style not in WALL_WRITERS:
            problems.append(f"walls.{fid}: {NOT_YET.get(wall.style, 'wall/' + wall.style)}")
    if getattr(cfg, "minimize", None) is not None:
        problems.append("minimize: an energy minimization before the run")
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
    return _with(cfg, {"run": {"steps": int(steps), "thermo": int(thermo)}}), notes


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
    soft_written: list[SoftWallSpec] = field(default_factory=list)  # wall_energy / wall_force indices

    def decide(self, key: str, text: str | None = None) -> None:
        self.decisions.setdefault(key, text or DECISIONS[key])

    def group(self, name: str) -> str:
        return "all" if name == "all" else self.groups[name]

    def fix_id(self, fid: str) -> str:
        out = _lammps_id(fid, self.fix_ids)
        if out != fid:
            self.notes.append(f"fix ID {fid!r} written as {out!r} (LAMMPS IDs: letters, digits, underscores)")
        return out

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
    """fix wall/lj93 | lj126 | lj1043 | colloid | harmonic | morse, in box units; fix_modify
    energy yes for `energy: true`; columns f_ID and f_ID[i]."""
    lid = s.fix_id(fid)
    written = dict(wall.faces())
    mapping: dict[str, Any] = {"style": wall.style, "group": s.group(wall.group), "units": "box"}
    if wall.pbc:
        mapping["pbc"] = True
    for face in spec.faces:
        values: dict[str, Any] = {"coord": _coord_word(face, written[face.name].coord, s)}
        for key, v in face.params.items():
            if isinstance(v, str) and key == "alpha":
                const = s.case.variables.constant_value(v)
                if const is None:
                    raise ExportError(f"walls.{fid}.{face.name}.alpha: LAMMPS ignores a variable alpha (alpha = 0, "
                                      f"physics.md decisions table) and v_{v} changes during the run: cannot export")
                s.decide("morse_alpha", DECISIONS["morse_alpha"] + f" ({face.label}: v_{v} = {_num(const)})")
                v = const
            values[key] = f"v_{v}" if isinstance(v, str) else float(v)
        mapping[face.name] = values
    if wall.style == "lj1043":
        s.decide("lj1043")
    s.fixes.append(to_fix_line(lid, mapping))
    if spec.energy:
        s.fixes.append(f"fix_modify {lid} energy yes")
    if getattr(spec, "virial", False):
        s.fixes.append(f"fix_modify {lid} virial yes")
    s.columns.append(Column(f"wall_energy[{fid}]", f"f_{lid}", "wall_energy", len(s.soft_written)))
    first = sum(len(w.faces) for w in s.soft_written)
    s.soft_written.append(spec)
    for i, face in enumerate(spec.faces):
        s.columns.append(Column(f"wall_force[{face.label}]", f"f_{lid}[{i + 1}]", "wall_force", first + i))


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


WALL_WRITERS: dict[str, WallWriter] = {
    **{style: _soft_wall for style in ("lj93", "lj126", "lj1043", "colloid", "harmonic", "morse")},
    "reflect": _reflect_wall,
}

# pair style name -> writer(pair model, s); none yet ("pair: lj/cut" lands with its own issue).
PAIR_WRITERS: dict[str, Callable[[Any, _Script], None]] = {}


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
    """What an atom kind adds: the atom_style, data-file sections, commands after read_data."""

    style: str
    sections: list[tuple[str, list[str]]]  # (header, rows)
    after_read: list[str]
    ntypes: int


def _types(case: Case) -> tuple[np.ndarray, np.ndarray]:
    """One atom type per distinct mass: (masses of the types, type of each atom, 1-based)."""
    masses, inverse = np.unique(case.mass, return_inverse=True)
    return masses, inverse.astype(np.int64) + 1


def _atoms_atomic(case: Case) -> AtomSections:
    """atom_style atomic: per-type masses (exact), `id type x y z`, `id vx vy vz`."""
    masses, types = _types(case)
    ids = np.arange(1, case.natoms + 1)
    x, v = case.x, case.v
    return AtomSections("atomic", [
        ("Masses", _rows(np.arange(1, len(masses) + 1), masses)),
        ("Atoms # atomic", _rows(ids, types, x[:, 0], x[:, 1], x[:, 2])),
        ("Velocities", _rows(ids, v[:, 0], v[:, 1], v[:, 2])),
    ], [], len(masses))


def _atoms_sphere(case: Case) -> AtomSections:
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


def _atom_style(case: Case) -> str:
    return "sphere" if np.any(case.radius > 0) else "atomic"


ATOM_WRITERS: dict[str, Callable[[Case], AtomSections]] = {"atomic": _atoms_atomic, "sphere": _atoms_sphere}


def _data_file(case: Case, atoms: AtomSections, title: str) -> str:
    lo, hi = case.box_lo.tolist(), case.box_hi.tolist()
    out = [f"LAMMPS data file: {title}", "", f"{case.natoms} atoms", f"{atoms.ntypes} atom types", ""]
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
                   "etot": "etotal", "atoms": "atoms"}


def export_case(cfg: Config, case: Case, *, data_dir: str | Path | None = None, source: str = "",
                notes: list[str] | tuple[str, ...] = ()) -> LammpsExport:
    """The LAMMPS script and data file of a step-based case (see `lammps_ready`) built from `cfg`.

    The script's read_data names the data file in `data_dir` (default: no folder, so the data
    file is read from the folder LAMMPS runs in); `source` labels the comment block; `notes` are
    added to its notes."""
    check_exportable(cfg)
    if case.steps is None:
        raise ExportError("a run to a simulated time must be converted to steps first (lammps_ready)")
    name = re.sub(r"[^A-Za-z0-9_.\-]", "_", cfg.name) or "wallbatch"
    script_name, data_name = f"in.{name}", f"data.{name}"
    s = _Script(cfg, case, notes=list(notes))
    taken: set[str] = {"all"}
    for g in case.group_names:
        s.groups[g] = _lammps_id(g, taken)
        if s.groups[g] != g:
            s.notes.append(f"group {g!r} written as {s.groups[g]!r} (LAMMPS IDs: letters, digits, underscores)")
    nve = _lammps_id("wb_nve", s.fix_ids | set(cfg.walls))
    s.fix_ids.add(nve)

    # decisions that depend on the whole case
    if cfg.units == "lj":
        s.decide("norm")
    if any(g.create.random is not None or (g.velocity is not None and g.velocity.temperature is not None)
           for g in cfg.atoms):
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
               "wallbatch reports 1/2 m v^2 (docs/physics.md)")
        s.notes.append(why)
        s.expected.update({"ke": why, "etot": why})
    if cfg.lattice is not None:
        s.notes.append(f"lattice {cfg.lattice.style} {cfg.lattice.scale!r}: every value is written in box units")
    if case.periodic.any():
        s.notes.append("periodic positions are wrapped every step, as wallbatch does "
                       "(neigh_modify every 1 delay 0 check no)")

    outputs = ["time", "dt"] + [o for o in case.outputs if o not in ("step", "time", "dt")]
    thermo_cols = [Column(o, THERMO_KEYWORDS[o], o) for o in outputs if o in THERMO_KEYWORDS]
    skipped = [o for o in outputs if o not in THERMO_KEYWORDS and not o.startswith("reflect_")]
    if skipped:
        s.notes.append(f"output(s) {', '.join(skipped)} not written (no LAMMPS keyword in this export)")
    columns = tuple(thermo_cols + s.columns)

    atoms = ATOM_WRITERS[_atom_style(case)](case)
    title = f"wallbatch {__version__} export of {cfg.name}" + (f", case {source}" if source else "")
    data = _data_file(case, atoms, title)
    read = data_name if data_dir is None else str(Path(data_dir) / data_name)
    read = f'"{read}"' if re.search(r"\s", read) else read

    lines = [f"# LAMMPS input written by {title}",
             f"# Run it next to {data_name}:  lmp -in {script_name}",
             "#",
             "# Where wallbatch decides differently from LAMMPS (decisions table: shared/spec/physics.md,",
             "# docs/physics.md), as far as this case is concerned:"]
    s.decisions = {k: s.decisions[k] for k in [*DECISIONS, *s.decisions] if k in s.decisions}  # table order
    lines += _bullets(list(s.decisions.values()) or ["(none)"])
    lines += ["#", "# Export notes:"]
    exact = ("positions, velocities, masses and radii are in the data file as shortest round-trip decimals: "
             "LAMMPS reads the same doubles")
    lines += _bullets([exact, *s.notes])
    lines += ["", f"units           {cfg.units}", "dimension       3",
              "boundary        " + " ".join("p" if p else "f" for p in case.periodic),
              f"atom_style      {atoms.style}", "atom_modify     map yes"]
    if cfg.lattice is not None:
        lines.append(f"lattice         {cfg.lattice.style} {_num(cfg.lattice.scale)}   # all values below are in box units")
    lines.append(f"read_data       {read}")
    lines += atoms.after_read
    for g, lid in s.groups.items():
        lines.append(f"group           {lid} id {_id_ranges(case.atom_group == case.group_names.index(g))}")
    for vname, text in s.variables.items():
        lines.append(f'variable        {vname} equal "{text}"')
    lines += ["", f"timestep        {_num(case.dt)}", "neigh_modify    every 1 delay 0 check no",
              f"fix             {nve} all nve"]
    lines += [_pad(f) for f in s.fixes]
    lines += ["", "thermo_style    custom step " + " ".join(c.keyword for c in columns),
              'thermo_modify   norm no format float "%.17g"',
              f"thermo          {int(case.thermo)}",
              f"run             {int(case.steps)}", ""]
    return LammpsExport("\n".join(lines), data, script_name, data_name, columns, int(case.steps),
                        int(case.thermo), tuple(s.decisions.values()), tuple(s.notes), dict(s.expected))


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
    """Write the script and data file into `folder` (created); return their paths."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    script, data = folder / exp.script_name, folder / exp.data_name
    script.write_text(exp.script)
    data.write_text(exp.data)
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
