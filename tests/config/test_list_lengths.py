"""A fixed-length list of the wrong length is named at the list with its expected and given length
(not pydantic's "Field required" for an item that is not there)."""

from __future__ import annotations

from pathlib import Path

import pytest

from wallbatch.config.source import ConfigError
from wallbatch.config.sweep import load_plan

SCENE = """\
box: {lo: LO, hi: [10, 10, 12], boundary: [p, p, f]}
atoms:
  - group: gas
    create: {random: {count: 10}}
    mass: 1.0
run: {steps: 10}
"""


def problems(path: Path, sets: tuple[str, ...] = ()) -> list[str]:
    """The ConfigError lines of loading `path`."""
    with pytest.raises(ConfigError) as info:
        load_plan(path, list(sets))
    return info.value.problems


@pytest.mark.parametrize("lo, got", [("[0, 0]", 2), ("[0]", 1), ("[0, 0, 0, 0]", 4)])
def test_box_lo_of_wrong_length(tmp_path: Path, lo: str, got: int) -> None:
    p = tmp_path / "s.yaml"
    p.write_text(SCENE.replace("LO", lo))
    assert problems(p) == [f"{p}:1:11: box.lo: expects 3 values, got {got}"]


def test_linspace_with_two_values(tmp_path: Path) -> None:
    (tmp_path / "s.yaml").write_text(SCENE.replace("LO", "[0, 0, 0]"))
    p = tmp_path / "w.yaml"
    p.write_text("base: s.yaml\nsweep: {product: {lz: {path: box.hi.2, values: {linspace: [12, 14]}}}}\n")
    assert problems(p) == [f"{p}:2:59: sweep.product.lz.values.linspace: linspace expects 3 values [a, b, n], got 2"]
