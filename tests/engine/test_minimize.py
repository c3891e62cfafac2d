"""Tests for wallbatch.engine.minimize: closed-form minima, LJ clusters between walls, batching,
every stopping criterion, and LAMMPS 22Jul2025 `minimize` as the oracle.

All objectives are written here in numpy (no engine): a 9-3 / 12-6 / harmonic wall at z = 0
acting on z, and a 12-6 LJ pair potential. Every objective works on a batch (R, N, 3) with
per-case parameters picked by ``rows``, and treats each case on its own, so batched and
single-case runs can be compared bit for bit.
"""

from __future__ import annotations

import os
import tempfile

import numpy as np
import pytest

from lammps_oracle import _load_lammps, requires_lammps
from wallbatch.engine.minimize import MinResult, minimize
from wallbatch.lammps.log import minimize_stats
from wallbatch.scene.case import MinSettings

# ----------------------------------------------------------------------------- objectives


def lj93(r, eps, sigma, rc=None):
    """9-3 wall: E = eps[(2/15)(s/r)^9 - (s/r)^3] (- E(rc) inside rc), F = -dE/dr."""
    sr3 = (sigma / r) ** 3
    sr9 = sr3 * sr3 * sr3
    e = eps * ((2.0 / 15.0) * sr9 - sr3)
    f = eps * (1.2 * sr9 - 3.0 * sr3) / r
    if rc is None:
        return e, f
    src3 = (sigma / rc) ** 3
    e_rc = eps * ((2.0 / 15.0) * src3**3 - src3)
    inside = r < rc
    return np.where(inside, e - e_rc, 0.0), np.where(inside, f, 0.0)


def lj126(r, eps, sigma):
    """12-6 wall: E = 4 eps[(s/r)^12 - (s/r)^6]."""
    sr6 = (sigma / r) ** 6
    return 4.0 * eps * (sr6 * sr6 - sr6), eps * (48.0 * sr6 * sr6 - 24.0 * sr6) / r


def harmonic(r, eps, rc):
    """Harmonic wall: E = eps (r - rc)^2 for r < rc, else 0."""
    inside = r < rc
    return np.where(inside, eps * (r - rc) ** 2, 0.0), np.where(inside, 2.0 * eps * (rc - r), 0.0)


def wall_objective(wall, **params):
    """Atoms feel ``wall(z, **params)`` from a wall at z = 0; params are (C,) arrays or floats."""

    def objective(x, rows):
        p = {k: (np.asarray(v)[rows][:, None] if np.ndim(v) else v) for k, v in params.items()}
        e, fz = wall(x[:, :, 2], **p)
        f = np.zeros_like(x)
        f[:, :, 2] = fz
        return e.sum(axis=1), f

    return objective


def lj_pair(x):
    """12-6 LJ (eps = sigma = 1), all pairs, no cut-off: (E (R,), F (R, N, 3))."""
    n = x.shape[1]
    d = x[:, :, None, :] - x[:, None, :, :]
    r2 = np.einsum("cijk,cijk->cij", d, d)
    r2 = np.where(np.eye(n, dtype=bool), 1.0, r2)
    ir6 = 1.0 / (r2 * r2 * r2)
    off = ~np.eye(n, dtype=bool)
    e = np.where(off, 4.0 * (ir6 * ir6 - ir6), 0.0)
    fr = np.where(off, 24.0 * (2.0 * ir6 * ir6 - ir6) / r2, 0.0)
    return 0.5 * e.sum(axis=(1, 2)), (fr[..., None] * d).sum(axis=2)


def slab_objective(hi, eps_w=1.0, rc_w=None):
    """LJ cluster between 9-3 walls (sigma 1) at z = 0 and z = hi; hi, eps_w per case or float."""

    def objective(x, rows):
        h = np.asarray(hi)[rows][:, None] if np.ndim(hi) else hi
        ew = np.asarray(eps_w)[rows][:, None] if np.ndim(eps_w) else eps_w
        e, f = lj_pair(x)
        z = x[:, :, 2]
        e_lo, f_lo = lj93(z, ew, 1.0, rc_w)
        e_hi, f_hi = lj93(h - z, ew, 1.0, rc_w)
        f[:, :, 2] += f_lo - f_hi
        return e + e_lo.sum(axis=1) + e_hi.sum(axis=1), f

    return objective


