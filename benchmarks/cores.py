"""Where the time of a two-core run goes: the timeline of `wallbatch run` of the suite's 64-case
sweep with --jobs 1 and --jobs 2 (when each process reaches each phase), and one N = 1e6 case
with 1 and 2 threads (wall and CPU seconds of the engine run).

    python benchmarks/cores.py [--steps 10000] [--skip-jobs] [--skip-threads]

Each measurement is a new process. The machine is shared: compare within one run, and read the
CPU seconds (a process's user + system time) next to the wall seconds.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

import common
from suite import write_yaml

TRACE = r"""
import os, sys, time
T0 = float(os.environ["CORES_T0"])
def log(msg):
    sys.stderr.write(f"@@ {time.time() - T0:7.3f} {time.process_time():7.3f} {os.getpid()} {msg}\n")
log("python started")
import wallbatch.batch.runner as R
log("wallbatch imported")
def wrap(name):
    f = getattr(R, name)
    def g(*a, **k):
        log("start " + name)
        try:
            return f(*a, **k)
        finally:
            log("end " + name)
    g.__qualname__ = g.__name__ = name
    g.__module__ = R.__name__
    setattr(R, name, g)
for name in ("_warm_compiler", "_first_built", "execute", "_run_window", "write_results_file"):
    wrap(name)
from wallbatch.cli import app
sys.argv = ["wallbatch"] + sys.argv[1:]
try:
    app()
finally:
    log("exit")
"""

THREADS = r"""
import sys, time
sys.path.insert(0, {here!r})
import common
from wallbatch.engine.engine import Engine
from wallbatch.engine import threads
parts = []  # CPU seconds of each thread's part of each split call
split = threads._in_threads
def timed(calls):
    cpu = [0.0] * len(calls)
    def part(k, call):
        def run():
            t = time.thread_time()
            try:
                return call()
            finally:
                cpu[k] = time.thread_time() - t
        return run
    out = split([part(k, c) for k, c in enumerate(calls)])
    parts.append(cpu)
    return out
