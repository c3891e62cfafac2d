"""Property-based fuzzing of `wallbatch import-lammps` (hypothesis): the shipped example script
and a script with thermostats, regions and region walls, mutated at the text level (words
replaced by LAMMPS keywords, numbers and odd values, lines deleted, duplicated or swapped), go
through the importer. It either returns a config with what it could not import listed by line,
or stops with LammpsImportError naming the script; no other exception escapes."""

from __future__ import annotations

from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from wallbatch.config.source import ConfigError
from wallbatch.lammps.importer import LammpsImportError, import_lammps_text

ROOT = Path(__file__).resolve().parents[2]
THERMO = """units lj
boundary p p f
region box block 0 10 0 10 0 12 units box
create_box 2 box
region slab block INF INF INF INF 2 10 units box
region pore cylinder z 5 5 3 INF INF side in units box
create_atoms 1 random 200 4127 slab
create_atoms 2 single 5 5 6 units box
mass * 1.0
group hot type 2
velocity all create 1.5 87287 loop geom
fix 1 all nvt temp 1.0 1.0 0.5
fix 2 hot langevin 2.0 2.0 0.1 48279
fix w all wall/region pore lj93 1.0 1.0 2.5
fix r all wall/reflect zlo EDGE zhi EDGE
timestep 0.002
thermo 50
run 500
"""
SEEDS = [(ROOT / "examples" / "lammps" / "in.wall").read_text(), THERMO]
WORDS = ["", "0", "-1", "1e400", "nan", "INF", "-INF", "EDGE", "v_nope", "${x}", "$(1/0)", "all", "*", "2*", "1*2",
         "units", "box", "lattice", "zlo", "zhi", "xlo", "fix", "region", "group", "variable", "equal", "index",
         "include in.none", "read_data none.data", "create_atoms", "wall/lj93", "wall/reflect", "wall/region",
         "wall/table", "wall/lepton", "langevin", "nvt", "temp", "pair_style", "pair_coeff", "run", "minimize",
         "timestep", "dimension 2", "boundary f f f", "mass", "&", "#", "'", '"', "\u00e9"]


@st.composite
def mutated(draw) -> str:
    text = draw(st.sampled_from(SEEDS))
    for _ in range(draw(st.integers(1, 4))):
        lines = text.splitlines(keepends=True)
        kind = draw(st.sampled_from(["word", "insert", "delete", "dup", "swap"]))
        i = draw(st.integers(0, len(lines) - 1))
        if kind == "word":
            words = lines[i].split()
            if words:
                words[draw(st.integers(0, len(words) - 1))] = draw(st.sampled_from(WORDS))
                lines[i] = " ".join(words) + "\n"
        elif kind == "insert":
            words = lines[i].split()
            words.insert(draw(st.integers(0, len(words))), draw(st.sampled_from(WORDS)))
            lines[i] = " ".join(words) + "\n"
        elif kind == "delete":
            del lines[i]
        else:
            j = draw(st.integers(0, len(lines) - 1))
            if kind == "dup":
                lines.insert(i, lines[j])
            else:
                lines[i], lines[j] = lines[j], lines[i]
        text = "".join(lines)
    return text


@pytest.mark.slow
@settings(max_examples=150, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
@given(text=mutated())
def test_mutated_scripts_only_stop_with_a_located_import_error(tmp_path, text):
    try:
        result = import_lammps_text(text, tmp_path)
    except LammpsImportError as exc:
        assert str(exc).startswith(str(tmp_path / "in.script")), f"not located: {exc}\n--- script ---\n{text}"
        return
    except ConfigError as exc:  # a data file or include the importer reads on
        assert all(p.startswith(str(tmp_path)) for p in exc.problems), exc.problems
        return
    assert all(i.line >= 1 and i.reason for i in result.unsupported)
