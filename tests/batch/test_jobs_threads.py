"""`--jobs` and threads together: windows per worker, workers forked after this process ran
threaded compiled chunks, and the same numbers whatever the split."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from wallbatch.api import load
from wallbatch.batch import runner
from wallbatch.batch.runner import run_plan
from wallbatch.engine import compiled, threads

ROOT = Path(__file__).resolve().parents[2]


def sweep_file(tmp: Path, cases: int, atoms: int, steps: int = 40) -> Path:
    path = tmp / f"sweep{cases}x{atoms}.yaml"
    path.write_text(f"base: {ROOT / 'configs' / 'lj93-slit.yaml'}\n"
                    f"set: {{run.steps: {steps}, run.thermo: 10, atoms.0.create.random.count: {atoms}}}\n"
                    "sweep: {product: {eps: {path: walls.zwalls.zlo.epsilon, values: {linspace: [0.5, 2.0, "
                    f"{cases}]}}}}}}}}\n")
    return path


def test_windows_per_worker(tmp_path):
    """64 cases of 1000 atoms: one window with one worker, WINDOWS_PER_JOB per worker with two
    (a worker slowed by other load takes fewer); small cases keep windows of MIN_WINDOW_ATOMS
    atoms; every case in exactly one window, in order."""
    plan = load(sweep_file(tmp_path, 64, 1000))
    todo = list(range(64))
    assert [len(w) for w in runner.make_windows(plan, todo, 1)] == [64]
    two = runner.make_windows(plan, todo, 2)
    assert [len(w) for w in two] == [64 // (2 * runner.WINDOWS_PER_JOB)] * (2 * runner.WINDOWS_PER_JOB)
    assert [i for w in two for i in w] == todo
    small = load(sweep_file(tmp_path, 10, 500))
    assert [len(w) for w in runner.make_windows(small, list(range(10)), 2)] == [5, 5]  # 5000 atoms over 4000


@pytest.mark.skipif(compiled.njit is None, reason="numba not importable")
def test_jobs_after_threaded_chunks_in_this_process(tmp_path, monkeypatch):
    """This process first runs a sweep with its chunks split over threads (forced on small
    cases), then forks `--jobs 2` workers: the workers run, and every number is bit-identical to
    the one-thread `--jobs 1` run."""
    monkeypatch.setattr(threads, "MIN_WORK", 1)
    monkeypatch.setenv("WALLBATCH_NUMBA", "1")  # the compiled path, though the plan is small
    plan = load(sweep_file(tmp_path, 6, 300))
    monkeypatch.setenv("WALLBATCH_THREADS", "1")
    one = run_plan(plan, None, jobs=1, progress=False)
    monkeypatch.setenv("WALLBATCH_THREADS", "2")
    before = threads.splits["cases"]
    threaded = run_plan(plan, None, jobs=1, progress=False)
    assert threads.splits["cases"] > before  # the batch of 6 cases did run in two threads here
    monkeypatch.delenv("WALLBATCH_THREADS")  # workers: their share of the cores
    two = run_plan(plan, tmp_path / "two.nc", jobs=2, progress=False)
    for name in ("pe", "ke", "wall_force", "wall_energy"):
        np.testing.assert_array_equal(threaded[name].values, one[name].values)
        np.testing.assert_array_equal(two[name].values, one[name].values)


def test_bad_thread_count_is_a_clear_error(tmp_path, monkeypatch):
    monkeypatch.setenv("WALLBATCH_THREADS", "many")
    with pytest.raises(runner.RunError, match="WALLBATCH_THREADS='many': give a whole number of threads"):
        run_plan(load(sweep_file(tmp_path, 2, 50)), None, jobs=1, progress=False)


def test_small_run_keeps_its_results_instead_of_reading_the_parts(tmp_path, monkeypatch):
    """A run of at most KEEP_CASES cases writes its parts but fills the results file from the
    results it kept (no part read back); the file is identical to one filled from the parts."""
    plan = load(sweep_file(tmp_path, 4, 40))
    reads = []
    real = runner.read_part
    monkeypatch.setattr(runner, "read_part", lambda folder, key: reads.append(key) or real(folder, key))
    kept = run_plan(plan, tmp_path / "kept.nc", jobs=1, progress=False)
    assert reads == []
    monkeypatch.setattr(runner, "KEEP_CASES", 0)
    read = run_plan(plan, tmp_path / "read.nc", jobs=1, progress=False)
    assert len(reads) == 4
    assert sorted(kept.data_vars) == sorted(read.data_vars)
    for name in kept.data_vars:
        if name != "seconds":  # each run's own timing
            np.testing.assert_array_equal(kept[name].values, read[name].values)
    assert kept["pe"].shape == (4, 5) and np.isfinite(kept["pe"].values).all()


@pytest.mark.skipif(compiled.njit is None, reason="numba not importable")
@pytest.mark.parametrize("length, time_based", [("run.steps: 40", False), ("run.steps: null, run.time: 0.2, run.thermo: {time: 0.05}", True)])
def test_warm_up_builds_the_kernel_the_run_uses(monkeypatch, tmp_path, length, time_based):
    """Before forking workers, the first case's warm-up step asks for the very kernel the run will
    use (step- or time-based: each leaves the other's code out), so the workers inherit it instead
    of each compiling another."""
    monkeypatch.setenv("WALLBATCH_NUMBA", "1")
    calls: list[tuple] = []
    real = compiled.kernel_for

    def spy(*args, **kwargs):
        calls.append((args, tuple(sorted(kwargs.items()))))
        return real(*args, **kwargs)

    monkeypatch.setattr(compiled, "kernel_for", spy)
    path = sweep_file(tmp_path, 1, 500, steps=40)
    path.write_text(path.read_text().replace("run.steps: 40, run.thermo: 10", length if time_based else
                                             length + ", run.thermo: 10"))
    case = runner.build_case(load(path).cases[0].config)
    runner._warm_compiler(case)
    warmed = set(calls)
    calls.clear()
    from wallbatch.engine.engine import Engine

    eng = Engine([case])
    assert eng.run()[0].status == "ok" and eng.fast.compiled_chunks > 0
    assert set(calls) == warmed and len(warmed) == 1
    assert dict(next(iter(warmed))[1])["time"] is time_based
