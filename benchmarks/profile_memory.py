"""Memory of big sweeps: a whole `wallbatch run` of many cases, and profiles (issue 18).

    python benchmarks/profile_memory.py --sweep 10000 [--atoms 100] [--samples 100] [--jobs 1]
    python benchmarks/profile_memory.py [--cases 1000] [--bins 50] [--windows 100] [--atoms 20]

--sweep N: the lj93 slit (configs/lj93-slit.yaml) with N cases (epsilon x sigma), `--atoms`
atoms and `--samples` samples each (5 steps apart), run end to end as `wallbatch run` in a child
process; prints its peak resident memory (ru_maxrss of the child), its wall time and the size of
the results file, next to the same sweep with a tenth of the cases: a run whose memory is bounded
by what runs grows by about the plan (~11 kB per case) and the output arrays themselves.

Without --sweep: profiles over a big sweep, 1000 cases x 50-bin profiles x 100 windows.

What a profile quantity needs is cases x windows x bins float64 (8 bytes each): 40 kB per case
for 50 bins and 100 windows. The script runs the sweep as one batch (an ideal gas in a harmonic
slit, one profile quantity, every = freq = 10 steps) and prints, per case: the bytes needed, the
bytes the engine holds for the profile (windows store + running sums), and the peak memory traced
by tracemalloc while running the batch and while building the results Dataset (NumPy reports its
allocations to tracemalloc), next to the same run without the profile.
"""

from __future__ import annotations

import argparse
import math
import os
import resource
import subprocess
import sys
import tempfile
import time
import tracemalloc
from pathlib import Path

from wallbatch.api import load
from wallbatch.batch.runner import build_cases
from wallbatch.engine.engine import Engine
from wallbatch.io.netcdf import build_dataset


def config(cases: int, bins: int, windows: int, atoms: int, profiles: bool) -> dict:
    cfg = {
        "box": {"lo": [0, 0, 0], "hi": [6, 6, 10], "boundary": ["p", "p", "f"]},
        "regions": {"slab": {"style": "block", "lo": [0, 0, 3], "hi": [6, 6, 7], "units": "box"}},
        "atoms": [{"group": "gas", "create": {"random": {"count": atoms, "region": "slab"}}, "mass": 1.0,
                   "velocity": {"temperature": 1.0}}],
        "walls": {"w": {"style": "harmonic", "units": "box", "zlo": [-1.0, 5.0, 1.0, 4.0],
                        "zhi": [11.0, 5.0, 1.0, 4.0]}},
        "run": {"steps": 10 * windows, "thermo": 0},
        "sweep": {"product": {"k": {"path": "walls.w.zlo.epsilon",
                                    "values": {"linspace": [5.0, 10.0, cases]}}}},
    }
    if profiles:
        cfg["output"] = {"profiles": {"across": {"axis": "z", "bins": bins, "every": 10, "repeat": 1, "freq": 10,
                                                 "quantities": ["density/number"]}}}
    return cfg


def measure(cfg: dict) -> tuple[int, int, int, float]:
    """(engine profile bytes, peak bytes while running, peak bytes while building the Dataset, seconds)."""
    plan = load(cfg)
    cases, _ = build_cases(plan)
    tracemalloc.start()
    t0 = time.perf_counter()
    eng = Engine(cases)
    results = eng.run()
    seconds = time.perf_counter() - t0
    _, peak_run = tracemalloc.get_traced_memory()
    held = 0
    if eng.profiles is not None:
        held = sum(a.nbytes for d in eng.profiles.out for a in d.values())
        held += sum(a.nbytes for d in eng.profiles.sums for a in d.values())
    tracemalloc.reset_peak()
    ds = build_dataset(results, cases[0], dims=plan.dims)
    _, peak_build = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    del ds
    return held, peak_run, peak_build, seconds


ROOT = Path(__file__).resolve().parents[1]


def sweep_yaml(cases: int, atoms: int, samples: int) -> str:
    """A sweep of the lj93 slit with `cases` cases (epsilon x sigma, as square as possible)."""
    a = max(1, int(math.isqrt(cases)))
    while cases % a:
        a -= 1
    b = cases // a
    return (f"base: {ROOT / 'configs' / 'lj93-slit.yaml'}\n"
            f"set: {{run.steps: {5 * samples}, run.thermo: 5, atoms.0.create.random.count: {atoms}}}\n"
            "sweep:\n  product:\n"
            f"    epsilon: {{path: [walls.zwalls.zlo.epsilon, walls.zwalls.zhi.epsilon], values: {{linspace: [0.5, 2.0, {a}]}}}}\n"
            f"    sigma: {{path: [walls.zwalls.zlo.sigma, walls.zwalls.zhi.sigma], values: {{linspace: [0.8, 1.2, {b}]}}}}\n")


