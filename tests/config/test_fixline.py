"""Tests for wallbatch.config.fixline: LAMMPS wall fix lines <-> the wall mapping form."""

from __future__ import annotations

import re

import pytest

from wallbatch.config.fixline import FLAT_STYLES, SUPPORTED_STYLES, FixLineError, parse_fix_line, to_fix_line

# --------------------------------------------------------------------------------------------
# output forms


def test_config_md_example_line():
    line = "fix top all wall/lj126 zhi 20.0 1.0 1.0 2.5 units box"
    assert parse_fix_line(line, "top") == {
        "style": "lj126",
        "group": "all",
        "zhi": {"coord": 20.0, "epsilon": 1.0, "sigma": 1.0, "cutoff": 2.5},
        "units": "box",
    }


def test_flat_lj93_two_faces_edge_variable_and_keywords():
    line = "fix zwalls fluid wall/lj93 zlo EDGE 1.0 1.0 2.5 zhi v_top 1 v_s 2.5 units box pbc yes"
    out = parse_fix_line(line, "zwalls")
    assert out == {
        "style": "lj93",
        "group": "fluid",
        "zlo": {"coord": "EDGE", "epsilon": 1.0, "sigma": 1.0, "cutoff": 2.5},
        "zhi": {"coord": "v_top", "epsilon": 1.0, "sigma": "v_s", "cutoff": 2.5},
        "units": "box",
        "pbc": True,
    }
    assert list(out)[:4] == ["style", "group", "zlo", "zhi"]
    assert all(isinstance(v, float) for v in (out["zlo"]["epsilon"], out["zhi"]["cutoff"]))


def test_face_order_is_kept():
    out = parse_fix_line("fix w all wall/lj93 zhi 10 1 1 2.5 xlo 0 1 1 2.5 units box", "w")
    assert [k for k in out if k.endswith(("lo", "hi"))] == ["zhi", "xlo"]


@pytest.mark.parametrize("style", ["lj93", "lj126", "lj1043", "colloid", "harmonic", "ees"])
def test_flat_styles_with_epsilon_sigma(style):
    out = parse_fix_line(f"fix w all wall/{style} xlo -1.5 2 0.5 3e0", "w")
    assert out == {
        "style": style,
        "group": "all",
        "xlo": {"coord": -1.5, "epsilon": 2.0, "sigma": 0.5, "cutoff": 3.0},
    }


def test_morse_face_keys_and_variables():
    out = parse_fix_line("fix m all wall/morse ylo 0.0 v_d v_a v_r 4.0 yhi 10 1 2 1.1 4 units lattice", "m")
    assert out == {
        "style": "morse",
        "group": "all",
        "ylo": {"coord": 0.0, "D0": "v_d", "alpha": "v_a", "r0": "v_r", "cutoff": 4.0},
        "yhi": {"coord": 10.0, "D0": 1.0, "alpha": 2.0, "r0": 1.1, "cutoff": 4.0},
        "units": "lattice",
    }


def test_scientific_numbers_are_floats():
    out = parse_fix_line("fix w all wall/lj93 xlo 1e-5 1E2 .5 2.5e+0", "w")
    assert out["xlo"] == {"coord": 1e-5, "epsilon": 100.0, "sigma": 0.5, "cutoff": 2.5}
    assert all(type(v) is float for v in out["xlo"].values())


def test_pbc_no_kept_and_fld_no_dropped():
    out = parse_fix_line("fix w all wall/lj93 xlo 0 1 1 2.5 fld no pbc no", "w")
    assert out["pbc"] is False
    assert "fld" not in out


def test_repeated_keyword_last_wins_as_lammps():
    out = parse_fix_line("fix w all wall/lj93 xlo 0 1 1 2.5 units box units lattice", "w")
    assert out["units"] == "lattice"


def test_trailing_comment_and_extra_whitespace_are_ignored():
    line = "  fix top   all\twall/lj126 zhi 20.0 1.0 1.0 2.5   units box  # the lid"
    assert parse_fix_line(line, "top") == parse_fix_line(
        "fix top all wall/lj126 zhi 20.0 1.0 1.0 2.5 units box", "top"
    )
    # a comment may also touch the last word
    assert parse_fix_line("fix r all wall/reflect xlo EDGE#mirror", "r") == {
        "style": "reflect",
        "group": "all",
        "xlo": "EDGE",
    }