def cluster(n, seed, spacing=1.12, noise=0.05, z0=0.85):
    """n atoms of a perturbed simple-cubic 3x3x3 grid (a gentle start near an LJ minimum)."""
    rng = np.random.default_rng(seed)
    grid = np.array([[i, j, k] for i in range(3) for j in range(3) for k in range(3)], float)[:n]
    x = grid * spacing + rng.normal(0.0, noise, grid.shape)
    x[:, 2] += z0
    return x


def pair_distances(x):
    """Sorted interatomic distances of one configuration (N, 3)."""
    i, j = np.triu_indices(len(x), 1)
    return np.sort(np.linalg.norm(x[i] - x[j], axis=1))


def one_atom(z):
    return np.array([[[0.3, -0.2, z]]])


def run(x, objective, history=None, mass=1.0, **kw):
    """minimize() with per-case energy histories collected through the callback."""
    settings = MinSettings(**{"etol": 0.0, "ftol": 1e-10, "maxiter": 1000, "maxeval": 10000, **kw})

    def hook(rows, iterations, energies):
        for r, i, e in zip(rows, iterations, energies):
            history.setdefault(int(r), []).append((int(i), float(e)))

    return minimize(np.asarray(x, float), objective, settings, mass=mass,
                    callback=None if history is None else hook)


FIRE = {"style": "fire", "timestep": 0.005}
STYLES = [pytest.param({}, id="cg"), pytest.param(FIRE, id="fire")]


# ----------------------------------------------------------------------------- closed-form minima


@pytest.mark.parametrize("style", STYLES)
def test_lj93_wall_minimum(style):
    eps, sigma = 0.8, 1.3
    res = run(one_atom(2.4), wall_objective(lj93, eps=eps, sigma=sigma), **style)
    assert res.stop_reason == ["force tolerance"] and res.fnorm2[0] < 1e-10
    assert res.x[0, 0, 2] == pytest.approx(0.4 ** (1 / 6) * sigma, abs=1e-10)  # 1.1173...
    assert res.energy_after[0] == pytest.approx(-(2 / 3) * np.sqrt(2.5) * eps, rel=1e-14)
    assert res.x[0, 0, :2].tolist() == [0.3, -0.2]  # no force along x, y: untouched
    assert res.energy_before[0] == pytest.approx(eps * ((2 / 15) * (1.3 / 2.4) ** 9 - (1.3 / 2.4) ** 3))


@pytest.mark.parametrize("style", STYLES)
def test_lj126_wall_minimum(style):
    eps, sigma = 1.5, 0.9
    res = run(one_atom(1.7), wall_objective(lj126, eps=eps, sigma=sigma), **style)
    assert res.stop_reason == ["force tolerance"]
    assert res.x[0, 0, 2] == pytest.approx(2 ** (1 / 6) * sigma, abs=1e-11)
    assert res.energy_after[0] == pytest.approx(-eps, rel=1e-14)


def test_harmonic_wall_pushes_to_cutoff():
    # cg: a gentle wall (2 eps < 1, so no step overshoots rc) halves the distance to rc
    # every iteration until E no longer changes
    res = run(one_atom(0.5), wall_objective(harmonic, eps=0.25, rc=1.5), etol=1e-10)
    assert res.stop_reason == ["energy tolerance"]
    assert 1.5 - 1e-8 < res.x[0, 0, 2] <= 1.5 and res.energy_after[0] < 1e-16
    # fire coasts past rc, where E = F = 0, by less than dmax
    for eps in (0.25, 2.0):
        res = run(one_atom(0.5), wall_objective(harmonic, eps=eps, rc=1.5), **FIRE)
        assert res.stop_reason == ["force tolerance"] and res.fnorm2[0] == 0.0
        assert 1.5 < res.x[0, 0, 2] < 1.5 + 0.1 and res.energy_after[0] == 0.0


