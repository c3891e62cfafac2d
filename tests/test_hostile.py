"""A corpus of hostile or mistaken inputs (issue 14): each is refused as the project's own error,
with its place (file:line:col, the sweep file's line, the `--set` argument) and a wording that says
what to do; nothing escapes as a traceback, nothing is destroyed, nothing runs as "ok" that is not.
Also the run's own safety: -o naming an input, parts that are damaged or foreign, the lock file,
a full disk, limits checked before allocating."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pytest
import xarray as xr
from typer.testing import CliRunner

from wallbatch.batch import runner as runner_mod
from wallbatch.batch.runner import PART_SUFFIX, RunError, case_key, parts_dir, read_part, run_plan, save_part
from wallbatch.cli import app
from wallbatch.config.source import ConfigError, load_yaml
from wallbatch.config.sweep import load_plan

from factories import slit_yaml

cli = CliRunner()

SCENE = slit_yaml('hostile', 20, 40, 20)


@pytest.fixture
def scene(tmp_path: Path) -> Path:
    path = tmp_path / "scene.yaml"
    path.write_text(SCENE)
    return path


def sweep_file(tmp_path: Path, body: str, name: str = "sweep.yaml") -> Path:
    (tmp_path / "scene.yaml").write_text(SCENE)
    path = tmp_path / name
    path.write_text("base: scene.yaml\n" + textwrap.dedent(body))
    return path


def run(*args) -> "CliRunner.Result":
    return cli.invoke(app, [str(a) for a in args])


def config_error(path: Path, sets=()) -> list[str]:
    with pytest.raises(ConfigError) as info:
        load_plan(path, list(sets))
    return info.value.problems


# ============================================================================================
# YAML that is not plain data, or not text


@pytest.mark.slow
@pytest.mark.parametrize("text, where, words", [
    ("a: !!python/object/apply:os.system ['echo pwned']\n", "f.yaml:1:4: a:",
     "YAML tag !!python/object/apply:os.system is not allowed"),
    ("a: !custom 1\n", "f.yaml:1:4: a:", "YAML tag !custom is not allowed"),
    ("a: &x [1, *x]\n", "f.yaml:1:4: a.1:", "an alias refers to the value that contains it"),
    ("a: " + "[" * 3000 + "]" * 3000 + "\n", "f.yaml:", "nested too deeply"),
    ("a: " + "[" * 70 + "]" * 70 + "\n", "f.yaml:1:", "nested more than 64 levels deep"),
    ("? [a, b]\n: 1\n", "f.yaml:1:3: (top level):", "a key must be plain text or a number"),
    ('"a\\nb": 1\n', "f.yaml:1:1: (top level):", "a key may not contain a line break"),
    ("a: 1\na: 2\n", "f.yaml:2:1: a:", "defined twice (first at line 1); keep one"),
    ("walls:\n  0x1: a\n  1: b\n", "f.yaml:3:3: walls.1:",
     "defined twice (first at line 2 as 0x1; YAML reads both as 1); keep one"),
    ("walls:\n  1: a\n  '1': b\n", "f.yaml:3:3: walls.1:", "defined twice (first at line 2); keep one"),
    ("walls:\n  ~: a\n", "f.yaml:2:3: walls:", "the key ~ reads as null: write a name"),
    ("a: \x07\n", "f.yaml:1:4:", "the character U+0007 is not allowed in YAML"),
    ("a: [1, 2\n", "f.yaml:2:1:", "YAML syntax error"),
    ("a:\n\tb: 1\n", "f.yaml:2:1:", "YAML syntax error: found character '\\t' that cannot start any token: indent "
     "with spaces (YAML does not allow tabs there)"),
    ("", "f.yaml:", "the file is empty"),
])
def test_yaml_refused_with_location(text, where, words):
    with pytest.raises(ConfigError) as info:
        load_yaml(text, "f.yaml")
    msg = str(info.value)
    assert msg.startswith(where) and words in msg, msg


@pytest.mark.slow  # over 2.5 s
def test_alias_bomb_refused_before_expanding():
    levels = ["a0: &a0 [1, 1, 1, 1, 1, 1, 1, 1, 1, 1]"]
    levels += [f"a{i}: &a{i} [" + ", ".join([f"*a{i - 1}"] * 10) + "]" for i in range(1, 9)]
    text = "\n".join(levels) + "\n"
    assert len(text) < 1100  # a 1 kB file that expands to 10^9 values
    with pytest.raises(ConfigError, match=r"expands to more than 2,000,000 values"):
        load_yaml(text, "bomb.yaml")


def test_non_utf8_and_utf16_files(tmp_path):
    latin = tmp_path / "latin.yaml"
    latin.write_bytes(b"name: caf\xe9\n")
    assert config_error(latin) == [f"{latin}:1:10: the config is not UTF-8 text (byte 0xe9)"]
    utf16 = tmp_path / "u16.yaml"
    utf16.write_bytes("name: x\n".encode("utf-16"))
    (msg,) = config_error(utf16)
    assert msg.startswith(f"{utf16}:1:1: the config is not UTF-8 text") and "UTF-16: save it as UTF-8" in msg


def test_fifo_and_directory_as_config(tmp_path):
    fifo = tmp_path / "pipe.yaml"
    os.mkfifo(fifo)
    assert config_error(fifo) == [f"{fifo}: cannot read the config: it is not a regular file (a pipe or a device)"]
    assert config_error(tmp_path) == [f"{tmp_path}: cannot read the config: it is a directory"]


def test_sweep_file_structure_errors(tmp_path):
    (tmp_path / "list.yaml").write_text("- 1\n- 2\n")
    bad_base = tmp_path / "b.yaml"
    bad_base.write_text("base: list.yaml\n")
    (msg,) = config_error(bad_base)
    assert msg.startswith(f"{tmp_path / 'list.yaml'}:1:1: (top level): the base scene must be a mapping")
    p = sweep_file(tmp_path, "set: [1, 2]\n")
    assert config_error(p) == [f"{p}:2:6: set: set: give a mapping of path: value"]
    p = sweep_file(tmp_path, "sweep: {}\n", "x.yaml")
    p.write_text("base: [scene.yaml]\n")
    assert config_error(p) == [f"{p}:1:7: base: base: give the path of the scene file (text)"]


# ============================================================================================
# errors at the place the user wrote them


def test_sweep_errors_at_the_sweep_file_line_once_with_cases(tmp_path):
    p = sweep_file(tmp_path, """\
        sweep:
          product:
            cut: {path: walls.zwalls.zlo.cutoff, values: [-1.0, 2.5, -3.0]}
            eps: {path: walls.zwalls.zlo.epsilon, values: [1.0, 2.0]}
        """)
    problems = config_error(p)
    assert problems == [f"{p}:4:50: walls.zwalls.zlo.cutoff: Input should be greater than 0 "
                        f"(cases cut=-1.0, eps=1.0; cut=-1.0, eps=2.0; cut=-3.0, eps=1.0; cut=-3.0, eps=2.0)"]


def test_identical_error_of_every_case_once(tmp_path):
    p = sweep_file(tmp_path, """\
        sweep:
          product:
            eps: {path: walls.zwalls.zlo.epsilonn, values: [1.0, 2.0, 3.0]}
        """)
    (msg,) = config_error(p)
    assert msg.startswith(f"{p}:4:") and msg.endswith("(every case)") and "walls.zwalls.zlo.epsilonn" in msg


def test_bad_sweep_path_at_its_line(tmp_path):
    p = sweep_file(tmp_path, """\
        sweep:
          product:
            eps: {path: walls.nowall.zlo.epsilon, values: [1.0, 2.0]}
        """)
    (msg,) = config_error(p)
    assert msg.startswith(f"{p}:4:") and "sweep.product.eps" in msg and "walls.nowall does not exist" in msg


def test_a_sweep_path_into_a_face_written_as_a_list_names_its_keys(tmp_path):
    p = sweep_file(tmp_path, """\
        sweep:
          product:
            eps: {path: walls.zwalls.zlo.1, values: [1.0, 2.0]}
        """)
    (msg,) = config_error(p)
    assert msg == (f"{p}:4:17: sweep.product.eps: sweep path walls.zwalls.zlo.1: a face's values are named, also "
                   "where the file writes them as a list: walls.zwalls.zlo.{coord, epsilon, sigma, cutoff}")


@pytest.mark.parametrize("body, where, words", [
    ("sweep:\n  zip:\n    dim: g\n    params:\n      a: {path: run.steps, values: [1, 2]}\n"
     "      b: {path: run.thermo, values: [1]}\n", ":6:7: sweep.zip.params:", "must have equal lengths"),
    ("sweep:\n  product:\n    temp: {path: run.steps, values: [10, 20]}\n", ":4:11: sweep.product.temp:",
     "would clash with names of the results file"),
    ("sweep:\n  product:\n    n: {path: run.steps, values: {range: [1, 2, 1e-12]}}\n", ":4:8: sweep.product.n:",
     "values: more than the limit of 100,000 per dimension"),
    ("sweep:\n  product:\n    a: {path: run.steps, values: {linspace: [1, 2, 1000]}}\n"
     "    b: {path: run.thermo, values: {linspace: [1, 2, 1000]}}\n", ":3:3: sweep:",
     "1,000,000 cases: more than the limit of 100,000"),
    ("sweep:\n  replicas: 1000000000\n", ":3:3: sweep:", "1,000,000,000 cases: more than the limit of 100,000"),
    ("sweep:\n  product:\n    e: {path: run.steps, values: {logspace: [0, 400, 3]}}\n",
     ":4:45: sweep.product.e.values.logspace:", "10^400 is not a usable number; give exponents between -307 and 307"),
])
def test_sweep_structure_errors_have_sweep_file_locations(tmp_path, body, where, words):
    p = sweep_file(tmp_path, body)
    (msg,) = config_error(p)
    assert msg.startswith(f"{p}{where}") and words in msg, msg


@pytest.mark.parametrize("name, where, words", [
    ('"a/b"', ":4:12: sweep.product.a/b:", "'a/b' is not a NetCDF name"),
    ('""', ":4:9: sweep.product.:", "'' is empty"),
    ("wall_force_mean", ":4:22: sweep.product.wall_force_mean:", "'wall_force_mean' would clash with a variable"),
    ("temp_sem", ":4:15: sweep.product.temp_sem:", "'temp_sem' would clash with a variable"),
    ("window", ":4:13: sweep.product.window:", "'window' would clash with a variable"),
    ("wall_pressure_mean", ":4:25: sweep.product.wall_pressure_mean:", "would clash with a variable"),
])
def test_sweep_names_the_results_file_cannot_hold_are_refused_at_their_line(tmp_path, name, where, words):
    """Refused before anything runs: such a name failed writing the file after every case had run
    ('a/b', ''), crashed ('window') or silently replaced a time mean (`wall_force_mean`)."""
    p = sweep_file(tmp_path, f"sweep:\n  product:\n    {name}: {{path: run.steps, values: [10, 20]}}\n")
    (msg,) = config_error(p)
    assert msg.startswith(f"{p}{where} ") and words in msg and msg.endswith(": choose another name"), msg
    p = sweep_file(tmp_path, "sweep:\n  zip:\n    dim: g\n    params:\n"
                             "      temp_mean: {path: run.steps, values: [10, 20]}\n")
    (msg,) = config_error(p)
    assert msg.startswith(f"{p}:6:18: sweep.zip.params.temp_mean: 'temp_mean' would clash"), msg
    ok = sweep_file(tmp_path, "sweep:\n  product:\n    gap_mean: {path: run.steps, values: [10, 20]}\n")
    assert [d.name for d in load_plan(ok).dims] == ["gap_mean"]


def test_set_errors_name_the_argument(scene):
    assert config_error(scene, ["epsilon=2"]) == [
        "--set epsilon=2: epsilon: unknown key (misspelled? see shared/spec/config.md for the valid keys)"] or \
        config_error(scene, ["epsilon=2"])[0].startswith("--set epsilon=2: epsilon: unknown key")
    (msg,) = config_error(scene, ["walls.zwalls.zlo.epsilon=abc"])
    assert msg == ("--set walls.zwalls.zlo.epsilon=abc: walls.zwalls.zlo.epsilon: expected a number or a variable "
                   "reference v_name, got 'abc'")
    assert config_error(scene, ["run.steps=[1"]) == [
        "--set run.steps=[1: the value is not valid YAML (expected ',' or ']', but got '<stream end>')"]
    assert config_error(scene, ["run.steps"]) == ["--set run.steps: write path=value"]
    (msg,) = config_error(scene, ["walls.nowall.zlo.epsilon=1"])
    assert msg.startswith("--set walls.nowall.zlo.epsilon=1: ") and "walls.nowall does not exist" in msg
    (msg,) = config_error(scene, ["run.steps=!!python/name:os.system"])
    assert msg.startswith("--set run.steps=!!python/name:os.system: the value is not valid YAML")


@pytest.mark.parametrize("setting, where", [
    ("output.profiles={rho: {axis: z, bins: x, every: 1, repeat: 1, freq: 1, quantities: [temp]}}",
     "output.profiles.rho.bins"),
    ("fixes={nvt: {style: nvt, temp: [1, 1], damp: 0.1, tchain: x}}", "fixes.nvt.tchain"),
    ("walls.new={style: lj93, zlo: [EDGE, 1, 1, x]}", "walls.new.zlo.cutoff"),
])
def test_a_mistake_inside_a_set_mapping_is_named_in_full(scene, setting, where):
    """Keys the file does not have are still named down to the wrong value, at the argument."""
    (msg,) = config_error(scene, [setting])
    assert msg.startswith(f"--set {setting}: {where}: Input should be a valid "), msg


def test_union_tags_stay_out_of_a_set_value_s_location(scene):
    """pydantic's union members (`constrained-int`, `float`, a model's name) are not keys."""
    for setting, where in (("run.thermo=x", "run.thermo"), ("regions.slab.hi=x", "regions.slab.hi"),
                           ("regions.new={style: block, lo: [0, 0, 1], hi: x, units: box}", "regions.new.hi")):
        problems = config_error(scene, [setting])
        assert problems and all(p.startswith(f"--set {setting}: {where}: ") for p in problems), problems


def test_union_tags_stay_out_of_a_file_value_s_location(tmp_path):
    """The same written in the file (`run.thermo.constrained-int` and `regions.slab.hi.float` before)."""
    text = Path(__file__).resolve().parents[1].joinpath("configs", "quickstart.yaml").read_text()
    text = text.replace("hi: [10, 10, 11], units: box}", "hi: x, units: box}").replace("thermo: 200}", "thermo: x}")
    path = tmp_path / "bad.yaml"
    path.write_text(text)
    problems = config_error(path)
    assert len(problems) == 4, problems
    assert [p.split(": ")[1] for p in problems] == ["regions.slab.hi"] * 2 + ["run.thermo"] * 2, problems


def test_a_new_fix_line_replaces_the_wall_it_overrides(tmp_path):
    """`--set walls.ID.fix=LINE` (and a sweep over it) on a wall written as a fix line replaces the
    wall: its style, faces and numbers are the new line's, the keys written beside the old line
    stay (energy). They used to merge: the old style kept, the new face added beside the old one.
    A line that cannot be read is named at the --set argument, not at the file's wall."""
    root = Path(__file__).resolve().parents[1]
    piston = root / "configs" / "lj126-piston.yaml"
    new = "fix piston all wall/lj93 zlo EDGE 2.0 1.3 2.5 units box"
    wall = load_plan(piston, [f"walls.piston.fix={new}"]).cases[0].config.walls["piston"]
    assert wall.style == "lj93" and wall.energy is True
    assert [(face, spec.epsilon, spec.sigma, spec.cutoff) for face, spec in wall.faces()] == [("zlo", 2.0, 1.3, 2.5)]
    p = tmp_path / "lines.yaml"
    p.write_text(f"base: {piston}\nsweep:\n  product:\n    line:\n      path: walls.piston.fix\n      values:\n"
                 f"        - fix piston all wall/lj126 zhi v_piston 2.0 1.3 1.122462 units box\n        - {new}\n")
    walls = [c.config.walls["piston"] for c in load_plan(p).cases]
    assert [(w.style, [f for f, _ in w.faces()], w.energy) for w in walls] == [("lj126", ["zhi"], True),
                                                                               ("lj93", ["zlo"], True)]
    assert [s.epsilon for _, s in walls[0].faces()] == [2.0]
    (msg,) = config_error(piston, ["walls.piston.fix=garbage"])
    assert msg.startswith("--set walls.piston.fix=garbage: walls.piston.fix: word 1 'garbage': a wall line must "
                          "start with 'fix'"), msg


