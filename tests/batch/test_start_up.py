"""What a run does once, before and after its cases (batch/runner.py): every case is built exactly
once in a one-process run (the first case, which the results layout comes from, is not built again
at the end), the collector's freezing around the workers' fork leaves a library caller's process
as it was, and `wallbatch run` numbers do not depend on any of it."""

from __future__ import annotations

import gc
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from wallbatch.api import load
from wallbatch.batch import runner
from wallbatch.batch.runner import run_plan
from wallbatch.engine import compiled

ROOT = Path(__file__).resolve().parents[2]


def sweep_file(tmp: Path, cases: int, atoms: int = 200, steps: int = 40, extra: str = "") -> Path:
    path = tmp / "sweep.yaml"
    path.write_text(f"base: {ROOT / 'configs' / 'lj93-slit.yaml'}\n"
                    f"set: {{run.steps: {steps}, run.thermo: 10, atoms.0.create.random.count: {atoms}{extra}}}\n"
                    "sweep: {product: {eps: {path: walls.zwalls.zlo.epsilon, values: {linspace: [0.5, 2.0, "
                    f"{cases}]}}}}}}}}\n")
    return path


def counting_builds(monkeypatch) -> list[tuple]:
    """Every build_one call of the runner, as the case's sweep coordinates."""
    seen: list[tuple] = []
    real = runner.build_one

    def build_one(sc, plan=None):
        seen.append(tuple(sc.coords.values()))
        return real(sc, plan)

    monkeypatch.setattr(runner, "build_one", build_one)
    return seen


@pytest.mark.parametrize("output", [False, True])
def test_one_process_builds_every_case_once(tmp_path, monkeypatch, output):
    plan = load(sweep_file(tmp_path, 5))
    seen = counting_builds(monkeypatch)
    ds = run_plan(plan, tmp_path / "out.nc" if output else None, jobs=1, progress=False)
    assert sorted(seen) == sorted(tuple(sc.coords.values()) for sc in plan.cases)  # five builds, one each
    assert list(ds["status"].values) == ["ok"] * 5
    monkeypatch.undo()
    again = run_plan(plan, None, jobs=1, progress=False)  # the same numbers built the old way round
    for name in ("pe", "ke", "wall_force"):
        np.testing.assert_array_equal(ds[name].values, again[name].values)
    assert ds["seconds"].values.min() > 0  # the first case's build time is still counted


@pytest.mark.slow
def test_a_first_case_that_cannot_be_built_is_skipped_once(tmp_path, monkeypatch):
    """Case 0 fails to build (more atoms than fit at the overlap distance): tried once, its message
    kept; the layout comes from case 1, built once."""
    path = tmp_path / "sweep.yaml"
    path.write_text(f"base: {ROOT / 'configs' / 'lj93-slit.yaml'}\n"
                    "set: {run.steps: 20, run.thermo: 10}\n"
                    "sweep: {product: {n: {path: atoms.0.create.random.count, values: [2000, 50, 60]}}}\n")
    plan = load(path)
    seen = counting_builds(monkeypatch)
    ds = run_plan(plan, None, jobs=1, progress=False)
    assert list(ds["status"].values) == ["failed", "ok", "ok"]
    assert "placed only" in str(ds["error"].values[0])
    assert seen.count((50,)) == 1 and seen.count((60,)) == 1 and seen.count((2000,)) == 1


@pytest.mark.skipif(compiled.njit is None, reason="numba not importable")
@pytest.mark.parametrize("frozen_before", [False, True])
def test_forking_workers_leaves_the_collector_as_it_was(tmp_path, monkeypatch, frozen_before):
    """A library caller's objects are not left frozen by `jobs=2`; a caller that froze its own
    start-up (the command line) keeps it frozen. The numbers equal the one-process run's."""
    monkeypatch.setenv("WALLBATCH_NUMBA", "1")
    plan = load(sweep_file(tmp_path, 4))
    one = run_plan(plan, None, jobs=1, progress=False)
    gc.unfreeze()
    try:
        if frozen_before:
            gc.freeze()
        two = run_plan(plan, tmp_path / "two.nc", jobs=2, progress=False)
        assert (gc.get_freeze_count() > 0) is frozen_before
        assert gc.isenabled()
    finally:
        gc.unfreeze()
    for name in ("pe", "ke", "wall_force", "wall_energy"):
        np.testing.assert_array_equal(two[name].values, one[name].values)


def _child(code: str, var: str, given: str | None) -> list[str]:
    """The words a new Python process running `code` prints, with environment variable `var` unset
    (None) or set to `given`, and this tree's wallbatch."""
    env = {k: v for k, v in os.environ.items() if k != var}
    env["PYTHONPATH"] = str(ROOT / "src")
    if given is not None:
        env[var] = given
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, check=True)
    return out.stdout.split()


_THREADS = """
import os, sys
import wallbatch.cli  # noqa: F401 - the command line's module, as `wallbatch` starts
import numpy  # noqa: F401 - imported by now in any case
print(os.environ.get("OPENBLAS_NUM_THREADS"), len(os.listdir("/proc/self/task")))
"""


@pytest.mark.slow
@pytest.mark.skipif(not Path("/proc/self/task").is_dir(), reason="needs Linux /proc")
@pytest.mark.parametrize("given", [None, "2"])
def test_the_command_line_starts_no_blas_threads_unless_asked(given):
    """NumPy's OpenBLAS starts a thread per core when NumPy is imported (~0.07 s of a command's
    start-up): the command line asks for one, i.e. none besides the main thread, unless the user
    set OPENBLAS_NUM_THREADS (then theirs is kept)."""
    value, tasks = _child(_THREADS, "OPENBLAS_NUM_THREADS", given)
    assert value == (given or "1")
    if given is None:
        assert int(tasks) == 1  # the main thread alone


