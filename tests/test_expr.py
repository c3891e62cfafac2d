"""Tests for wallbatch.expr: LAMMPS equal-style variable expressions."""

from __future__ import annotations

import math

import numpy as np
import pytest

from wallbatch.expr import (
    Binary,
    Call,
    EvalContext,
    Num,
    Unary,
    VariableError,
    VarRef,
    Variables,
    parse,
    to_lammps,
)


def const(text: str) -> float:
    value = Variables({"a": text}).constant_value("a")
    assert value is not None
    return value


def make_ctx(step, *, begin=100, end=105, dt=0.1, time=None, box_hi=(10.0, 10.0, 10.0), atoms=50):
    """A context as the engine builds it for a step-based run with constant dt."""
    step_arr = np.asarray(step)
    n_b = step_arr - begin
    elapsed_time = n_b * np.asarray(dt)
    ramp_fraction = np.where(n_b == 0, 0.0, n_b / (end - begin)) if end != begin else 0.0
    return EvalContext(
        step=step,
        begin_step=begin,
        end_step=end,
        dt=dt,
        time=elapsed_time if time is None else time,
        elapsed_time=elapsed_time,
        ramp_fraction=ramp_fraction,
        box_lo=(0.0, 0.0, 0.0),
        box_hi=box_hi,
        atoms=atoms,
    )


# --- parsing and LAMMPS precedence -------------------------------------------------------------


@pytest.mark.parametrize(
    "text, expected",
    [
        ("2^3^2", 64.0),  # ^ is left-associative
        ("-2^2", 4.0),  # unary minus binds tighter than ^
        ("2^-2", 0.25),
        ("-7%3", -1.0),  # C fmod
        ("7%-3", 1.0),
        ("7.5%2", 1.5),
        ("log(100)", 2.0),  # base 10
        ("ln(exp(2))", 2.0),
        ("round(2.5)", 3.0),
        ("round(-2.5)", -2.0),  # floor(x + 0.5)
        ("round(-2.6)", -3.0),
        ("floor(-1.5)", -2.0),
        ("ceil(-1.5)", -1.0),
        ("1 + 2 * 3", 7.0),
        ("(1 + 2) * 3", 9.0),
        ("2 * 3 ^ 2", 18.0),
        ("10 - 4 - 3", 3.0),
        ("12 / 3 / 2", 2.0),
        ("1 - -1", 2.0),
        ("1 < 2", 1.0),
        ("2 <= 1", 0.0),
        ("3 > 2", 1.0),
        ("3 >= 3", 1.0),
        ("1 == 1.0", 1.0),
        ("1 != 1", 0.0),
        ("1 < 2 < 3", 1.0),  # (1<2) < 3
        ("1 + 1 == 2", 1.0),  # + binds tighter than ==
        ("1 < 2 == 1", 1.0),  # < binds tighter than ==
        ("1 && 0", 0.0),
        ("2 && -1", 1.0),
        ("0 || 0", 0.0),
        ("0 || 3", 1.0),
        ("1 || 0 && 0", 1.0),  # && binds tighter than ||
        ("!0", 1.0),
        ("!5", 0.0),
        ("!0 + 1", 2.0),  # ! binds tighter than +
        ("1 |^ 1", 0.0),
        ("ternary(1, 2, 3)", 2.0),
        ("ternary(0, 2, 3)", 3.0),
        ("ternary(2 > 1 && 1, 10, 20)", 10.0),
        ("atan2(1, 1) * 4", math.pi),
        ("atan2(1, -1)", 3 * math.pi / 4),
        ("min(3, -2)", -2.0),
        ("max(3, -2)", 3.0),
        ("PI", math.pi),
        ("sin(PI/2) + cos(0) + tan(0)", 2.0),
        ("asin(1) + acos(1) + atan(1)", math.pi / 2 + math.pi / 4),
        ("sqrt(16) + abs(-3)", 7.0),
        ("1e-5", 1e-5),
        ("1.0E+3", 1000.0),
        (".5", 0.5),
        ("5.", 5.0),
        ("2.5e2", 250.0),
        ("0^0", 1.0),
    ],
)
def test_constant_expressions(text: str, expected: float) -> None:
    assert const(text) == pytest.approx(expected, rel=1e-12, abs=1e-15)


