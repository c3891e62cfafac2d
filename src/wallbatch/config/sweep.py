"""Sweeps (docs/reference/config.md "Sweeps"): expand one scene into a labelled grid of cases.

`product` entries are full-grid dimensions, a `zip` moves several parameters together on one
dimension, `replicas` adds independent random streams. Paths address the validated model, so a
wall written as a LAMMPS fix line is swept like any other. Every expanded case is validated before
any case runs.
"""

from __future__ import annotations

import copy
import hashlib
import itertools
import json
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Annotated, Any, Union

import numpy as np
import yaml
from pydantic import ConfigDict, Discriminator, Field, PositiveInt, Tag, ValidationError, field_validator

from wallbatch.config.models import Config, Model, validate_data
from wallbatch.config.source import (FACES, ConfigError, SourceMap, _Loader, load_yaml, read_config_text,
                                     model_type_errors, tuple_length_errors)

# ----------------------------------------------------------------------------- the sweep models


class _SweepModel(Model):
    # built when a sweep is first validated: a config without one never pays for them
    model_config = ConfigDict(defer_build=True)


class Linspace(_SweepModel):
    linspace: tuple[float, float, PositiveInt]


class Logspace(_SweepModel):
    logspace: tuple[float, float, PositiveInt]

    @field_validator("logspace")
    @classmethod
    def _exponents(cls, v: tuple[float, float, int]) -> tuple[float, float, int]:
        if max(abs(v[0]), abs(v[1])) > 307:  # 10**308 overflows (numpy warned), 10**-324 is 0
            raise ValueError(f"logspace [a, b, n] takes base-10 exponents: 10^{v[0] if abs(v[0]) > 307 else v[1]:g} "
                             f"is not a usable number; give exponents between -307 and 307")
        return v


class Range(_SweepModel):
    range: tuple[float, float, float]

    @field_validator("range")
    @classmethod
    def _step(cls, v: tuple[float, float, float]) -> tuple[float, float, float]:
        if v[2] == 0 or (v[1] - v[0]) / v[2] < 0:
            raise ValueError("range [a, b, step] needs a step that goes from a toward b")
        return v


def _values_kind(v: Any) -> str | None:
    """Which form of `values` v is written in (a list, or a mapping keyed linspace, logspace or
    range), so that a mistake in one form is reported alone, not with every other form's errors."""
    if isinstance(v, (list, tuple)):
        return "list"
    if isinstance(v, dict):
        return next((k for k in ("linspace", "logspace", "range") if k in v), None)
    return None


VALUES_FORMS = "a list, {linspace: [a, b, n]}, {logspace: [a, b, n]} or {range: [a, b, step]}"
Values = Annotated[Union[Annotated[Annotated[list[Any], Field(min_length=1)], Tag("list")],
                         Annotated[Linspace, Tag("linspace")], Annotated[Logspace, Tag("logspace")],
                         Annotated[Range, Tag("range")]],
                   Discriminator(_values_kind, custom_error_type="values",
                                 custom_error_message=f"values: give {VALUES_FORMS}")]


class Param(_SweepModel):
    path: Union[str, Annotated[list[str], Field(min_length=1)]]
    values: Values


def _untagged(loc: tuple) -> tuple:
    """A sweep validation error's location without the tags the discriminators add (`_entry_kind`
    after a product entry's name, `_values_kind` after `values`), so it names keys of the file."""
    out: list = []
    for i, key in enumerate(loc):
        after_entry = i >= 2 and loc[i - 2] == "product" and key in ("param", "values")
        after_values = i >= 1 and loc[i - 1] == "values" and key in ("list", "linspace", "logspace", "range")
        if not (after_entry or after_values):
            out.append(key)
    return tuple(out)


