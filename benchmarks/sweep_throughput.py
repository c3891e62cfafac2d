"""Throughput of the 27-case lj93 slit sweep (N = 1000 atoms, epsilon x sigma x cutoff):
all cases batched on the case axis vs one case at a time, in one process and one run.

    python benchmarks/sweep_throughput.py [--steps 10000] [--atoms 1000]

Prints a table: mode, cases, seconds, atom-steps/s, speed-up. Compare ratios within one run:
the machine is shared and noisy.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from wallbatch.engine.engine import run_cases
from wallbatch.batch.runner import build_cases
from wallbatch.config.sweep import load_plan

SWEEP = Path(__file__).resolve().parents[1] / "sweeps" / "lj93-epsilon-sigma-cutoff.yaml"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=10000)
    ap.add_argument("--atoms", type=int, default=1000)
    args = ap.parse_args()
    plan = load_plan(SWEEP, [f"run.steps={args.steps}", f"atoms.0.create.random.count={args.atoms}",
                             "run.thermo=1000", "atoms.0.create.random.overlap=0.5"])
    cases, errors = build_cases(plan)
    assert not errors, errors
    atom_steps = sum(c.natoms for c in cases) * args.steps

    rows = []
    t0 = time.perf_counter()
    batched = run_cases(cases)
    rows.append(("batched (one batch of 27)", time.perf_counter() - t0))
    t0 = time.perf_counter()
    single = [run_cases([c])[0] for c in cases]
    rows.append(("one case at a time", time.perf_counter() - t0))
    same = all(np.array_equal(a.data[k], b.data[k], equal_nan=True) for a, b in zip(batched, single) for k in a.data)

    print(f"27-case lj93 slit sweep, N = {args.atoms}, {args.steps} steps, {atom_steps:,} atom-steps")
    print(f"{'mode':<28} {'cases':>5} {'seconds':>9} {'atom-steps/s':>14} {'speed-up':>9}")
    base = rows[1][1]
    for name, sec in rows:
        print(f"{name:<28} {len(cases):>5} {sec:>9.2f} {atom_steps / sec:>14.3e} {base / sec:>8.2f}x")
    print(f"batched results bit-identical to one-at-a-time: {same}")


if __name__ == "__main__":
    main()
