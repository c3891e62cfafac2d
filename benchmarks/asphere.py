"""Ellipsoids between wall/ees walls (configs/ellipsoids-ees-slit.yaml scaled): wallbatch's
compiled path (engine/asphere_compiled.py), its NumPy path and LAMMPS, in one process and run.

    python benchmarks/asphere.py [--sizes 1000 10000] [--atom-steps 2e7] [--clock wall|cpu] [--no-lammps]

The scene is the shipped config's: prolate ellipsoids (semi-axes 1, 0.5, 0.5, mass 1, random
orientations, L = (0, 0, 0.3), T = 1) in a slab x, y periodic, z in [0, 8], started in z in
[2, 6] at the config's number density (30 per 10 x 10 of area), between two wall/ees faces
(epsilon 2, sigma 1, cut-off 7.99) at the z edges; x and y grow with N. `--region` adds the
same slit with the walls as a wall/region/ees block instead of the flat faces.

LAMMPS runs the case exported by `wallbatch export-lammps` (the same atoms, bit for bit) with
its defaults: the export's `neigh_modify ... check no` line (it makes LAMMPS wrap every step, as
wallbatch does, for sample-by-sample validation) is dropped, so LAMMPS uses `check yes`. Timed:
wallbatch's engine run of the case (setup, steps, samples; the kernel is loaded by a short run
first), LAMMPS's `run` command. Ratios are atom-steps/s wallbatch / LAMMPS (> 1: faster).
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

import common  # noqa: E402
from common import fmt, lammps_module  # noqa: E402

from wallbatch.config.models import config_from_dict  # noqa: E402
from wallbatch.engine.engine import Engine  # noqa: E402
from wallbatch.lammps.export import export_case, lammps_ready, write_export  # noqa: E402
from wallbatch.scene.build import build_case  # noqa: E402


def ellipsoid_slit(n: int, *, steps: int = 1000, thermo: int = 100, region: bool = False, seed: int = 7) -> dict:
    """configs/ellipsoids-ees-slit.yaml with n ellipsoids at the same areal density (30 per 100)."""
    side = 10.0 * math.sqrt(n / 30.0)
    cfg = {"name": f"ellipsoids-ees-{n}", "units": "lj", "seed": seed,
           "box": {"lo": [0, 0, 0], "hi": [side, side, 8], "boundary": ["p", "p", "f"]},
           "regions": {"middle": {"style": "block", "lo": [0, 0, 2], "hi": [side, side, 6], "units": "box"}},
           "atoms": [{"group": "rods", "create": {"random": {"count": n, "region": "middle", "overlap": 1.5}},
                      "mass": 1.0, "shape": [1.0, 0.5, 0.5], "orientation": "random",
                      "angmom": {"values": [0.0, 0.0, 0.3]}, "velocity": {"temperature": 1.0}}],
           "timestep": 0.002, "run": {"steps": steps, "thermo": thermo},
           "output": {"thermo": ["step", "time", "dt", "temp", "ke", "pe", "etot", "erot"]}}
    if region:
        cfg["regions"]["slit"] = {"style": "block", "lo": [-10, -10, 0], "hi": [side + 10, side + 10, 8], "units": "box"}
        cfg["walls"] = {"slit": {"style": "region/ees", "region": "slit", "epsilon": 2.0, "sigma": 1.0,
                                 "cutoff": 3.0, "energy": True}}
    else:
        cfg["walls"] = {"slit": {"style": "ees", "units": "box", "energy": True,
                                 "zlo": ["EDGE", 2.0, 1.0, 7.99], "zhi": ["EDGE", 2.0, 1.0, 7.99]}}
    return cfg


def run_wallbatch(cfg: dict, numba: bool) -> tuple[float, dict, Engine]:
    """Seconds of the engine run (after a 10-step warm-up run that loads the kernel)."""
    os.environ["WALLBATCH_NUMBA"] = "1" if numba else "0"
    warm = build_case(config_from_dict(dict(cfg, run={"steps": 10, "thermo": 10})))
    Engine([warm]).run()
    case = build_case(config_from_dict(cfg))
    eng = Engine([case])
    t0 = common.CLOCK()
    res = eng.run()[0]
    sec = common.CLOCK() - t0
    assert res.status == "ok", res.error
    return sec, res.data, eng


def run_lammps(cfg: dict) -> tuple[float, dict]:
    """Seconds of LAMMPS's `run` on the exported case, with LAMMPS's default neighbor settings."""
    lammps = lammps_module()
    conf, notes = lammps_ready(config_from_dict(cfg))
    case = build_case(conf)
    exp = export_case(conf, case, notes=notes)
    with tempfile.TemporaryDirectory(prefix="wb_asphere_") as tmp:
        write_export(exp, tmp)
        log = os.path.join(tmp, "log.lammps")
        cwd = os.getcwd()
        os.chdir(tmp)
        lmp = lammps.lammps(cmdargs=["-log", log, "-screen", "none", "-nocite"])
        try:
            seconds = 0.0
            for line in exp.script.splitlines():
                line = line.strip()
                if not line or line.startswith("#") or line.startswith("neigh_modify"):
                    continue
                if line.startswith("run"):
                    t0 = common.CLOCK()
                    lmp.command(line)
                    seconds = common.CLOCK() - t0
                else:
                    lmp.command(line)
        finally:
            lmp.close()
            os.chdir(cwd)
        with open(log, encoding="utf-8", errors="replace") as fh:
            thermo = common._thermo(fh.read())
    return seconds, thermo


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sizes", type=int, nargs="+", default=[1000, 10000])
    ap.add_argument("--atom-steps", type=float, default=2e7)
    ap.add_argument("--clock", choices=("wall", "cpu"), default="cpu")
    ap.add_argument("--no-lammps", action="store_true")
    ap.add_argument("--no-numpy", action="store_true", help="skip the NumPy path")
    ap.add_argument("--region", action="store_true", help="wall/region/ees block instead of flat wall/ees")
    args = ap.parse_args()
    common.set_clock(args.clock)
    use_lammps = not args.no_lammps and lammps_module() is not None
    print(f"benchmarks/asphere.py {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}, {os.uname().machine} "
          f"{os.cpu_count()} cores, load average {', '.join(f'{x:.1f}' for x in os.getloadavg())}, "
          f"clock {args.clock}, scene {'wall/region/ees block' if args.region else 'wall/ees slit'}")
    head = f"{'N':>6} {'steps':>6} {'numba s':>8} {'NumPy s':>8} {'LMP s':>8} {'nb/LMP':>7} {'np/LMP':>7} " \
           f"{'chunks':>6} {'etot diff nb-np':>15} {'etot diff nb-LMP':>16}"
    print(head, flush=True)
    for n in args.sizes:
        steps = max(100, int(args.atom_steps // n))
        cfg = ellipsoid_slit(n, steps=steps, thermo=max(1, steps // 10), region=args.region)
        t_nb, d_nb, eng = run_wallbatch(cfg, True)
        chunks = eng.fast.compiled_chunks if eng.fast is not None else 0
        t_np, d_np = (None, None) if args.no_numpy else run_wallbatch(cfg, False)[:2]
        t_lmp, d_lmp = run_lammps(cfg) if use_lammps else (None, None)
        scale = np.max(np.abs(d_nb["etot"]))
        dnp = None if d_np is None else float(np.max(np.abs(d_nb["etot"] - d_np["etot"])) / scale)
        dlmp = None
        if d_lmp is not None and "v_wb_etot" in d_lmp and len(d_lmp["v_wb_etot"]) == len(d_nb["etot"]):
            dlmp = float(np.max(np.abs(d_nb["etot"] - d_lmp["v_wb_etot"])) / scale)
        print(f"{n:>6} {steps:>6} {fmt(t_nb, '.2f'):>8} {fmt(t_np, '.2f'):>8} {fmt(t_lmp, '.2f'):>8} "
              f"{fmt(t_lmp / t_nb if t_lmp else None, '.2f'):>7} "
              f"{fmt(t_lmp / t_np if t_lmp and t_np else None, '.2f'):>7} {chunks:>6} "
              f"{fmt(dnp, '.1e'):>15} {fmt(dlmp, '.1e'):>16}", flush=True)


if __name__ == "__main__":
    main()
