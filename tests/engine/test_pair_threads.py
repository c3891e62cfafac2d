"""One pair lj/cut case over threads (pair_compiled._chunk_threaded, build_threaded,
forces_threaded): the list build cut in runs of cells and the force pass cut in runs of rows
must give the one-thread kernels' lists and forces bit for bit, and a whole run on 2 or 3 threads
the one-thread run's samples and state bit for bit. Small scenes are split by lowering
THREAD_MIN_ATOMS; each test checks that the threaded path really ran.
"""

from __future__ import annotations

import numpy as np
import pytest

from wallbatch.engine import pair_compiled
from wallbatch.engine.engine import Engine
from wallbatch.engine.pair_compiled import PairChunks

from tests.engine.test_pair_chunks import (THERMOSTATS, assert_bits, cases_of, flow_fluid, frozen_post, liquid_2d,
                                           slit, sphere_cavity, timed_slit)

pytestmark = pytest.mark.skipif(pair_compiled.njit is None, reason="numba not importable")

E24, E4, SIG2, RC2, OFF = 24.0, 4.0, 1.0, 6.25, 0.016316891136  # lj/cut eps 1 sigma 1 rc 2.5, shifted


def liquid(m: int = 10, seed: int = 1) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """4 m^3 atoms: an fcc lattice at rho 0.8, shaken (sd 0.2): x, y periodic, z fixed."""
    a = (4.0 / 0.8) ** (1.0 / 3.0)
    basis = np.array([[0, 0, 0], [0.5, 0.5, 0], [0.5, 0, 0.5], [0, 0.5, 0.5]])
    cells = np.stack(np.meshgrid(*(np.arange(m),) * 3, indexing="ij"), -1).reshape(-1, 1, 3)
    x = ((cells + basis) * a).reshape(-1, 3) + 0.25 * a
    x += np.random.default_rng(seed).normal(0.0, 0.2, x.shape)
    lo, hi = np.zeros(3), np.array([m * a, m * a, (m + 1) * a])
    return x, lo, hi - lo, np.array([True, True, False])


def one_thread_list(x, lo, length, per, reach=2.8):
    N = len(x)
    owner, first, neigh = np.empty(N, np.int32), np.empty(N + 1, np.int64), np.empty(80 * N, np.int32)
    m = pair_compiled.build_case(x, lo, length, per, reach, owner, first, neigh)
    return owner, first, neigh, m


@pytest.mark.parametrize("parts", [2, 3, 5])
def test_threaded_build_and_forces_are_the_one_thread_bits(parts):
    """4000 atoms (12 cells a side): the threaded build writes the one-thread list (owners, row
    starts, partners) and the threaded force pass its forces, bit for bit; the parts really
    overlap (atoms touched by two parts go through the log)."""
    x, lo, length, per = liquid()
    owner, first, neigh, m = one_thread_list(x, lo, length, per)
    f1 = np.zeros_like(x)
    pair_compiled.forces_case(x, f1, owner, first, neigh, E24, E4, SIG2, RC2, OFF, length, per, False)
    o2, fr2, n2 = np.empty_like(owner), np.empty_like(first), np.zeros(80 * len(x), np.int32)
    assert pair_compiled.build_threaded(x, lo, length, per, 2.8, o2, fr2, n2, parts) == m > 30 * len(x)
    np.testing.assert_array_equal(o2, owner)
    np.testing.assert_array_equal(fr2, first)
    np.testing.assert_array_equal(n2[:m], neigh[:m])
    marks, rows = np.zeros((parts, len(x)), np.uint8), np.empty(parts + 1, np.int64)
    assert pair_compiled.build_threaded(x, lo, length, per, 2.8, o2, fr2, n2, parts, marks=marks, rows=rows) == m
    np.testing.assert_array_equal(n2[:m], neigh[:m])
    for split in (pair_compiled.RowSplit(o2, fr2, n2, parts),  # parts of equal pairs, marked by itself
                  pair_compiled.RowSplit(o2, fr2, n2, parts, marks=marks, rows=rows)):  # the build's parts
        assert len(np.unique(split.firstp)) == parts and split.rb[1] > 0 and split.mixed.any()
        f2 = np.zeros_like(x)
        pair_compiled.forces_threaded(x, f2, o2, fr2, n2, split, E24, E4, SIG2, RC2, OFF, length, per)
        np.testing.assert_array_equal(f2, f1)
    assert np.abs(f1).max() > 10.0  # real forces, summing to 0 (Newton's third law) to rounding
    assert np.abs(f1.sum(axis=0)).max() < 1e-12 * np.abs(f1).sum()


