"""LAMMPS wall fix lines <-> wallbatch's wall mapping form.

In a config a wall may be written as a LAMMPS command string::

    walls:
      top: "fix top all wall/lj126 zhi 20.0 1.0 1.0 2.5 units box"

:func:`parse_fix_line` turns such a string into the plain dict of the config's *mapping form*
(the Pydantic wall models validate it afterwards); :func:`to_fix_line` writes a mapping-form
dict back as a LAMMPS line (for export).

This module checks the *words* of a line: known style, faces and keywords, argument counts,
numbers where numbers are needed, ``EDGE`` / ``v_name`` where LAMMPS allows them. Value ranges
(cutoff > 0, vflow > 0, seed range, T > 0, wall ordering, periodic faces, ...) are left to the
model validators, which check hand-written mappings the same way.

Supported styles and the dicts they give (keys only when they appear in the line; numbers as
``float``, ``EDGE`` and ``v_name`` kept as strings):

* ``wall/STYLE`` for every style of the registry (wallbatch.styles.STYLES) ->
  ``{"style": STYLE, "group": "all", "zlo": {"coord", <the style's parameters>}, ...,
  "units": "box", "pbc": True}``; a face's words are the style's ``positional`` order
  (e.g. ``coord epsilon sigma cutoff``).
  ``fld no`` is accepted and dropped, ``fld yes`` is refused.
* ``wall/reflect`` -> ``{"style": "reflect", "group", "xlo": "EDGE", "xhi": 10.0, "units"}``.
* ``wall/flow AXIS VFLOW T SEED N w1..wN [units lattice|box]`` ->
  ``{"style": "flow", "group", "axis", "vflow", "temperature", "seed" (int), "coords", "units"}``.
* ``wall/region regionID STYLE args`` (the style's parameters, for the styles with ``region``) ->
  ``{"style": "region", "group", "region", "potential", <the style's parameters>}``.
* ``wall/region/ees regionID eps sigma rc`` ->
  ``{"style": "region/ees", "group", "region", "epsilon", "sigma", "cutoff"}``.

Tokenising follows the LAMMPS input reader: words are separated by whitespace, single or
double quotes group words, and an unquoted ``#`` starts a comment that runs to the end of the
line. A keyword given twice keeps its last value, as in LAMMPS.
"""

from __future__ import annotations

import math
import re
import shlex
from collections.abc import Mapping, Sequence
from typing import Any

from wallbatch.styles import STYLES, region_styles

__all__ = [
    "FixLineError",
    "parse_fix_line",
    "to_fix_line",
    "FACES",
    "FLAT_STYLES",
    "REGION_POTENTIALS",
    "SUPPORTED_STYLES",
    "face_fields",
]

FACES: tuple[str, ...] = ("xlo", "xhi", "ylo", "yhi", "zlo", "zhi")
# the registry's styles whose faces are numbers (the others build a style per face from words:
# an expression, a table file); every registry style is read and written by the same code
FLAT_STYLES: tuple[str, ...] = tuple(n for n, s in STYLES.items() if not s.per_face)
REGION_POTENTIALS: tuple[str, ...] = region_styles()
SUPPORTED_STYLES: tuple[str, ...] = tuple(f"wall/{s}" for s in FLAT_STYLES) + (
    "wall/reflect",
    "wall/flow",
    "wall/region",
    "wall/region/ees",
    "wall/reflect/stochastic",
) + tuple(f"wall/{n}" for n, s in STYLES.items() if s.per_face)

_FLAT_KEYWORDS = ("units", "pbc", "fld")
_REFLECT_KEYWORDS = ("units",)
# Mapping keys with no word in the LAMMPS fix line (fix_modify settings, wallbatch options).
_NON_LAMMPS_KEYS = frozenset({"energy", "virial", "frame", "rule"})

_NUMBER_RE = re.compile(r"[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?\Z")
_INT_RE = re.compile(r"[+-]?\d+\Z")
_VARIABLE_RE = re.compile(r"v_[A-Za-z_][A-Za-z0-9_]*\Z")
_ID_RE = re.compile(r"[A-Za-z0-9_]+\Z")


def face_fields(style: str) -> tuple[str, ...]:
    """Field names of one face of a flat wall of ``style``, in LAMMPS argument order."""
    return STYLES[style].positional


def _variable_field(style: str, field: str) -> bool:
    """True if the face field may be an equal-style variable v_name (coord may also be EDGE)."""
    return field != "coord" and STYLES[style].param(field).variable


