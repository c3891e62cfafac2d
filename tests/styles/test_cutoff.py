"""Cut-off modes of the wall styles (wallbatch.styles.cutoff, docs/physics.md §17): closed forms for
every registered style, compiled == NumPy, the energy drift's order in dt through the engine, the
config checks, sweeps, batching and the export refusal.
"""

from __future__ import annotations

import inspect
import math
import re

import numpy as np
import pytest

from wallbatch.api import load
from wallbatch.config.models import config_from_dict, load_config_text
from wallbatch.config.source import ConfigError
from wallbatch.convergence import convergence
from wallbatch.engine.engine import Engine
from wallbatch.lammps.export import ExportError, check_exportable
from wallbatch.scene.build import build_case
from wallbatch.scene.case import structure_key
from wallbatch.styles import STYLES
from wallbatch.styles.cutoff import CUTOFF_MODES, CutoffStyle, supported, switch

from test_registry import _uses_libm, contact, values

WRAPPED = sorted(n for n, s in STYLES.items() if supported(s))
R_ON = 1.8  # switch_on of the tests (cut-off 2.5)


def params(name: str) -> dict[str, float]:
    return {**values(STYLES[name]), "switch_on": R_ON}


def test_every_style_with_a_closed_form_takes_every_mode():
    """The wrapper applies to every soft style with F(r) and E(r) - E(rc) in r alone (not ees)."""
    assert WRAPPED == sorted(n for n, s in STYLES.items() if s.shifted and s.shifted_fn is not None)
    assert "lj93" in WRAPPED and "ees" not in WRAPPED
    with pytest.raises(ValueError, match="only cutoff_mode shift"):
        CutoffStyle(STYLES["ees"], "smooth")
    with pytest.raises(ValueError, match="cutoff_mode must be one of"):
        CutoffStyle(STYLES["lj93"], "cubic")


def test_switch_closed_form():
    """S(x) = 1 - 10x^3 + 15x^4 - 6x^5 and dS/dr on [r_on, rc]; exactly 1 and 0 outside."""
    r_on, rc = 1.0, 3.0
    r = np.linspace(0.5, 3.5, 61)
    s, ds = switch(r, r_on, rc)
    x = np.clip((r - r_on) / (rc - r_on), 0.0, 1.0)
    np.testing.assert_allclose(s, 1 - 10 * x**3 + 15 * x**4 - 6 * x**5, rtol=1e-12, atol=2e-15)
    near = np.linspace(2.999, 3.0, 7)[:-1]  # relative accuracy as r -> rc: S = (1 - x)^3 (1 + 3x + 6x^2)
    y = (3.0 - near) / 2.0
    np.testing.assert_allclose(switch(near, r_on, rc)[0], y**3 * (10 - 15 * y + 6 * y * y), rtol=1e-13)
    np.testing.assert_allclose(ds, -30 * x**2 * (1 - x) ** 2 / (rc - r_on), rtol=1e-13, atol=1e-300)
    h = 1e-6  # dS/dr is the derivative of S
    np.testing.assert_allclose(ds, (switch(r + h, r_on, rc)[0] - switch(r - h, r_on, rc)[0]) / (2 * h), atol=1e-9)
    assert np.all(s[r <= r_on] == 1.0) and np.all(ds[r <= r_on] == 0.0)
    assert np.all(s[r >= rc] == 0.0) and np.all(ds[r >= rc] == 0.0)
    assert switch(2.0, r_on, rc)[0] == 0.5  # symmetric about the middle


@pytest.mark.parametrize("name", WRAPPED)
def test_shift_is_the_style_itself(name):
    """shift (the default) returns the style's own F(r) and E(r) - E(rc), bit for bit."""
    style, p = STYLES[name], params(name)
    r = np.linspace(contact(style, p), p["cutoff"], 50)
    e, f = CutoffStyle(style, "shift").energy_force(r, p)
    assert np.array_equal(f, style.force(r, *style.args(p)))
    assert np.array_equal(e, style.shifted_energy(r, p))


