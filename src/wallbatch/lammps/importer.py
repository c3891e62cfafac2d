"""`wallbatch import-lammps`: a LAMMPS input script -> an equivalent wallbatch config (docs/howto/import-lammps.md).

The script is read as LAMMPS reads it: `&` continues a line, an unquoted `#` starts a comment,
`$x`, `${name}` and `$(expr[:format])` are substituted before a line runs (equal-style values as
`%.15g`, immediate `$()` values as `%.20g`, as LAMMPS formats them), quotes group words. Variables:
equal, index, internal, string (`variable NAME delete` too); `--var name=value` defines an index
variable before the script, so the script's own `variable name index ...` is ignored (LAMMPS's
`-var`). Loops (`jump`, `next`, `label`, `if`) are not followed.

Each command becomes part of the config and is kept as a comment above it (`# 12: fix ...`).
Commands that only change output cosmetics are ignored with a comment; everything else the
importer cannot express is listed at the end of the config with its line number (and makes the
import incomplete: `--strict` exits non-zero). Wall fixes go through the config's own fix-line
reader (`parse_fix_line`), so every wall style wallbatch has is covered.

Atoms: each creation command (`create_atoms box|region|single|random`, `read_data`) is a chunk;
wallbatch atom groups (disjoint) are the parts of the chunks that the LAMMPS groups used by fixes,
the atom types, masses and velocity commands tell apart. A LAMMPS group a wall acts on must be
one such part (or all atoms). Random numbers (`create_atoms random`, `velocity create`) are drawn
by wallbatch's own generators (statistically the same, not the same numbers); `--exact` runs the
script's setup in LAMMPS up to the first run/minimize and points the config at the state it
writes (a LAMMPS data file beside the config), so the imported config reproduces the LAMMPS run.
"""

from __future__ import annotations

import math
import os
import re
import shlex
from dataclasses import dataclass, field
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import numpy as np
import yaml

from wallbatch.config.ensemble import FIX_STYLES as ENSEMBLE_STYLES
from wallbatch.config.ensemble import parse_ensemble_line
from wallbatch.config.fixline import FixLineError, parse_fix_line
from wallbatch.config.models import Config, Lattice, Region, load_config_text
from wallbatch.config.source import ConfigError
from wallbatch.expr import EvalContext, VariableError, Variables, VarRef, _walk, parse
from wallbatch.geometry.regions import RegionGeom
from wallbatch.lammps.validate import load_lammps
from wallbatch.scene.build import _lattice_positions as lattice_positions
from wallbatch.scene.datafile import (
    DataFileError,
    id_ranges,
    parse_id_ranges,
    read_data_file,
    select_ids,
)
from wallbatch.units import LATTICE_CELL, LATTICE_POSITIONS, UNIT_SYSTEMS, lattice_constant

__all__ = ["ImportResult", "Issue", "LammpsImportError", "import_lammps", "import_lammps_text"]

# commands that change only what LAMMPS prints or how fast it runs: ignored with a comment
COSMETIC = frozenset({
    "echo", "log", "print", "thermo_modify", "atom_modify", "neighbor", "neigh_modify", "comm_modify",
    "comm_style", "processors", "newton", "package", "suffix", "timer", "title", "write_data", "write_restart",
    "write_dump", "write_coeff", "info", "plugin", "partition", "special_bonds",
})
# not run by --exact: they write files, print or run shell commands, and change no atom
SETUP_SKIPPED = frozenset({"log", "print", "shell", "echo", "info", "dump", "dump_modify", "undump", "write_data",
                           "write_restart", "write_dump", "write_coeff", "restart", "thermo_style", "thermo_modify"})
THERMO_MAP = {"step": "step", "time": "time", "dt": "dt", "temp": "temp", "ke": "ke", "pe": "pe", "etotal": "etot",
              "press": "press", "atoms": "atoms", "ecouple": "ecouple", "econserve": "econserve"}
INTEGRATORS = ("nve", "nve/asphere", "nve/sphere")
# thermostats and friends: imported as verbatim lines into `fixes:`
ENSEMBLE_FIXES = tuple(s for s in ENSEMBLE_STYLES if s not in INTEGRATORS)
DEFAULT_THERMO = ["step", "time", "dt", "temp", "ke", "pe", "etot"]


MAX_INCLUDE_DEPTH = 32  # include files within include files: deeper is a loop (a file including itself)


class LammpsImportError(ValueError):
    """The script cannot be read at all (missing file, no box, ...)."""


class Unsupported(Exception):
    """A command (or part of one) the importer cannot express: reported with its line."""


@dataclass(frozen=True)
class Issue:
    line: int  # 1-based line number in its file
    text: str  # the command as written
    reason: str
    file: str = ""

    def format(self) -> str:
        where = f"{self.file}:{self.line}" if self.file else f"line {self.line}"
        return f"{where}: {self.text}  ->  {self.reason}"


@dataclass
class ImportResult:
    """The imported config (YAML text and data), what could not be imported, and notes."""

    text: str
    data: dict
    unsupported: list[Issue]
    ignored: list[Issue]
    notes: list[str]
    written: list[Path] = field(default_factory=list)  # data files written (--exact)
    problems: list[str] = field(default_factory=list)  # the config does not validate

    @property
    def complete(self) -> bool:
        return not self.unsupported and not self.problems


EXACT_VELOCITIES = "; import with --exact to start from the velocities LAMMPS gives the atoms"


@dataclass
class _Cmd:
    line: int
    raw: str  # as written (continuations joined)
    file: str


# ----------------------------------------------------------------------------- reading lines


def _logical_lines(text: str, file: str) -> list[_Cmd]:
    """Join `&` continuations; keep the first line number of each command."""
    out: list[_Cmd] = []
    buf, start = "", 0
    for k, line in enumerate(text.splitlines(), start=1):
        if not buf:
            start = k
        stripped = line.rstrip()
        if stripped.endswith("&"):
            buf += stripped[:-1] + " "
            continue
        buf += line
        out.append(_Cmd(start, buf.strip(), file))
        buf = ""
    if buf:
        out.append(_Cmd(start, buf.strip(), file))
    return out


def _strip_comment(text: str) -> str:
    quote = None
    for i, c in enumerate(text):
        if quote:
            if c == quote:
                quote = None
        elif c in "'\"":
            quote = c
        elif c == "#":
            return text[:i]
    return text


def _words(text: str) -> list[str]:
    lexer = shlex.shlex(text, posix=True)
    lexer.whitespace_split = True
    lexer.commenters = ""
    lexer.escape = ""
    try:
        return list(lexer)
    except ValueError as exc:
        raise Unsupported(f"cannot split the line into words ({exc})") from None


def _num(word: str, what: str) -> float:
    try:
        return float(word)
    except ValueError:
        raise Unsupported(f"{what} must be a number, got {word!r}") from None


def _int(word: str, what: str) -> int:
    try:
        return int(word)
    except ValueError:
        raise Unsupported(f"{what} must be an integer, got {word!r}") from None


def _type_range(word: str, ntypes: int) -> list[int]:
    """LAMMPS type ranges: `2`, `*`, `2*`, `*3`, `1*3`."""
    if "*" not in word:
        return [_int(word, "atom type")]
    a, _, b = word.partition("*")
    lo = int(a) if a else 1
    hi = int(b) if b else ntypes
    return list(range(lo, hi + 1))


# ----------------------------------------------------------------------------- atoms


def _codes(values: np.ndarray) -> np.ndarray:
    """Integer codes of float values (equal values, equal codes; NaN: -1)."""
    out = np.full(len(values), -1, np.int64)
    ok = ~np.isnan(values)
    out[ok] = np.unique(values[ok], return_inverse=True)[1].ravel()
    return out


@dataclass
class _Chunk:
    kind: str  # lattice | random | single | file
    spec: dict  # the config's create: mapping
    count: int
    line: int
    file: Any = None  # DataFile


class _Atoms:
    """Every atom the script creates, in LAMMPS ID order, with the per-atom facts that decide the
    wallbatch groups. Positions are NaN where wallbatch draws them (create_atoms random)."""

    def __init__(self) -> None:
        self.chunks: list[_Chunk] = []
        self.chunk = np.zeros(0, np.int64)
        self.ids = np.zeros(0, np.int64)
        self.types = np.zeros(0, np.int64)
        self.x = np.zeros((0, 3))
        self.mass = np.zeros(0)  # NaN: the type's mass (mass command / Masses section)
        self.vel = np.zeros(0, np.int64)  # index into velocity specs (0: none)
        self.velocities: list[Any] = [None]
        self.vel_group: dict[int, str] = {}  # velocity spec index -> the LAMMPS group of its `velocity create`
        self.radius = np.zeros(0)  # NaN: as created
        self.groups: dict[str, np.ndarray] = {}

    @property
    def n(self) -> int:
        return len(self.ids)

    def add(self, chunk: _Chunk, types: np.ndarray, x: np.ndarray, ids: np.ndarray | None = None) -> None:
        start = int(self.ids.max()) + 1 if self.n else 1
        ids = np.arange(start, start + chunk.count) if ids is None else ids
        self.chunks.append(chunk)
        self.chunk = np.concatenate([self.chunk, np.full(chunk.count, len(self.chunks) - 1)])
        self.ids = np.concatenate([self.ids, ids])
        self.types = np.concatenate([self.types, types])
        self.x = np.concatenate([self.x, x])
        self.mass = np.concatenate([self.mass, np.full(chunk.count, np.nan)])
        self.vel = np.concatenate([self.vel, np.zeros(chunk.count, np.int64)])
        self.radius = np.concatenate([self.radius, np.full(chunk.count, np.nan)])
        for g in self.groups:
            self.groups[g] = np.concatenate([self.groups[g], np.zeros(chunk.count, bool)])

    def group(self, name: str) -> np.ndarray:
        if name == "all":
            return np.ones(self.n, bool)
        if name not in self.groups:
            raise Unsupported(f"unknown group {name!r}")
        return self.groups[name]


