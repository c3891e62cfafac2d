"""Threads for the compiled chunks (wallbatch.engine.threads): a run with 2 or 3 threads gives
bit for bit the numbers of one thread, for every scene kind it splits (atoms of one case: flat,
region and reflect walls, moving walls, time-based runs; cases of a batch, failures included),
and each test checks that the split really happened (or, for the scenes it must not split,
that it did not). Threads are forced on small scenes (MIN_WORK = 1); atom counts are not
multiples of the split."""

from __future__ import annotations

import numpy as np
import pytest
from factories import slab_gas

from wallbatch.config.models import config_from_dict
from wallbatch.engine import compiled as fast
from wallbatch.engine import threads
from wallbatch.engine.engine import Engine
from wallbatch.scene.build import build_case

pytestmark = pytest.mark.skipif(fast.njit is None, reason="numba not importable")


def gas(walls, *, n=700, steps=120, thermo=40, dt=0.005, seed=5, output=None, **extra):
    return slab_gas(walls, n=n, hi=(14.0, 14.0, 8.0), margin=1.6, temperature=1.5, seed=seed, dt=dt, steps=steps,
                    thermo=thermo, output=output, **extra)


def lj93(lo=0.0, hi=8.0, eps=1.0):
    return {"w": {"style": "lj93", "units": "box", "energy": True,
                  "zlo": {"coord": lo, "epsilon": eps, "sigma": 1.0, "cutoff": 2.5},
                  "zhi": {"coord": hi, "epsilon": 1.0, "sigma": 1.0, "cutoff": 2.5}}}


def run_with(monkeypatch, configs, nthreads):
    """Results of the configs as one batch with `nthreads` threads, the engine, the splits made."""
    monkeypatch.setenv("WALLBATCH_NUMBA", "1")
    monkeypatch.setenv("WALLBATCH_THREADS", str(nthreads))
    monkeypatch.setattr(threads, "MIN_WORK", 1)
    before = dict(threads.splits)
    eng = Engine([build_case(config_from_dict(d)) for d in configs])
    res = eng.run()
    return res, eng, {k: threads.splits[k] - before[k] for k in before}


def assert_identical(a, b):
    assert [r.status for r in a] == [r.status for r in b]
    assert [r.error for r in a] == [r.error for r in b]
    for x, y in zip(a, b):
        assert x.data.keys() == y.data.keys()
        for name in x.data:
            assert np.array_equal(x.data[name], y.data[name], equal_nan=True), name


def check(monkeypatch, configs, split, fallbacks=0):
    """Threaded (2 and 3) == one thread bit for bit; the calls were split as `split` says
    ("atoms", "cases" or None); `fallbacks` chunks handed back to NumPy (a case that fails)."""
    one, eng1, made = run_with(monkeypatch, configs, 1)
    assert made == {"cases": 0, "atoms": 0}
    assert eng1.fast is not None and eng1.fast.compiled_chunks > 0 and eng1.fast.fallbacks == fallbacks
    kinds = len(eng1.fast.kernel.signatures)
    for n in (2, 3):
        got, eng, made = run_with(monkeypatch, configs, n)
        assert_identical(one, got)
        assert eng.fast.compiled_chunks == eng1.fast.compiled_chunks and eng.fast.fallbacks == fallbacks
        assert len(eng.fast.kernel.signatures) == kinds  # the parts' arrays have the same types: no new compile
        for kind in ("atoms", "cases"):
            assert (made[kind] > 0) == (split == kind), (n, made)
    return one


def test_flat_walls_one_case_split_over_atoms(monkeypatch):
    res = check(monkeypatch, [gas(lj93(), output=["step", "ke", "pe"])], "atoms")
    assert res[0].status == "ok" and np.ptp(res[0].data["ke"]) > 0  # the gas moved and met the walls


def test_moving_harmonic_wall_and_reflect_without_statistics(monkeypatch):
    walls = {"w": {"style": "harmonic", "units": "box",
                   "zlo": {"coord": "v_lo", "epsilon": 20.0, "cutoff": 1.5}, "zhi": {"coord": 8.0, "epsilon": 5.0,
                                                                                     "cutoff": 1.0}},
             "r": {"style": "reflect", "units": "box", "frame": "wall", "zhi": 7.2}}
    check(monkeypatch, [gas(walls, variables={"lo": "swiggle(0.0, 0.5, 0.3)"})], "atoms")


