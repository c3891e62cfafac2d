"""One large lj93 gas slit case (no pair forces) sampled every K steps, on one thread and on two:
where splitting the case over threads pays (`compiled.SPLIT_SAMPLE_STEPS`), beside LAMMPS serial.

    python benchmarks/split_samples.py [--atoms 100000] [--steps 400] [--every 10 25 50 100] [--repeat 2]

Each wallbatch run is a new process (WALLBATCH_THREADS=1 or 2) timing `Engine([case]).run()`
after a short warm-up run that loads the kernels; the two thread counts go in turns, best of
`--repeat` each. A split case takes each sample from a NumPy pass over all atoms; samples closer
than SPLIT_SAMPLE_STEPS steps stay in the kernel on one thread (then both columns run the same
way). LAMMPS: the exported case, its `run` timed, serially, with its default neighbor settings
(`--no-lammps` to skip).
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

CHILD = """
import sys
sys.path.insert(0, {here!r})
import common
from suite import engine_run
engine_run(common.build(common.gas_slit(20000, "lj93", steps=10, thermo=10)))
sec, res, path = engine_run(common.build(common.gas_slit({n}, "lj93", steps={steps}, thermo={every})))
print("RESULT", sec, float(res.data["ke"][-1]).hex())
"""


def wallbatch_run(n: int, steps: int, every: int, threads: int) -> tuple[float, str]:
    """(seconds, final ke's bits) of one run in a new process with `threads` threads."""
    env = dict(os.environ, WALLBATCH_THREADS=str(threads), NUMBA_NUM_THREADS=str(threads))
    out = subprocess.run([sys.executable, "-c", CHILD.format(here=str(HERE), n=n, steps=steps, every=every)],
                         env=env, capture_output=True, text=True, check=True).stdout
    _, sec, bits = next(ln for ln in out.splitlines() if ln.startswith("RESULT")).split()
    return float(sec), bits


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--atoms", type=int, default=100_000)
    ap.add_argument("--steps", type=int, default=400)
    ap.add_argument("--every", type=int, nargs="+", default=[10, 25, 50, 100], help="steps between samples")
    ap.add_argument("--repeat", type=int, default=2, help="runs of each thread count, in turns (best kept)")
    ap.add_argument("--no-lammps", action="store_true")
    args = ap.parse_args(argv)
    for name in ("atoms", "steps", "repeat"):
        if getattr(args, name) < 1:
            ap.error(f"--{name} {getattr(args, name)}: give a whole number, 1 or more")
    if any(k < 1 or k > args.steps for k in args.every):
        ap.error(f"--every {' '.join(map(str, args.every))}: each must be from 1 to --steps ({args.steps})")
    import common  # noqa: PLC0415
    from wallbatch.engine.compiled import SPLIT_SAMPLE_STEPS  # noqa: PLC0415

    lammps = not args.no_lammps and common.lammps_module() is not None
    print(f"N = {args.atoms:,}, {args.steps} steps; SPLIT_SAMPLE_STEPS = {SPLIT_SAMPLE_STEPS}; "
          f"best of {args.repeat}, thread counts in turns")
    print("| steps per sample | wb 1 thread [s] | wb 2 threads [s] | 2/1 | same bits | LAMMPS serial [s] |")
    print("| --- | --- | --- | --- | --- | --- |")
    for every in args.every:
        best = {1: float("inf"), 2: float("inf")}
        bits = set()
        for _ in range(args.repeat):
            for k in (1, 2):
                sec, b = wallbatch_run(args.atoms, args.steps, every, k)
                best[k] = min(best[k], sec)
                bits.add(b)
        lmp = "n/a"
        if lammps:
            cfg = common.gas_slit(args.atoms, "lj93", steps=args.steps, thermo=every)
            lmp = f"{min(common.lammps_export_run(cfg) for _ in range(args.repeat)):.3f}"
        print(f"| {every} | {best[1]:.3f} | {best[2]:.3f} | {best[1] / best[2]:.2f}x | "
              f"{'yes' if len(bits) == 1 else 'NO'} | {lmp} |")


if __name__ == "__main__":
    main()