def _sweep_message(error: dict) -> str:
    """A sweep validation error's text: a linspace, logspace or range written with fewer than its
    three numbers says which three (pydantic: "Field required")."""
    form = next((k for k in ("linspace", "logspace", "range") if k in error["loc"]), None)
    if form is not None and error["type"] == "missing" and isinstance(error.get("input"), (list, tuple)):
        return f"{form} expects 3 values [a, b, {'step' if form == 'range' else 'n'}], got {len(error['input'])}"
    if error["type"] == "string_pattern_mismatch":  # a zip's dim: a name in the results file
        return (f"{error['input']!r}: a dimension name is letters, digits and underscores, not starting with a "
                f"digit (it names a dimension of the results file)")
    return error["msg"].removeprefix("Value error, ")


def _entry_kind(v: Any) -> str:
    """A product entry: {path: ..., values: ...} (a mapping with either key: the other is then
    reported missing), or the shorthand whose key is the path."""
    return "param" if isinstance(v, dict) and ("path" in v or "values" in v) else "values"


class Zip(_SweepModel):
    dim: Annotated[str, Field(pattern=r"^[A-Za-z_][A-Za-z0-9_]*$")]
    params: Annotated[dict[str, Param], Field(min_length=1)]


class Sweep(_SweepModel):
    product: dict[str, Annotated[Union[Annotated[Param, Tag("param")], Annotated[Values, Tag("values")]],
                                 Discriminator(_entry_kind)]] = {}
    zip: Zip | None = None
    replicas: PositiveInt | None = None


MAX_VALUES = 100_000  # values of one sweep dimension
MAX_CASES = 100_000  # cases of one sweep (each is validated before anything runs)


def count_values(values: Any) -> int:
    """How many values a sweep entry makes, without making them."""
    if isinstance(values, (Linspace, Logspace)):
        return int((values.linspace if isinstance(values, Linspace) else values.logspace)[2])
    if isinstance(values, Range):
        a, b, step = values.range
        n = (b - a) / step - 1e-9
        return int(np.ceil(n)) if np.isfinite(n) and n < 1e18 else 10**18
    return len(values)


def expand_values(values: Any) -> list:
    """A value list from a list, linspace, logspace (base-10 exponents) or range [a, b, step)."""
    n = count_values(values)
    if n > MAX_VALUES:
        raise ValueError(f"{n:,} values: more than the limit of {MAX_VALUES:,} per dimension")
    if isinstance(values, Linspace):
        a, b, n = values.linspace
        return np.linspace(a, b, n).tolist()
    if isinstance(values, Logspace):
        a, b, n = values.logspace
        return np.logspace(a, b, n).tolist()
    if isinstance(values, Range):  # a, a + step, ... up to but excluding b (as numpy.arange)
        a, b, step = values.range
        n = int(np.ceil((b - a) / step - 1e-9))
        whole = all(float(x).is_integer() for x in values.range)
        return [int(a + k * step) if whole else a + k * step for k in range(n)]
    return list(values)


# ----------------------------------------------------------------------------- the grid

# names of the results file that a sweep dimension or zip parameter may not take
RESERVED = frozenset({
    "time", "dt", "temp", "ke", "pe", "etot", "press", "atoms", "erot", "step", "sample", "fix", "face",
    "face_fix", "face_name", "wall_energy", "wall_force", "reflect_count", "reflect_impulse", "flow_crossings",
    "region_force", "rfix", "spatial", "ecouple", "econserve", "status", "error", "seconds", "dump_path",
})


@dataclass(frozen=True)
class SweepDim:
    """One output dimension: name, coordinate values, the dotted path(s) it sets, and for a zip
    the values of each parameter along it (extra coordinates)."""

    name: str
    values: list
    paths: tuple[str, ...]
    extra: dict[str, tuple[list, tuple[str, ...]]] = field(default_factory=dict)

    @property
    def path(self) -> str:
        return ", ".join(self.paths)


@dataclass(frozen=True)
class SweepCase:
    index: tuple[int, ...]  # place in the grid
    coords: dict[str, Any]  # dim name -> value
    config: Config
    seed_key: tuple[int, ...]

    @property
    def label(self) -> str:
        return ", ".join(f"{k}={v}" for k, v in self.coords.items()) or "(single case)"