def test_stiff_harmonic_wall_cg_stops_short():
    """LAMMPS's quadratic line search overshoots into the force-free region (f.h = 0) and gives
    up one step short of rc ("quadratic factors are zero"); the LAMMPS test below agrees."""
    res = run(one_atom(0.5), wall_objective(harmonic, eps=2.0, rc=1.5), etol=1e-10)
    assert res.stop_reason == ["quadratic factors are zero"]
    assert res.x[0, 0, 2] == pytest.approx(1.4, abs=1e-12)
    assert (res.iterations[0], res.evaluations[0]) == (10, 11)


# ----------------------------------------------------------------------------- LJ cluster


def test_cluster_cg_descends_and_converges_fire_agrees():
    x = cluster(13, seed=5)[None]
    obj = slab_objective(hi=4.0)
    hist: dict = {}
    cg = run(x, obj, hist, ftol=1e-8)
    iters, energies = np.array(hist[0]).T
    assert iters.tolist() == list(range(1, cg.iterations[0] + 1))
    steps = np.diff(np.concatenate([cg.energy_before, energies]))
    # a line search accepts a step only if E falls (backtracking) or rises by < EMACH (secant)
    assert steps.max() < 1e-8 and (steps < 0).mean() > 0.9
    assert cg.stop_reason == ["force tolerance"] and cg.fnorm2[0] < 1e-8
    assert energies[-1] == cg.energy_after[0]
    e, f = obj(cg.x, np.array([0]))
    assert e[0] == cg.energy_after[0] and np.sqrt((f * f).sum()) == pytest.approx(cg.fnorm2[0])
    assert cg.energy_after[0] < cg.energy_before[0] - 1.0

    fire = run(x, obj, ftol=1e-8, maxiter=5000, **FIRE)
    assert fire.stop_reason == ["force tolerance"]
    assert fire.energy_after[0] == pytest.approx(cg.energy_after[0], rel=1e-12)  # -46.4718...
    # the same minimum, up to the zero modes of planar walls (shifts in x, y, turns about z)
    assert np.abs(pair_distances(fire.x[0]) - pair_distances(cg.x[0])).max() < 1e-6
    assert np.abs(np.sort(fire.x[0, :, 2]) - np.sort(cg.x[0, :, 2])).max() < 1e-6


@pytest.mark.slow
@pytest.mark.parametrize("style", STYLES)
def test_batch_equals_single_runs(style):
    x = np.stack([cluster(13, seed=s) for s in (4, 5, 6)])
    x[1, :, 2] += 0.1
    hi, eps_w = np.array([4.0, 4.6, 3.8]), np.array([1.0, 0.6, 1.4])
    kw = {"etol": 1e-8, "ftol": 1e-6, "maxiter": 3000, **style}
    hist: dict = {}
    batch = run(x, slab_objective(hi, eps_w), hist, **kw)
    assert len(set(batch.iterations.tolist())) == 3  # each case stops on its own
    for c in range(3):
        h1: dict = {}
        alone = run(x[c : c + 1], slab_objective(hi[c : c + 1], eps_w[c : c + 1]), h1, **kw)
        assert batch.stop_reason[c] == alone.stop_reason[0]
        assert batch.iterations[c] == alone.iterations[0]
        assert batch.evaluations[c] == alone.evaluations[0]
        assert np.array_equal(batch.x[c], alone.x[0])
        assert batch.energy_after[c] == alone.energy_after[0]
        assert batch.fnorm2[c] == alone.fnorm2[0]
        assert hist[c] == h1[0]


