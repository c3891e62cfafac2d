"""Run UX (issue 13): cheap start-up imports, the one-line compile message, --jobs capped by the
cores and tasks, `seconds` measured per case, runtime failures printed with their coordinates."""

from __future__ import annotations

import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from wallbatch.batch import runner
from wallbatch.batch.runner import run_plan
from wallbatch.cli import app
from wallbatch.config.sweep import load_plan

from factories import slit_yaml

cli = CliRunner()
HEAVY = ("dask", "distributed", "scipy.spatial", "matplotlib")

SCENE = slit_yaml('ux', 30, 4000, 400)


def sweep(tmp_path: Path, body: str) -> Path:
    (tmp_path / "scene.yaml").write_text(SCENE)
    path = tmp_path / "sweep.yaml"
    path.write_text("base: scene.yaml\n" + textwrap.dedent(body))
    return path


@pytest.mark.parametrize("code", ["import wallbatch",
                                  "import sys; sys.argv = ['wallbatch', '--help']\n"
                                  "from wallbatch.cli import app\ntry:\n    app()\nexcept SystemExit:\n    pass"])
def test_startup_imports_no_heavy_module(code):
    probe = code + f"\nimport sys; print('heavy:' + ','.join(m for m in {HEAVY!r} if m in sys.modules))"
    res = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, timeout=120)
    assert res.returncode == 0, res.stderr
    assert res.stdout.strip().splitlines()[-1] == "heavy:"


RUN_HEAVY = ("dask", "distributed", "matplotlib", "numba", "xarray", "pandas", "scipy.spatial", "scipy.sparse")


def _run_probe(tmp_path: Path, numba: str | None) -> list[str]:
    """`wallbatch run` of a small flat-wall scene in a new process: its output lines, then the
    heavy modules it imported."""
    import os

    (tmp_path / "scene.yaml").write_text(SCENE.replace("steps: 4000", "steps: 40"))
    probe = ("import sys; sys.argv = ['wallbatch', 'run', 'scene.yaml', '-o', 'o.nc', '--force']\n"
             "from wallbatch.cli import app\ntry:\n    app()\nexcept SystemExit:\n    pass\n"
             f"print('heavy:' + ','.join(m for m in {RUN_HEAVY!r} if m in sys.modules))")
    env = {k: v for k, v in os.environ.items() if k != "WALLBATCH_NUMBA"}
    if numba is not None:
        env["WALLBATCH_NUMBA"] = numba
    res = subprocess.run([sys.executable, "-c", probe], cwd=tmp_path, capture_output=True, text=True, timeout=300,
                         env=env)
    assert res.returncode == 0, res.stderr
    return res.stdout.strip().splitlines()


@pytest.mark.slow
def test_small_run_imports_neither_numba_nor_xarray_nor_scipy_spatial(tmp_path):
    """A small run (30 atoms x 40 steps, far below backend.SMALL_RUN) runs NumPy, writes its file
    with netCDF4 directly and places atoms without scipy: none of the heavy modules is imported."""
    assert _run_probe(tmp_path, None) == ["1 of 1 case(s) ok -> o.nc", "heavy:"]


@pytest.mark.slow
def test_small_run_with_numba_forced_imports_numba_only(tmp_path):
    """WALLBATCH_NUMBA=1 forces the compiled path whatever the size (and the probe sees it)."""
    assert _run_probe(tmp_path, "1") == ["1 of 1 case(s) ok -> o.nc", "heavy:numba"]


def test_xarray_still_handles_dask_after_a_run(tmp_path):
    """The dask deferral is exact: once dask is imported, chunked data behaves as usual."""
    (tmp_path / "scene.yaml").write_text(SCENE.replace("steps: 4000", "steps: 40"))
    ds = run_plan(load_plan(tmp_path / "scene.yaml"), tmp_path / "o.nc", progress=False)
    import xarray as xr

    with xr.open_dataset(tmp_path / "o.nc", chunks={}) as lazy:
        assert type(lazy["pe"].data).__module__.startswith("dask")
        np.testing.assert_array_equal(lazy["pe"].values, ds["pe"].values)


