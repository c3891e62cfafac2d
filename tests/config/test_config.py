"""Tests for wallbatch.config.models: the config language of shared/spec/config.md.

Valid configs: every way of writing a wall gives the same validated model. Bad configs: a
`ConfigError` whose message names `FILE:LINE:COL` of the offending value and its dotted path.
"""

from __future__ import annotations

import re

import pytest
import yaml

from wallbatch.config.models import (
    WALL_MODELS,
    Config,
    ReflectWall,
    SoftWall,
    config_from_dict,
    load_config,
    load_config_text,
)
from wallbatch.config.source import ConfigError, load_yaml

MorseWall = WALL_MODELS["morse"]

FILE = "cfg.yaml"

# A small valid scene: one atom in a box with a fixed z boundary. Walls are appended after it.
HEAD = """\
name: test-scene
box:
  lo: [0.0, 0.0, 0.0]
  hi: [10.0, 10.0, 12.0]
  boundary: [p, p, f]
atoms:
  - group: fluid
    create:
      positions: [[5.0, 5.0, 6.0]]
    mass: 1.0
variables:
  top: "12.0 - ramp(0.0, 2.0)"
run:
  steps: 10
"""


def scene(walls: str = "", extra: str = "") -> str:
    """HEAD, then `extra` top-level lines, then a `walls:` block holding `walls` (indented lines)."""
    text = HEAD + extra
    if walls:
        text += "walls:\n" + walls
    return text


def line_of(text: str, needle: str, nth: int = 1) -> int:
    """1-based number of the line holding the nth occurrence of `needle`."""
    hits = [i + 1 for i, line in enumerate(text.splitlines()) if needle in line]
    assert len(hits) >= nth, f"{needle!r} not found {nth} time(s) in the test config"
    return hits[nth - 1]


def col_of(text: str, needle: str, nth: int = 1) -> int:
    """1-based column of the nth line holding `needle`, where `needle` starts."""
    line = text.splitlines()[line_of(text, needle, nth) - 1]
    return line.index(needle) + 1


def config_error(text: str) -> ConfigError:
    with pytest.raises(ConfigError) as info:
        load_config_text(text, FILE)
    return info.value


def where(line: int, col: int | None = None) -> str:
    return f"{FILE}:{line}:" if col is None else f"{FILE}:{line}:{col}:"


def problem_at(err: ConfigError, line: int) -> str:
    """The one reported problem located on `line` (fails if there is none)."""
    hits = [p for p in err.problems if p.startswith(where(line))]
    assert hits, f"no problem reported at line {line}: {err.problems}"
    return hits[0]


# ============================================================================================
# valid configs


def test_minimal_scene_loads_with_the_written_values():
    cfg = load_config_text(HEAD, FILE)
    assert isinstance(cfg, Config)
    assert cfg.name == "test-scene"
    assert cfg.box.lo == (0.0, 0.0, 0.0)
    assert cfg.box.hi == (10.0, 10.0, 12.0)
    assert cfg.box.boundary == ("p", "p", "f")
    assert cfg.atoms[0].group == "fluid"
    assert cfg.atoms[0].create.positions == [(5.0, 5.0, 6.0)]
    assert cfg.atoms[0].mass == 1.0
    assert cfg.variables == {"top": "12.0 - ramp(0.0, 2.0)"}
    assert cfg.run.steps == 10


def test_defaults():
    text = scene(
        extra="lattice: {style: fcc, scale: 0.8442}\n",
        walls="  zw:\n    style: lj93\n    zlo: [EDGE, 1.0, 1.0, 2.5]\n"
        "  mirror:\n    style: reflect\n    zhi: EDGE\n",
    )
    cfg = load_config_text(text, FILE)
    assert cfg.units == "lj"
    assert cfg.seed == 0
    assert cfg.timestep is None  # the unit system's LAMMPS default is applied later
    assert cfg.pair is None and cfg.dt_reset is None and cfg.sweep is None
    wall = cfg.walls["zw"]
    assert wall.units == "lattice"  # as in LAMMPS
    assert wall.group == "all"
    assert wall.energy is False
    assert wall.virial is False
    assert wall.pbc is False
    assert cfg.walls["mirror"].frame == "lab"
    assert cfg.walls["mirror"].units == "lattice"
    assert cfg.run.thermo == 0
    assert cfg.run.time is None
    assert cfg.output.thermo == ["step", "time", "dt", "temp", "ke", "pe", "etot"]
    assert cfg.output.dump is None


def test_missing_name_defaults_and_box_boundary_defaults_to_periodic():
    text = HEAD.replace("name: test-scene\n", "").replace("  boundary: [p, p, f]\n", "")
    cfg = load_config_text(text, FILE)
    assert cfg.box.boundary == ("p", "p", "p")
    assert isinstance(cfg.name, str) and cfg.name


LJ126_TOP = {"coord": 12.0, "epsilon": 1.0, "sigma": 1.0, "cutoff": 2.5}


@pytest.mark.parametrize(
    "wall",
    [
        "  top:\n    style: lj126\n    units: box\n"
        "    zhi: {coord: 12.0, epsilon: 1.0, sigma: 1.0, cutoff: 2.5}\n",
        "  top:\n    style: lj126\n    units: box\n    zhi: [12.0, 1.0, 1.0, 2.5]\n",
        '  top: "fix top all wall/lj126 zhi 12.0 1.0 1.0 2.5 units box"\n',
        '  top: {fix: "fix top all wall/lj126 zhi 12.0 1.0 1.0 2.5 units box"}\n',
    ],
    ids=["mapping", "positional", "fix-line", "fix-mapping"],
)
def test_four_wall_forms_give_the_same_model(wall):
    cfg = load_config_text(scene(wall), FILE)
    top = cfg.walls["top"]
    assert isinstance(top, SoftWall)
    assert top.model_dump() == {
        "style": "lj126",
        "group": "all",
        "units": "box",
        "energy": False,
        "virial": False,
        "pbc": False,
        "cutoff_mode": "shift",
        "switch_on": None,
        "xlo": None,
        "xhi": None,
        "ylo": None,
        "yhi": None,
        "zlo": None,
        "zhi": LJ126_TOP,
    }
    assert [name for name, _ in top.faces()] == ["zhi"]