def test_a_value_twice_on_a_product_dimension_is_refused_at_its_line(tmp_path):
    """Two equal values of a dimension (1 and 1.0 too) would be two cases with one coordinate and
    one random stream, the same results twice and an ambiguous selection: refused at the values
    (or the shorthand entry). Repeated parameters along a zip are distinct cases (the zip's
    coordinate is the position) and stay allowed."""
    p = sweep_file(tmp_path, """\
        sweep:
          product:
            eps: {path: walls.zwalls.zlo.epsilon, values: [1.0, 2.0, 1]}
        """)
    (msg,) = config_error(p)
    assert msg == (f"{p}:4:51: sweep.product.eps.values: dimension eps: values 1 and 3 are the same (1): the two "
                   f"cases would be one case (one coordinate, one random stream); remove one, or use "
                   f"sweep.replicas for independent repeats"), msg
    p = sweep_file(tmp_path, """\
        sweep:
          product:
            walls.zwalls.zlo.epsilon: [2.0, 2.0]
        """)
    (msg,) = config_error(p)
    assert msg.startswith(f"{p}:4:") and "sweep.product.walls.zwalls.zlo.epsilon: dimension epsilon: values 1 and 2" \
        in msg, msg
    p = sweep_file(tmp_path, """\
        sweep:
          zip:
            dim: g
            params:
              a: {path: walls.zwalls.zlo.epsilon, values: [1.0, 1.0]}
              b: {path: walls.zwalls.zlo.sigma, values: [1.0, 1.0]}
        """)
    plan = load_plan(p)
    assert [c.coords for c in plan.cases] == [{"g": 0}, {"g": 1}] and plan.cases[0].seed_key != plan.cases[1].seed_key


