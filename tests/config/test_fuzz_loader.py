"""Property-based fuzzing of the config loader (hypothesis): every shipped config and sweep file,
mutated at the text level (characters replaced, lines deleted, duplicated or swapped, YAML
tokens, tags, anchors, aliases, non-finite numbers and odd unicode inserted), goes through
`load_plan`, the function `check` and `run` start with. No input may escape as anything but the
project's ConfigError, and every problem it reports starts with its place: a file:line:col, a
file name, or the `--set` argument."""

from __future__ import annotations

import re
import shutil
from pathlib import Path

import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from wallbatch.config.source import ConfigError
from wallbatch.config.sweep import load_plan

ROOT = Path(__file__).resolve().parents[2]
SEEDS = sorted(p.relative_to(ROOT) for p in [*ROOT.glob("configs/*.yaml"), *ROOT.glob("sweeps/*.yaml")])
TOKENS = [": ", "- ", "[", "]", "{", "}", ",", "&a ", "*a", "!!python/object/apply:os.system ['true']", "!tag ",
          "? ", "\n", "\n  ", "\t", "#", "|", ">", "'", '"', ".inf", "-.inf", ".nan", "NaN", "1e308", "-1e308",
          "1e-320", "0", "-1", "99999999999999999999", "null", "~", "true", "v_x", "EDGE", "INF", "<<: *a",
          "\u00e9", "\u2028", "\ufeff", "0x1", "1:", "fix w all wall/lj93 zlo EDGE 1 1 2.5",
          "&a [1, *a]", "{path: run.steps, values: [1, 2]}", "linspace: [0, 1, 1000000]"]
LOCATED = re.compile(r"^(\S+\.ya?ml(:\d+:\d+)?: |\S+: |--set |\.\.\. and \d+ more)")


@pytest.fixture(scope="module")
def tree(tmp_path_factory) -> Path:
    """A copy of configs/ and sweeps/ (sweeps name their base as ../configs/...)."""
    root = tmp_path_factory.mktemp("fuzz")
    for folder in ("configs", "sweeps"):
        shutil.copytree(ROOT / folder, root / folder)
    return root


@st.composite
def mutated(draw) -> tuple[Path, str]:
    seed = draw(st.sampled_from(SEEDS))
    text = (ROOT / seed).read_text()
    for _ in range(draw(st.integers(1, 4))):
        lines = text.splitlines(keepends=True) or [""]
        kind = draw(st.sampled_from(["replace", "insert", "delete_line", "dup_line", "swap_lines", "chars"]))
        pos = draw(st.integers(0, max(0, len(text))))
        if kind == "replace":
            end = min(len(text), pos + draw(st.integers(0, 12)))
            text = text[:pos] + draw(st.sampled_from(TOKENS)) + text[end:]
        elif kind == "insert":
            text = text[:pos] + draw(st.sampled_from(TOKENS)) + text[pos:]
        elif kind == "chars":
            end = min(len(text), pos + draw(st.integers(0, 6)))
            text = text[:pos] + draw(st.text(max_size=6)) + text[end:]
        else:
            i = draw(st.integers(0, len(lines) - 1))
            j = draw(st.integers(0, len(lines) - 1))
            if kind == "delete_line":
                del lines[i]
            elif kind == "dup_line":
                lines.insert(i, lines[j])
            else:
                lines[i], lines[j] = lines[j], lines[i]
            text = "".join(lines)
    return seed, text


def _check(tree: Path, seed: Path, text: str) -> None:
    path = tree / seed.parent / "fuzz.yaml"
    path.write_text(text, encoding="utf-8", errors="surrogatepass")
    try:
        load_plan(path)
    except ConfigError as exc:
        assert exc.problems, "a ConfigError without a problem"
        for problem in exc.problems:
            assert LOCATED.match(problem), f"no location: {problem!r}\n--- input ---\n{text}"
            assert len(problem) < 3000, f"message of {len(problem)} characters"


@pytest.mark.slow
@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture,
                                                                   HealthCheck.too_slow], derandomize=True)
@given(case=mutated())
def test_mutated_configs_only_raise_located_config_errors(tree, case):
    seed, text = case
    _check(tree, seed, text)


@pytest.mark.slow
@settings(max_examples=1500, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture,
                                                                     HealthCheck.too_slow])
