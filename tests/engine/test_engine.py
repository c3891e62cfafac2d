"""Tests for wallbatch.engine.engine (with walls.py and scene.py): the step, reflect, variables,
dt/reset, lattice scaling, groups, failures, time-based runs and batching.

Every expected number is computed here by hand or by a small independent scalar reference
(physics.md §1.2, §2, §3, §7, §9, §10, §15), never read back from the engine.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from factories import atoms, run_one, slab_gas
from factories import box_scene as scene
from factories import run_dataset as run

from wallbatch.config.models import config_from_dict
from wallbatch.engine.engine import Engine, run_cases
from wallbatch.scene.case import structure_key
from wallbatch.scene.build import build_case

FCC_LJ_0_8442 = 1.6795961913825073  # physics.md §2.1 table
REAL_FTM2V = 1.0 / 48.88821291**2
METAL_FTM2V = 9648.533823273016


# ----------------------------------------------------------------------------- helpers


def engine(d) -> Engine:
    """An Engine on the scene, set up at step 0 (forces and outputs computed)."""
    eng = Engine([build_case(config_from_dict(d))])
    eng.setup()
    return eng


def harmonic_face(coord, eps, rc):
    return {"coord": coord, "epsilon": eps, "cutoff": rc}


def lj_face(coord, eps=1.0, sigma=1.0, rc=2.5):
    return {"coord": coord, "epsilon": eps, "sigma": sigma, "cutoff": rc}


def ideal_gas(walls, *, dt, total_time, seed=3, n=20, hi_z=6.0, thermo=1, output=None):
    """n atoms at temperature 1 in a slab (x, y periodic, z fixed), no pair forces."""
    return slab_gas(walls, n=n, hi=(5, 5, hi_z), margin=1.5, temperature=1.0, seed=seed, dt=dt,
                    steps=int(round(total_time / dt)), thermo=thermo, output=output)


# ----------------------------------------------------------------------------- energy conservation


@pytest.mark.slow
@pytest.mark.parametrize("style", ["lj93", "harmonic"])
def test_soft_walls_conserve_energy_to_second_order(style):
    # Both faces' cut-offs span the whole box, so every atom always feels a smooth force (no
    # force kink at rc): velocity Verlet's energy error is then cleanly O(dt^2).
    face = (lambda c: lj_face(c, rc=6.0)) if style == "lj93" else (lambda c: harmonic_face(c, 1.0, 6.0))
    walls = {"w": {"style": style, "units": "box", "energy": True, "zlo": face(0.0), "zhi": face(6.0)}}
    drift = []
    for dt in (0.004, 0.002):
        ds = run(ideal_gas(walls, dt=dt, total_time=6.0))
        assert ds.status.item() == "ok", ds.error.item()
        assert np.allclose(ds.pe.values, ds.wall_energy.sel(fix="w").values)  # energy: true
        assert np.ptp(ds.pe.values) > 0.1  # the walls really exchange energy with the gas
        etot = ds.etot.values
        drift.append(np.max(np.abs(etot - etot[0])))
    assert drift[1] > 0
    assert 3.0 < drift[0] / drift[1] < 5.0


@pytest.mark.slow  # 1-3 s: kept out of the fast subset's one-minute budget
def test_reflect_energy_error_is_first_order():
    # A harmonic zlo spring spanning the box pushes every atom against a reflecting zhi wall
    # (a "ball bouncing on a floor"). Between bounces velocity Verlet with this linear force has
    # tiny O(dt^2) bounded error; each reflection changes etot by g(2 delta - dt v_half)
    # (physics.md §7: primitive splitting, O(dt)), pseudo-random in sign. The energy error is a
    # random walk with O(dt) steps: its quadratic variation sqrt(sum d(etot)^2) over a fixed
    # time halves when dt halves (hundreds of bounces make that ratio sharp; the max of one
    # random walk is too noisy to pin).
    walls = {"soft": {"style": "harmonic", "units": "box", "energy": True,
                      "zlo": harmonic_face(0.0, 1.0, 10.0)},
             "mirror": {"style": "reflect", "units": "box", "zhi": "EDGE"}}
    qv, bounces = [], []
    for dt in (0.004, 0.002):
        d = ideal_gas(walls, dt=dt, total_time=4.0, n=100, hi_z=5.0,
                      output=["step", "time", "dt", "ke", "pe", "etot", "reflect_count"])
        ds = run(d)
        assert ds.status.item() == "ok", ds.error.item()
        etot = ds.etot.values
        qv.append(np.sqrt(np.sum(np.diff(etot) ** 2)))
        bounces.append(np.nansum(ds.reflect_count.values))
    assert min(bounces) > 300
    assert abs(bounces[0] - bounces[1]) < 0.05 * bounces[0]  # same physics at both dt
    assert qv[0] > 1e-2  # a real, measurable error (compare O(1e-4) for smooth soft walls)
    assert 1.6 < qv[0] / qv[1] < 2.5


# ----------------------------------------------------------------------------- wall/reflect


def test_reflect_single_atom_no_force():
    # physics.md §15: (x, v) = (0.05, -1) -> (0.05, +1) after one step with dt = 0.1
    d = scene([atoms("a", [(5, 5, 0.05)], [(0, 0, -1.0)])],
              {"m": {"style": "reflect", "units": "box", "zlo": "EDGE"}})
    eng = engine(d)
    eng.advance(1)
    assert eng.state.step.tolist() == [1]
    assert eng.state.x[0, 0].tolist() == pytest.approx([5.0, 5.0, 0.05], abs=1e-15)
    assert eng.state.v[0, 0].tolist() == [0.0, 0.0, 1.0]


def test_reflect_single_atom_with_force():
    # §7 example with a force: v_half = v0 + dt/2 f0, drift, mirror, then the final half kick with
    # the force at the mirrored position. The force comes from a harmonic zhi wall spanning the box
    # (eps chosen so that f(0.05) = -2, as in the §7 example); it is not constant, so the final v
    # is computed by hand.
    eps, rc, top = 1.0 / 10.05, 20.0, 10.0
    force = lambda z: -2.0 * eps * (rc - (top - z))  # noqa: E731  (hi wall pushes -z)
    d = scene([atoms("a", [(5, 5, 0.05)], [(0, 0, -1.0)])],
              {"m": {"style": "reflect", "units": "box", "zlo": "EDGE"},
               "spring": {"style": "harmonic", "units": "box", "zhi": harmonic_face("EDGE", eps, rc)}})
    eng = engine(d)
    eng.advance(1)
    dt = 0.1
    v_half = -1.0 + 0.5 * dt * force(0.05)
    z = 0.05 + dt * v_half
    assert z < 0 and v_half == pytest.approx(-1.1, rel=1e-12)
    z = -z  # mirrored: 0.06
    v = -v_half + 0.5 * dt * force(z)
    assert eng.state.x[0, 0, 2] == pytest.approx(0.06, rel=1e-12)
    assert eng.state.v[0, 0, 2] == pytest.approx(v, rel=1e-13)
    assert v == pytest.approx(1.1 - 0.1 * 10.06 / 10.05, rel=1e-13)


def test_reflect_keeps_every_atom_inside():
    rng = np.random.default_rng(5)
    n = 200
    x = rng.uniform(0.2, 2.8, (n, 3))
    v = rng.normal(0.0, 3.0, (n, 3))
    d = scene([atoms("a", x, v)],
              {"box": {"style": "reflect", "units": "box", "xlo": "EDGE", "xhi": "EDGE",
                       "ylo": "EDGE", "yhi": "EDGE", "zlo": 0.0, "zhi": 3.0}},
              hi=(3.0, 3.0, 3.0), timestep=0.02, steps=300)
    eng = engine(d)
    ke0 = np.sum(eng.state.v ** 2)
    for _ in range(300):
        eng.advance(1)
        assert eng.state.ncases == 1, eng.errors
        assert np.all((eng.state.x >= 0.0) & (eng.state.x <= 3.0))
    # no force: reflection only flips signs, so |v| per component is conserved exactly
    assert np.array_equal(np.sort(np.abs(eng.state.v), axis=None), np.sort(np.abs(v), axis=None))
    assert np.sum(eng.state.v ** 2) == pytest.approx(ke0, rel=1e-14)
    ds = run(d)
    assert ds.status.item() == "ok"


@pytest.mark.parametrize("frame, v_after", [("lab", -1.0), ("wall", 2 * (-2.0) - 1.0)])
def test_reflect_moving_wall_frame(frame, v_after):
    # zhi wall at vdisplace(5, -2): 5 - 2 n dt, moving at v_wall = -2. The atom at 4.75 moving +1
    # reaches 4.85 at step 1, past the wall at 4.8: mirrored to 2*4.8 - 4.85 = 4.75.
    # lab: v -> -v = -1 (LAMMPS); wall: v -> 2 v_wall - v = -5.
    d = scene([atoms("a", [(5, 5, 4.75)], [(0, 0, 1.0)])],
              {"m": {"style": "reflect", "units": "box", "frame": frame, "zhi": "v_top"}},
              variables={"top": "vdisplace(5.0, -2.0)"}, steps=1,
              output={"thermo": ["step", "time", "dt", "ke", "reflect_count", "reflect_impulse"]})
    eng = engine(d)
    eng.advance(1)
    assert eng.state.x[0, 0, 2] == pytest.approx(4.75, abs=1e-13)
    assert eng.state.v[0, 0, 2] == pytest.approx(v_after, rel=1e-12)
    ds = run(d)
    assert ds.reflect_count.sel(face="m/zhi").values.tolist() == [0.0, 1.0]
    # momentum given to the wall along +z: m (v_before - v_after) / ftm2v
    assert ds.reflect_impulse.sel(face="m/zhi").values[1] == pytest.approx(1.0 - v_after, rel=1e-12)
    assert ds.ke.values[1] == pytest.approx(0.5 * v_after**2, rel=1e-12)


def test_reflect_count_and_impulse_real_units():
    # One atom bouncing between zlo = 0 and zhi = 10 with no force: the reflected trajectory is
    # the unfolded one z = 5.05 + 0.3 t folded into the box. Crossings of the unfolded z at
    # 10 (zhi, step 17), 20 (zlo, step 50), 30 (zhi, step 84).
    m, vz = 12.0, 0.3
    d = scene([atoms("a", [(5, 5, 5.05)], [(0, 0, vz)], mass=m)],
              {"m": {"style": "reflect", "units": "box", "zlo": "EDGE", "zhi": "EDGE"}},
              units="real", timestep=None, steps=100, thermo=50,
              output={"thermo": ["step", "time", "dt", "ke", "reflect_count", "reflect_impulse"]})
    ds = run(d)
    assert ds.status.item() == "ok"
    assert ds.dt.values[0] == 1.0  # the real-units default timestep (fs)
    count = ds.reflect_count
    assert count.sel(face="m/zhi").values.tolist() == [0.0, 1.0, 1.0]
    assert count.sel(face="m/zlo").values.tolist() == [0.0, 1.0, 0.0]
    per = 2.0 * m * vz / REAL_FTM2V  # kcal/mol/Angstrom * fs
    imp = ds.reflect_impulse
    assert imp.sel(face="m/zhi").values[1:] == pytest.approx([per, per], rel=1e-12)
    assert imp.sel(face="m/zlo").values[1:] == pytest.approx([-per, 0.0], rel=1e-12)
    assert imp.sel(face="m/zhi").values[0] == 0.0


def test_reflect_variable_coord_lattice_units():
    # physics.md §15: a variable zhi wall under lattice sc 0.5 (lj: spacing 2^(1/3)) reflects about
    # 7.3 * 1.2599 = 9.19742; constants and variables are scaled, EDGE is not.
    spacing = (1.0 / 0.5) ** (1.0 / 3.0)
    d = scene([atoms("a", [(5, 5, 9.19)], [(0, 0, 1.0)])],
              {"m": {"style": "reflect", "zhi": "v_w"}},  # units lattice (default)
              lattice={"style": "sc", "scale": 0.5}, variables={"w": "7.3"}, timestep=0.01)
    eng = engine(d)
    eng.advance(1)
    wall = 7.3 * spacing
    assert wall == pytest.approx(9.19742, abs=1e-5)
    assert eng.state.x[0, 0, 2] == pytest.approx(2 * wall - 9.20, rel=1e-13)
    assert eng.state.v[0, 0, 2] == -1.0


# ----------------------------------------------------------------------------- variables


HEAVY = 1.0e15  # a probe atom that does not move: the force on it reads the wall position


def _probe_scene(coord, variables, *, steps=12, dt=0.1, x=5.0, **extra):
    eps, rc = 1.5, 4.0
    d = scene([atoms("probe", [(x, 5, 5)], mass=HEAVY)],
              {"w": {"style": "harmonic", "units": "box", "xlo": harmonic_face(coord, eps, rc)}},
              variables=variables, timestep=dt, steps=steps, thermo=1, **extra)
    # lo face: vector entry = side * F = -2 eps (rc - (x - coord))
    expected = lambda c: -2.0 * eps * (rc - (x - c))  # noqa: E731
    return d, expected


@pytest.mark.parametrize("expr, position", [
    ("ramp(2.0, 3.0)", lambda n, dt, N: 2.0 + (n / N) * (3.0 - 2.0)),
    ("vdisplace(2.0, 0.5)", lambda n, dt, N: 2.0 + 0.5 * n * dt),
    ("swiggle(2.0, 0.5, 0.8)", lambda n, dt, N: 2.0 + 0.5 * math.sin(2 * math.pi / 0.8 * n * dt)),
    ("cwiggle(2.0, 0.5, 0.8)", lambda n, dt, N: 2.0 + 0.5 * (1 - math.cos(2 * math.pi / 0.8 * n * dt))),
    ("2.0 + 0.01 * step", lambda n, dt, N: 2.0 + 0.01 * n),
])
def test_variable_wall_position_every_step(expr, position):
    steps, dt = 12, 0.1
    d, expected = _probe_scene("v_w", {"w": expr}, steps=steps, dt=dt)
    ds = run(d)
    assert ds.status.item() == "ok", ds.error.item()
    n = ds.step.values
    assert n.tolist() == list(range(steps + 1))
    want = [expected(position(k, dt, steps)) for k in n]
    assert ds.wall_force.sel(face="w/xlo").values == pytest.approx(want, rel=1e-12, abs=1e-12)


def test_variable_epsilon():
    # epsilon may be a variable: it is re-evaluated every step
    steps, dt, rc, x = 5, 0.1, 4.0, 5.0
    d = scene([atoms("probe", [(x, 5, 5)], mass=HEAVY)],
              {"w": {"style": "harmonic", "units": "box",
                     "xlo": {"coord": 2.0, "epsilon": "v_k", "cutoff": rc}}},
              variables={"k": "1.0 + step"}, timestep=dt, steps=steps)
    ds = run(d)
    want = [-2.0 * (1.0 + k) * (rc - (x - 2.0)) for k in range(steps + 1)]
    assert ds.wall_force.values[:, 0] == pytest.approx(want, rel=1e-12)


def test_ramp_follows_time_fraction_in_time_based_run():
    # config.md: with run: {time: T}, ramp moves with the fraction of simulated time elapsed
    d, expected = _probe_scene("v_w", {"w": "ramp(2.0, 3.0)"}, dt=0.03)
    d["run"] = {"time": 1.0, "thermo": {"time": 0.25}}
    ds = run(d)
    assert ds.status.item() == "ok", ds.error.item()
    t = ds.time.values
    assert t.tolist() == [0.0, 0.25, 0.5, 0.75, 1.0]
    want = [expected(2.0 + tt / 1.0) for tt in t]
    assert ds.wall_force.sel(face="w/xlo").values == pytest.approx(want, rel=1e-12)


def test_vdisplace_uses_elapsed_time_under_dt_reset():
    # decisions table: vdisplace with dt_reset is allowed and uses elapsed simulated time. A light
    # atom oscillating in a z spring makes dt vary; the heavy probe reads the x wall position.
    eps, rc, x = 1.5, 4.0, 5.0
    d = scene([atoms("probe", [(x, 5, 5)], mass=HEAVY),
               atoms("osc", [(5, 5, 3.0)], [(0, 0, 0.7)])],
              {"w": {"style": "harmonic", "units": "box", "group": "probe",
                     "xlo": harmonic_face("v_w", eps, rc)},
               "spring": {"style": "harmonic", "units": "box", "group": "osc",
                          "zlo": harmonic_face(0.0, 2.0, 10.0), "zhi": harmonic_face(10.0, 2.0, 10.0)}},
              variables={"w": "vdisplace(1.0, 0.2)"}, steps=30, thermo=1,
              dt_reset={"every": 1, "xmax": 0.05, "units": "box"})
    ds = run(d)
    assert ds.status.item() == "ok", ds.error.item()
    dts = ds.dt.values
    assert np.ptp(dts) > 1e-3  # dt really varies
    t = ds.time.values
    want = -2.0 * eps * (rc - (x - (1.0 + 0.2 * t)))
    assert ds.wall_force.sel(face="w/xlo").values == pytest.approx(want, rel=1e-12)
    # with a constant dt this would be 1 + 0.2 * n * dt_now, which differs
    wrong = -2.0 * eps * (rc - (x - (1.0 + 0.2 * ds.step.values * dts)))
    assert not np.allclose(wrong, want, rtol=1e-6)


# ----------------------------------------------------------------------------- dt/reset


def ref_dt(v, f, m, xmax, *, ftm2v=1.0, mvv2e=1.0, emax=None, tmin=None, tmax=None):
    """physics.md §9 for one atom, written out independently."""
    v, f = np.asarray(v, float), np.asarray(f, float)
    vn, fn = math.sqrt(v @ v), math.sqrt(f @ f)
    dtv = xmax / vn if vn > 0 else 1e20
    dtf = math.sqrt(2.0 * xmax / (ftm2v * fn / m)) if fn > 0 else 1e20
    dt = min(dtv, dtf)
    if emax is not None and vn * fn > 0:
        dt = min(dt, emax / (fn * vn) / math.sqrt(ftm2v * mvv2e))
    disp = dt * v + 0.5 * dt * dt * (f / m) * ftm2v
    dr = math.sqrt(disp @ disp)
    if dr > xmax:
        dt = dt * xmax / dr
    if tmin is not None:
        dt = max(dt, tmin)
    if tmax is not None:
        dt = min(dt, tmax)
    return dt


def _dt_scene(*, units="lj", m=1.0, vx=1.0, eps=1.0, x0=1.0, rc=2.0, xmax=0.1, steps=3, thermo=1,
              **dtr):
    """One atom at x0 moving +x inside a harmonic xlo spring: f_x = 2 eps (rc - x0) at setup."""
    d = scene([atoms("a", [(x0, 5, 5)], [(vx, 0, 0)], mass=m)],
              {"w": {"style": "harmonic", "units": "box", "xlo": harmonic_face(0.0, eps, rc)}},
              units=units, timestep=None, steps=steps, thermo=thermo,
              dt_reset={"every": 1, "xmax": xmax, "units": "box", **dtr})
    return d


def test_dt_reset_setup_reference_value():
    # §9 reference [V]: lj, m = 1, v = (1,0,0), f = (2,0,0), Xmax 0.1 box: setup dt = 0.1 * 0.1/0.11
    ds = run(_dt_scene())
    assert ds.status.item() == "ok", ds.error.item()
    assert ds.dt.values[0] == pytest.approx(0.09090909090909091, rel=1e-15)
    assert ds.time.values[0] == 0.0
    assert ds.time.values[1] == pytest.approx(0.09090909090909091, rel=1e-15)


def test_dt_reset_emax_reference_value():
    ds = run(_dt_scene(emax=0.05))  # §9: 0.025
    assert ds.dt.values[0] == pytest.approx(0.025, rel=1e-14)


def test_dt_reset_metal_reference_value():
    # §9 [V]: metal, m = 10, v = 5, f = 3, Xmax = 0.05, emax 0.5 -> 0.003701865534094182.
    # f = 2 eps (rc - r) = 2 * 1.5 * (2 - 1) = 3 eV/Angstrom.
    ds = run(_dt_scene(units="metal", m=10.0, vx=5.0, eps=1.5, xmax=0.05, emax=0.5))
    assert ds.status.item() == "ok", ds.error.item()
    assert ds.dt.values[0] == pytest.approx(0.003701865534094182, rel=1e-14)


def test_dt_reset_trajectory_matches_scalar_reference():
    # the whole dt/time sequence against an independent velocity-Verlet + §9 loop
    eps, rc, m, xmax, steps = 1.0, 2.0, 1.0, 0.1, 8
    ds = run(_dt_scene(steps=steps))
    force = lambda x: 2.0 * eps * (rc - x) if x < rc else 0.0  # noqa: E731
    x, v = 1.0, 1.0
    f = force(x)
    dt = ref_dt([v, 0, 0], [f, 0, 0], m, xmax)
    times, dts, t = [0.0], [dt], 0.0
    for _ in range(steps):
        v += 0.5 * dt * f / m
        x += dt * v
        f = force(x)
        v += 0.5 * dt * f / m
        t += dt
        dt = ref_dt([v, 0, 0], [f, 0, 0], m, xmax)
        times.append(t)
        dts.append(dt)
    assert ds.dt.values == pytest.approx(dts, rel=1e-13)
    assert ds.time.values == pytest.approx(times, rel=1e-13)
    assert len(set(np.round(dts, 12))) == len(dts)  # dt changed at every step


@pytest.mark.parametrize("bounds, expected", [
    ({"tmax": 0.05}, 0.05),
    ({"tmin": 0.2}, 0.2),
    ({"tmin": 0.01, "tmax": 0.5}, 0.09090909090909091),
    ({"tmax": "INF"}, 0.09090909090909091),
    ({"tmax": "NULL", "tmin": "NULL"}, 0.09090909090909091),
    ({"tmax": None, "tmin": None}, 0.09090909090909091),
    ({"tmin": "INF"}, 0.09090909090909091),
])
def test_dt_reset_tmin_tmax_clamps(bounds, expected):
    ds = run(_dt_scene(**bounds))
    assert ds.status.item() == "ok", ds.error.item()
    assert ds.dt.values[0] == pytest.approx(expected, rel=1e-15)


def test_dt_reset_nothing_moves_gives_big_dt():
    # §9 quirk: all v = f = 0 and no tmax -> dt = 1e20
    d = scene([atoms("a", [(5, 5, 5)])], steps=2, timestep=None, boundary=("p", "p", "p"),
              dt_reset={"every": 1, "xmax": 0.1, "units": "box"})
    ds = run(d)
    assert ds.dt.values.tolist() == [1e20, 1e20, 1e20]
    assert ds.time.values.tolist() == [0.0, 1e20, 2e20]


def test_dt_reset_cadence_and_time_is_cumulative_dt():
    # every 3: dt changes only at steps 0, 3, 6, ...; time[k+1] = time[k] + dt in force at k
    d = _dt_scene(steps=9, every=3, xmax=0.05)
    d["dt_reset"]["every"] = 3
    ds = run(d)
    dts, t, steps = ds.dt.values, ds.time.values, ds.step.values
    assert np.allclose(np.diff(t), dts[:-1], rtol=1e-14, atol=0)
    assert t == pytest.approx(np.concatenate([[0.0], np.cumsum(dts[:-1])]), rel=1e-14)
    changed = steps[1:][dts[1:] != dts[:-1]]
    assert changed.tolist() == [3, 6, 9]


def test_dt_reset_lattice_xmax_uses_xlattice():
    # units lattice (default): Xmax * xlattice; f = 0, motion along z: dt = xmax * a / |v|
    d = scene([atoms("a", [(5, 5, 5)], [(0, 0, 2.0)])], boundary=("p", "p", "p"), steps=1,
              lattice={"style": "fcc", "scale": 0.8442},
              dt_reset={"every": 1, "xmax": 0.1})
    ds = run(d)
    assert ds.status.item() == "ok", ds.error.item()
    assert ds.dt.values[0] == pytest.approx(0.1 * FCC_LJ_0_8442 / 2.0, rel=1e-15)


# ----------------------------------------------------------------------------- lattice units


def test_lattice_scales_constant_and_variable_coords_not_edge():
    # §15: lattice fcc 0.8442 (lj), harmonic xlo 1.0 (constant) and ylo v_wy = 1.0 (variable)
    # scaled by the spacing, zlo EDGE (= box lo z = 1.0) not scaled.
    eps, rc, a = 1.0, 2.5, FCC_LJ_0_8442
    pos = (2.0, 2.5, 1.5)
    d = scene([atoms("a", [pos])],
              {"w": {"style": "harmonic", "energy": True,  # units lattice (default)
                     "xlo": harmonic_face(1.0, eps, rc), "ylo": harmonic_face("v_wy", eps, rc),
                     "zlo": harmonic_face("EDGE", eps, rc)}},
              lo=(0.0, 0.0, 1.0), lattice={"style": "fcc", "scale": 0.8442}, variables={"wy": "1.0"},
              steps=0)
    ds = run(d)
    assert ds.status.item() == "ok", ds.error.item()
    r = [pos[0] - 1.0 * a, pos[1] - 1.0 * a, pos[2] - 1.0]
    e = sum(eps * (ri - rc) ** 2 for ri in r)
    assert ds.wall_energy.values[0, 0] == pytest.approx(e, rel=1e-14)
    assert ds.wall_force.values[0] == pytest.approx([-2 * eps * (rc - ri) for ri in r], rel=1e-14)


@pytest.mark.parametrize("units", ["real", "metal"])
def test_lattice_scale_is_the_constant_in_real_and_metal(units):
    eps, rc = 1.0, 2.5
    d = scene([atoms("a", [(4.0, 5, 5)])],
              {"w": {"style": "harmonic", "xlo": harmonic_face(1.0, eps, rc)}},
              units=units, lattice={"style": "fcc", "scale": 3.52}, steps=0)
    ds = run(d)
    r = 4.0 - 3.52
    assert ds.wall_energy.values[0, 0] == pytest.approx(eps * (r - rc) ** 2, rel=1e-14)


def test_lattice_units_without_lattice_is_an_error():
    from wallbatch.config.source import ConfigError
    d = scene([atoms("a", [(4.0, 5, 5)])],
              {"w": {"style": "harmonic", "xlo": harmonic_face(1.0, 1.0, 2.5)}})
    with pytest.raises(ConfigError, match="units: box"):
        config_from_dict(d)


# ----------------------------------------------------------------------------- groups, energy flag


LJ93_E_1_2 = -0.48889776297466175  # §15: lj93 r = 1.2, eps = sigma = 1, rc = 2.5
LJ93_FW_1_2 = 1.2529525597914448


@pytest.mark.parametrize("energy", [True, False])
def test_group_restricted_wall_and_energy_flag(energy):
    # wall zlo at 2.0 acting on group `in` only: the `in` atom sits at r = 1.2; the `out` atom is
    # behind the wall (z = 1.0) but is not in the group, so it feels nothing and is no error.
    d = scene([atoms("in", [(2, 5, 3.2)]), atoms("out", [(5, 5, 1.0)])],
              {"w": {"style": "lj93", "units": "box", "group": "in", "energy": energy,
                     "zlo": lj_face(2.0)}}, steps=0)
    ds = run(d)
    assert ds.status.item() == "ok", ds.error.item()
    assert ds.wall_energy.values[0, 0] == pytest.approx(LJ93_E_1_2, rel=1e-14)
    assert ds.wall_force.values[0, 0] == pytest.approx(LJ93_FW_1_2, rel=1e-14)
    assert ds.pe.values[0] == (pytest.approx(LJ93_E_1_2, rel=1e-14) if energy else 0.0)
    assert ds.etot.values[0] == pytest.approx(ds.ke.values[0] + ds.pe.values[0], rel=1e-15)
    eng = engine(d)
    assert eng.state.f[0, 0].tolist() == pytest.approx([0.0, 0.0, -LJ93_FW_1_2], rel=1e-14)
    assert eng.state.f[0, 1].tolist() == [0.0, 0.0, 0.0]


# ----------------------------------------------------------------------------- failures


def _piston(extra_wall_steps=60, rc=1.0):
    # a harmonic zlo wall moving up at speed 1 (vdisplace) overtakes heavy atom 1 at z = 5.05
    # between step 50 (wall at 5.0) and step 51 (wall at 5.1); atom 0 at z = 8 is still ahead.
    return scene([atoms("a", [(5, 5, 8.0), (2, 2, 5.05)], mass=HEAVY)],
                 {"piston": {"style": "harmonic", "units": "box",
                             "zlo": harmonic_face("v_w", 1.0, rc)}},
                 variables={"w": "vdisplace(0.0, 1.0)"}, boundary=("p", "p", "f"),
                 steps=extra_wall_steps, thermo=10)


def test_atom_behind_wall_fails_the_case():
    res = run_one(_piston())
    assert res.status == "failed"
    msg = res.error
    assert "piston" in msg and "zlo" in msg
    assert "step 51" in msg
    assert "atom ID 2" in msg
    assert "harmonic" in msg
    for name, values in res.data.items():
        assert np.isnan(values).all(), name


def test_atom_behind_wall_at_setup():
    d = scene([atoms("a", [(5, 5, 3.0), (5, 5, 1.0)])],
              {"w": {"style": "lj93", "units": "box", "zlo": lj_face(2.0)}}, steps=5)
    ds = run(d)
    assert ds.status.item() == "failed"
    msg = ds.error.item()
    assert "walls.w" in msg and "zlo" in msg and "step 0" in msg and "atom ID 2" in msg
    assert np.isnan(ds.ke.values).all() and ds.ke.shape == (6,)  # steps 0..5, thermo 1


def _lost_scene():
    # z = 9.55 + 0.1 n passes box hi 10 at step 5; no wall on zhi (the lj93 zlo wall reaches no atom:
    # it only gives the scene the compiled kernel of the other lj93 slits instead of one of its own)
    return scene([atoms("a", [(5, 5, 5.0), (5, 5, 9.55)], [(0, 0, 0), (0, 0, 1.0)])],
                 {"w": {"style": "lj93", "units": "box", "zlo": lj_face(0.0)}},
                 boundary=("p", "p", "f"), steps=10, thermo=2)


def test_lost_atom_through_fixed_boundary():
    res = run_one(_lost_scene())
    assert res.status == "failed"
    msg = res.error
    assert "lost" in msg.lower()
    assert "atom ID 2" in msg and "step 5" in msg and "fixed z boundary" in msg
    for name, values in res.data.items():
        assert np.isnan(values).all(), name




@pytest.mark.parametrize("make, nsamp", [(_piston, 7), (_lost_scene, 6)], ids=["behind-wall", "lost"])
def test_midrun_failure_of_a_single_case_gives_a_nan_dataset(make, nsamp):
    res = run_one(make())
    assert res.status == "failed"
    assert all(v.shape[0] == nsamp for v in res.data.values())
    ds = run(make())
    assert ds.status.item() == "failed"
    assert "step" in ds.error.item()
    assert ds.sizes["sample"] == nsamp
    for name in ("ke", "pe", "etot", "temp", "time", "dt"):
        assert np.isnan(ds[name].values).all(), name


# ----------------------------------------------------------------------------- time-based runs


def test_time_based_run_samples_land_exactly():
    # the lj93 zlo wall reaches no atom (z >= 4.8): the scene shares its compiled kernel with others
    d = scene([atoms("a", [(5, 5, 5)], [(0.3, 0.1, -0.2)])], {"w": {"style": "lj93", "units": "box",
              "zlo": lj_face(0.0)}}, boundary=("p", "p", "f"), timestep=0.03)
    d["run"] = {"time": 1.0, "thermo": {"time": 0.25}}
    ds = run(d)
    assert ds.status.item() == "ok", ds.error.item()
    assert ds.time.values.tolist() == [0.0, 0.25, 0.5, 0.75, 1.0]
    # 8 full steps of 0.03 (0.24) plus one clipped step of 0.01 per interval
    assert ds.step.values.tolist() == [0, 9, 18, 27, 36]
    assert ds.dt.values == pytest.approx([0.03] * 5, rel=1e-15)
    # the engine's own clocks, not just the output coordinate
    res = run_cases([build_case(config_from_dict(d))])[0]
    assert res.data["time"].tolist() == [0.0, 0.25, 0.5, 0.75, 1.0]


def test_time_based_run_with_dt_reset(monkeypatch):
    d = _dt_scene(steps=1)
    d["run"] = {"time": 0.5, "thermo": {"time": 0.1}}
    ds = run(d)
    assert ds.status.item() == "ok", ds.error.item()
    want = [0.0, 0.1, 0.2, 0.3, 0.4, 0.5]
    assert ds.time.values == pytest.approx(want, abs=1e-15)
    # the engine's own clock on the NumPy path (its kernel, time-based with dt/reset, is the NumPy
    # one bit for bit: tests/engine/test_compiled.py test_dt_reset_time_based)
    monkeypatch.setenv("WALLBATCH_NUMBA", "0")
    res = run_cases([build_case(config_from_dict(d))])[0]
    assert res.data["time"] == pytest.approx(want, abs=1e-15)
    assert np.all(np.diff(ds.step.values) >= 2)  # dt/reset keeps dt < 0.1: several steps per sample
    assert ds.dt.values[0] == pytest.approx(0.09090909090909091, rel=1e-15)
    assert np.all(ds.dt.values > 0.05) and np.all(ds.dt.values < 0.1)


def test_time_based_run_clock_is_step_count_times_dt(monkeypatch):
    """run: {time: T} at a fixed dt: the clock after n steps is n dt from the step count (as in
    step-based runs), not n repeated additions of dt, which drift (0.7999999999999999 after 8
    steps of 0.1; 1.6e-6 relative after 1e7 steps); the samples still land exactly on the
    thermo times."""
    from wallbatch.engine import compiled

    monkeypatch.setattr(compiled, "enabled", lambda: False)  # the NumPy loop, step by step
    d = scene([atoms("a", [(5, 5, 5)], [(0.01, 0.0, 0.0)])], boundary=("p", "p", "p"), timestep=0.1)
    d["run"] = {"time": 400.05, "thermo": {"time": 200.0}}
    seen: list[tuple[int, float]] = []
    real = Engine.finish_step

    def spy(self, out, sample):
        real(self, out, sample)
        seen.append((int(self.state.step[0]), float(self.state.time[0])))

    monkeypatch.setattr(Engine, "finish_step", spy)
    res = run_cases([build_case(config_from_dict(d))])[0]
    assert res.status == "ok", res.error
    assert res.data["time"].tolist() == [0.0, 200.0, 400.0, 400.05]
    landings = {2000, 4000, 4001}
    off = [(n, t) for n, t in seen if n not in landings and t != 200.0 * (n > 2000) + (n - 2000 * (n > 2000)) * 0.1]
    assert not off, off[:3]
    summed = 0.0
    for _ in range(1999):
        summed += 0.1
    assert summed != 1999 * 0.1  # the repeated sum this replaces does drift


# ----------------------------------------------------------------------------- batching


def _gas_case(eps_lo, zlo_coord=0.0, seed=3):
    walls = {"w": {"style": "lj93", "units": "box", "energy": True,
                   "zlo": lj_face(zlo_coord, eps=eps_lo, rc=2.5), "zhi": lj_face(6.0, eps=1.0, rc=2.5)},
             "m": {"style": "reflect", "units": "box", "zhi": 5.9}}
    d = ideal_gas(walls, dt=0.005, total_time=2.0, thermo=20,
                  output=["step", "time", "dt", "temp", "ke", "pe", "etot", "reflect_count", "reflect_impulse"])
    d["seed"] = seed
    return build_case(config_from_dict(d))


def test_batched_cases_are_bit_identical_to_single_runs():
    a, b = _gas_case(1.0), _gas_case(2.0)
    # epsilon 0 with the wall at z = 1 inside the gas: an atom crosses it mid-run (step 329)
    c = _gas_case(0.0, zlo_coord=1.0)
    assert structure_key(a) == structure_key(b) == structure_key(c)  # they really share a batch
    together = run_cases([a, b, c])
    alone = [run_cases([x])[0] for x in (a, b, c)]
    assert [r.status for r in together] == ["ok", "ok", "failed"]
    assert "walls.w" in together[2].error and "zlo" in together[2].error
    assert together[2].error == alone[2].error
    for r_together, r_alone in zip(together[:2], alone[:2]):
        assert r_together.data.keys() == r_alone.data.keys()
        for key in r_alone.data:
            assert np.array_equal(r_together.data[key], r_alone.data[key]), key
    # and the two epsilons really give different physics
    assert not np.array_equal(together[0].data["wall_energy"], together[1].data["wall_energy"])