def test_jobs_capped_by_cores(tmp_path, monkeypatch):
    path = sweep(tmp_path, "sweep: {product: {eps: {path: walls.zwalls.zlo.epsilon, values: [1.0, 2.0]}}}\n")
    monkeypatch.setattr(runner, "usable_cores", lambda: 1)
    seen = {}
    real = runner.execute

    def spy(tasks, jobs, executor, scheduler, plan=None):
        seen["jobs"], seen["tasks"] = jobs, len(tasks)
        return real(tasks, jobs, executor, scheduler, plan=plan)

    monkeypatch.setattr(runner, "execute", spy)
    res = cli.invoke(app, ["run", str(path), "-o", str(tmp_path / "o.nc"), "--jobs", "64"])
    assert res.exit_code == 0, res.output
    assert "--jobs 64 capped at 1 (the cores this machine lets the run use)" in res.output
    assert seen == {"jobs": 1, "tasks": 1}


def test_seconds_are_measured_per_case(tmp_path):
    """Three cases in one batch; one loses an atom at the first steps and leaves the batch: its
    seconds are a small fraction of those that ran 4000 steps (no batch average)."""
    path = sweep(tmp_path, """\
        sweep:
          product:
            top: {path: walls.zwalls.zhi.coord, values: [9.9, 9.95, 30.0]}
        """)
    ds = run_plan(load_plan(path), progress=False)
    assert ds["status"].values.tolist() == ["ok", "ok", "failed"]
    sec = ds["seconds"].values
    assert sec[2] < 0.25 * min(sec[0], sec[1]), sec
    assert sec[0] > 0 and sec[1] > 0


def test_runtime_failure_printed_with_coordinates(tmp_path):
    path = sweep(tmp_path, """\
        sweep:
          product:
            top: {path: walls.zwalls.zhi.coord, values: [9.9, 30.0]}
            eps: {path: walls.zwalls.zlo.epsilon, values: [1.0]}
        """)
    res = cli.invoke(app, ["run", str(path), "-o", str(tmp_path / "o.nc"), "-j", "1"])
    assert res.exit_code == 1
    line = next(ln for ln in res.output.splitlines() if ln.startswith("failed"))
    assert line.startswith("failed (1 case: top=30.0, eps=1.0): atom ") and "left the box" in line


def test_tasks_bounded_by_atoms(tmp_path, monkeypatch):
    """A running batch holds at most MAX_BATCH_ATOMS atoms (its memory is bounded), and the
    results do not depend on how the cases were split."""
    path = sweep(tmp_path, "sweep: {product: {eps: {path: walls.zwalls.zlo.epsilon, values: [1, 2, 3, 4, 5]}}}\n")
    plan = load_plan(path, ["run.steps=40", "run.thermo=20"])
    whole = run_plan(plan, progress=False)
    built, _ = runner.build_cases(plan)
    assert [len(t) for t in runner.make_tasks(dict(enumerate(built)), jobs=1)] == [5]
    monkeypatch.setattr(runner, "MAX_BATCH_ATOMS", 60)  # 30 atoms per case: 2 cases per task
    assert [len(t) for t in runner.make_tasks(dict(enumerate(built)), jobs=1)] == [2, 2, 1]
    split = run_plan(plan, progress=False)
    for name in ("pe", "temp", "wall_force"):
        np.testing.assert_array_equal(split[name].values, whole[name].values)


_GC_PROBE = """
import gc, sys
starts = []
gc.callbacks.append(lambda phase, info: starts.append(info["generation"]) if phase == "start" else None)
sys.argv = ['wallbatch'] + {args!r}
import wallbatch.cli as cli
done = cli._start_up_done
at = {{}}
def spy():
    at.setdefault("paused", not gc.isenabled())
    at.setdefault("during", len(starts) - at["before"])
    done()
cli._start_up_done = spy
at["before"] = len(starts)
try:
    cli.app()
except SystemExit as exc:
    at["code"] = exc.code
print(at["paused"], at["during"], at.get("code"), gc.isenabled(), gc.get_freeze_count() > 0)
"""