@pytest.mark.parametrize("name", WRAPPED)
def test_force_shift_closed_form(name):
    """E_fs = E(r) - E(rc) + (r - rc) F(rc), F_fs = F(r) - F(rc): both exactly 0 at rc."""
    style, p = STYLES[name], params(name)
    cs = CutoffStyle(style, "force-shift")
    rc = p["cutoff"]
    assert float(cs.force(rc, p)) == 0.0 and float(cs.energy(rc, p)) == 0.0
    r = np.linspace(contact(style, p), rc, 40)
    f_rc = style.force(rc, *style.args(p))
    np.testing.assert_allclose(cs.force(r, p), style.force(r, *style.args(p)) - f_rc, rtol=1e-14, atol=1e-14)
    np.testing.assert_allclose(cs.energy(r, p), style.shifted_energy(r, p) + (r - rc) * f_rc,
                               rtol=1e-14, atol=1e-14)


@pytest.mark.parametrize("name", WRAPPED)
@pytest.mark.parametrize("mode", CUTOFF_MODES)
def test_force_is_minus_gradient(name, mode):
    """F = -dE/dr everywhere inside the cut-off, r_on included (central differences)."""
    style, p = STYLES[name], params(name)
    cs = CutoffStyle(style, mode)
    r = np.concatenate([np.linspace(contact(style, p), p["cutoff"], 23)[1:-1], [R_ON, R_ON + 0.1, 2.45]])
    h = 1e-6
    numeric = -(cs.energy(r + h, p) - cs.energy(r - h, p)) / (2 * h)
    force = cs.force(r, p)
    np.testing.assert_allclose(force, numeric, rtol=1e-6, atol=1e-7 * np.abs(force).max())


def _order_at(fn, x: float, side: int) -> float:
    """The order k of fn(x + side h) -> 0 as h -> 0 (log2 of the ratio at h and h/2)."""
    h = 2e-3
    a, b = abs(float(fn(x + side * h))), abs(float(fn(x + side * h / 2)))
    return math.log2(a / b) if b > 0 else math.inf


@pytest.mark.parametrize("name", WRAPPED)
def test_smooth_is_c2_at_switch_on_and_the_cutoff(name):
    """smooth: E, F and dF/dr vanish at rc (orders >= 3, 2, 1 from below; past rc the engine gives
    0), and join shift at r_on with E, F, dF/dr continuous (the differences grow as x^3, x^2, x).
    force-shift, for contrast, leaves dF/dr jumping at rc (F vanishes only to first order)."""
    style, p = STYLES[name], params(name)
    sm, sh, fs = (CutoffStyle(style, m) for m in ("smooth", "shift", "force-shift"))
    rc = p["cutoff"]
    assert float(sm.energy(rc, p)) == 0.0 and float(sm.force(rc, p)) == 0.0
    dfdr = lambda cs: (lambda r: (cs.force(r + 1e-7, p) - cs.force(r - 1e-7, p)) / 2e-7)  # noqa: E731
    assert _order_at(lambda r: sm.energy(r, p), rc, -1) > 2.9
    assert _order_at(lambda r: sm.force(r, p), rc, -1) > 1.9
    assert _order_at(dfdr(sm), rc, -1) > 0.9
    if abs(float(dfdr(fs)(rc - 1e-4))) > 1e-6:  # a style whose F'(rc) != 0 (all but harmonic)
        assert _order_at(lambda r: fs.force(r, p), rc, -1) < 1.1
    # below r_on: shift exactly; above: the differences to shift vanish as x^3, x^2, x at r_on
    below = np.linspace(contact(style, p), R_ON, 30)
    assert np.array_equal(sm.force(below, p), sh.force(below, p))
    assert np.array_equal(sm.energy(below, p), sh.energy(below, p))
    assert _order_at(lambda r: sm.energy(r, p) - sh.energy(r, p), R_ON, 1) > 2.9
    assert _order_at(lambda r: sm.force(r, p) - sh.force(r, p), R_ON, 1) > 1.9


