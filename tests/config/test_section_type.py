"""A scalar or a list where a section of keys belongs is said plainly at its key, without the
validating model's class name ("instance of Run"), and a number given to a union of a number and
a section gets only the number's error."""

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
walls:
  w: {style: lj93, units: box, zlo: [EDGE, 1.0, 1.0, 2.5], zhi: ZHI}
run: RUN
"""


def problems(tmp_path: Path, zhi: str = "[EDGE, 1.0, 1.0, 2.5]", run: str = "{steps: 10}",
             sets: tuple[str, ...] = ()) -> tuple[Path, list[str]]:
    """The file written and the ConfigError lines of loading it."""
    p = tmp_path / "s.yaml"
    p.write_text(SCENE.replace("ZHI", zhi).replace("RUN", run))
    with pytest.raises(ConfigError) as info:
        load_plan(p, list(sets))
    return p, info.value.problems


def test_number_for_a_section(tmp_path: Path) -> None:
    p, got = problems(tmp_path, run="5")
    assert got == [f"{p}:8:6: run: expected a mapping of keys (key: value), got a number 5"]


def test_text_for_a_section(tmp_path: Path) -> None:
    p, got = problems(tmp_path, run="fast")
    assert got == [f"{p}:8:6: run: expected a mapping of keys (key: value), got text 'fast'"]


def test_number_for_a_face(tmp_path: Path) -> None:
    p, got = problems(tmp_path, zhi="5")
    assert got == [f"{p}:7:65: walls.w.zhi: expected a mapping of keys (key: value) or the positional list of the "
                   "LAMMPS command (coord epsilon sigma cutoff ...), got a number 5"]


def test_number_for_a_face_by_set(tmp_path: Path) -> None:
    _, got = problems(tmp_path, sets=("walls.w.zhi=5",))
    assert got == ["--set walls.w.zhi=5: walls.w.zhi: expected a mapping of keys (key: value) or the positional "
                   "list of the LAMMPS command (coord epsilon sigma cutoff ...), got a number 5"]


def test_negative_thermo_one_error(tmp_path: Path) -> None:
    p, got = problems(tmp_path, run="{steps: 10, thermo: -10}")
    assert got == [f"{p}:8:26: run.thermo: Input should be greater than or equal to 0"]