def _short(name: str) -> str:
    """A parameter's name in usage lines (LAMMPS's manual writes eps and rc)."""
    return {"epsilon": "eps", "cutoff": "rc"}.get(name, name)


class FixLineError(ValueError):
    """A LAMMPS fix line that wallbatch cannot read.

    The message names the offending word and its 1-based position in the line, e.g.
    ``"word 7 'fld': ..."``. The word, its position and the whole line are also kept as the
    attributes ``word``, ``position`` and ``line``.
    """

    def __init__(
        self,
        message: str,
        *,
        word: str | None = None,
        position: int | None = None,
        line: str | None = None,
    ) -> None:
        self.word = word
        self.position = position
        self.line = line
        self.detail = message
        if position is not None:
            message = f"word {position} {word!r}: {message}"
        super().__init__(message)


# --------------------------------------------------------------------------------------------
# parsing


def _split(text: str) -> list[str]:
    lexer = shlex.shlex(text, posix=True)
    lexer.whitespace_split = True
    lexer.commenters = "#"
    lexer.escape = ""  # LAMMPS has no backslash escapes
    try:
        return list(lexer)
    except ValueError as exc:  # unbalanced quotes
        raise FixLineError(
            f"cannot split the fix line into words ({exc}): close the quote", line=text
        ) from None


class _Words:
    """The words of one line and the error helper that names them."""

    def __init__(self, text: str) -> None:
        self.text = text
        self.words = _split(text)

    def __len__(self) -> int:
        return len(self.words)

    def __getitem__(self, i: int) -> str:
        return self.words[i]

    def error(self, i: int, message: str) -> FixLineError:
        """Error about the word at 0-based index ``i``."""
        return FixLineError(message, word=self.words[i], position=i + 1, line=self.text)

    def missing(self, message: str) -> FixLineError:
        """Error about words missing at the end of the line (names the last word)."""
        return self.error(len(self.words) - 1, message)

    # -- typed words ---------------------------------------------------------------------------

    def number(self, i: int, what: str) -> float:
        w = self.words[i]
        if _NUMBER_RE.match(w):
            return float(w)
        hint = ""
        if w.startswith("v_"):
            hint = f" (a v_name variable is not allowed for {what} here)"
        elif w.startswith("$"):
            hint = " (variable substitution with $ is not supported)"
        raise self.error(i, f"{what} must be a number{hint}; write e.g. 2.5 or 1e-5")

    def integer(self, i: int, what: str) -> int:
        w = self.words[i]
        if _INT_RE.match(w):
            return int(w)
        raise self.error(i, f"{what} must be an integer; write e.g. 593894")

    def number_or_variable(self, i: int, what: str) -> float | str:
        w = self.words[i]
        if _NUMBER_RE.match(w):
            return float(w)
        if _VARIABLE_RE.match(w):
            return w
        raise self.error(i, f"{what} must be a number or an equal-style variable v_name{_hint(w)}")

    def coord(self, i: int, what: str) -> float | str:
        w = self.words[i]
        if w == "EDGE" or _VARIABLE_RE.match(w):
            return w
        if _NUMBER_RE.match(w):
            return float(w)
        raise self.error(i, f"{what} must be EDGE, a number or an equal-style variable v_name{_hint(w)}")

    def identifier(self, i: int, what: str) -> str:
        w = self.words[i]
        if _ID_RE.match(w):
            return w
        raise self.error(i, f"{what} must use only letters, digits and underscores")


def _hint(w: str) -> str:
    if w.upper() == "EDGE":
        return " (EDGE is written in capitals)"
    if w.startswith("$"):
        return " (variable substitution with $ is not supported: write v_name)"
    if w.startswith("v_"):
        return " (a variable name starts with a letter or underscore after v_)"
    return ""