def test_region_wall_split_over_atoms(monkeypatch):
    d = gas({}, n=333)
    d["regions"]["ball"] = {"style": "sphere", "center": [7, 7, 4], "radius": 6.5, "units": "box"}
    d["regions"]["mid"] = {"style": "sphere", "center": [7, 7, 4], "radius": 3.5, "units": "box"}
    d["box"]["boundary"] = ["p", "p", "p"]
    d["walls"] = {"r": {"style": "region", "region": "ball", "potential": "lj93", "epsilon": 1.0, "sigma": 1.0,
                        "cutoff": 2.5}}
    check(monkeypatch, [d], "atoms")


def test_time_based_run_split_over_atoms(monkeypatch):
    d = gas(lj93(), thermo={"time": 0.2})
    d["run"] = {"time": 0.6, "thermo": {"time": 0.2}}
    check(monkeypatch, [d], "atoms")


def test_batch_split_over_cases_with_a_failing_case(monkeypatch):
    """Five cases (one has a zero-strength wall inside the gas, which an atom crosses): the same
    statuses, messages and numbers with the cases in 2 or 3 threads."""
    configs = [gas(lj93(eps=e), n=300, seed=s) for e, s in ((1.0, 1), (0.5, 2), (2.0, 3), (1.5, 4))]
    configs.insert(2, gas(lj93(lo=1.5, eps=0.0), n=300, seed=9))
    res = check(monkeypatch, configs, "cases", fallbacks=1)
    assert [r.status for r in res].count("failed") == 1


@pytest.mark.parametrize("what", ["reflect statistics", "dt/reset"])
def test_coupled_atoms_are_not_split(monkeypatch, what):
    """Reflect statistics (sums over atoms) and fix dt/reset (the smallest dt over atoms) couple
    the atoms of a case within a chunk: one case runs in one thread, with the same numbers."""
    if what == "dt/reset":
        d = gas(lj93(lo=0.5), output=["step", "dt", "ke"])
        d["dt_reset"] = {"every": 2, "tmin": 1.0e-5, "tmax": 0.01, "xmax": 0.02, "units": "box"}
    else:
        d = gas({**lj93(), "r": {"style": "reflect", "units": "box", "zhi": 7.0}},
                output=["step", "ke", "reflect_count", "reflect_impulse"])
    res = check(monkeypatch, [d], None)
    if what != "dt/reset":
        assert res[0].data["reflect_count"].sum() > 0


def test_stochastic_reflect_runs_of_cases_one_call_each(monkeypatch):
    """wall/reflect/stochastic draws from its case's generator atom after atom: its chunks run one
    case per call, runs of cases in threads (compiled.FastPath._chunk), with the same numbers."""
    def cfg(seed):
        # both faces stochastic, no other wall: the kernel of tests/engine/test_stochastic_engine.py
        return gas({"s": {"style": "reflect/stochastic", "rstyle": "maxwell", "seed": seed, "units": "box",
                          "zlo": {"coord": 1.5, "temp": 1.5, "accom": 0.5},
                          "zhi": {"coord": 8.0, "temp": 1.0, "accom": 0.8}}},
                   output=["step", "ke", "reflect_count"])
    res = check(monkeypatch, [cfg(3), cfg(4)], "cases")
    assert all(r.data["reflect_count"].sum() > 0 for r in res)