# ----------------------------------------------------------------------------- the importer


class _Importer:
    def __init__(self, script: Path, variables: dict[str, str], exact_state: Path | None = None) -> None:
        self.script = script
        self.base = script.parent
        self.vars: dict[str, tuple[str, Any]] = {k: ("index", str(v)) for k, v in variables.items()}
        self.exact_state = exact_state
        self.unsupported: list[Issue] = []
        self.ignored: list[Issue] = []
        self.notes: list[str] = []
        self.comments: dict[str, list[str]] = {}
        self.cmd: _Cmd | None = None
        self.units = "lj"
        self.dimension = 3
        self.boundary = ["p", "p", "p"]
        self.atom_style = "atomic"
        self.lattice: dict | None = None
        self.spacing: float | None = None
        self.box: tuple[list[float], list[float]] | None = None
        self.ntypes = 0
        self.type_mass: dict[int, float] = {}
        self.regions: dict[str, dict] = {}
        self.atoms = _Atoms()
        self.pair: dict | None = None
        self.pair_coeffs: dict[tuple[int, int], tuple[float, float]] = {}
        self.timestep: float | None = None
        self.walls: dict[str, dict] = {}
        self.wall_lines: dict[str, _Cmd] = {}
        self.integrators: list[tuple[str, str, str]] = []  # (fix ID, group, style)
        self.ensemble: list[tuple[str, str, list[str]]] = []  # (fix ID, group, words): fixes: entries
        self.dt_reset: dict | None = None
        self.computes: dict[str, str] = {}  # ID -> style
        self.thermo = 0
        self.thermo_style: list[str] | None = None
        self.min_style = "cg"
        self.dmax: float | None = None
        self.minimize: dict | None = None
        self.steps_after_min = False  # a minimize not yet followed by reset_timestep 0: LAMMPS's run starts later
        self.run: int | None = None
        self.seed: int | None = None
        self.dump: dict | None = None
        self.first_run_line: int | None = None  # index into the command list
        self.config_variables: set[str] = set()
        self.lines_before_run: list[_Cmd] = []
        self.stopped = False
        self.where: dict[str, _Cmd] = {}  # topic -> the command an end-of-import issue points at

    # -- bookkeeping ------------------------------------------------------------------------

    def here(self) -> str:
        """The current command's place for notes: `line N`, or `FILE:N` in an include file."""
        c = self.cmd
        return f"line {c.line}" if c.file == str(self.script) else f"{c.file}:{c.line}"

    def note_line(self, key: str) -> None:
        """Keep the current command as a comment above config section `key`."""
        c = self.cmd
        where = f"{c.line}" if c.file == str(self.script) else f"{Path(c.file).name}:{c.line}"  # an include file's
        self.comments.setdefault(key, []).append(f"{where}: {c.raw}")

    def issue_at(self, topic: str, text: str, reason: str) -> None:
        """An issue found while writing the config, pointed at the command of `topic`."""
        c = self.where.get(topic)
        self.unsupported.append(Issue(c.line, c.raw, reason, c.file if c.file != str(self.script) else "") if c
                                else Issue(0, text, reason))

    def unsupported_here(self, reason: str) -> None:
        c = self.cmd
        self.unsupported.append(Issue(c.line, c.raw, reason, c.file if c.file != str(self.script) else ""))

    def ignore_here(self, reason: str) -> None:
        c = self.cmd
        self.ignored.append(Issue(c.line, c.raw, reason, c.file if c.file != str(self.script) else ""))

    # -- substitution ------------------------------------------------------------------------

    def eval_expr(self, text: str) -> float:
        """An equal-style expression now (step 0, time 0, the box and atom count so far)."""
        exprs: dict[str, Any] = {}
        todo = ["__now__"]
        try:
            exprs["__now__"] = text
            while todo:
                name = todo.pop()
                node = parse(str(exprs[name])) if not isinstance(exprs[name], float) else None
                if node is None:
                    continue
                for ref in {n.name for n in _walk(node) if isinstance(n, VarRef)}:
                    if ref in exprs:
                        continue
                    if ref not in self.vars:
                        raise Unsupported(f"variable v_{ref} is not defined")
                    style, value = self.vars[ref]
                    if style == "internal":
                        exprs[ref] = float(value)
                    elif style == "equal":
                        exprs[ref] = value
                        todo.append(ref)
                    else:
                        try:
                            exprs[ref] = float(value)
                        except ValueError:
                            raise Unsupported(f"variable v_{ref} ({style}) is not a number: {value!r}") from None
            lo, hi = self.box if self.box else ([0.0] * 3, [0.0] * 3)
            dt = self.timestep if self.timestep is not None else UNIT_SYSTEMS[self.units].dt
            ctx = EvalContext(step=0, begin_step=0, end_step=0, dt=dt, time=0.0, elapsed_time=0.0,
                              ramp_fraction=0.0, box_lo=tuple(lo), box_hi=tuple(hi), atoms=self.atoms.n)
            return float(Variables(exprs).evaluate("__now__", ctx))
        except VariableError as exc:
            raise Unsupported(f"cannot evaluate {text!r} while importing: {exc}") from None

    def value_of(self, name: str) -> str:
        if name not in self.vars:
            raise Unsupported(f"substitution for an undefined variable {name!r}")
        style, value = self.vars[name]
        if style == "equal":
            return "%.15g" % self.eval_expr(value)  # noqa: UP031 - LAMMPS C formats
        if style == "internal":
            return "%.15g" % value  # noqa: UP031
        return str(value)

    def substitute(self, text: str) -> str:
        out, i, quote = [], 0, None
        while i < len(text):
            c = text[i]
            if quote:
                if c == quote:
                    quote = None
                out.append(c)
                i += 1
                continue
            if c in "'\"":
                quote = c
                out.append(c)
                i += 1
                continue
            if c != "$" or i + 1 >= len(text):
                out.append(c)
                i += 1
                continue
            nxt = text[i + 1]
            if nxt == "{":
                end = text.find("}", i + 2)
                if end < 0:
                    raise Unsupported("unmatched ${")
                out.append(self.value_of(text[i + 2:end]))
                i = end + 1
            elif nxt == "(":
                depth, j = 0, i + 1
                while j < len(text):
                    depth += {"(": 1, ")": -1}.get(text[j], 0)
                    if depth == 0:
                        break
                    j += 1
                if depth:
                    raise Unsupported("unmatched $(")
                inner = text[i + 2:j]
                fmt = "%.20g"
                head, colon, tail = inner.rpartition(":")
                if colon and tail.startswith("%"):
                    inner, fmt = head, tail
                try:
                    out.append(fmt % self.eval_expr(inner))
                except (TypeError, ValueError):
                    raise Unsupported(f"bad format {fmt!r} in $({text[i + 2:j]})") from None
                i = j + 1
            else:
                out.append(self.value_of(nxt))
                i += 2
        return "".join(out)

    # -- driver -------------------------------------------------------------------------------

    def run_file(self, path: Path, depth: int = 0) -> None:
        try:
            text = path.read_text()
        except OSError as exc:
            if depth == 0:
                raise LammpsImportError(f"{path}: cannot read the script: {exc.strerror}") from None
            raise Unsupported(f"include file {path} cannot be read ({exc.strerror})") from None
        for cmd in _logical_lines(text, str(path)):
            self.where["end"] = cmd
            if self.stopped:
                return
            self.cmd = cmd
            body = _strip_comment(cmd.raw).strip()
            if not body:
                continue
            try:
                words = _words(self.substitute(body))
                if not words:
                    continue
                if words[0] == "include":
                    if len(words) != 2:
                        raise Unsupported("include takes one file name")
                    inc = Path(words[1])
                    if depth + 1 > MAX_INCLUDE_DEPTH:
                        raise Unsupported(f"include nested more than {MAX_INCLUDE_DEPTH} deep (does {words[1]} "
                                          f"include itself?): not followed")
                    self.run_file(inc if inc.is_absolute() else self.base / inc, depth + 1)
                    self.cmd = cmd
                    continue
                if self.first_run_line is None:
                    self.lines_before_run.append(cmd)
                self.dispatch(words)
            except Unsupported as exc:
                self.unsupported_here(str(exc))
            except LammpsImportError:
                raise
            except IndexError:  # a command's handler read a word the line does not have
                self.unsupported_here(f"{body.split()[0]}: too few arguments (LAMMPS would stop here too)")
            except (ValueError, ArithmeticError) as exc:  # values no handler check caught (pydantic's too)
                text = " ".join(str(exc).split())
                self.unsupported_here(f"{body.split()[0]}: cannot use these values: {text[:300]}")

    def dispatch(self, w: list[str]) -> None:
        name = w[0]
        handler = getattr(self, "c_" + name.replace("/", "_"), None)
        if handler is not None:
            handler(w)
        elif name in ("neighbor", "neigh_modify"):
            self.ignore_here("neighbor-list setting: wallbatch builds its own lists (LAMMPS gives the same forces as "
                             "long as its list misses no pair)")
        elif name in COSMETIC:
            self.ignore_here("output or performance setting only: no effect on the results")
        else:
            raise Unsupported(f"command {name!r} is not supported by the importer")

    # -- commands: setup ----------------------------------------------------------------------

    def c_units(self, w: list[str]) -> None:
        if len(w) != 2 or w[1] not in UNIT_SYSTEMS:
            raise Unsupported(f"units {' '.join(w[1:])}: wallbatch has units {', '.join(UNIT_SYSTEMS)}")
        self.units = w[1]
        self.note_line("units")

    def c_dimension(self, w: list[str]) -> None:
        if w[1:] == ["3"]:
            self.note_line("units")
            return
        if w[1:] == ["2"] and "dimension" in Config.model_fields:
            self.dimension = 2
            self.note_line("dimension")
            return
        raise Unsupported("2-D scenes (dimension 2) are not supported by this version of wallbatch")

    def c_boundary(self, w: list[str]) -> None:
        if len(w) != 4:
            raise Unsupported("boundary takes three words (x y z)")
        out = []
        for d, b in enumerate(w[1:]):
            if b == "p":
                out.append("p")
            elif b == "f" or b == "ff":
                out.append("f")
            else:
                out.append("f")
                self.unsupported_here(f"boundary {b} along {'xyz'[d]}: shrink-wrapped boundaries (s, m) are not "
                                      f"supported; imported as f (fixed)")
        self.boundary = out
        self.note_line("box")

    def c_atom_style(self, w: list[str]) -> None:
        if len(w) != 2 or w[1] not in ("atomic", "sphere", "ellipsoid"):
            raise Unsupported(f"atom_style {' '.join(w[1:])}: wallbatch has atomic, sphere and ellipsoid atoms")
        self.atom_style = w[1]
        self.note_line("atoms")

    def c_lattice(self, w: list[str]) -> None:
        if len(w) < 3:
            raise Unsupported("lattice takes a style and a scale")
        style, scale = w[1], _num(w[2], "the lattice scale")
        if not (math.isfinite(scale) and scale > 0):
            raise Unsupported(f"the lattice scale must be a positive number, got {w[2]}")
        if len(w) > 3:
            raise Unsupported(f"lattice keywords {' '.join(w[3:])} (origin, orient, spacing, basis, ...) are not "
                              f"supported: wallbatch lattices are the cubic sc, bcc, fcc cells")
        if style == "none":
            self.lattice, self.spacing = None, scale
            self.note_line("lattice")
            return
        if style not in LATTICE_POSITIONS:
            raise Unsupported(f"lattice style {style}: wallbatch has sc, bcc, fcc")
        self.lattice = {"style": style, "scale": scale}
        self.spacing = lattice_constant(style, scale, self.units)
        self.note_line("lattice")

    def scale(self, units: str) -> np.ndarray:
        """LAMMPS's xlattice, ylattice, zlattice [length] for `units` lattice (1 for box): the
        lattice constant times the cell's edges (hex: a, sqrt(3) a, a)."""
        if units == "box":
            return np.ones(3)
        if self.spacing is None:
            # LAMMPS's default lattice is `lattice none 1.0`: lattice units are then box units
            note = (f"{self.here()}: units lattice (the LAMMPS default) before any lattice command: "
                    f"LAMMPS's default lattice none 1.0 makes them box units, as written here")
            if note not in self.notes:
                self.notes.append(note)
            return np.ones(3)
        style = self.lattice["style"] if self.lattice is not None else "none"
        return self.spacing * np.asarray(LATTICE_CELL.get(style, (1.0, 1.0, 1.0)))

    def c_region(self, w: list[str]) -> None:
        if len(w) < 3:
            raise Unsupported("region takes an ID and a style")
        rid, style = w[1], w[2]
        nargs = {"block": 6, "sphere": 4, "cylinder": 6}.get(style)
        if nargs is None:
            raise Unsupported(f"region style {style}: wallbatch has block, sphere, cylinder")
        args, rest = w[3:3 + nargs], w[3 + nargs:]
        if len(args) < nargs:
            raise Unsupported(f"region {style} takes {nargs} arguments")
        side, units = "in", "lattice"
        k = 0
        while k < len(rest):
            if rest[k] == "side" and k + 1 < len(rest) and rest[k + 1] in ("in", "out"):
                side = rest[k + 1]
            elif rest[k] == "units" and k + 1 < len(rest) and rest[k + 1] in ("lattice", "box"):
                units = rest[k + 1]
            else:
                raise Unsupported(f"region keyword {rest[k]!r} (move, rotate, open, ...) is not supported")
            k += 2
        s = self.scale(units)

        def bound(word: str, d: int, hi: bool) -> float:
            if word == "EDGE":
                if self.box is None:
                    raise Unsupported("EDGE in a region needs the box to exist")
                return float(self.box[1 if hi else 0][d])
            if word in ("INF", "+INF", "-INF"):
                return -math.inf if word == "-INF" or (word == "INF" and not hi) else math.inf
            return _num(word, "a region bound") * float(s[d])

        if style == "block":
            lo = [bound(args[2 * d], d, False) for d in range(3)]
            hi = [bound(args[2 * d + 1], d, True) for d in range(3)]
            region = {"style": "block", "lo": lo, "hi": hi}
        elif style == "sphere":
            # as LAMMPS: the center by each axis's spacing, the radius by xlattice
            region = {"style": "sphere", "center": [_num(a, "a sphere center") * float(s[k])
                                                    for k, a in enumerate(args[:3])],
                      "radius": _num(args[3], "the sphere radius") * float(s[0])}
        else:
            axis = args[0]
            if axis not in ("x", "y", "z"):
                raise Unsupported("a cylinder's axis is x, y or z")
            d = "xyz".index(axis)
            # as LAMMPS: c1, c2 by the spacings of the two other axes, the radius by c1's
            across = [k for k in range(3) if k != d]
            region = {"style": "cylinder", "axis": axis,
                      "center": [_num(a, "a cylinder center") * float(s[k]) for k, a in zip(across, args[1:3])],
                      "radius": _num(args[3], "the cylinder radius") * float(s[across[0]]),
                      "lo": bound(args[4], d, False), "hi": bound(args[5], d, True)}
        region["side"] = side
        region["units"] = "box"
        self.regions[rid] = region
        self.note_line(f"regions.{rid}")

    def geom(self, rid: str) -> RegionGeom:
        if rid not in self.regions:
            raise Unsupported(f"unknown region {rid!r}")
        return RegionGeom.from_config(Region.model_validate(self.regions[rid]), None)

    def c_create_box(self, w: list[str]) -> None:
        if len(w) < 3:
            raise Unsupported("create_box takes N and a region ID")
        if len(w) > 3:
            raise Unsupported(f"create_box keywords {' '.join(w[3:])} (bonds, extra/...) are not supported")
        self.ntypes = _int(w[1], "the number of atom types")
        r = self.regions.get(w[2])
        if r is None or r["style"] != "block":
            raise Unsupported(f"create_box needs a block region (got {w[2]!r})")
        if any(math.isinf(v) for v in r["lo"] + r["hi"]):
            raise Unsupported("create_box needs a block region with finite bounds")
        self.box = (list(r["lo"]), list(r["hi"]))
        self.note_line("box")

    def c_read_data(self, w: list[str]) -> None:
        if len(w) < 2:
            raise Unsupported("read_data takes a file name")
        if len(w) > 2:
            raise Unsupported(f"read_data keywords {' '.join(w[2:])} (add, offset, shift, extra, ...) are not "
                              f"supported")
        path = Path(w[1])
        path = path if path.is_absolute() else self.base / path
        if self.box is not None:
            raise Unsupported("read_data into an existing box (add append) is not supported")
        try:
            df = read_data_file(path, self.atom_style, tuple(b == "p" for b in self.boundary))
        except DataFileError as exc:
            raise Unsupported(str(exc)) from None
        self.box = (df.box_lo.tolist(), df.box_hi.tolist())
        self.ntypes = max(self.ntypes, int(df.types.max()) if df.natoms else 1)
        if self.exact_state is None:
            self.add_file_chunk(df, path)
        self.note_line("box")
        self.note_line("atoms")

    def add_file_chunk(self, df: Any, path: Path) -> None:
        chunk = _Chunk("file", {"file": str(path)}, df.natoms, self.cmd.line if self.cmd else 0, df)
        self.atoms.add(chunk, df.types, df.x, df.ids)

    def c_create_atoms(self, w: list[str]) -> None:
        if self.exact_state is not None:
            self.note_line("atoms")
            return
        if self.box is None:
            raise Unsupported("create_atoms before the box exists")
        if len(w) < 3:
            raise Unsupported("create_atoms takes a type and a style")
        atype, style = _int(w[1], "the atom type"), w[2]
        rest = w[3:]
        if style in ("box", "region"):
            region = None
            if style == "region":
                if not rest:
                    raise Unsupported("create_atoms region needs a region ID")
                region, rest = rest[0], rest[1:]
                if region not in self.regions:
                    raise Unsupported(f"unknown region {region!r}")
            if rest:
                raise Unsupported(f"create_atoms keywords {' '.join(rest)} are not supported")
            if self.lattice is None:
                raise Unsupported("create_atoms box/region needs a lattice (sc, bcc or fcc)")
            x = self.lattice_points(region)
            spec = {"lattice": {"region": region} if region else {}}
            chunk = _Chunk("lattice", spec, len(x), self.cmd.line)
        elif style == "single":
            if len(rest) < 3:
                raise Unsupported("create_atoms single takes x y z")
            units = "lattice"
            extra = rest[3:]
            if extra[:1] == ["units"] and len(extra) >= 2:
                units, extra = extra[1], extra[2:]
            if extra:
                raise Unsupported(f"create_atoms keywords {' '.join(extra)} are not supported")
            x = np.array([[_num(v, "a coordinate") * float(a) for v, a in zip(rest[:3], self.scale(units))]])
            chunk = _Chunk("single", {"positions": x.tolist()}, 1, self.cmd.line)
        elif style == "random":
            if len(rest) < 3:
                raise Unsupported("create_atoms random takes N seed region-ID")
            count, seed, region = _int(rest[0], "N"), _int(rest[1], "the seed"), rest[2]
            spec: dict[str, Any] = {"count": count}
            if region != "NULL":
                if region not in self.regions:
                    raise Unsupported(f"unknown region {region!r}")
                spec["region"] = region
            extra = rest[3:]
            k = 0
            while k < len(extra):
                if extra[k] == "overlap" and k + 1 < len(extra):
                    spec["overlap"] = _num(extra[k + 1], "overlap")
                elif extra[k] == "maxtry" and k + 1 < len(extra) or extra[k] == "units" and k + 1 < len(extra):
                    pass
                else:
                    raise Unsupported(f"create_atoms random keyword {extra[k]!r} is not supported")
                k += 2
            self.seed = self.seed if self.seed is not None else seed
            self.notes.append(f"{self.here()}: create_atoms random: wallbatch draws its own random positions "
                              f"(same distribution, other numbers); --exact uses LAMMPS's")
            x = np.full((count, 3), np.nan)
            chunk = _Chunk("random", {"random": spec}, count, self.cmd.line)
        else:
            raise Unsupported(f"create_atoms style {style} is not supported")
        self.atoms.add(chunk, np.full(chunk.count, atype), x)
        self.note_line("atoms")

    def lattice_points(self, region: str | None) -> np.ndarray:
        """The lattice points wallbatch creates for `create: {lattice: ...}` (scene.build's rule)."""
        scene = SimpleNamespace(units=self.units, lattice=Lattice.model_validate(self.lattice),
                                box=SimpleNamespace(lo=tuple(self.box[0]), hi=tuple(self.box[1])),
                                regions={k: Region.model_validate(v) for k, v in self.regions.items()})
        return lattice_positions(scene, region)

    def c_mass(self, w: list[str]) -> None:
        if len(w) != 3:
            raise Unsupported("mass takes a type and a value")
        m = _num(w[2], "the mass")
        for t in _type_range(w[1], max(self.ntypes, 1)):
            self.type_mass[t] = m
        self.note_line("atoms")

    def c_set(self, w: list[str]) -> None:
        if self.exact_state is not None and w[3:4] != ["mass"]:
            self.note_line("atoms")
            return
        if len(w) < 5:
            raise Unsupported("set takes a style, an ID and keyword/value pairs")
        sel = self.select(w[1], w[2])
        k = 3
        while k < len(w):
            key = w[k]
            if key == "mass" and k + 1 < len(w) and self.atom_style == "atomic":
                raise Unsupported("set mass: LAMMPS stops here (atom_style atomic has per-type masses only): "
                                  "give the atoms their own type and use 'mass TYPE VALUE', "
                                  "or use atom_style sphere")
            elif key == "mass" and k + 1 < len(w):
                self.atoms.mass[sel] = _num(w[k + 1], "mass")
            elif key == "diameter" and k + 1 < len(w) and self.atom_style == "sphere":
                self.atoms.radius[sel] = 0.5 * _num(w[k + 1], "diameter")
            else:
                raise Unsupported(f"set keyword {key!r} is not supported (mass; diameter for spheres); import with "
                                  f"--exact to start from the atoms LAMMPS sets")
            k += 2
        self.note_line("atoms")

    def select(self, style: str, ident: str) -> np.ndarray:
        a = self.atoms
        if style == "type":
            mask = np.zeros(a.n, bool)
            for t in _type_range(ident, max(self.ntypes, 1)):
                mask |= a.types == t
            return mask
        if style == "group":
            return a.group(ident)
        if style == "atom":
            try:
                return select_ids(a.ids, ident)
            except ValueError as exc:
                raise Unsupported(str(exc)) from None
        raise Unsupported(f"set {style}: use type, group or atom")

    def c_group(self, w: list[str]) -> None:
        if len(w) < 3:
            raise Unsupported("group takes an ID and a style")
        name, style, args = w[1], w[2], w[3:]
        a = self.atoms
        if name == "all":
            raise Unsupported("group all cannot be redefined")
        if style == "delete":
            a.groups.pop(name, None)
            return
        if style == "clear":
            a.groups[name] = np.zeros(a.n, bool)
            return
        if style == "empty":
            mask = np.zeros(a.n, bool)
        elif style in ("type", "id"):
            values = a.types if style == "type" else a.ids
            mask = np.zeros(a.n, bool)
            ops = {"<": np.less, "<=": np.less_equal, ">": np.greater, ">=": np.greater_equal, "==": np.equal,
                   "!=": np.not_equal}
            if args and args[0] in ops:
                mask = ops[args[0]](values, _int(args[1], style))
            elif args and args[0] == "<>":
                mask = (values >= _int(args[1], style)) & (values <= _int(args[2], style))
            else:
                for word in args:
                    if style == "type":
                        for t in _type_range(word, max(self.ntypes, 1)):
                            mask |= values == t
                    else:
                        try:
                            for lo, hi in parse_id_ranges(word):
                                mask |= (values >= lo) & (values <= hi)
                        except ValueError as exc:
                            raise Unsupported(str(exc)) from None
        elif style == "region":
            if len(args) != 1:
                raise Unsupported("group region takes one region ID")
            if np.isnan(a.x).any():
                raise Unsupported("group region over atoms that wallbatch places at random (create_atoms random): "
                                  "which atoms are inside is not known before the run; use --exact")
            mask = self.geom(args[0]).contains(a.x) if a.n else np.zeros(0, bool)
        elif style in ("subtract", "union", "intersect"):
            masks = [a.group(g) for g in args]
            if not masks:
                raise Unsupported(f"group {style} needs groups")
            if style == "subtract":
                mask = masks[0].copy()
                for m in masks[1:]:
                    mask &= ~m
            elif style == "union":
                mask = np.logical_or.reduce(masks)
            else:
                mask = np.logical_and.reduce(masks)
        else:
            raise Unsupported(f"group style {style} is not supported (type, id, region, subtract, union, intersect)")
        a.groups[name] = a.groups.get(name, np.zeros(a.n, bool)) | mask
        self.note_line("atoms")

    def c_velocity(self, w: list[str]) -> None:
        """`velocity G create T SEED` / `velocity G set vx vy vz` (velocities in lattice or box units)."""
        if self.exact_state is not None:
            self.note_line("atoms")
            return
        if len(w) < 3:
            raise Unsupported("velocity takes a group and a style")
        sel, style, rest = self.atoms.group(w[1]), w[2], w[3:]
        if style == "create":
            if len(rest) < 2:
                raise Unsupported("velocity create takes T and a seed")
            temp, seed = _num(rest[0], "the temperature"), _int(rest[1], "the seed")
            kw = dict(zip(rest[2::2], rest[3::2]))
            bad = {k: v for k, v in kw.items() if (k, v) not in {("dist", "gaussian"), ("dist", "uniform"),
                                                                  ("mom", "yes"), ("rot", "no"), ("loop", "all"),
                                                                  ("loop", "geom"), ("loop", "local")}}
            if bad:
                raise Unsupported(f"velocity create keywords {bad} are not supported (wallbatch: zero momentum, no "
                                  f"rotation removal){EXACT_VELOCITIES}")
            self.seed = self.seed if self.seed is not None else seed
            spec = {"temperature": temp}
            self.atoms.vel_group[len(self.atoms.velocities)] = w[1]
            self.notes.append(f"{self.here()}: velocity create: wallbatch draws Gaussian velocities with zero "
                              f"momentum at exactly T over the LAMMPS group {w[1]} (the wallbatch groups it spans "
                              f"share one draw: velocity.shared; other random numbers than LAMMPS); --exact uses "
                              f"LAMMPS's")
        elif style == "set":
            if len(rest) < 3:
                raise Unsupported("velocity set takes vx vy vz")
            kw = dict(zip(rest[3::2], rest[4::2]))
            units = kw.pop("units", "lattice")
            if kw.get("sum", "no") != "no" or set(kw) - {"sum"}:
                raise Unsupported(f"velocity set keywords {kw} are not supported{EXACT_VELOCITIES}")
            if "NULL" in rest[:3]:
                raise Unsupported(f"velocity set with NULL components is not supported{EXACT_VELOCITIES}")
            s = self.scale(units)
            spec = {"values": [_num(v, "a velocity") * float(a) for v, a in zip(rest[:3], s)]}
        else:
            raise Unsupported(f"velocity {style} is not supported (create, set){EXACT_VELOCITIES}")
        self.atoms.velocities.append(spec)
        self.atoms.vel[sel] = len(self.atoms.velocities) - 1
        self.note_line("atoms")

    def c_variable(self, w: list[str]) -> None:
        if len(w) < 3:
            raise Unsupported("variable takes a name and a style")
        name, style, args = w[1], w[2], w[3:]
        if style == "delete":
            self.vars.pop(name, None)
            return
        if style == "index":
            if name not in self.vars:
                self.vars[name] = ("index", args[0] if args else "")
        elif style == "string":
            self.vars[name] = ("string", " ".join(args))
        elif style == "internal":
            self.vars[name] = ("internal", _num(args[0], "an internal variable's value"))
        elif style == "equal":
            # a formula wallbatch cannot evaluate (thermo keywords like ke, c_ID, ...) is reported
            # where it is used (a wall, a substitution), not here: thermo_style may use it
            self.vars[name] = ("equal", " ".join(args))
        else:
            raise Unsupported(f"variable style {style} is not supported (equal, index, internal, string)")
        self.note_line("variables")
        self.where[f"var:{name}"] = self.cmd

    # -- commands: forces, fixes, run ---------------------------------------------------------

    def c_pair_style(self, w: list[str]) -> None:
        if w[1:] == ["none"]:
            self.pair = None
            return
        if len(w) != 3 or w[1] != "lj/cut":
            raise Unsupported(f"pair_style {' '.join(w[1:])}: wallbatch has lj/cut (one global cutoff) or none")
        self.pair = {"style": "lj/cut", "cutoff": _num(w[2], "the cutoff")}
        self.note_line("pair")

    def c_pair_coeff(self, w: list[str]) -> None:
        if self.pair is None:
            raise Unsupported("pair_coeff without pair_style lj/cut")
        if len(w) not in (5, 6):
            raise Unsupported("pair_coeff I J epsilon sigma [cutoff]")
        if len(w) == 6 and _num(w[5], "the cutoff") != self.pair["cutoff"]:
            raise Unsupported("a per-pair cutoff differing from pair_style's is not supported")
        eps, sig = _num(w[3], "epsilon"), _num(w[4], "sigma")
        n = max(self.ntypes, 1)
        for i in _type_range(w[1], n):
            for j in _type_range(w[2], n):
                self.pair_coeffs[(min(i, j), max(i, j))] = (eps, sig)
        self.where["pair_coeff"] = self.cmd
        self.note_line("pair")

    def c_pair_modify(self, w: list[str]) -> None:
        kw = dict(zip(w[1::2], w[2::2]))
        if set(kw) - {"shift"} or kw.get("shift") not in ("yes", "no"):
            raise Unsupported(f"pair_modify {' '.join(w[1:])}: only shift yes|no is supported")
        if self.pair is None:
            raise Unsupported("pair_modify without pair_style lj/cut")
        self.pair["shift"] = kw["shift"] == "yes"
        self.note_line("pair")

    def c_timestep(self, w: list[str]) -> None:
        self.timestep = _num(w[1], "the timestep")
        self.note_line("timestep")

    def c_reset_timestep(self, w: list[str]) -> None:
        if w[1:2] != ["0"] or w[2:] not in ([], ["time", "0.0"], ["time", "0"]):
            raise Unsupported("reset_timestep other than to 0 is not supported")
        self.steps_after_min = False
        self.ignore_here("wallbatch runs start at step 0 and time 0")

    def c_compute(self, w: list[str]) -> None:
        if len(w) >= 4 and w[3] == "erotate/asphere":
            self.computes[w[1]] = w[3]
            self.ignore_here("wallbatch's erot output (and ke, etot include it)")
            return
        raise Unsupported(f"compute {' '.join(w[3:4])} is not known to wallbatch")

    def c_fix(self, w: list[str]) -> None:
        if len(w) < 4:
            raise Unsupported("fix takes an ID, a group and a style")
        fid, group, style = w[1], w[2], w[3]
        self.where[f"fix:{fid}"] = self.cmd
        if style in INTEGRATORS:
            if len(w) > 4:
                raise Unsupported(f"fix {style} keywords {' '.join(w[4:])} are not supported")
            self.integrators.append((fid, group, style))
            self.where.setdefault("integrate", self.cmd)
            self.note_line("integrators")
            return
        if style == "dt/reset":
            self.fix_dt_reset(w)
            return
        if style.startswith("wall/"):
            line = " ".join(shlex.quote(x) if re.search(r"\s", x) else x for x in w)
            try:
                wall = parse_fix_line(line, fid)
            except FixLineError as exc:
                raise Unsupported(str(exc)) from None
            self.atoms.group(group)  # must exist
            if wall.get("style") == "flow" and self.seed is None:
                self.seed = int(wall["seed"])  # the config's master seed: the script's first seed
            self.walls[fid] = wall
            self.wall_lines[fid] = self.cmd
            self.note_line(f"walls.{fid}")
            return
        if style in ENSEMBLE_FIXES and "fixes" in Config.model_fields:  # a wallbatch with a fixes: section
            try:
                parse_ensemble_line(" ".join(w), fid)
            except FixLineError as exc:
                raise Unsupported(str(exc)) from None
            self.atoms.group(group)  # must exist
            self.ensemble.append((fid, group, w))
            self.where.setdefault("integrate", self.cmd)
            self.note_line("integrators")
            return
        raise Unsupported(f"fix {style} is not supported by this version of wallbatch")

    def fix_dt_reset(self, w: list[str]) -> None:
        if len(w) < 8:
            raise Unsupported("fix dt/reset N Tmin Tmax Xmax [units box|lattice] [emax e]")
        bound = lambda s: None if s in ("NULL", "INF") else _num(s, "a dt bound")
        spec: dict[str, Any] = {"every": _int(w[4], "N"), "group": w[2], "tmin": bound(w[5]), "tmax": bound(w[6]),
                                "xmax": _num(w[7], "Xmax")}
        kw = w[8:]
        k = 0
        while k < len(kw):
            if kw[k] == "units" and k + 1 < len(kw):
                spec["units"] = kw[k + 1]
            elif kw[k] == "emax" and k + 1 < len(kw):
                spec["emax"] = _num(kw[k + 1], "emax")
            else:
                raise Unsupported(f"fix dt/reset keyword {kw[k]!r} is not supported")
            k += 2
        self.dt_reset = spec
        self.where["dt_reset"] = self.cmd
        self.note_line("dt_reset")

    def c_fix_modify(self, w: list[str]) -> None:
        fid = w[1]
        kw = dict(zip(w[2::2], w[3::2]))
        if fid not in self.walls:
            raise Unsupported(f"fix_modify of {fid!r}, which is not a wall fix")
        for key, value in kw.items():
            if key not in ("energy", "virial") or value not in ("yes", "no"):
                raise Unsupported(f"fix_modify {key} {value}: only energy and virial yes|no")
            self.walls[fid][key] = value == "yes"
        self.note_line(f"walls.{fid}")

    def c_unfix(self, w: list[str]) -> None:
        if w[1] in self.walls and self.first_run_line is None:
            del self.walls[w[1]]
            return
        raise Unsupported("unfix is supported only for walls removed before the run")

    def c_thermo(self, w: list[str]) -> None:
        self.thermo = _int(w[1], "the thermo interval")
        self.note_line("run")

    def c_thermo_style(self, w: list[str]) -> None:
        if w[1] != "custom":
            self.thermo_style = None
            self.ignore_here("thermo_style one/multi: wallbatch's default outputs")
            return
        out = []
        dropped = []
        for word in w[2:]:
            if word in THERMO_MAP:
                out.append(THERMO_MAP[word])
            elif word.startswith("f_") and word[2:].split("[")[0] in self.walls:
                continue  # wall energies and forces are always in the results
            elif word.startswith("c_") and self.computes.get(word[2:]) == "erotate/asphere":
                out.append("erot")
            elif word.startswith("v_") and self.rotational_sum(word[2:]):
                out.append(self.rotational_sum(word[2:]))
            else:
                dropped.append(word)
        if dropped:
            self.notes.append(f"{self.here()}: thermo columns {' '.join(dropped)} have no wallbatch output "
                              f"and are left out")
        self.thermo_style = list(dict.fromkeys(out))
        self.note_line("output")

    def rotational_sum(self, var: str) -> str | None:
        """`ke+c_ROT` / `etotal+c_ROT` (ROT an erotate/asphere compute): wallbatch's ke / etot."""
        style, text = self.vars.get(var, ("", ""))
        m = re.fullmatch(r"\(?\s*(ke|etotal)\s*\+\s*c_(\w+)\s*\)?", str(text)) if style == "equal" else None
        if m and self.computes.get(m.group(2)) == "erotate/asphere":
            return "ke" if m.group(1) == "ke" else "etot"
        return None

    def c_dump(self, w: list[str]) -> None:
        if len(w) < 6 or w[3] not in ("atom", "custom"):
            raise Unsupported("dump styles other than atom and custom are not supported")
        fields = set()
        cols = w[6:] if w[3] == "custom" else ["x", "y", "z"]
        for c in cols:
            if c in ("x", "y", "z", "xu", "yu", "zu", "xs", "ys", "zs"):
                fields.add("x")
            elif c in ("vx", "vy", "vz"):
                fields.add("v")
        self.dump = {"every": _int(w[4], "N"), "fields": [f for f in ("x", "v") if f in fields] or ["x"]}
        self.notes.append(f"{self.here()}: dump {w[1]}: wallbatch stores the trajectory in its results file "
                          f"(output.dump), not in {w[5]}")
        self.note_line("output")

    def c_dump_modify(self, w: list[str]) -> None:
        self.ignore_here("dump formatting")

    def c_undump(self, w: list[str]) -> None:
        self.ignore_here("dump formatting")

    def c_min_style(self, w: list[str]) -> None:
        if w[1] not in ("cg", "fire"):
            raise Unsupported(f"min_style {w[1]}: wallbatch has cg and fire")
        self.min_style = w[1]
        self.note_line("minimize")

    def c_min_modify(self, w: list[str]) -> None:
        kw = dict(zip(w[1::2], w[2::2]))
        if set(kw) - {"dmax"}:
            raise Unsupported(f"min_modify {' '.join(w[1:])}: only dmax is supported")
        self.dmax = _num(kw["dmax"], "dmax")
        self.note_line("minimize")

    def c_minimize(self, w: list[str]) -> None:
        if self.run is not None or self.minimize is not None:
            raise Unsupported("a second minimize, or a minimize after a run: wallbatch runs one minimize, then one "
                              "run")
        self.mark_first_run()
        self.minimize = {"style": self.min_style, "etol": _num(w[1], "etol"), "ftol": _num(w[2], "ftol"),
                         "maxiter": _int(w[3], "maxiter"), "maxeval": _int(w[4], "maxeval")}
        if self.dmax is not None:
            self.minimize["dmax"] = self.dmax
        self.steps_after_min = True
        self.note_line("minimize")

    def c_run(self, w: list[str]) -> None:
        if self.run is not None:
            raise Unsupported("a second run: wallbatch imports the first run only")
        self.mark_first_run()
        if len(w) > 2:
            self.unsupported_here(f"run keywords {' '.join(w[2:])} are not supported; the run length is kept")
        self.run = _int(w[1], "the number of steps")
        self.note_line("run")
        if self.steps_after_min:
            self.unsupported_here("after minimize, LAMMPS's run starts at the step the minimizer stopped at, so its "
                                  "thermo samples and 'step' in variables differ from wallbatch's run, which starts "
                                  "at step 0: add 'reset_timestep 0' after minimize (as export-lammps writes)")

    def mark_first_run(self) -> None:
        if self.first_run_line is None:
            self.first_run_line = len(self.lines_before_run) - 1
            self.lines_before_run.pop()

    # -- the config ---------------------------------------------------------------------------

    def wall_group(self, name: str, parts: dict[str, np.ndarray], where: str) -> str:
        if name == "all":
            return "all"
        mask = self.atoms.group(name)
        if mask.all():
            return "all"
        for pname, pmask in parts.items():
            if np.array_equal(pmask, mask):
                return pname
        raise Unsupported(f"{where}: group {name} is not one atom group of the imported config (wallbatch walls act "
                          f"on one group or all)")

    def partitions(self, used: list[str]) -> list[tuple[str, np.ndarray, dict]]:
        """Disjoint wallbatch atom groups: (name, mask, entry without group)."""
        a = self.atoms
        if a.n == 0:
            why = [i for i in self.unsupported
                   if i.text.split()[:1] and i.text.split()[0] in ("create_atoms", "read_data", "region", "lattice")]
            because = "".join(f"\n  {i.file or self.script}:{i.line}: {i.text.strip()}  ->  {i.reason}" for i in why)
            raise LammpsImportError(f"{self.script}: the script creates no atoms (create_atoms or read_data)"
                                    + (f"; not imported:{because}" if because else ""))
        # one row of integer keys per atom; equal rows = one wallbatch group
        single = np.array([c.kind == "single" for c in a.chunks])[a.chunk]
        cols = [np.where(single, -1, a.chunk), a.types, _codes(a.mass), _codes(a.radius), a.vel]
        cols += [a.groups[g].astype(np.int64) for g in used]
        _, first, inverse = np.unique(np.stack(cols, axis=1), axis=0, return_index=True, return_inverse=True)
        inverse = inverse.ravel()
        keys: dict[tuple, np.ndarray] = {}
        for k in np.argsort(first, kind="stable"):  # groups in order of their first atom
            i = int(first[k])
            key = (None, int(a.types[i]), None if np.isnan(a.mass[i]) else float(a.mass[i]),
                   None if np.isnan(a.radius[i]) else float(a.radius[i]), int(a.vel[i]))
            keys[key + (int(k),)] = np.flatnonzero(inverse == k)
        spans: dict[int, int] = {}  # velocity spec -> the groups it is given to
        for key in keys:
            spans[key[4]] = spans.get(key[4], 0) + 1
        labels: dict[int, str] = {}  # a shared set's label: the LAMMPS group (made unique, a valid name)
        for k in sorted(k for k in a.vel_group if spans.get(k, 0) > 1):
            base = re.sub(r"[^A-Za-z0-9_\-]", "_", a.vel_group[k])
            base = base if re.match(r"[A-Za-z_]", base) else "v_" + base
            label, n = base, 2
            while label in labels.values():
                label, n = f"{base}_{n}", n + 1
            labels[k] = label
        names: set[str] = set()
        out = []
        for key, idx in keys.items():
            mask = np.zeros(a.n, bool)
            mask[idx] = True
            chunk = a.chunks[a.chunk[idx[0]]]
            entry: dict[str, Any] = {}
            whole = np.array_equal(mask, a.chunk == a.chunk[idx[0]]) if chunk.kind != "single" else True
            if chunk.kind == "file":
                entry["create"] = {"file": chunk.spec["file"]}
                if not whole:
                    entry["create"]["ids"] = id_ranges(a.ids[mask])
            elif chunk.kind == "single":
                entry["create"] = {"positions": a.x[mask].tolist()}
            elif chunk.kind == "lattice":
                entry["create"] = chunk.spec if whole else {"positions": a.x[mask].tolist()}
            else:
                spec = dict(chunk.spec["random"])
                spec["count"] = int(mask.sum())
                entry["create"] = {"random": spec}
            t = key[1]
            if key[3] is not None:
                entry["radius"] = key[3]
            elif chunk.kind != "file" and self.atom_style == "sphere":
                entry["radius"] = 0.5  # LAMMPS's default diameter 1 for created sphere atoms
            if key[2] is not None:
                entry["mass"] = key[2]
            elif chunk.kind != "file" and self.atom_style == "sphere":
                r = entry["radius"]  # LAMMPS: density 1 for created sphere atoms
                entry["mass"] = 4.0 * math.pi / 3.0 * r * r * r if r > 0 else 1.0
            elif chunk.kind != "file" or (self.atom_style == "atomic" and t in self.type_mass):
                if t not in self.type_mass and chunk.kind != "file":
                    raise Unsupported(f"atom type {t} has no mass (mass {t} VALUE)")
                if t in self.type_mass:
                    entry["mass"] = self.type_mass[t]
            if key[4]:
                entry["velocity"] = dict(a.velocities[key[4]])
                if key[4] in labels:  # one `velocity create` over several groups: one draw
                    entry["velocity"]["shared"] = labels[key[4]]
            name = self.part_name(mask, used, t, names)
            names.add(name)
            out.append((name, mask, entry))
        return out

    def part_name(self, mask: np.ndarray, used: list[str], atype: int, taken: set[str]) -> str:
        for g in list(used) + list(self.atoms.groups):
            if np.array_equal(self.atoms.groups[g], mask) and g not in taken:
                return g
        inside = [g for g in used if g in self.atoms.groups and not np.any(mask & ~self.atoms.groups[g])]
        base = "_".join(inside) if inside else f"type{atype}"
        if base in self.atoms.groups:  # a strict subset of that LAMMPS group: the rest of it
            base += "_only"
        if not re.fullmatch(r"[A-Za-z_][A-Za-z0-9_\-]*", base):
            base = f"g_{base}"
        name, k = base, 2
        while name in taken or name in self.atoms.groups:
            name, k = f"{base}_{k}", k + 1
        return name

    def build(self, name: str) -> tuple[dict, dict[str, list[str]]]:
        if self.box is None:
            # the commands a box comes from that were not imported: they are why there is none
            why = [i for i in self.unsupported
                   if i.text.split()[:1] and i.text.split()[0] in ("create_box", "read_data", "region", "lattice")]
            because = "".join(f"\n  {i.file or self.script}:{i.line}: {i.text.strip()}  ->  {i.reason}" for i in why)
            raise LammpsImportError(f"{self.script}: no box (create_box or read_data) in the script"
                                    + (f"; not imported:{because}" if because else ""))
        data: dict[str, Any] = {"name": name, "units": self.units}
        if self.seed is not None:
            data["seed"] = self.seed
        if self.dimension == 2:
            data["dimension"] = 2
        data["box"] = {"lo": self.box[0], "hi": self.box[1], "boundary": self.boundary}
        if self.lattice is not None:
            data["lattice"] = self.lattice
        used = []
        for fid, wall in self.walls.items():
            used.append(wall.get("group", "all"))
        used += [g for _, g, _ in self.ensemble]
        if self.dt_reset is not None:
            used.append(self.dt_reset["group"])
        integrator_only = {g for _, g, _ in self.integrators} - set(used)
        if "fixes" in Config.model_fields and (self.ensemble or self.partial_integration()):
            integrator_only = set()  # the fixes: section names these groups
        used += list(self.atoms.groups)  # every LAMMPS group the script defines keeps its atoms apart
        used = [g for g in dict.fromkeys(used) if g != "all" and g in self.atoms.groups and g not in integrator_only]
        parts = self.partitions(used)
        pmasks = {p: m for p, m, _ in parts}
        data["atoms"] = [{"group": p, **entry} for p, _, entry in parts]
        fixes = self.fixes_section(pmasks)
        if fixes:
            data["fixes"] = fixes
        else:
            self.check_integrators(parts)
        if self.pair is not None:
            coeffs = set(self.pair_coeffs.values())
            if not coeffs:
                raise LammpsImportError(f"{self.script}: pair_style lj/cut without pair_coeff")
            (ti, tj), (eps, sig) = next(iter(self.pair_coeffs.items()))
            if len(coeffs) > 1:
                sets = ", ".join(f"types {i} {j}: {e:g} {s:g}" for (i, j), (e, s) in self.pair_coeffs.items())
                self.issue_at("pair_coeff", "pair_coeff", f"several lj/cut coefficient sets ({sets}): "
                                              f"wallbatch has one epsilon and sigma for all atom pairs (per-type "
                                              f"coefficients are not supported yet); the config uses epsilon {eps:g} "
                                              f"sigma {sig:g} (types {ti} {tj}) for every pair")
            data["pair"] = {"style": "lj/cut", "epsilon": eps, "sigma": sig, "cutoff": self.pair["cutoff"],
                            **({"shift": True} if self.pair.get("shift") else {})}
        if self.timestep is not None:
            data["timestep"] = self.timestep
        walls: dict[str, Any] = {}
        for fid, wall in self.walls.items():
            wall = dict(wall)
            try:
                wall["group"] = self.wall_group(wall.get("group", "all"), pmasks, f"fix {fid}")
            except Unsupported as exc:
                c = self.wall_lines[fid]
                self.unsupported.append(Issue(c.line, c.raw, str(exc)))
                continue
            if wall["group"] == "all":
                del wall["group"]
            self.lattice_free_units(wall, fid)
            if wall.get("region") is not None and wall["region"] not in self.regions:
                c = self.wall_lines[fid]
                self.unsupported.append(Issue(c.line, c.raw, f"unknown region {wall['region']!r}"))
                continue
            walls[fid] = wall
        refs = self.variable_refs(walls)
        if refs:
            data["variables"] = refs
        used_regions = {w.get("region") for w in walls.values()} | {
            (e["create"].get("random") or e["create"].get("lattice") or {}).get("region") for e in data["atoms"]}
        regions = {k: v for k, v in self.regions.items() if k in used_regions}
        if regions:
            data["regions"] = regions
        if walls:
            data["walls"] = walls
        if self.dt_reset is not None:
            d = dict(self.dt_reset)
            try:
                d["group"] = self.wall_group(d["group"], pmasks, "fix dt/reset")
            except Unsupported as exc:
                self.issue_at("dt_reset", "fix dt/reset", str(exc))
            if d["group"] == "all":
                del d["group"]
            if d.get("units", "lattice") == "lattice" and self.lattice is None:
                d["xmax"] = d["xmax"] * (self.spacing or 1.0)
                d["units"] = "box"
            data["dt_reset"] = d
        if self.minimize is not None:
            data["minimize"] = self.minimize
        if self.run is None:
            self.issue_at("end", "(end of script)", "no run command: imported as a run of 0 steps")
        data["run"] = {"steps": self.run or 0, "thermo": self.thermo}
        output: dict[str, Any] = {}
        if self.thermo_style is not None and self.thermo_style != DEFAULT_THERMO:
            output["thermo"] = self.thermo_style
        if self.dump is not None:
            output["dump"] = self.dump
        if output:
            data["output"] = output
        return data, self.comments

    def lattice_free_units(self, wall: dict, fid: str) -> None:
        """Walls in lattice units (LAMMPS's default) without a lattice, or with a hex lattice
        (whose x and y spacings differ, which a config's lattice units cannot say): LAMMPS scales
        each face's coordinate by its axis's spacing (`lattice none`: 1.0 by default), so they are
        written in box units."""
        hex_ = self.lattice is not None and self.lattice["style"] == "hex"
        if wall.get("style") in ("region", "region/ees") or (self.lattice is not None and not hex_):
            return
        if wall.get("units", "lattice") == "lattice":
            spacing = self.scale("lattice") if hex_ else np.full(3, self.spacing if self.spacing is not None else 1.0)
            if np.any(spacing != 1.0):
                for face in ("xlo", "xhi", "ylo", "yhi", "zlo", "zhi"):
                    f, s = wall.get(face), float(spacing["xyz".index(face[0])])
                    c = f.get("coord") if isinstance(f, dict) else f
                    if isinstance(c, float):
                        if isinstance(f, dict):
                            f["coord"] = c * s
                        else:
                            wall[face] = c * s
                    elif isinstance(c, str) and c.startswith("v_"):
                        self.unsupported.append(Issue(self.wall_lines[fid].line, self.wall_lines[fid].raw,
                                                      f"a variable coordinate in lattice units of lattice "
                                                      f"{'hex' if hex_ else 'none'} (write the wall with units box)"))
                if wall.get("style") == "flow":
                    s = float(spacing["xyz".index(wall["axis"])])
                    wall["coords"] = [c * s for c in wall["coords"]]
            wall["units"] = "box"

    def variable_refs(self, walls: dict) -> dict[str, Any]:
        """The variables the walls reference (v_name), with the ones those reference. An undefined
        one is reported at the line that uses it (the wall fix, or the variable referencing it)."""
        names: list[tuple[str, str]] = []  # (name, the `where` topic of the line that uses it)

        def scan(value: Any, topic: str) -> None:
            if isinstance(value, dict):
                for v in value.values():
                    scan(v, topic)
            elif isinstance(value, list):
                for v in value:
                    scan(v, topic)
            elif isinstance(value, str) and value.startswith("v_"):
                names.append((value[2:], topic))

        for fid, wall in walls.items():
            scan(wall, f"fix:{fid}")
        out: dict[str, Any] = {}
        while names:
            n, user = names.pop(0)
            if n in out:
                continue
            if n not in self.vars:
                self.issue_at(user, f"v_{n}", f"variable {n} is not defined")
                continue
            style, value = self.vars[n]
            if style == "equal":
                out[n] = value
                try:
                    names += [(r.name, f"var:{n}") for r in _walk(parse(value)) if isinstance(r, VarRef)]
                except VariableError as exc:
                    self.issue_at(f"var:{n}", f"v_{n}", f"equal-style formula of {n} that wallbatch cannot "
                                  f"evaluate: {exc}")
            elif style == "internal":
                out[n] = float(value)
            else:
                try:
                    out[n] = float(value)
                except ValueError:
                    self.issue_at(f"var:{n}", f"v_{n}", f"{style} variable {n} is not a number")
        return out

    def partial_integration(self) -> bool:
        """Some atom is integrated by no fix nve, or by two."""
        count = np.zeros(self.atoms.n, int)
        for _, group, _ in self.integrators:
            if group == "all" or group in self.atoms.groups:
                count += self.atoms.group(group)
        return bool(np.any(count != 1))

    def fixes_section(self, pmasks: dict[str, np.ndarray]) -> dict[str, str]:
        """`fixes:` (fix-ID -> verbatim LAMMPS line, its group renamed to the config's) when the
        script has thermostats or integrates only part of the atoms and this wallbatch has a
        fixes: section; {} when the default integration (nve on every atom) says it all."""
        if "fixes" not in Config.model_fields:
            return {}
        if not self.ensemble and not self.partial_integration():
            return {}
        out = {}
        lines = [(fid, group, ["fix", fid, group, "nve" if style == "nve/sphere" else style])
                 for fid, group, style in self.integrators] + self.ensemble
        for fid, group, words in lines:
            try:
                name = self.wall_group(group, pmasks, f"fix {fid}")
            except Unsupported as exc:
                self.issue_at("integrate", f"fix {fid}", str(exc))
                continue
            out[fid] = " ".join(["fix", fid, name, *words[3:]])
        return out

    def check_integrators(self, parts: list) -> None:
        """The integrator fixes must together integrate every atom once, nve/asphere for ellipsoids
        and nve for the others: wallbatch's (only) integration."""
        if not self.integrators:
            self.issue_at("end", "(no fix nve)", "the script integrates no atom (no fix nve): wallbatch "
                                          "integrates every atom with nve (nve/asphere for ellipsoids)")
            return
        count = np.zeros(self.atoms.n, int)
        for fid, group, style in self.integrators:
            try:
                count += self.atoms.group(group)
            except Unsupported as exc:
                self.issue_at("integrate", f"fix {fid}", str(exc))
        if np.any(count != 1):
            self.issue_at("integrate", "fix " + " ".join(f[0] for f in self.integrators),
                                          "wallbatch integrates every atom exactly once (nve): atoms integrated "
                                          f"{sorted(set(count.tolist()))} time(s) here (static or "
                                          "doubly integrated atoms need the fixes: section of a newer wallbatch)")