def parse_fix_line(text: str, fix_id: str) -> dict:
    """Parse ``'fix ID group style args...'`` into the wall mapping form.

    ``fix_id`` is the mapping key the string was written under: the line's ID must equal it.
    Raises :class:`FixLineError` (a ``ValueError``) naming the offending word and its 1-based
    position.
    """
    if not isinstance(text, str):
        raise FixLineError(f"a fix line must be a string, not {type(text).__name__}")
    w = _Words(text)
    if len(w) == 0:
        raise FixLineError(
            "empty fix line: write 'fix ID group-ID style args ...'", line=text
        )
    if w[0] != "fix":
        raise w.error(0, "a wall line must start with 'fix': write 'fix ID group-ID style args ...'")
    if len(w) < 2:
        raise w.missing(f"missing fix ID, group-ID and style: write 'fix {fix_id} all wall/STYLE ...'")
    if w[1] != fix_id:
        raise w.error(
            1,
            f"the fix ID must equal the mapping key {fix_id!r} the line is written under: "
            f"write 'fix {fix_id} ...' or rename the key to {w[1]!r}",
        )
    if len(w) < 3:
        raise w.missing("missing group-ID and style after the fix ID: write e.g. 'all wall/lj93 ...'")
    group = w.identifier(2, "the group-ID")
    if len(w) < 4:
        raise w.missing(f"missing wall style after the group-ID; supported: {', '.join(SUPPORTED_STYLES)}")
    style = w[3]
    if style not in SUPPORTED_STYLES:
        raise w.error(3, f"unknown or unsupported fix style; supported: {', '.join(SUPPORTED_STYLES)}")
    short = style[len("wall/"):]
    if short in STYLES:
        return _parse_flat(w, short, group)
    if short == "reflect":
        return _parse_reflect(w, group)
    if short == "reflect/stochastic":
        return _parse_stochastic(w, group)
    if short == "flow":
        return _parse_flow(w, group)
    if short == "region":
        return _parse_region(w, group)
    return _parse_region_ees(w, group)


def _face_arguments(w: _Words, i: int, need: int, stops: Sequence[str]) -> int:
    """How many argument words follow the face at index ``i`` (up to ``need``), stopping at
    the end of the line or at a face or keyword name."""
    got = 0
    while got < need and i + 1 + got < len(w) and w[i + 1 + got] not in stops:
        got += 1
    return got


def _keyword_value(w: _Words, i: int, choices: tuple[str, ...]) -> str:
    name = w[i]
    alternatives = " or ".join(f"'{name} {c}'" for c in choices)
    if i + 1 >= len(w):
        raise w.error(i, f"missing value after {name}: write {alternatives}")
    value = w[i + 1]
    if value not in choices:
        raise w.error(i + 1, f"bad {name} value: write {alternatives}")
    return value


def _wall_words(w: _Words, style: str, out: dict) -> int:
    """The style's wall parameters (words before the first face, e.g. wall/table's tabstyle N)
    into ``out``; returns the index of the first face."""
    entry = STYLES[style]
    names = [p.name for p in entry.wall_parameters]
    for k, p in enumerate(entry.wall_parameters):
        j = 4 + k
        if j >= len(w):
            raise w.missing(f"missing arguments: write 'fix {w[1]} {w[2]} wall/{style} {' '.join(names)} face "
                            f"{' '.join(face_fields(style))} ...'")
        if p.kind == "choice":
            if w[j] not in p.choices:
                raise w.error(j, f"{p.name} must be {' or '.join(p.choices)}")
            out[p.name] = w[j]
        elif p.kind == "integer":
            out[p.name] = w.integer(j, f"{p.name} ({p.doc})" if p.doc else p.name)
            if p.min is not None and out[p.name] < p.min:
                raise w.error(j, f"{p.name} must be at least {p.min:g}")
            if p.max is not None and out[p.name] > p.max:
                raise w.error(j, f"{p.name} must be at most {p.max:,.0f}")
        else:
            out[p.name] = w[j]
    return 4 + len(entry.wall_parameters)