def test_inactive_cases_are_not_evaluated():
    seen = []
    obj = wall_objective(lj93, eps=1.0, sigma=1.0)

    def spy(x, rows):
        seen.extend(rows.tolist())
        return obj(x, rows)

    x = np.concatenate([one_atom(2.0), one_atom(1.5), one_atom(1.2)])
    res = minimize(x, spy, MinSettings(0.0, 1e-10, 100, 1000), active=np.array([True, False, True]))
    assert 1 not in seen
    assert res.stop_reason[1] == "inactive" and np.array_equal(res.x[1], x[1])
    assert (res.iterations[1], res.evaluations[1]) == (0, 0) and np.isnan(res.energy_after[1])
    assert res.stop_reason[0] == res.stop_reason[2] == "force tolerance"


# ----------------------------------------------------------------------------- stopping criteria


def zero_energy(force):
    """E = 0 everywhere with the given forces: walls whose energy is not counted."""

    def objective(x, rows):
        return np.zeros(len(rows)), force(x)

    return objective


def wall_force_only(x):
    f = np.zeros_like(x)
    f[:, :, 2] = lj93(x[:, :, 2], 1.0, 1.0)[1]
    return f


def test_energy_tolerance():
    res = run(one_atom(1.9), wall_objective(lj93, eps=1.0, sigma=1.0), etol=1e-4, ftol=0.0)
    assert res.stop_reason == ["energy tolerance"]
    assert (res.iterations[0], res.evaluations[0]) == (15, 27)  # LAMMPS: 15 27 (see below)


def test_force_tolerance():
    res = run(one_atom(1.9), wall_objective(lj93, eps=1.0, sigma=1.0), ftol=1e-12)
    assert res.stop_reason == ["force tolerance"] and res.fnorm2[0] < 1e-12
    assert (res.iterations[0], res.evaluations[0]) == (20, 37)  # LAMMPS: 20 37


@pytest.mark.parametrize("style", STYLES)
def test_max_iterations(style):
    res = run(one_atom(1.9), wall_objective(lj93, eps=1.0, sigma=1.0), ftol=0.0, maxiter=7, **style)
    assert res.stop_reason == ["max iterations"] and res.iterations[0] == 7
    assert res.evaluations[0] == (7 if style == {} else 8)  # fire: one extra for the v = 0 start
    none = run(one_atom(1.9), wall_objective(lj93, eps=1.0, sigma=1.0), maxiter=0, **style)
    assert none.stop_reason == ["max iterations"] and none.iterations[0] == 0
    assert np.array_equal(none.x, one_atom(1.9)) and none.energy_after[0] == none.energy_before[0]


def test_max_force_evaluations():
    res = run(one_atom(1.9), wall_objective(lj93, eps=1.0, sigma=1.0), ftol=0.0, maxeval=9)
    assert res.stop_reason == ["max force evaluations"]
    assert (res.iterations[0], res.evaluations[0]) == (9, 9)
    # checked after complete line searches only: the last one may overshoot maxeval
    res = run(cluster(13, 1)[None], slab_objective(4.0), ftol=0.0, maxeval=20)
    assert res.stop_reason == ["max force evaluations"] and 20 <= res.evaluations[0] < 40


def test_fire_ignores_maxeval_like_lammps():
    res = run(one_atom(1.9), wall_objective(lj93, eps=1.0, sigma=1.0), ftol=0.0, maxeval=9,
              maxiter=50, **FIRE)
    assert res.stop_reason == ["max iterations"] and res.evaluations[0] > 9


def test_linesearch_alpha_is_zero():
    # wall force without its energy: E never falls along the force, backtracking gives up
    res = run(one_atom(1.9), zero_energy(wall_force_only), etol=1e-6)
    assert res.stop_reason == ["linesearch alpha is zero"]
    assert (res.iterations[0], res.evaluations[0]) == (1, 22)  # LAMMPS: 1 22
    assert np.array_equal(res.x, one_atom(1.9))  # back at the start of the line search


