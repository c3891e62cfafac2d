"""Random creation with `overlap` (scene/build.py `_random_positions`, a NumPy cell list): the
accepted positions are exactly those of the rule "drop a candidate closer than overlap to an atom
placed before, then the later point of each candidate pair at most overlap apart", minimum image
in periodic dimensions, none across fixed ones; checked against scipy's cKDTree (the former
implementation, kept here as the reference) and against brute force."""

from __future__ import annotations

from types import SimpleNamespace as NS

import numpy as np
import pytest

from wallbatch.scene import build


def reference(cfg: NS, spec: NS, rng: np.random.Generator, existing: np.ndarray) -> np.ndarray:
    """The same rounds with scipy.spatial.cKDTree (periodic boxsize; fixed dims in a box twice as
    long plus the overlap, so they never wrap inside the box)."""
    from scipy.spatial import cKDTree

    lo, hi = np.asarray(cfg.box.lo, float), np.asarray(cfg.box.hi, float)
    length = hi - lo
    periodic = np.array([b == "p" for b in cfg.box.boundary])
    ov = spec.overlap
    boxsize = np.where(periodic, length, 2 * length + 2 * ov + 1.0)
    accepted = [existing] if len(existing) else []
    n_have = 0
    for _ in range(200):
        need = spec.count - n_have
        if need <= 0:
            break
        cand = lo + rng.random((max(2 * need, 64), 3)) * length
        if accepted:
            old = np.concatenate(accepted)
            d, _ = cKDTree(np.mod(old - lo, boxsize), boxsize=boxsize).query(np.mod(cand - lo, boxsize), k=1)
            cand = cand[d >= ov]
        pairs = cKDTree(np.mod(cand - lo, boxsize), boxsize=boxsize).query_pairs(ov, output_type="ndarray")
        if len(pairs):
            keep = np.ones(len(cand), bool)
            keep[pairs.max(axis=1)] = False
            cand = cand[keep]
        cand = cand[:need]
        accepted.append(cand)
        n_have += len(cand)
    return np.concatenate(accepted)[len(existing):]


def scene(lo, hi, boundary, count, overlap, dimension=3):
    return (NS(box=NS(lo=list(lo), hi=list(hi), boundary=list(boundary)), dimension=dimension),
            NS(count=count, overlap=overlap, region=None))


def test_two_dimensional_placement_is_in_the_plane_z_0_and_apart_in_it():
    """dimension: 2: every random atom at z = 0 (LAMMPS's create_atoms random too; the exported
    data file then reads in LAMMPS), so `overlap` holds in the x-y plane; x and y are the draws a
    3-D placement of the same candidates would make."""
    cfg, spec = scene((0, 0, -0.5), (10, 10, 0.5), "ppp", 60, 0.9, dimension=2)
    x = build._random_positions(cfg, spec, np.random.default_rng(3), "atoms.0.create.random", np.zeros((0, 3)))
    assert x.shape == (60, 3) and np.all(x[:, 2] == 0.0)
    d = np.abs(x[:, None, :2] - x[None, :, :2])
    d = np.minimum(d, 10.0 - d)
    r = np.sqrt((d * d).sum(-1)) + np.eye(60) * 99
    assert r.min() > 0.9
    first = np.random.default_rng(3).random((120, 3))  # the first round's candidates (2 x 60)
    assert np.array_equal(x[0, :2], first[0, :2] * 10.0)


@pytest.mark.parametrize("seed", range(12))
def test_overlap_placement_equals_the_kdtree_rule_bit_for_bit(seed):
    r = np.random.default_rng(1000 + seed)
    length = r.uniform(2.0, 25.0, 3)
    lo = r.uniform(-5.0, 5.0, 3)
    boundary = [str(b) for b in r.choice(["p", "f"], 3)]
    overlap = float(r.uniform(0.2, 2.5))
    count = int(min(r.integers(1, 1500), 0.4 * np.prod(length) / overlap ** 3)) or 1
    existing = lo + r.random((int(r.integers(0, 150)), 3)) * length if seed % 2 else np.zeros((0, 3))
    cfg, spec = scene(lo, lo + length, boundary, count, overlap)
    want = reference(cfg, spec, np.random.default_rng(seed), existing)
    if len(want) < count:  # too dense for 200 rounds: the same verdict, with the count placed
        with pytest.raises(build.CaseError, match=f"placed only {len(want)} of {count} atoms"):
            build._random_positions(cfg, spec, np.random.default_rng(seed), "atoms.0.create.random", existing)
        return
    got = build._random_positions(cfg, spec, np.random.default_rng(seed), "atoms.0.create.random", existing)
    assert np.array_equal(got, want)


