"""The JSON schema (draft 2020-12) of a wallbatch config, for editors and `wallbatch schema`.
"""

from __future__ import annotations

import json

from wallbatch.config.models import Config
from wallbatch.config.sweep import Sweep


def config_json_schema() -> dict:
    """JSON schema (draft 2020-12) of a wallbatch config: the `Config` model, with its `sweep`
    property described by the `Sweep` model when the sweep module is present."""
    schema = Config.model_json_schema()
    if True:
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
    return {"$schema": "https://json-schema.org/draft/2020-12/schema",
            **{k: v for k, v in schema.items() if k != "title"},
            "title": "wallbatch config"}