@dataclass(frozen=True)
class SweepPlan:
    dims: list[SweepDim]
    cases: list[SweepCase]  # in C order over dims
    base_text: str
    sweep_text: str
    inputs: tuple[str, ...] = ()  # resolved paths of the files the plan was read from
    where: SourceMap | None = field(default=None, compare=False, repr=False)  # where each value was written

    @property
    def shape(self) -> tuple[int, ...]:
        return tuple(len(d.values) for d in self.dims)

    def placed(self, message: str, key: str | None = None) -> str:
        """A case's build error `KEY: why` led by the place KEY was written: file:line:col in the
        config, the sweep entry of a swept value, or the `--set` argument. `key` is the KEY the
        error was raised with (`CaseError.key`); without one, a KEY leading the message is used.
        Unchanged when there is no key or the plan knows no place for it."""
        if key is None:
            m = _KEY_FIRST.match(message)
            key = m.group(1) if m is not None else None
        if self.where is None or key is None:
            return message
        loc = tuple(int(p) if p.isdigit() else p for p in key.split("."))
        where = _where_text(self.where, loc)
        return message if where == self.where.filename else f"{where}: {message}"


def config_to_dict(cfg: Config) -> dict:
    """The validated model as plain data, faces in their written order: the document that sweep
    paths address and that validates back to the same model."""
    data = cfg.model_dump(mode="json", exclude_none=True)
    for fid, wall in cfg.walls.items():
        order = getattr(wall, "_order", None)
        if order:
            w = data["walls"][fid]
            faces = {f: w.pop(f) for f in order if f in w}
            w.update(faces)
    return data


def set_path(data: dict, path: str, value: Any) -> None:
    """Set a dotted path (integers index lists) in plain config data."""
    parts = path.split(".")
    node: Any = data
    for i, part in enumerate(parts[:-1]):
        key: Any = int(part) if isinstance(node, list) and part.lstrip("-").isdigit() else part
        try:
            node = node[key]
        except (KeyError, IndexError, TypeError):
            where = ".".join(parts[: i + 1])
            raise ConfigError([f"sweep path {path}: {where} does not exist in the config"]) from None
    last = parts[-1]
    if isinstance(node, list):
        if not last.lstrip("-").isdigit() or not -len(node) <= int(last) < len(node):
            raise ConfigError([f"sweep path {path}: {last} is not an index of a list of {len(node)}"])
        node[int(last)] = value
    elif isinstance(node, dict):
        if last.isdigit() and last not in node and len(parts) > 1 and parts[-2] in FACES:
            raise ConfigError([f"sweep path {path}: a face's values are named, also where the file writes them "
                               f"as a list: {'.'.join(parts[:-1])}.{{{', '.join(node)}}}"])
        node[last] = value
    else:
        raise ConfigError([f"sweep path {path}: {'.'.join(parts[:-1])} is a value, not a mapping or list"])


_FIX_LINE_PATH = re.compile(r"walls\.([^.]+)\.fix")
_KEY_FIRST = re.compile(r"([A-Za-z_][\w-]*(?:\.[\w/-]+)*): ")  # a message led by a config key: `atoms.0.create: ...`


def set_value(data: dict, path: str, value: Any, raw: Any) -> None:
    """`set_path` on a case's validated data, but a wall's fix line (`walls.ID.fix`) replaces the
    wall: the keys the file (`raw`, as read) wrote beside the old line stay (`energy: true`),
    every key the old line set goes (else the new line's style, faces and keywords would merge
    with the old line's: a new face beside the old ones, the old style kept)."""
    m = _FIX_LINE_PATH.fullmatch(path)
    walls = data.get("walls") if isinstance(data, dict) else None
    if m and isinstance(walls, dict) and m.group(1) in walls:
        old = raw.get("walls", {}).get(m.group(1)) if isinstance(raw, dict) and isinstance(raw.get("walls"), dict) \
            else None
        beside = {k: v for k, v in old.items() if k != "fix"} if isinstance(old, dict) and "fix" in old else {}
        walls[m.group(1)] = {**copy.deepcopy(beside), "fix": value}
        return
    set_path(data, path, value)