def _parse_flat(w: _Words, style: str, group: str) -> dict:
    fields = face_fields(style)
    stops = FACES + _FLAT_KEYWORDS
    out: dict[str, Any] = {"style": style, "group": group}
    faces: dict[str, dict] = {}
    keywords: dict[str, Any] = {}
    i = _wall_words(w, style, out)
    while i < len(w):
        word = w[i]
        if word in FACES:
            if word in faces:
                raise w.error(
                    i,
                    f"{word} wall defined twice: give each face once per fix "
                    "(use a second fix for another wall on the same face)",
                )
            got = _face_arguments(w, i, len(fields), stops)
            if got < len(fields):
                raise w.error(
                    i,
                    f"missing arguments for the {word} wall: wall/{style} faces take "
                    f"{' '.join(fields)} ({len(fields)} words), found {got}",
                )
            face: dict[str, Any] = {}
            for k, field in enumerate(fields):
                j = i + 1 + k
                what = f"{word} {field}"
                if field == "coord":
                    face[field] = w.coord(j, what)
                elif not STYLES[style].param(field).numeric:
                    face[field] = w[j]  # a word: an expression, a file name
                elif _variable_field(style, field):
                    face[field] = w.number_or_variable(j, what)
                else:
                    face[field] = w.number(j, what)
            faces[word] = face
            i += 1 + len(fields)
        elif word == "units":
            keywords["units"] = _keyword_value(w, i, ("lattice", "box"))
            i += 2
        elif word == "pbc":
            keywords["pbc"] = _keyword_value(w, i, ("yes", "no")) == "yes"
            i += 2
        elif word == "fld":
            if _keyword_value(w, i, ("yes", "no")) == "yes":
                raise w.error(
                    i,
                    "fld yes (lubrication) is not supported: wallbatch has no FLD lubrication "
                    "models; remove 'fld yes' or write 'fld no'",
                )
            i += 2
        else:
            raise w.error(
                i,
                f"unknown face or keyword for wall/{style}: expected a face "
                f"({' '.join(FACES)}) or one of the keywords units, pbc, fld",
            )
    if not faces:
        entry = STYLES[style]
        head = " ".join(str(out[p.name]) for p in entry.wall_parameters)
        args = (" ".join(f.upper() for f in fields[1:]) if entry.per_face
                else f"{' '.join(['1.0'] * (len(fields) - 2))} 2.5")
        raise w.error(
            3,
            f"no walls defined: give at least one face, e.g. "
            f"'fix {w[1]} {group} wall/{style} {head + ' ' if head else ''}zlo EDGE {args}'",
        )
    out.update(faces)
    out.update(keywords)
    return out


def _parse_reflect(w: _Words, group: str) -> dict:
    stops = FACES + _REFLECT_KEYWORDS
    out: dict[str, Any] = {"style": "reflect", "group": group}
    faces: dict[str, Any] = {}
    keywords: dict[str, Any] = {}
    i = 4
    while i < len(w):
        word = w[i]
        if word in FACES:
            if word in faces:
                raise w.error(i, f"{word} wall defined twice: give each face once per fix")
            if _face_arguments(w, i, 1, stops) < 1:
                raise w.error(
                    i,
                    f"missing argument for the {word} wall: wall/reflect faces take one coord "
                    "(EDGE, a number or v_name)",
                )
            faces[word] = w.coord(i + 1, f"{word} coord")
            i += 2
        elif word == "units":
            keywords["units"] = _keyword_value(w, i, ("lattice", "box"))
            i += 2
        else:
            extra = ""
            if word in ("pbc", "fld"):
                extra = f" ({word} belongs to the force walls, not to wall/reflect)"
            raise w.error(
                i,
                f"unknown face or keyword for wall/reflect{extra}: expected a face "
                f"({' '.join(FACES)}) or the keyword units",
            )
    if not faces:
        raise w.error(
            3, f"no walls defined: give at least one face, e.g. 'fix {w[1]} {group} wall/reflect zlo EDGE'"
        )
    out.update(faces)
    out.update(keywords)
    return out


_FLOW_USAGE = "wall/flow AXIS VFLOW T SEED N w1 ... wN [units lattice|box]"


def _parse_flow(w: _Words, group: str) -> dict:
    if len(w) < 10:
        raise w.missing(f"missing arguments: write 'fix {w[1]} {group} {_FLOW_USAGE}' with N >= 1")
    axis = w[4]
    if axis not in ("x", "y", "z"):
        raise w.error(4, "the flow axis must be x, y or z")
    vflow = w.number(5, "vflow (the flow velocity)")
    temperature = w.number(6, "T (the temperature)")
    seed = w.integer(7, "SEED (the random seed)")
    count = w.integer(8, "N (the number of flow walls)")
    if count < 1:
        raise w.error(8, "N, the number of flow walls, must be a positive integer")
    rest = list(range(9, len(w)))  # indices of the words after N
    units: str | None = None
    if "units" in (w[j] for j in rest):
        k = next(j for j in rest if w[j] == "units")
        if k != len(w) - 2:
            if k == len(w) - 1:
                raise w.error(k, "missing value after units: write 'units box' or 'units lattice'")
            raise w.error(
                k,
                "units must be the last two words of a wall/flow line, after all N wall "
                "coordinates: write '... N w1 ... wN units box'",
            )
        units = _keyword_value(w, k, ("lattice", "box"))
        coord_idx = rest[:-2]
    else:
        coord_idx = rest
    if len(coord_idx) != count:
        if len(coord_idx) == count + 2 and units is None:
            k = coord_idx[count]
            raise w.error(
                k,
                f"after the {count} wall coordinates only 'units lattice' or 'units box' may follow",
            )
        raise w.error(
            8,
            f"wrong wall count: N = {count} but {len(coord_idx)} wall coordinates follow; "
            "give exactly N coordinates, then optionally 'units lattice|box'",
        )
    coords = [w.number(j, f"wall coordinate w{n + 1}") for n, j in enumerate(coord_idx)]
    out: dict[str, Any] = {
        "style": "flow",
        "group": group,
        "axis": axis,
        "vflow": vflow,
        "temperature": temperature,
        "seed": seed,
        "coords": coords,
    }
    if units is not None:
        out["units"] = units
    return out


