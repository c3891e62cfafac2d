"""lj/cut and flow walls with an LJ fluid against LAMMPS (issue 15), timed on CPU time of this
process (LAMMPS runs serially in it too), interleaved and repeated: steadier than wall time on a
shared machine.

    python benchmarks/pairspeed.py [--atoms 4000 32000] [--steps 500] [--repeat 3] [--flow]

Rows: the LJ slit of benchmarks/pair_lj.py (fcc at rho 0.8 melting at T = 2 between lj93 walls,
lj/cut 2.5 shifted, skin 0.3, LAMMPS `neigh_modify every 1 delay 0 check yes`), and with --flow
the LJ fluid with four wall/flow walls of benchmarks/flow_scene.py (LAMMPS defaults: check yes).
Each repeat runs wallbatch then LAMMPS on the same state; the table gives the median seconds and
the median of the per-repeat ratios of atom-steps/s (wallbatch / LAMMPS).
"""

from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(__file__))
from common import build, lammps_module, lammps_run  # noqa: E402
from flow_scene import flow_config  # noqa: E402
from pair_lj import run_lammps, slit  # noqa: E402
from pair_lj import config as slit_config  # noqa: E402

import pair_lj  # noqa: E402
from wallbatch.engine.engine import run_cases  # noqa: E402
import common  # noqa: E402


def wallbatch_seconds(case) -> float:
    t0 = time.process_time()
    (res,) = run_cases([case])
    sec = time.process_time() - t0
    assert res.status == "ok", res.error
    return sec


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--atoms", type=int, nargs="+", default=[4000, 32000])
    ap.add_argument("--steps", type=int, default=500)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--flow", action="store_true", help="also the flow-wall LJ fluid (N = first --atoms)")
    ap.add_argument("--no-slit", action="store_true")
    args = ap.parse_args()
    common.set_clock("cpu")
    pair_lj.time.perf_counter = time.process_time  # pair_lj's LAMMPS timer on CPU time too
    from wallbatch.config.models import config_from_dict
    from wallbatch.scene.build import build_case

    t0 = time.process_time()
    run_cases([build_case(config_from_dict(slit_config(*slit(500), 10)))])  # load or compile kernels
    run_cases([build(flow_config(200, 10, "lammps"))])
    print(f"warm-up (kernel load or compile): {time.process_time() - t0:.2f} s CPU")
    have_lammps = lammps_module() is not None
    rows = []
    scenes = [] if args.no_slit else [("LJ slit lj/cut", n) for n in args.atoms]
    if args.flow:
        scenes.append(("flow walls LJ fluid", args.atoms[0]))
    for name, n_req in scenes:
        wb, lmp = [], []
        for _ in range(args.repeat):
            if name.startswith("LJ slit"):
                x, v, lo, hi = slit(n_req)
                n = len(x)
                case = build_case(config_from_dict(slit_config(x, v, lo, hi, args.steps)))
                wb.append(wallbatch_seconds(case))
                if have_lammps:
                    lmp.append(run_lammps(x, v, lo, hi, args.steps)[0])
            else:
                case = build(flow_config(n_req, args.steps, "lammps"))
                n = case.natoms
                wb.append(wallbatch_seconds(case))
                if have_lammps:
                    lmp.append(lammps_run(case, args.steps)[0])
        ratio = np.median(np.array(lmp) / np.array(wb)) if lmp else float("nan")
        rows.append((name, n, np.median(wb), np.median(lmp) if lmp else float("nan"), ratio))
    print(f"{'scene':<22} {'N':>6} {'steps':>6} {'wb s':>7} {'LAMMPS s':>9} {'wb Matom-steps/s':>17} {'vs LAMMPS':>9}")
    for name, n, w, l, r in rows:
        print(f"{name:<22} {n:>6} {args.steps:>6} {w:>7.2f} {l:>9.2f} {n * args.steps / w / 1e6:>17.3f} {r:>8.2f}x")


if __name__ == "__main__":
    main()
