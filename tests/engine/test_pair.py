"""Tests for wallbatch.engine.pair (pair_style lj/cut, physics.md §12): §12 check values, the neighbor
list against a brute-force all-pairs sum, rebuild bookkeeping, force = -dE/dx, per-case bit
identity, take(), and LAMMPS `run 0` parity (energy, per-atom forces, virial). Each of these runs
on both paths (fixture `compiled`: NumPy reference and numba kernels); further tests check that
the two paths agree to 1e-13 and exercise the cell list's edge cases (tiny and huge boxes, atoms
far outside a fixed face, list growth)."""

from __future__ import annotations

import numpy as np
import pytest
from lammps_oracle import _load_lammps, requires_lammps

from wallbatch.engine import pair_compiled as pair_numba
from wallbatch.engine.pair import DEFAULT_SKIN, PairLJCut, default_skin, lj_pair

needs_numba = pytest.mark.skipif(pair_numba.njit is None, reason="numba not importable")


@pytest.fixture(params=[False, pytest.param(True, marks=needs_numba)], ids=["numpy", "numba"])
def compiled(request) -> bool:
    """Run a test on the NumPy path and on the compiled (numba) path."""
    return request.param

# physics.md §12, LAMMPS 22Jul2025
EPS12, SIGMA12, R12, RC12 = 1.2, 1.1, 1.3, 2.5
E12, E12_SHIFTED, F12 = -1.1151250943428515, -1.0805475274697793, 2.1624404761628178


# -- helpers -----------------------------------------------------------------------------------

def jittered(rng: np.random.Generator, n: int, lo, hi, periodic, jitter: float = 0.15) -> np.ndarray:
    """n random sites of a grid filling the box, each moved by up to jitter*spacing (no overlaps:
    nearest distance >= (1 - 2 jitter) spacing); periodic dims wrapped into [lo, hi)."""
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    length = hi - lo
    a = length.min()
    while np.prod(np.floor(length / a)) < 1.2 * n:
        a *= 0.98
    m = np.floor(length / a).astype(int)
    grid = np.stack(np.meshgrid(*(np.arange(k) for k in m), indexing="ij"), -1).reshape(-1, 3)
    site = grid[rng.permutation(len(grid))[:n]]
    spacing = length / m
    x = lo + (site + 0.5 + rng.uniform(-jitter, jitter, (n, 3))) * spacing
    per = np.asarray(periodic, bool)
    x[:, per] = lo[per] + np.mod(x[:, per] - lo[per], length[per])
    return x


def brute(x, eps, sig, rc, shift, length, periodic):
    """All-pairs LJ: energy (C,), forces (C, N, 3), virial (C,), and scales sum|e|, sum|r.F| (C,)."""
    C, N = x.shape[:2]
    iu, ju = np.triu_indices(N, 1)
    energy, virial, escale, wscale = (np.zeros(C) for _ in range(4))
    forces = np.zeros_like(x)
    for c in range(C):
        d = x[c, iu] - x[c, ju]
        for k in np.flatnonzero(periodic):
            d[:, k] -= length[k] * np.round(d[:, k] / length[k])
        r = np.sqrt((d * d).sum(axis=1))
        m = r < rc[c]
        r, d = r[m], d[m]
        sr6 = (sig[c] / r) ** 6
        e = 4 * eps[c] * (sr6 * sr6 - sr6)
        if shift:
            src6 = (sig[c] / rc[c]) ** 6
            e -= 4 * eps[c] * (src6 * src6 - src6)
        dedr = 4 * eps[c] * (-12 * sr6 * sr6 + 6 * sr6) / r  # dE/dr
        fij = (-dedr / r)[:, None] * d  # force on i from j
        np.add.at(forces[c], iu[m], fij)
        np.add.at(forces[c], ju[m], -fij)
        energy[c], escale[c] = e.sum(), np.abs(e).sum()
        rf = (fij * d).sum(axis=1)
        virial[c], wscale[c] = rf.sum(), np.abs(rf).sum()
    return energy, forces, virial, escale, wscale


