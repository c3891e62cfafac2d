"""--jobs 2 against --jobs 1 on 2 cores: the lj93 slit sweep scaled to 64 cases (4 x 4 x 4).

    python benchmarks/jobs.py [--steps 2000] [--atoms 500] [--rounds 2]

Each measurement is a fresh child process (so each loads its kernels, as a real run does) that
loads the plan, then times `run_plan` to a results file (the part --jobs changes: building,
running, saving parts, writing the file). Rounds interleave --jobs 1 and --jobs 2 so the
machine's load falls on both; the best of the rounds is compared. The results files of both
must be bit-identical. Compare ratios within one run: the machine is shared and noisy.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

SWEEP = """\
base: {base}
set: {{run.steps: {steps}, atoms.0.create.random.count: {atoms}}}
sweep:
  product:
    epsilon: {{path: [walls.zwalls.zlo.epsilon, walls.zwalls.zhi.epsilon], values: [0.5, 1.0, 1.5, 2.0]}}
    sigma:   {{path: [walls.zwalls.zlo.sigma, walls.zwalls.zhi.sigma], values: {{linspace: [0.8, 1.2, 4]}}}}
    cutoff:  {{path: [walls.zwalls.zlo.cutoff, walls.zwalls.zhi.cutoff], values: [1.0, 2.0, 2.5, 4.0]}}
"""

CHILD = """\
import json, resource, sys, time
from wallbatch.api import load
from wallbatch.batch.runner import run_plan
plan = load(sys.argv[1])
t0, c0 = time.perf_counter(), time.process_time()
run_plan(plan, sys.argv[2], jobs=int(sys.argv[3]), progress=False)
ru = resource.getrusage(resource.RUSAGE_CHILDREN)
print(json.dumps({"seconds": time.perf_counter() - t0, "cpu": time.process_time() - c0,
                  "workers": ru.ru_utime + ru.ru_stime}))
"""


def once(cfg: Path, out: Path, jobs: int) -> dict:
    proc = subprocess.run([sys.executable, "-c", CHILD, str(cfg), str(out), str(jobs)], capture_output=True, text=True,
                          env={**os.environ, "PYTHONPATH": str(ROOT / "src")})
    if proc.returncode != 0:
        raise SystemExit(proc.stderr)
    return json.loads(proc.stdout.strip().splitlines()[-1])


def same(a: Path, b: Path) -> bool:
    import numpy as np
    import xarray as xr

    with xr.open_dataset(a) as da, xr.open_dataset(b) as db:
        return all(np.array_equal(da[k].values, db[k].values) for k in da.data_vars
                   if k not in ("seconds",) and da[k].dtype.kind == "f")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=2000)
    ap.add_argument("--atoms", type=int, default=500)
    ap.add_argument("--rounds", type=int, default=2)
    a = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        cfg = Path(tmp) / "sweep.yaml"
        cfg.write_text(SWEEP.format(base=ROOT / "configs" / "lj93-slit.yaml", steps=a.steps, atoms=a.atoms))
        times: dict[int, list[float]] = {1: [], 2: []}
        crit: dict[int, list[float]] = {1: [], 2: []}
        cpu: dict[int, list[float]] = {1: [], 2: []}
        par: list[float] = []
        for r in range(a.rounds):
            for jobs in (1, 2):
                m = once(cfg, Path(tmp) / f"j{jobs}.nc", jobs)
                times[jobs].append(m["seconds"])
                cpu[jobs].append(m["cpu"] + m["workers"])
                crit[jobs].append(m["cpu"] + m["workers"] / jobs)  # the parent, then equal shares
                if jobs == 2:
                    par.append(m["cpu"])
                Path(tmp, f"j{jobs}.nc").rename(Path(tmp) / f"j{jobs}-{r}.nc")
        identical = same(Path(tmp) / "j1-0.nc", Path(tmp) / "j2-0.nc")
    t1, t2 = min(times[1]), min(times[2])
    c1, c2 = min(crit[1]), min(crit[2])
    print(f"64-case lj93 slit sweep, N = {a.atoms}, {a.steps} steps, {os.cpu_count()} cores, load "
          f"{os.getloadavg()[0]:.1f}")
    print(f"  --jobs 1: {t1:6.2f} s   (rounds: {', '.join(f'{t:.2f}' for t in times[1])})")
    print(f"  --jobs 2: {t2:6.2f} s   (rounds: {', '.join(f'{t:.2f}' for t in times[2])})")
    print(f"  speed-up: {t1 / t2:.2f}x wall clock; results bit-identical: {identical}")
    print(f"  CPU seconds (parent + workers): --jobs 1 {min(cpu[1]):.2f}, --jobs 2 {min(cpu[2]):.2f}; critical path "
          f"(parent + a worker's share): {c1:.2f} vs {c2:.2f} s: {c1 / c2:.2f}x on unthrottled cores")
    print(f"  parent CPU with --jobs 2 (start-up, numba initialised once before forking, parts, file): "
          f"{min(par):.2f} s")


if __name__ == "__main__":
    main()