def test_split_points():
    """Atom splits fall on multiples of ALIGN, itself a multiple of the kernel's block (the blocks
    are the same blocks), and cover every atom once; case splits are as even as they can be."""
    assert threads.ALIGN % fast.BLOCK == 0
    x = np.zeros((1, 1000, 3))
    named = {k: None for k in threads.KNOWN}
    named.update(x=x, fx=(np.zeros((0, 4)),), time_mode=False, nsteps=10**6, fl_int=np.zeros(3, np.int64),
                 dtr_every=0, stats=False, st_meta=np.zeros((0, 4), np.int64), sm=(np.zeros(0, np.int64),))
    kind, parts = threads.plan_split(named, 3)  # more runs than threads (OVERSPLIT), here one per block
    assert kind == "atoms" and [(p.start, p.stop) for p in parts] == [(0, 256), (256, 512), (512, 768), (768, 1000)]
    big = {**named, "x": np.zeros((1, 100_000, 3)), "nsteps": 100}
    kind, parts = threads.plan_split(big, 2)
    assert len(parts) == 2 * threads.OVERSPLIT and all(p.start % threads.ALIGN == 0 for p in parts)
    assert parts[0].start == 0 and parts[-1].stop == 100_000
    assert all(a.stop == b.start for a, b in zip(parts, parts[1:]))
    few = threads.plan_split({**big, "nsteps": 5}, 2)[1]  # 5e5 atom-steps: two runs of at least MIN_WORK
    assert len(few) == 2
    named["x"] = np.zeros((7, 10, 3))
    kind, parts = threads.plan_split(named, 2)
    assert kind == "cases" and [(p.start, p.stop) for p in parts] == [(0, 3), (3, 7)]
    assert threads.plan_split({**named, "fl_int": np.array([1, 2, 0])}, 2) is None  # wall/flow
    assert threads.plan_split({**named, "fx": (np.zeros((1, 4)),)}, 2) is None  # fixes:
    assert threads.plan_split({**named, "st_meta": np.zeros((1, 4), np.int64)}, 2) is None  # reflect/stochastic
    one = {**named, "x": np.zeros((1, 1000, 3))}
    assert threads.plan_split({**one, "dtr_every": 5}, 2) is None  # dt/reset couples the atoms
    assert threads.plan_split({**one, "stats": True}, 2) is None  # reflect statistics: sums over atoms
    assert threads.plan_split({**one, "sm": (np.arange(1, 4),)}, 2) is None  # a sampled chunk: sums over atoms
    assert threads.plan_split({**named, "sm": (np.arange(1, 4),)}, 2)[0] == "cases"  # its cases still split
    named["nsteps"] = 10
    assert threads.plan_split(named, 2) is None  # 700 atom-steps: not worth a thread
    named.pop("stats")
    assert threads.plan_split({**named, "nsteps": 10**6}, 2) is None  # an argument list it does not know


def test_runs_go_to_the_thread_that_is_free():
    """More calls than threads: each thread takes the next call not yet taken, so while the first
    call holds one thread the other runs the rest; results come back in call order and an
    exception in one call is re-raised after all ran."""
    import threading
    import time

    who = {}

    def call(k):
        def run():
            who[k] = threading.current_thread().name
            if k == 0:
                time.sleep(0.3)  # this thread busy (a core slowed by other work)
            return 10 + k
        return run

    calls = [call(k) for k in range(8)]
    assert threads._in_threads(calls, 2) == [10 + k for k in range(8)]
    slow = who[0]  # the thread that took the slow call took no other: the other thread ran them all
    assert sum(name == slow for name in who.values()) == 1 and len(set(who.values())) == 2
    assert threads._in_threads(calls[:3]) == [10, 11, 12]  # default: a thread per call

    def bad():
        raise RuntimeError("part 2")

    ran = []
    with pytest.raises(RuntimeError, match="part 2"):
        threads._in_threads([lambda: ran.append(0), bad, lambda: ran.append(2), lambda: ran.append(3)], 2)
    assert sorted(ran) == [0, 2, 3]


def test_thread_count(monkeypatch):
    monkeypatch.setenv("WALLBATCH_THREADS", "3")
    assert threads.count() == 3
    monkeypatch.delenv("WALLBATCH_THREADS")
    monkeypatch.setattr(threads, "_default", None)
    assert threads.count() == threads.usable_cores()
    threads.set_default(1)
    assert threads.count() == 1
    for bad in ("0", "two", "-1", "1.5"):
        monkeypatch.setenv("WALLBATCH_THREADS", bad)
        with pytest.raises(ValueError, match="WALLBATCH_THREADS=.*whole number of threads"):
            threads.count()