def assert_matches(pair, x, eps, sig, rc, shift, length, periodic, rtol=1e-12):
    """compute() equals the brute force: E and W relative to sum|terms|, F to max|F| of the case."""
    f = np.zeros_like(x)
    energy, virial = pair.compute(x, f, True)
    e_ref, f_ref, w_ref, escale, wscale = brute(x, eps, sig, rc, shift, length, periodic)
    assert np.all(escale > 0)  # the check is not vacuous: every case has pairs inside rc
    assert np.all(np.abs(energy - e_ref) <= rtol * escale)
    assert np.all(np.abs(virial - w_ref) <= rtol * wscale)
    fscale = np.abs(f_ref).max(axis=(1, 2))
    assert np.all(np.abs(f - f_ref).max(axis=(1, 2)) <= rtol * fscale)


BOXES = {  # boundary letters -> (lo, hi)
    "ppp": ((0.0, 0.0, 0.0), (7.0, 6.5, 6.0)),
    "fff": ((-1.0, 0.5, 0.0), (5.5, 7.0, 6.5)),
    "ppf": ((0.0, -2.0, 1.0), (6.5, 4.8, 7.5)),
    "fpf": ((-3.0, 0.0, 0.0), (3.5, 6.0, 6.2)),
}
EPS = np.array([1.0, 0.5, 1.3])
SIG = np.array([1.0, 0.9, 1.1])
RC = np.array([2.5, 2.0, 1.8])


def batch(boundary: str, n: int, seed: int, shift: bool = False, skin: float = 0.3, compiled: bool = False):
    lo, hi = BOXES[boundary]
    periodic = np.array([b == "p" for b in boundary])
    rng = np.random.default_rng(seed)
    x = np.stack([jittered(rng, n, lo, hi, periodic) for _ in range(len(EPS))])
    pair = PairLJCut(EPS, SIG, RC, box_lo=lo, box_hi=hi, periodic=periodic, shift=shift, skin=skin,
                     compiled=compiled)
    return pair, x, np.subtract(hi, lo), periodic


# -- §12 check values --------------------------------------------------------------------------

@pytest.mark.parametrize("shift, e_ref", [(False, E12), (True, E12_SHIFTED)])
def test_section12_check_values(shift, e_ref, compiled):
    x = np.array([[[0.0, 2.0, 3.0], [R12, 2.0, 3.0]]])
    r = R12
    pair = PairLJCut(EPS12, SIGMA12, RC12, box_lo=(-5, -5, -5), box_hi=(5, 5, 5),
                     periodic=(False, False, False), shift=shift, compiled=compiled)
    f = np.zeros_like(x)
    energy, virial = pair.compute(x, f, True)
    assert energy[0] == pytest.approx(e_ref, rel=1e-14)
    assert np.linalg.norm(f[0, 0]) == pytest.approx(F12, rel=1e-13)
    assert np.dot(f[0, 0], x[0, 1] - x[0, 0]) > 0  # attractive: atom 0 pulled towards atom 1
    np.testing.assert_array_equal(f[0, 1], -f[0, 0])
    assert virial[0] == pytest.approx(-F12 * r, rel=1e-13)  # W = r_01 . F_01 < 0 when attractive
    e, fpair = lj_pair(np.array(R12 * R12), EPS12, SIGMA12)
    assert e == pytest.approx(E12, rel=1e-14) and fpair * R12 == pytest.approx(-F12, rel=1e-14)


def test_outside_cutoff_and_defaults(compiled):
    x = np.array([[[0.0, 0.0, 0.0], [2.5, 0.0, 0.0], [0.0, 2.4999999, 0.0]]])
    pair = PairLJCut(1.0, 1.0, 2.5, box_lo=(-5, -5, -5), box_hi=(5, 5, 5), periodic=(True, True, False),
                     compiled=compiled)
    f = np.zeros_like(x)
    energy, _ = pair.compute(x, f, True)
    assert f[0, 1].tolist() == [0.0, 0.0, 0.0]  # r == rc is outside (LAMMPS: rsq < cutsq)
    assert f[0, 2, 1] != 0.0
    assert energy[0] == lj_pair(np.array(2.4999999**2), 1.0, 1.0)[0]  # only the pair 0-2 counts
    assert pair.compute(x, f, False) is None
    assert pair.skin == 0.3 and default_skin("lj") == 0.3
    assert default_skin("real") == default_skin("metal") == 2.0 == DEFAULT_SKIN["real"]


