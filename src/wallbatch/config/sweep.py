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
from dataclasses import dataclass, field
from pathlib import Path
from typing import Annotated, Any, Union

import numpy as np
import yaml
from pydantic import Field, PositiveInt, ValidationError, field_validator

from wallbatch.config.models import Config, Model, validate_data
from wallbatch.config.source import ConfigError, SourceMap, _Loader, load_yaml

# ----------------------------------------------------------------------------- the sweep models


class Linspace(Model):
    linspace: tuple[float, float, PositiveInt]


class Logspace(Model):
    logspace: tuple[float, float, PositiveInt]


class Range(Model):
    range: tuple[float, float, float]

    @field_validator("range")
    @classmethod
    def _step(cls, v: tuple[float, float, float]) -> tuple[float, float, float]:
        if v[2] == 0 or (v[1] - v[0]) / v[2] < 0:
            raise ValueError("range [a, b, step] needs a step that goes from a toward b")
        return v


Values = Union[Annotated[list[Any], Field(min_length=1)], Linspace, Logspace, Range]


class Param(Model):
    path: Union[str, Annotated[list[str], Field(min_length=1)]]
    values: Values


class Zip(Model):
    dim: Annotated[str, Field(pattern=r"^[A-Za-z_][A-Za-z0-9_]*$")]
    params: Annotated[dict[str, Param], Field(min_length=1)]


class Sweep(Model):
    product: dict[str, Union[Param, Values]] = {}
    zip: Zip | None = None
    replicas: PositiveInt | None = None


def expand_values(values: Any) -> list:
    """A value list from a list, linspace, logspace (base-10 exponents) or range [a, b, step)."""
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

    @property
    def shape(self) -> tuple[int, ...]:
        return tuple(len(d.values) for d in self.dims)


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
        node[last] = value
    else:
        raise ConfigError([f"sweep path {path}: {'.'.join(parts[:-1])} is a value, not a mapping or list"])


def _seed_key(coords: dict[str, Any]) -> tuple[int, ...]:
    """Random streams per case from its coordinates (never its place in a batch)."""
    digest = hashlib.sha256(json.dumps(coords, sort_keys=True, default=str).encode()).digest()
    return tuple(int.from_bytes(digest[i:i + 4], "little") for i in range(0, 16, 4))


def _dims(sweep: Sweep, order: list[str]) -> list[SweepDim]:
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
                        raise ConfigError([f"sweep.product: shorthand paths {short[dim]} and {name} both make a "
                                           f"dimension '{dim}': write {{path: ..., values: ...}} with distinct names"])
                    short[dim] = name
                    dims.append(SweepDim(dim, expand_values(entry), (name,)))
        elif key == "zip" and sweep.zip is not None:
            lens = {k: len(expand_values(p.values)) for k, p in sweep.zip.params.items()}
            if len(set(lens.values())) > 1:
                raise ConfigError([f"sweep.zip: parameters must have equal lengths, got "
                                   f"{', '.join(f'{k}: {n}' for k, n in lens.items())}"])
            extra = {k: (expand_values(p.values), (p.path,) if isinstance(p.path, str) else tuple(p.path))
                     for k, p in sweep.zip.params.items()}
            n = next(iter(lens.values()))
            paths = tuple(p for _, ps in extra.values() for p in ps)
            dims.append(SweepDim(sweep.zip.dim, list(range(n)), paths, extra))
    if sweep.replicas:
        dims.append(SweepDim("replica", list(range(sweep.replicas)), ("seed",)))
    names = [d.name for d in dims] + [k for d in dims for k in d.extra]
    dup = {n for n in names if names.count(n) > 1}
    if dup:
        raise ConfigError([f"sweep: name(s) {', '.join(sorted(dup))} used twice (dimensions and zip "
                           f"parameters share one namespace): rename"])
    clash = sorted(set(names) & RESERVED)
    if clash:
        raise ConfigError([f"sweep: {', '.join(clash)} would clash with names of the results file "
                           f"({', '.join(sorted(RESERVED))}): choose another name"])
    return dims