_PLUGINS = """
import importlib.metadata, os, sys
scans = []
real = importlib.metadata.distributions
importlib.metadata.distributions = lambda *a, **k: (scans.append(1), real(*a, **k))[1]
import wallbatch.cli  # noqa: F401 - the command line's module, as `wallbatch` starts
from wallbatch import api
api.load({"units": "lj", "box": {"lo": [0, 0, 0], "hi": [5, 5, 5]},
          "atoms": [{"group": "g", "create": {"positions": [[1, 1, 1]]}, "mass": 1.0}], "run": {"steps": 1}})
print(repr(os.environ.get("PYDANTIC_DISABLE_PLUGINS")), len(scans))
"""


@pytest.mark.slow
@pytest.mark.parametrize("given", [None, ""])
def test_the_command_line_looks_for_no_pydantic_plugins_unless_asked(given):
    """Looking for Pydantic plugins reads every installed package's entry points at the first
    model's build: the command line turns plugins off (PYDANTIC_DISABLE_PLUGINS=__all__), unless
    the user set the variable (then theirs is kept, and Pydantic looks)."""
    value, scans = _child(_PLUGINS, "PYDANTIC_DISABLE_PLUGINS", given)
    assert value == repr(given if given is not None else "__all__")
    assert (int(scans) > 0) == (given is not None)


def _console(args: list[str], cwd: Path, **env: str) -> subprocess.CompletedProcess:
    """`python -m wallbatch.cli ARGS` as the console script runs (cli.main), output through pipes."""
    full = {**os.environ, "PYTHONPATH": str(ROOT / "src"), **env}
    return subprocess.run([sys.executable, "-m", "wallbatch.cli", *args], cwd=cwd, capture_output=True, text=True,
                          env=full, timeout=600)


@pytest.mark.slow
def test_the_console_script_exits_at_once_with_the_commands_code_and_its_output(tmp_path):
    """cli.main ends the process without Python's teardown: the exit code is the command's (0 ok, 2
    bad input), everything printed reaches the pipes, and the results file is complete (readable,
    every case there)."""
    sweep = sweep_file(tmp_path, 3, atoms=40, steps=20)
    ok = _console(["run", str(sweep), "-o", "out.nc", "--force", "-j", "2"], tmp_path)
    assert ok.returncode == 0, ok.stderr
    assert ok.stdout.strip() == "3 of 3 case(s) ok -> out.nc"
    import xarray as xr

    with xr.open_dataset(tmp_path / "out.nc") as ds:
        assert list(ds["status"].values) == ["ok"] * 3
        assert np.isfinite(ds["pe"].values).all()
    assert not (tmp_path / "out.nc.parts").exists() and not (tmp_path / "out.nc.lock").exists()
    bad = _console(["run", "missing.yaml"], tmp_path)
    assert bad.returncode == 2
    assert bad.stderr.startswith("error: invalid config") and "missing.yaml" in bad.stderr
    version = _console(["--version"], tmp_path)
    assert (version.returncode, version.stdout.startswith("wallbatch ")) == (0, True)


@pytest.mark.slow
def test_a_bad_config_fails_before_the_runner_and_engine_are_imported(tmp_path):
    """`wallbatch run` with a config that cannot be read or validated says so without importing the
    runner, the engine or netCDF4 (the error comes in a fraction of the run's start-up)."""
    (tmp_path / "bad.yaml").write_text("units: lj\nbox: {lo: [0, 0, 0], hi: [1, 1, 1]}\nrun: {steps: -5}\n")
    probe = ("import sys\nimport wallbatch.cli as cli\nsys.argv = ['wallbatch', 'run', sys.argv[1]]\n"
             "try:\n    cli.app()\nexcept SystemExit as exc:\n    code = exc.code\n"
             "print(code, *(m in sys.modules for m in ('wallbatch.batch.runner', 'wallbatch.engine.engine', "
             "'netCDF4')))\n")
    env = {**os.environ, "PYTHONPATH": str(ROOT / "src")}
    for name in ("missing.yaml", "bad.yaml"):
        out = subprocess.run([sys.executable, "-c", probe, name], cwd=tmp_path, capture_output=True, text=True,
                             env=env, check=True)
        assert out.stdout.split() == ["2", "False", "False", "False"], (name, out.stdout, out.stderr)
        assert out.stderr.startswith("error: invalid config")


@pytest.mark.parametrize("before", ["enabled", "disabled"])
def test_importing_the_command_line_leaves_the_collector_as_it_was(before):
    """cli.py pauses the collector while its imports run (~80k long-lived objects) and restores
    it right after: a program importing it keeps its collector on (or off), and no object of
    its own is frozen."""
    code = ("import gc, sys\n"
            f"{'gc.disable()' if before == 'disabled' else ''}\n"
            "import wallbatch.cli\n"
            "print(gc.isenabled(), gc.get_freeze_count(), 'numpy' in sys.modules)")
    env = {**os.environ, "PYTHONPATH": str(ROOT / "src")}
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=120)
    assert res.returncode == 0, res.stderr
    assert res.stdout.split() == [str(before == "enabled"), "0", "True"]