@pytest.mark.parametrize("kwargs, match", [
    ({"cutoff": 3.0}, "half the periodic box"),
    ({"epsilon": -1.0}, "epsilon"),
    ({"sigma": 0.0}, "sigma"),
    ({"skin": -0.1}, "skin"),
])
def test_bad_parameters(kwargs, match):
    args = {"epsilon": 1.0, "sigma": 1.0, "cutoff": 2.5, "skin": 0.3} | kwargs
    with pytest.raises(ValueError, match=match):
        PairLJCut(args["epsilon"], args["sigma"], args["cutoff"], box_lo=(0, 0, 0), box_hi=(6, 10, 10),
                  periodic=(True, False, False), skin=args["skin"])


# -- neighbor list = brute force ---------------------------------------------------------------

@pytest.mark.parametrize("shift", [False, True])
@pytest.mark.parametrize("boundary", list(BOXES))
def test_matches_brute_force(boundary, shift, compiled):
    pair, x, length, periodic = batch(boundary, 160, seed=len(boundary) + 7 * shift, shift=shift, compiled=compiled)
    fixed = np.flatnonzero(~periodic)
    if len(fixed):  # an atom a little outside a fixed face (the engine checks lost atoms after forces)
        x[:, 0, fixed[0]] = BOXES[boundary][1][fixed[0]] + 0.05
    assert_matches(pair, x, EPS, SIG, RC, shift, length, periodic)
    assert pair.builds == 3 and pair.case_builds.tolist() == [1, 1, 1]
    iu, ju = np.triu_indices(x.shape[1], 1)  # the list holds exactly the pairs within rc + skin
    d = x[:, iu] - x[:, ju]
    for k in np.flatnonzero(periodic):
        d[..., k] -= length[k] * np.round(d[..., k] / length[k])
    assert pair.npairs == np.sum(np.sqrt((d * d).sum(axis=2)) <= (RC + pair.skin)[:, None])


def test_random_walk_rebuilds_only_when_needed(compiled):
    """Small random moves with wrapping: the list stays exact, and a case is rebuilt exactly when
    one of its atoms has moved more than skin/2 (minimum image) since its last build."""
    skin = 0.3
    pair, x, length, periodic = batch("ppf", 120, seed=3, skin=skin, compiled=compiled)
    lo = np.asarray(BOXES["ppf"][0])
    rng = np.random.default_rng(11)
    step = np.array([0.02, 0.006, 0.0])  # per case: fast, slow, frozen
    ref = x.copy()
    expected = np.ones(3, dtype=int)
    assert_matches(pair, x, EPS, SIG, RC, False, length, periodic)
    for _ in range(60):
        x = x + step[:, None, None] * rng.standard_normal(x.shape)
        for k in np.flatnonzero(periodic):
            x[..., k] = lo[k] + np.mod(x[..., k] - lo[k], length[k])
        d = x - ref
        for k in np.flatnonzero(periodic):
            d[..., k] -= length[k] * np.round(d[..., k] / length[k])
        moved = np.sqrt((d * d).sum(axis=2)).max(axis=1) > skin / 2
        expected += moved
        ref[moved] = x[moved]
        assert_matches(pair, x, EPS, SIG, RC, False, length, periodic)
        np.testing.assert_array_equal(pair.case_builds, expected)
    assert expected[0] >= 5 and 1 < expected[1] < expected[0] and expected[2] == 1
    assert pair.builds == expected.sum()


def test_rebuild_threshold_is_half_skin(compiled):
    """Two atoms just beyond rc + skin, each moved just under skin/2 towards the other: no rebuild
    and no force (still beyond rc); a little further: one rebuild, and the force appears."""
    rc, skin = 2.5, 0.3
    pair = PairLJCut(1.0, 1.0, rc, box_lo=(0, 0, 0), box_hi=(10, 10, 10), periodic=(True, True, False),
                     skin=skin, compiled=compiled)
    gap = rc + skin + 1e-9
    x = np.array([[[5.0 - gap / 2, 5.0, 5.0], [5.0 + gap / 2, 5.0, 5.0]]])
    f = np.zeros_like(x)
    pair.compute(x, f, False)
    assert pair.builds == 1 and not f.any()
    step = skin / 2 - 1e-9
    x[0, 0, 0] += step
    x[0, 1, 0] -= step
    pair.compute(x, f, False)
    assert pair.builds == 1 and not f.any()  # distance rc + 3e-9, nobody moved more than skin/2
    x[0, 0, 0] += 0.01
    x[0, 1, 0] -= 0.01
    pair.compute(x, f, False)
    assert pair.builds == 2 and f[0, 1, 0] < 0 < f[0, 0, 0]  # attractive at r = rc - 0.02