def test_fix_mapping_form_sets_wallbatch_keywords():
    text = scene('  top: {fix: "fix top all wall/lj126 zhi 12.0 1.0 1.0 2.5 units box", energy: true}\n')
    top = load_config_text(text, FILE).walls["top"]
    reference = load_config_text(
        scene("  top: {style: lj126, units: box, energy: true, zhi: [12.0, 1.0, 1.0, 2.5]}\n"), FILE
    ).walls["top"]
    assert top.energy is True
    assert top.model_dump() == reference.model_dump()
    assert top.zhi.model_dump() == LJ126_TOP


def test_fix_line_keeps_group_edge_variables_and_pbc():
    text = scene('  zw: "fix zw fluid wall/lj93 zhi v_top 2.0 1.5 2.5 xlo EDGE 1.0 1.0 2.5 units box pbc yes"\n')
    wall = load_config_text(text, FILE).walls["zw"]
    assert wall.style == "lj93"
    assert wall.group == "fluid"
    assert wall.pbc is True
    assert wall.units == "box"
    assert wall.zhi.model_dump() == {"coord": "v_top", "epsilon": 2.0, "sigma": 1.5, "cutoff": 2.5}
    assert wall.xlo.model_dump() == {"coord": "EDGE", "epsilon": 1.0, "sigma": 1.0, "cutoff": 2.5}
    assert [name for name, _ in wall.faces()] == ["zhi", "xlo"]


def test_variables_allowed_for_coord_and_parameters():
    text = scene(
        "  zw:\n    style: lj93\n    units: box\n"
        "    zhi: {coord: v_top, epsilon: v_top, sigma: v_top, cutoff: 2.5}\n"
    )
    face = load_config_text(text, FILE).walls["zw"].zhi
    assert face.model_dump() == {"coord": "v_top", "epsilon": "v_top", "sigma": "v_top", "cutoff": 2.5}


@pytest.mark.parametrize(
    "wall",
    [
        "  m:\n    style: morse\n    units: box\n    zlo: [EDGE, 2.0, 1.5, 1.2, 3.0]\n",
        "  m:\n    style: morse\n    units: box\n"
        "    zlo: {coord: EDGE, D0: 2.0, alpha: 1.5, r0: 1.2, cutoff: 3.0}\n",
        '  m: "fix m all wall/morse zlo EDGE 2.0 1.5 1.2 3.0 units box"\n',
    ],
    ids=["positional", "mapping", "fix-line"],
)
def test_morse_positional_order_is_coord_D0_alpha_r0_cutoff(wall):
    m = load_config_text(scene(wall), FILE).walls["m"]
    assert isinstance(m, MorseWall)
    assert m.zlo.model_dump() == {"coord": "EDGE", "D0": 2.0, "alpha": 1.5, "r0": 1.2, "cutoff": 3.0}


def test_morse_positional_with_lj_arity_is_an_error():
    text = scene("  m: {style: morse, units: box, zlo: [EDGE, 2.0, 1.5, 3.0]}\n")
    err = config_error(text)
    msg = problem_at(err, line_of(text, "m: {style: morse"))
    assert "walls.m" in msg
    assert "coord D0 alpha r0 cutoff" in msg


def test_harmonic_may_leave_out_sigma_in_the_mapping_form():
    text = scene("  h: {style: harmonic, units: box, zlo: {coord: EDGE, epsilon: 3.0, cutoff: 2.5}}\n")
    h = load_config_text(text, FILE).walls["h"]
    assert h.zlo.model_dump() == {"coord": "EDGE", "epsilon": 3.0, "sigma": None, "cutoff": 2.5}


def test_lj93_needs_sigma():
    text = scene("  w: {style: lj93, units: box, zlo: {coord: EDGE, epsilon: 1.0, cutoff: 2.5}}\n")
    err = config_error(text)
    msg = problem_at(err, line_of(text, "w: {style: lj93"))
    assert "walls.w" in msg and "sigma is required" in msg


def test_reflect_faces_bare_or_mapping():
    text = scene(
        "  mirrors:\n    style: reflect\n    units: box\n"
        "    zhi: EDGE\n    zlo: {coord: EDGE}\n    xlo: 1.5\n    xhi: v_top\n    pbc: true\n"
    )
    wall = load_config_text(text, FILE).walls["mirrors"]
    assert isinstance(wall, ReflectWall)
    assert [(name, face.coord) for name, face in wall.faces()] == [
        ("zhi", "EDGE"), ("zlo", "EDGE"), ("xlo", 1.5), ("xhi", "v_top"),
    ]


def test_reflect_fix_line_matches_mapping_form():
    mapped = load_config_text(scene("  r: {style: reflect, units: box, zhi: EDGE, zlo: {coord: 2.0}}\n"), FILE)
    lined = load_config_text(scene('  r: "fix r all wall/reflect zhi EDGE zlo 2.0 units box"\n'), FILE)
    assert mapped.walls["r"].model_dump() == lined.walls["r"].model_dump()
    assert [n for n, _ in lined.walls["r"].faces()] == ["zhi", "zlo"]


def test_reflect_face_takes_only_a_coord():
    text = scene("  r: {style: reflect, units: box, zlo: {coord: EDGE, epsilon: 1.0}}\n")
    err = config_error(text)
    msg = problem_at(err, line_of(text, "r: {style: reflect"))
    assert "walls.r.zlo.epsilon" in msg and "unknown key" in msg


@pytest.mark.parametrize("key", ["energy", "virial"])
@pytest.mark.parametrize("wall,fix", [
    ("{style: reflect, units: box, zlo: EDGE, KEY: true}", "wall/reflect"),
    ('{fix: "fix r all wall/reflect zlo EDGE units box", KEY: true}', "wall/reflect"),
    ("{style: reflect/stochastic, rstyle: diffusive, seed: 3, units: box, zlo: {coord: EDGE, temp: 1.0}, KEY: true}",
     "wall/reflect/stochastic"),
])
def test_reflecting_walls_refuse_energy_and_virial(wall, fix, key):
    """LAMMPS refuses fix_modify energy / virial on wall/reflect and wall/reflect/stochastic (they
    store no energy): so does the config, at the key, instead of dropping it silently; false is
    accepted (the default)."""
    text = scene(f"  r: {wall.replace('KEY', key)}\n")
    msg = problem_at(config_error(text), line_of(text, "  r: "))
    assert f"walls.r.{key}: {fix} has no {key}" in msg
    assert f"does not support fix_modify {key} command" in msg
    load_config_text(scene(f"  r: {wall.replace('KEY: true', key + ': false')}\n"), FILE)