def _source_with_helpers(fn) -> str:
    """The source of `fn` and of the functions of its module it calls, transitively
    (colloid_shifted: colloid_dg and its series and closed forms)."""
    module = inspect.getmodule(fn)
    seen, todo, out = {fn.__name__}, [fn], []
    while todo:
        src = inspect.getsource(todo.pop())
        out.append(src)
        for name in re.findall(r"\b(\w+)\(", src):
            if name not in seen and inspect.isfunction(getattr(module, name, None)):
                seen.add(name)
                todo.append(getattr(module, name))
    return "".join(out)


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(n for n in WRAPPED if STYLES[n].compiled))
@pytest.mark.parametrize("mode", CUTOFF_MODES)
def test_compiled_force_is_the_numpy_force(name, mode):
    """The compiled closure of each (style, mode) gives the NumPy wrapper's bits (a few ulp where
    the style calls libm, as the plain forces)."""
    fast = pytest.importorskip("wallbatch.engine.compiled")
    if fast.njit is None:
        pytest.skip("numba not importable")
    style, p = STYLES[name], params(name)
    m = CUTOFF_MODES.index(mode)
    if m not in fast._modes(style):
        pytest.skip(f"{name} {mode} runs in NumPy (no compiled shifted energy)")
    cs = CutoffStyle(style, mode)
    r = np.linspace(contact(style, p), p["cutoff"], 401)
    want = cs.force(r, p)
    args = [float(a) for a in (*style.args(p), p["switch_on"])]
    got = np.array([fast.MODE_FORCES[(fast.STYLE_IDS[name], m)](float(ri), *args) for ri in r])
    libm = _uses_libm(style) or (mode == "smooth" and re.search(r"np\.(exp|expm1|log|arctanh)",
                                                                 _source_with_helpers(style.shifted_fn)))
    if libm:
        scale = np.abs(want).max()
        np.testing.assert_allclose(got, want, rtol=0, atol=1e-14 * scale)
    else:
        assert np.array_equal(got, want)


# ----------------------------------------------------------------------------- through the engine


def gas(mode: str = "shift", switch_on: float | None = None, style: str = "lj93", count: int = 200,
        steps: int = 2500, thermo: int = 250) -> dict:
    """An ideal gas (no pair forces) in a slit between two walls at z = 0 and 10, rc = 2.5."""
    face = {"epsilon": 1.0, "sigma": 1.0, "cutoff": 2.5}
    w = {"style": style, "units": "box", "energy": True, "cutoff_mode": mode,
         "zlo": {"coord": 0.0, **face}, "zhi": {"coord": 10.0, **face}}
    if switch_on is not None:
        w["switch_on"] = switch_on
    group = {"group": "gas", "create": {"random": {"count": count, "region": "slab"}}, "mass": 1.0,
             "velocity": {"temperature": 1.0}}
    if style == "colloid":
        group["radius"] = 0.3
    return {"seed": 7, "box": {"lo": [0, 0, 0], "hi": [10, 10, 10], "boundary": ["p", "p", "f"]},
            "regions": {"slab": {"style": "block", "lo": [0, 0, 1.0], "hi": [10, 10, 9.0], "units": "box"}},
            "atoms": [group], "walls": {"w": w}, "timestep": 0.004, "run": {"steps": steps, "thermo": thermo}}


def drift_order(mode: str, switch_on: float | None = None) -> tuple[float, float]:
    """(order of the energy drift, order of the etot error) in dt over 10 time units."""
    rep = convergence(gas(mode, switch_on), dts=[0.008, 0.004, 0.002, 0.001, 0.0005])
    pts = rep.points[:-1]
    slope = np.polyfit(np.log([q.h for q in pts]), np.log([q.drift for q in pts]), 1)[0]
    return float(slope), rep.orders["etot"]


@pytest.mark.slow  # over 2.5 s
def test_force_continuous_modes_restore_second_order():
    """lj93 slit, rc = 2.5 (F(rc) = -0.077): the energy drift over a fixed simulated time falls as
    dt^2 with force-shift and smooth (measured 1.99, 1.99), but only as dt^1.3 with shift; the
    etot error 2.13, 2.13 against 1.64."""
    shift = drift_order("shift")
    fs = drift_order("force-shift")
    sm = drift_order("smooth", 2.0)
    assert fs[0] >= 1.9 and sm[0] >= 1.9, (fs, sm)
    assert fs[1] >= 1.9 and sm[1] >= 1.9, (fs, sm)
    assert shift[0] < 1.6 and shift[1] < 1.8, shift