def test_set_on_a_swept_path_is_refused(tmp_path):
    p = sweep_file(tmp_path, """\
        sweep:
          product:
            eps: {path: walls.zwalls.zlo.epsilon, values: [1.0, 2.0]}
        """)
    (msg,) = config_error(p, ["walls.zwalls.zlo.epsilon=3"])
    assert msg == (f"--set walls.zwalls.zlo.epsilon=3: walls.zwalls.zlo.epsilon is also swept by sweep.product.eps "
                   f"({p}:4:51): drop one of the two")
    (msg,) = config_error(p, ["walls.zwalls.zlo={coord: EDGE, epsilon: 1, sigma: 1, cutoff: 2.5}"])
    assert "is also swept by sweep.product.eps" in msg  # a parent of the swept path


@pytest.mark.parametrize("values,where,text", [
    ("{linspace: [0.5, 1.5, 0]}", "values.linspace.2", "Input should be greater than 0"),
    ("{linspace: [.nan, 1.5, 3]}", "values.linspace.0", "Input should be a finite number"),
    ("{range: [1.0, 0.5, 0.1]}", "values.range", "range [a, b, step] needs a step that goes from a toward b"),
    ("{lnspace: [0.5, 1.5, 3]}", "values", "values: give a list, {linspace: [a, b, n]}"),
    ("3", "values", "values: give a list, {linspace: [a, b, n]}"),
    ("[]", "values", "List should have at least 1 item"),
    ("{linspace: [0.5, 1.5]}", "values.linspace", "linspace expects 3 values [a, b, n], got 2"),  # "Field required"
    ("{range: [1.0]}", "values.range", "range expects 3 values [a, b, step], got 1"),  # once, not per number missing
])
def test_a_bad_values_form_is_one_problem_at_its_key(tmp_path, values, where, text):
    """A mistake inside one form of `values` is reported once, at that form's key (it came with an
    error for every other form: up to 20 lines, most of them about forms the user did not write)."""
    p = sweep_file(tmp_path, f"""\
        sweep:
          product:
            eps: {{path: walls.zwalls.zlo.epsilon, values: {values}}}
        """)
    (msg,) = config_error(p)
    assert msg.startswith(f"{p}:4:") and f"sweep.product.eps.{where}: {text}" in msg, msg