def test_quadratic_factors_are_zero():
    # constant force, E = 0: f.h does not change along the line
    res = run(one_atom(1.9), zero_energy(lambda x: np.full_like(x, 0.7)))
    assert res.stop_reason == ["quadratic factors are zero"]
    assert (res.iterations[0], res.evaluations[0]) == (1, 2)  # LAMMPS: 1 2
    assert np.array_equal(res.x, one_atom(1.9))


def test_forces_are_zero():
    res = run(one_atom(1.9), zero_energy(np.zeros_like), etol=1e-4)
    assert res.stop_reason == ["forces are zero"]  # LAMMPS says "search direction is not downhill"
    assert (res.iterations[0], res.evaluations[0]) == (1, 0) and res.fnorm2[0] == 0.0
    fire = run(one_atom(1.9), zero_energy(np.zeros_like), **FIRE)
    assert fire.stop_reason == ["force tolerance"]  # LAMMPS: force tolerance, 1 2
    assert (fire.iterations[0], fire.evaluations[0]) == (1, 2)


def test_search_direction_is_not_downhill():
    # forces so small that f.h underflows to 0 while h itself is not zero
    res = run(one_atom(1.9), zero_energy(lambda x: np.full_like(x, 1e-200)))
    assert res.stop_reason == ["search direction is not downhill"]
    assert (res.iterations[0], res.evaluations[0]) == (1, 0)


@pytest.mark.slow
def test_fire_max_iterations_with_vf_negative():
    # zero forces keep v.f = 0 (not > 0): velocity reset in every iteration, 2000 allowed
    res = run(one_atom(1.9), zero_energy(np.zeros_like), ftol=0.0, maxiter=10000, **FIRE)
    assert res.stop_reason == ["max iterations with v.f negative"]
    assert res.iterations[0] == 2001 and res.evaluations[0] == 2 * 2000


@pytest.mark.parametrize("style", STYLES)
def test_nan_stops_the_case_only(style):
    good = wall_objective(lj93, eps=1.0, sigma=1.0)

    def objective(x, rows):
        e, f = good(x, rows)
        e[(rows == 1) & (x[:, 0, 2] < 1.0)] = np.nan  # case 1 breaks on its way down
        return e, f

    x = np.concatenate([one_atom(1.9), one_atom(1.9)])
    res = minimize(x, objective, MinSettings(0.0, 1e-10, 1000, 10000, **style))
    assert res.stop_reason == ["force tolerance", "NaN"]
    z = res.x[1, 0, 2]
    assert 1.0 <= z < 1.9  # the last accepted state, with its own energy
    assert res.energy_after[1] == good(res.x[1:], np.array([0]))[0][0]
    assert res.evaluations[1] > 0


@pytest.mark.parametrize("style", STYLES)
def test_non_conservative_wall_terminates(style):
    """Wall force present, its energy not counted (no fix_modify energy): see module docs."""
    res = run(one_atom(1.9), zero_energy(wall_force_only), **style)
    if style:  # fire follows the forces to the wall minimum
        assert res.stop_reason == ["force tolerance"]
        assert res.x[0, 0, 2] == pytest.approx(0.4 ** (1 / 6), abs=1e-10)
        assert (res.iterations[0], res.evaluations[0]) == (236, 243)  # LAMMPS: 236 243
        stop = run(one_atom(1.9), zero_energy(wall_force_only), etol=1e-6, **style)
        assert stop.stop_reason == ["energy tolerance"] and stop.iterations[0] == 22  # LAMMPS: 22 23
    else:
        assert res.stop_reason == ["linesearch alpha is zero"]


# ----------------------------------------------------------------------------- LAMMPS oracle