def _seed_key(coords: dict[str, Any]) -> tuple[int, ...]:
    """Random streams per case from its coordinates (never its place in a batch)."""
    digest = hashlib.sha256(json.dumps(coords, sort_keys=True, default=str).encode()).digest()
    return tuple(int.from_bytes(digest[i:i + 4], "little") for i in range(0, 16, 4))


def _same(value: Any) -> Any:
    """A hashable form of a sweep value that is equal for equal values (1 and 1.0 too, as the
    results coordinate holds them)."""
    if isinstance(value, (list, tuple)):
        return tuple(_same(v) for v in value)
    if isinstance(value, dict):
        return tuple(sorted((str(k), _same(v)) for k, v in value.items()))
    return value


def _dim_where(smap: SourceMap, name: str, zip_param: str | None = None) -> tuple:
    """The sweep-file location of a dimension (or zip parameter) entry, as a SourceMap loc."""
    if zip_param is not None:
        return ("sweep", "zip", "params", zip_param)
    if name == "replica":
        return ("sweep", "replicas")
    return ("sweep", "product", name)


def _dims(sweep: Sweep, order: list[str], smap: SourceMap) -> list[SweepDim]:
    sizes = [count_values(e.values if isinstance(e, Param) else e) for e in sweep.product.values()] if \
        "product" in order else []
    if sweep.zip is not None and "zip" in order:
        sizes.append(max(count_values(p.values) for p in sweep.zip.params.values()))
    sizes.append(sweep.replicas or 1)
    for name, entry in sweep.product.items():
        n = count_values(entry.values if isinstance(entry, Param) else entry)
        if n > MAX_VALUES:
            raise ConfigError([smap.format(("sweep", "product", name), f"{n:,} values: more than the limit of "
                                                                       f"{MAX_VALUES:,} per dimension")])
    for name, p in (sweep.zip.params.items() if sweep.zip is not None else []):
        if count_values(p.values) > MAX_VALUES:
            raise ConfigError([smap.format(("sweep", "zip", "params", name),
                                           f"{count_values(p.values):,} values: more than the limit of "
                                           f"{MAX_VALUES:,} per dimension")])
    total = 1
    for n in sizes:
        total *= max(n, 1)
    if total > MAX_CASES:
        raise ConfigError([smap.format(("sweep",), f"{total:,} cases: more than the limit of {MAX_CASES:,} "
                                                   f"cases in one run; split the sweep")])
    dims: list[SweepDim] = []
    for key in order:
        if key == "product":
            short: dict[str, str] = {}
            for name, entry in sweep.product.items():
                if isinstance(entry, Param):
                    paths = (entry.path,) if isinstance(entry.path, str) else tuple(entry.path)
                    dims.append(SweepDim(name, expand_values(entry.values), paths))
                else:
                    dim = name.split(".")[-1]
                    if dim in short:
                        raise ConfigError([smap.format(
                            ("sweep", "product", name), f"shorthand paths {short[dim]} and {name} both make a "
                            f"dimension '{dim}': write {{path: ..., values: ...}} with distinct names")])
                    short[dim] = name
                    dims.append(SweepDim(dim, expand_values(entry), (name,)))
        elif key == "zip" and sweep.zip is not None:
            lens = {k: len(expand_values(p.values)) for k, p in sweep.zip.params.items()}
            if len(set(lens.values())) > 1:
                raise ConfigError([smap.format(("sweep", "zip", "params"), "parameters must have equal lengths, "
                                               f"got {', '.join(f'{k}: {n}' for k, n in lens.items())}")])
            extra = {k: (expand_values(p.values), (p.path,) if isinstance(p.path, str) else tuple(p.path))
                     for k, p in sweep.zip.params.items()}
            n = next(iter(lens.values()))
            paths = tuple(p for _, ps in extra.values() for p in ps)
            dims.append(SweepDim(sweep.zip.dim, list(range(n)), paths, extra))
    for d in dims:  # a value twice on a product dimension: two cases with one coordinate and one random stream
        if d.extra:
            continue  # (a zip's coordinate is the position along it: repeated parameters are distinct cases)
        seen: dict[Any, int] = {}
        for i, v in enumerate(d.values):
            same = _same(v)
            if same in seen:
                key = next((k for k, e in sweep.product.items() if (k if isinstance(e, Param) else k.split(".")[-1])
                            == d.name), d.name)
                at = ("sweep", "product", key) + (("values",) if isinstance(sweep.product.get(key), Param) else ())
                raise ConfigError([smap.format(at, f"dimension {d.name}: values {seen[same] + 1} and {i + 1} are "
                                                   f"the same ({v}): the two cases would be one case (one coordinate, "
                                                   f"one random stream); remove one, or use sweep.replicas for "
                                                   f"independent repeats")])
            seen[same] = i
    if sweep.replicas:
        dims.append(SweepDim("replica", list(range(sweep.replicas)), ("seed",)))
    names = [d.name for d in dims] + [k for d in dims for k in d.extra]
    dup = {n for n in names if names.count(n) > 1}
    if dup:
        raise ConfigError([smap.format(("sweep",), f"name(s) {', '.join(sorted(dup))} used twice (dimensions and "
                                                   f"zip parameters share one namespace): rename")])
    clash = sorted(set(names) & RESERVED)
    if clash:
        where = next(_dim_where(smap, d.name) for d in dims if d.name in clash) if any(
            d.name in clash for d in dims) else ("sweep", "zip")
        raise ConfigError([smap.format(where, f"{', '.join(clash)} would clash with names of the results file "
                                              f"({', '.join(sorted(RESERVED))}): choose another name")])
    for d in dims:  # names the file derives from the outputs, and names NetCDF cannot store
        for name, loc in [(d.name, ("sweep", "zip", "dim") if d.extra else _dim_where(smap, d.name))] + \
                [(k, ("sweep", "zip", "params", k)) for k in d.extra]:
            why = _name_problem(name)
            if why:
                raise ConfigError([smap.format(loc, f"{name!r} {why}: choose another name")])
    return dims


