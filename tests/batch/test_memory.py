"""Memory of a run is bounded by what runs, not by the number of cases (issue 14).

The plan itself (one validated config per case) is loaded before measuring: what is measured is
what the run adds on top of it, traced by tracemalloc (NumPy reports its arrays to it).
"""

from __future__ import annotations

import gc
import tracemalloc
from pathlib import Path

import numpy as np
import pytest
import xarray as xr
from factories import cyclic_garbage

from wallbatch.api import load
from wallbatch.batch.runner import run_plan

ROOT = Path(__file__).resolve().parents[2]


def tiny_sweep(tmp: Path, cases: int) -> Path:
    """A sweep file of `cases` cases of 64 atoms between lj93 walls, 3 samples each."""
    path = tmp / f"sweep{cases}.yaml"
    path.write_text(f"base: {ROOT / 'configs' / 'lj93-slit.yaml'}\n"
                    "set: {run.steps: 20, run.thermo: 10, atoms.0.create.random.count: 64}\n"
                    "sweep: {product: {eps: {path: walls.zwalls.zlo.epsilon, values: {linspace: [0.5, 2.0, "
                    f"{cases}]}}}}}}}}\n")
    return path


def traced_peak(tmp: Path, cases: int) -> tuple[int, xr.Dataset]:
    """Peak bytes a run of `cases` cases adds to its loaded plan, and the results it wrote."""
    plan = load(tiny_sweep(tmp, cases))
    run_plan(load(tiny_sweep(tmp, 2)), None, progress=False)  # kernels loaded, caches warm
    gc.collect()
    tracemalloc.start()
    try:
        base = tracemalloc.get_traced_memory()[0]
        run_plan(plan, tmp / f"out{cases}.nc", progress=False)
        peak = tracemalloc.get_traced_memory()[1] - base
    finally:
        tracemalloc.stop()
    return peak, xr.load_dataset(tmp / f"out{cases}.nc")


@pytest.mark.slow  # ~60 s: 1500 cases under tracemalloc
def test_peak_memory_does_not_grow_with_cases(tmp_path, monkeypatch):
    # one engine for both runs: by its work alone the 300-case run would run NumPy, the 1200-case
    # run compiled (engine/backend.py), and what is compared is the cost of more cases
    monkeypatch.setenv("WALLBATCH_NUMBA", "1")
    small, ds_small = traced_peak(tmp_path, 300)  # both above MAX_BATCH: equal windows
    big, ds_big = traced_peak(tmp_path, 1200)
    assert (ds_big["status"] == "ok").all() and (ds_small["status"] == "ok").all()
    # what must grow: the output arrays and their averages, the status and error strings and the
    # bookkeeping of each case (measured: 1.1 kB per case); a run holding every built case and
    # every result twice (before windows) grew by 23 kB per case here. (Until a finished batch's
    # engine was freed by reference counting, tests/engine/test_engine_freed.py, finished windows
    # waited for Python's full collections, and the peak moved with their timing: 3.6 to 7.6 kB
    # per case, depending on what else the process had imported. Then 5.4 kB per case when the
    # whole tests/batch directory ran: a reference cycle per case left to the collector's full
    # passes, and one new interned string per part path, whose table's growth (~3.7 MB at once)
    # came when the process's other interned strings made it: both gone, 1.1 kB per case however
    # the tests are collected and whatever numba imports.)
    grow = big - small
    per_case = grow / 900
    assert per_case < 2_500, f"peak grew by {grow / 1e6:.1f} MB ({per_case:.0f} bytes per case): {small=} {big=}"
    np.testing.assert_array_equal(ds_big["pe"].values[0], ds_small["pe"].values[0])  # same case 0


def test_workers_build_their_own_cases(tmp_path, monkeypatch):
    """With --jobs 2 the tasks sent to the workers are case indices (each worker builds its cases
    from the plan it inherited), and the results are bit-identical to --jobs 1."""
    from wallbatch.batch import runner

    plan = load(tiny_sweep(tmp_path, 6))
    sent = []
    real = runner.execute

    def spy(tasks, jobs, executor, scheduler, plan=None):
        sent.extend(tasks)
        return real(tasks, jobs, executor, scheduler, plan=plan)

    monkeypatch.setattr(runner, "execute", spy)
    one = run_plan(plan, None, jobs=1, progress=False)
    sent.clear()
    two = run_plan(plan, tmp_path / "two.nc", jobs=2, progress=False)
    assert sent and all(type(i) is int for task in sent for i in task)
    assert sorted(i for task in sent for i in task) == list(range(6))
    for name in ("pe", "ke", "wall_force", "wall_energy"):
        np.testing.assert_array_equal(two[name].values, one[name].values)


def test_sweep_changing_the_layout_fails_and_leaves_no_parts(tmp_path):
    """Cases are built window by window, so a swept run length is found when its first case is
    built: a clear error, and no parts left to resume."""
    path = tmp_path / "steps.yaml"
    path.write_text(f"base: {ROOT / 'configs' / 'lj93-slit.yaml'}\n"
                    "set: {run.steps: 20, run.thermo: 10, atoms.0.create.random.count: 8}\n"
                    "sweep: {product: {steps: {path: run.steps, values: [20, 40]}}}\n")
    out = tmp_path / "o.nc"
    from wallbatch.scene.case import CaseError

    words = r"case steps=40 differs from case steps=20 in run\.steps: the cases of a sweep share one results file"
    with pytest.raises(CaseError, match=words):
        run_plan(load(path), out, jobs=1, progress=False)
    assert not (tmp_path / "o.nc.parts").exists() and not out.exists()


@pytest.mark.slow
def test_a_run_leaves_no_cyclic_garbage_per_case(tmp_path):
    """Nothing a case goes through (building it, its variables, running it, saving its part and
    reading it back for the file) leaves reference cycles: garbage that only the collector's full
    passes free, rare in a process holding numba's objects, so the peak memory of a long sweep
    followed their timing (a recursive closure per case in expr.Variables; np.load's header
    parsing per array read back). What is left is the NetCDF writer's, once per run."""
    counts = {}
    for cases in (4, 270):  # 270 > KEEP_CASES: the results are read back from the parts
        plan = load(tiny_sweep(tmp_path, cases))
        with cyclic_garbage(save=False) as left:
            run_plan(plan, tmp_path / f"g{cases}.nc", progress=False)
        counts[cases] = left["found"]
    assert counts[270] - counts[4] < 20, counts