def lammps_minimize(x, style, walls, pair="pair_style zero 1.0\npair_coeff * *",
                    z_hi=10.0, minimize_args="1e-10 1e-10 10000 100000", timestep=0.005,
                    mass=1.0, norm=True):
    """LAMMPS (units lj, thermo norm yes: its default) minimisation of atoms in a fixed box.

    Returns final positions, extensive pe, stopping criterion, iterations, evaluations.
    """
    lammps = _load_lammps()
    n = len(x)
    with tempfile.TemporaryDirectory(prefix="wb_min_") as tmp:
        log = os.path.join(tmp, "log.lammps")
        lmp = lammps.lammps(cmdargs=["-log", log, "-screen", "none", "-nocite"])
        try:
            lmp.commands_string(
                "units lj\natom_style atomic\natom_modify map array\nboundary f f f\n"
                f"region box block -20 20 -20 20 0 {z_hi!r} units box\ncreate_box 1 box\n"
                f"mass 1 {mass!r}"
            )
            lmp.create_atoms(n, list(range(1, n + 1)), [1] * n, np.ravel(x).tolist())
            lmp.commands_string(
                f"{pair}\n{walls}\ntimestep {timestep!r}\nmin_style {style}\n"
                "thermo_style custom step pe\nthermo_modify format float %.17g\n"
                + ("" if norm else "thermo_modify norm no\n")
                +
                f"minimize {minimize_args}"
            )
            xf = np.ctypeslib.as_array(lmp.gather_atoms("x", 1, 3)).reshape(n, 3).copy()
            pe = lmp.get_thermo("pe") * (n if norm else 1)  # norm yes: thermo pe is pe / N
        finally:
            lmp.close()
        with open(log, encoding="utf-8") as fh:
            text = fh.read()
    stats = minimize_stats(text)[-1]
    return xf, pe, stats.stop_reason, stats.iterations, stats.evaluations


@requires_lammps
@pytest.mark.parametrize("style", STYLES)
def test_lammps_lj_cluster_between_lj93_walls(style):
    """20 LJ atoms (pair lj/cut 6.0: every pair inside) between wall/lj93 zlo 0 and zhi 4
    (cut-off 5.0, fix_modify energy yes), `minimize 1e-10 1e-10 10000 100000`."""
    x = cluster(20, seed=3)
    walls = ("fix w all wall/lj93 zlo 0.0 1.0 1.0 5.0 zhi 4.0 1.0 1.0 5.0 units box\n"
             "fix_modify w energy yes")
    xl, el, stop, niter, neval = lammps_minimize(
        x, style.get("style", "cg"), walls, pair="pair_style lj/cut 6.0\npair_coeff 1 1 1.0 1.0",
        z_hi=4.0)
    ours = run(x[None], slab_objective(4.0, rc_w=5.0), etol=1e-10, ftol=1e-10, maxiter=10000,
               maxeval=100000, norm=True, **style)
    assert ours.stop_reason[0] == stop == "energy tolerance"
    assert ours.energy_after[0] == pytest.approx(el, rel=1e-11, abs=0)  # -82.9142794...
    assert np.abs(ours.x[0] - xl).max() < (1e-6 if not style else 1e-10)
    # the same path: CG to ~1e-7 in positions (summation order differs), fire to ~1e-12;
    # LAMMPS: cg 199 iterations, 394 evaluations; fire 362, 369 (equal here, 2 spare for rounding)
    assert abs(ours.iterations[0] - niter) <= 2 and abs(ours.evaluations[0] - neval) <= 4


@requires_lammps
@pytest.mark.parametrize("eps", [0.25, 2.0])
@pytest.mark.parametrize("style", STYLES)
def test_lammps_single_atom_harmonic_wall(style, eps):
    """wall/harmonic zlo 0 eps 1 1.5 on one atom: same stop, counts and position as LAMMPS."""
    x = one_atom(0.5)[0]
    xl, el, stop, niter, neval = lammps_minimize(
        x, style.get("style", "cg"), f"fix w all wall/harmonic zlo 0.0 {eps!r} 1.0 1.5\n"
        "fix_modify w energy yes")
    ours = run(x[None], wall_objective(harmonic, eps=eps, rc=1.5), etol=1e-10, norm=True, **style)
    assert (ours.stop_reason[0], ours.iterations[0], ours.evaluations[0]) == (stop, niter, neval)
    assert ours.x[0] == pytest.approx(xl, abs=1e-14)
    assert ours.energy_after[0] == pytest.approx(el, abs=1e-15)