def test_quoted_words():
    out = parse_fix_line("fix w all 'wall/lj93' \"zlo\" EDGE 1 1 2.5", "w")
    assert out["style"] == "lj93" and "zlo" in out


def test_reflect():
    out = parse_fix_line("fix mirrors all wall/reflect xlo EDGE xhi 10.0 ylo v_y units box", "mirrors")
    assert out == {
        "style": "reflect",
        "group": "all",
        "xlo": "EDGE",
        "xhi": 10.0,
        "ylo": "v_y",
        "units": "box",
    }


def test_flow_physics_seed_line():
    out = parse_fix_line("fix 1 all wall/flow x 0.4 1.5 593894 4 2.0 4.0 6.0 8.0", "1")
    assert out == {
        "style": "flow",
        "group": "all",
        "axis": "x",
        "vflow": 0.4,
        "temperature": 1.5,
        "seed": 593894,
        "coords": [2.0, 4.0, 6.0, 8.0],
    }
    assert type(out["seed"]) is int
    assert all(type(c) is float for c in out["coords"])


def test_flow_config_example_with_units():
    out = parse_fix_line("fix inflow all wall/flow x 0.4 1.5 593894 4 2 4 6 8 units box", "inflow")
    assert out == {
        "style": "flow",
        "group": "all",
        "axis": "x",
        "vflow": 0.4,
        "temperature": 1.5,
        "seed": 593894,
        "coords": [2.0, 4.0, 6.0, 8.0],
        "units": "box",
    }


def test_flow_range_checks_are_left_to_the_models():
    # vflow <= 0, T <= 0, seed <= 0 and unordered walls are the validators' business
    out = parse_fix_line("fix f all wall/flow z -0.4 0 0 2 8.0 2.0", "f")
    assert out["vflow"] == -0.4 and out["temperature"] == 0.0 and out["seed"] == 0
    assert out["coords"] == [8.0, 2.0]


def test_region_lj93_config_example():
    out = parse_fix_line("fix around all wall/region ball lj93 1.0 1.0 2.5", "around")
    assert out == {
        "style": "region",
        "group": "all",
        "region": "ball",
        "potential": "lj93",
        "epsilon": 1.0,
        "sigma": 1.0,
        "cutoff": 2.5,
    }


@pytest.mark.parametrize("potential", ["lj93", "lj126", "lj1043", "colloid", "harmonic"])
def test_region_potentials(potential):
    out = parse_fix_line(f"fix a g1 wall/region pipe {potential} 2 0.5 1.5", "a")
    assert out == {
        "style": "region",
        "group": "g1",
        "region": "pipe",
        "potential": potential,
        "epsilon": 2.0,
        "sigma": 0.5,
        "cutoff": 1.5,
    }


def test_region_morse():
    out = parse_fix_line("fix a all wall/region ball morse 1.0 2.0 1.1 3.0", "a")
    assert out == {
        "style": "region",
        "group": "all",
        "region": "ball",
        "potential": "morse",
        "D0": 1.0,
        "alpha": 2.0,
        "r0": 1.1,
        "cutoff": 3.0,
    }


def test_region_ees():
    out = parse_fix_line("fix e all wall/region/ees ball 1.0 1.0 2.5", "e")
    assert out == {
        "style": "region/ees",
        "group": "all",
        "region": "ball",
        "epsilon": 1.0,
        "sigma": 1.0,
        "cutoff": 2.5,
    }


# --------------------------------------------------------------------------------------------
# round trips

