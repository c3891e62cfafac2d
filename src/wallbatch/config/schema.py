"""The JSON schema (draft 2020-12) of wallbatch's YAML files, for editors and `wallbatch schema`.

`config_json_schema()` describes a config: the Pydantic `Config` model widened to every form the
loader accepts (faces by name or positional `[coord, ...]` in the style's LAMMPS order, walls as
LAMMPS fix lines or `{fix: ..., energy: ...}`, bare reflect faces `zlo: EDGE`), with a description
on every key (the models' own, else the key table of config/keys.py). `json_schema()` accepts a
config or a sweep file (`base:`, `set:`, `sweep:`).
"""

from __future__ import annotations

import copy
import json
from typing import Any

from wallbatch.config.keys import KEYS
from wallbatch.config.models import COORD_SCHEMA, WALL_MODELS, Config, ReflectWall
from wallbatch.config.source import FACES
from wallbatch.config.sweep import Sweep
from wallbatch.styles import STYLES
from wallbatch.styles.cutoff import CUTOFF_MODES

FIX_LINE = {"type": "string", "pattern": r"^\s*fix\s",
            "description": "the wall as a LAMMPS fix line: `fix ID group wall/STYLE args ... [keywords]` (ID = this "
                           "key)"}


def _with_sweep(schema: dict) -> dict:
    """Config's schema with its `sweep` property described by the `Sweep` model."""
    sweep = Sweep.model_json_schema()
    defs = schema.setdefault("$defs", {})
    sub_defs = sweep.pop("$defs", {})
    renames = {k: (k if k not in defs or defs[k] == v else f"Sweep{k}") for k, v in sub_defs.items()}
    if any(k != v for k, v in renames.items()):
        text = json.dumps({"root": sweep, "defs": sub_defs})
        for old, new in renames.items():
            text = text.replace(f'"#/$defs/{old}"', f'"#/$defs/{new}"')
        moved = json.loads(text)
        sweep, sub_defs = moved["root"], moved["defs"]
    for old, body in sub_defs.items():
        defs[renames[old]] = body
    name = "Sweep" if "Sweep" not in defs else "SweepSpec"
    defs[name] = sweep
    props = schema.setdefault("properties", {})
    props["sweep"] = {
        "anyOf": [{"$ref": f"#/$defs/{name}"}, {"type": "null"}],
        "default": None,
        "description": "parameter sweep: product dimensions, a zip dimension and replicas",
    }
    return schema


def _faces(defs: dict) -> None:
    """Faces of the registry's wall models: by name, with the style's required parameters, or
    positionally `[coord, p1, ...]` in LAMMPS order; reflect faces also as a bare coord."""
    for name, model in WALL_MODELS.items():
        style = STYLES[name]
        wall = defs[model.__name__]
        face_ref = next(a["$ref"] for a in wall["properties"]["zlo"]["anyOf"] if "$ref" in a)
        face = defs[face_ref.split("/")[-1]]
        face["required"] = ["coord", *(p.name for p in style.parameters if p.required)]
        items = [copy.deepcopy(face["properties"][k]) for k in style.positional]
        for item in items:
            if "anyOf" in item:  # an optional parameter is still a word of the positional form
                item["anyOf"] = [a for a in item["anyOf"] if a != {"type": "null"}]
            item.pop("default", None)
        positional = {"type": "array", "prefixItems": items, "items": False, "minItems": len(items),
                      "description": f"positional form: [{', '.join(style.positional)}] (LAMMPS order)"}
        for f in FACES:
            wall["properties"][f]["anyOf"].insert(1, positional)
    reflect = defs[ReflectWall.__name__]
    for f in FACES:
        reflect["properties"][f]["anyOf"].insert(1, {**COORD_SCHEMA, "description": "the coord alone"})


def _walls(schema: dict) -> None:
    """A wall is a mapping of its model, a fix line, or `{fix: LINE, energy:, virial:, cutoff_mode:,
    switch_on:}`."""
    walls = schema["properties"]["walls"]
    models = walls["additionalProperties"]
    walls["additionalProperties"] = {"anyOf": [models, FIX_LINE, {
        "type": "object", "required": ["fix"], "additionalProperties": False,
        "description": "a LAMMPS fix line with wallbatch settings",
        "properties": {"fix": FIX_LINE,
                       "energy": {"type": "boolean", "description": KEYS["walls.ID.energy"].doc},
                       "virial": {"type": "boolean", "description": KEYS["walls.ID.virial"].doc},
                       "cutoff_mode": {"enum": list(CUTOFF_MODES), "description": KEYS["walls.ID.cutoff_mode"].doc},
                       "switch_on": {"type": "number", "minimum": 0,
                                     "description": KEYS["walls.ID.switch_on"].doc}}}]}