@pytest.mark.slow
@pytest.mark.parametrize("args, code", [(["run", "scene.yaml", "-o", "o.nc", "--force"], 0),
                                        (["run", "missing.yaml"], 2), (["check", "scene.yaml"], 0)])
def test_start_up_runs_without_garbage_collection_then_resumes_it(tmp_path, args, code):
    """`wallbatch run` imports its modules and validates its config with the collector paused (no
    collection at all until the start-up is done), then freezes what start-up built and resumes
    collection; a failing command and the other commands resume it too."""
    (tmp_path / "scene.yaml").write_text(SCENE.replace("steps: 4000", "steps: 40"))
    res = subprocess.run([sys.executable, "-c", _GC_PROBE.format(args=args)], cwd=tmp_path, capture_output=True,
                         text=True, timeout=300)
    assert res.returncode == 0, res.stderr
    assert res.stdout.split()[-5:] == ["True", "0", str(code), "True", "True"]


@pytest.mark.slow
def test_only_the_wall_styles_a_config_uses_get_their_models_built(tmp_path):
    """Start-up builds the Pydantic model of a registered wall style when a config first uses it
    (`wallbatch run` of an lj93 slit builds lj93's only; the other non-registry wall models, the
    fixes' and the sweep's stay unbuilt too); the JSON schema still holds every style and builds
    them all."""
    (tmp_path / "scene.yaml").write_text(SCENE.replace("steps: 4000", "steps: 40"))
    probe = ("import sys; sys.argv = ['wallbatch', 'run', 'scene.yaml', '-o', 'o.nc', '--force']\n"
             "from wallbatch.cli import app\ntry:\n    app()\nexcept SystemExit:\n    pass\n"
             "from wallbatch.config import models as m\n"
             "print('made:' + ','.join(m.WALL_MODELS.made()))\n"
             "from wallbatch.config import sweep as sw\n"
             "from wallbatch.config.ensemble import FIX_MODELS\n"
             "print('built:' + ','.join([k for k, c in m.OTHER_WALLS.items() if c.__pydantic_complete__]\n"
             "                          + [c.__name__ for c in (sw.Sweep, sw.Param) if c.__pydantic_complete__]\n"
             "                          + [k for k, c in FIX_MODELS.items() if c.__pydantic_complete__]))\n"
             "from wallbatch.config.schema import json_schema\n"
             "tags = json_schema()['$defs']['Config']['properties']['walls']['additionalProperties']['anyOf'][0]\n"
             "print('schema:' + ','.join(sorted(tags['discriminator']['mapping'])))\n"
             "print('made:' + ','.join(sorted(m.WALL_MODELS.made())))\n")
    res = subprocess.run([sys.executable, "-c", probe], cwd=tmp_path, capture_output=True, text=True, timeout=300)
    assert res.returncode == 0, res.stderr
    lines = res.stdout.strip().splitlines()
    from wallbatch.config.models import OTHER_WALLS
    from wallbatch.styles import STYLES

    assert lines[-4:] == ["made:lj93", "built:", "schema:" + ",".join(sorted([*STYLES, *OTHER_WALLS])),
                          "made:" + ",".join(sorted(STYLES))]


MINIMIZE_SWEEP = """\
units: lj
seed: 3
box: {lo: [0, 0, 0], hi: [6, 6, 6], boundary: [p, p, f]}
atoms:
  - group: g
    create: {positions: [[1, 1, 1.5], [3, 3, 3.0], [4, 4, 4.4]]}
    mass: 1.0
walls:
  quiet: {style: lj93, units: box, zlo: {coord: EDGE, epsilon: 1.0, sigma: 1.0, cutoff: 2.5}}
minimize: {style: cg}
run: {steps: 10, thermo: 5}
sweep:
  product:
    eps: {path: walls.quiet.zlo.epsilon, values: [1.0, 2.0, 3.0]}
"""


