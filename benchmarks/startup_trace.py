"""Helper `startup3` (issue 15): where the serial time of one `wallbatch run` goes, as a timeline
of events in the parent and in each worker (seconds since the driver launched the process):
process start (/proc/self/stat), interpreter up, imports done, config parsed, numba set up,
kernels loaded (warm-up before forking), fork (each worker's initializer), each worker's first
and last window, the results file written (merge of the parts), and process exit.

    PYTHONPATH=$PWD/src python benchmarks/startup_trace.py [--jobs 1 2] [--steps 10000] [--small]

Default scene: benchmarks/jobs_scaling.py's 64-case sweep (suite.py's jobs2 row); --small:
end-to-end-small (one case, N = 1000, 2000 steps). WALLBATCH_THREADS=1. One warm run first. The
instrumented run wraps runner functions (like jobs_scaling.py's CPU notes): a few microseconds
per event. Each event also shows the process's CPU seconds and minor page faults so far (a
forked worker's count starts at 0: copy-on-write faults show there). Take timings under the
machine's timing lock.
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

import common  # noqa: E402
import jobs_scaling  # noqa: E402

TRACE = r"""
import os, sys, time
T0 = float(os.environ["WB_T0"])
FOLDER = os.environ["WB_TRACE_DIR"]
def note(what):
    t = time.monotonic() - T0
    with open("/proc/self/stat") as fh:
        minflt = int(fh.read().rsplit(")", 1)[1].split()[7])
    with open(os.path.join(FOLDER, str(os.getpid())), "a") as fh:
        fh.write(f"{t:.4f} {time.process_time():.4f} {minflt} {what}\n")
with open("/proc/self/stat") as fh:
    start_ticks = int(fh.read().rsplit(")", 1)[1].split()[19])
boot = time.clock_gettime(time.CLOCK_BOOTTIME)
note(f"process start (/proc: {start_ticks / os.sysconf('SC_CLK_TCK') - boot + time.monotonic() - T0:.3f})")
note("interpreter up")
import wallbatch.cli as cli
from wallbatch.batch import runner
note("imports done (cli, runner)")
parent = os.getpid()
if os.environ.get("WB_WINDOWS_PER_JOB"):  # to try other window sizes
    runner.WINDOWS_PER_JOB = int(os.environ["WB_WINDOWS_PER_JOB"])
def wrap(mod, name, before=None, after=None, only_parent=False):
    real = getattr(mod, name)
    def wrapped(*a, **k):
        if before and not (only_parent and os.getpid() != parent):
            note(before)
        out = real(*a, **k)
        if after and not (only_parent and os.getpid() != parent):
            note(after)
        return out
    wrapped.__qualname__, wrapped.__module__ = real.__qualname__, real.__module__  # pickled by name
    setattr(mod, name, wrapped)
wrap(cli, "_plan", None, "config parsed")
wrap(runner, "_set_up_numba", "numba set-up starts", "numba set up")
wrap(runner, "_warm_compiler", "warm-up starts", "warm-up done (kernels loaded)")
wrap(runner, "_worker_init", "worker forked (initializer)")
wrap(runner, "_run_window", "window starts", "window ends")
wrap(runner, "write_results_file", "results file: merge starts", "results file written")
import atexit
atexit.register(note, "atexit")
sys.argv = ["wallbatch"] + sys.argv[1:]
cli.app()
"""


def trace(src: Path, work: Path, args: list[str]) -> tuple[list[tuple[float, int, str]], float]:
    """Events (seconds, pid, what) of one instrumented run, and the driver's wall time to its exit."""
    with tempfile.TemporaryDirectory(prefix="wb_trace_") as folder:
        env = dict(os.environ, WALLBATCH_THREADS="1", PYTHONPATH=str(src), WB_TRACE_DIR=folder)
        env.pop("PYTHONDONTWRITEBYTECODE", None)
        env["WB_T0"] = repr(time.monotonic())
        t0 = float(env["WB_T0"])
        proc = subprocess.run([sys.executable, "-c", TRACE, *args], cwd=work, env=env, capture_output=True, text=True)
        end = time.monotonic() - t0
        if proc.returncode != 0:
            raise SystemExit(proc.stdout + proc.stderr)
        events = []
        for p in Path(folder).iterdir():
            for line in p.read_text().splitlines():
                t, cpu, faults, what = line.split(" ", 3)
                events.append((float(t), int(p.name), f"{float(cpu):7.3f} {int(faults):7d}  {what}"))
    return sorted(events), end


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--jobs", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--steps", type=int, default=10000)
    ap.add_argument("--small", action="store_true")
    ap.add_argument("--src", type=Path, default=HERE.parent / "src")
    args = ap.parse_args()
    import yaml  # noqa: PLC0415

    cfg = common.gas_slit(1000, "lj93", steps=2000, thermo=100) if args.small else jobs_scaling.sweep_config(args.steps)
    print(f"# load average {os.getloadavg()[0]:.2f}; {'end-to-end-small' if args.small else '64-case sweep'}; "
          f"src {args.src.resolve()}")
    with tempfile.TemporaryDirectory(prefix="wb_trace_work_") as tmp:
        work = Path(tmp)
        (work / "c.yaml").write_text(yaml.safe_dump(cfg, sort_keys=False))
        trace(args.src.resolve(), work, ["run", "c.yaml", "-o", "warm.nc", "--force", "-j", "1"])
        for jobs in args.jobs:
            events, end = trace(args.src.resolve(), work, ["run", "c.yaml", "-o", "out.nc", "--force", "-j", str(jobs)])
            parent = events[0][1]
            print(f"\n## --jobs {jobs}: exit seen by the driver at {end:.3f} s\n  wall s  process  CPU s  minflt")
            names = {parent: "parent"}
            for t, pid, what in events:
                who = names.setdefault(pid, f"worker {len(names)}")
                print(f"{t:8.3f}  {who:9s} {what}")


if __name__ == "__main__":
    main()