# ----------------------------------------------------------------------------- YAML


def _flow(value: Any) -> str:
    return yaml.safe_dump(value, default_flow_style=True, width=10 ** 6, sort_keys=False).strip()


def _yaml(data: dict, comments: dict[str, list[str]], header: list[str], tail: list[str]) -> str:
    """The config as YAML, each section preceded by the LAMMPS lines it comes from."""
    out = [f"# {h}" if h else "#" for h in header]

    def lines_for(key: str) -> list[str]:
        return [f"# {c}" for c in comments.get(key, [])]

    order = {"units": ["units"], "box": ["box"], "lattice": ["lattice"], "timestep": ["timestep"],
             "pair": ["pair"], "dt_reset": ["dt_reset"], "minimize": ["minimize"], "run": ["run"],
             "output": ["output"], "variables": ["variables"], "atoms": ["atoms", "integrators"],
             "dimension": ["dimension"]}
    if "output" not in data:  # thermo_style lines that gave the default outputs
        comments = {**comments, "run": comments.get("run", []) + comments.get("output", [])}
    for key, value in data.items():
        out.append("")
        for k in order.get(key, []):
            out += lines_for(k)
        if key in ("walls", "regions"):
            out.append(f"{key}:")
            for sub, item in value.items():
                out += ["  " + c for c in lines_for(f"{key}.{sub}")]
                out.append(f"  {_flow({sub: item})[1:-1]}")
        elif key == "atoms":
            out.append("atoms:")
            for item in value:
                out.append(f"  - {_flow(item)}")
        elif key == "variables":
            out.append("variables:")
            for sub, item in value.items():
                out.append(f"  {_flow({sub: item})[1:-1]}")
        else:
            out.append(f"{_flow({key: value})[1:-1]}")
    if tail:
        out += [""] + [f"# {t}" if t else "#" for t in tail]
    return "\n".join(out) + "\n"