@pytest.mark.slow
@pytest.mark.parametrize("jobs", ["1", "2"])
def test_a_wallbatch_warning_is_one_line_once_per_run(tmp_path, jobs):
    """minimize with a wall whose energy is left out warns (MinimizeWarning) for every case it
    builds; `wallbatch run` shows it as one line, `warning: ...`, once, without Python's file and
    source line, whatever the workers; no ResourceWarning of wallbatch's own files either."""
    (tmp_path / "m.yaml").write_text(MINIMIZE_SWEEP)
    res = subprocess.run([sys.executable, "-W", "always::ResourceWarning", "-m", "wallbatch.cli", "run", "m.yaml",
                          "-o", "m.nc", "-j", jobs], cwd=tmp_path, capture_output=True, text=True, timeout=300)
    assert res.returncode == 0, res.stderr
    lines = res.stderr.splitlines()
    assert lines == ["warning: minimize: wall(s) quiet have energy: false, so (as in LAMMPS without fix_modify energy "
                     "yes) their forces act during minimization but their energy is not in the minimized quantity; "
                     "set energy: true on them for a consistent minimization"], res.stderr


PACKED = """\
name: packed
units: lj
box: {lo: [0, 0, 0], hi: [5, 5, 5], boundary: [p, p, f]}
atoms:
  - group: g
    create: {random: {count: 20, overlap: 1.0}}
    mass: 1.0
walls:
  w: {style: harmonic, units: box, zlo: [EDGE, 1.0, 1.0, 1.5], zhi: [EDGE, 1.0, 1.0, 1.5]}
run: {steps: 10, thermo: 5}
sweep:
  product:
    n:
      path: atoms.0.create.random.count
      values: [20, 400]
    spec:
      path: atoms.0.create.random
      values: [{count: 20, overlap: 1.0}, {count: 300, overlap: 1.1}]
"""


def test_a_case_that_cannot_be_built_is_named_at_the_place_of_its_key(tmp_path):
    """A case whose atoms cannot be placed (only built, not validated, can tell) named the key and
    the case but not where the key was written: `check` and `run` now lead its message with the
    key's file:line:col, or the sweep entry's place when the sweep wrote the key's whole value,
    or the --set argument."""
    path = tmp_path / "packed.yaml"
    path.write_text(PACKED.replace("    spec:\n      path: atoms.0.create.random\n      values: [{count: 20, "
                                   "overlap: 1.0}, {count: 300, overlap: 1.1}]\n", ""))
    res = cli.invoke(app, ["check", str(path)])
    assert res.exit_code == 1
    assert (f"1 case(s) (n=400) cannot be built: {path}:6:22: atoms.0.create.random: placed only "
            in res.output)
    res = cli.invoke(app, ["run", str(path), "-o", str(tmp_path / "p.nc"), "-j", "1"])
    assert f"failed (1 case: n=400): {path}:6:22: atoms.0.create.random: placed only" in res.output
    swept = tmp_path / "swept.yaml"
    swept.write_text(PACKED.replace("    n:\n      path: atoms.0.create.random.count\n      values: [20, 400]\n", ""))
    res = cli.invoke(app, ["check", str(swept)])
    assert f"cannot be built: {swept}:15:15: atoms.0.create.random: placed only" in res.output
    single = tmp_path / "single.yaml"
    single.write_text(PACKED.split("sweep:")[0])
    res = cli.invoke(app, ["check", str(single), "--set", "atoms.0.create.random={count: 500, overlap: 1.0}"])
    assert ("the case cannot be built: --set atoms.0.create.random={count: 500, overlap: 1.0}: "
            "atoms.0.create.random: placed only" in res.output)


