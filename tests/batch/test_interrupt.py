"""Fault injection on `wallbatch run --jobs 2` in a subprocess: Ctrl-C (SIGINT to the process
group, as a terminal sends it), SIGTERM to the parent alone and SIGKILL of the parent. Finished
cases stay in OUT.nc.parts, the message and exit code are the documented ones, no worker process
outlives the run, a rerun without --resume refuses and --resume reuses the saved cases."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest

from wallbatch.batch.runner import PART_SUFFIX, case_key, parts_dir
from wallbatch.config.sweep import load_plan

from factories import slit_yaml

pytestmark = pytest.mark.slow

SCENE = slit_yaml('inttest', 40, 1500000, 150000)
# 12 atom counts = 12 structures = 12 tasks of one case each (~1 s per case on one core)
SWEEP = """\
base: scene.yaml
sweep:
  product:
    n: {path: atoms.0.create.random.count, values: {range: [40, 52, 1]}}
"""
TOTAL = 12
# `wallbatch run` with windows of 2 cases: by default this 540-atom sweep makes 2 windows of 6
# cases (a window holds at least runner.MIN_WINDOW_ATOMS atoms), one per worker; both finish at
# about the same moment and save their 6 parts together, so a signal sent after the first parts
# would land after the last. 8 windows of 2 finish in 4 rounds, and an interrupt lands between them.
_ENTRY = ("import sys; import wallbatch.batch.runner as r; r.MIN_WINDOW_ATOMS = 1; "
          "from wallbatch.cli import app; sys.argv[0] = 'wallbatch'; app()")


def _children(pid: int) -> set[int]:
    """PIDs whose parent is `pid` (from /proc)."""
    out = set()
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            stat = (entry / "stat").read_text()
        except OSError:
            continue
        fields = stat[stat.rfind(")") + 2:].split()
        if int(fields[1]) == pid:
            out.add(int(entry.name))
    return out


def _alive(pids: set[int]) -> set[int]:
    alive = set()
    for pid in pids:
        try:
            state = Path(f"/proc/{pid}/stat").read_text()
        except OSError:
            continue
        if state[state.rfind(")") + 2] != "Z":  # a zombie is dead (waiting for its reaper)
            alive.add(pid)
    return alive


def _finished(parts: Path) -> set[str]:
    return {p.stem for p in parts.glob(f"*{PART_SUFFIX}") if not p.name.startswith(".")} if parts.is_dir() else set()


@pytest.fixture
def sweep(tmp_path: Path) -> Path:
    (tmp_path / "scene.yaml").write_text(SCENE)
    path = tmp_path / "sweep.yaml"
    path.write_text(textwrap.dedent(SWEEP))
    return path


def _start(sweep: Path, out: Path, *extra: str) -> tuple[subprocess.Popen, Path]:
    log = sweep.parent / "run.log"
    cmd = [sys.executable, "-c", _ENTRY, "run", str(sweep), "-o", str(out), "--jobs", "2", *extra]
    # its own process group, as a shell job is; Ctrl-C as in a terminal: a test run started in the
    # background (`cmd &` without job control, nohup) ignores SIGINT, which its children inherit
    proc = subprocess.Popen(cmd, cwd=sweep.parent, stdout=log.open("w"), stderr=subprocess.STDOUT,
                            start_new_session=True,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    return proc, log


def _wait_for_parts_and_workers(proc: subprocess.Popen, parts: Path, log: Path, n: int = 1) -> set[int]:
    """Wait until `n` cases are saved; return the worker PIDs seen meanwhile. The first run on a
    fresh clone compiles the kernels in both workers at once (a minute or more on a loaded
    2-core machine), hence the long wait."""
    workers: set[int] = set()
    t_end = time.monotonic() + 600
    while time.monotonic() < t_end:
        workers |= _children(proc.pid)
        if proc.poll() is not None:
            pytest.fail(f"the run ended before it could be interrupted:\n{log.read_text()}")
        if len(_finished(parts)) >= n:
            return workers | _children(proc.pid)
        time.sleep(0.02)
    pytest.fail(f"no part within 600 s:\n{log.read_text()}")


def _interrupt(sweep: Path, sig: int, to_group: bool) -> tuple[subprocess.Popen, str, set[int], float, Path]:
    out = sweep.parent / "out.nc"
    proc, log = _start(sweep, out)
    try:
        workers = _wait_for_parts_and_workers(proc, parts_dir(out), log, n=2)
        assert len(workers) >= 2  # --jobs 2: two worker processes (plus a resource tracker at most)
        t0 = time.monotonic()
        if to_group:
            os.killpg(proc.pid, sig)
        else:
            os.kill(proc.pid, sig)
        proc.wait(timeout=30)
        elapsed = time.monotonic() - t0
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
    deadline = time.monotonic() + 10
    while _alive(workers) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert not _alive(workers), f"workers left running: {_alive(workers)}"
    return proc, log.read_text(), workers, elapsed, out


@pytest.mark.parametrize("sig,to_group", [(signal.SIGINT, True), (signal.SIGTERM, False)],
                         ids=["ctrl-c-to-group", "sigterm-to-parent"])
def test_interrupt_keeps_parts_stops_workers_exits_130(sweep, sig, to_group):
    proc, text, _, elapsed, out = _interrupt(sweep, sig, to_group)
    parts = parts_dir(out)
    saved = _finished(parts)
    keys = {case_key(c) for c in load_plan(sweep).cases}
    assert proc.returncode == 130, text
    assert elapsed < 8.0, f"took {elapsed:.1f} s to stop"
    assert 2 <= len(saved) < TOTAL and saved <= keys
    assert f"interrupted: {len(saved)}/{TOTAL} cases saved in {parts}; rerun with --resume" in text
    assert "Traceback" not in text
    assert not out.exists()
    assert not out.with_name("out.nc.lock").exists()  # the lock is released

    # a rerun without --resume refuses and deletes nothing
    again = subprocess.run([sys.executable, "-m", "wallbatch.cli", "run", str(sweep), "-o", str(out), "-j", "2"],
                           cwd=sweep.parent, capture_output=True, text=True, timeout=120)
    assert again.returncode == 2
    assert f"{parts} holds {len(saved)} finished case(s) of an earlier run: add --resume to reuse them, " \
           f"or --fresh to discard them" in again.stderr
    assert _finished(parts) == saved

    # --resume says how many cases it reuses and computes the rest
    resumed = subprocess.run([sys.executable, "-m", "wallbatch.cli", "run", str(sweep), "-o", str(out), "-j", "2",
                              "--resume"], cwd=sweep.parent, capture_output=True, text=True, timeout=300)
    assert resumed.returncode == 0, resumed.stderr
    assert f"resuming: {len(saved)} of {TOTAL} case(s) reused from {parts}" in resumed.stderr
    assert f"{TOTAL} of {TOTAL} case(s) ok" in resumed.stdout
    assert out.exists() and not parts.exists()


def test_sigkill_of_the_parent_leaves_no_worker(sweep):
    proc, _, workers, _, out = _interrupt(sweep, signal.SIGKILL, False)
    assert proc.returncode == -signal.SIGKILL
    assert len(_finished(parts_dir(out))) >= 2  # finished parts survive a kill -9 too


def test_a_killed_worker_is_one_message_and_the_parts_stay(sweep):
    out = sweep.parent / "out.nc"
    proc, log = _start(sweep, out)
    try:
        workers = _wait_for_parts_and_workers(proc, parts_dir(out), log, n=1)
        victim = max(workers)  # a worker (the resource tracker, if any, started first)
        os.kill(victim, signal.SIGKILL)
        proc.wait(timeout=60)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
    text = log.read_text()
    saved = _finished(parts_dir(out))
    assert proc.returncode == 2, text
    assert (f"error: a worker process died (killed, or out of memory?): the {len(saved)} finished case(s) are "
            f"kept in {parts_dir(out)}; rerun with --resume") in text
    assert "Traceback" not in text and len(saved) >= 1
    time.sleep(1.0)
    assert not _alive(workers)