def run_sweep(cases: int, atoms: int, samples: int, jobs: int) -> tuple[float, float, float]:
    """(peak RSS MB of the child `wallbatch run`, seconds, results file MB)."""
    with tempfile.TemporaryDirectory() as tmp:
        cfg = Path(tmp) / "sweep.yaml"
        cfg.write_text(sweep_yaml(cases, atoms, samples))
        out = Path(tmp) / "out.nc"
        code = ("import resource, sys\nfrom wallbatch.cli import app as main\n"
                "try:\n    main()\nexcept SystemExit as exc:\n    code = exc.code\nelse:\n    code = 0\n"
                "print('MAXRSS', resource.getrusage(resource.RUSAGE_SELF).ru_maxrss, file=sys.stderr)\n"
                "sys.exit(code)\n")
        t0 = time.perf_counter()
        proc = subprocess.run([sys.executable, "-c", code, "run", str(cfg), "-o", str(out), "--jobs", str(jobs)],
                              capture_output=True, text=True, env={**os.environ, "PYTHONPATH": str(ROOT / "src")})
        seconds = time.perf_counter() - t0
        if proc.returncode != 0:
            raise SystemExit(proc.stdout + proc.stderr)
        rss = max(int(line.split()[1]) for line in proc.stderr.splitlines() if line.startswith("MAXRSS")) / 1e3
        rss = max(rss, resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1e3 if jobs > 1 else 0.0)
        return rss, seconds, out.stat().st_size / 1e6


def main_sweep(cases: int, atoms: int, samples: int, jobs: int) -> None:
    print(f"lj93 slit sweep, N = {atoms}, {samples} samples, --jobs {jobs}: wallbatch run end to end")
    print(f"{'cases':>7} {'peak RSS MB':>12} {'seconds':>9} {'results MB':>11}")
    for n in (max(1, cases // 10), cases):
        rss, sec, size = run_sweep(n, atoms, samples, jobs)
        print(f"{n:>7} {rss:>12.0f} {sec:>9.1f} {size:>11.1f}", flush=True)


def main() -> None:
    if "--sweep" in sys.argv:
        ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
        ap.add_argument("--sweep", type=int, required=True)
        ap.add_argument("--atoms", type=int, default=100)
        ap.add_argument("--samples", type=int, default=100)
        ap.add_argument("--jobs", type=int, default=1)
        a = ap.parse_args()
        main_sweep(a.sweep, a.atoms, a.samples, a.jobs)
        return
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", type=int, default=1000)
    ap.add_argument("--bins", type=int, default=50)
    ap.add_argument("--windows", type=int, default=100)
    ap.add_argument("--atoms", type=int, default=20)
    a = ap.parse_args()
    need = a.windows * a.bins * 8
    base = measure(config(a.cases, a.bins, a.windows, a.atoms, False))
    prof = measure(config(a.cases, a.bins, a.windows, a.atoms, True))
    per = lambda b: b / a.cases  # noqa: E731
    print(f"{a.cases} cases x {a.windows} windows x {a.bins} bins, {a.atoms} atoms, one quantity")
    print(f"  needed (windows x bins float64):      {per(need * a.cases):10.0f} bytes/case")
    print(f"  held by the engine (store + sums):    {per(prof[0]):10.0f} bytes/case  "
          f"({prof[0] / (need * a.cases):.2f} x needed)")
    print(f"  peak traced while running:            {per(prof[1]):10.0f} bytes/case  "
          f"(without the profile: {per(base[1]):.0f})")
    print(f"  peak traced building the Dataset:     {per(prof[2]):10.0f} bytes/case  "
          f"(without the profile: {per(base[2]):.0f}; transient: the stacked copy of the windows, the "
          f"window selection and the blocking temporaries)")
    print(f"  run time: {base[3]:.1f} s without, {prof[3]:.1f} s with the profile (first includes compilation)")

if __name__ == "__main__":
    main()