def test_dense_packing_needs_many_rounds_and_keeps_every_pair_apart():
    """1000 atoms at overlap 0.8 in 10^3 (periodic x, y; fixed z): dozens of rounds, the same
    atoms as the reference, and every minimum-image distance >= 0.8 (brute force)."""
    cfg, spec = scene((0, 0, 0), (10, 10, 10), "ppf", 1000, 0.8)
    got = build._random_positions(cfg, spec, np.random.default_rng(3), "p", np.zeros((0, 3)))
    assert np.array_equal(got, reference(cfg, spec, np.random.default_rng(3), np.zeros((0, 3))))
    d = np.abs(got[:, None, :] - got[None, :, :])
    d[..., :2] = np.minimum(d[..., :2], 10.0 - d[..., :2])  # z is fixed: no image
    r = np.sqrt((d * d).sum(-1))
    assert r[np.triu_indices(len(got), 1)].min() >= 0.8


@pytest.mark.parametrize("boundary", ["ppp", "fff", "pfp"])
def test_close_pairs_finds_every_pair_within_r(boundary):
    """The cell list against all pairs: same set of pairs (i < j) with d <= r, same d^2, for
    boxes with 1, 2 and many cells per dimension."""
    r = np.random.default_rng(5)
    box = np.array([1.5, 3.1, 12.0])  # 1, 2 and many cells of width >= 0.7
    pts = r.random((300, 3)) * box
    periodic = np.array([b == "p" for b in boundary])
    boxsize = np.where(periodic, box, 2 * box + 2.4)
    i, j, d2 = build._close_pairs(pts, None, boxsize, 0.7)
    sel = d2 <= 0.49
    got = set(zip(i[sel].tolist(), j[sel].tolist()))
    dx = np.abs(pts[:, None, :] - pts[None, :, :])
    dx = np.minimum(dx, boxsize - dx)
    full = (dx * dx).sum(-1)
    ii, jj = np.nonzero(np.triu(full <= 0.49, 1))
    assert got == set(zip(ii.tolist(), jj.tolist())) and len(got) > 50
    assert np.array_equal(np.sort(d2[sel]), np.sort(full[ii, jj]))


@pytest.mark.parametrize("boundary", ["ppp", "ppf"])
def test_close_pairs_cell_table_and_binary_search_agree_bit_for_bit(boundary):
    """The two ways of finding a cell's points (a table of every cell, or a binary search of the
    sorted cell keys, chosen by size) give the same pairs in the same order, with and without a
    second point set; and in a box of far more cells than points every pair within r is found."""
    r = np.random.default_rng(11)
    box = np.array([9.0, 7.0, 30.0])
    periodic = np.array([b == "p" for b in boundary])
    boxsize = np.where(periodic, box, 2 * box + 2.0)
    a, b = r.random((400, 3)) * box, r.random((250, 3)) * box
    for other in (None, b):
        table = build._close_pairs(a, other, boxsize, 0.6, dense=True)
        search = build._close_pairs(a, other, boxsize, 0.6, dense=False)
        assert len(table[0]) > 20
        for x, y in zip(table, search):
            assert np.array_equal(x, y)
    few = r.random((150, 3)) * box  # the binary search against all pairs
    i, j, d2 = build._close_pairs(few, None, boxsize, 1.5, dense=False)
    dx = np.abs(few[:, None, :] - few[None, :, :])
    dx = np.minimum(dx, boxsize - dx)
    full = (dx * dx).sum(-1)
    ii, jj = np.nonzero(np.triu(full <= 1.5 * 1.5, 1))
    sel = d2 <= 1.5 * 1.5
    assert set(zip(i[sel].tolist(), j[sel].tolist())) == set(zip(ii.tolist(), jj.tolist())) and len(ii) > 5
