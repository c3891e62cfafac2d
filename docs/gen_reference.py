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

# What the models do not say (meaning, unit kind, LAMMPS equivalent per dotted key path) lives in
# the package, next to the models, so the JSON schema reads the same table.
from wallbatch.config.keys import COORD, KEYS, NUM_OR_VAR, Key  # noqa: E402,F401

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
    if hasattr(ann, "full_annotation"):  # a type validated on demand (config/models.py Wall): what it stands for
        ann = ann.full_annotation()
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