DERIVED_SUFFIXES = ("_mean", "_sem", "_sem_converged")  # time means of the outputs (io/averages.py)
DERIVED = frozenset({"window", "window_step", "wall_pressure", "min_iterations", "min_evaluations",
                     "min_stop_reason", "min_energy_before", "min_energy", "min_fnorm"})


def _name_problem(name: str) -> str | None:
    """Why a sweep dimension or zip parameter cannot have this name in the results file (None: it can)."""
    if not name or not name.strip():
        return "is empty"
    if "/" in name or any(ord(ch) < 32 or ord(ch) == 127 for ch in name) or name != name.rstrip() or \
            not (name[0].isalnum() or name[0] == "_" or ord(name[0]) > 127):
        return ("is not a NetCDF name (no '/', no control characters, no trailing blank, "
                "starting with a letter, a digit or '_')")
    base = next((name[:-len(s)] for s in DERIVED_SUFFIXES if name.endswith(s)), None)
    if name in DERIVED or name.startswith("profile_") or name.endswith("_bin") or \
            (base is not None and (base in RESERVED or base in DERIVED)):
        return ("would clash with a variable the results file derives from its outputs (time means "
                "NAME_mean, NAME_sem, NAME_sem_converged, wall_pressure_*, profile_*, window, window_step, "
                "*_bin, min_*)")
    return None