_VALUE_FORMS = {  # the forms of a sweep's values
    "linspace": "[a, b, n]: n evenly spaced values from a to b (both included)",
    "logspace": "[a, b, n]: n values from 10^a to 10^b, evenly spaced in the exponent",
    "range": "[a, b, step]: a, a + step, ... up to b (excluded), as numpy.arange",
}


def _fixes(schema: dict) -> None:
    """A fix under `fixes:` is a mapping of its model or a LAMMPS fix line."""
    fixes = schema["properties"].get("fixes")
    if fixes is None:
        return
    for alt in fixes.get("anyOf", [fixes]):
        if isinstance(alt.get("additionalProperties"), dict):
            alt["additionalProperties"] = {"anyOf": [alt["additionalProperties"], {
                **FIX_LINE, "description": "the fix as a LAMMPS fix line: `fix ID group STYLE args ...` (ID = this "
                                           "key)"}]}


def _describe(schema: dict) -> None:
    """Give every property a description: the model's, else the key table's (config/keys.py)."""
    defs = schema["$defs"]

    def key_path(path: str) -> str:
        return path.lstrip(".")

    def visit(node: Any, path: str, seen: tuple = ()) -> None:
        if not isinstance(node, dict):
            return
        ref = node.get("$ref")
        if ref:
            name = ref.split("/")[-1]
            if (name, path) not in seen:
                visit(defs[name], path, seen + ((name, path),))
            return
        for k in ("anyOf", "oneOf", "allOf", "prefixItems"):
            for sub in node.get(k, ()):
                visit(sub, path, seen)
        if isinstance(node.get("items"), dict):
            visit(node["items"], path + "[]", seen)
        for pattern, sub in node.get("patternProperties", {}).items():
            visit(sub, path + ".NAME", seen)
        extra = node.get("additionalProperties")
        if isinstance(extra, dict):
            visit(extra, path + (".ID" if path == ".walls" else ".NAME"), seen)
        for prop, sub in node.get("properties", {}).items():
            child = f"{path}.{prop}"
            shown = key_path(child)
            if shown.startswith("walls.ID.") and prop in FACES:
                child = ".walls.ID.FACE"
            key = KEYS.get(key_path(child))
            if "description" not in sub and prop in _VALUE_FORMS and key is None:
                sub["description"] = _VALUE_FORMS[prop]
            if "description" not in sub:
                if key is None:
                    raise KeyError(f"no description for the config key {key_path(child)}: add it to config/keys.py")
                sub["description"] = key.doc
            visit(sub, child, seen)

    visit(schema, "")


def config_json_schema() -> dict:
    """JSON schema (draft 2020-12) of a wallbatch config: every form the loader accepts, a
    description on every key."""
    schema = _with_sweep(Config.model_json_schema())
    _faces(schema["$defs"])
    _walls(schema)
    _fixes(schema)
    _describe(schema)
    return {"$schema": "https://json-schema.org/draft/2020-12/schema",
            **{k: v for k, v in schema.items() if k != "title"},
            "title": "wallbatch config"}


def json_schema() -> dict:
    """JSON schema of any wallbatch YAML file: a config, or a sweep file (`base:` a config path,
    `set:` dotted paths to new values, `sweep:` the grid)."""
    cfg = config_json_schema()
    defs = cfg.pop("$defs")
    sweep_ref = cfg["properties"]["sweep"]["anyOf"][0]
    defs["Config"] = {k: v for k, v in cfg.items() if k not in ("$schema", "title")}
    defs["SweepFile"] = {
        "type": "object", "required": ["base"], "additionalProperties": False,
        "description": "a sweep file: a base config, values set on it, and a sweep grid",
        "properties": {
            "base": {"type": "string", "description": "path of the base config, relative to this file"},
            "set": {"type": "object", "description": "dotted paths of the base config (`walls.w.zlo.epsilon`, "
                                                      "`box.hi.2`) and the values they take",
                    "additionalProperties": True},
            "sweep": {**sweep_ref, "description": "the sweep grid: product dimensions, a zip dimension, replicas"},
        },
    }
    return {"$schema": "https://json-schema.org/draft/2020-12/schema", "title": "wallbatch config or sweep file",
            "anyOf": [{"$ref": "#/$defs/Config"}, {"$ref": "#/$defs/SweepFile"}], "$defs": defs}