# -- force = -dE/dx ------------------------------------------------------------------------------

@pytest.mark.parametrize("shift", [False, True])
def test_force_is_minus_gradient(shift, compiled):
    pair, x, _, _ = batch("ppf", 60, seed=5, shift=shift, compiled=compiled)
    _, forces = pair.energy_forces(x)
    rng = np.random.default_rng(2)
    h = 1e-5
    for c in range(3):
        fscale = np.abs(forces[c]).max()
        for a, k in zip(rng.integers(0, 60, 6), rng.integers(0, 3, 6)):
            xp, xm = x.copy(), x.copy()
            xp[c, a, k] += h
            xm[c, a, k] -= h
            fd = -(pair.energy_forces(xp)[0][c] - pair.energy_forces(xm)[0][c]) / (2 * h)
            assert abs(fd - forces[c, a, k]) <= 1e-6 * fscale
    assert pair.builds == 3  # h << skin/2: no rebuild


# -- batches: per-case bit identity, take(), NaN cases --------------------------------------------

def test_case_independent_of_batch_and_take(compiled):
    """A case's forces, energy and virial are bit-identical whether it runs alone or in a batch
    whose other cases rebuild at other times, also after take() drops a case mid-run."""
    pair, x, length, periodic = batch("ppp", 100, seed=9, compiled=compiled)
    lo, hi = BOXES["ppp"]
    singles = [PairLJCut(EPS[c], SIG[c], RC[c], box_lo=lo, box_hi=hi, periodic=periodic, compiled=compiled)
               for c in range(3)]
    rng = np.random.default_rng(4)
    step, live = np.array([0.03, 0.01, 0.02]), [0, 1, 2]
    for n in range(30):
        x = x + step[:, None, None] * rng.standard_normal(x.shape)
        x = lo + np.mod(x - np.asarray(lo), length)
        if n == 15:
            builds = pair.case_builds.copy()
            pair.take(np.array([True, False, True]))
            x, step, live = x[[0, 2]], step[[0, 2]], [0, 2]
            assert pair.ncases == 2 and pair.epsilon.tolist() == EPS[[0, 2]].tolist()
            np.testing.assert_array_equal(pair.case_builds, builds[[0, 2]])
        f = np.zeros_like(x)
        e, w = pair.compute(x, f, True)
        for row, c in enumerate(live):
            f1 = np.zeros_like(x[:1])
            e1, w1 = singles[c].compute(x[row:row + 1], f1, True)
            assert np.array_equal(f[row], f1[0]) and e[row] == e1[0] and w[row] == w1[0]
    assert len(set(pair.case_builds.tolist())) == 2  # the two cases were rebuilt at different times
    assert_matches(pair, x, EPS[[0, 2]], SIG[[0, 2]], RC[[0, 2]], False, length, periodic)
    pair.take(np.array([1, 0]))  # indices, reordering
    assert_matches(pair, x[::-1].copy(), EPS[[2, 0]], SIG[[2, 0]], RC[[2, 0]], False, length, periodic)


def test_nan_case_does_not_touch_others(compiled):
    pair, x, _, _ = batch("ppf", 80, seed=13, compiled=compiled)
    f_ok = np.zeros_like(x)
    e_ok, w_ok = pair.compute(x, f_ok, True)
    x[1, 5, 0] = np.nan
    f = np.zeros_like(x)
    e, w = pair.compute(x, f, True)
    assert np.isnan(f[1]).all() and np.isnan(e[1]) and np.isnan(w[1])
    assert np.array_equal(f[[0, 2]], f_ok[[0, 2]]) and np.array_equal(e[[0, 2]], e_ok[[0, 2]])
    assert np.array_equal(w[[0, 2]], w_ok[[0, 2]])


# -- compiled path against the NumPy path ----------------------------------------------------------

def listed_pairs(pair: PairLJCut, c: int) -> np.ndarray:
    """Case c's neighbor list as rows (i, j), i < j, sorted (either path)."""
    if pair.compiled:
        first = pair._first[c]
        i = np.repeat(pair._owner[c], np.diff(first))
        pairs = np.sort(np.stack([i, pair._neigh[c, :first[-1]]], axis=1), axis=1)
    else:
        pairs = pair._pairs[c]
    return pairs[np.lexsort(pairs.T[::-1])]