ROUND_TRIP_LINES = [
    *(f"fix w all wall/{s} zlo EDGE 1.0 1.0 2.5 zhi v_top 0.5 v_s 2.5 units box" for s in FLAT_STYLES if s != "morse"),
    "fix w all wall/lj93 xlo 1e-05 1.0 1.0 2.5 pbc yes",
    "fix w all wall/lj93 xhi 3.0 1.0 1.0 2.5 units lattice pbc no",
    "fix w all wall/morse zhi 12.0 1.0 v_a 1.1 4.0 xlo EDGE v_d 2.0 v_r 4.0",
    "fix w g wall/reflect xlo EDGE xhi 10.0 zlo v_z units box",
    "fix w all wall/reflect ylo -2.5",
    "fix w all wall/flow x 0.4 1.5 593894 4 2.0 4.0 6.0 8.0",
    "fix w all wall/flow y 0.4 1.5 7 1 5.0 units lattice",
    "fix w all wall/region ball lj93 1.0 1.0 2.5",
    "fix w all wall/region ball colloid 1.0 1.0 2.5",
    "fix w all wall/region ball harmonic 1.0 1.0 2.5",
    "fix w all wall/region pipe morse 1.0 2.0 1.1 3.0",
    "fix w all wall/region/ees ball 1.0 1.0 2.5",
    'fix w all wall/lepton zlo EDGE "k*(r-rc)^2; k=100.0; rc=4.0" 4.0 zhi v_top "exp(-r)" 2.5 units box',
    "fix w all wall/table spline 500 zlo EDGE walls.table LJ93 2.5 xhi 3.0 t.table HARM 2.0 pbc yes",
    "fix w all wall/reflect/stochastic diffusive 23424 zlo EDGE 300.0 0.1 0.1 0.0 zhi EDGE 200.0 0.1 0.1 0.0",
    "fix w all wall/reflect/stochastic maxwell 3 ylo 5.0 1.0 0.1 0.0 0.0 0.8 units box",
    "fix w all wall/reflect/stochastic ccl 2 xlo 0.0 300.0 0.0 0.1 0.0 0.9 0.8 0.7 xhi EDGE 1.5 0.0 0.1 0.0 0.9 0.8 0.7",
]


@pytest.mark.parametrize("line", ROUND_TRIP_LINES)
def test_round_trip(line):
    wall = parse_fix_line(line, "w")
    again = to_fix_line("w", wall)
    assert again == line
    assert parse_fix_line(again, "w") == wall


def test_every_style_has_a_round_trip_case():
    styles = {line.split()[3] for line in ROUND_TRIP_LINES}
    assert styles == set(SUPPORTED_STYLES)


def test_to_fix_line_accepts_other_mapping_shapes():
    wall = {
        "style": "lj93",
        "units": "box",
        "energy": True,  # fix_modify setting: not part of the fix line
        "virial": False,
        "zlo": {"coord": "EDGE", "epsilon": 1.0, "sigma": 1.0, "cutoff": 2.5},
        "zhi": ["v_top", 1.0, 1.0, 2.5],
    }
    assert to_fix_line("zwalls", wall) == (
        "fix zwalls all wall/lj93 zlo EDGE 1.0 1.0 2.5 zhi v_top 1.0 1.0 2.5 units box"
    )
    mirrors = {"style": "reflect", "xlo": "EDGE", "xhi": {"coord": "EDGE"}, "frame": "lab"}
    assert to_fix_line("mirrors", mirrors) == "fix mirrors all wall/reflect xlo EDGE xhi EDGE"
    flow = {"style": "flow", "axis": "x", "vflow": 0.4, "temperature": 1.5, "seed": 593894,
            "coords": [2, 4, 6, 8], "units": "box", "rule": "exact"}
    assert to_fix_line("inflow", flow) == "fix inflow all wall/flow x 0.4 1.5 593894 4 2 4 6 8 units box"
    # numbers that YAML read as text
    assert to_fix_line("w", {"style": "lj93", "xlo": [0, "1e-5", 1, 2.5]}) == (
        "fix w all wall/lj93 xlo 0 1e-05 1 2.5"
    )


def test_to_fix_line_harmonic_without_sigma():
    line = to_fix_line("h", {"style": "harmonic", "xlo": {"coord": 0.0, "epsilon": 2.0, "cutoff": 1.5}})
    assert line == "fix h all wall/harmonic xlo 0.0 2.0 1.0 1.5"
    line = to_fix_line("h", {"style": "region", "region": "b", "potential": "harmonic",
                             "epsilon": 2.0, "cutoff": 1.5})
    assert line == "fix h all wall/region b harmonic 2.0 1.0 1.5"


def test_to_fix_line_from_fix_entry():
    line = "fix top all wall/lj126 zhi 20.0 1.0 1.0 2.5 units box"
    assert to_fix_line("top", {"fix": line, "energy": True}) == line