# each mode of each style; the compiled pairs that no other test uses share one scene (three wall
# fixes on both faces: one kernel instead of three)
@pytest.mark.parametrize("fixes", [
    (("lj93", "force-shift", None),), (("lj93", "smooth", 1.5),), (("colloid", "smooth", 1.5),),
    (("morse", "force-shift", None), ("morse", "smooth", 1.5), ("colloid", "force-shift", None)),
], ids=lambda fixes: "+".join(f"{style}-{mode}" for style, mode, _ in fixes))
def test_compiled_engine_matches_numpy(fixes, monkeypatch):
    """Each mode runs in the numba path (colloid smooth: in NumPy) with the NumPy engine's samples,
    bit for bit for plain-arithmetic styles."""
    fast = pytest.importorskip("wallbatch.engine.compiled")
    if fast.njit is None:
        pytest.skip("numba not importable")
    styles = {style for style, _, _ in fixes}
    d = gas(count=60, steps=300, thermo=50, style="colloid" if "colloid" in styles else "lj93")
    walls = {}
    for k, (style, mode, switch_on) in enumerate(fixes):
        w = gas(mode, switch_on, style=style if style != "morse" else "lj93")["walls"]["w"]
        if style == "morse":
            for f in ("zlo", "zhi"):
                w[f] = {"coord": w[f]["coord"], "D0": 1.0, "alpha": 2.0, "r0": 1.0, "cutoff": 2.5}
            w["style"] = "morse"
        walls[f"w{k}"] = w
    d["walls"] = walls
    case = build_case(config_from_dict(d))
    monkeypatch.setenv("WALLBATCH_NUMBA", "0")
    ref = Engine([case]).run()[0]
    monkeypatch.setenv("WALLBATCH_NUMBA", "1")
    eng = Engine([case])
    got = eng.run()[0]
    assert ref.status == got.status == "ok"
    assert ref.data["wall_force"].shape[1] == 2 * len(fixes) and np.all(ref.data["wall_force"][1:] != 0.0)
    compiled = all(CUTOFF_MODES.index(mode) in fast._modes(STYLES[style]) for style, mode, _ in fixes)
    if compiled:
        assert eng.fast is not None and eng.fast.compiled_chunks > 0 and eng.fast.fallbacks == 0
    else:
        assert eng.fast is None or eng.fast.compiled_chunks == 0
    exact = styles == {"lj93"}
    for key, want in ref.data.items():
        if exact:
            assert np.array_equal(got.data[key], want, equal_nan=True), key
        else:
            scale = np.nanmax(np.abs(want)) if np.isfinite(want).any() else 0.0
            np.testing.assert_allclose(got.data[key], want, rtol=0, atol=1e-12 * max(scale, 1e-300), err_msg=key)


def test_engine_forces_and_energy_are_the_wrapper():
    """One atom per face: the engine's force and wall energy are CutoffStyle's, and an atom past
    the cut-off feels nothing."""
    d = gas("smooth", 2.0, count=1, steps=0)
    d["atoms"][0]["create"] = {"positions": [[1, 1, 2.2], [2, 2, 7.7], [3, 3, 5.0]]}
    eng = Engine([build_case(config_from_dict(d))])
    eng.setup()
    cs = CutoffStyle(STYLES["lj93"], "smooth")
    p = {"epsilon": 1.0, "sigma": 1.0, "cutoff": 2.5, "switch_on": 2.0}
    f = eng.state.f[0, :, 2]
    r_hi = 10.0 - 7.7
    assert f[0] == cs.force(2.2, p) != 0.0 and f[1] == -cs.force(r_hi, p) != 0.0 and f[2] == 0.0
    eng.state.f[...] = 0.0
    e, _ = eng.soft[0].apply(eng.state, True)
    assert e[0] == cs.energy(2.2, p) + cs.energy(r_hi, p)


