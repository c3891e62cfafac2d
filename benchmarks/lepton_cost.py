"""The measurements behind wall/lepton's automatic choice of path (engine/compiled.py,
`lepton_seconds`): the lj93 gas slit with both faces as wall/lepton expressions, one case of
N = 100, 1000, 10000 atoms, 1000 steps, sampled every step (thermo 1) and every 100 steps, on the
NumPy path (WALLBATCH_LEPTON_COMPILED=never) and compiled (always; the kernel compiled and loaded
by a warm-up run first, so its start-up is not in the times).

    flock /tmp/wb-cpu.lock python benchmarks/lepton_cost.py [--src DIR]

Prints seconds per step and per atom-step of each run, then the model's constants fitted to
them: NumPy seconds per step and per atom-step (thermo 100) and per sample and per sampled atom
(thermo 1 minus thermo 100), compiled seconds per atom-step.

With `--pair`: an LJ liquid (pair lj/cut, `common.lj_slit`) between the same wall/lepton faces,
N = 1000, 4000, 16000, 500 steps, sampled every 100 steps: the per-step compiled pair path with its
walls in NumPy (never) against the fused pair chunk (always); both run the same compiled pair
forces, so the fit is of the difference (the model's LEPTON_PAIR_* constants), and the first
compile of the fused kernel with these expressions (in a fresh cache folder) is timed too.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
STEPS = 1000


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--src", default=str(HERE.parent / "src"), help="the wallbatch package's src directory")
    ap.add_argument("--pair", action="store_true", help="with pair lj/cut: the fused pair chunk's constants")
    args = ap.parse_args()
    if args.pair:
        import tempfile  # noqa: PLC0415

        os.environ["WALLBATCH_CACHE_DIR"] = tempfile.mkdtemp(prefix="wb_lepton_cost_")  # a first compile
    os.environ.setdefault("WALLBATCH_THREADS", "1")
    sys.path.insert(0, str(Path(args.src).resolve()))
    sys.path.insert(1, str(HERE))
    import numpy as np  # noqa: PLC0415
    import common  # noqa: PLC0415 - after sys.path is set
    from wallbatch.engine.engine import Engine  # noqa: PLC0415

    print(f"load average {os.getloadavg()}")
    if args.pair:
        pair_costs(np, common, Engine)
        return
    sizes = (100, 1000, 10000)
    per_step: dict[tuple[str, int, int], float] = {}
    for mode in ("never", "always"):
        os.environ["WALLBATCH_LEPTON_COMPILED"] = mode
        for n in sizes:
            Engine([common.build(common.lepton_slit(n, steps=10, thermo=1))]).run()  # warm-up: kernels loaded
            for thermo in (1, 100):
                case = common.build(common.lepton_slit(n, steps=STEPS, thermo=thermo))
                t0 = time.perf_counter()
                Engine([case]).run()
                sec = (time.perf_counter() - t0) / STEPS
                per_step[(mode, n, thermo)] = sec
                print(f"{mode:6s} N={n:6d} thermo {thermo:3d}: {sec * 1e3:.3f} ms per step, "
                      f"{sec / n * 1e9:.0f} ns per atom-step", flush=True)
    ns = np.array(sizes, float)
    unsampled = np.polyfit(ns, [per_step[("never", n, 100)] for n in sizes], 1)
    sample = np.polyfit(ns, [per_step[("never", n, 1)] - per_step[("never", n, 100)] for n in sizes], 1)
    compiled = np.polyfit(ns, [per_step[("always", n, 1)] for n in sizes], 1)
    print(f"NumPy: {unsampled[1] * 1e3:.3f} ms per step + {unsampled[0] * 1e9:.1f} ns per atom-step; per sample "
          f"{sample[1] * 1e3:.3f} ms + {sample[0] * 1e9:.1f} ns per atom")
    print(f"compiled, sampled every step: {compiled[0] * 1e9:.1f} ns per atom-step (+ {compiled[1] * 1e3:.3f} ms per step)")
    print(f"load average {os.getloadavg()}")


def lepton_lj(common, n: int, steps: int, thermo: int) -> dict:  # noqa: ANN001
    """`common.lj_slit` with its two lj93 faces written as wall/lepton expressions of lj93."""
    cfg = common.lj_slit(n, steps=steps, thermo=thermo)
    cfg["walls"] = common.lepton_slit(100)["walls"]
    return cfg


def pair_costs(np, common, Engine) -> None:  # noqa: ANN001
    """The --pair measurements: the fused kernel's first compile, then each size on both paths."""
    os.environ["WALLBATCH_LEPTON_COMPILED"] = "always"
    t0 = time.perf_counter()
    eng = Engine([common.build(lepton_lj(common, 1000, 10, 10))])
    eng.run()
    assert type(eng.fast).__name__ == "PairChunks", "the fused pair chunk did not run"
    took = time.perf_counter() - t0
    print(f"first compile of the fused chunk with these expressions (and its run): {took:.1f} s")
    sizes, steps = (1000, 4000, 16000), 500
    per_step: dict[tuple[str, int], float] = {}
    for n in sizes:
        for mode in ("never", "always"):
            os.environ["WALLBATCH_LEPTON_COMPILED"] = mode
            Engine([common.build(lepton_lj(common, n, 10, 10))]).run()  # warm-up
            best = float("inf")
            for _ in range(2):
                case = common.build(lepton_lj(common, n, steps, 100))
                t0 = time.perf_counter()
                Engine([case]).run()
                best = min(best, (time.perf_counter() - t0) / steps)
            per_step[(mode, n)] = best
            print(f"{mode:6s} N={n:6d}: {best * 1e3:.3f} ms per step, {best / n * 1e9:.0f} ns per atom-step",
                  flush=True)
    ns = np.array(sizes, float)
    diff = np.polyfit(ns, [per_step[("never", n)] - per_step[("always", n)] for n in sizes], 1)
    print(f"NumPy walls minus fused: {diff[1] * 1e3:.3f} ms per step + {diff[0] * 1e9:.1f} ns per atom-step")


if __name__ == "__main__":
    main()
