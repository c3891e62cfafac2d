"""Resuming an interrupted sweep (`wallbatch run ... --resume`, runner.run_plan(resume=True)):
finished cases persisted under OUT.parts/ are reused, never recomputed; the final file equals an
uninterrupted run's; a changed config invalidates exactly the changed cases."""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pytest
import xarray as xr
from typer.testing import CliRunner

from wallbatch.cli import app
from wallbatch.batch.runner import (PART_SUFFIX, RunError, build_cases, case_key, load_part, make_tasks, parts_dir,
                                    run_plan, save_part)
from wallbatch.config.sweep import load_plan

from factories import slit_yaml

cli = CliRunner()

SCENE = slit_yaml('resumetest', 40, 100, 20)


def write_sweep(tmp_path: Path, body: str, name: str = "sweep.yaml") -> Path:
    (tmp_path / "scene.yaml").write_text(SCENE)
    path = tmp_path / name
    path.write_text("base: scene.yaml\n" + textwrap.dedent(body))
    return path


def finished_parts(parts: Path) -> set[str]:
    """Keys of the complete parts (a `.KEY.tmp.part` being written does not count)."""
    if not parts.exists():
        return set()
    return {p.stem for p in parts.glob(f"*{PART_SUFFIX}") if not p.name.startswith(".")}


def same(a, b) -> bool:
    a, b = np.asarray(a), np.asarray(b)
    if a.dtype.kind == "f" and b.dtype.kind == "f":
        return a.shape == b.shape and np.array_equal(a, b, equal_nan=True)
    return a.shape == b.shape and np.array_equal(a, b)


def assert_same_results(ds: xr.Dataset, ref: xr.Dataset) -> None:
    """Equal in every data variable but `seconds`, every coordinate, every attribute but `created`."""
    assert set(ds.data_vars) == set(ref.data_vars)
    for name in ds.data_vars:
        assert ds[name].dims == ref[name].dims, name
        assert ds[name].attrs == ref[name].attrs, name
        if name != "seconds":
            assert same(ds[name].values, ref[name].values), name
    assert set(ds.coords) == set(ref.coords)
    for name in ds.coords:
        assert same(ds[name].values, ref[name].values), name
        assert ds[name].attrs == ref[name].attrs, name
    strip = lambda attrs: {k: v for k, v in attrs.items() if k != "created"}  # noqa: E731
    assert strip(ds.attrs) == strip(ref.attrs)


def open_nc(path: Path) -> xr.Dataset:
    with xr.open_dataset(path) as ds:
        return ds.load()


# ============================================================================================
# kill -9 in the middle of a run, then --resume


KILL_SWEEP = """\
set: {{run.steps: {steps}, run.thermo: {thermo}}}
sweep:
  product:
    n: {{path: atoms.0.create.random.count, values: {{range: [40, 48, 1]}}}}
  replicas: 2
"""


def _start_and_kill(tmp_path: Path, sweep: Path, out: Path, deadline_s: float = 60.0):
    """Run the CLI in a subprocess, SIGKILL it once OUT.parts/ holds a finished part.
    Returns the part keys found after the kill, or None if the run finished first."""
    parts = parts_dir(out)
    cmd = [sys.executable, "-m", "wallbatch.cli", "run", str(sweep), "-o", str(out), "-j", "1"]
    log = (tmp_path / "run.log").open("w")
    proc = subprocess.Popen(cmd, cwd=tmp_path, stdout=log, stderr=subprocess.STDOUT)
    try:
        t_end = time.monotonic() + deadline_s
        while time.monotonic() < t_end:
            if proc.poll() is not None:
                return None  # finished (or died) before a part was seen: caller makes it bigger
            if finished_parts(parts):
                os.kill(proc.pid, signal.SIGKILL)
                proc.wait(timeout=30)
                if proc.returncode != -signal.SIGKILL:
                    return None  # it finished between the look and the kill
                return finished_parts(parts)
            time.sleep(0.005)
        pytest.fail(f"no part appeared in {parts} within {deadline_s} s: {(tmp_path / 'run.log').read_text()}")
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait(timeout=30)
        log.close()


def test_one_process_saves_each_batch_before_the_next_runs(tmp_path, monkeypatch):
    """With -j 1 a window of cases of several structures runs as several batches; each batch's
    parts are on disk before the next batch starts, so a kill in the middle of a window loses no
    finished batch (before: the window's parts were all written at its end)."""
    from wallbatch.batch import runner  # noqa: PLC0415

    out = tmp_path / "out.nc"
    plan = load_plan(write_sweep(tmp_path, KILL_SWEEP.format(steps=40, thermo=20)))
    seen: list[int] = []  # parts on disk as each batch starts
    real = runner._run_task

    def task(cases):  # noqa: ANN001, ANN202
        seen.append(len(finished_parts(parts_dir(out))))
        return real(cases)

    monkeypatch.setattr(runner, "_run_task", task)
    assert len(runner.make_windows(plan, list(range(16)), 1)) == 1  # one window ...
    run_plan(plan, out, jobs=1, progress=False)
    assert seen == [0, 2, 4, 6, 8, 10, 12, 14]  # ... of 8 batches of 2 replicas, each saved in turn
    assert out.exists() and not parts_dir(out).exists()