class OverlayMap(SourceMap):
    """A SourceMap whose errors under some dotted paths point at another place: the sweep file's
    line of a swept value or a `set:` entry, or the `--set` command-line argument."""

    def __init__(self, base: SourceMap, where: dict[str, str], data: Any = None):
        super().__init__(base.filename, base.marks, base.data)
        self.where = where  # dotted path -> location text ("file:line:col" or "--set a.b=1")
        # the data with the values written elsewhere (validated form): what a location inside one
        # of them walks, where the file's data has no such keys (`--set output.profiles={...}`)
        self._written = None if data is None else SourceMap(base.filename, {}, data)

    def origin(self, dotted: str) -> str | None:
        for path, where in self.where.items():
            if dotted == path or dotted.startswith(path + "."):
                return where
        return None

    def format(self, loc: tuple, message: str) -> str:
        path, _, missing = self.walk(loc)
        if missing and self._written is not None:  # a key the file does not have, inside a value
            full = self._written.walk(loc)[0]  # written elsewhere: walk that value
            if self.origin(".".join(str(p) for p in full)) is not None:
                path = full
        dotted = ".".join(str(p) for p in path) or "(top level)"
        where = self.origin(dotted)
        if where is not None:
            return f"{where}: {dotted}: {message}"
        inside = [p for p in self.where if path and p.startswith(dotted + ".")]
        if inside:  # a check of a section that holds a value written elsewhere (`--set run.steps=`)
            return f"{super().format(loc, message)} (with {inside[0]} from {self.where[inside[0]]})"
        return super().format(loc, message)


def _where_text(smap: SourceMap, loc: tuple) -> str:
    """`file:line:col` of a loc in a SourceMap (the nearest known mark)."""
    return smap.format(loc, "").rsplit(": ", 2)[0]


def _overlaps(a: str, b: str) -> bool:
    return a == b or a.startswith(b + ".") or b.startswith(a + ".")


def _group(problems: list[tuple[str, str]], total: int) -> list[str]:
    """Identical problems of several cases once, with the list of cases."""
    by_msg: dict[str, list[str]] = {}
    for label, msg in problems:
        by_msg.setdefault(msg, []).append(label)
    out = []
    for msg, labels in by_msg.items():
        if len(labels) == total and total > 1:
            out.append(f"{msg} (every case)")
        else:
            shown = "; ".join(labels[:4]) + (f"; and {len(labels) - 4} more" if len(labels) > 4 else "")
            out.append(f"{msg} (case{'s' if len(labels) > 1 else ''} {shown})")
    return out