def test_a_zip_dimension_name_that_is_no_word_says_what_a_name_is(tmp_path):
    """It was pydantic's "String should match pattern '^[A-Za-z_][A-Za-z0-9_]*$'"."""
    p = sweep_file(tmp_path, """\
        sweep:
          zip: {dim: 'a b', params: {e: {path: walls.zwalls.zlo.epsilon, values: [1.0]}}}
        """)
    (msg,) = config_error(p)
    assert msg == (f"{p}:3:14: sweep.zip.dim: 'a b': a dimension name is letters, digits and underscores, not "
                   f"starting with a digit (it names a dimension of the results file)")


def test_a_product_entry_without_its_path_says_so(tmp_path):
    p = sweep_file(tmp_path, """\
        sweep:
          product:
            eps: {values: [1.0, 2.0]}
        """)
    assert config_error(p) == [f"{p}:4:10: sweep.product.eps.path: Field required"]


def test_two_sweep_entries_on_one_value_are_refused_where_the_second_is_written(tmp_path):
    """A path swept inside another swept path (a parent set to a number, then its child) or swept
    twice: one located error naming both entries, before any case is built (found by the loader's
    fuzz test: the case expansion used to fail with no location)."""
    p = sweep_file(tmp_path, """\
        sweep:
          product:
            zlo: {path: walls.zwalls.zlo, values: [{coord: EDGE, epsilon: 1, sigma: 1, cutoff: 2.5}]}
            eps: {path: walls.zwalls.zlo.epsilon, values: [1.0, 2.0]}
        """)
    (msg,) = config_error(p)
    assert msg == (f"{p}:5:17: sweep.product.eps: walls.zwalls.zlo.epsilon lies inside walls.zwalls.zlo, which is "
                   f"swept by sweep.product.zlo ({p}:4:17): sweep one or the other")
    p = sweep_file(tmp_path, """\
        sweep:
          product:
            eps: {path: walls.zwalls.zlo.epsilon, values: [1.0, 2.0]}
            zlo: {path: walls.zwalls.zlo, values: [{coord: EDGE, epsilon: 1, sigma: 1, cutoff: 2.5}]}
        """)
    (msg,) = config_error(p)
    assert msg.startswith(f"{p}:5:17: sweep.product.zlo: walls.zwalls.zlo contains walls.zwalls.zlo.epsilon, ")
    p = sweep_file(tmp_path, """\
        sweep:
          product:
            a: {path: walls.zwalls.zlo.epsilon, values: [1.0, 2.0]}
          zip:
            dim: both
            params:
              b: {path: [walls.zwalls.zhi.epsilon, walls.zwalls.zlo.epsilon], values: [3.0, 4.0]}
        """)
    (msg,) = config_error(p)
    assert msg.startswith(f"{p}:") and "walls.zwalls.zlo.epsilon is also swept by sweep.product.a" in msg
    # different values side by side stay allowed
    ok = sweep_file(tmp_path, """\
        sweep:
          product:
            lo: {path: walls.zwalls.zlo.epsilon, values: [1.0, 2.0]}
            hi: {path: walls.zwalls.zhi.epsilon, values: [1.0, 2.0]}
        """)
    assert len(load_plan(ok).cases) == 4


@pytest.mark.slow
def test_long_user_text_is_cut(scene):
    (msg,) = config_error(scene, ["walls.zwalls.zlo.epsilon=" + "x" * 2_000_000])
    assert len(msg) < 600 and msg.endswith("...: walls.zwalls.zlo.epsilon: expected a number or a variable "
                                           "reference v_name, got '" + "x" * 60 + "'")


# ============================================================================================
# non-finite numbers


