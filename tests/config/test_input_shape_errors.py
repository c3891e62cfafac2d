"""Input of the wrong shape is named at its key (file:line:col, or the `--set` argument), in plain
words:

- a fixed-length list of the wrong length, with its expected and given length (not pydantic's
  "Field required" for an item that is not there);
- a scalar or a list where a section of keys belongs, without the validating model's class name
  ("instance of Run"); a number given to a union of a number and a section gets only the number's
  error;
- two `--set` arguments on one value (the same path, or one inside the other) are refused, naming
  both as typed (not the last one silently winning);
- a check of a whole section that fails because of a `--set` value inside it names that argument
  (`--set run.steps=` with `run: {steps: 10}`: the file's run line alone reads as valid)."""

from __future__ import annotations

from collections.abc import Callable
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
WALLSrun: RUN
"""
WALLS = """\
walls:
  w: {style: lj93, units: box, zlo: [EDGE, 1.0, 1.0, 2.5], zhi: ZHI}
"""


@pytest.fixture
def scene(tmp_path: Path) -> Callable[..., Path]:
    """Write tmp_path/s.yaml: a gas in a 10 x 10 x 12 box, with `box.lo` = lo, `run:` = run and,
    when zhi is given, a wall `w` (lines 6-7, run then on line 8) whose zhi face is zhi."""

    def write(lo: str = "[0, 0, 0]", zhi: str | None = None, run: str = "{steps: 10}") -> Path:
        walls = "" if zhi is None else WALLS.replace("ZHI", zhi)
        p = tmp_path / "s.yaml"
        p.write_text(SCENE.replace("LO", lo).replace("WALLS", walls).replace("RUN", run))
        return p

    return write


def problems(path: Path, sets: tuple[str, ...] | list[str] = ()) -> list[str]:
    """The ConfigError lines of loading `path` with `--set` arguments `sets`."""
    with pytest.raises(ConfigError) as info:
        load_plan(path, list(sets))
    return info.value.problems


# -- lists of the wrong length ---------------------------------------------------------------

@pytest.mark.parametrize("lo, got", [("[0, 0]", 2), ("[0]", 1), ("[0, 0, 0, 0]", 4)])
def test_box_lo_of_wrong_length(scene, lo: str, got: int) -> None:
    p = scene(lo=lo)
    assert problems(p) == [f"{p}:1:11: box.lo: expects 3 values, got {got}"]


def test_linspace_with_two_values(scene, tmp_path: Path) -> None:
    scene()
    p = tmp_path / "w.yaml"
    p.write_text("base: s.yaml\nsweep: {product: {lz: {path: box.hi.2, values: {linspace: [12, 14]}}}}\n")
    assert problems(p) == [f"{p}:2:59: sweep.product.lz.values.linspace: linspace expects 3 values [a, b, n], got 2"]


# -- a scalar where a section belongs --------------------------------------------------------

FACE = "[EDGE, 1.0, 1.0, 2.5]"


def test_number_for_a_section(scene) -> None:
    p = scene(zhi=FACE, run="5")
    assert problems(p) == [f"{p}:8:6: run: expected a mapping of keys (key: value), got a number 5"]


def test_text_for_a_section(scene) -> None:
    p = scene(zhi=FACE, run="fast")
    assert problems(p) == [f"{p}:8:6: run: expected a mapping of keys (key: value), got text 'fast'"]


def test_number_for_a_face(scene) -> None:
    p = scene(zhi="5")
    assert problems(p) == [f"{p}:7:65: walls.w.zhi: expected a mapping of keys (key: value) or the positional list "
                           "of the LAMMPS command (coord epsilon sigma cutoff ...), got a number 5"]


def test_number_for_a_face_by_set(scene) -> None:
    p = scene(zhi=FACE)
    assert problems(p, ("walls.w.zhi=5",)) == [
        "--set walls.w.zhi=5: walls.w.zhi: expected a mapping of keys (key: value) or the positional "
        "list of the LAMMPS command (coord epsilon sigma cutoff ...), got a number 5"]


def test_negative_thermo_one_error(scene) -> None:
    p = scene(zhi=FACE, run="{steps: 10, thermo: -10}")
    assert problems(p) == [f"{p}:8:26: run.thermo: Input should be greater than or equal to 0"]


# -- one value set twice by --set ------------------------------------------------------------

@pytest.mark.parametrize("sets, message", [
    (["run.steps=5", "run.steps=6"],
     "--set run.steps=6: run.steps is also set by --set run.steps=5: give each value once"),
    (["run={steps: 5}", "run.steps=6"],
     "--set run.steps=6: run.steps lies inside run, set by --set run={steps: 5}: give each value once"),
    (["run.steps=6", "run={steps: 5}"],
     "--set run={steps: 5}: run contains run.steps, set by --set run.steps=6: give each value once"),
])
def test_one_value_set_twice(scene, sets: list[str], message: str) -> None:
    assert problems(scene(), sets) == [message]


def test_two_values_set_once_each(scene) -> None:
    plan = load_plan(scene(), ["run.steps=6", "run.thermo=2"])
    assert plan.cases[0].config.run.steps == 6


# -- a --set inside a section that then fails its check --------------------------------------

@pytest.mark.parametrize("arg, key", [("run.steps=", "run.steps"), ("run.time=5", "run.time")])
def test_section_check_names_the_set(scene, arg: str, key: str) -> None:
    p = scene()
    assert problems(p, [arg]) == [f"{p}:6:6: run: give exactly one of steps or time (with {key} from --set {arg})"]
