"""Walls moved by step-dependent variables during `minimize`: LAMMPS's minimizer advances the step
counter once per iteration (0 at the initial evaluation, k during iteration k), `ramp` runs over
maxiter steps and fire's adaptive timestep is LAMMPS's `dt` (`time` = step dt). Closed forms for
the wall at its moved position, the clock the minimizer hands out, batching, and LAMMPS
22Jul2025 (an oracle through its Python API; nothing copied) on a two-atom scene.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from factories import case_of
from test_minimize import harmonic, one_atom, run, wall_objective
from test_pair_minimize_engine import lammps_minimize, lj93_energy, scene_yaml

from wallbatch.engine.engine import Engine, run_cases
from wallbatch.engine.minimize import minimize
from wallbatch.scene.case import MinSettings

LO, HI = (-5.0, -5.0, 0.0), (5.0, 5.0, 10.0)
X2 = np.array([[0.3, -0.2, 2.2], [1.3, 0.4, 2.6]])  # between lj93 walls at z = 0 and z = v_zw ~ 3
RC = 2.5
LMP_NO_PAIR = "pair_style zero 1.0\npair_coeff * *"
ZERO_FORCE_MIN = "etol: 0.0, ftol: 0.0, maxiter: 5, maxeval: 1000"


def scene(style: str, zw: str, minimize: str = "etol: 0.0, ftol: 1.0e-10, maxiter: 30, maxeval: 1000",
          x=X2, steps: int = 0) -> str:
    walls = ("  w:\n    style: lj93\n    units: box\n    energy: true\n"
             f"    zlo: [0.0, 1.0, 1.0, {RC!r}]\n    zhi: [v_zw, 1.0, 1.0, {RC!r}]\n")
    return scene_yaml(x, np.zeros_like(x), LO, HI, "fff", walls=walls, minimize=f"{{style: {style}, {minimize}}}",
                      steps=steps, thermo=steps, outputs=("step", "pe"), dump=steps,
                      extra=f'variables:\n  zw: "{zw}"\n')


def wall_energy(z: np.ndarray, zw: float) -> float:
    """Both lj93 faces (epsilon = sigma = 1, shifted at the cut-off) on atoms at heights z."""
    e = 0.0
    for r in (np.asarray(z), zw - np.asarray(z)):
        e += float(np.where(r < RC, lj93_energy(r) - lj93_energy(RC), 0.0).sum())
    return e


def minimized(text: str) -> tuple[dict, np.ndarray]:
    """The case's results and its minimized positions (the run's first dump frame, if it has one)."""
    eng = Engine([case_of(text)])
    res = eng.run()[0]
    assert res.status == "ok", res.error
    return res.data, (res.frames["x"][0] if res.frames else eng.state.x[0]).copy()


# ----------------------------------------------------------------------------- closed forms


@pytest.mark.parametrize("style, reason, niter", [("cg", "linesearch alpha is zero", 7),
                                                  ("fire", "max iterations", 30)])
def test_wall_energy_is_that_at_the_moved_position(style, reason, niter):
    """zhi at v_zw = 3 + 0.01 step: after k iterations the minimized energy is the closed form
    of the walls at zw = 3 + 0.01 k on the final positions (LAMMPS: cg 7 iterations, its failed
    line search re-evaluated at step 7; fire 30). The run after minimize starts at step 0 (as
    the exported script's reset_timestep 0): its step-0 pe has the wall back at 3.0."""
    d, x = minimized(scene(style, "3.0+0.01*step", steps=1))
    assert (d["min_stop_reason"], int(d["min_iterations"])) == (reason, niter)
    moved = wall_energy(x[:, 2], 3.0 + 0.01 * niter)
    assert d["min_energy"] == pytest.approx(moved, rel=1e-13)
    assert abs(moved - wall_energy(x[:, 2], 3.0)) > 1e-2  # a wall left at 3.0 would be far off
    assert d["pe"][0] == pytest.approx(wall_energy(x[:, 2], 3.0), rel=1e-13)


def test_ramp_runs_over_maxiter():
    """ramp(0, 0.3) during minimize is 0.3 k / maxiter (LAMMPS: the minimization is a run of
    maxiter steps), not a fraction of the dynamics run (here 1000 steps)."""
    d, x = minimized(scene("fire", "3.0+ramp(0.0,0.3)", steps=1000))
    assert (d["min_stop_reason"], int(d["min_iterations"])) == ("max iterations", 30)
    assert d["min_energy"] == pytest.approx(wall_energy(x[:, 2], 3.3), rel=1e-13)


def test_stop_without_line_search_evaluates_at_its_step():
    """An atom 2.6 below the wall (cut-off 2.5): all forces zero at step 0, so cg stops in its
    first iteration (forces are zero); LAMMPS then evaluates once more at step 1, where the wall
    (7.6 - 0.2 step) is 2.4 away: that energy and force are the minimization's result."""
    d, x = minimized(scene("cg", "7.6-0.2*step", ZERO_FORCE_MIN, x=np.array([[0.3, -0.2, 5.0]])))
    assert (d["min_stop_reason"], int(d["min_iterations"]), int(d["min_evaluations"])) == ("forces are zero", 1, 0)
    assert x[0, 2] == 5.0 and d["min_energy_before"] == 0.0
    assert d["min_energy"] == pytest.approx(lj93_energy(2.4) - lj93_energy(RC), rel=1e-13)
    assert d["min_fnorm"] == pytest.approx(abs(1.2 / 2.4 ** 10 - 3.0 / 2.4 ** 4), rel=1e-13)


# ----------------------------------------------------------------------------- the minimizer's clock


@pytest.mark.parametrize("style", ["cg", "fire"])
def test_clock_gives_lammps_steps(style):
    """The clock sees step 0 at the initial evaluation, then the iteration number: it never goes
    back, rises by one per iteration and ends at the iteration count; fire passes its own dt."""
    seen = []
    settings = MinSettings(0.0, 1e-10, 40, 1000, style=style, timestep=0.005)
    res = minimize(one_atom(1.9), wall_objective(harmonic, eps=0.25, rc=2.5), settings,
                   clock=lambda steps, dt: seen.append((int(steps[0]), None if dt is None else float(dt[0]))))
    steps = [s for s, _ in seen]
    assert steps[0] == 0 and steps[-1] == res.iterations[0] > 3
    assert all(0 <= b - a <= 1 for a, b in zip(steps, steps[1:]))
    assert sorted(set(steps)) == list(range(res.iterations[0] + 1))
    assert len(steps) >= res.evaluations[0] + 1
    dts = {dt for _, dt in seen}
    assert dts == {None} if style == "cg" else (0.005 in dts and len(dts) > 1)  # fire's dt grows


def test_clock_on_a_static_objective_changes_nothing():
    """With a clock but an objective that ignores it, the extra evaluations at a stop give the
    numbers in memory: every result is bit-identical to a run without a clock."""
    def wall_force_only(x, rows):  # E = 0 (a wall without energy): cg gives up, linesearch alpha is zero
        f = np.zeros_like(x)
        f[:, :, 2] = 1.0 / x[:, :, 2] ** 2
        return np.zeros(len(rows)), f

    for objective in (wall_force_only, wall_objective(harmonic, eps=0.25, rc=1.5)):
        x = np.concatenate([one_atom(0.5), one_atom(0.9)])
        plain = run(x, objective, etol=1e-8)
        calls = []
        clocked = minimize(x, objective, MinSettings(1e-8, 1e-10, 1000, 10000),
                           clock=lambda steps, dt: calls.append(steps.copy()))
        for field in ("x", "energy_before", "energy_after", "iterations", "evaluations", "fnorm2"):
            np.testing.assert_array_equal(getattr(clocked, field), getattr(plain, field), err_msg=field)
        assert clocked.stop_reason == plain.stop_reason
    assert plain.stop_reason[0] == "energy tolerance"


def test_cases_at_different_iterations_share_a_batch():
    """Three cases from different heights stop after different iteration counts; each case's wall
    follows its own step, so the batch gives bit-identical results to each case run alone."""
    cases = [case_of(scene("cg", "3.0+0.01*step", "etol: 1.0e-6, ftol: 1.0e-10, maxiter: 200, maxeval: 1000"))
             for _ in range(3)]
    cases = [dataclasses.replace(c, x=c.x - [0.0, 0.0, dz]) for c, dz in zip(cases, (0.0, 0.6, 1.1))]
    batched = run_cases(cases)
    for c, res in zip(cases, batched):
        alone = run_cases([c])[0]
        for k in ("min_iterations", "min_evaluations", "min_energy", "min_fnorm", "min_stop_reason", "pe"):
            np.testing.assert_array_equal(res.data[k], alone.data[k], err_msg=k)
    assert len({int(r.data["min_iterations"]) for r in batched}) == 3


# ----------------------------------------------------------------------------- LAMMPS


@pytest.mark.lammps
@pytest.mark.parametrize("style, zw", [("cg", "3.0+0.01*step"), ("fire", "3.0+0.01*step"), ("cg", "3.0+0.3*time"),
                                       ("fire", "3.0+0.3*time"), ("fire", "3.0+swiggle(0.0,0.1,0.05)")])
def test_moving_wall_minimize_matches_lammps(style, zw):
    """fix wall/lj93 zhi v_zw, `minimize 0.0 1e-10 30 1000` (thermo_modify norm no): the same
    stop, iterations, evaluations, energy and positions as LAMMPS (fire's time and swiggle
    follow its adaptive dt)."""
    d, x = minimized(scene(style, zw))
    fixes = (f"variable zw equal {zw}\nfix w all wall/lj93 zhi v_zw 1.0 1.0 {RC!r} zlo 0.0 1.0 1.0 {RC!r} units box\n"
             "fix_modify w energy yes")
    xl, el, stop, counts = lammps_minimize(X2, LO, HI, "fff", LMP_NO_PAIR, fixes, style, "0.0 1e-10 30 1000")
    assert (d["min_stop_reason"], int(d["min_iterations"]), int(d["min_evaluations"])) == (stop, *counts)
    assert d["min_energy"] == pytest.approx(el, rel=1e-12)
    assert np.abs(x - xl).max() < 1e-12
    static, _ = minimized(scene(style, "3.0"))
    assert abs(static["min_energy"] - el) > 1e-3  # the moving wall matters here


@pytest.mark.lammps
def test_stop_at_a_later_step_matches_lammps():
    """cg with all forces zero at step 0 (LAMMPS: search direction is not downhill, a known
    difference in wording): both evaluate once more at step 1, with the wall moved in."""
    x0 = np.array([[0.3, -0.2, 5.0]])
    d, x = minimized(scene("cg", "7.6-0.2*step", ZERO_FORCE_MIN, x=x0))
    fixes = (f"variable zw equal 7.6-0.2*step\nfix w all wall/lj93 zhi v_zw 1.0 1.0 {RC!r} units box\n"
             "fix_modify w energy yes")
    xl, el, stop, counts = lammps_minimize(x0, LO, HI, "fff", LMP_NO_PAIR, fixes, "cg", "0.0 0.0 5 1000")
    assert (stop, counts) == ("search direction is not downhill", (1, 0))
    assert (int(d["min_iterations"]), int(d["min_evaluations"])) == counts
    assert d["min_energy"] == pytest.approx(el, rel=1e-12) and el < -1e-3
    assert np.array_equal(x, xl)