def test_region_wall_takes_the_mode():
    """wall/region with force-shift: the contact force is F(r) - F(rc) along the normal."""
    d = gas("shift", count=1, steps=0)
    d["walls"] = {"ball": {"style": "region", "region": "ball", "potential": "lj93", "epsilon": 1.0, "sigma": 1.0,
                           "cutoff": 2.5, "cutoff_mode": "force-shift", "energy": True}}
    d["regions"]["ball"] = {"style": "sphere", "center": [5, 5, 5], "radius": 4.0, "units": "box"}
    d["atoms"][0]["create"] = {"positions": [[5, 5, 7.0]]}  # 2.0 from the surface
    eng = Engine([build_case(config_from_dict(d))])
    eng.setup()
    cs = CutoffStyle(STYLES["lj93"], "force-shift")
    p = {"epsilon": 1.0, "sigma": 1.0, "cutoff": 2.5}
    np.testing.assert_allclose(eng.state.f[0, 0], [0, 0, -cs.force(2.0, p)], rtol=1e-15, atol=1e-300)
    e, _ = eng.region_walls[0].apply(eng.state, True)
    np.testing.assert_allclose(e[0], cs.energy(2.0, p), rtol=1e-15)


# ----------------------------------------------------------------------------- config, sweeps, export

YAML = """\
box: {lo: [0, 0, 0], hi: [10, 10, 10], boundary: [p, p, f]}
atoms:
  - group: a
    create: {positions: [[1, 1, 5]]}
    mass: 1.0
walls:
  w:
    style: lj93
    units: box
WALL
    zlo: {coord: 0.0, epsilon: 1.0, sigma: 1.0, cutoff: 2.5}
run: {steps: 0}
"""


@pytest.mark.parametrize("wall,line,field,message", [
    ("    cutoff_mode: smooth\n    switch_on: 2.5", 11, "walls.w.switch_on", "must be smaller than the cut-off"),
    ("    cutoff_mode: force-shift\n    switch_on: 1.0", 11, "walls.w.switch_on", "needs cutoff_mode: smooth"),
    ("    switch_on: 1.0", 10, "walls.w.switch_on", "needs cutoff_mode: smooth"),
    ("    cutoff_mode: smooth", 10, "walls.w.cutoff_mode", "needs switch_on"),
    ("    cutoff_mode: cubic", 10, "walls.w.cutoff_mode", "'shift', 'force-shift' or 'smooth'"),
    ("    cutoff_mode: smooth\n    switch_on: -1", 11, "walls.w.switch_on", "greater than or equal to 0"),
])
def test_config_errors_name_file_line_and_field(wall, line, field, message):
    with pytest.raises(ConfigError) as exc:
        load_config_text(YAML.replace("WALL", wall), "scene.yaml")
    text = str(exc.value)
    assert re.search(rf"scene\.yaml:{line}:\d+: {re.escape(field)}: ", text), text
    assert message in text, text


def test_ees_and_fix_lines():
    """wall/ees takes only shift; a fix line takes cutoff_mode/switch_on next to `fix:`."""
    ees = YAML.replace("style: lj93", "style: ees").replace("WALL", "    cutoff_mode: force-shift")
    ees = ees.replace("mass: 1.0", "mass: 1.0\n    shape: [0.3, 0.3, 0.3]")
    with pytest.raises(ConfigError, match=r"scene\.yaml:11:\d+: walls\.w\.cutoff_mode: wall/ees takes only"):
        load_config_text(ees, "scene.yaml")
    text = YAML.split("walls:")[0] + ("walls:\n  w:\n    fix: fix w all wall/lj93 zlo 0.0 1.0 1.0 2.5 units box\n"
                                      "    cutoff_mode: smooth\n    switch_on: 2.0\nrun: {steps: 0}\n")
    cfg = load_config_text(text)
    assert cfg.walls["w"].cutoff_mode == "smooth" and cfg.walls["w"].switch_on == 2.0
    spec = build_case(cfg).soft_walls[0]
    assert spec.cutoff_mode == "smooth" and spec.faces[0].params["switch_on"] == 2.0


