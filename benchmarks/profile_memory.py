"""Memory of profiles over a big sweep (issue 18): 1000 cases x 50-bin profiles x 100 windows.

    python benchmarks/profile_memory.py [--cases 1000] [--bins 50] [--windows 100] [--atoms 20]

What a profile quantity needs is cases x windows x bins float64 (8 bytes each): 40 kB per case
for 50 bins and 100 windows. The script runs the sweep as one batch (an ideal gas in a harmonic
slit, one profile quantity, every = freq = 10 steps) and prints, per case: the bytes needed, the
bytes the engine holds for the profile (windows store + running sums), and the peak memory traced
by tracemalloc while running the batch and while building the results Dataset (NumPy reports its
allocations to tracemalloc), next to the same run without the profile.
"""

from __future__ import annotations

import argparse
import time
import tracemalloc

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


def main() -> None:
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