def test_parse_returns_tree() -> None:
    assert parse("-2^2") == Binary("^", Unary("-", Num(2.0)), Num(2.0))
    assert parse("max(v_a, 1)") == Call("max", (VarRef("a"), Num(1.0)))


def test_to_lammps_round_trips_and_rewrites_min_max() -> None:
    text = "-2^2 + max(3, v_a) * min(1, 2) - !0 % 3"
    out = to_lammps(parse(text))
    assert "max" not in out and "min" not in out and "ternary" in out
    v = Variables({"a": "4", "x": text, "y": out})
    assert v.constant_value("y") == pytest.approx(v.constant_value("x"))


def test_numeric_values_accepted() -> None:
    v = Variables({"a": 2, "b": 1.5, "c": "v_a * v_b"})
    assert v.constant_value("c") == 3.0
    assert v.names() == ["a", "b", "c"]


# --- physics.md section 10 reference values ----------------------------------------------------


def test_ramp_reference_values() -> None:
    v = Variables({"r": "ramp(2, 12)"})
    values = [float(v.evaluate("r", make_ctx(n))) for n in range(100, 106)]
    assert values == pytest.approx([2, 4, 6, 8, 10, 12])


def test_vdisplace_reference_values() -> None:
    v = Variables({"d": "vdisplace(1, 3)"})
    values = [float(v.evaluate("d", make_ctx(n))) for n in range(100, 106)]
    assert values == pytest.approx([1.0, 1.3, 1.6, 1.9, 2.2, 2.5])


def test_wiggle_reference_values() -> None:
    v = Variables({"s": "swiggle(1, 2, 0.8)", "c": "cwiggle(1, 2, 0.8)"})
    ctx = make_ctx(103)
    assert float(v.evaluate("s", ctx)) == pytest.approx(2.41421356, abs=1e-8)
    assert float(v.evaluate("c", ctx)) == pytest.approx(4.41421356, abs=1e-8)
    start = make_ctx(100)  # both start at x; cwiggle starts with zero velocity
    assert float(v.evaluate("s", start)) == 1.0
    assert float(v.evaluate("c", start)) == 1.0


def test_wiggle_negative_period_is_accepted() -> None:
    v = Variables({"s": "swiggle(1, 2, -0.8)"})
    assert float(v.evaluate("s", make_ctx(103))) == pytest.approx(1 - 1.41421356, abs=1e-8)


def test_run_start_stop_reference() -> None:
    # run 4 start 95 stop 110 from step 105: ramp(2,12) = 8.6667 at 105, 10 at 107
    v = Variables({"r": "ramp(2, 12)", "d": "vdisplace(1, 3)", "el": "elaplong"})
    ctx105 = make_ctx(105, begin=95, end=110)
    assert float(v.evaluate("r", ctx105)) == pytest.approx(8.6667, abs=1e-4)
    assert float(v.evaluate("r", make_ctx(107, begin=95, end=110))) == pytest.approx(10.0)
    assert float(v.evaluate("d", ctx105)) == pytest.approx(4.0)
    assert float(v.evaluate("el", ctx105)) == 10.0


def test_thermo_keywords() -> None:
    v = Variables(
        {
            "step": "step",
            "el": "elapsed + elaplong",
            "dt": "dt",
            "t": "time",
            "box": "xlo + xhi + ylo + yhi + zlo + zhi",
            "l": "lx * 100 + ly * 10 + lz",
            "vol": "vol",
            "n": "atoms",
        }
    )
    ctx = EvalContext(
        step=103, begin_step=100, end_step=105, dt=0.1, time=10.3, elapsed_time=0.3,
        ramp_fraction=0.6, box_lo=(0.0, -1.0, 2.0), box_hi=(4.0, 2.0, 7.0), atoms=42,
    )  # fmt: skip
    values = {name: float(v.evaluate(name, ctx)) for name in v.names()}
    assert values == pytest.approx(
        {"step": 103, "el": 6, "dt": 0.1, "t": 10.3, "box": 14, "l": 435, "vol": 60, "n": 42}
    )


# --- vectorisation over cases -----------------------------------------------------------------