@pytest.mark.parametrize(
    "order",
    [("zhi", "zlo", "xlo"), ("xlo", "zlo", "zhi"), ("zlo", "xlo", "zhi")],
)
def test_face_order_is_the_written_order(order):
    body = "".join(f"    {face}: [EDGE, 1.0, 1.0, 2.5]\n" for face in order)
    text = scene("  zw:\n    style: lj93\n    units: box\n    pbc: true\n" + body)
    wall = load_config_text(text, FILE).walls["zw"]
    assert [name for name, _ in wall.faces()] == list(order)


def test_wall_order_is_the_written_order():
    text = scene(
        "  zz: {style: harmonic, units: box, zlo: [EDGE, 1.0, 1.0, 2.5]}\n"
        "  aa: {style: lj93, units: box, zhi: [EDGE, 1.0, 1.0, 2.5]}\n"
        '  mm: "fix mm all wall/reflect zhi 11.5 units box"\n'
    )
    assert list(load_config_text(text, FILE).walls) == ["zz", "aa", "mm"]


def test_face_in_periodic_dimension_allowed_with_pbc():
    text = scene("  w: {style: lj93, units: box, pbc: true, xlo: [EDGE, 1.0, 1.0, 2.5]}\n")
    assert load_config_text(text, FILE).walls["w"].xlo.coord == "EDGE"


# --- numbers written like 1e-5 -------------------------------------------------------------


def test_plain_yaml_reads_1e_minus_5_as_text():
    # the reason for the rule: YAML 1.1 wants a dot in a float
    assert yaml.safe_load("a: 1e-5") == {"a": "1e-5"}


def test_load_yaml_reads_exponent_numbers_as_floats():
    data, _ = load_yaml("a: 1e-5\nb: 1E+3\nc: -2.5e-3\nd: 1.0e-5\ne: 3e2\nf: word\n", FILE)
    assert data == {"a": 1e-5, "b": 1000.0, "c": -2.5e-3, "d": 1e-5, "e": 300.0, "f": "word"}
    assert all(isinstance(data[k], float) for k in "abcde")


def test_1e_minus_5_is_a_number_everywhere_a_number_fits():
    text = scene(
        "  w:\n    style: lj93\n    units: box\n"
        "    zlo: {coord: 1e-5, epsilon: 1e-5, sigma: 1e0, cutoff: 2e0}\n"
        "    zhi: [1.2e1, 1e-5, 1e0, 25e-1]\n",
        extra="timestep: 1e-5\n"
        "dt_reset: {every: 10, tmin: 1e-5, tmax: 1e-2, xmax: 1e-1, units: box}\n",
    )
    cfg = load_config_text(text, FILE)
    assert cfg.timestep == 1e-5
    assert cfg.walls["w"].zlo.model_dump() == {"coord": 1e-5, "epsilon": 1e-5, "sigma": 1.0, "cutoff": 2.0}
    assert cfg.walls["w"].zhi.model_dump() == {"coord": 12.0, "epsilon": 1e-5, "sigma": 1.0, "cutoff": 2.5}
    assert (cfg.dt_reset.tmin, cfg.dt_reset.tmax, cfg.dt_reset.xmax) == (1e-5, 1e-2, 0.1)


def test_quoted_number_strings_are_numbers():
    text = scene('  w: {style: lj93, units: box, zlo: ["1e-5", "2.0", "1", "2.5"]}\n')
    assert load_config_text(text, FILE).walls["w"].zlo.model_dump() == {
        "coord": 1e-5, "epsilon": 2.0, "sigma": 1.0, "cutoff": 2.5,
    }


# --- dt_reset bounds ------------------------------------------------------------------------


@pytest.mark.parametrize(
    "written, value",
    [("INF", None), ("NULL", None), ("null", None), ("~", None), ("1.0e-5", 1e-5), ("1e-5", 1e-5),
     ("0.002", 0.002), ("0", 0.0)],
)
def test_dt_reset_tmin_accepts_inf_null_and_numbers(written, value):
    text = HEAD + f"dt_reset:\n  every: 10\n  tmin: {written}\n  xmax: 0.1\n  units: box\n"
    d = load_config_text(text, FILE).dt_reset
    assert d.tmin == value
    assert d.tmax is None  # default: no bound


@pytest.mark.parametrize(
    "written, value",
    [("INF", None), ("NULL", None), ("null", None), ("0.01", 0.01), ("1e-2", 0.01), ("3", 3.0)],
)
def test_dt_reset_tmax_accepts_inf_null_and_numbers(written, value):
    text = HEAD + f"dt_reset:\n  every: 5\n  tmax: {written}\n  xmax: 0.1\n  units: box\n"
    d = load_config_text(text, FILE).dt_reset
    assert d.tmax == value
    assert d.tmin is None
    assert (d.every, d.xmax, d.group, d.units) == (5, 0.1, "all", "box")


def test_dt_reset_defaults():
    text = HEAD + "lattice: {style: sc, scale: 1.0}\ndt_reset: {every: 10, xmax: 0.2}\n"
    d = load_config_text(text, FILE).dt_reset
    assert (d.tmin, d.tmax, d.emax, d.group, d.units) == (None, None, None, "all", "lattice")


def test_dt_reset_tmin_not_below_tmax():
    text = HEAD + "dt_reset: {every: 10, tmin: 0.1, tmax: 0.01, xmax: 0.1, units: box}\n"
    err = config_error(text)
    msg = problem_at(err, line_of(text, "dt_reset:"))
    assert "dt_reset" in msg and "tmin" in msg and "tmax" in msg


def test_dt_reset_bound_rejects_words():
    text = HEAD + "dt_reset: {every: 10, tmin: forever, xmax: 0.1, units: box}\n"
    err = config_error(text)
    msg = problem_at(err, line_of(text, "dt_reset:"))
    assert "dt_reset.tmin" in msg


# --- other entry points ---------------------------------------------------------------------