@pytest.mark.parametrize(
    "wall, match",
    [
        ({"style": "lj93"}, "no faces"),
        ({"style": "lj93", "xlo": [0, 1, 1]}, "expected 4 values"),
        ({"style": "lj93", "xlo": {"coord": 0, "epsilon": 1, "sigma": 1}}, "missing cutoff"),
        ({"style": "lj93", "xlo": [0, 1, 1, "v_rc"]}, "cutoff: expected a number"),
        ({"style": "lj93", "xlo": [0, 1, 1, 2.5], "units": "metres"}, "units"),
        ({"style": "lj93", "xlo": [0, 1, 1, 2.5], "fld": True}, "fld"),
        ({"style": "lj93", "xlo": [0, 1, 1, 2.5], "colour": "red"}, "colour"),
        ({"style": "wiggle"}, "unknown style"),
        ({"style": "flow", "axis": "x", "vflow": 1, "temperature": 1, "seed": 1.5, "coords": [1]}, "seed"),
        ({"style": "region", "region": "b", "potential": "ees", "epsilon": 1, "sigma": 1, "cutoff": 1},
         "potential"),
    ],
)
def test_to_fix_line_errors(wall, match):
    with pytest.raises(ValueError, match=match):
        to_fix_line("w", wall)


# --------------------------------------------------------------------------------------------
# errors: each names the word and its 1-based position


def _error(line: str, fix_id: str = "w") -> FixLineError:
    with pytest.raises(FixLineError) as info:
        parse_fix_line(line, fix_id)
    err = info.value
    assert isinstance(err, ValueError)
    return err


def _assert_word(err: FixLineError, position: int, word: str) -> None:
    msg = str(err)
    assert msg.startswith(f"word {position} {word!r}: "), msg
    assert err.position == position and err.word == word


def test_error_not_starting_with_fix():
    err = _error("fox w all wall/lj93 xlo 0 1 1 2.5")
    _assert_word(err, 1, "fox")
    assert "must start with 'fix'" in str(err)


def test_error_empty_line():
    with pytest.raises(FixLineError, match="empty fix line"):
        parse_fix_line("   # only a comment", "w")


def test_error_unclosed_quote():
    with pytest.raises(FixLineError, match="quote"):
        parse_fix_line("fix w all 'wall/lj93 xlo 0 1 1 2.5", "w")


def test_error_id_mismatch():
    err = _error("fix bottom all wall/lj93 zlo EDGE 1 1 2.5", "top")
    _assert_word(err, 2, "bottom")
    assert "'top'" in str(err) and "mapping key" in str(err) and "fix top" in str(err)


@pytest.mark.parametrize(
    "line, position, word, text",
    [
        ("fix", 1, "fix", "missing fix ID"),
        ("fix w", 2, "w", "missing group-ID"),
        ("fix w all", 3, "all", "missing wall style"),
    ],
)
def test_error_truncated_head(line, position, word, text):
    err = _error(line)
    _assert_word(err, position, word)
    assert text in str(err)


def test_error_bad_group_id():
    err = _error("fix w a-b wall/lj93 xlo 0 1 1 2.5")
    _assert_word(err, 3, "a-b")
    assert "group-ID" in str(err)


@pytest.mark.parametrize("style", ["wall/piston", "wall/lj93/kk", "nve", "wall/gran"])
def test_error_unknown_style_lists_supported(style):
    err = _error(f"fix w all {style} xlo 0 1 1 2.5")
    _assert_word(err, 4, style)
    msg = str(err)
    assert "unknown or unsupported fix style" in msg
    for supported in SUPPORTED_STYLES:
        assert supported in msg


def test_error_unknown_keyword():
    err = _error("fix w all wall/lj93 xlo 0 1 1 2.5 colour red")
    _assert_word(err, 10, "colour")
    assert "unknown face or keyword" in str(err) and "units, pbc, fld" in str(err)


def test_error_unknown_face():
    err = _error("fix w all wall/lj93 wlo 0 1 1 2.5")
    _assert_word(err, 5, "wlo")
    assert "xlo xhi ylo yhi zlo zhi" in str(err)


def test_error_face_twice():
    err = _error("fix w all wall/lj93 xlo 0 1 1 2.5 xhi 9 1 1 2.5 xlo 1 1 1 2.5")
    _assert_word(err, 15, "xlo")
    assert "xlo wall defined twice" in str(err)


def test_error_missing_face_arguments_at_end():
    err = _error("fix w all wall/lj93 zlo 0.0 1.0")
    _assert_word(err, 5, "zlo")
    msg = str(err)
    assert "missing arguments" in msg and "coord epsilon sigma cutoff" in msg and "found 2" in msg