def expand(data: dict, srcmap: SourceMap, base_text: str = "", base_dir: Path = Path("."),
           overrides: dict[str, Any] | None = None, *, sweep_map: SourceMap | None = None,
           origins: dict[str, str] | None = None, inputs: tuple[str, ...] = ()) -> SweepPlan:
    """Validate the scene, apply `overrides` (path -> value, on the validated form), expand its
    `sweep:` (if any) and validate every case.

    `sweep_map` locates the `sweep:` entries (a sweep file's map; default `srcmap`); `origins`
    names where each override was written (a sweep file's `set:` line or a `--set` argument), so
    that an error in an overridden or swept value points there."""
    if not isinstance(data, dict):
        raise ConfigError([srcmap.format((), f"the config must be a mapping of keys, not a {type(data).__name__}")])
    data = copy.deepcopy(data)
    smap = sweep_map or srcmap
    origins = dict(origins or {})
    raw_sweep = data.pop("sweep", None)
    # the cross-field checks run on what runs: the base with its overrides, or each case (a value
    # that `set:` or the sweep replaces is no problem of the sweep)
    base = validate_data(data, srcmap, base_dir, cross=not overrides and raw_sweep is None)
    if overrides:
        for key in overrides:
            origins.setdefault(key, f"--set {key}")
        base_data = config_to_dict(base)
        for key, value in overrides.items():
            try:
                set_value(base_data, key, value, data)
            except ConfigError as exc:
                raise ConfigError([f"{origins[key]}: {p.removeprefix(f'sweep path {key}: ')}"
                                   for p in exc.problems]) from None
        base = validate_data(base_data, OverlayMap(srcmap, origins, base_data), base_dir, cross=raw_sweep is None)
        base_text = (f"# {srcmap.filename} with {', '.join(f'{k}={v}' for k, v in overrides.items())}\n"
                     + yaml.safe_dump(config_to_dict(base), sort_keys=False))
    base._base_dir = base_dir
    if raw_sweep is None:
        return SweepPlan([], [SweepCase((), {}, base, ())], base_text, "", inputs,
                         OverlayMap(srcmap, origins, config_to_dict(base)) if origins else srcmap)
    try:
        sweep = Sweep.model_validate(raw_sweep)
    except ValidationError as exc:
        errors = model_type_errors(tuple_length_errors(exc.errors(include_url=False)))
        raise ConfigError(list(dict.fromkeys(smap.format(("sweep",) + _untagged(e["loc"]), _sweep_message(e))
                                             for e in errors))) from None
    order = [k for k in raw_sweep if k in ("product", "zip")]
    dims = _dims(sweep, order, smap)
    base_data = config_to_dict(base)
    # where each swept path was written, and paths checked once (not once per case)
    swept: dict[str, str] = {}
    setters: dict[str, tuple[tuple, str]] = {}  # each swept path: the entry that sets it, and where it is
    for d in dims:
        if d.name == "replica" and d.paths == ("seed",):
            continue
        for param, (vals, paths) in _entries(d):
            loc = _dim_where(smap, d.name, param)
            where = _where_text(smap, loc + ("values",)) if smap.marks.get(loc + ("values",)) else \
                _where_text(smap, loc)
            path_where = _where_text(smap, loc + ("path",)) if smap.marks.get(loc + ("path",)) else where
            for p in paths:
                for q, (other, other_where) in setters.items():  # two entries writing one value
                    if other != loc and _overlaps(p, q):
                        inside = "is also swept by" if p == q else (
                            f"lies inside {q}, which is swept by" if p.startswith(q + ".") else
                            f"contains {q}, which is swept by")
                        raise ConfigError([f"{path_where}: {'.'.join(map(str, loc))}: {p} {inside} "
                                           f"{'.'.join(map(str, other))} ({other_where}): sweep one or the other"])
                setters.setdefault(p, (loc, path_where))
                for key in overrides or {}:  # a --set the sweep would silently override
                    if _overlaps(key, p) and origins[key].startswith("--set"):
                        raise ConfigError([f"{origins[key]}: {key} is also swept by {'.'.join(map(str, loc))} "
                                           f"({where}): drop one of the two"])
                try:
                    set_value(copy.deepcopy(base_data), p, vals[0], data)
                except ConfigError as exc:
                    raise ConfigError([f"{path_where}: {'.'.join(map(str, loc))}: {q}" for q in exc.problems]) \
                        from None
                swept[p] = where
    case_map = OverlayMap(srcmap, {**origins, **swept}, base_data)
    # the top-level sections a swept path writes into are copied per case; the others are shared
    # (validation does not change its input), and so are their validated models when equal to the
    # base's: a 10,000-case sweep holds one copy of what its cases have in common
    touched = {p.split(".")[0] for p in swept}
    shared = [name for name in type(base).model_fields if name not in touched]
    cases, problems = [], []
    for index in itertools.product(*(range(len(d.values)) for d in dims)):
        case_data = {k: copy.deepcopy(v) if k in touched else v for k, v in base_data.items()}
        coords: dict[str, Any] = {}
        for d, i in zip(dims, index):
            coords[d.name] = d.values[i]
            if d.name == "replica" and d.paths == ("seed",):
                continue
            # (each path was set above on the base; swept paths are disjoint, so none fails here)
            for _, (vals, paths) in _entries(d):
                for p in paths:
                    set_value(case_data, p, vals[i], data)
        label = ", ".join(f"{k}={v}" for k, v in coords.items())
        try:
            cfg = validate_data(case_data, case_map, base_dir)
        except ConfigError as exc:
            problems.extend((label, p) for p in exc.problems)
            continue
        cfg._base_dir = base_dir
        for name in shared:
            if cfg.__dict__[name] == base.__dict__[name]:
                cfg.__dict__[name] = base.__dict__[name]
        cases.append(SweepCase(index, coords, cfg, _seed_key(coords)))
    if problems:
        grouped = _group(problems, int(np.prod([len(d.values) for d in dims], dtype=int)))
        raise ConfigError(grouped[:20] + ([f"... and {len(grouped) - 20} more"] if len(grouped) > 20 else []))
    return SweepPlan(dims, cases, base_text, yaml.safe_dump(raw_sweep, sort_keys=False), inputs, case_map)