def test_load_config_reads_a_file_and_names_it(tmp_path):
    path = tmp_path / "scene.yaml"
    path.write_text(scene("  w: {style: lj93, units: box, zlo: [EDGE, 1.0, 1.0, 2.5]}\n"))
    cfg = load_config(path)
    assert cfg.walls["w"].zlo.cutoff == 2.5

    bad_text = scene("  w: {style: lj93, units: box, zlo: [EDGE, 1.0, 1.0, 2.5], bogus: 1}\n")
    path.write_text(bad_text)
    with pytest.raises(ConfigError) as info:
        load_config(path)
    assert f"{path}:{line_of(bad_text, 'bogus')}:" in str(info.value)
    assert "walls.w.bogus" in str(info.value)


def test_load_config_missing_file_is_a_config_error(tmp_path):
    path = tmp_path / "nope.yaml"
    with pytest.raises(ConfigError) as info:
        load_config(path)
    assert str(path) in str(info.value)
    assert "cannot read" in str(info.value)


def test_config_from_dict_validates_like_yaml():
    data = {
        "box": {"lo": [0, 0, 0], "hi": [10, 10, 12], "boundary": ["p", "p", "f"]},
        "atoms": [{"group": "g", "create": {"positions": [[5, 5, 6]]}, "mass": 1.0}],
        "walls": {"top": "fix top all wall/lj126 zhi 12.0 1.0 1.0 2.5 units box"},
        "timestep": "1e-5",
        "run": {"steps": 3},
    }
    cfg = config_from_dict(data)
    assert cfg.timestep == 1e-5
    assert cfg.walls["top"].zhi.model_dump() == LJ126_TOP


def test_config_from_dict_errors_name_the_path():
    data = {
        "box": {"lo": [0, 0, 0], "hi": [10, 10, 12], "boundary": ["p", "p", "f"]},
        "atoms": [{"group": "g", "create": {"positions": [[5, 5, 6]]}, "mass": 1.0}],
        "walls": {"w": {"style": "lj93", "units": "box", "zlo": {"coord": "EDGE", "epsilon": "abc",
                                                                  "sigma": 1.0, "cutoff": 2.5}}},
        "run": {"steps": 3},
    }
    with pytest.raises(ConfigError) as info:
        config_from_dict(data)
    assert str(info.value).startswith("<dict>: walls.w.zlo.epsilon: ")
    assert "'abc'" in str(info.value)


# ============================================================================================
# bad configs: FILE:LINE:COL, dotted path, a clear message


def test_unknown_key_in_a_face():
    text = scene(
        "  zw:\n    style: lj93\n    units: box\n"
        "    zlo: {coord: EDGE, epsilon: 1.0, sigmaa: 1.0, cutoff: 2.5}\n"
    )
    err = config_error(text)
    line = line_of(text, "sigmaa")
    col = col_of(text, "sigmaa: ") + len("sigmaa: ")  # the value
    assert str(err).startswith(where(line, col) + " walls.zw.zlo.sigmaa: ")
    assert "unknown key" in str(err)


def test_unknown_top_level_key():
    text = HEAD + "timestpe: 0.1\n"
    err = config_error(text)
    assert str(err).startswith(where(line_of(text, "timestpe")))
    assert "timestpe: unknown key" in str(err)


def test_unknown_wall_keyword():
    text = scene("  zw:\n    style: lj93\n    units: box\n    zlo: [EDGE, 1.0, 1.0, 2.5]\n    colour: red\n")
    err = config_error(text)
    assert where(line_of(text, "colour: red")) in str(err)
    assert "walls.zw.colour" in str(err) and "unknown key" in str(err)


def test_wrong_type():
    text = scene(
        "  zw:\n    style: lj93\n    units: box\n"
        "    zlo: {coord: EDGE, epsilon: abc, sigma: 1.0, cutoff: 2.5}\n"
    )
    err = config_error(text)
    line = line_of(text, "epsilon: abc")
    col = col_of(text, "abc")
    assert str(err).startswith(where(line, col) + " walls.zw.zlo.epsilon: ")
    assert "'abc'" in str(err) and "number" in str(err)


def test_wrong_type_top_level_number():
    text = HEAD + "timestep: fast\n"
    err = config_error(text)
    assert str(err).startswith(where(line_of(text, "timestep: fast"), col_of(text, "fast")) + " timestep: ")
    assert "number" in str(err)


def test_bad_boundary_letter():
    text = HEAD.replace("boundary: [p, p, f]", "boundary: [p, p, s]")
    err = config_error(text)
    assert where(line_of(text, "boundary:")) in str(err)
    assert "box.boundary.2" in str(err)


def test_missing_required_face_field_names_the_field():
    text = scene(
        "  zw:\n    style: lj93\n    units: box\n"
        "    zlo: {coord: EDGE, epsilon: 1.0, sigma: 1.0}\n"
    )
    err = config_error(text)
    assert str(err).startswith(where(line_of(text, "zlo:")))
    assert "walls.zw.zlo.cutoff" in str(err)
    assert "required" in str(err).lower()


def test_missing_required_top_level_field_names_it():
    text = HEAD.replace("run:\n  steps: 10\n", "")
    err = config_error(text)
    assert err.problems == [f"{FILE}:1:1: run: Field required"]


def test_positional_face_wrong_count():
    text = scene("  zw: {style: lj93, units: box, zlo: [EDGE, 1.0, 2.5]}\n")
    err = config_error(text)
    assert where(line_of(text, "zw:")) in str(err)
    assert "walls.zw" in str(err)
    assert "takes 4 values (coord epsilon sigma cutoff), got 3" in str(err)


def test_units_lattice_without_lattice():
    """A wall coordinate in lattice units (the default) needs a `lattice:`; a wall at EDGE alone has
    nothing to scale and is accepted."""
    load_config_text(scene("  zw: {style: lj93, zlo: [EDGE, 1.0, 1.0, 2.5]}\n"), FILE)
    text = scene("  zw: {style: lj93, zlo: [0.5, 1.0, 1.0, 2.5]}\n")
    err = config_error(text)
    assert len(err.problems) == 1
    msg = err.problems[0]
    assert msg.startswith(where(line_of(text, "zw:")))
    assert "walls.zw:" in msg
    assert "units: box" in msg and "lattice:" in msg


def test_units_lattice_with_lattice_is_fine():
    text = scene("  zw: {style: lj93, zlo: [EDGE, 1.0, 1.0, 2.5]}\n", extra="lattice: {style: fcc, scale: 0.8}\n")
    assert load_config_text(text, FILE).walls["zw"].units == "lattice"