def test_error_missing_face_arguments_before_keyword():
    err = _error("fix w all wall/morse zlo 0.0 1.0 2.0 2.5 units box")
    _assert_word(err, 5, "zlo")
    assert "coord D0 alpha r0 cutoff" in str(err) and "found 4" in str(err)


@pytest.mark.parametrize(
    "line, position, word, field",
    [
        ("fix w all wall/lj93 xlo 0 one 1 2.5", 7, "one", "xlo epsilon must be a number or"),
        ("fix w all wall/lj93 xlo 0 1 1 v_rc", 9, "v_rc", "xlo cutoff must be a number"),
        ("fix w all wall/lj93 xlo edge 1 1 2.5", 6, "edge", "xlo coord must be EDGE"),
        ("fix w all wall/lj93 xlo v_1x 1 1 2.5", 6, "v_1x", "xlo coord must be EDGE"),
        ("fix w all wall/lj93 xlo ${z} 1 1 2.5", 6, "${z}", "xlo coord must be EDGE"),
        ("fix w all wall/lj93 xlo 0 1 1 nan", 9, "nan", "xlo cutoff must be a number"),
        ("fix w all wall/morse ylo 0 1 x 1 2", 8, "x", "ylo alpha must be a number or"),
        ("fix w all wall/reflect xlo left", 6, "left", "xlo coord must be EDGE"),
        ("fix w all wall/flow x fast 1.5 5 1 2.0", 6, "fast", "vflow (the flow velocity) must be a number"),
        ("fix w all wall/flow x 0.4 hot 5 1 2.0", 7, "hot", "T (the temperature) must be a number"),
        ("fix w all wall/flow x 0.4 1.5 5.5 1 2.0", 8, "5.5", "SEED (the random seed) must be an integer"),
        ("fix w all wall/flow x 0.4 1.5 5 one 2.0", 9, "one", "N (the number of flow walls) must be an integer"),
        ("fix w all wall/flow x 0.4 1.5 5 2 2.0 EDGE", 11, "EDGE", "wall coordinate w2 must be a number"),
        ("fix w all wall/region ball lj93 1 v_s 2.5", 8, "v_s", "sigma must be a number"),
        ("fix w all wall/region ball morse 1 2 r0 2.5", 9, "r0", "r0 must be a number"),
        ("fix w all wall/region/ees ball 1 1 big", 8, "big", "cutoff must be a number"),
    ],
)
def test_error_not_a_number_names_field(line, position, word, field):
    err = _error(line)
    _assert_word(err, position, word)
    assert field in str(err)


@pytest.mark.parametrize(
    "line, position, word",
    [
        ("fix w all wall/lj93 xlo 0 1 1 2.5 units metres", 11, "metres"),
        ("fix w all wall/reflect xlo 0 units real", 8, "real"),
        ("fix w all wall/flow x 0.4 1.5 5 1 2.0 units lj", 12, "lj"),
    ],
)
def test_error_bad_units_value(line, position, word):
    err = _error(line)
    _assert_word(err, position, word)
    assert "bad units value" in str(err) and "'units box'" in str(err) and "'units lattice'" in str(err)


def test_error_units_without_value():
    err = _error("fix w all wall/lj93 xlo 0 1 1 2.5 units")
    _assert_word(err, 10, "units")
    assert "missing value after units" in str(err)


def test_error_bad_pbc_value():
    err = _error("fix w all wall/lj93 xlo 0 1 1 2.5 pbc true")
    _assert_word(err, 11, "true")
    assert "'pbc yes' or 'pbc no'" in str(err)


@pytest.mark.parametrize(
    "line",
    ["fix w all wall/lj93", "fix w all wall/lj93 units box", "fix w all wall/reflect units box"],
)
def test_error_no_faces(line):
    err = _error(line)
    _assert_word(err, 4, line.split()[3])
    assert "no walls defined" in str(err)


def test_error_fld_yes():
    err = _error("fix w all wall/lj93 xlo 0 1 1 2.5 fld yes")
    _assert_word(err, 10, "fld")
    assert "fld yes (lubrication) is not supported" in str(err)


def test_error_fld_yes_example_position():
    err = _error("fix w all wall/lj93 fld yes")
    assert str(err).startswith("word 5 'fld': ")


def test_error_reflect_rejects_force_wall_keywords():
    err = _error("fix w all wall/reflect xlo EDGE pbc yes")
    _assert_word(err, 7, "pbc")
    assert "wall/reflect" in str(err) and "units" in str(err)