# ----------------------------------------------------------------------------- entry points


def _with_line(problem: str, imp: _Importer) -> str:
    """A validation problem of walls.ID / fixes.ID prefixed with the script line of fix ID."""
    m = re.search(r": (?:walls|fixes)\.([A-Za-z0-9_]+)", problem)
    c = imp.where.get(f"fix:{m.group(1)}") if m else None
    if c is None:
        return problem
    return Issue(c.line, c.raw, problem, c.file if c.file != str(imp.script) else "").format()


def _relative(path: str, base: Path) -> str:
    try:
        return os.path.relpath(Path(path).resolve(), base.resolve())
    except ValueError:
        return str(path)


def run_setup_in_lammps(script: Path, commands: list[_Cmd], variables: dict[str, str], data_out: Path) -> None:
    """Run the script's commands before its first run/minimize in LAMMPS (Python module) and write
    the state with write_data (17 significant digits: exact doubles)."""
    module = load_lammps()
    args = ["-screen", "none", "-log", "none", "-nocite"]
    for k, v in variables.items():
        args += ["-var", k, str(v)]
    here = os.getcwd()
    lmp = module.lammps(cmdargs=args)
    try:
        os.chdir(script.parent)
        for c in commands:
            words = _strip_comment(c.raw).split()
            if words and words[0] not in SETUP_SKIPPED:
                lmp.command(c.raw)
        lmp.command(f'write_data "{data_out.resolve()}" nocoeff')
    except Exception as exc:  # noqa: BLE001 - LAMMPS raises a plain Exception with its message
        raise LammpsImportError(f"LAMMPS stopped while running the script's setup (--exact): "
                                f"{str(exc).strip() or type(exc).__name__}") from None
    finally:
        os.chdir(here)
        lmp.close()