threads._in_threads = timed
common.time_wallbatch(common.build(common.gas_slit(20000, "lj93", steps=10, thermo=10)))
case = common.build(common.gas_slit({n}, "lj93", steps={steps}, thermo={steps}))
w0, c0 = time.perf_counter(), time.process_time()
parts.clear()
res = Engine([case]).run()[0]
cpu = time.process_time() - c0
path = cpu - sum(sum(p) - max(p) for p in parts)  # on idle cores: the busiest thread of each split call
print("RESULT", time.perf_counter() - w0, cpu, threads.splits["atoms"], path, float(res.data["ke"][-1]).hex())
"""


def sweep_config(steps: int) -> dict:
    """The suite's jobs2-64cases sweep: 8 x 8 epsilon, sigma of the lj93 gas slit, N = 1000."""
    cfg = common.gas_slit(1000, "lj93", steps=steps, thermo=max(1, steps // 10))
    cfg["sweep"] = {"product": {
        "eps": {"path": ["walls.w.zlo.epsilon", "walls.w.zhi.epsilon"], "values": {"linspace": [0.5, 2.0, 8]}},
        "sig": {"path": ["walls.w.zlo.sigma", "walls.w.zhi.sigma"], "values": {"linspace": [0.8, 1.2, 8]}}}}
    return cfg


def timeline(work: Path, jobs: int) -> tuple[float, float, list[str]]:
    """(wall s, CPU s of the process tree, the phase lines) of one traced `wallbatch run`."""
    env = dict(os.environ, WALLBATCH_THREADS="1", CORES_T0=repr(time.time()))
    t0 = time.perf_counter()
    before = os.times()
    proc = subprocess.run([sys.executable, "-c", TRACE, "run", "sweep.yaml", "-o", "sweep.nc", "--force",
                           "-j", str(jobs)], cwd=work, env=env, capture_output=True, text=True, check=True)
    wall = time.perf_counter() - t0
    after = os.times()
    cpu = (after.children_user - before.children_user) + (after.children_system - before.children_system)
    lines = [ln[3:] for ln in proc.stderr.splitlines() if ln.startswith("@@ ")]
    return wall, cpu, lines


def summarise(lines: list[str]) -> tuple[str, float]:
    """Per process: its phases (first start .. last end of each, wall seconds from the launch), in
    order of appearance; and the critical path in CPU seconds, what the run would take on idle
    cores: the parent's CPU up to its first worker's start (all of it without workers), plus
    the busiest worker's CPU, plus the parent's CPU after the last worker's end."""
    procs: dict[str, dict[str, list[float]]] = {}
    cpu: dict[str, list[tuple[float, float]]] = {}
    for ln in lines:
        t, c, pid, what = ln.split(maxsplit=3)
        procs.setdefault(pid, {}).setdefault(what.split()[-1], []).append(float(t))
        cpu.setdefault(pid, []).append((float(t), float(c)))
    pids = list(procs)
    parent = cpu[pids[0]]
    if len(pids) == 1:
        path = parent[-1][1]
    else:
        start = min(t for p in pids[1:] for t, _ in cpu[p])
        end = max(t for p in pids[1:] for t, _ in cpu[p])
        before = max((c for t, c in parent if t <= start), default=0.0)
        after = parent[-1][1] - max((c for t, c in parent if t <= end), default=0.0)
        path = before + max(cpu[p][-1][1] for p in pids[1:]) + after
    out = []
    for k, (pid, ph) in enumerate(procs.items()):
        who = "parent" if k == 0 else f"worker {k}"
        parts = [f"{name} {min(ts):.2f}" + (f"-{max(ts):.2f}" if len(ts) > 1 else "") + (
            f" (x{len(ts) // 2})" if len(ts) > 2 else "") for name, ts in ph.items()]
        out.append(f"  {who}: " + "; ".join(parts) + f" [{cpu[pid][-1][1]:.2f} s CPU]")
    return "\n".join(out), path


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=10000)
    ap.add_argument("--skip-jobs", action="store_true")
    ap.add_argument("--skip-threads", action="store_true")
    args = ap.parse_args()
    if not args.skip_jobs:
        with tempfile.TemporaryDirectory(prefix="wb_cores_") as tmp:
            work = Path(tmp)
            write_yaml(work / "sweep.yaml", sweep_config(args.steps))
            timeline(work, 1)  # kernels compiled and cached, files warm: not reported
            best: dict[int, tuple[float, float, list[str]]] = {}
            for _ in range(2):  # interleaved, best of two each
                for j in (1, 2):
                    got = timeline(work, j)
                    if j not in best or got[0] < best[j][0]:
                        best[j] = got
            path = {}
            for j in (1, 2):
                wall, cpu, lines = best[j]
                text, path[j] = summarise(lines)
                print(f"--jobs {j}: {wall:.2f} s wall, {cpu:.2f} s CPU (all processes), critical path "
                      f"{path[j]:.2f} s CPU")
                print(text)
            print(f"--jobs 2 / --jobs 1: {best[1][0] / best[2][0]:.2f}x wall, {path[1] / path[2]:.2f}x on the "
                  f"critical path in CPU seconds (idle cores)")
    if not args.skip_threads:
        got = {}
        for k in (1, 2, 1, 2):
            env = dict(os.environ, WALLBATCH_THREADS=str(k))
            text = subprocess.run([sys.executable, "-c", THREADS.format(here=str(HERE), n=1_000_000, steps=100)],
                                  env=env, capture_output=True, text=True, check=True).stdout
            r = next(ln.split()[1:] for ln in text.splitlines() if ln.startswith("RESULT"))
            if k not in got or float(r[0]) < float(got[k][0]):
                got[k] = r
        for k in (1, 2):
            print(f"N = 1e6, 100 steps, {k} thread(s): {float(got[k][0]):.3f} s wall, {float(got[k][1]):.3f} s CPU, "
                  f"critical path {float(got[k][3]):.3f} s CPU, atom splits {got[k][2]}, final ke {got[k][4]}")
        print(f"2 threads / 1: {float(got[1][0]) / float(got[2][0]):.2f}x wall, "
              f"{float(got[1][3]) / float(got[2][3]):.2f}x on the critical path in CPU seconds (idle cores); final ke "
              f"{'bit-identical' if got[1][4] == got[2][4] else 'DIFFERS'}")


if __name__ == "__main__":
    main()