@requires_lammps
@pytest.mark.parametrize("style", STYLES)
def test_lammps_wall_without_energy(style):
    """wall/lj93 without fix_modify energy: LAMMPS and wallbatch stop the same way."""
    x = one_atom(1.9)[0]
    xl, _, stop, niter, neval = lammps_minimize(
        x, style.get("style", "cg"), "fix w all wall/lj93 zlo 0.0 1.0 1.0 2.5",
        minimize_args="1e-6 1e-10 1000 100000")
    ours = run(x[None], zero_energy(wall_force_only), etol=1e-6, norm=True, **style)
    assert (ours.stop_reason[0], ours.iterations[0], ours.evaluations[0]) == (stop, niter, neval)
    assert ours.x[0] == pytest.approx(xl, abs=1e-12)


@requires_lammps
@pytest.mark.parametrize("norm, counts", [(True, (32, 32)), (False, (33, 33))])
def test_lammps_thermo_norm(norm, counts):
    """norm = thermo_modify norm: 4 atoms at a harmonic wall, E -> 0, so the 1e-8 floor of the
    energy tolerance decides (E / N with norm yes, the lj default: one iteration earlier)."""
    x = np.array([[0.3, 0.2, 0.5], [1.5, 0.2, 0.9], [3.0, 0.0, 0.2], [3.0, 2.0, 1.1]])
    xl, el, stop, niter, neval = lammps_minimize(
        x, "cg", "fix w all wall/harmonic zlo 0.0 0.25 1.0 1.5\nfix_modify w energy yes",
        minimize_args="1e-6 0.0 1000 10000", norm=norm)
    ours = run(x[None], wall_objective(harmonic, eps=0.25, rc=1.5), etol=1e-6, ftol=0.0,
               norm=norm)
    assert (stop, niter, neval) == ("energy tolerance", *counts)
    assert (ours.stop_reason[0], ours.iterations[0], ours.evaluations[0]) == (stop, niter, neval)
    assert ours.x[0] == pytest.approx(xl, abs=1e-14)
    assert ours.energy_after[0] == pytest.approx(el, abs=1e-16)


@requires_lammps
def test_lammps_fire_mass_and_timestep():
    """fire moves with dt ftm2v/m: mass 2.5 and timestep 0.02 (lj units, ftm2v = 1)."""
    x = one_atom(2.2)[0]
    xl, el, stop, niter, neval = lammps_minimize(
        x, "fire", "fix w all wall/lj93 zlo 0.0 1.0 1.0 2.5\nfix_modify w energy yes",
        minimize_args="0.0 1e-10 1000 100000", timestep=0.02, mass=2.5)
    ours = run(x[None], wall_objective(lj93, eps=1.0, sigma=1.0, rc=2.5), style="fire",
               timestep=0.02, mass=2.5)
    assert (ours.stop_reason[0], ours.iterations[0], ours.evaluations[0]) == (stop, niter, neval)
    assert ours.x[0] == pytest.approx(xl, abs=1e-12)
    assert ours.energy_after[0] == pytest.approx(el, abs=1e-14)
    default = run(x[None], wall_objective(lj93, eps=1.0, sigma=1.0, rc=2.5), style="fire",
                  timestep=0.02)
    assert default.iterations[0] != niter  # the mass matters


def test_result_type_and_settings_validation():
    res = run(one_atom(1.9), wall_objective(lj93, eps=1.0, sigma=1.0))
    assert isinstance(res, MinResult) and res.iterations.dtype.kind == "i"
    with pytest.raises(ValueError, match="timestep"):
        MinSettings(0.0, 0.0, 10, 10, style="fire")
    with pytest.raises(ValueError, match="style"):
        MinSettings(0.0, 0.0, 10, 10, style="sd")
    with pytest.raises(ValueError, match="etol"):
        MinSettings(-1.0, 0.0, 10, 10)