def test_error_reflect_face_without_coord():
    err = _error("fix w all wall/reflect xlo units box")
    _assert_word(err, 5, "xlo")
    assert "missing argument" in str(err)


def test_error_reflect_face_twice():
    err = _error("fix w all wall/reflect xlo EDGE xlo 1.0")
    _assert_word(err, 7, "xlo")
    assert "xlo wall defined twice" in str(err)


# ---- wall/flow word errors (physics.md §8.6) -----------------------------------------------


def test_error_flow_missing_arguments():
    err = _error("fix w all wall/flow x 0.4 1.5 593894 4")
    _assert_word(err, 9, "4")
    assert "missing arguments" in str(err) and "AXIS VFLOW T SEED N" in str(err)


def test_error_flow_bad_axis():
    err = _error("fix w all wall/flow q 0.4 1.5 593894 1 2.0")
    _assert_word(err, 5, "q")
    assert "axis must be x, y or z" in str(err)


@pytest.mark.parametrize(
    "line, found",
    [
        ("fix w all wall/flow x 0.4 1.5 593894 4 2.0 4.0 6.0", 3),
        ("fix w all wall/flow x 0.4 1.5 593894 2 2.0 4.0 6.0", 3),
        ("fix w all wall/flow x 0.4 1.5 593894 1 2.0 4.0 6.0 8.0 units box", 4),
    ],
)
def test_error_flow_wrong_wall_count(line, found):
    err = _error(line)
    _assert_word(err, 9, line.split()[8])
    assert "wrong wall count" in str(err) and f"{found} wall coordinates follow" in str(err)


def test_error_flow_nonpositive_count():
    err = _error("fix w all wall/flow x 0.4 1.5 593894 0 2.0")
    _assert_word(err, 9, "0")
    assert "positive integer" in str(err)


def test_error_flow_units_not_last():
    err = _error("fix w all wall/flow x 0.4 1.5 593894 2 units box 2.0 4.0")
    _assert_word(err, 10, "units")
    assert "units must be the last two words" in str(err)


def test_error_flow_trailing_pair_not_units():
    err = _error("fix w all wall/flow x 0.4 1.5 593894 2 2.0 4.0 style box")
    _assert_word(err, 12, "style")
    assert "'units lattice' or 'units box'" in str(err)


def test_error_flow_units_missing_value():
    err = _error("fix w all wall/flow x 0.4 1.5 593894 1 2.0 units")
    _assert_word(err, 11, "units")
    assert "missing value after units" in str(err)


# ---- region walls --------------------------------------------------------------------------


def test_error_region_unknown_potential():
    err = _error("fix w all wall/region ball lj96 1 1 2.5")
    _assert_word(err, 6, "lj96")
    assert "unknown wall/region style" in str(err) and "lj93, lj126, lj1043, colloid, harmonic, morse" in str(err)


def test_error_region_ees_points_to_region_ees():
    err = _error("fix w all wall/region ball ees 1 1 2.5")
    _assert_word(err, 6, "ees")
    assert "wall/region/ees" in str(err)


def test_error_region_missing_arguments():
    err = _error("fix w all wall/region ball morse 1 2 1.1")
    _assert_word(err, 9, "1.1")
    assert "missing arguments" in str(err) and "morse D0 alpha r0 rc" in str(err) and "found 3" in str(err)


def test_error_region_missing_region():
    err = _error("fix w all wall/region")
    _assert_word(err, 4, "wall/region")
    assert "missing region ID" in str(err)


def test_error_region_too_many_arguments():
    err = _error("fix w all wall/region ball lj93 1 1 2.5 units box")
    _assert_word(err, 10, "units")
    assert "too many arguments" in str(err) and "units come from the region" in str(err)


def test_error_region_ees_missing_arguments():
    err = _error("fix w all wall/region/ees ball 1 1")
    _assert_word(err, 7, "1")
    assert "missing arguments" in str(err) and "found 2" in str(err)


def test_error_region_ees_too_many_arguments():
    err = _error("fix w all wall/region/ees ball 1 1 2.5 3.0")
    _assert_word(err, 9, "3.0")
    assert "too many arguments" in str(err)


def test_error_message_always_has_word_prefix():
    # every error about a word follows "word N 'WORD': ..."
    err = _error("fix w all wall/lj93 xlo 0 1 1 2.5 fld maybe")
    assert re.match(r"word 11 'maybe': ", str(err))