def test_region_units_lattice_without_lattice():
    text = HEAD + "regions:\n  slab: {style: block, lo: [0, 0, 1], hi: [10, 10, 11]}\n"
    err = config_error(text)
    assert where(line_of(text, "slab:")) in str(err)
    assert "regions.slab.units" in str(err) and "units: box" in str(err)


def test_dt_reset_units_lattice_without_lattice():
    text = HEAD + "dt_reset: {every: 10, xmax: 0.1}\n"
    err = config_error(text)
    assert where(line_of(text, "dt_reset:")) in str(err)
    assert "dt_reset" in str(err) and "units: box" in str(err)


def test_face_in_periodic_dimension():
    text = scene("  zw:\n    style: lj93\n    units: box\n    xhi: [EDGE, 1.0, 1.0, 2.5]\n")
    err = config_error(text)
    msg = err.problems[0]
    assert msg.startswith(where(line_of(text, "xhi:"), col_of(text, "[EDGE")) + " walls.zw.xhi: ")
    assert "periodic" in msg and "pbc" in msg


def test_reflect_face_in_periodic_dimension():
    text = scene("  r: {style: reflect, units: box, ylo: EDGE}\n")
    err = config_error(text)
    assert where(line_of(text, "r: {style")) in str(err)
    assert "walls.r.ylo" in str(err) and "periodic" in str(err)


@pytest.mark.parametrize("cutoff", ["-2.5", "0", "0.0"])
def test_non_positive_cutoff(cutoff):
    text = scene(
        "  zw:\n    style: lj93\n    units: box\n"
        f"    zlo: {{coord: EDGE, epsilon: 1.0, sigma: 1.0, cutoff: {cutoff}}}\n"
    )
    err = config_error(text)
    line = line_of(text, "cutoff:")
    col = col_of(text, f"cutoff: {cutoff}") + len("cutoff: ")
    assert str(err).startswith(where(line, col) + " walls.zw.zlo.cutoff: ")
    assert "greater than 0" in str(err)


def test_non_positive_cutoff_positional_names_the_field():
    text = scene("  zw: {style: lj93, units: box, zlo: [EDGE, 1.0, 1.0, 0]}\n")
    err = config_error(text)
    assert where(line_of(text, "zw:")) in str(err)
    assert "walls.zw.zlo.cutoff" in str(err) or "walls.zw.zlo.3" in str(err)


def test_non_positive_cutoff_positional_is_an_error_at_its_element():
    text = scene("  zw: {style: lj93, units: box, zlo: [EDGE, 1.0, 1.0, 0]}\n")
    err = config_error(text)
    assert str(err).startswith(where(line_of(text, "zw:"), col_of(text, "1.0, 0]") + len("1.0, ")) + " walls.zw.zlo.cutoff")
    assert "greater than 0" in str(err)


def test_negative_epsilon():
    text = scene("  zw:\n    style: lj93\n    units: box\n    zlo: {coord: EDGE, epsilon: -1.0, sigma: 1.0, cutoff: 2.5}\n")
    err = config_error(text)
    assert where(line_of(text, "epsilon: -1.0")) in str(err)
    assert "walls.zw.zlo.epsilon" in str(err) and ">= 0" in str(err)


def test_face_defined_twice():
    text = scene(
        "  zw:\n    style: lj93\n    units: box\n"
        "    zlo: {coord: EDGE, epsilon: 1.0, sigma: 1.0, cutoff: 2.5}\n"
        "    zlo: {coord: 1.0, epsilon: 1.0, sigma: 1.0, cutoff: 2.5}\n"
    )
    err = config_error(text)
    first, second = line_of(text, "zlo:", 1), line_of(text, "zlo:", 2)
    assert err.problems == [
        f"{FILE}:{second}:5: walls.zw.zlo: defined twice (first at line {first}); keep one"
    ]


def test_top_level_key_defined_twice():
    text = HEAD + "run:\n  steps: 20\n"
    err = config_error(text)
    assert str(err).startswith(where(line_of(text, "run:", 2), 1) + " run: defined twice")


def test_face_twice_in_a_fix_line():
    text = scene('  zw: "fix zw all wall/lj93 zlo EDGE 1 1 2.5 zlo 1.0 1 1 2.5 units box"\n')
    err = config_error(text)
    assert where(line_of(text, "zw:")) in str(err)
    assert "'zlo'" in str(err) and "defined twice" in str(err)


def test_unknown_variable_in_a_wall():
    text = scene(
        "  zw:\n    style: lj93\n    units: box\n"
        "    zhi: {coord: v_nope, epsilon: 1.0, sigma: 1.0, cutoff: 2.5}\n"
    )
    err = config_error(text)
    line = line_of(text, "v_nope")
    assert err.problems == [
        f"{FILE}:{line}:{col_of(text, 'v_nope')}: walls.zw.zhi.coord: unknown variable v_nope "
        "(define it under variables:)"
    ]


def test_unknown_variable_as_a_parameter():
    text = scene("  zw:\n    style: lj93\n    units: box\n    zhi: {coord: 11.0, epsilon: v_eps, sigma: 1.0, cutoff: 2.5}\n")
    err = config_error(text)
    assert where(line_of(text, "v_eps"), col_of(text, "v_eps")) in str(err)
    assert "walls.zw.zhi.epsilon" in str(err) and "v_eps" in str(err)


def test_unknown_variable_inside_an_expression():
    text = HEAD.replace('  top: "12.0 - ramp(0.0, 2.0)"', '  top: "12.0 - v_zz"')
    err = config_error(text)
    assert where(line_of(text, "  top: ")) in str(err)
    assert "variables" in str(err) and "'top'" in str(err) and "v_zz" in str(err)


def test_variable_cycle():
    text = HEAD.replace('  top: "12.0 - ramp(0.0, 2.0)"\n', '  a: "v_b + 1"\n  b: "2 * v_a"\n')
    err = config_error(text)
    assert len(err.problems) == 1
    msg = err.problems[0]
    assert msg.startswith(where(line_of(text, "a: ")))
    assert "variables" in msg
    assert "cycle" in msg and "a -> b -> a" in msg


def test_variable_self_reference_is_a_cycle():
    text = HEAD.replace('"12.0 - ramp(0.0, 2.0)"', '"v_top + 1"')
    err = config_error(text)
    assert where(line_of(text, "  top: ")) in str(err)
    assert "cycle" in str(err) and "top -> top" in str(err)