def _region_params(w: _Words, start: int, fields: tuple[str, ...], usage: str) -> dict:
    got = len(w) - start
    if got < len(fields):
        raise w.missing(
            f"missing arguments: write '{usage}' ({len(fields)} numbers after "
            f"{w[start - 1]}, found {got})"
        )
    if got > len(fields):
        raise w.error(
            start + len(fields),
            f"too many arguments: write '{usage}'; region walls take no keywords "
            "(units come from the region)",
        )
    return {f: w.number(start + k, f) for k, f in enumerate(fields)}


def _parse_region(w: _Words, group: str) -> dict:
    if len(w) < 5:
        raise w.missing("missing region ID: write 'wall/region regionID STYLE eps sigma rc'")
    region = w.identifier(4, "the region ID")
    if len(w) < 6:
        raise w.missing(
            f"missing potential style after the region ID; supported: {', '.join(REGION_POTENTIALS)}"
        )
    potential = w[5]
    if potential not in REGION_POTENTIALS:
        extra = " (for ellipsoids use fix wall/region/ees)" if potential in STYLES and STYLES[potential].needs_shape \
            else ""
        raise w.error(
            5, f"unknown wall/region style{extra}; supported: {', '.join(REGION_POTENTIALS)}"
        )
    fields: tuple[str, ...] = STYLES[potential].params
    usage = f"wall/region regionID {potential} {' '.join(_short(f) for f in fields)}"
    out: dict[str, Any] = {"style": "region", "group": group, "region": region, "potential": potential}
    out.update(_region_params(w, 6, fields, usage))
    return out


def _parse_region_ees(w: _Words, group: str) -> dict:
    if len(w) < 5:
        raise w.missing("missing region ID: write 'wall/region/ees regionID eps sigma rc'")
    region = w.identifier(4, "the region ID")
    out: dict[str, Any] = {"style": "region/ees", "group": group, "region": region}
    out.update(
        _region_params(w, 5, ("epsilon", "sigma", "cutoff"), "wall/region/ees regionID eps sigma rc")
    )
    return out


# --------------------------------------------------------------------------------------------
# writing


def _fmt_number(value: Any, what: str) -> str:
    if isinstance(value, bool):
        raise ValueError(f"{what}: expected a number, got {value!r}")
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if not math.isfinite(value):
            raise ValueError(f"{what}: expected a finite number, got {value!r}")
        return repr(value)
    if isinstance(value, str) and _NUMBER_RE.match(value.strip()):
        return repr(float(value))
    raise ValueError(f"{what}: expected a number, got {value!r}")


def _fmt_value(value: Any, what: str, *, edge: bool, variable: bool) -> str:
    if isinstance(value, str):
        s = value.strip()
        if edge and s == "EDGE":
            return s
        if variable and _VARIABLE_RE.match(s):
            return s
    return _fmt_number(value, what)


def _fmt_int(value: Any, what: str) -> str:
    if isinstance(value, bool):
        raise ValueError(f"{what}: expected an integer, got {value!r}")
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float) and value.is_integer():
        return str(int(value))
    if isinstance(value, str) and _INT_RE.match(value.strip()):
        return str(int(value))
    raise ValueError(f"{what}: expected an integer, got {value!r}")


def _check_word(value: Any, what: str) -> str:
    if not isinstance(value, str) or not _ID_RE.match(value):
        raise ValueError(f"{what} must be letters, digits and underscores, got {value!r}")
    return value


def _as_mapping(wall: Any) -> dict:
    if hasattr(wall, "model_dump"):  # a Pydantic model
        wall = wall.model_dump(exclude_none=True)
    if not isinstance(wall, Mapping):
        raise ValueError(f"a wall must be a mapping, got {type(wall).__name__}")
    return {k: v for k, v in wall.items() if v is not None}


