"""The plan-level choice of engine (engine/backend.py): a plan whose work, sum over all cases of
steps x (atoms + STEP_ATOMS), is below SMALL_RUN runs NumPy (numba never imported), otherwise
compiled; WALLBATCH_NUMBA=0/1 forces either; the choice covers every case and every worker, and
atoms are counted from the config and the headers of atoms files."""

from __future__ import annotations

import numpy as np
import pytest

from factories import slit_yaml
from wallbatch.batch.runner import run_plan
from wallbatch.config.models import load_config, load_config_text
from wallbatch.config.sweep import load_plan
from wallbatch.engine import backend
from wallbatch.scene.build import atom_count, build_case


def plan_of(tmp_path, count: int, steps: int, sweep: str = ""):
    path = tmp_path / "scene.yaml"
    path.write_text(slit_yaml("b", count, steps, max(1, steps // 4)) + sweep)
    return load_plan(path)


def test_work_is_steps_times_atoms_plus_the_step_cost_summed_over_every_case(tmp_path, monkeypatch):
    monkeypatch.delenv("WALLBATCH_NUMBA", raising=False)
    one = plan_of(tmp_path, 30, 400)
    assert backend.plan_work(one) == 400 * (30 + backend.STEP_ATOMS)
    sweep = plan_of(tmp_path, 30, 400, "sweep:\n  product: {walls.zwalls.zlo.epsilon: [1.0, 2.0, 3.0]}\n")
    assert backend.plan_work(sweep) == 3 * 400 * (30 + backend.STEP_ATOMS)
    assert backend.choose(one) is False and backend.choose(sweep) is False
    steps = -(-backend.SMALL_RUN // (30 + backend.STEP_ATOMS))  # the first length at the threshold
    assert backend.choose(plan_of(tmp_path, 30, steps)) is True
    assert backend.choose(plan_of(tmp_path, 30, steps - 1)) is False


def test_pair_forces_and_ellipsoids_weigh_more(tmp_path, monkeypatch):
    """NumPy's pair lj/cut and ellipsoid steps cost ~50x per atom: their plans go compiled sooner."""
    monkeypatch.delenv("WALLBATCH_NUMBA", raising=False)
    flat = plan_of(tmp_path, 30, 400)
    path = tmp_path / "pair.yaml"
    path.write_text(slit_yaml("b", 30, 400, 100) + "pair: {style: lj/cut, epsilon: 1.0, sigma: 1.0, cutoff: 2.5}\n")
    pair = load_plan(path)
    assert backend.plan_work(pair) == 400 * (backend.HEAVY_ATOM * 30 + backend.HEAVY_STEP * backend.STEP_ATOMS)
    assert backend.plan_work(pair) > 10 * backend.plan_work(flat)


@pytest.mark.parametrize("value, compiled", [("0", False), ("off", False), ("1", True), ("yes", True)])
def test_wallbatch_numba_forces_the_path_for_any_plan(tmp_path, monkeypatch, value, compiled):
    monkeypatch.setenv("WALLBATCH_NUMBA", value)
    for steps in (10, 10**6):
        plan = plan_of(tmp_path, 30, steps)
        assert backend.choose(plan) is compiled
        with backend.plan_path(not compiled):  # the environment wins over a plan's choice
            assert backend.numba_allowed() is compiled
    assert "WALLBATCH_NUMBA" in backend.describe(plan)


def test_a_small_plan_runs_numpy_in_every_case_and_is_restored_after(tmp_path, monkeypatch):
    """While the plan runs (on_result is called in the run) the compiled path is off; after it,
    the process default (compiled allowed) is back; the results equal the NumPy engine's."""
    monkeypatch.delenv("WALLBATCH_NUMBA", raising=False)
    plan = plan_of(tmp_path, 30, 40, "sweep:\n  product: {walls.zwalls.zlo.epsilon: [1.0, 2.0]}\n")
    seen = []
    ds = run_plan(plan, None, progress=False, on_result=lambda i, r: seen.append(backend.numba_allowed()))
    assert seen == [False, False] and backend.numba_allowed() is True
    assert backend.describe(plan).startswith("engine: NumPy: work 3.22e+05")
    monkeypatch.setenv("WALLBATCH_NUMBA", "0")
    ref = run_plan(plan, None, progress=False)
    for name in ("pe", "ke", "wall_force"):
        np.testing.assert_array_equal(ds[name].values, ref[name].values)


DATA = """\
LAMMPS data file

3 atoms
1 atom types

0 10 xlo xhi
0 10 ylo yhi
0 10 zlo zhi

Atoms # atomic

1 1 1.0 1.0 1.0
2 1 2.0 2.0 2.0
3 1 3.0 3.0 3.0
"""


def test_atom_count_reads_file_headers_and_matches_the_built_case(tmp_path):
    (tmp_path / "s.data").write_text(DATA)
    np.savez(tmp_path / "s.npz", x=np.full((4, 3), 5.0))
    text = ("units: lj\nseed: 1\nbox: {lo: [0, 0, 0], hi: [10, 10, 10], boundary: [p, p, f]}\natoms:\n"
            "  - group: a\n    create: {file: %s}\n    mass: 1.0\n"
            "  - group: b\n    create: {random: {count: 7}}\n    mass: 1.0\n"
            "  - group: c\n    create: {positions: [[1, 1, 1], [2, 2, 2]]}\n    mass: 1.0\nrun: {steps: 10}\n")
    for name, n in (("s.data", 3), ("s.npz", 4)):
        (tmp_path / "scene.yaml").write_text(text % name)
        cfg = load_config(tmp_path / "scene.yaml")
        assert atom_count(cfg) == n + 7 + 2 == build_case(cfg).natoms
    (tmp_path / "scene.yaml").write_text(text % "missing.data")
    assert atom_count(load_config(tmp_path / "scene.yaml")) == 9  # unreadable: counted 0 (the build fails)


def test_a_lattice_counts_the_box_over_the_cell():
    """fcc at reduced density 0.8 in a 6^3 box: ceil(6 / a)^3 cells of 4 atoms, at least the
    atoms the lattice places and not far above."""
    cfg = load_config_text("units: lj\nseed: 1\nlattice: {style: fcc, scale: 0.8}\n"
                           "box: {lo: [0, 0, 0], hi: [6, 6, 6], boundary: [p, p, p]}\n"
                           "atoms:\n  - group: a\n    create: {lattice: {}}\n    mass: 1.0\nrun: {steps: 10}\n")
    built = build_case(cfg).natoms
    assert built <= atom_count(cfg) <= 1.5 * built



@pytest.mark.slow
def test_a_ctrl_c_during_a_kernel_that_returns_an_array_is_an_interrupt():
    """A SIGINT while a compiled function that returns a tuple holding an array runs: numba's
    boxing of the array runs Python code, which raises the pending KeyboardInterrupt, and the call
    fails with a SystemError caused by it; `call_kernel` raises it as KeyboardInterrupt (the pair chunks'
    kernel returns its list: a Ctrl-C failed the case as an internal error), and a result
    without a signal as it is."""
    import os
    import signal
    import threading
    import time

    numba = pytest.importorskip("numba")

    @numba.njit(nogil=True)
    def spin(n):
        x = 0.0
        for k in range(n):
            x += 1e-9 * (k & 7)
        return 0, n, np.full(3, x)  # (status, count, array): as the pair chunk returns its list

    spin(10)  # compile
    t0 = time.perf_counter()
    spin(20_000_000)
    per = max(1e-9, (time.perf_counter() - t0) / 20_000_000)
    n = int(0.4 / per)  # ~0.4 s; the signal at 0.1 s
    old = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        got_8 = backend.call_kernel(spin, 8)  # (no signal: the result)
        assert got_8[:2] == (0, 8) and np.array_equal(got_8[2], spin(8)[2]) and got_8[2][0] > 0
        entry = backend.resolved(spin, (n,))  # (the entry point of `backend.resolved`: the same)
        assert entry is not spin
        for call in (spin, lambda m: backend.call_kernel(spin, m), lambda m: backend.call_kernel(entry, m)):
            threading.Timer(0.1, os.kill, (os.getpid(), signal.SIGINT)).start()
            with pytest.raises(BaseException) as got:
                call(n)
                time.sleep(1.0)  # (if the call returned cleanly: the signal lands here)
            if call is spin:  # numba's own report, so the test can fail
                assert got.type is SystemError and isinstance(got.value.__cause__, KeyboardInterrupt)
            else:
                assert got.type is KeyboardInterrupt
    finally:
        signal.signal(signal.SIGINT, old)


@pytest.mark.slow
def test_resolved_entry_point_gives_the_dispatchers_bits_for_tuples_of_arrays():
    """`backend.resolved`: for arguments of a compiled signature (nested tuples of arrays, as the
    pair chunk kernel takes), the overload's own entry point, which writes and returns what the
    dispatcher's call does; the dispatcher itself before that signature is compiled, for
    arguments of another type, and a plain Python function as it is."""
    numba = pytest.importorskip("numba")

    @numba.njit(nogil=True)
    def kick(k, x, pair):
        a, (b, c) = pair
        for i in range(x.shape[0]):
            x[i] += k * a[i] * b[i] - c[i]
        return 0, x.sum()

    rng = np.random.default_rng(5)
    x0 = rng.random(50)
    pair = (rng.random(50), (rng.random(50), rng.random(50)))
    assert backend.resolved(kick, (2, x0, pair)) is kick  # not compiled yet: the dispatcher
    want = x0.copy()
    ref = kick(2, want, pair)
    entry = backend.resolved(kick, (3, x0, pair))  # (another int: the same int64 signature)
    assert entry is not kick
    got = x0.copy()
    assert entry(2, got, pair) == ref
    np.testing.assert_array_equal(got, want)
    assert backend.resolved(kick, (2.0, x0, pair)) is kick  # a float k: no such overload
    assert backend.resolved(kick, (2, x0.astype(np.float32), pair)) is kick

    def plain(k):
        return k

    assert backend.resolved(plain, (1,)) is plain


def test_repeated_calls_type_the_arguments_once():
    """`backend.Repeated`: the first call goes to `first` (or the dispatcher), the later ones to the
    entry point resolved for the first call's argument types, each with the dispatcher's result."""
    numba = pytest.importorskip("numba")

    @numba.njit(nogil=True)
    def scale(x, k):
        for i in range(x.shape[0]):
            x[i] *= k
        return x.sum()

    firsts = []
    call = backend.Repeated(scale, lambda *a: firsts.append(1) or scale(*a))
    assert call.entry is None
    x = np.arange(5.0)
    assert call(x, 2.0) == 20.0 and firsts == [1]
    assert call.entry is not None and call.entry is not scale  # compiled by the first call: its entry point
    assert call(x, 0.5) == 10.0 and firsts == [1]
    np.testing.assert_array_equal(x, np.arange(5.0))


def test_a_later_repeated_of_the_same_kernel_and_argument_kinds_skips_numbas_typing(monkeypatch):
    """`backend.Repeated` without `first` keeps the resolved entry point for the process under the
    arguments' kinds (`argument_kinds`): the next chunk's Repeated of the same kernel, with other
    arrays of the same kinds, calls that entry point at once (no `resolved`, no dispatcher call),
    with the same result; arguments of another kind (float32, a read-only array, an int beyond
    int64) are typed and resolved anew, each to its own entry point."""
    numba = pytest.importorskip("numba")

    @numba.njit(nogil=True)
    def shift(x, pair, k):
        a, b = pair
        for i in range(x.shape[0]):
            x[i] += k * a[i] - b[i]
        return x.sum()

    rng = np.random.default_rng(3)
    x, pair = rng.random(20), (rng.random(20), rng.random(20))
    first = backend.Repeated(shift)
    want = x.copy()
    assert first(want, pair, 2) == pytest.approx(want.sum())
    assert first.entry is not None and first.entry is not shift
    resolves = []
    real = backend.resolved
    monkeypatch.setattr(backend, "resolved", lambda k, a: resolves.append(1) or real(k, a))
    later = backend.Repeated(shift)
    got = x.copy()
    out = later(got, (pair[0].copy(), pair[1].copy()), 2)  # other arrays, the same kinds
    assert resolves == [] and later.entry is first.entry
    np.testing.assert_array_equal(got, want)
    assert out == want.sum()
    other = backend.Repeated(shift)
    x32 = x.astype(np.float32)
    other(x32, pair, 2)
    assert resolves == [1] and other.entry is not first.entry
    np.testing.assert_allclose(x32, want, rtol=1e-6)
    kinds = backend.argument_kinds
    ro = pair[0].copy()
    ro.flags.writeable = False
    assert kinds((x, (pair[0], pair[1]), 2)) == kinds((x.copy(), (pair[1], pair[0]), 7))
    assert kinds((x, (ro, pair[1]), 2)) != kinds((x, pair, 2))  # read-only: another numba type
    assert kinds((x[::2], pair, 2)) != kinds((x, pair, 2))  # strided: layout A
    assert kinds((x, pair, 1 << 63)) != kinds((x, pair, 2))  # beyond int64: uint64
    assert kinds((x, pair, 2.0)) != kinds((x, pair, 2))
    assert kinds((x, [1, 2], 2)) is None  # a list (or any other object): no key, typed each time
    assert kinds((np.float64(1.0),)) == kinds((np.float64(2.0),)) != kinds((np.float32(1.0),))
    rec = np.zeros(1, [("a", "f8")])[0], np.zeros(1, [("b", "i4")])[0]
    assert kinds((rec[0],)) != kinds((rec[1],))  # records: by their fields