def test_variable_syntax_error():
    text = HEAD.replace('"12.0 - ramp(0.0, 2.0)"', '"12.0 - * 2"')
    err = config_error(text)
    msg = err.problems[0]
    assert msg.startswith(where(line_of(text, "top:")))
    assert "variables" in msg and "'top'" in msg and "syntax error" in msg


def test_variable_syntax_error_points_at_the_bad_variable():
    text = HEAD.replace('  top: "12.0 - ramp(0.0, 2.0)"\n', '  ok: "1.0"\n  bad: "1 + * 2"\n')
    err = config_error(text)
    assert str(err).startswith(where(line_of(text, "bad:"))) and " variables.bad: " in str(err)


def test_unknown_group():
    text = scene("  zw:\n    style: lj93\n    group: fluidd\n    units: box\n    zlo: [EDGE, 1.0, 1.0, 2.5]\n")
    err = config_error(text)
    assert str(err).startswith(where(line_of(text, "fluidd"), col_of(text, "fluidd")) + " walls.zw.group: ")
    assert "unknown group 'fluidd'" in str(err)


def test_unknown_group_in_a_fix_line():
    text = scene('  zw: "fix zw fluidd wall/lj93 zlo EDGE 1.0 1.0 2.5 units box"\n')
    err = config_error(text)
    # the fix line is one YAML string: its location and path are the wall's own
    assert str(err).startswith(where(line_of(text, "zw:"), col_of(text, '"fix')) + " walls.zw")
    assert "unknown group 'fluidd'" in str(err)


def test_unknown_region_in_random_create():
    text = HEAD.replace("      positions: [[5.0, 5.0, 6.0]]", "      random: {count: 3, region: nowhere}")
    err = config_error(text)
    assert where(line_of(text, "nowhere")) in str(err)
    assert "atoms.0.create.random.region" in str(err) and "nowhere" in str(err)


def test_group_all_is_reserved():
    text = HEAD.replace("group: fluid", "group: all")
    err = config_error(text)
    assert where(line_of(text, "group: all")) in str(err)
    assert "atoms.0.group" in str(err) and "reserved" in str(err)


# --- LAMMPS fix lines -----------------------------------------------------------------------


def test_fix_line_unknown_word():
    text = scene('  top: "fix top all wall/lj126 zhi 12.0 1.0 1.0 2.5 units box bogus"\n')
    err = config_error(text)
    assert where(line_of(text, "  top: ", 2)) in str(err)
    assert "'bogus'" in str(err) and "word 12" in str(err)
    assert "unknown face or keyword" in str(err)


def test_fix_line_id_differs_from_key():
    text = scene('  top: "fix other all wall/lj126 zhi 12.0 1.0 1.0 2.5 units box"\n')
    err = config_error(text)
    assert where(line_of(text, "  top: ", 2)) in str(err)
    assert "'other'" in str(err) and "'top'" in str(err) and "mapping key" in str(err)


@pytest.mark.parametrize(
    "wall",
    [
        '  top: "fix top all wall/lj126 zhi 12.0 1.0 1.0 2.5 units box bogus"\n',
        '  top: "fix other all wall/lj126 zhi 12.0 1.0 1.0 2.5 units box"\n',
        '  top: {fix: "fix top all wall/lj126 zhi 12.0 1.0 1.0 2.5 units box bogus", energy: true}\n',
    ],
    ids=["unknown-word", "id-mismatch", "fix-mapping"],
)
def test_fix_line_error_names_its_own_wall(wall):
    text = scene("  first: {style: lj93, units: box, zlo: [EDGE, 1.0, 1.0, 2.5]}\n" + wall)
    err = config_error(text)
    assert where(line_of(text, "  top: ", 2)) in str(err)
    assert "walls.top" in str(err)


def test_fix_line_fld_yes_refused():
    text = scene('  top: "fix top all wall/lj126 zhi 12.0 1.0 1.0 2.5 units box fld yes"\n')
    err = config_error(text)
    assert where(line_of(text, "  top: ", 2)) in str(err)
    assert "fld yes" in str(err) and "not supported" in str(err) and "lubrication" in str(err)


def test_fix_line_fld_no_accepted():
    text = scene('  top: "fix top all wall/lj126 zhi 12.0 1.0 1.0 2.5 units box fld no"\n')
    top = load_config_text(text, FILE).walls["top"]
    assert top.zhi.model_dump() == LJ126_TOP


def test_fld_in_mapping_form_is_an_error():
    text = scene("  zw:\n    style: lj93\n    units: box\n    fld: yes\n    zlo: [EDGE, 1.0, 1.0, 2.5]\n")
    err = config_error(text)
    assert where(line_of(text, "fld: yes")) in str(err)
    assert "walls.zw.fld" in str(err)


def test_fld_in_mapping_form_says_not_supported():
    text = scene("  zw:\n    style: lj93\n    units: box\n    fld: yes\n    zlo: [EDGE, 1.0, 1.0, 2.5]\n")
    err = config_error(text)
    assert "not supported" in str(err) or "lubrication" in str(err)


def test_fix_line_unknown_style():
    text = scene('  w: "fix w all wall/lj94 zlo EDGE 1 1 2.5"\n')
    err = config_error(text)
    assert "'wall/lj94'" in str(err) and "unknown or unsupported fix style" in str(err)


def test_unknown_style_in_mapping_form():
    text = scene("  w: {style: lj94, units: box, zlo: [EDGE, 1.0, 1.0, 2.5]}\n")
    err = config_error(text)
    assert where(line_of(text, "w: {style")) in str(err)
    assert "walls.w" in str(err) and "'lj94'" in str(err)


# --- ellipsoids, regions, flow, pair: cross-field checks -----------------------------------


