"""lj/cut slit rows of the suite (`ljcut-*`) timed in CPU seconds of this process instead of wall
seconds: on a shared, loaded machine the wall clock measures the load as much as the code.

    PYTHONPATH=src python benchmarks/pair_cpu.py [--atoms 4000 32000 100000] [--repeat 2]

For each N: the scene of the suite's row (benchmarks/common.py lj_fcc_slit, the same steps and
thermo), wallbatch's engine run (after a warm-up that loads the kernels) and LAMMPS's `run` of the
exported script, interleaved `--repeat` times; the table gives the best CPU seconds of each and the
ratio LAMMPS / wallbatch (the suite's atom-steps/s ratio). Both run serially in this process
(WALLBATCH_THREADS=1 unless set, as in the suite).
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
os.environ.setdefault("WALLBATCH_THREADS", "1")  # one thread, as the suite's rows (before numba loads)

import common  # noqa: E402
from common import build, lammps_export_run, lj_fcc_slit  # noqa: E402

from wallbatch.engine.engine import Engine  # noqa: E402

ATOM_STEPS = {4000: 4e6, 32000: 6.4e6, 100000: 5e6}  # the suite's rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--atoms", type=int, nargs="+", default=[4000, 32000, 100000])
    ap.add_argument("--repeat", type=int, default=2)
    args = ap.parse_args()
    common.CLOCK = time.process_time
    print(f"{'N':>8} {'steps':>6} {'wallbatch cpu s':>16} {'LAMMPS cpu s':>13} {'ratio':>6}")
    for n in args.atoms:
        steps = max(20, int(ATOM_STEPS.get(n, 5e6) // n))  # the suite's `scaled` at scale 1
        cfg = lj_fcc_slit(n, steps=steps, thermo=max(1, steps // 10))
        Engine([build(dict(cfg, run={**cfg["run"], "steps": 10, "thermo": 10}))]).run()  # load the kernels
        wb, lmp = [], []
        for _ in range(args.repeat):
            case = build(cfg)
            t0 = time.process_time()
            res = Engine([case]).run()[0]
            wb.append(time.process_time() - t0)
            assert res.status == "ok", res.error
            lmp.append(lammps_export_run(cfg, case))
        print(f"{case.natoms:>8} {steps:>6} {min(wb):>16.3f} {min(lmp):>13.3f} {min(lmp) / min(wb):>6.2f}", flush=True)


if __name__ == "__main__":
    main()