def test_vectorised_over_cases() -> None:
    dt = np.array([0.1, 0.2, 0.5])
    time = np.array([1.0, 2.0, 3.0])
    v = Variables(
        {
            "d": "vdisplace(1, 3)",
            "t": "time * 2",
            "c": "ternary(dt > 0.15, 1/dt, -1)",
            "k": "5",
            "o": "dt > 0.15 || time < 1.5",
        }
    )
    ctx = make_ctx(103, dt=dt, time=time)
    np.testing.assert_allclose(v.evaluate("d", ctx), 1 + 3 * 3 * dt)
    np.testing.assert_allclose(v.evaluate("t", ctx), [2.0, 4.0, 6.0])
    np.testing.assert_allclose(v.evaluate("c", ctx), [-1.0, 5.0, 2.0])
    np.testing.assert_allclose(v.evaluate("o", ctx), [1.0, 1.0, 1.0])
    k = v.evaluate("k", ctx)
    assert k.shape == (3,) and k.dtype == np.float64
    np.testing.assert_allclose(k, 5.0)


def test_vectorised_steps_and_box() -> None:
    v = Variables({"r": "ramp(2, 12)", "h": "zhi - 1"})
    ctx = make_ctx(np.arange(100, 106), box_hi=(10.0, 10.0, np.full(6, 12.0)))
    np.testing.assert_allclose(v.evaluate("r", ctx), [2, 4, 6, 8, 10, 12])
    np.testing.assert_allclose(v.evaluate("h", ctx), np.full(6, 11.0))


def test_scalar_context_gives_0d_array() -> None:
    out = Variables({"a": "step"}).evaluate("a", make_ctx(101))
    assert isinstance(out, np.ndarray) and out.shape == () and out.dtype == np.float64


# --- errors ---------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "text, fragment",
    [
        ("1 + * 2", "'*'"),
        ("(1 + 2", "expected ')'"),
        ("1 2", "'2'"),
        ("1 +", "end of expression"),
        ("+1", "'+'"),  # no unary plus in LAMMPS
        ("1 = 1", "'='"),
        ("1 & 1", "'&'"),
        ("2 $ 3", "'$'"),
        ("", "expected a value"),
    ],
)
def test_syntax_errors(text: str, fragment: str) -> None:
    with pytest.raises(VariableError, match="syntax error") as info:
        Variables({"bad": text})
    assert "'bad'" in str(info.value) and fragment in str(info.value)
    assert "position" in str(info.value)


def test_unknown_keyword_and_function() -> None:
    with pytest.raises(VariableError, match="unknown keyword 'temp'"):
        Variables({"a": "1 + temp"})
    with pytest.raises(VariableError, match="unknown function 'stride'"):
        Variables({"a": "stride(1, 2, 3)"})
    with pytest.raises(VariableError, match="unknown keyword 'pi'"):
        Variables({"a": "pi"})


def test_unknown_variable() -> None:
    with pytest.raises(VariableError, match=r"'a' references unknown variable 'v_nope'"):
        Variables({"a": "v_nope + 1"})
    with pytest.raises(VariableError, match="unknown variable 'zz'"):
        Variables({"a": "1"}).evaluate("zz", make_ctx(100))


@pytest.mark.parametrize(
    "text, message",
    [
        ("vdisplace(1)", "Invalid vdisplace function in variable formula: must have 2 arguments"),
        ("ramp(1, 2, 3)", "Invalid ramp function in variable formula: must have 2 arguments"),
        ("swiggle(1, 2)", "Invalid swiggle function in variable formula: must have 3 arguments"),
        ("sqrt()", "Invalid sqrt function in variable formula: must have 1 argument"),
        ("atan2(1)", "Invalid atan2 function in variable formula: must have 2 arguments"),
        ("ternary(1, 2)", "Invalid ternary function in variable formula: must have 3 arguments"),
    ],
)
def test_wrong_argument_count(text: str, message: str) -> None:
    with pytest.raises(VariableError, match=message):
        Variables({"a": text})


