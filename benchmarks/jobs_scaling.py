"""How `--jobs 2` over `--jobs 1` grows with the size of the sweep: suite.py's jobs2-64cases row
(64 lj93 gas slit cases, N = 1000, an 8 x 8 epsilon, sigma sweep, each run a new `wallbatch run`
process, warm kernels, WALLBATCH_THREADS=1) at several run lengths.

    python benchmarks/jobs_scaling.py [--steps 10000 20000 40000] [--rounds 2] [--src DIR ...]

With T(jobs) = S + W / jobs (S: what each run does once, serially: Python, imports, numba's
set-up and the kernel load, the plan, forking, merging the parts and writing the file; W: the
cases), two runs give S = 2 T2 - T1 and W = 2 (T1 - T2), and the ratio T1 / T2 = (S + W) /
(S + W / 2) tends to 2 as the sweep grows. --src runs the same table for other source trees
(e.g. the main branch's src) in the same rounds: compare ratios within one run only, the
machine is shared and its load moves. Rounds interleave -j 1 and -j 2 (and the trees); the best
of the rounds is kept. The results files of -j 1 and -j 2 must be bit-identical. The CPU model
ratio is T1 / T2 from CPU seconds (-j 1's; -j 2's parent, serially, then its slower worker),
what two free cores would give: steadier than wall time on a loaded machine.
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

ROOT = HERE.parent


def sweep_config(steps: int, n: int = 1000) -> dict:
    """suite.py's jobs2 row at `steps` steps (thermo every steps / 10)."""
    cfg = common.gas_slit(n, "lj93", steps=steps, thermo=max(1, steps // 10))
    cfg["sweep"] = {"product": {
        "eps": {"path": ["walls.w.zlo.epsilon", "walls.w.zhi.epsilon"], "values": {"linspace": [0.5, 2.0, 8]}},
        "sig": {"path": ["walls.w.zlo.sigma", "walls.w.zhi.sigma"], "values": {"linspace": [0.8, 1.2, 8]}}}}
    return cfg


# `wallbatch run` as the console script runs it, each worker process noting its CPU seconds after
# each window it ran (in WB_CPU_DIR/<pid>), for the CPU model below
CPU_NOTES = """
import os, sys, time
import wallbatch.cli  # first, as the console script: what it sets before NumPy loads (OpenBLAS threads)
from wallbatch.batch import runner
parent, folder, real = os.getpid(), os.environ["WB_CPU_DIR"], runner._run_window
def noted(*args, **kwargs):
    out = real(*args, **kwargs)
    if os.getpid() != parent:
        with open(os.path.join(folder, str(os.getpid())), "w") as fh:
            fh.write(repr(time.process_time()))
    return out
runner._run_window = noted
from wallbatch.cli import app
sys.argv = ["wallbatch"] + sys.argv[1:]
app()
"""


def run_once(src: Path, work: Path, jobs: int, out: str, notes: bool = False) -> tuple[float, float, list[float]]:
    """(wall seconds, CPU seconds of the process and its workers, each worker's CPU seconds) of one
    `wallbatch run` (the workers' only with `notes`: run through CPU_NOTES)."""
    env = dict(os.environ, WALLBATCH_THREADS="1", PYTHONPATH=str(src))
    env.pop("PYTHONDONTWRITEBYTECODE", None)  # as a user's Python: the .pyc files are kept
    args = ["run", "sweep.yaml", "-o", out, "--force", "-j", str(jobs)]
    cmd = [sys.executable, "-c", CPU_NOTES, *args] if notes else [sys.executable, "-m", "wallbatch.cli", *args]
    with tempfile.TemporaryDirectory(prefix="wb_cpu_") as folder:
        env["WB_CPU_DIR"] = folder
        t0 = time.perf_counter()
        proc = subprocess.Popen(cmd, cwd=work, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT)
        _, status, usage = os.wait4(proc.pid, 0)
        wall = time.perf_counter() - t0
        workers = [float(p.read_text()) for p in Path(folder).iterdir()]
    text = proc.stdout.read().decode(errors="replace") if proc.stdout else ""
    if os.waitstatus_to_exitcode(status) != 0:
        raise SystemExit(f"{' '.join(cmd)} failed:\n{text}")
    return wall, usage.ru_utime + usage.ru_stime, workers


def same_results(a: Path, b: Path) -> bool:
    """The outputs of two results files are the same bits (their attributes may differ)."""
    import xarray as xr  # noqa: PLC0415

    with xr.open_dataset(a) as da, xr.open_dataset(b) as db:
        return all(da[k].equals(db[k]) for k in da.data_vars if k not in ("seconds",))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, nargs="+", default=[10000, 20000, 40000])
    ap.add_argument("--rounds", type=int, default=2)
    ap.add_argument("--src", type=Path, nargs="*", default=[], help="other source trees to compare")
    args = ap.parse_args()
    import yaml  # noqa: PLC0415

    trees = [ROOT / "src", *[p.resolve() for p in args.src]]
    load0 = os.getloadavg()[0]
    rows = []
    with tempfile.TemporaryDirectory(prefix="wb_jobs_scaling_") as tmp:
        for steps in args.steps:
            work = Path(tmp) / str(steps)
            work.mkdir()
            (work / "sweep.yaml").write_text(yaml.safe_dump(sweep_config(steps), sort_keys=False))
            best: dict[tuple[int, int], tuple[float, float, float]] = {}
            for src in trees:  # the kernels in each tree's numba cache, the files in the page cache
                run_once(src, work, 1, "warm.nc")
            for _ in range(args.rounds):
                for t, src in enumerate(trees):
                    for jobs in (1, 2):
                        wall, cpu, workers = run_once(src, work, jobs, f"t{t}j{jobs}.nc")
                        # the CPU model: the parent's CPU serially, then the slower worker's
                        model = cpu if jobs == 1 else cpu - sum(workers) + max(workers, default=0.0)
                        if jobs == 2:  # the workers' CPU from a second run, noted (the timed run is the plain command)
                            _, cpu_n, workers = run_once(src, work, jobs, f"t{t}n.nc", notes=True)
                            model = cpu_n - sum(workers) + max(workers, default=0.0) if len(workers) == 2 else float("nan")
                        old = best.get((t, jobs))
                        now = (wall, cpu, model)
                        best[(t, jobs)] = tuple(min(a, b) for a, b in zip(old, now)) if old else now  # type: ignore[assignment]
            for t, src in enumerate(trees):
                (t1, c1, m1), (t2, c2, m2) = best[(t, 1)], best[(t, 2)]
                same = same_results(work / f"t{t}j1.nc", work / f"t{t}j2.nc")
                rows.append((steps, src, t1, t2, t1 / t2, 2 * t2 - t1, 2 * (t1 - t2), c1, c2, m1 / m2, same))
    load1 = os.getloadavg()[0]
    print(f"# --jobs 2 vs --jobs 1, 64 cases N = 1000 ({os.cpu_count()} cores; load average {load0:.2f} before, "
          f"{load1:.2f} after; best of {args.rounds})")
    print("| steps | source | -j 1 (s) | -j 2 (s) | ratio | S = 2 T2 - T1 (s) | W = 2 (T1 - T2) (s) | "
          "CPU -j 1 / -j 2 (s) | CPU model ratio | -j 1 == -j 2 |")
    print("| ---: | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | --- |")
    for steps, src, t1, t2, ratio, s, w, c1, c2, model, same in rows:
        print(f"| {steps} | {src} | {t1:.2f} | {t2:.2f} | {ratio:.2f}x | {s:.2f} | {w:.2f} | {c1:.2f} / {c2:.2f} | "
              f"{model:.2f}x | {'bit-identical' if same else 'DIFFER'} |")
    print("CPU model ratio: -j 1's CPU seconds over (-j 2's parent CPU + its slower worker's CPU), each the best "
          "of the rounds: the ratio two free cores would give, steadier than wall time when other programs load "
          "the machine (a noted run of -j 2 gives the workers' CPU)")


if __name__ == "__main__":
    main()