@pytest.mark.parametrize("parts", [2, 3, 5])
@pytest.mark.parametrize("xper", [True, False])
@pytest.mark.parametrize("shift", [0.0, 0.37])
def test_row_zones_hold_every_mixed_row(parts, xper, shift):
    """The build's `row_zones` (the only rows RowSplit checks for partners of another part) hold
    every row that has one: the split from them has the mixed rows and log lengths of the split
    that checks every row, with x periodic (rows wrapping to layers 0 and 1) or not, and parts
    starting mid-layer (shares moved by `shift`); with two parts the zones leave rows out."""
    x, lo, length, per = liquid()
    per = per.copy()
    per[0] = xper
    N = len(x)
    owner, first, neigh = np.empty(N, np.int32), np.empty(N + 1, np.int64), np.zeros(80 * N, np.int32)
    marks, rows = np.zeros((parts, N), np.uint8), np.empty(parts + 1, np.int64)
    zones = np.full((parts, 2, 2), -1, np.int64)
    shares = np.arange(parts + 1) / parts
    shares[1:-1] += shift / parts
    assert pair_compiled.build_threaded(x, lo, length, per, 2.8, owner, first, neigh, parts, marks=marks, rows=rows,
                                        shares=shares, zones=zones) > 30 * N
    full = pair_compiled.RowSplit(owner, first, neigh, parts, marks=marks, rows=rows)
    zoned = pair_compiled.RowSplit(owner, first, neigh, parts, marks=marks, rows=rows, zones=zones)
    assert full.mixed.sum() > 0.05 * N
    np.testing.assert_array_equal(zoned.mixed, full.mixed)
    np.testing.assert_array_equal(zoned.logs, full.logs)
    checked = (zones[1:, :, 1] - zones[1:, :, 0]).sum()
    assert (zones[:, :, 1] >= zones[:, :, 0]).all() and zones[0].sum() == 0
    assert checked <= N - rows[1]
    if parts == 2 and shift == 0.0:  # ~17 layers of cells: part 1 holds ~8, its zones ~5
        assert checked < 0.8 * (N - rows[1])
    f1, f2 = np.zeros_like(x), np.zeros_like(x)
    pair_compiled.forces_case(x, f1, owner, first, neigh, E24, E4, SIG2, RC2, OFF, length, per, False)
    pair_compiled.forces_threaded(x, f2, owner, first, neigh, zoned, E24, E4, SIG2, RC2, OFF, length, per)
    np.testing.assert_array_equal(f2, f1)


@pytest.mark.parametrize("parts", [2, 3, 5])
@pytest.mark.parametrize("scene", ["liquid", "clumped"])
def test_threaded_binning_is_the_counting_sort_of_one_thread(parts, scene):
    """bin_threaded (runs of atoms: extent, cells and counts, scatter) gives `_bin`'s owner, sorted
    positions, cell starts and grid bit for bit, for odd atom counts, and a clump leaving most
    cells empty and piling many atoms in one; both are the counting sort of the cells computed
    here in NumPy (ascending atom within a cell)."""
    x, lo, length, per = liquid(5)
    x = x[:-1] if scene == "liquid" else x[:401]  # 499 / 401 atoms
    if scene == "clumped":
        x[:300] = x[0] + 0.01 * np.random.default_rng(2).random((300, 3))
        x[300, 0] -= 3.0 * length[0]  # far outside the periodic box: wrapped
    N, reach = len(x), 2.8
    o1 = np.empty(N, np.int32)
    xs1, cs1, nb1 = pair_compiled._bin(x, lo, length, per, reach, o1)
    o2 = np.empty(N, np.int32)
    xs2, cs2, nb2 = pair_compiled.bin_threaded(x, lo, length, per, reach, o2, parts)
    for a, b in ((o2, o1), (xs2, xs1), (cs2, cs1), (nb2, nb1)):
        assert a.dtype == b.dtype
        np.testing.assert_array_equal(a, b)
    # the same sort from NumPy: positions from lo (wrapped) or the lowest atom, cells of ext / nb
    p = x - np.where(per, lo, x.min(axis=0))
    p[:, per] = np.mod(p[:, per], length[per])
    ext = np.where(per, length, x.max(axis=0) - x.min(axis=0))
    ck = np.clip((p / (ext / nb1)).astype(np.int64), 0, nb1 - 1) * (nb1 > 1)
    cell = (ck[:, 0] * nb1[1] + ck[:, 1]) * nb1[2] + ck[:, 2]
    np.testing.assert_array_equal(o1, np.argsort(cell, kind="stable"))
    np.testing.assert_array_equal(cs1, np.concatenate(([0], np.cumsum(np.bincount(cell, minlength=nb1.prod())))))
    np.testing.assert_allclose(xs1, p[o1], rtol=0, atol=1e-12)
    counts = np.diff(cs1)
    if scene == "clumped":  # most cells empty, one holding the clump
        assert (counts == 0).mean() > 0.5 and counts.max() >= 300
    else:
        assert (counts == 0).mean() < 0.1 and counts.max() < 10