def test_cycles_are_named() -> None:
    with pytest.raises(VariableError, match="a -> b -> a"):
        Variables({"a": "v_b + 1", "b": "2 * v_a"})
    with pytest.raises(VariableError, match="c -> c"):
        Variables({"c": "v_c"})
    with pytest.raises(VariableError, match="x -> y -> z -> x"):
        Variables({"w": "v_x", "x": "v_y", "y": "v_z", "z": "v_x + 1"})


def test_division_by_zero() -> None:
    with pytest.raises(VariableError, match="'a'.*Divide by 0"):
        Variables({"a": "1 / (2 - 2)"}).constant_value("a")
    with pytest.raises(VariableError, match="Modulo 0"):
        Variables({"a": "5 % 0"}).constant_value("a")
    # in only one of the cases, and via another variable: still an error that names both
    v = Variables({"inv": "1 / (dt - 0.2)", "top": "v_inv + 1"})
    ctx = make_ctx(103, dt=np.array([0.1, 0.2, 0.3]))
    with pytest.raises(VariableError, match=r"'inv' \(via top -> inv\): Divide by 0"):
        v.evaluate("top", ctx)
    # LAMMPS evaluates every ternary argument, so an unselected branch still errors
    with pytest.raises(VariableError, match="Divide by 0"):
        Variables({"a": "ternary(1, 1, 1/0)"}).constant_value("a")


@pytest.mark.parametrize(
    "text, message",
    [
        ("sqrt(-1)", "Sqrt of negative"),
        ("ln(0)", "Log of zero/negative"),
        ("log(-2)", "Log of zero/negative"),
        ("asin(1.5)", "Arcsin of invalid"),
        ("acos(-1.01)", "Arccos of invalid"),
        ("0^-1", "Invalid power"),
    ],
)
def test_domain_errors(text: str, message: str) -> None:
    with pytest.raises(VariableError, match=message):
        Variables({"a": text}).constant_value("a")


def test_wiggle_zero_period() -> None:
    v = Variables({"s": "swiggle(0, 1, 0)", "c": "cwiggle(0, 1, 2 - 2)"})
    with pytest.raises(VariableError, match=r"Invalid swiggle\(x,y,z\) function.*z must be > 0"):
        v.evaluate("s", make_ctx(101))
    with pytest.raises(VariableError, match=r"Invalid cwiggle\(x,y,z\)"):
        v.evaluate("c", make_ctx(101))


def test_invalid_variable_name() -> None:
    with pytest.raises(VariableError, match="invalid variable name"):
        Variables({"a-b": "1"})


# --- dependency queries -----------------------------------------------------------------------


def test_dependencies_through_chains() -> None:
    v = Variables(
        {
            "amp": "0.5 * 2",
            "period": "sqrt(v_amp) * 3",
            "wig": "swiggle(0, v_amp, v_period)",
            "top": "12 - v_wig",
            "half": "lz / 2",
            "mid": "v_half + v_amp",
            "steps": "ternary(step > 10, 1, 0)",
        }
    )
    assert v.uses("amp") == frozenset()
    assert v.uses("period") == {"sqrt"}
    assert v.uses("top") == {"swiggle", "sqrt"}
    assert v.uses("mid") == {"lz"}
    assert v.uses("steps") == {"ternary", "step"}

    assert not v.depends_on_time("amp")
    assert not v.depends_on_time("period")
    assert v.depends_on_time("wig")
    assert v.depends_on_time("top")
    assert not v.depends_on_time("mid")  # box-dependent but constant during a run
    assert v.depends_on_time("steps")

    assert v.constant_value("amp") == 1.0
    assert v.constant_value("period") == 3.0
    assert v.constant_value("top") is None
    assert v.constant_value("mid") is None  # needs the box
    assert v.constant_value("steps") is None

    ctx = make_ctx(103, box_hi=(10.0, 10.0, 8.0))
    assert float(v.evaluate("mid", ctx)) == 5.0
    assert float(v.evaluate("top", ctx)) == pytest.approx(12 - math.sin(2 * math.pi / 3 * 0.3))


@pytest.mark.parametrize("word", ["elapsed", "elaplong", "dt", "time", "ramp(0,1)", "vdisplace(0,1)"])
def test_time_names(word: str) -> None:
    v = Variables({"a": word, "b": "v_a * 0"})
    assert v.depends_on_time("b")
    assert v.constant_value("b") is None