def _face_words(style: str, face: str, value: Any, where: str) -> list[str]:
    fields = face_fields(style)
    entry = STYLES[style]
    if isinstance(value, Mapping):
        unknown = set(value) - set(fields) - set(entry.face_keys)
        if unknown:
            raise ValueError(f"{where}.{face}: unknown field(s) {sorted(unknown)}; expected {list(fields)}")
        values = entry.fix_face({k: v for k, v in value.items() if v is not None})
    elif isinstance(value, Sequence) and not isinstance(value, str):
        items = list(value)
        optional = [k for k, f in enumerate(fields) if f != "coord" and not STYLES[style].param(f).required]
        if len(items) == len(fields) - len(optional):  # the optional fields left out (e.g. harmonic's sigma)
            for k in optional:
                items.insert(k, None)
        if len(items) != len(fields):
            raise ValueError(f"{where}.{face}: expected {len(fields)} values {list(fields)}, got {len(items)}")
        values = dict(zip(fields, items))
    else:
        raise ValueError(f"{where}.{face}: expected a mapping or a list, got {value!r}")
    for p in STYLES[style].parameters:
        if values.get(p.name) is None and p.placeholder is not None:
            values[p.name] = p.placeholder  # ignored by the style, but LAMMPS wants a word there
    words = [face]
    for field in fields:
        if values.get(field) is None:
            raise ValueError(f"{where}.{face}: missing {field}")
        if field != "coord" and not entry.param(field).numeric:
            words.append(_word(values[field], entry.param(field), f"{where}.{face}.{field}"))
            continue
        words.append(
            _fmt_value(
                values[field],
                f"{where}.{face}.{field}",
                edge=field == "coord",
                variable=field == "coord" or _variable_field(style, field),
            )
        )
    return words


def _word(value: Any, param: Any, what: str) -> str:
    """A face's word parameter as written in a fix line: an expression in double quotes, a file
    name or keyword as it is."""
    if param.quoted:
        text = str(value)
        if '"' in text:
            raise ValueError(f"{what}: a double quote cannot be written in a LAMMPS fix line")
        return f'"{text}"'
    return _check_path(value, what)


def _reject_unknown(wall: dict, allowed: set[str], where: str) -> None:
    unknown = set(wall) - allowed - _NON_LAMMPS_KEYS
    if unknown:
        raise ValueError(f"{where}: key(s) {sorted(unknown)} have no place in a {wall['style']} fix line")


