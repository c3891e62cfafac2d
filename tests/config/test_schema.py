"""The JSON schema (config/schema.py) accepts every form the loader accepts and rejects what it
rejects: every shipped YAML file validates, a set of bad configs fails both."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import yaml

from wallbatch.config.models import load_config_text
from wallbatch.config.schema import config_json_schema, json_schema
from wallbatch.config.source import ConfigError, _Loader
from wallbatch.config.sweep import load_plan

jsonschema = pytest.importorskip("jsonschema")

ROOT = Path(__file__).resolve().parents[2]
SHIPPED = sorted(p for d in ("configs", "sweeps") for p in (ROOT / d).rglob("*.yaml"))


@pytest.fixture(scope="module")
def validator():
    schema = json_schema()
    jsonschema.Draft202012Validator.check_schema(schema)
    return jsonschema.Draft202012Validator(schema)


def data(text: str):
    """YAML as the loader reads it, then as JSON sees it (mapping keys are strings)."""
    return json.loads(json.dumps(yaml.load(text, Loader=_Loader)))


def test_shipped_files_exist():
    assert len(SHIPPED) >= 20


@pytest.mark.slow
@pytest.mark.parametrize("path", SHIPPED, ids=lambda p: str(p.relative_to(ROOT)))
def test_every_shipped_file_is_valid(path, validator):
    load_plan(path)  # the loader accepts it ...
    errors = [f"{'.'.join(map(str, e.absolute_path))}: {e.message[:200]}"
              for e in validator.iter_errors(data(path.read_text()))]
    assert not errors, "\n".join(errors)  # ... and so does the schema


BASE = """
units: lj
box: {lo: [0, 0, 0], hi: [6, 6, 8], boundary: [p, p, f]}
atoms:
  - {group: gas, create: {random: {count: 10}}, mass: 1.0, velocity: {temperature: 1.0}}
timestep: 0.005
run: {steps: 10}
walls:
"""

GOOD = {
    "mapping": "  w: {style: lj93, units: box, zlo: {coord: EDGE, epsilon: 1.0, sigma: 1.0, cutoff: 2.5}}",
    "positional": "  w: {style: lj126, units: box, zlo: [0.0, 1.0, 1.0, 2.5], zhi: [v_top, v_e, 1.0, 2.5]}",
    "positional morse": "  w: {style: morse, units: box, zhi: [8.0, 1.0, 1.5, 1.2, 3.0]}",
    "harmonic without sigma": "  w: {style: harmonic, units: box, zlo: {coord: 0.0, epsilon: 5.0, cutoff: 1.0}}",
    "fix line": '  w: "fix w all wall/lj93 zlo EDGE 1.0 1.0 2.5 units box"',
    "fix mapping": '  w: {fix: "fix w all wall/lj93 zlo EDGE 1.0 1.0 2.5 units box", energy: true}',
    "bare reflect faces": "  w: {style: reflect, units: box, zlo: EDGE, zhi: v_top}",
    "numeric string": "  w: {style: lj93, units: box, zlo: {coord: '0.5', epsilon: '1e-1', sigma: 1.0, cutoff: 2.5}}",
}
VARIABLES = "variables: {top: 8.0, e: 1.0}\n"

BAD = {
    "unknown style": "  w: {style: lj99, units: box, zlo: [0.0, 1.0, 1.0, 2.5]}",
    "positional too short": "  w: {style: lj93, units: box, zlo: [0.0, 1.0, 2.5]}",
    "positional too long": "  w: {style: morse, units: box, zlo: [0.0, 1.0, 1.0, 1.0, 1.0, 2.5]}",
    "lj93 without sigma": "  w: {style: lj93, units: box, zlo: {coord: 0.0, epsilon: 1.0, cutoff: 2.5}}",
    "morse keys on lj": "  w: {style: lj93, units: box, zlo: {coord: 0.0, D0: 1.0, alpha: 1.0, r0: 1.0, cutoff: 2.5}}",
    "bad coord word": "  w: {style: lj93, units: box, zlo: [edge, 1.0, 1.0, 2.5]}",
    "variable cutoff": "  w: {style: lj93, units: box, zlo: [0.0, 1.0, 1.0, v_top]}",
    "zero cutoff": "  w: {style: lj93, units: box, zlo: [0.0, 1.0, 1.0, 0.0]}",
    "not a fix line": '  w: "wall/lj93 zlo EDGE 1.0 1.0 2.5"',
    "unknown key": "  w: {style: lj93, units: box, zlo: [0.0, 1.0, 1.0, 2.5], colour: red}",
    "unknown face key": "  w: {style: reflect, units: box, zlo: {coord: EDGE, epsilon: 1.0}}",
}


@pytest.mark.parametrize("name", sorted(GOOD))
def test_forms_accepted_by_both(name, validator):
    text = VARIABLES + BASE + GOOD[name] + "\n"
    load_config_text(text)
    assert validator.is_valid(data(text))


@pytest.mark.parametrize("name", sorted(BAD))
def test_bad_configs_rejected_by_both(name, validator):
    text = VARIABLES + BASE + BAD[name] + "\n"
    with pytest.raises(ConfigError):
        load_config_text(text)
    assert not validator.is_valid(data(text))


def test_sweep_file_forms(validator, tmp_path):
    good = {"base": "../configs/quickstart.yaml", "set": {"run.steps": 10},
            "sweep": {"product": {"epsilon": {"path": "walls.w.zlo.epsilon", "values": {"linspace": [0.5, 1.5, 3]}}}}}
    assert validator.is_valid(good)
    assert not validator.is_valid({**good, "extra": 1})  # a sweep file takes only base, set, sweep
    assert not validator.is_valid({"set": {"run.steps": 10}})  # no base, and not a config


def test_every_key_has_a_description():
    schema = config_json_schema()
    missing = [f"{name}.{key}" for name, d in schema["$defs"].items() for key, v in d.get("properties", {}).items()
               if not v.get("description")]
    missing += [key for key, v in schema["properties"].items() if not v.get("description")]
    assert not missing