def walk(x, rng, step, lo, length, periodic):
    """One random-walk step of every atom (step (C,) [length]), wrapped in periodic dims."""
    x = x + np.asarray(step)[:, None, None] * rng.standard_normal(x.shape)
    for k in np.flatnonzero(periodic):
        x[..., k] = lo[k] + np.mod(x[..., k] - lo[k], length[k])
    return x


@needs_numba
@pytest.mark.parametrize("shift", [False, True])
@pytest.mark.parametrize("boundary", list(BOXES))
def test_compiled_matches_numpy(boundary, shift):
    """Three cases with different eps, sigma, rc on a random walk with rebuilds: both paths make
    the same rebuild decisions, hold the same pairs, and give forces, energy and virial equal to
    1e-13 relative (forces to max|F| of the case; energy and virial to the sum of |pair terms|,
    the scale of their rounding; relative to |E| and |W| themselves they agree to < 1e-13 too)."""
    ref, x, length, periodic = batch(boundary, 160, seed=21, shift=shift, compiled=False)
    fast, _, _, _ = batch(boundary, 160, seed=21, shift=shift, compiled=True)
    lo = np.asarray(BOXES[boundary][0])
    rng = np.random.default_rng(8)
    for _ in range(12):
        fa, fb = np.zeros_like(x), np.zeros_like(x)
        ea, wa = ref.compute(x, fa, True)
        eb, wb = fast.compute(x, fb, True)
        _, f_ref, _, escale, wscale = brute(x, EPS, SIG, RC, shift, length, periodic)
        assert np.all(np.abs(fa - fb).max(axis=(1, 2)) <= 1e-13 * np.abs(f_ref).max(axis=(1, 2)))
        assert np.all(np.abs(ea - eb) <= 1e-13 * escale) and np.all(np.abs(wa - wb) <= 1e-13 * wscale)
        assert not np.array_equal(fa, np.zeros_like(fa))
        np.testing.assert_array_equal(ref.case_builds, fast.case_builds)
        for c in range(3):
            np.testing.assert_array_equal(listed_pairs(ref, c), listed_pairs(fast, c))
        x = walk(x, rng, [0.04, 0.02, 0.03], lo, length, periodic)
    assert ref.case_builds.min() >= 3  # the lists were rebuilt along the way
    f = np.zeros_like(x)  # outputs=False: the same forces, nothing returned
    assert fast.compute(x, f, False) is None
    fb = np.zeros_like(x)
    fast.compute(x, fb, True)
    np.testing.assert_array_equal(f, fb)


@needs_numba
def test_single_pair_same_bits():
    """With one pair there is no summation order: both paths give the same bits (the compiled
    kernel repeats the NumPy operations), through periodic faces and along fixed dims."""
    lo, hi, periodic = (0.0, -1.0, 2.0), (7.1, 6.3, 9.7), np.array([True, True, False])
    rng = np.random.default_rng(41)
    a = lo + rng.uniform(0, 1, (40, 3)) * np.subtract(hi, lo)
    b = a + rng.uniform(-1.5, 1.5, (40, 3))
    for k in np.flatnonzero(periodic):  # partner wrapped: the pair is seen through a face
        b[:, k] = lo[k] + np.mod(b[:, k] - lo[k], hi[k] - lo[k])
    x = np.stack([a, b], axis=1)  # 40 cases of 2 atoms
    eps, sig, rc = rng.uniform(0.5, 1.5, 40), rng.uniform(0.8, 1.2, 40), np.full(40, 2.5)
    out = []
    for compiled in (False, True):
        pair = PairLJCut(eps, sig, rc, box_lo=lo, box_hi=hi, periodic=periodic, shift=True, compiled=compiled)
        f = np.zeros_like(x)
        out.append((f, *pair.compute(x, f, True)))
    for u, v in zip(*out):
        np.testing.assert_array_equal(u, v)
    assert np.count_nonzero(out[0][1]) > 30  # most cases have their pair inside rc