SCENE_ERRORS = {
    "flow-axis-fixed": (
        "",
        "  inflow:\n    style: flow\n    axis: z\n    vflow: 0.4\n    temperature: 1.5\n"
        "    seed: 593894\n    coords: [2.0, 4.0]\n    units: box\n",
        "axis: z", "walls.inflow.axis", "non-periodic boundary along the flow axis",
    ),
    "flow-order": (
        "",
        "  inflow:\n    style: flow\n    axis: x\n    vflow: 0.4\n    temperature: 1.5\n"
        "    seed: 593894\n    coords: [4.0, 2.0]\n    units: box\n",
        "coords:", "walls.inflow.coords", "strictly increasing",
    ),
    "flow-outside": (
        "",
        "  inflow:\n    style: flow\n    axis: x\n    vflow: 0.4\n    temperature: 1.5\n"
        "    seed: 593894\n    coords: [2.0, 10.0]\n    units: box\n",
        "coords:", "walls.inflow.coords", "inside the box",
    ),
    "flow-temperature": (
        "",
        "  inflow:\n    style: flow\n    axis: x\n    vflow: 0.4\n    temperature: 0.0\n"
        "    seed: 593894\n    coords: [2.0, 4.0]\n    units: box\n",
        "temperature: 0.0", "walls.inflow.temperature", "greater than 0",
    ),
    "ees-no-shape": ("", "  e:\n    style: ees\n    units: box\n    zlo: [EDGE, 1.0, 1.0, 2.5]\n", "group",
                     "walls.e.group", "requires ellipsoids"),
    "region-missing": (
        "",
        "  around:\n    style: region\n    region: ball\n    potential: lj93\n    epsilon: 1.0\n"
        "    sigma: 1.0\n    cutoff: 2.5\n",
        "region: ball", "walls.around.region", "unknown region 'ball'",
    ),
    "region-morse-params": (
        "regions:\n  ball: {style: sphere, center: [5, 5, 6], radius: 3.0, units: box}\n",
        "  around:\n    style: region\n    region: ball\n    potential: morse\n    epsilon: 1.0\n"
        "    sigma: 1.0\n    cutoff: 2.5\n",
        "style: region", "walls.around.D0", "needs D0",
    ),
    "region-ees-no-shape": (
        "regions:\n  ball: {style: sphere, center: [5, 5, 6], radius: 3.0, units: box}\n",
        "  around:\n    style: region/ees\n    region: ball\n    epsilon: 1.0\n    sigma: 1.0\n    cutoff: 2.5\n",
        "group", "walls.around.group", "requires ellipsoids",
    ),
    "region-colloid-no-radius": (
        "regions:\n  ball: {style: sphere, center: [5, 5, 6], radius: 3.0, units: box}\n",
        "  around:\n    style: region\n    region: ball\n    potential: colloid\n    epsilon: 1.0\n"
        "    sigma: 1.0\n    cutoff: 2.5\n",
        "group", "walls.around.group", "requires extended particles",
    ),
}


@pytest.mark.parametrize("case", list(SCENE_ERRORS), ids=list(SCENE_ERRORS))
def test_scene_errors_of_new_styles(case):
    extra, walls, needle, path, words = SCENE_ERRORS[case]
    text = scene(walls, extra=extra)
    err = config_error(text)  # a ConfigError, never a traceback of another type
    msg = "\n".join(err.problems)
    assert f" {path}" in msg and words in msg, msg
    if needle != "group":  # group defaults (not written): reported at the wall
        assert where(line_of(text, needle)) in msg


@pytest.mark.parametrize(
    "line, fid",
    [
        ("fix w all wall/flow x 0.4 1.5 593894 2 2.0 4.0 units box", "w"),
        ("fix w all wall/region ball lj93 1.0 1.0 2.5", "w"),
        ("fix w all wall/region/ees ball 1.0 1.0 2.5", "w"),
    ],
    ids=["flow", "region", "region-ees"],
)
def test_new_styles_as_fix_lines_validate(line, fid):
    extra = "regions:\n  ball: {style: sphere, center: [5, 5, 6], radius: 3.0, units: box}\n"
    text = scene(f'  {fid}: "{line}"\n', extra=extra).replace("mass: 1.0\n", "mass: 1.0\n    shape: [1.0, 0.5, 0.5]\n")
    cfg = load_config_text(text, FILE)
    assert cfg.walls[fid].style == line.split()[3].removeprefix("wall/") or cfg.walls[fid].style == "flow"


def test_orientation_needs_a_shape():
    text = HEAD.replace("    mass: 1.0\n", "    mass: 1.0\n    orientation: random\n")
    err = config_error(text)
    assert where(line_of(text, "orientation:")) in str(err)
    assert "atoms.0.orientation" in str(err) and "shape" in str(err)


def test_minimize_defaults_and_errors():
    cfg = load_config_text(scene("", "minimize: {style: fire}\n"), FILE)
    assert (cfg.minimize.style, cfg.minimize.etol, cfg.minimize.ftol, cfg.minimize.maxiter,
            cfg.minimize.maxeval, cfg.minimize.dmax) == ("fire", 1e-4, 1e-6, 1000, 10000, 0.1)
    text = scene("", "minimize: {style: sd, maxiter: 0}\n")
    err = config_error(text)
    assert "minimize.style" in str(err) and "minimize.maxiter" in str(err)


# --- box and run ----------------------------------------------------------------------------


def test_box_hi_not_above_lo():
    text = HEAD.replace("hi: [10.0, 10.0, 12.0]", "hi: [10.0, 0.0, 12.0]")
    err = config_error(text)
    assert len(err.problems) == 1
    assert err.problems[0].startswith(f"{FILE}:")
    assert "box.hi[1] = 0.0 must be greater than box.lo[1] = 0.0" in str(err)


def test_box_hi_not_above_lo_points_at_hi():
    text = HEAD.replace("hi: [10.0, 10.0, 12.0]", "hi: [10.0, 0.0, 12.0]")
    err = config_error(text)
    assert str(err).startswith(where(line_of(text, "hi: ["))) and " box.hi" in str(err)


def test_run_with_both_steps_and_time():
    text = HEAD.replace("run:\n  steps: 10\n", "run: {steps: 10, time: 1.0}\n")
    err = config_error(text)
    assert err.problems == [
        f"{FILE}:{line_of(text, 'run:')}:{col_of(text, '{steps')}: run: give exactly one of steps or time"
    ]


def test_run_with_neither_steps_nor_time():
    text = HEAD.replace("run:\n  steps: 10\n", "run: {thermo: 5}\n")
    err = config_error(text)
    assert where(line_of(text, "run:")) in str(err)
    assert "run: give exactly one of steps or time" in str(err)


def test_time_sampling_needs_a_time_run():
    text = HEAD.replace("run:\n  steps: 10\n", "run:\n  steps: 10\n  thermo: {time: 0.5}\n")
    err = config_error(text)
    assert where(line_of(text, "thermo:"), col_of(text, "{time")) in str(err)
    assert "run.thermo" in str(err)