def test_a_build_error_is_placed_by_the_key_it_carries(tmp_path, monkeypatch):
    """`SweepPlan.placed` read the key out of the message text; a build error now carries its key
    (`CaseError.key`), which places the message also when its text does not start with the key.
    Without a key, a key leading the text is still used, and other text is left as it is."""
    from wallbatch.scene.case import CaseError

    single = tmp_path / "single.yaml"
    single.write_text(PACKED.split("sweep:")[0])
    plan = load_plan(single)

    def fail(cfg, seed_key):
        raise CaseError("too many atoms for the box", key="atoms.0.create.random")

    monkeypatch.setattr(runner, "build_case", fail)
    case, error, _ = runner.build_one(plan.cases[0], plan)
    assert case is None and error == f"{single}:6:22: too many atoms for the box"
    assert plan.placed("atoms.0.create.random: x") == f"{single}:6:22: atoms.0.create.random: x"
    assert plan.placed("the scene has no atoms: check atoms:") == "the scene has no atoms: check atoms:"


THERMOSTAT_DT_RESET = """\
units: lj
seed: 3
box: {lo: [0, 0, 0], hi: [8, 8, 10], boundary: [p, p, f]}
atoms:
  - group: gas
    create: {random: {count: 50, region: middle, overlap: 0.9}}
    mass: 1.0
    velocity: {temperature: 1.0}
regions:
  middle: {style: block, lo: [0, 0, 2], hi: [8, 8, 8], units: box}
variables:
  top: "10.0 - ramp(0.0, 1.0)"
walls:
  zwalls:
    style: lj93
    units: box
    zlo: {coord: EDGE, epsilon: 1.0, sigma: 1.0, cutoff: 2.5}
    zhi: {coord: TOP, epsilon: 1.0, sigma: 1.0, cutoff: 2.5}
fixes:
  t: "fix t all temp/berendsen 1.0 1.0 0.5"
dt_reset: {every: 1, tmin: 1.0e-6, tmax: 0.005, xmax: 0.02, units: box}
run: {steps: 40, thermo: 10}
"""


@pytest.mark.slow
@pytest.mark.parametrize("top, path", [
    ("EDGE", "engine: ran compiled (numba) for 1 case(s)"),
    # a wall moved by a variable with fix dt/reset: the compiled kernels hand every chunk back
    ("v_top", "engine: ran on the NumPy path for 1 case(s)"),
])
def test_verbose_run_reports_the_path_the_steps_took(tmp_path, monkeypatch, top, path):
    """`run -v` with WALLBATCH_NUMBA=1 on a thermostat + fix dt/reset scene (50 atoms, 40 steps):
    the line before the run says compiled where the scene allows, the line after it the path the
    steps took (it said 'compiled' though a scene the kernels do not take ran in NumPy)."""
    pytest.importorskip("numba")
    monkeypatch.setenv("WALLBATCH_NUMBA", "1")
    config = tmp_path / "s.yaml"
    config.write_text(THERMOSTAT_DT_RESET.replace("TOP", top))
    got = cli.invoke(app, ["run", str(config), "-o", str(tmp_path / "s.nc"), "-j", "1", "-v"])
    assert got.exit_code == 0, got.output
    lines = [line for line in got.output.splitlines() if line.startswith("engine:")]
    assert lines == ["engine: compiled (numba) where the scene allows (the NumPy path runs the rest), as "
                     "WALLBATCH_NUMBA=1 asks", path]


def test_ran_counts_cases_by_the_path_of_their_steps():
    from wallbatch.engine import backend

    assert backend.ran([]) == "engine: no step was run"
    assert backend.ran([(0, 0), (0, 40)]) == "engine: ran on the NumPy path for 1 case(s)"
    assert backend.ran([(40, 0), (30, 10), (39, 1), (0, 40)]) == (
        "engine: ran compiled (numba) for 1 case(s); partly compiled for 2 case(s) (11 of their 80 steps on the "
        "NumPy path); on the NumPy path for 1 case(s)")