def geometry(name: str, rng: np.random.Generator):
    """Scenes for the cell list's corner cases: lo, hi, boundary, positions (3, n, 3)."""
    if name == "tiny periodic box":  # rc + skin > L/2: one cell per dim, minimum image per pair
        lo, hi, bnd = (0.0, 0.0, 0.0), (5.2, 5.3, 5.4), "ppp"
        return lo, hi, bnd, np.stack([jittered(rng, 100, lo, hi, [True] * 3) for _ in range(3)])
    if name == "sparse clumps":  # 60^3 box, 2 clumps, one across the periodic corner: capped cells
        lo, hi, bnd = (0.0, 0.0, 0.0), (60.0, 60.0, 60.0), "ppp"
        xs = []
        for _ in range(3):
            a = jittered(rng, 27, (-1.6,) * 3, (1.6,) * 3, [False] * 3)
            b = jittered(rng, 27, (30.0,) * 3, (33.2,) * 3, [False] * 3)
            xs.append(np.mod(np.concatenate([a, b]), 60.0))
        return lo, hi, bnd, np.stack(xs)
    if name == "atoms far outside fixed faces":  # extent 1e60 along z: bins capped
        lo, hi, bnd = BOXES["ppf"][0], BOXES["ppf"][1], "ppf"
        x = np.stack([jittered(rng, 120, lo, hi, [True, True, False]) for _ in range(3)])
        x[:, 0, 2], x[:, 1, 2] = 1.0e60, -55.0  # (the NumPy path's cKDTree once failed on 1e60)
        x[:, 2, 2], x[:, 3, 2] = hi[2] + 1.0, hi[2] + 1.5  # a pair beyond the face, still interacting
        return lo, hi, bnd, x
    if name == "flat layer":  # zero extent along a fixed dim; periodic y
        lo, hi, bnd = (0.0, 0.0, 0.0), (9.0, 8.0, 4.0), "fpf"
        x = np.stack([jittered(rng, 70, lo, (9.0, 8.0, 1.0), [False, True, False]) for _ in range(3)])
        x[..., 2] = 2.0
        return lo, hi, bnd, x
    raise KeyError(name)


GEOMETRIES = ["tiny periodic box", "sparse clumps", "atoms far outside fixed faces", "flat layer"]


@pytest.mark.parametrize("name", GEOMETRIES)
def test_cell_list_edge_geometries(name, compiled):
    """Brute force agrees, and the list holds exactly the pairs within rc + skin, in boxes that
    hit the cell list's special cases (one cell per periodic dim, capped cell counts, huge
    extents of fixed dims, zero extent)."""
    lo, hi, bnd, x = geometry(name, np.random.default_rng(len(name)))
    periodic = np.array([b == "p" for b in bnd])
    length = np.subtract(hi, lo)
    pair = PairLJCut(EPS, SIG, RC, box_lo=lo, box_hi=hi, periodic=periodic, shift=True, compiled=compiled)
    assert_matches(pair, x, EPS, SIG, RC, True, length, periodic)
    iu, ju = np.triu_indices(x.shape[1], 1)
    d = x[:, iu] - x[:, ju]
    for k in np.flatnonzero(periodic):
        d[..., k] -= length[k] * np.round(d[..., k] / length[k])
    within = np.sqrt((d * d).sum(axis=2)) <= (RC + pair.skin)[:, None]
    assert pair.npairs == within.sum()
    for c in range(3):
        expect = np.stack([iu[within[c]], ju[within[c]]], axis=1)
        np.testing.assert_array_equal(listed_pairs(pair, c), expect[np.lexsort(expect.T[::-1])])


def test_few_atoms(compiled):
    """N = 0 and 1: no pairs, zero force and energy; N = 2 across a periodic face: one pair."""
    for n in (0, 1):
        pair = PairLJCut(1.0, 1.0, 2.5, box_lo=(0, 0, 0), box_hi=(8, 8, 8), periodic=(True,) * 3, compiled=compiled)
        x = np.full((1, n, 3), 4.0)
        f = np.zeros_like(x)
        assert pair.compute(x, f, True) == (np.zeros(1), np.zeros(1)) and pair.npairs == 0
    pair = PairLJCut(1.0, 1.0, 2.5, box_lo=(0, 0, 0), box_hi=(8, 8, 8), periodic=(True,) * 3, compiled=compiled)
    x = np.array([[[0.2, 4.0, 4.0], [7.5, 4.0, 4.0]]])  # 0.7 apart through the x face
    f = np.zeros_like(x)
    energy, virial = pair.compute(x, f, True)
    e, fpair = lj_pair(np.array(0.7**2), 1.0, 1.0)
    assert energy[0] == pytest.approx(e, rel=1e-14) and virial[0] == pytest.approx(fpair * 0.49, rel=1e-14)
    assert f[0, 0, 0] == pytest.approx(fpair * 0.7, rel=1e-14)  # d = x0 - image of x1 = +0.7
    assert f[0, 0, 0] > 0 and f[0, 1, 0] == -f[0, 0, 0]  # repelled away from atom 1's image at x = -0.5