@pytest.mark.parametrize("setting, words", [
    ("walls.zwalls.zlo.cutoff=.inf", "Input should be a finite number"),
    ("walls.zwalls.zlo.epsilon=.nan", "expected a finite number, got 'nan'"),
    ("walls.zwalls.zlo.epsilon='NaN'", "expected a finite number, got 'NaN'"),
    ("walls.zwalls.zlo.coord=-.inf", "expected a finite number, got '-inf'"),
    ("atoms.0.mass=.inf", "Input should be a finite number"),
    ("atoms.0.velocity.temperature=.inf", "Input should be a finite number"),
    ("run={time: .inf, thermo: 0}", "Input should be a finite number"),
    ("box.hi=[1e308, 6, 10]", "is not a finite number"),
    ("box.lo=[-1e308, 0, 0]", "is not a finite number"),
])
def test_non_finite_numbers_refused(scene, setting, words):
    (msg,) = config_error(scene, [setting])
    assert words in msg, msg
    assert msg.startswith("--set ") or msg.startswith(f"{scene}:")


@pytest.mark.parametrize("setting, where, words", [
    ("run.steps=true", "run.steps", "Input should be a valid integer"),
    ("seed=false", "seed", "Input should be a valid integer"),
    ("atoms.0.mass=true", "atoms.0.mass", "Input should be a valid number"),
    ("box.hi=[true, 6, 10]", "box.hi.0", "Input should be a valid number"),
    ("walls.zwalls.zlo.epsilon=true", "walls.zwalls.zlo.epsilon", "expected a number"),
    ("fixes={nvt: {style: nvt, temp: [1, 1], damp: 0.1, tchain: true}}", "fixes.nvt.tchain", "valid integer"),
    ("output.profiles={rho: {axis: z, bins: true, every: 1, repeat: 1, freq: 1, quantities: [temp]}}",
     "output.profiles.rho.bins", "valid integer"),
])
def test_true_or_false_is_not_a_number(scene, setting, where, words):
    """Pydantic reads a bool as 1 or 0 in lax mode (`steps: true` would run one step)."""
    (msg,) = config_error(scene, [setting])
    assert f": {where}: " in msg and words in msg, msg


def test_bool_keys_still_take_bools(scene):
    plan = load_plan(scene, ["walls.zwalls.energy=false", "run.steps=10"])
    assert plan.cases[0].config.walls["zwalls"].energy is False and plan.cases[0].config.run.steps == 10


def test_region_bounds_may_be_infinite_never_nan(scene):
    (msg,) = config_error(scene, ["regions.slab.lo=[.nan, 0, 1]"])
    assert msg == "--set regions.slab.lo=[.nan, 0, 1]: regions.slab.lo: expected numbers, got NaN"
    (msg,) = config_error(scene, ["regions.slab={style: sphere, center: [3, 3, .inf], radius: 1, units: box}"])
    assert "regions.slab.center: expected a finite number" in msg
    plan = load_plan(scene, ["regions.slab.lo=[-.inf, -.inf, 1]"])  # an open side, as LAMMPS's INF
    assert plan.cases[0].config.regions["slab"].lo == (-np.inf, -np.inf, 1.0)


def test_dt_reset_bounds_nan_refused_inf_word_allowed(scene):
    scene.write_text(SCENE + "dt_reset: {every: 1, tmin: .nan, tmax: INF, xmax: 0.05, units: box}\n")
    (msg,) = config_error(scene)
    assert msg == f"{scene}:20:28: dt_reset.tmin: expected a finite number: write INF or NULL for no bound"
    scene.write_text(SCENE + "dt_reset: {every: 1, tmin: [1], tmax: INF, xmax: 0.05, units: box}\n")
    (msg,) = config_error(scene)
    assert msg.endswith("dt_reset.tmin: expected a number, INF or NULL")
    scene.write_text(SCENE + "dt_reset: {every: 1, tmin: NULL, tmax: INF, xmax: 0.05, units: box}\n")
    assert load_plan(scene).cases[0].config.dt_reset.tmax is None


# ============================================================================================
# a case failing during setup fails alone


@pytest.mark.slow
def test_variable_dividing_by_zero_fails_that_case_only(tmp_path):
    p = sweep_file(tmp_path, """\
        set:
          variables.d: 1
          variables.a: "1 + 1/(v_d - 2)"
          walls.zwalls.zlo.epsilon: v_a
        sweep:
          product:
            d: {path: variables.d, values: [1, 2, 3]}
        """)
    out = tmp_path / "out.nc"
    res = run("run", p, "-o", out, "-j", "1")
    assert res.exit_code == 1, res.output
    assert "2 of 3 case(s) ok" in res.output
    assert "failed (1 case: d=2): cannot set up the case: variable 'a': Divide by 0 in variable formula" in res.output
    res = run("check", p)
    assert res.exit_code == 1
    assert f"{p}: the config is valid, but 1 of 3 case(s) cannot be built" in res.output
    assert ("1 case(s) (d=2) cannot be built: cannot set up the case: variable 'a': Divide by 0 in variable "
            "formula") in res.output
    one = tmp_path / "one.yaml"  # a single case (no sweep) that cannot be built
    text = p.read_text().replace("variables.d: 1", "variables.d: 2")
    one.write_text(text[:text.index("sweep:")])
    res = run("check", one)
    assert res.exit_code == 1
    assert "the config is valid, but 1 of 1 case(s) cannot be built" in res.output
    assert "  the case cannot be built: cannot set up the case: variable 'a': Divide by 0" in res.output
    with xr.open_dataset(out) as ds:
        assert ds["status"].values.tolist() == ["ok", "failed", "ok"]
        assert np.isfinite(ds["pe"].sel(d=3).values).all() and np.isnan(ds["pe"].sel(d=2).values).all()


def test_limits_on_steps_and_samples(tmp_path):
    p = sweep_file(tmp_path, """\
        sweep:
          product:
            n: {path: run.steps, values: [40, 2000000000000000]}
        """)
    res = run("run", p, "-o", tmp_path / "o.nc", "-j", "1")
    assert res.exit_code == 1
    assert "run.steps = 2,000,000,000,000,000 is more than the limit of 1,000,000,000,000" in res.output
    p = sweep_file(tmp_path, "set: {run.steps: 100000000, run.thermo: 1}\n", "s.yaml")
    res = run("run", p, "-o", tmp_path / "s.nc", "-j", "1")
    assert res.exit_code == 2 and "run.thermo makes 100,000,002 samples: more than the limit" in res.output


