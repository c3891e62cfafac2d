"""The measurements behind wall/lepton's automatic choice of path (engine/compiled.py,
`lepton_seconds`): the lj93 gas slit with both faces as wall/lepton expressions, one case of
N = 100, 1000, 10000 atoms, 1000 steps, sampled every step (thermo 1) and every 100 steps, on the
NumPy path (WALLBATCH_LEPTON_COMPILED=never) and compiled (always; the kernel compiled and loaded
by a warm-up run first, so its start-up is not in the times).

    flock /tmp/wb-cpu.lock python benchmarks/lepton_cost.py [--src DIR]

Prints seconds per step and per atom-step of each run, then the model's constants fitted to
them: NumPy seconds per step and per atom-step (thermo 100) and per sample and per sampled atom
(thermo 1 minus thermo 100), compiled seconds per atom-step.
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
    args = ap.parse_args()
    os.environ.setdefault("WALLBATCH_THREADS", "1")
    sys.path.insert(0, str(Path(args.src).resolve()))
    sys.path.insert(1, str(HERE))
    import numpy as np  # noqa: PLC0415
    import common  # noqa: PLC0415 - after sys.path is set
    from wallbatch.engine.engine import Engine  # noqa: PLC0415

    print(f"load average {os.getloadavg()}")
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


if __name__ == "__main__":
    main()
