"""Two `--set` arguments on one value (the same path, or one inside the other) are refused, naming
both as typed (not the last one silently winning)."""

from __future__ import annotations

from pathlib import Path

import pytest

from wallbatch.config.source import ConfigError
from wallbatch.config.sweep import load_plan

SCENE = """\
box: {lo: [0, 0, 0], hi: [10, 10, 12], boundary: [p, p, f]}
atoms:
  - group: gas
    create: {random: {count: 10}}
    mass: 1.0
run: {steps: 10}
"""


@pytest.mark.parametrize("sets, message", [
    (["run.steps=5", "run.steps=6"],
     "--set run.steps=6: run.steps is also set by --set run.steps=5: give each value once"),
    (["run={steps: 5}", "run.steps=6"],
     "--set run.steps=6: run.steps lies inside run, set by --set run={steps: 5}: give each value once"),
    (["run.steps=6", "run={steps: 5}"],
     "--set run={steps: 5}: run contains run.steps, set by --set run.steps=6: give each value once"),
])
def test_one_value_set_twice(tmp_path: Path, sets: list[str], message: str) -> None:
    p = tmp_path / "s.yaml"
    p.write_text(SCENE)
    with pytest.raises(ConfigError) as info:
        load_plan(p, sets)
    assert info.value.problems == [message]


def test_two_values_set_once_each(tmp_path: Path) -> None:
    p = tmp_path / "s.yaml"
    p.write_text(SCENE)
    plan = load_plan(p, ["run.steps=6", "run.thermo=2"])
    assert plan.cases[0].config.run.steps == 6