def test_list_growth_keeps_other_cases(compiled):
    """Case 1 is compressed 0.45x between two calls, so its rebuilt list is ~10x longer (the
    compiled path grows its pair storage): case 0, not rebuilt, keeps bit-identical results, and
    both still match the brute force."""
    lo, hi = (0.0, 0.0, 0.0), (12.0, 12.0, 12.0)
    periodic = np.zeros(3, dtype=bool)
    rng = np.random.default_rng(17)
    x = np.stack([jittered(rng, 100, lo, hi, periodic) for _ in range(2)])
    eps, sig, rc = EPS[:2], SIG[:2], np.array([2.5, 2.5])
    pair = PairLJCut(eps, sig, rc, box_lo=lo, box_hi=hi, periodic=periodic, compiled=compiled)
    f0 = np.zeros_like(x)
    e0, w0 = pair.compute(x, f0, True)
    before = pair.npairs
    x[1] = 6.0 + 0.45 * (x[1] - 6.0)
    f1 = np.zeros_like(x)
    e1, w1 = pair.compute(x, f1, True)
    assert pair.case_builds.tolist() == [1, 2] and pair.npairs > 5 * before
    assert np.array_equal(f1[0], f0[0]) and e1[0] == e0[0] and w1[0] == w0[0]
    assert_matches(pair, x, eps, sig, rc, False, np.subtract(hi, lo), periodic)


def test_any_memory_layout(compiled):
    """Non-contiguous positions and a Fortran-ordered force array give the same bits."""
    pair, x, _, _ = batch("ppf", 50, seed=31, compiled=compiled)
    f = np.zeros_like(x)
    e, w = pair.compute(x, f, True)
    big = np.zeros((3, 100, 3))
    big[:, ::2] = x
    pair2, _, _, _ = batch("ppf", 50, seed=31, compiled=compiled)
    f2 = np.asfortranarray(np.zeros_like(x))
    e2, w2 = pair2.compute(big[:, ::2], f2, True)
    assert np.array_equal(f2, f) and np.array_equal(e2, e) and np.array_equal(w2, w)
    assert np.abs(f).max() > 1.0


def test_path_selection(monkeypatch):
    """WALLBATCH_NUMBA=0 selects the NumPy path; otherwise the compiled one when numba imports;
    compiled=False always forces NumPy."""
    args = (1.0, 1.0, 2.5)
    box = {"box_lo": (0, 0, 0), "box_hi": (8, 8, 8), "periodic": (True, True, False)}
    monkeypatch.setenv("WALLBATCH_NUMBA", "0")
    assert not PairLJCut(*args, **box).compiled
    monkeypatch.setenv("WALLBATCH_NUMBA", "1")
    assert PairLJCut(*args, **box).compiled == (pair_numba.njit is not None)
    assert not PairLJCut(*args, **box, compiled=False).compiled


@needs_numba
def test_engine_paths_agree(monkeypatch):
    """The engine on both pair paths (an fcc LJ liquid melting between lj93 walls, 40 steps):
    thermo outputs equal to 1e-10 relative (rounding differences only, barely grown in 40 steps)."""
    from wallbatch.config.models import config_from_dict
    from wallbatch.engine.engine import run_cases
    from wallbatch.scene.build import build_case

    cfg = {
        "name": "lj-slit", "units": "lj", "seed": 3, "lattice": {"style": "fcc", "scale": 0.8},
        "box": {"lo": [0, 0, 0], "hi": [6.84, 6.84, 8.0], "boundary": ["p", "p", "f"]},  # 4 fcc cells in x, y
        "regions": {"pore": {"style": "block", "lo": [0, 0, 1.0], "hi": [6.8, 6.8, 7.0], "units": "box"}},
        "atoms": [{"group": "liquid", "create": {"lattice": {"region": "pore"}}, "mass": 1.0,
                   "velocity": {"temperature": 2.0}}],
        "pair": {"style": "lj/cut", "epsilon": 1.0, "sigma": 1.0, "cutoff": 2.5, "shift": True},
        "walls": {"pore": {"style": "lj93", "units": "box", "energy": True, "virial": True,
                           "zlo": ["EDGE", 1.0, 1.0, 2.5], "zhi": ["EDGE", 1.0, 1.0, 2.5]}},
        "timestep": 0.005, "run": {"steps": 40, "thermo": 10},
        "output": {"thermo": ["step", "pe", "etot", "press"]},
    }
    case = build_case(config_from_dict(cfg))
    assert case.natoms > 150
    results = {}
    for flag in ("0", "1"):
        monkeypatch.setenv("WALLBATCH_NUMBA", flag)
        (res,) = run_cases([case])
        assert res.status == "ok", res.error
        results[flag] = res.data
    for key in ("pe", "etot", "press"):
        np.testing.assert_allclose(results["1"][key], results["0"][key], rtol=1e-10, atol=0)
    assert np.ptp(results["0"]["pe"]) > 1.0  # the state changes along the run