@pytest.mark.slow  # runs, kills and resumes `wallbatch run` in child processes: 1-8 s with the machine loaded
def test_kill_then_resume_recomputes_only_the_missing_cases(tmp_path):
    out = tmp_path / "out.nc"
    parts = parts_dir(out)
    steps = 3000
    seen = []
    for _attempt in range(6):  # (a fast host runs 16 small cases of 9,000 steps in ~30 ms after its start)
        sweep = write_sweep(tmp_path, KILL_SWEEP.format(steps=steps, thermo=steps // 10))
        found = _start_and_kill(tmp_path, sweep, out)
        seen.append((steps, None if found is None else len(found)))
        if found is not None and len(found) < 16 and not out.exists():  # (every part saved: killed too late)
            break
        for leftover in (out, parts):  # too fast to catch: make the scene bigger and retry
            if leftover.is_dir():
                shutil.rmtree(leftover)
            elif leftover.exists():
                leftover.unlink()
        steps *= 3
    else:
        pytest.fail(f"the run always finished before it could be killed: (steps, parts seen) {seen}")

    plan = load_plan(sweep)
    total = len(plan.cases)
    assert total == 16
    # precondition: with -j 1 the cases run as several batches, so parts appear before the end
    built, _ = build_cases(plan)
    assert len(make_tasks(dict(enumerate(built)), jobs=1)) == 8
    keys = [case_key(c) for c in plan.cases]
    assert found <= set(keys)  # the parts are cases of this plan
    assert 0 < len(found) < total
    print(f"killed after {len(found)} of {total} cases (run.steps = {steps})")
    assert not out.exists()  # killed: no results file yet
    saved_seconds = {k: load_part(parts, k).seconds for k in found}

    computed: list[int] = []
    ds = run_plan(plan, out, jobs=1, resume=True, progress=False, on_result=lambda i, r: computed.append(i))
    assert len(computed) == total - len(found)
    assert sorted(computed) == [i for i, k in enumerate(keys) if k not in found]
    assert not parts.exists()  # removed after success
    assert (ds["status"] == "ok").all()

    resumed = open_nc(out)
    run_plan(plan, tmp_path / "ref.nc", jobs=1, progress=False)  # uninterrupted
    ref = open_nc(tmp_path / "ref.nc")
    assert_same_results(resumed, ref)
    # the reused cases keep the seconds measured by the killed run
    secs = resumed["seconds"].values.ravel()
    for i, k in enumerate(keys):
        if k in found:
            assert secs[i] == saved_seconds[k]


# ============================================================================================
# a changed config invalidates exactly the changed cases


BASE_SWEEP = """\
set: {{walls.zwalls.zhi.sigma: {sigma}}}
sweep:
  product:
    epsilon: {{path: [walls.zwalls.zlo.epsilon, walls.zwalls.zhi.epsilon], values: {eps}}}
  replicas: {reps}
"""


def make_sweep(tmp_path: Path, eps="[0.5, 1.0, 2.0]", reps=2, sigma=1.0, name="sweep.yaml") -> Path:
    return write_sweep(tmp_path, BASE_SWEEP.format(eps=eps, reps=reps, sigma=sigma), name)


@pytest.fixture
def first_run(tmp_path):
    """A completed run of 3 epsilons x 2 replicas with a copy of its parts (taken from
    `on_result`, before run_plan removes them): (out, saved parts folder, dataset)."""
    out = tmp_path / "out.nc"
    parts = parts_dir(out)
    saved = tmp_path / "saved.parts"

    def keep(i, res):
        shutil.copytree(parts, saved, dirs_exist_ok=True)

    ds = run_plan(load_plan(make_sweep(tmp_path)), out, jobs=1, progress=False, on_result=keep)
    assert not parts.exists()
    assert len(finished_parts(saved)) == 6
    return out, saved, ds


def restore(saved: Path, out: Path) -> None:
    parts = parts_dir(out)
    if parts.exists():
        shutil.rmtree(parts)
    shutil.copytree(saved, parts)


def resume_counting(plan, out: Path) -> tuple[list[int], xr.Dataset]:
    computed: list[int] = []
    ds = run_plan(plan, out, jobs=1, resume=True, progress=False, on_result=lambda i, r: computed.append(i))
    assert not parts_dir(out).exists()
    return sorted(computed), ds


def test_changed_swept_value_recomputes_only_its_cases(tmp_path, first_run):
    out, saved, ds_a = first_run
    restore(saved, out)
    plan_b = load_plan(make_sweep(tmp_path, eps="[0.5, 1.0, 3.0]"))
    computed, ds = resume_counting(plan_b, out)
    assert computed == [i for i, c in enumerate(plan_b.cases) if c.coords["epsilon"] == 3.0] == [4, 5]
    fresh = run_plan(plan_b, progress=False)
    assert_same_results(open_nc(out), fresh)
    # reused cases are those of the first run, seconds included
    assert same(ds["seconds"].sel(epsilon=[0.5, 1.0]).values, ds_a["seconds"].sel(epsilon=[0.5, 1.0]).values)


def test_more_replicas_recompute_only_the_new_replica(tmp_path, first_run):
    out, saved, _ = first_run
    restore(saved, out)
    plan = load_plan(make_sweep(tmp_path, reps=3))
    computed, _ = resume_counting(plan, out)
    assert computed == [i for i, c in enumerate(plan.cases) if c.coords["replica"] == 2] == [2, 5, 8]
    assert_same_results(open_nc(out), run_plan(plan, progress=False))


def test_changed_base_value_recomputes_every_case(tmp_path, first_run):
    out, saved, _ = first_run
    restore(saved, out)
    computed, _ = resume_counting(load_plan(make_sweep(tmp_path, sigma=1.1)), out)
    assert computed == list(range(6))
    # the same through a --set override
    restore(saved, out)
    computed, _ = resume_counting(load_plan(make_sweep(tmp_path), ["walls.zwalls.zlo.sigma=1.2"]), out)
    assert computed == list(range(6))


def test_unchanged_validated_config_reuses_every_case(tmp_path, first_run):
    """The case identity is the validated config: an override that restates the scene's own value,
    or a sweep file rewritten in another form, changes nothing."""
    out, saved, ds_a = first_run
    restore(saved, out)
    computed, ds = resume_counting(load_plan(make_sweep(tmp_path), ["walls.zwalls.zlo.sigma=1.0"]), out)
    assert computed == []
    assert same(ds["seconds"].values, ds_a["seconds"].values)
    restore(saved, out)
    rewritten = write_sweep(tmp_path, """\
        set: {walls.zwalls.zhi.sigma: 1}
        sweep:
          product:
            epsilon:
              path: [walls.zwalls.zlo.epsilon, walls.zwalls.zhi.epsilon]
              values: {linspace: [0.5, 1.0, 2]}
          replicas: 2
        """, "rewritten.yaml")
    plan = load_plan(rewritten)
    computed, _ = resume_counting(plan, out)
    assert computed == []  # epsilon 0.5 and 1.0 were kept, 2.0 is simply not in this grid


def test_damaged_part_is_recomputed(tmp_path, first_run):
    out, saved, ds_a = first_run
    restore(saved, out)
    plan = load_plan(make_sweep(tmp_path))
    victim = case_key(plan.cases[3])
    (parts_dir(out) / f"{victim}{PART_SUFFIX}").write_bytes(b"not a part file")
    (parts_dir(out) / f".{case_key(plan.cases[0])}.tmp{PART_SUFFIX}").write_bytes(b"half written")
    computed, ds = resume_counting(plan, out)
    assert computed == [3]
    assert_same_results(open_nc(out), ds_a)


def test_without_resume_leftover_parts_refuse_and_fresh_discards_them(tmp_path, first_run):
    out, saved, ds_a = first_run
    restore(saved, out)
    with pytest.raises(RunError, match=r"out\.nc\.parts holds 6 finished case\(s\) of an earlier run: add --resume "
                                       r"to reuse them, or --fresh to discard them"):
        run_plan(load_plan(make_sweep(tmp_path)), out, jobs=1, progress=False)
    assert len(finished_parts(parts_dir(out))) == 6  # nothing deleted
    computed: list[int] = []
    run_plan(load_plan(make_sweep(tmp_path)), out, jobs=1, progress=False, fresh=True,
             on_result=lambda i, r: computed.append(i))
    assert sorted(computed) == list(range(6))
    assert not parts_dir(out).exists()
    assert_same_results(open_nc(out), ds_a)


def test_parts_from_save_part_are_reused(tmp_path):
    """Parts written by runner.save_part for some cases: a resume computes the rest only."""
    path = make_sweep(tmp_path)
    plan = load_plan(path)
    ref = run_plan(plan, progress=False)
    # hand-made parts for cases 0 and 5, from a run of those cases alone
    from wallbatch.batch.runner import _run_task

    built, _ = build_cases(plan)
    out = tmp_path / "out.nc"
    for i, res in zip((0, 5), _run_task([built[0], built[5]])):
        save_part(parts_dir(out), case_key(plan.cases[i]), res)
    computed, _ = resume_counting(plan, out)
    assert computed == [1, 2, 3, 4]
    assert_same_results(open_nc(out), ref)


def test_cli_resume_reuses_parts(tmp_path, first_run):
    out, saved, ds_a = first_run
    restore(saved, out)
    path = make_sweep(tmp_path, eps="[0.5, 1.0, 3.0]")
    res = cli.invoke(app, ["run", str(path), "-o", str(out), "-j", "1", "--resume"])
    assert res.exit_code == 0, res.output
    assert "6 of 6 case(s) ok" in res.output
    assert f"resuming: 4 of 6 case(s) reused from {parts_dir(out)}" in res.output
    assert not parts_dir(out).exists()
    ds = open_nc(out)
    # epsilon 0.5 and 1.0 come from the parts (their seconds are the first run's), 3.0 is new
    assert same(ds["seconds"].sel(epsilon=[0.5, 1.0]).values, ds_a["seconds"].sel(epsilon=[0.5, 1.0]).values)
    assert_same_results(ds, run_plan(load_plan(path), progress=False))


def test_parts_of_an_earlier_format_refuse_too_and_resume_recomputes_them(tmp_path):
    """The .npz parts that wallbatch versions before PART_FORMAT 3 wrote count as an earlier run's:
    without --resume the run refuses and deletes nothing; --resume reports and recomputes them."""
    out = tmp_path / "out.nc"
    plan = load_plan(make_sweep(tmp_path))
    old = parts_dir(out) / f"{case_key(plan.cases[0])}.npz"
    parts_dir(out).mkdir()
    old.write_bytes(b"PK\x03\x04 an old part")
    with pytest.raises(RunError, match=r"out\.nc\.parts holds 1 finished case\(s\) of an earlier run"):
        run_plan(plan, out, jobs=1, progress=False)
    assert old.exists()
    notes: list[str] = []
    computed: list[int] = []
    run_plan(plan, out, jobs=1, progress=False, resume=True, log=notes.append,
             on_result=lambda i, r: computed.append(i))
    assert sorted(computed) == list(range(len(plan.cases)))
    assert f"resuming: 0 of {len(plan.cases)} case(s) reused from {parts_dir(out)}; 1 part(s) written by an older " \
           "wallbatch: recomputed" in notes
    assert out.exists() and not parts_dir(out).exists()


def test_edited_atoms_file_recomputes_its_cases(tmp_path):
    """A case's identity includes the content of the files it reads: an atoms file edited between
    an interrupt and --resume makes every case that reads it run again (the parts of the old file
    were reused, mixing two different inputs in one results file)."""
    rng = np.random.default_rng(5)
    x = np.column_stack([rng.uniform(0, 6, 30), rng.uniform(0, 6, 30), rng.uniform(2, 7, 30)])
    np.savez(tmp_path / "atoms.npz", x=x, v=np.zeros_like(x))
    scene = SCENE.replace("create: {random: {count: 40, overlap: 0.8, region: slab}}",
                          "create: {file: atoms.npz}").replace("    velocity: {temperature: 1.0}\n", "")
    assert "atoms.npz" in scene and "velocity" not in scene
    (tmp_path / "scene.yaml").write_text(scene)
    sweep = tmp_path / "sweep.yaml"
    sweep.write_text("base: scene.yaml\nsweep:\n  product:\n    eps: {path: walls.zwalls.zlo.epsilon, "
                     "values: [0.5, 1.0]}\n")
    out, saved = tmp_path / "out.nc", tmp_path / "saved.parts"
    run_plan(load_plan(sweep), out, jobs=1, progress=False,
             on_result=lambda i, r: shutil.copytree(parts_dir(out), saved, dirs_exist_ok=True))
    restore(saved, out)  # as if interrupted after both cases were saved
    np.savez(tmp_path / "atoms.npz", x=x, v=np.full_like(x, 0.5))  # the atoms file is edited
    plan = load_plan(sweep)
    computed, ds = resume_counting(plan, out)
    assert computed == [0, 1]
    fresh = run_plan(plan, progress=False)
    assert_same_results(open_nc(out), fresh)
    assert float(fresh["ke"].isel(eps=0, sample=0)) == pytest.approx(30 * 0.5 * 3 * 0.25)
    # unchanged files: every part is reused
    restore(saved, out)
    np.savez(tmp_path / "atoms.npz", x=x, v=np.zeros_like(x))
    assert resume_counting(load_plan(sweep), out)[0] == []