def _entries(d: Any) -> list[tuple[str | None, tuple[list, tuple[str, ...]]]]:
    """A dimension's entries: (param, (values, paths)) of each zip parameter, or (None, its own)."""
    return list(d.extra.items()) if d.extra else [(None, (d.values, d.paths))]


def parse_set(item: str) -> tuple[str, Any]:
    """One `--set path=value` argument: the path and the value read as YAML."""
    key, sep, value = item.partition("=")
    shown = item if len(item) <= 200 else item[:197] + "..."
    if not sep or not key.strip():
        raise ConfigError([f"--set {shown}: write path=value"])
    try:
        return key.strip(), yaml.load(value, Loader=_Loader)
    except yaml.YAMLError as exc:
        raise ConfigError([f"--set {shown}: the value is not valid YAML ({getattr(exc, 'problem', None) or exc})"]) \
            from None
    except RecursionError:
        raise ConfigError([f"--set {shown}: the value is nested too deeply"]) from None


def load_plan(path: str | Path, overrides: list[str] = ()) -> SweepPlan:
    """Read a config (optionally with `sweep:`) or a sweep file (`base:`, `set:`, `sweep:`),
    apply `--set path=value` overrides, expand and validate every case."""
    path = Path(path)
    text = read_config_text(path)
    data, srcmap = load_yaml(text, str(path))
    base_dir = path.parent
    base_text = text
    inputs = [str(path.resolve())]
    origins: dict[str, str] = {}
    sweep_map = None
    if isinstance(data, dict) and "base" in data:
        extra = set(map(str, data)) - {"base", "set", "sweep"}
        if extra:
            raise ConfigError([srcmap.format((sorted(extra)[0],), "a sweep file takes only base, set and sweep")])
        if not isinstance(data["base"], str):
            raise ConfigError([srcmap.format(("base",), "base: give the path of the scene file (text)")])
        if not isinstance(data.get("set") or {}, dict):
            raise ConfigError([srcmap.format(("set",), "set: give a mapping of path: value")])
        base_path = (path.parent / data["base"]).resolve()
        try:
            base_text = read_config_text(base_path)
        except ConfigError as exc:
            raise ConfigError([srcmap.format(("base",), p.split(": ", 1)[-1]) for p in exc.problems]) from None
        inputs.append(str(base_path))
        sets = {str(k): v for k, v in (data.get("set") or {}).items()}
        origins = {str(k): _where_text(srcmap, ("set", k)) for k in (data.get("set") or {})}
        sweep_map = srcmap if "sweep" in data else None
        base_where = _where_text(srcmap, ("base",))
        scene, srcmap = load_yaml(base_text, str(base_path))
        if not isinstance(scene, dict):
            raise ConfigError([srcmap.format((), f"the base scene must be a mapping of keys, "
                                                 f"not a {type(scene).__name__}")])
        if "base" in scene:  # a sweep file (or this one) as the base: one level only
            what = "this sweep file itself" if base_path == path.resolve() else "a sweep file"
            raise ConfigError([f"{base_where}: base: {data['base']} is {what}, not a scene: give the scene config "
                               f"that the sweep varies (a sweep file's base is one scene file)"])
        base_dir = base_path.parent
        if "sweep" in data:  # the sweep file's sweep replaces one of the scene
            scene["sweep"] = data["sweep"]
        data = scene
    else:
        sets = {}
    given: dict[str, str] = {}  # path -> its --set argument, as typed
    for item in overrides:
        key, value = parse_set(item)
        shown = f"--set {item if len(item) <= 200 else item[:197] + '...'}"
        for other, other_shown in given.items():  # two --set on one value: which one wins is no guess to make
            if _overlaps(key, other):
                what = "is also set by" if key == other else \
                    ("lies inside " if key.startswith(other + ".") else "contains ") + f"{other}, set by"
                raise ConfigError([f"{shown}: {key} {what} {other_shown}: give each value once"])
        given[key] = shown
        sets[key] = value
        origins[key] = shown
    return expand(data, srcmap, base_text, base_dir, sets, sweep_map=sweep_map, origins=origins,
                  inputs=tuple(inputs))