# -- LAMMPS run 0 parity ---------------------------------------------------------------------------

def lammps_run0(x, lo, hi, boundary, eps, sigma, rc, shift):
    """LAMMPS lj/cut at step 0: pe (norm no), per-atom forces, W = 3 V P_virial / nktv2p."""
    lo, hi, eps, sigma, rc = [float(v) for v in lo], [float(v) for v in hi], float(eps), float(sigma), float(rc)
    lammps = _load_lammps()
    lmp = lammps.lammps(cmdargs=["-log", "none", "-screen", "none", "-nocite"])
    try:
        for line in [
            "units lj", "atom_style atomic", "atom_modify map array",
            "boundary " + " ".join(boundary),
            "region box block " + " ".join(f"{lo[d]!r} {hi[d]!r}" for d in range(3)) + " units box",
            "create_box 1 box", "mass 1 1.0",
        ]:
            lmp.command(line)
        n = len(x)
        assert lmp.create_atoms(n, list(range(1, n + 1)), [1] * n, x.ravel().tolist()) == n
        got = np.ctypeslib.as_array(lmp.gather_atoms("x", 1, 3)).reshape(-1, 3)
        assert np.array_equal(got, x)
        for line in [
            f"pair_style lj/cut {rc!r}", f"pair_coeff 1 1 {eps!r} {sigma!r}",
            f"pair_modify shift {'yes' if shift else 'no'}",
            "neighbor 0.3 bin", "neigh_modify every 1 delay 0 check yes",
            "compute wvir all pressure NULL virial",
            "thermo_style custom step pe c_wvir", "thermo_modify norm no", "run 0",
        ]:
            lmp.command(line)
        pe = lmp.get_thermo("pe")
        press = lmp.extract_compute("wvir", 0, 0)  # LMP_STYLE_GLOBAL, LMP_TYPE_SCALAR
        forces = np.ctypeslib.as_array(lmp.gather_atoms("f", 1, 3)).reshape(-1, 3).copy()
    finally:
        lmp.close()
    volume = np.prod(np.subtract(hi, lo))
    return pe, forces, 3.0 * volume * press  # nktv2p = 1 in lj units


@requires_lammps
@pytest.mark.parametrize("shift", [False, True])
def test_lammps_run0_parity(shift, compiled):
    lo, hi, boundary = (0.0, -1.0, 0.5), (7.2, 6.0, 7.4), ("p", "p", "f")
    periodic = np.array([True, True, False])
    rng = np.random.default_rng(2025 + shift)
    x = np.stack([jittered(rng, 200, lo, hi, periodic) for _ in range(2)])
    eps, sig, rc = np.array([1.0, 1.3]), np.array([1.0, 0.95]), np.array([2.5, 3.0])
    pair = PairLJCut(eps, sig, rc, box_lo=lo, box_hi=hi, periodic=periodic, shift=shift, compiled=compiled)
    f = np.zeros_like(x)
    energy, virial = pair.compute(x, f, True)
    for c in range(2):
        pe, f_lmp, w_lmp = lammps_run0(x[c], lo, hi, boundary, eps[c], sig[c], rc[c], shift)
        assert energy[c] == pytest.approx(pe, rel=1e-10)
        assert virial[c] == pytest.approx(w_lmp, rel=1e-10)
        assert np.abs(f[c] - f_lmp).max() <= 1e-10 * np.abs(f_lmp).max()
        assert abs(w_lmp) > 1.0 and np.abs(f_lmp).max() > 1.0  # a real configuration, not an empty one