def to_fix_line(fix_id: str, wall: Any) -> str:
    """Write a wall in mapping form as a LAMMPS ``fix`` line.

    The inverse of :func:`parse_fix_line`: ``parse_fix_line(to_fix_line(i, d), i) == d`` for
    every dict ``d`` that :func:`parse_fix_line` returns. Also accepts the other shapes of the
    mapping form (positional face lists, a reflect face as ``{coord: ...}``, a harmonic face
    without ``sigma``, which is written as 1.0 since LAMMPS ignores it). Keys with no LAMMPS
    word (``energy``, ``virial``: ``fix_modify`` settings; ``frame``, ``rule``: wallbatch
    options) are left out; the caller writes ``fix_modify`` lines itself. A ``{fix: "..."}``
    entry is re-parsed and re-written.
    """
    _check_word(fix_id, "the fix ID")
    wall = _as_mapping(wall)
    if "fix" in wall:
        return to_fix_line(fix_id, parse_fix_line(wall["fix"], fix_id))
    where = f"walls.{fix_id}"
    style = wall.get("style")
    if style is None:
        raise ValueError(f"{where}: missing style")
    group = _check_word(wall.get("group", "all"), f"{where}.group")
    words = ["fix", fix_id, group]

    if style in STYLES or style == "reflect":
        keywords = ("units", "pbc") if style != "reflect" else ("units",)
        head = STYLES[style].wall_parameters if style in STYLES else ()
        _reject_unknown(wall, {"style", "group", *FACES, *keywords, "fld", *(p.name for p in head)}, where)
        words.append(f"wall/{style}")
        for p in head:
            if p.name not in wall:
                raise ValueError(f"{where}: missing {p.name}")
            words.append(_fmt_int(wall[p.name], f"{where}.{p.name}") if p.kind == "integer" else
                         _choice(wall[p.name], p.choices, f"{where}.{p.name}") if p.kind == "choice" else
                         _check_path(wall[p.name], f"{where}.{p.name}"))
        faces = [k for k in wall if k in FACES]
        if not faces:
            raise ValueError(f"{where}: no faces ({' '.join(FACES)}) given")
        for face in faces:
            value = wall[face]
            if style == "reflect":
                if isinstance(value, Mapping):
                    if set(value) != {"coord"}:
                        raise ValueError(f"{where}.{face}: a reflect face takes only coord")
                    value = value["coord"]
                words += [face, _fmt_value(value, f"{where}.{face}", edge=True, variable=True)]
            else:
                words += _face_words(style, face, value, where)
        if "units" in wall:
            words += ["units", _choice(wall["units"], ("lattice", "box"), f"{where}.units")]
        if "pbc" in wall and style != "reflect":
            words += ["pbc", "yes" if _flag(wall["pbc"], f"{where}.pbc") else "no"]
        if "fld" in wall and _flag(wall["fld"], f"{where}.fld"):
            raise ValueError(f"{where}.fld: fld yes (lubrication) is not supported")
    elif style == "reflect/stochastic":
        words += _stochastic_words(wall, where)
    elif style == "flow":
        _reject_unknown(
            wall, {"style", "group", "axis", "vflow", "temperature", "seed", "coords", "units"}, where
        )
        for key in ("axis", "vflow", "temperature", "seed", "coords"):
            if key not in wall:
                raise ValueError(f"{where}: missing {key}")
        coords = wall["coords"]
        if isinstance(coords, str) or not isinstance(coords, Sequence) or len(coords) == 0:
            raise ValueError(f"{where}.coords: expected a non-empty list of numbers")
        words += [
            "wall/flow",
            _choice(wall["axis"], ("x", "y", "z"), f"{where}.axis"),
            _fmt_number(wall["vflow"], f"{where}.vflow"),
            _fmt_number(wall["temperature"], f"{where}.temperature"),
            _fmt_int(wall["seed"], f"{where}.seed"),
            str(len(coords)),
        ]
        words += [_fmt_number(c, f"{where}.coords.{n}") for n, c in enumerate(coords)]
        if "units" in wall:
            words += ["units", _choice(wall["units"], ("lattice", "box"), f"{where}.units")]
    elif style in ("region", "region/ees"):
        if style == "region":
            potential = _choice(wall.get("potential"), REGION_POTENTIALS, f"{where}.potential")
            params = STYLES[potential].parameters
            fields: tuple[str, ...] = STYLES[potential].params
        else:
            params = ()
            fields = ("epsilon", "sigma", "cutoff")
        _reject_unknown(wall, {"style", "group", "region", "potential", *fields}, where)
        values = dict(wall)
        for p in params:
            if p.name not in values and p.placeholder is not None:
                values[p.name] = p.placeholder  # ignored by the style; LAMMPS still reads a word
        words += [f"wall/{style}", _check_word(wall.get("region"), f"{where}.region")]
        if style == "region":
            words.append(potential)
        for field in fields:
            if field not in values:
                raise ValueError(f"{where}: missing {field}")
            words.append(_fmt_number(values[field], f"{where}.{field}"))
    else:
        raise ValueError(
            f"{where}.style: unknown style {style!r}; supported: "
            f"{', '.join(s[len('wall/'):] for s in SUPPORTED_STYLES)}"
        )
    return " ".join(words)


def _choice(value: Any, choices: tuple[str, ...], what: str) -> str:
    if value not in choices:
        raise ValueError(f"{what}: expected one of {', '.join(choices)}, got {value!r}")
    return value


def _flag(value: Any, what: str) -> bool:
    if isinstance(value, bool):
        return value
    if value in ("yes", "no"):
        return value == "yes"
    raise ValueError(f"{what}: expected true/false (or yes/no), got {value!r}")


# --------------------------------------------------------------------------------------------
# wall/reflect/stochastic

_RSTYLE_ACCOM = {"diffusive": 0, "maxwell": 1, "ccl": 3}
_STOCHASTIC_USAGE = "wall/reflect/stochastic diffusive|maxwell|ccl SEED face coord temp vx vy vz [accom ...] [units lattice|box]"


def rstyle_hint(rstyle: object) -> str:
    """The hint for a long name of the Cercignani-Lampis model (LAMMPS spells it ccl), else ''."""
    long = isinstance(rstyle, str) and rstyle.lower() in ("cercignanilampis", "cercignani-lampis", "cl")
    return " (LAMMPS spells the Cercignani-Lampis model ccl: it refuses the long name too)" if long else ""