def expand(data: dict, srcmap: SourceMap, base_text: str = "", base_dir: Path = Path("."),
           overrides: dict[str, Any] | None = None) -> SweepPlan:
    """Validate the scene, apply `overrides` (path -> value, on the validated form), expand its
    `sweep:` (if any) and validate every case."""
    data = copy.deepcopy(data)
    raw_sweep = data.pop("sweep", None) if isinstance(data, dict) else None
    base = validate_data(data, srcmap, base_dir)
    if overrides:
        base_data = config_to_dict(base)
        for key, value in overrides.items():
            set_path(base_data, key, value)
        base = validate_data(base_data, srcmap, base_dir)
        base_text = (f"# {srcmap.filename} with {', '.join(f'{k}={v}' for k, v in overrides.items())}\n"
                     + yaml.safe_dump(config_to_dict(base), sort_keys=False))
    base._base_dir = base_dir
    if raw_sweep is None:
        return SweepPlan([], [SweepCase((), {}, base, ())], base_text, "")
    try:
        sweep = Sweep.model_validate(raw_sweep)
    except ValidationError as exc:
        raise ConfigError([srcmap.format(("sweep",) + tuple(e["loc"]), e["msg"].removeprefix("Value error, "))
                           for e in exc.errors(include_url=False)]) from None
    order = [k for k in raw_sweep if k in ("product", "zip")]
    dims = _dims(sweep, order)
    base_data = config_to_dict(base)
    cases, problems = [], []
    for index in itertools.product(*(range(len(d.values)) for d in dims)):
        case_data = copy.deepcopy(base_data)
        coords: dict[str, Any] = {}
        for d, i in zip(dims, index):
            coords[d.name] = d.values[i]
            if d.name == "replica" and d.paths == ("seed",):
                continue
            if d.extra:
                for _, (vals, paths) in d.extra.items():
                    for p in paths:
                        set_path(case_data, p, vals[i])
            else:
                for p in d.paths:
                    set_path(case_data, p, d.values[i])
        label = ", ".join(f"{k}={v}" for k, v in coords.items())
        try:
            cfg = validate_data(case_data, srcmap, base_dir)
        except ConfigError as exc:
            problems.extend(f"case {label}: {p}" for p in exc.problems)
            continue
        cfg._base_dir = base_dir
        cases.append(SweepCase(index, coords, cfg, _seed_key(coords)))
    if problems:
        raise ConfigError(problems[:20] + ([f"... and {len(problems) - 20} more"] if len(problems) > 20 else []))
    return SweepPlan(dims, cases, base_text, yaml.safe_dump(raw_sweep, sort_keys=False))


def load_plan(path: str | Path, overrides: list[str] = ()) -> SweepPlan:
    """Read a config (optionally with `sweep:`) or a sweep file (`base:`, `set:`, `sweep:`),
    apply `--set path=value` overrides, expand and validate every case."""
    path = Path(path)
    try:
        text = path.read_text()
    except OSError as exc:
        raise ConfigError([f"{path}: cannot read the config: {exc.strerror}"]) from None
    data, srcmap = load_yaml(text, str(path))
    base_dir = path.parent
    base_text = text
    if isinstance(data, dict) and "base" in data:
        extra = set(data) - {"base", "set", "sweep"}
        if extra:
            raise ConfigError([srcmap.format((sorted(extra)[0],), "a sweep file takes only base, set and sweep")])
        base_path = (path.parent / str(data["base"])).resolve()
        try:
            base_text = base_path.read_text()
        except OSError as exc:
            raise ConfigError([srcmap.format(("base",), f"cannot read {base_path}: {exc.strerror}")]) from None
        sets = {str(k): v for k, v in (data.get("set") or {}).items()}
        scene, srcmap = load_yaml(base_text, str(base_path))
        base_dir = base_path.parent
        if "sweep" in data:
            scene["sweep"] = data["sweep"]
        data = scene
    else:
        sets = {}
    for item in overrides:
        key, sep, value = item.partition("=")
        if not sep:
            raise ConfigError([f"--set {item}: write path=value"])
        sets[key.strip()] = yaml.load(value, Loader=_Loader)
    return expand(data, srcmap, base_text, base_dir, sets)
