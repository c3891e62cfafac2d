"""A check of a whole section that fails because of a `--set` value inside it names that argument
(`--set run.steps=` with `run: {steps: 10}`: the file's run line alone reads as valid)."""

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


@pytest.mark.parametrize("arg, key", [("run.steps=", "run.steps"), ("run.time=5", "run.time")])
def test_section_check_names_the_set(tmp_path: Path, arg: str, key: str) -> None:
    p = tmp_path / "s.yaml"
    p.write_text(SCENE)
    with pytest.raises(ConfigError) as info:
        load_plan(p, [arg])
    assert info.value.problems == [f"{p}:6:6: run: give exactly one of steps or time (with {key} from --set {arg})"]