def test_sweep_over_mode_and_switch_on_and_batching():
    """A zip over cutoff_mode (with switch_on null where not smooth) and a product over switch_on:
    modes split into batches, switch_on values share one, and a case gives the same numbers alone
    or in its batch."""
    d = gas(count=40, steps=200, thermo=50)
    d["sweep"] = {"zip": {"dim": "treatment", "params": {
        "mode": {"path": "walls.w.cutoff_mode", "values": ["shift", "force-shift", "smooth"]},
        "on": {"path": "walls.w.switch_on", "values": [None, None, 2.0]}}}}
    plan = load(d)
    cases = [build_case(sc.config, sc.seed_key) for sc in plan.cases]
    assert [c.soft_walls[0].cutoff_mode for c in cases] == list(CUTOFF_MODES)
    assert len({structure_key(c) for c in cases}) == 3
    d2 = gas("smooth", 2.0, count=40, steps=200, thermo=50)
    d2["sweep"] = {"product": {"on": {"path": "walls.w.switch_on", "values": [1.0, 1.5, 2.2]}}}
    plan2 = load(d2)
    cases2 = [build_case(sc.config, sc.seed_key) for sc in plan2.cases]
    assert len({structure_key(c) for c in cases2}) == 1
    together = Engine(cases2).run()
    for i, c in enumerate(cases2):
        alone = Engine([c]).run()[0]
        for key, want in alone.data.items():
            assert np.array_equal(together[i].data[key], want, equal_nan=True), key
    assert not np.array_equal(together[0].data["etot"], together[2].data["etot"])


def test_export_refuses_a_non_shift_region_wall():
    """A flat wall with a non-shift mode is exported as a wall/table (tests/lammps/test_cutoff_table.py);
    a region wall cannot be."""
    for mode, on in (("force-shift", None), ("smooth", 2.0)):
        d = gas("shift")
        d["walls"] = {"ball": {"style": "region", "region": "ball", "potential": "lj93", "epsilon": 1.0,
                               "sigma": 1.0, "cutoff": 2.5, "cutoff_mode": mode, "energy": True,
                               **({"switch_on": on} if on else {})}}
        d["regions"]["ball"] = {"style": "sphere", "center": [5, 5, 5], "radius": 4.0, "units": "box"}
        with pytest.raises(ExportError, match=rf"walls\.ball: cutoff_mode {mode} on wall/region \(LAMMPS's wall "
                                              rf"fixes only shift"):
            check_exportable(config_from_dict(d))
        check_exportable(config_from_dict(gas(mode, on)))
    check_exportable(config_from_dict(gas("shift")))


@pytest.mark.lammps
def test_lammps_shift_has_the_same_low_order(tmp_path):
    """LAMMPS (whose walls are `shift`) on the same lj93 slit: its energy drift has wallbatch's
    shift numbers (an ideal gas: no chaos, the runs agree to rounding) and the same order < 1.6,
    which force-shift and smooth raise to ~2 (test_force_continuous_modes_restore_second_order)."""
    from wallbatch.lammps import validate as validate_mod
    from wallbatch.lammps.export import lab_frame, lammps_ready

    dts = [0.008, 0.004, 0.002, 0.001]
    ours, theirs = [], []
    for i, dt in enumerate(dts):
        d = gas("shift", steps=int(round(10.0 / dt)), thermo=int(round(1.0 / dt)))
        d["timestep"] = dt
        cfg, _ = lab_frame(lammps_ready(config_from_dict(d))[0])
        case = build_case(cfg)
        exp = validate_mod.export_case(cfg, case, data_dir=tmp_path / str(i))
        (tmp_path / str(i)).mkdir(exist_ok=True)
        ref = validate_mod.run_lammps(exp, tmp_path / str(i))
        etot = next(c.keyword for c in exp.thermo_columns if c.key == "etot")
        res = Engine([case]).run()[0]
        t = res.data["time"]
        ours.append(abs(np.polyfit(t, res.data["etot"], 1)[0]) / case.natoms)
        assert "norm no" in exp.script  # extensive totals, as wallbatch
        theirs.append(abs(np.polyfit(t, ref[etot], 1)[0]) / case.natoms)
    order = lambda v: float(np.polyfit(np.log(dts), np.log(v), 1)[0])  # noqa: E731
    print("drift wallbatch", ours, "LAMMPS", theirs, "orders", order(ours), order(theirs))
    np.testing.assert_allclose(theirs, ours, rtol=1e-6)
    assert order(theirs) < 1.6 and order(ours) < 1.6, (order(theirs), order(ours))