def test_unknown_thermo_keyword():
    text = HEAD + "output:\n  thermo: [step, temp, bogus]\n"
    err = config_error(text)
    assert where(line_of(text, "thermo:")) in str(err)
    assert "output.thermo.2" in str(err)


# --- several problems at once -----------------------------------------------------------------


def test_several_model_errors_all_reported():
    text = scene(
        "  zw:\n    style: lj93\n    units: box\n"
        "    zlo: {coord: EDGE, epsilon: abc, sigma: 1.0, cutoff: 2.5}\n"
        "    zhi: {coord: 12.0, epsilon: 1.0, sigmaa: 1.0, cutoff: 2.5}\n",
        extra="timestep: -0.5\nseed: -3\n",
    )
    err = config_error(text)
    assert len(err.problems) == 4, err.problems
    assert "walls.zw.zlo.epsilon" in problem_at(err, line_of(text, "epsilon: abc"))
    assert "walls.zw.zhi.sigmaa: unknown key" in problem_at(err, line_of(text, "sigmaa"))
    assert "timestep: Input should be greater than 0" in problem_at(err, line_of(text, "timestep:"))
    assert " seed: " in problem_at(err, line_of(text, "seed:"))
    assert str(err) == "\n".join(err.problems)


def test_several_scene_errors_all_reported():
    text = scene(
        "  a: {style: lj93, units: box, group: nobody, zlo: [EDGE, 1.0, 1.0, 2.5]}\n"
        "  b: {style: lj93, units: box, xlo: [EDGE, 1.0, 1.0, 2.5]}\n"
        "  c: {style: harmonic, units: box, zhi: {coord: v_nope, epsilon: 1.0, cutoff: 2.5}}\n"
        "  d: {style: lj93, zlo: [0.5, 1.0, 1.0, 2.5]}\n"
    )
    err = config_error(text)
    assert len(err.problems) == 4, err.problems
    assert "walls.a.group: unknown group 'nobody'" in problem_at(err, line_of(text, "  a: {"))
    assert "walls.b.xlo: cannot use a xlo wall in periodic x dimension" in problem_at(err, line_of(text, "  b: {"))
    assert "walls.c.zhi.coord: unknown variable v_nope" in problem_at(err, line_of(text, "  c: {"))
    assert "walls.d: units: lattice" in problem_at(err, line_of(text, "  d: {"))


# --- YAML itself ------------------------------------------------------------------------------


def test_yaml_syntax_error_reports_file_and_line():
    text = HEAD.replace("run:\n  steps: 10\n", "run:\n  steps: 10\n   thermo: 5\n")
    err = config_error(text)
    assert len(err.problems) == 1
    assert err.problems[0].startswith(where(line_of(text, "thermo: 5")))
    assert "YAML syntax error" in err.problems[0]


def test_yaml_unclosed_flow_mapping_reports_file_and_line():
    text = HEAD + "output: {thermo: [step, temp]\nseed: 3\n"
    err = config_error(text)
    assert re.match(rf"{re.escape(FILE)}:{line_of(text, 'seed: 3')}:\d+: YAML syntax error", str(err))


def test_empty_file():
    err = config_error("")
    assert str(err) == f"{FILE}: the file is empty"


def test_top_level_not_a_mapping():
    err = config_error("- 1\n- 2\n")
    assert str(err).startswith(f"{FILE}:1:1: (top level): ")


def test_time_run_with_step_thermo_is_an_error():
    text = scene("").replace("run:\n  steps: 10\n", "run: {time: 1.0, thermo: 10}\n")
    err = config_error(text)
    assert "run.thermo" in str(err) and "thermo: {time: INTERVAL}" in str(err)


def test_dump_needs_a_step_based_run():
    text = scene("", "output:\n  dump: {every: 10, fields: [x]}\n").replace(
        "run:\n  steps: 10\n", "run: {time: 1.0}\n")
    err = config_error(text)
    assert "output.dump" in str(err) and "step-based run" in str(err)




# --- region walls and regions ---------------------------------------------------------------

REGION = "regions:\n  ball: {style: sphere, center: [5, 5, 6], radius: 4, units: box}\n"


@pytest.mark.parametrize("wall, key, needle", [
    ("{style: region, region: ball, potential: ees, epsilon: 1, sigma: 1, cutoff: 2.5}", "potential", "ees"),
    ("{style: region, region: ball, potential: lj93, epsilon: x, sigma: 1, cutoff: 2.5}", "epsilon", "x,"),
])
def test_region_wall_error_names_its_key_not_the_region(wall, key, needle):
    # `region` is both the wall's style (pydantic's union tag) and a key of the wall: the error
    # was reported as walls.w.region.KEY at the region's name
    text = scene(f"  w: {wall}\n", REGION)
    err = config_error(text)
    assert str(err).startswith(where(line_of(text, "  w: "), col_of(text, needle)) + f" walls.w.{key}:")


def test_region_wall_missing_key_is_named_at_the_wall():
    text = scene("  w: {style: region, region: ball, potential: lj93, epsilon: 1, sigma: 1}\n", REGION)
    err = config_error(text)
    at = where(line_of(text, "  w: "), col_of(text, "{style: region"))
    assert str(err).startswith(at + " walls.w.cutoff: Field required")


def test_region_wall_unknown_region_still_at_the_region_key():
    text = scene("  w: {style: region, region: nope, potential: lj93, epsilon: 1, sigma: 1, cutoff: 2.5}\n", REGION)
    err = config_error(text)
    at = where(line_of(text, "  w: "), col_of(text, "nope"))
    assert str(err).startswith(at + " walls.w.region: unknown region 'nope'")


def test_block_region_lo_above_hi_is_refused():
    # LAMMPS: "Illegal region block xlo: 6 >= xhi: 4"; an empty block made a region wall fail every atom
    text = scene(extra="regions:\n  b: {style: block, lo: [6, 1, 1], hi: [4, 9, 9], units: box}\n")
    err = config_error(text)
    assert str(err).startswith(where(line_of(text, "  b: ")) )
    assert "regions.b: a block region needs lo <= hi on every axis: xlo = 6 > xhi = 4" in str(err)
    ok = scene(extra="regions:\n  b: {style: block, lo: [4, 1, 1], hi: [4, 9, INF], units: box}\n")
    load_config_text(ok, FILE)