@pytest.mark.parametrize("parts", [2, 3])
def test_threaded_build_with_kept_work_arrays(parts):
    """build_threaded with a Workspace (its crew, its kept binning arrays and `aside`), twice on
    moved atoms, and once more after the kept arrays were filled with garbage: each time the
    one-thread list bit for bit, and the arrays are the same objects (kept, not fresh)."""
    x, lo, length, per = liquid(8)
    ws = pair_compiled.Workspace()
    kept = None
    for k, pos in enumerate((x, x + 0.05, x + 0.05)):
        owner, first, neigh, m = one_thread_list(pos, lo, length, per)
        if k == 2:
            for b in ws._bufs.values():
                b[...] = 7 if b.dtype.kind in "iu" else np.nan
        o2, fr2, n2 = np.empty_like(owner), np.empty_like(first), np.empty(80 * len(x), np.int32)
        got = pair_compiled.build_threaded(pos, lo, length, per, 2.8, o2, fr2, n2, parts, ws.crew(parts),
                                           buffer=ws.buffer)
        assert got == m > 30 * len(x)
        np.testing.assert_array_equal(o2, owner)
        np.testing.assert_array_equal(fr2, first)
        np.testing.assert_array_equal(n2[:m], neigh[:m])
        ids = {name: id(b) for name, b in ws._bufs.items()}
        assert {"bin_p", "bin_xs", "bin_cell", "bin_counts", "aside"} <= set(ids) and (kept is None or ids == kept)
        kept = ids
    crew = ws.crew(parts)
    assert ws.crew(parts) is crew and crew.size == parts