def import_lammps(script: str | Path, output: str | Path | None = None, variables: dict[str, str] | None = None,
                  exact: bool = False, name: str | None = None) -> ImportResult:
    """Import a LAMMPS input script. `output` (the config path to be written) decides where
    relative paths point from and, with `exact`, where the state's data file goes (beside it,
    same stem, `.data`). Raises LammpsImportError when the script cannot be read at all, and
    wallbatch.lammps.validate.LammpsMissing for `exact` without LAMMPS."""
    script = Path(script)
    variables = dict(variables or {})
    out_dir = Path(output).parent if output is not None else Path(".")
    stem = Path(output).stem if output is not None else script.name.replace("in.", "", 1).split(".")[0] or "imported"
    name = name or (script.name[3:] if script.name.startswith("in.") else script.stem) or "imported"
    imp = _Importer(script, variables)
    imp.run_file(script)
    written: list[Path] = []
    if exact:
        state = out_dir / f"{stem}.data"
        if imp.first_run_line is None:
            raise LammpsImportError(f"{script}: --exact needs a run or minimize command (the state before it is "
                                    f"written)")
        run_setup_in_lammps(script, imp.lines_before_run, variables, state)
        written.append(state)
        # LAMMPS's state replaces the created atoms; groups are evaluated on it, in script order
        df = read_data_file(state, imp.atom_style, tuple(b == "p" for b in imp.boundary))
        imp = _Importer(script, variables, exact_state=state)
        imp.add_file_chunk(df, state)
        imp.run_file(script)
        imp.notes.append(f"--exact: positions, velocities and masses are LAMMPS's state before the first "
                         f"run/minimize, written to {state.name} (groups are evaluated on that state)")
    try:
        data, comments = imp.build(name)
    except Unsupported as exc:  # a problem of the whole script (LAMMPS would not run it either)
        raise LammpsImportError(f"{script}: {exc}") from None
    for entry in data["atoms"]:
        create = entry["create"]
        if "file" in create:
            create["file"] = _relative(create["file"], out_dir)
    header = [f"Imported from {script} by wallbatch import-lammps.",
              "Each section is preceded by the LAMMPS lines it comes from (line number: command).",
              "Add a sweep: block to run it over parameters (docs/howto/sweep-a-wall.md)."]
    problems: list[str] = []
    try:
        # the text as written (the tail comes last), so that FILE:LINE:COL points into the written config
        load_config_text(_yaml(data, comments, header, []), str(output or "<imported config>"), base=out_dir)
    except ConfigError as exc:
        problems = [_with_line(p, imp) for p in exc.problems]
    tail = []
    if imp.notes:
        tail += ["Notes:"] + [f"  {n}" for n in imp.notes]
    if imp.ignored:
        tail += ["Ignored (no effect on the results):"] + [f"  {i.format()}" for i in imp.ignored]
    if imp.unsupported:
        tail += [f"NOT IMPORTED ({len(imp.unsupported)}): the config differs from the script here:"]
        tail += [f"  {i.format()}" for i in imp.unsupported]
    if problems:
        tail += ["The imported config does not validate:"] + [f"  {p}" for p in problems]
    if not imp.unsupported and not problems:
        tail += ["Import complete: every command was imported or is an output setting."]
    text = _yaml(data, comments, header, tail)
    return ImportResult(text, data, imp.unsupported, imp.ignored, imp.notes, written, problems)


def import_lammps_text(text: str, folder: str | Path, **kwargs: Any) -> ImportResult:
    """Import script text (written to FOLDER/in.script first; convenience for tests)."""
    path = Path(folder) / "in.script"
    path.write_text(text)
    return import_lammps(path, **kwargs)