@given(case=mutated())
@example(case=(Path("sweeps/lepton-spring.yaml"),  # found 2026-11-28: a swept path inside another swept path
               "base: ../configs/lepton-slit.yaml\nsweep:\n  product:\n"
               "    k: {path: walls.soft.zlo.params, values: [10.0, 50.0, 250.0]}\n"
               "    rc: {path: walls.soft.zlo.params.rc, values: [1.0, 1.5]}\n"))
def test_mutated_configs_only_raise_located_config_errors_long(tree, case):
    seed, text = case
    _check(tree, seed, text)


PATHS = ["run.steps", "run.thermo", "walls.zwalls.zlo.epsilon", "walls.zwalls.zlo", "walls", "atoms.0.mass",
         "atoms.9.mass", "box.hi.2", "box.hi.7", "sweep", "seed", "", ".", "a..b", "walls.zwalls.zlo.cutoff.x",
         "variables.v", "atoms.-1.mass", "regions.slab.lo",
         # keys the file does not have, given whole (an error inside is located by walking the value)
         "output.profiles", "output", "fixes", "regions.new", "walls.new", "walls.zwalls.zlo.1", "run"]
# whole values with a mistake somewhere inside (bools for numbers, text for numbers, union members)
MAPPINGS = ["{rho: {axis: z, bins: x, every: 1, repeat: 1, freq: 1, quantities: [temp]}}",
            "{profiles: {rho: {axis: z, bins: true, every: 1, repeat: 1, freq: 1, quantities: [temp]}}}",
            "{nvt: {style: nvt, temp: [1, true], damp: x}}", "{style: block, lo: [0, 0, 1], hi: x, units: box}",
            "{style: lj93, zlo: [EDGE, 1, true, x]}", "{style: lj93, zlo: {coord: x}}",
            "{steps: 10, thermo: {every: x}}", "[x, {a: [true]}]", "{x: {y: {z: true}}}"]
UNION_MEMBER = re.compile(r"\.(?:float|int|str|bool|none|constrained-\w+|(?!None\b)[A-Z][A-Za-z0-9]*[a-z]\w*)(?:\.|: )")


@pytest.mark.slow
@settings(max_examples=80, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture],
          derandomize=True)
@given(path=st.sampled_from(PATHS), value=st.one_of(st.sampled_from(TOKENS), st.sampled_from(MAPPINGS),
                                                    st.text(max_size=12)),
       eq=st.sampled_from(["=", "", "=="]))
def test_mutated_set_arguments_only_raise_located_config_errors(tree, path, value, eq):
    try:
        load_plan(tree / "configs" / "lj93-slit.yaml", [f"{path}{eq}{value}"])
    except ConfigError as exc:
        for problem in exc.problems:
            assert LOCATED.match(problem), f"no location: {problem!r}"
            # a union member (pydantic's tag of one type of a union) is never shown as a key
            assert not UNION_MEMBER.search(problem), problem


SWEEP_VALUES = ["[1.0, 2.0]", "[2]", "[]", "{linspace: [0.5, 1.5, 3]}", "[[1, 2], [3, 4]]", "[null]", "[.nan]",
                "[{coord: EDGE, epsilon: 1, sigma: 1, cutoff: 2.5}]", "[fix w all wall/lj93 zlo EDGE 1 1 2.5]"]


# nested and equal paths first (hypothesis draws the first elements of a list most often)
SWEEP_PATHS = ["walls.zwalls.zlo", "walls.zwalls.zlo.epsilon", "walls", "atoms.0", "atoms.0.mass", *PATHS]


@pytest.mark.slow
@settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture],
          derandomize=True)
@given(entries=st.lists(st.tuples(st.sampled_from(SWEEP_PATHS), st.sampled_from(SWEEP_VALUES)), min_size=1,
                        max_size=3), zipped=st.booleans())
@example(entries=[("walls.zwalls.zlo", "[1.0, 2.0]"), ("walls.zwalls.zlo.epsilon", "[1.0, 2.0]")], zipped=False)
def test_sweep_entries_on_any_paths_only_raise_located_config_errors(tree, entries, zipped):
    """Sweeps of one to three entries on paths that may not exist, index lists out of range, or lie
    inside one another (a parent swept to a value and its child): every problem is located."""
    empty = '""'
    rows = [f"    e{k}: {{path: {p or empty}, values: {v}}}" for k, (p, v) in enumerate(entries)]
    body = ("  zip:\n    dim: z\n    params:\n" + "\n".join("  " + r for r in rows) if zipped
            else "  product:\n" + "\n".join(rows))
    _check(tree, Path("sweeps/x.yaml"), f"base: ../configs/lj93-slit.yaml\nsweep:\n{body}\n")