def test_atoms_and_memory_checked_before_building(scene, tmp_path, monkeypatch):
    res = run("run", scene, "-o", tmp_path / "a.nc", "--set", "atoms.0.create.random.count=1e10")
    assert res.exit_code == 2
    assert "error: the scene would create 10,000,000,000 atoms, more than the limit of 100,000,000" in res.output
    # a lattice at an absurd density: estimated from the box volume, refused before any site is made
    scene.write_text(SCENE.replace("create: {random: {count: 20, overlap: 0.8, region: slab}}",
                                   "create: {lattice: {}}") + "lattice: {style: fcc, scale: 1.0e12}\n")
    res = run("run", scene, "-o", tmp_path / "b.nc")
    assert res.exit_code == 2 and "atoms, more than the limit of 100,000,000" in res.output
    scene.write_text(SCENE)
    monkeypatch.setenv("WALLBATCH_MAX_MEMORY", "10K")
    p = sweep_file(tmp_path, "sweep: {product: {n: {path: atoms.0.create.random.count, values: [20, 30]}}}\n")
    res = run("run", p, "-o", tmp_path / "c.nc")
    # 50 atoms held (80 B each) + the batch running (450 B each): 26,500 bytes > 10,000
    assert res.exit_code == 2 and ("error: the 2 case(s) create 50 atoms: about 26.5 kB in memory, more than the "
                                   "10.0 kB available (WALLBATCH_MAX_MEMORY sets the limit)") in res.output
    monkeypatch.setenv("WALLBATCH_MAX_MEMORY", "1M")
    assert run("run", p, "-o", tmp_path / "c.nc").exit_code == 0


# ============================================================================================
# the output: never an input, never silently overwritten, locked while running


def test_output_naming_the_config_is_refused(scene):
    before = scene.read_text()
    res = run("run", scene, "-o", scene)
    assert res.exit_code == 2
    assert f"error: -o {scene} is an input of this run: choose another name for the results" in res.output
    assert scene.read_text() == before


def test_output_naming_the_base_of_a_sweep_is_refused(tmp_path):
    p = sweep_file(tmp_path, "sweep: {product: {eps: {path: walls.zwalls.zlo.epsilon, values: [1.0]}}}\n")
    res = run("run", p, "-o", tmp_path / "scene.yaml", "--force")
    assert res.exit_code == 2 and "is an input of this run" in res.output
    assert (tmp_path / "scene.yaml").read_text() == SCENE


def test_output_that_is_not_a_results_file_is_never_overwritten(scene, tmp_path):
    other = tmp_path / "notes.txt"
    other.write_text("precious")
    res = run("run", scene, "-o", other, "--force")
    assert res.exit_code == 2 and f"-o {other} exists and is not a results file: refusing to overwrite it" in res.output
    assert other.read_text() == "precious"


def test_existing_results_need_force(scene, tmp_path):
    out = tmp_path / "r.nc"
    assert run("run", scene, "-o", out).exit_code == 0
    stamp = out.stat().st_mtime_ns
    res = run("run", scene, "-o", out)
    assert res.exit_code == 2 and f"{out} exists: add --force to overwrite it, or choose another -o" in res.output
    assert out.stat().st_mtime_ns == stamp
    assert run("run", scene, "-o", out, "--force").exit_code == 0


def test_output_directory_and_parts_file(scene, tmp_path):
    res = run("run", scene, "-o", tmp_path)
    assert res.exit_code == 2 and f"-o {tmp_path} is a directory" in res.output
    out = tmp_path / "r.nc"
    parts_dir(out).write_text("oops")
    res = run("run", scene, "-o", out)
    assert res.exit_code == 2 and f"{parts_dir(out)} exists and is not a folder of parts" in res.output


def test_lock_held_by_a_live_process_refuses(scene, tmp_path):
    out = tmp_path / "r.nc"
    holder = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
    try:
        (tmp_path / "r.nc.lock").write_text(f"{holder.pid}\n")
        res = run("run", scene, "-o", out)
        assert res.exit_code == 2
        assert f"{out} is being written by another wallbatch run (PID {holder.pid}" in res.output
        assert not out.exists()
    finally:
        holder.kill()
        holder.wait()
    res = run("run", scene, "-o", out)  # the holder is gone: its stale lock is taken over
    assert res.exit_code == 0, res.output
    assert not (tmp_path / "r.nc.lock").exists()