def test_threaded_build_says_when_the_list_is_short():
    """A list storage too short for some part: -1 (the caller grows it), as build_case."""
    x, lo, length, per = liquid(6)
    owner, first, neigh, m = one_thread_list(x, lo, length, per)
    short = np.empty(m // 2, np.int32)
    assert pair_compiled.build_threaded(x, lo, length, per, 2.8, owner.copy(), first.copy(), short, 2) == -1
    assert pair_compiled.build_case(x, lo, length, per, 2.8, owner.copy(), first.copy(), short) == -1


def run_threads(monkeypatch, config: dict, n: int):
    """(results, engine) of one case on n threads, any case of >= 2 atoms per thread split."""
    monkeypatch.setenv("WALLBATCH_NUMBA", "1")
    monkeypatch.setenv("WALLBATCH_THREADS", str(n))
    monkeypatch.setattr(pair_compiled, "THREAD_MIN_ATOMS", 2)
    monkeypatch.setattr(pair_compiled, "THREAD_MIN_USE", 0.0)  # never judged busy (a loaded test machine)
    eng = Engine(cases_of(config))
    assert isinstance(eng.fast, PairChunks)
    return eng.run(), eng


def threads_match_one(monkeypatch, config: dict) -> tuple[list, Engine, list[Engine]]:
    """(results, engine) of one thread and the engines of 2 and 3 threads, after checking that
    these give every sample, the final state and the neighbor builds of one thread bit for bit,
    every kernel call threaded (one thread: none; a call records a run of samples in the kernel,
    or one chunk per sample where the engine asks so), no chunk handed back."""
    ref, one = run_threads(monkeypatch, config, 1)
    assert one.fast.threaded_chunks == 0 and one.fast.compiled_chunks >= 3 and one.fast.fallbacks == 0
    engines = []
    for n in (2, 3):
        got, eng = run_threads(monkeypatch, config, n)
        assert_bits(got, ref)
        assert eng.fast.compiled_chunks == one.fast.compiled_chunks  # (samples recorded in the kernel: one each)
        assert eng.fast.threaded_chunks == (eng.fast.sampled_calls or eng.fast.compiled_chunks)  # every call threaded
        assert eng.fast.fallbacks == 0
        for name in ("x", "v", "f"):
            np.testing.assert_array_equal(getattr(eng.state, name), getattr(one.state, name), err_msg=name)
        np.testing.assert_array_equal(eng.pair.case_builds, one.pair.case_builds)
        engines.append(eng)
    return ref, one, engines


@pytest.mark.parametrize("scene", ["slit", "flow", "cavity"])
def test_one_case_on_threads_same_bits_as_one_thread(monkeypatch, scene):
    """lj93 slit (energy, virial, pressure sampled), wall/flow walls (random streams in the
    step), a wall/region sphere and a flat floor: 2 and 3 threads give every sample, the final
    state and the neighbor builds of one thread, bit for bit, and the chunks ran threaded."""
    config = {"slit": slit, "flow": flow_fluid, "cavity": sphere_cavity}[scene]()
    _, one, _ = threads_match_one(monkeypatch, config)
    assert one.pair.case_builds.min() >= 2  # lists rebuilt inside the chunks


@pytest.mark.parametrize("scene", sorted(THERMOSTATS) + ["langevin+enforce2d"])
def test_thermostats_on_threads_same_bits_as_one_thread(monkeypatch, scene):
    """A case with a thermostat cut over threads: each thread runs the Langevin forces and the
    final kick on its atoms, the fixes' sums over all atoms (nvt's chain, berendsen's and rescale's
    temperature, the Langevin draws atom after atom and its tally) run between the threads'
    calls (`fix_phase`), so 2 and 3 threads give one thread's samples (ecouple, econserve
    included), final state and Langevin forces bit for bit, every chunk threaded; and the
    thermostat did act."""
    kind, _, extra = scene.partition("+")
    config = liquid_2d() if extra == "enforce2d" else slit(steps=60, thermo=20)  # (2-D: enforce2d as a fix)
    config["fixes"] = dict(THERMOSTATS[kind])
    config["run"]["thermo"] = 20
    config["output"] = {"thermo": ["step", "temp", "pe", "etot", "press", "ecouple", "econserve"]}
    ref, one, engines = threads_match_one(monkeypatch, config)
    assert np.ptp(ref[0].data["ecouple"]) > 1e-3  # the thermostat exchanged energy
    for eng in engines:
        for a, b in zip(eng.ensemble.fixes, one.ensemble.fixes):
            if a.style == "langevin":
                assert np.abs(b.force).max() > 0
                np.testing.assert_array_equal(a.force, b.force)
    if extra == "enforce2d":
        assert [f.style for f in one.ensemble.fixes].count("enforce2d") == 1
        assert not one.state.v[..., 2].any() and not one.state.x[..., 2].any()


def test_reflect_walls_on_threads_same_bits_as_one_thread(monkeypatch):
    """wall/reflect faces without statistics, one moving (a variable; frame wall: reflected
    relative to the wall's velocity), on a case cut over threads: each thread reflects its atoms
    after the drift (`_pre_step`), the faces' last coords advance once all threads read them, so
    2 and 3 threads give one thread's samples and final state bit for bit, every chunk threaded;
    and the atoms stayed between the walls."""
    d = slit(steps=60, thermo=20)
    d["variables"] = {"top": "vdisplace(7.0, -1.0)"}
    d["walls"] = {"r": {"style": "reflect", "units": "box", "frame": "wall", "zlo": 1.6, "zhi": "v_top"}}
    _, one, _ = threads_match_one(monkeypatch, d)
    z = one.state.x[0, :, 2]
    top = 7.0 - 1.0 * 60 * 0.005
    assert z.min() >= 1.6 and z.max() <= top + 1e-12
    assert np.count_nonzero(z > top - 0.2) > 0  # atoms met the moving wall


def test_a_zero_temperature_on_threads_is_reported_as_on_one_thread(monkeypatch):
    """temp/berendsen meets a group at zero temperature (every atom at rest) in a threaded chunk:
    `fix_phase`'s status 6 hands the chunk back, and the NumPy loop reports what one thread does."""
    config = slit(steps=30, thermo=10)
    grid = [[a, b, c] for a in (1.5, 4.5, 7.5) for b in (1.5, 4.5, 7.5) for c in (3.0, 6.0, 9.0)]
    config["box"] = {"lo": [0, 0, 0], "hi": [9.0, 9.0, 12.0], "boundary": ["p", "p", "f"]}
    config["atoms"] = [{"group": "still", "create": {"positions": grid}, "mass": 1.0}]  # 3 apart: no forces
    config["fixes"] = dict(THERMOSTATS["berendsen"])
    ref, _ = run_threads(monkeypatch, config, 1)
    got, eng = run_threads(monkeypatch, config, 2)
    assert_bits(got, ref)
    assert ref[0].status == "failed" and "fixes.b: the temperature of group 'all' is 0 at step 1" in ref[0].error
    assert eng.fast.fallbacks >= 1 and eng.fast.threaded_chunks >= 1


def test_trouble_on_threads_hands_the_chunk_back(monkeypatch):
    """An atom shot through the lower wall in a threaded chunk: the chunk goes back to the NumPy
    loop, which reports what one thread reports."""
    bad = slit(steps=30)
    bad["atoms"].append({"group": "bullet", "create": {"positions": [[3.4, 3.4, 0.9]]}, "mass": 1.0,
                         "velocity": {"values": [[0.0, 0.0, -400.0]]}})
    ref, _ = run_threads(monkeypatch, bad, 1)
    got, eng = run_threads(monkeypatch, bad, 2)
    assert_bits(got, ref)
    assert got[0].status == "failed" and eng.fast.fallbacks >= 1 and eng.fast.threaded_chunks >= 1


def test_few_atoms_per_thread_stay_one_call(monkeypatch):
    """Below THREAD_MIN_ATOMS atoms per thread the chunk is one kernel call."""
    monkeypatch.setenv("WALLBATCH_NUMBA", "1")
    monkeypatch.setenv("WALLBATCH_THREADS", "2")
    eng = Engine(cases_of(slit()))
    assert eng.run()[0].status == "ok"
    assert eng.fast.compiled_chunks == 4 and eng.fast.threaded_chunks == 0


def test_busy_cores_run_chunks_in_one_call_for_a_while(monkeypatch):
    """A threaded chunk that used less of its cores than THREAD_MIN_USE (here: any) is followed by
    BUSY_SKIP chunks in one call, then threads again; the bits stay those of one thread."""
    config = slit(steps=80, thermo=10)
    ref, _ = run_threads(monkeypatch, config, 1)
    monkeypatch.setattr(pair_compiled, "BUSY_MIN_WALL", 0.0)
    monkeypatch.setattr(pair_compiled, "BUSY_SKIP", 3)
    monkeypatch.setenv("WALLBATCH_THREADS", "2")
    monkeypatch.setattr(pair_compiled, "THREAD_MIN_USE", 1e9)  # every threaded chunk looks starved
    monkeypatch.setattr(PairChunks, "samples_in_kernel", lambda self, at: False)  # a chunk per sample
    eng = Engine(cases_of(config))
    got = eng.run()
    assert_bits(got, ref)
    assert eng.fast.compiled_chunks == 8 and eng.fast.threaded_chunks == 2  # chunks 1 and 5 on threads


@pytest.mark.parametrize("parts", [2, 3, 5])
def test_threaded_pass_with_outputs_gives_the_one_thread_energy_and_virial(parts):
    """The sampled step's pass over threads: forces, energy and virial of `forces_case` bit for bit
    (each row's sums, then the rows in order), whatever the side split of the logs (`cut`); and
    the energy is the sum of the pairs' shifted LJ energies (a NumPy sum, to rounding)."""
    x, lo, length, per = liquid()
    owner, first, neigh, m = one_thread_list(x, lo, length, per)
    f1 = np.zeros_like(x)
    e1, w1 = pair_compiled.forces_case(x, f1, owner, first, neigh, E24, E4, SIG2, RC2, OFF, length, per, True)
    i, j = np.repeat(owner, np.diff(first)), neigh[:m]
    d = x[i] - x[j]
    d[:, :2] -= length[:2] * np.rint(d[:, :2] / length[:2])
    r2 = np.einsum("ij,ij->i", d, d)
    s6 = (SIG2 / r2) ** 3
    inside = r2 < RC2
    assert inside.sum() > 20 * len(x) and e1 == pytest.approx(np.sum((E4 * s6 * (s6 - 1.0) - OFF)[inside]), rel=1e-12)
    assert w1 == pytest.approx(np.sum((E24 * s6 * (2.0 * s6 - 1.0))[inside]), rel=1e-12)
    split = pair_compiled.RowSplit(owner, first, neigh, parts)
    for cut in (len(x), len(x) // 2, len(x) // 3, 0):
        f2 = np.zeros_like(x)
        _, e2, w2 = pair_compiled.forces_threaded(x, f2, owner, first, neigh, split, E24, E4, SIG2, RC2, OFF,
                                                  length, per, outputs=True, cut=cut)
        np.testing.assert_array_equal(f2, f1)
        assert (e2, w2) == (e1, w1)
        if 0 < cut < len(x):  # both sides of the logs in use
            assert (split.ends > split.logs[:-1]).any() and (split.downs < split.logs[1:]).any()
        f3 = np.zeros_like(x)  # replayed atom run by atom run, as the threads of a chunk do
        pair_compiled.forces_threaded(x, f3, owner, first, neigh, split, E24, E4, SIG2, RC2, OFF, length, per,
                                      replay=False, cut=cut)
        for a0, a1 in ((0, cut), (cut, len(x))):
            split.replay(f3, a0, a1)
        np.testing.assert_array_equal(f3, f1)


def test_row_split_reuses_the_logs_of_an_earlier_one():
    """A RowSplit made with `reuse` takes the earlier split's log arrays (no fresh pages) and
    still gives the one-thread forces bit for bit; a too-short one is not taken."""
    x, lo, length, per = liquid()
    owner, first, neigh, m = one_thread_list(x, lo, length, per)
    f1 = np.zeros_like(x)
    pair_compiled.forces_case(x, f1, owner, first, neigh, E24, E4, SIG2, RC2, OFF, length, per, False)
    old = pair_compiled.RowSplit(owner, first, neigh, 2)
    new = pair_compiled.RowSplit(owner, first, neigh, 2, reuse=old)
    assert new.lj is old.lj and new.lv is old.lv
    f2 = np.zeros_like(x)
    pair_compiled.forces_threaded(x, f2, owner, first, neigh, new, E24, E4, SIG2, RC2, OFF, length, per)
    np.testing.assert_array_equal(f2, f1)
    old.lj, old.lv = old.lj[:1], old.lv[:1]
    assert pair_compiled.RowSplit(owner, first, neigh, 2, reuse=old).lj is not old.lj


def test_pair_compute_of_one_large_case_on_threads(monkeypatch):
    """pair.compute outside chunks (the set-up's build and pass, per-step passes of scenes the
    chunks do not run) for one case of >= THREAD_MIN_ATOMS atoms per thread: the list, forces,
    energy and virial of one thread bit for bit; the split is kept while the list stays."""
    from wallbatch.engine.pair import PairLJCut

    x, lo, length, per = liquid(8)
    x = x[None]
    got = {}
    for n in (1, 2, 3):
        monkeypatch.setenv("WALLBATCH_THREADS", str(n))
        monkeypatch.setattr(pair_compiled, "THREAD_MIN_ATOMS", 256)
        pair = PairLJCut(1.0, 1.0, 2.5, box_lo=lo, box_hi=lo + length, periodic=per, skin=0.3, shift=True,
                         compiled=True)
        f = np.zeros_like(x)
        e, w = pair.compute(x, f, True)
        split = None if pair._split is None else pair._split[1]
        assert (split is None) == (n == 1)
        f2 = np.zeros_like(x)
        pair.compute(x + 0.01, f2, False)  # moved less than skin/2: the same list and split
        assert pair.builds == 1 and (n == 1 or pair._split[1] is split)
        got[n] = (f, e, w, f2, pair._owner.copy(), pair._first.copy(), pair._neigh[0, :pair._first[0, -1]].copy())
    for n in (2, 3):
        for a, b in zip(got[n], got[1]):
            np.testing.assert_array_equal(a, b)


@pytest.mark.parametrize("parts", [2, 3])
def test_row_split_logs_exactly_what_its_parts_write(parts):
    """RowSplit sizes each part's log to the additions its rows log (counted in `_mixed`: partners
    and owners whose first part is another), so a pass fills every part's log exactly, from both
    ends (q up from logs[p], qd down from logs[p+1], meeting), whatever the side cut; the count is
    the one of the firstp rule recomputed here in NumPy; part 0 logs nothing."""
    x, lo, length, per = liquid()
    owner, first, neigh, m = one_thread_list(x, lo, length, per)
    f1 = np.zeros_like(x)
    pair_compiled.forces_case(x, f1, owner, first, neigh, E24, E4, SIG2, RC2, OFF, length, per, False)
    split = pair_compiled.RowSplit(owner, first, neigh, parts)
    rowpart = np.searchsorted(split.rb, np.arange(len(owner)), side="right") - 1
    i, j = np.repeat(owner, np.diff(first)), neigh[:m]
    want = np.bincount(np.repeat(rowpart, np.diff(first))[split.firstp[j] != np.repeat(rowpart, np.diff(first))],
                       minlength=parts) + np.bincount(rowpart[split.firstp[owner] != rowpart], minlength=parts)
    np.testing.assert_array_equal(np.diff(split.logs), want)
    assert want[0] == 0 and (want[1:] > 0).all() and want.sum() < m // 2  # logs far shorter than the pairs
    for cut in (0, len(x) // 2, len(x)):
        f2 = np.zeros_like(x)
        pair_compiled.forces_threaded(x, f2, owner, first, neigh, split, E24, E4, SIG2, RC2, OFF, length, per,
                                      cut=cut)
        np.testing.assert_array_equal(split.ends, split.downs)  # each part's log written end to end
        np.testing.assert_array_equal(f2, f1)


def test_row_splits_of_one_workspace_share_its_log_arrays():
    """Splits made with a Workspace's `buffer` take their logs and row outputs from it (kept
    arrays: no fresh pages per split), one after another on lists of moved atoms, and each pass
    still gives the one-thread forces, energy and virial bit for bit."""
    x, lo, length, per = liquid()
    ws = pair_compiled.Workspace()
    crew = ws.crew(2)
    seen = set()
    for step in range(3):
        xs = x + 0.05 * step * np.random.default_rng(step).normal(size=x.shape)
        owner, first, neigh, m = one_thread_list(xs, lo, length, per)
        f1 = np.zeros_like(xs)
        e1, w1 = pair_compiled.forces_case(xs, f1, owner, first, neigh, E24, E4, SIG2, RC2, OFF, length, per, True)
        split = pair_compiled.RowSplit(owner, first, neigh, 2, crew, buffer=ws.buffer)
        seen.add((id(split.lj), id(split.lv)))
        f2 = np.zeros_like(xs)
        _, e2, w2 = pair_compiled.forces_threaded(xs, f2, owner, first, neigh, split, E24, E4, SIG2, RC2, OFF,
                                                  length, per, crew, outputs=True)
        np.testing.assert_array_equal(f2, f1)
        assert (e2, w2) == (e1, w1)
        assert split.row_outputs() is ws.buffer("rowew", (len(owner), 2), np.float64)
    assert len(seen) == 1 and split.lj is ws.buffer("log_j", split.lj.shape, np.int32)


@pytest.mark.parametrize("fixes", [{"i": "fix i fluid nve"},
                                   {"i": "fix i fluid nve", "t": "fix t fluid langevin 1.5 1.5 0.5 77 tally yes"}])
def test_frozen_atoms_on_threads_same_bits_as_one_thread(monkeypatch, fixes):
    """Atoms outside every integrator's group (`frozen_post`) in a case cut over threads: each
    thread drifts and kicks only its integrated atoms; 2 and 3 threads give one thread's bits,
    and the post keeps its positions and velocities to the bit."""
    ref, one, engines = threads_match_one(monkeypatch, frozen_post(fixes))
    start = cases_of(frozen_post(fixes))[0]
    for eng in (one, *engines):
        np.testing.assert_array_equal(eng.state.x[0, :12], start.x[:12])
        np.testing.assert_array_equal(eng.state.v[0, :12], start.v[:12])


@pytest.mark.parametrize("kind", ["langevin", "berendsen", "nvt"])
def test_thermostat_in_a_run_to_a_time_on_threads(monkeypatch, kind):
    """A run to a simulated time with a thermostat whose target ramps, on threads: `fix_phase`
    takes the case's clock for the ramp (time / run time); 2 and 3 threads give one thread's
    bits, one threaded chunk per sample interval."""
    config = timed_slit(0.0045)
    config["fixes"] = dict(THERMOSTATS[kind])
    config["output"]["thermo"] += ["ecouple", "econserve"]
    ref, one, engines = threads_match_one(monkeypatch, config)
    assert one.fast.compiled_chunks == 3


@pytest.mark.parametrize("kind", ["langevin", "nvt", "berendsen"])
def test_thermostat_with_flow_walls_on_threads(monkeypatch, kind):
    """A thermostat with wall/flow walls in a case cut over threads: the step's tail (all atoms)
    runs the fixes' end of step before the flow walls, as Engine.step does; 2 and 3 threads give
    one thread's bits, every chunk threaded."""
    config = flow_fluid("exact")
    config["fixes"] = dict(THERMOSTATS[kind])
    config["output"] = {"thermo": ["step", "temp", "pe", "etot", "ecouple", "econserve", "flow_crossings"]}
    ref, one, engines = threads_match_one(monkeypatch, config)
    assert ref[0].data["flow_crossings"][1:].sum() > 5 and np.ptp(ref[0].data["ecouple"]) > 0


LANGEVIN_SPLIT = {  # Langevin fixes whose draws the threads share (`SplitDraws`): no zero yes, no fix nvt
    "fluid+post": {"i": "fix i all nve", "t": "fix t fluid langevin 1.5 1.5 0.5 77 tally yes",
                   "p": "fix p post langevin 0.5 0.5 0.2 91"},
    "all+berendsen": {"i": "fix i all nve", "t": "fix t all langevin 1.5 1.0 0.5 48279",
                      "b": "fix b fluid temp/berendsen 1.5 1.0 0.2"},
    "zero-yes": {"i": "fix i all nve", "t": "fix t all langevin 1.5 1.0 0.5 48279 zero yes"},  # (one thread draws)
}


@pytest.mark.parametrize("scene", sorted(LANGEVIN_SPLIT))
def test_langevin_draws_split_over_threads_keep_the_one_thread_stream(monkeypatch, scene):
    """Langevin random forces drawn by the threads at once, each its run of atoms from copies of
    the fixes' generators advanced past the atoms before it (`SplitDraws`; a fix on the 12 post
    atoms, which all sit in the first run, and one on the fluid): 2 and 3 threads give one
    thread's samples, final state and Langevin forces bit for bit, over several chunks (each
    continuing the streams where the last ended). With zero yes one thread draws them all."""
    done = []
    real = pair_compiled.SplitDraws.done
    monkeypatch.setattr(pair_compiled.SplitDraws, "done", lambda self: done.append(1) or real(self))
    ref, one, engines = threads_match_one(monkeypatch, frozen_post(dict(LANGEVIN_SPLIT[scene])))
    assert (len(done) > 0) == (scene != "zero-yes")
    assert one.fast.compiled_chunks >= 3
    for eng in engines:
        for a, b in zip(eng.ensemble.fixes, one.ensemble.fixes):
            if a.style == "langevin":
                assert np.abs(b.force).max() > 0
                np.testing.assert_array_equal(a.force, b.force)
        for a, b in zip(eng.ensemble.langevin, one.ensemble.langevin):
            assert [r.bit_generator.state for r in a.rngs] == [r.bit_generator.state for r in b.rngs]


def test_split_draws_generators_stand_where_the_one_stream_reaches_each_part():
    """`SplitDraws`: part p's generators give the one stream's numbers from draw before[p] on, and
    after `done` each fix's generator stands where the one stream ends (two steps, each 30 draws
    per stream); a generator of another kind, or one holding half a 64-bit output, is refused, and
    `of` counts three draws per group atom before each part."""
    gens = (np.random.default_rng(11), np.random.default_rng(12))
    streams = [np.random.default_rng(11).random(60), np.random.default_rng(12).random(60)]
    before = np.array([[0, 0], [9, 0], [21, 6]])  # each part's first draw per fix (three parts)
    ends = np.vstack([before[1:], [30, 30]])
    split = pair_compiled.SplitDraws(gens, before)
    for step in range(2):
        parts = split.ready()
        got = [np.concatenate([parts[p][f].random(int(ends[p, f] - before[p, f])) for p in range(3)]) for f in range(2)]
        split.done()
        for f in range(2):
            np.testing.assert_array_equal(got[f], streams[f][30 * step:30 * step + 30])
    for f in range(2):
        ref = np.random.default_rng(11 + f)
        ref.random(60)
        assert gens[f].bit_generator.state == ref.bit_generator.state
    meta = np.array([[pair_compiled._compiled.FIX_LANGEVIN, 0, 0, 0, 0]])
    mask = np.array([[1, 0, 1, 1, 0, 1]], np.uint8)
    assert pair_compiled.SplitDraws.of(((meta,), (np.random.Generator(np.random.MT19937(1)),)), mask, [0, 3]) is None
    half = np.random.default_rng(1)
    half.integers(0, 10, dtype=np.uint32)  # (a 32-bit draw keeps the other half of its output)
    assert pair_compiled.SplitDraws.of(((meta,), (half,)), mask, [0, 3]) is None
    zero = meta.copy()
    zero[0, 3] = 1
    assert pair_compiled.SplitDraws.of(((zero,), (np.random.default_rng(1),)), mask, [0, 3]) is None
    ok = pair_compiled.SplitDraws.of(((meta,), (np.random.default_rng(1),)), mask, [0, 2, 5])
    np.testing.assert_array_equal(ok.before[:, 0], [0, 3, 9])