def _parse_stochastic(w: _Words, group: str) -> dict:
    """``wall/reflect/stochastic rstyle seed face pos temp vx vy vz [a | ax ay az] ... [units]``
    -> ``{"style": "reflect/stochastic", "group", "rstyle", "seed", face: {coord, temp, vel,
    accom}, "units"}``."""
    if len(w) < 6:
        raise w.missing(f"missing arguments: write 'fix {w[1]} {group} {_STOCHASTIC_USAGE}'")
    rstyle = w[4]
    if rstyle not in _RSTYLE_ACCOM:
        raise w.error(4, f"the reflection style must be diffusive, maxwell or ccl{rstyle_hint(rstyle)}")
    seed = w.integer(5, "SEED (the random seed)")
    if seed <= 0:
        raise w.error(5, "the random seed must be a positive integer")
    nacc = _RSTYLE_ACCOM[rstyle]
    fields = ("coord", "temp", "vx", "vy", "vz") + ("a", "b", "c")[:nacc]
    out: dict[str, Any] = {"style": "reflect/stochastic", "group": group, "rstyle": rstyle, "seed": seed}
    faces: dict[str, dict] = {}
    i = 6
    while i < len(w):
        word = w[i]
        if word in FACES:
            if word in faces:
                raise w.error(i, f"{word} wall defined twice: give each face once per fix")
            got = _face_arguments(w, i, len(fields), FACES + ("units",))
            if got < len(fields):
                raise w.error(
                    i,
                    f"missing arguments for the {word} wall: rstyle {rstyle} faces take pos temp vx vy vz"
                    f"{' and ' + str(nacc) + ' accommodation coefficient(s)' if nacc else ''} "
                    f"({len(fields)} words), found {got}",
                )
            c = w[i + 1]
            if c == "EDGE":
                coord: Any = "EDGE"
            elif _NUMBER_RE.match(c):
                coord = float(c)
            else:
                raise w.error(i + 1, f"{word} pos must be EDGE or a number (no variables for this wall)"
                              f"{_hint(c) if not c.startswith('v_') else ''}")
            vals = [w.number(i + 1 + k, f"{word} {f}") for k, f in enumerate(fields) if k > 0]
            face: dict[str, Any] = {"coord": coord, "temp": vals[0], "vel": vals[1:4]}
            if nacc == 1:
                face["accom"] = vals[4]
            elif nacc == 3:
                face["accom"] = vals[4:7]
            faces[word] = face
            i += 1 + len(fields)
        elif word == "units":
            out["units"] = _keyword_value(w, i, ("lattice", "box"))
            i += 2
        else:
            raise w.error(
                i, f"unknown face or keyword for wall/reflect/stochastic: expected a face ({' '.join(FACES)}) "
                "or the keyword units",
            )
    if not faces:
        raise w.error(3, f"no walls defined: give at least one face, e.g. 'fix {w[1]} {group} "
                         f"wall/reflect/stochastic diffusive 1234 zlo EDGE 1.0 0.0 0.0 0.0'")
    for name, face in faces.items():
        out[name] = face
    return out


def _stochastic_words(wall: Mapping, where: str) -> list[str]:
    _reject_unknown(wall, {"style", "group", "rstyle", "seed", "units", *FACES}, where)
    rstyle = _choice(wall.get("rstyle"), tuple(_RSTYLE_ACCOM), f"{where}.rstyle")
    words = ["wall/reflect/stochastic", rstyle, _fmt_int(wall.get("seed"), f"{where}.seed")]
    faces = [k for k in wall if k in FACES]
    if not faces:
        raise ValueError(f"{where}: no faces ({' '.join(FACES)}) given")
    for face in faces:
        spec = _as_mapping(wall[face])
        at = f"{where}.{face}"
        words += [face, "EDGE" if spec.get("coord") == "EDGE" else _fmt_number(spec.get("coord"), f"{at}.coord"),
                  _fmt_number(spec.get("temp"), f"{at}.temp")]
        vel = spec.get("vel", (0.0, 0.0, 0.0))
        words += [_fmt_number(v, f"{at}.vel") for v in vel]
        accom = spec.get("accom")
        if accom is not None:
            accom = [accom] if not isinstance(accom, Sequence) else list(accom)
            words += [_fmt_number(a, f"{at}.accom") for a in accom]
    if "units" in wall:
        words += ["units", _choice(wall["units"], ("lattice", "box"), f"{where}.units")]
    return words


def _check_path(value: Any, what: str) -> str:
    """A table file path as one LAMMPS word: in double quotes when it has a blank, a quote, '#' or
    '$' (which LAMMPS reads literally between quotes); a path with a double quote or a line break
    cannot be written."""
    if not isinstance(value, str) or not value or '"' in value or "\n" in value or "\r" in value:
        raise ValueError(f"{what}: a table file path without double quotes or line breaks, got {value!r}")
    return f'"{value}"' if any(c.isspace() or c in "'#$" for c in value) else value