@pytest.mark.slow
def test_concurrent_runs_on_one_output(tmp_path):
    (tmp_path / "scene.yaml").write_text(SCENE.replace("steps: 40, thermo: 20", "steps: 200000000, thermo: 20000"))
    out = tmp_path / "r.nc"
    cmd = [sys.executable, "-m", "wallbatch.cli", "run", "scene.yaml", "-o", str(out), "-j", "1"]
    # Ctrl-C as in a terminal: a test run started in the background (`cmd &` without job control)
    # ignores SIGINT, which its children inherit (as tests/batch/test_interrupt.py's runs)
    first = subprocess.Popen(cmd, cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                             preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    try:
        lock = tmp_path / "r.nc.lock"
        for _ in range(1200):
            if lock.exists() and lock.read_text().strip():
                break
            time.sleep(0.05)
        second = subprocess.run(cmd + ["--force"], cwd=tmp_path, capture_output=True, text=True, timeout=120)
        assert first.poll() is None, "the first run ended too early for the test"
        assert second.returncode == 2
        assert f"is being written by another wallbatch run (PID {first.pid}" in second.stderr
    finally:
        first.send_signal(signal.SIGINT)
        first.wait(timeout=60)


# ============================================================================================
# parts: damaged or foreign parts are reported and recomputed


@pytest.fixture
def sweep_parts(tmp_path):
    """A 4-case sweep, its reference results and a folder with every case's part."""
    p = sweep_file(tmp_path, """\
        sweep:
          product:
            eps: {path: walls.zwalls.zlo.epsilon, values: [0.5, 1.0, 1.5, 2.0]}
        """)
    plan = load_plan(p)
    out = tmp_path / "out.nc"
    saved = []
    ref = run_plan(plan, None, progress=False, on_result=lambda i, r: saved.append((i, r)))
    for i, res in saved:
        save_part(parts_dir(out), case_key(plan.cases[i]), res)
    return plan, out, ref


def test_damaged_and_foreign_parts_are_reported_and_recomputed(sweep_parts):
    plan, out, ref = sweep_parts
    parts = parts_dir(out)
    keys = [case_key(c) for c in plan.cases]
    data = (parts / f"{keys[0]}{PART_SUFFIX}").read_bytes()
    (parts / f"{keys[0]}{PART_SUFFIX}").write_bytes(data[: len(data) // 2])  # truncated
    flipped = bytearray((parts / f"{keys[1]}{PART_SUFFIX}").read_bytes())
    flipped[len(flipped) // 2] ^= 0x10  # one bit
    (parts / f"{keys[1]}{PART_SUFFIX}").write_bytes(bytes(flipped))
    (parts / f"{keys[2]}{PART_SUFFIX}").write_bytes(b"")  # empty
    # a placeholder, replaced below
    (parts / f"{keys[3]}{PART_SUFFIX}").write_bytes((parts / f"{keys[0]}{PART_SUFFIX}").read_bytes())
    # a part copied from another case: valid file, wrong case
    other = read_part(parts, keys[0])[0]
    assert other is None
    good = {}
    run_plan(plan, None, progress=False, on_result=lambda i, r: good.setdefault(i, r))
    save_part(parts, keys[0], good[0])
    # case 0's part under case 3's name
    os.replace(parts / f"{keys[0]}{PART_SUFFIX}", parts / f"{keys[3]}{PART_SUFFIX}")
    assert read_part(parts, keys[3]) == (None, "belongs to another case")
    assert read_part(parts, keys[2])[1].startswith("damaged")
    assert read_part(parts, keys[1])[1].startswith("damaged")
    notes: list[str] = []
    computed: list[int] = []
    ds = run_plan(plan, out, resume=True, progress=False, log=notes.append, on_result=lambda i, r: computed.append(i))
    assert sorted(computed) == [0, 1, 2, 3]
    note = next(n for n in notes if n.startswith("resuming:"))
    assert note.startswith(f"resuming: 0 of 4 case(s) reused from {parts}")
    assert "1 part(s) belongs to another case: recomputed" in note
    assert "part(s) damaged" in note
    for name in ("pe", "temp", "wall_force"):
        np.testing.assert_array_equal(ds[name].values, ref[name].values)


def test_bit_flip_in_data_is_caught_by_the_content_hash(sweep_parts):
    plan, out, _ = sweep_parts
    parts = parts_dir(out)
    key = case_key(plan.cases[1])
    res = read_part(parts, key)[0]
    digest = runner_mod._digest(key, res.status, res.error, res.seconds, res.data)  # the part's hash as saved
    res.data["pe"] = res.data["pe"].copy()
    res.data["pe"][1] += 1e-12  # a silently wrong number in a well-formed file that keeps the old hash
    (parts / f"{key}{PART_SUFFIX}").write_bytes(runner_mod.part_bytes(key, res, digest))
    assert read_part(parts, key) == (None, "damaged (content hash differs)")


# ============================================================================================
# a full disk


def test_disk_full_while_saving_a_part_keeps_the_others(sweep_parts, monkeypatch):
    plan, out, _ = sweep_parts
    import shutil

    shutil.rmtree(parts_dir(out))
    calls = {"n": 0}
    real = runner_mod._write_bytes

    def write(path, blob):
        calls["n"] += 1
        if calls["n"] == 3:  # the third part: half of it written, then the disk is full
            real(path, blob[: len(blob) // 2])
            raise OSError(28, "No space left on device")
        return real(path, blob)

    monkeypatch.setattr(runner_mod, "_write_bytes", write)
    with pytest.raises(RunError, match=r"cannot save a finished case in .*out\.nc\.parts: No space left on device; "
                                       r"free some space, then rerun with --resume"):
        run_plan(plan, out, jobs=1, progress=False)
    assert len(list(parts_dir(out).glob(f"*{PART_SUFFIX}"))) == 2  # the two saved before the disk filled
    assert not list(parts_dir(out).glob(".*"))  # no half-written temporary
    assert not out.with_name("out.nc.lock").exists()


def test_disk_full_while_writing_the_results_keeps_every_part(sweep_parts, monkeypatch):
    plan, out, _ = sweep_parts

    def full(ds, path):
        Path(str(path) + ".tmp").write_bytes(b"partial")
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(runner_mod, "write_netcdf", full)
    with pytest.raises(RunError) as info:
        run_plan(plan, out, resume=True, progress=False)
    assert str(info.value) == (f"cannot write {out}: No space left on device (disk full?); the 4 finished case(s) "
                               f"are kept in {parts_dir(out)}: free space or choose another -o, then rerun with "
                               f"--resume")
    assert len(list(parts_dir(out).glob(f"*{PART_SUFFIX}"))) == 4
    assert not Path(str(out) + ".tmp").exists() and not out.exists()


# ============================================================================================
# the top-level guard


@pytest.mark.slow
def test_unexpected_error_is_one_line_and_debug_shows_the_traceback(scene):
    code = ("import sys; import wallbatch.api as api\n"
            "def boom(*a, **k): raise RuntimeError('kaboom ' + 'x' * 500)\n"
            "api.check = boom\n"
            "from wallbatch.cli import app; sys.argv = ['wallbatch'] + sys.argv[1:]; app()")
    res = subprocess.run([sys.executable, "-c", code, "check", str(scene)], capture_output=True, text=True,
                         timeout=120)
    assert res.returncode == 3
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 2 and "Traceback" not in res.stderr
    assert lines[0].startswith("error: unexpected RuntimeError: kaboom xxx") and lines[0].endswith("...")
    assert len(lines[0]) < 260
    assert "please report it" in lines[1] and "--debug" in lines[1]
    res = subprocess.run([sys.executable, "-c", code, "--debug", "check", str(scene)], capture_output=True,
                         text=True, timeout=120)
    assert res.returncode == 1 and "Traceback" in res.stderr and "RuntimeError: kaboom" in res.stderr


def test_version():
    from wallbatch.version import __version__

    res = run("--version")
    assert res.exit_code == 0 and res.output.strip() == f"wallbatch {__version__}"


def test_show_on_a_foreign_netcdf(tmp_path):
    path = tmp_path / "foreign.nc"
    xr.Dataset({"t": ("x", np.arange(3.0))}).to_netcdf(path)
    res = run("show", path)
    assert res.exit_code == 2
    assert f"{path} is a NetCDF file but not a wallbatch results file" in res.output
    junk = tmp_path / "junk.nc"
    junk.write_text("hello")
    res = run("show", junk)
    assert res.exit_code == 2 and f"cannot open {junk}: not a NetCDF file, or a damaged one" in res.output
    assert "give the results file `wallbatch run -o` wrote" in res.output
    config = tmp_path / "scene.yaml"
    config.write_text("name: x\n")
    res = run("show", config)  # a config given where a results file belongs: say what to do with it
    assert res.exit_code == 2
    assert (f"this looks like a config: `wallbatch check {config}` checks it, `wallbatch run {config} -o scene.nc` "
            "writes a results file") in res.output


def test_an_unknown_or_missing_style_is_named_at_its_key(tmp_path):
    """A wall's style misspelled, or left out: pydantic's "Input tag 'lj39' found using 'style' does
    not match any of the expected tags" became one line at the style's value naming the styles; a
    wall without style also names the fix-line form."""
    head = ("box: {lo: [0,0,0], hi: [5,5,8], boundary: [p,p,f]}\n"
            "atoms: [{group: g, mass: 1, create: {random: {count: 10}}}]\n")
    p = tmp_path / "s.yaml"
    p.write_text(head + "walls: {w: {style: lj39, units: box, zlo: [EDGE, 1, 1, 2.5]}}\nrun: {steps: 10}\n")
    (msg,) = config_error(p)
    assert msg.startswith(f"{p}:3:20: walls.w.style: unknown style 'lj39': one of lj93, lj126, lj1043,"), msg
    p.write_text(head + "walls: {w: {units: box, zlo: [EDGE, 1, 1, 2.5]}}\nrun: {steps: 10}\n")
    (msg,) = config_error(p)
    assert msg == (f"{p}:3:12: walls.w: no style: give style: (see docs/reference/config.md) or fix: "
                   f"'fix ID group wall/STYLE ...' (a LAMMPS fix line)")


def test_output_written_as_a_folder_and_an_interrupt_with_nothing_saved(scene, tmp_path):
    """`-o out/` (a folder, by its slash) is refused before anything runs: a file named `out` was
    written. An interrupt before any case finished says there is nothing to resume (it pointed
    at a parts folder that does not exist)."""
    res = run("run", scene, "-o", f"{tmp_path}/out/")
    assert res.exit_code == 2 and not (tmp_path / "out").exists()
    assert f"-o {tmp_path}/out/: the results are one file, not a folder: give its name, e.g. {tmp_path}/out/scene.nc" \
        in res.output, res.output
    from wallbatch.batch.runner import Interrupted

    assert str(Interrupted(0, 50, tmp_path / "k.nc.parts")) == \
        "interrupted: 0/50 cases finished: nothing to resume, rerun to start again"
    assert str(Interrupted(3, 50, tmp_path / "k.nc.parts")) == \
        f"interrupted: 3/50 cases saved in {tmp_path / 'k.nc.parts'}; rerun with --resume"


@pytest.mark.parametrize("fields,text", [
    ("[]", "give the per-atom fields to write: [x], [v] or [x, v]"),
    ("[x, x]", "['x', 'x']: each field once ([x], [v] or [x, v])"),
])
def test_a_dump_without_fields_is_refused_at_its_key(tmp_path, fields, text):
    """`output.dump.fields: []` passed check and then failed the run with "unexpected ValueError:
    nothing to write ... a wallbatch bug"; now refused at the key, as a field named twice is."""
    path = tmp_path / "scene.yaml"
    path.write_text(SCENE + f"output:\n  dump: {{every: 10, fields: {fields}}}\n")
    (msg,) = config_error(path)
    assert msg.startswith(f"{path}:") and f"output.dump.fields: {text}" in msg, msg


def test_a_cylinder_with_lo_above_hi_is_refused_at_its_region(tmp_path):
    """A cylinder with lo > hi is empty: LAMMPS accepts it, and a wall/region on it (side out)
    then touches no atom, while wallbatch's contacts ignored the order (validate: every output
    differed). Refused at the region's line, like a block with lo > hi (decisions table)."""
    path = tmp_path / "scene.yaml"
    path.write_text(SCENE.replace("regions:\n", "regions:\n  rod: {style: cylinder, axis: z, center: [2, 2], "
                                  "radius: 1.0, lo: 7, hi: -1, side: out, units: box}\n", 1))
    (msg,) = config_error(path)
    assert msg.startswith(f"{path}:") and "regions.rod: a cylinder region needs lo <= hi along its axis: lo = 7 > " \
        "hi = -1 (an empty cylinder; LAMMPS accepts it and its wall then touches no atom): swap them" in msg, msg


def test_a_sweep_file_as_the_base_is_named_as_such(tmp_path):
    """A sweep file whose base is itself or another sweep file gave "box: Field required",
    "atoms: Field required", ... and "base: unknown key" at the base's line 1."""
    own = tmp_path / "own.yaml"
    own.write_text("base: own.yaml\nsweep:\n  replicas: 2\n")
    (msg,) = config_error(own)
    assert msg == (f"{own}:1:7: base: own.yaml is this sweep file itself, not a scene: give the scene config that "
                   f"the sweep varies (a sweep file's base is one scene file)")
    chained = tmp_path / "chained.yaml"
    chained.write_text("base: own.yaml\n")
    (msg,) = config_error(chained)
    assert msg.startswith(f"{chained}:1:7: base: own.yaml is a sweep file, not a scene")


def test_swept_wall_past_the_box_is_refused_at_its_sweep_line(tmp_path):
    """A lo face above the box's top (or a hi face below its bottom) puts every atom behind the
    wall: refused by `check` at the swept value, not a failure at step 0 of the run."""
    p = sweep_file(tmp_path, """\
        sweep:
          product:
            c: {path: walls.zwalls.zlo.coord, values: [0.0, 50.0]}
        """)
    (msg,) = config_error(p)
    assert msg == (f"{p}:4:47: walls.zwalls.zlo.coord: the zlo wall at 50 (box units) lies past the box (0 .. 10 "
                   "in z): every atom would be behind it; put it inside the box or use EDGE (case c=50.0)")
