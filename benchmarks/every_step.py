"""Sampling every step: every scene kind at thermo 1 against LAMMPS (thermo 1 too), one case of
N = 1000 atoms each.

    flock /tmp/wb-cpu.lock python benchmarks/every_step.py [--only NAME[,NAME...]] [--src DIR] [--steps-scale 1.0]
                                                           [--thermo 1]

Each row is benchmarks/suite.py's `speed` on a benchmarks/common.py scene with `thermo: 1`:
wallbatch's `Engine([case]).run()` timed after a short warm-up run (kernels loaded), against
LAMMPS's `run` of the same exported case (serial, its default neighbor settings), one after the
other in this process. ratio = LAMMPS seconds / wallbatch seconds (> 1: wallbatch is faster); the
target is ratio >= 1 for every row. `sampled in kernel` says whether the compiled path recorded the
samples inside its kernel (one call for many samples) or went one sample at a time (a chunk per
step and NumPy outputs). `--src DIR` imports wallbatch from DIR (another checkout's src, for a
before/after comparison in the same way). Compare ratios within one run; the load average is
printed before and after.
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent

N = 1000


def scenes(common: object, scale: float, thermo: int = 1) -> dict:
    """name -> config (thermo 1, or `thermo`) of every scene kind."""
    c = common
    s2 = max(10, int(2000 * scale))
    s1 = max(10, int(1000 * scale))
    return {
        "flat gas lj93": lambda: c.gas_slit(N, "lj93", steps=s2, thermo=thermo),
        "region sphere": lambda: c.region_gas(N, "sphere", steps=s2, thermo=thermo),
        "region cylinder": lambda: c.region_gas(N, "cylinder", steps=s2, thermo=thermo),
        "flow gas": lambda: c.flow_gas(N, steps=s2, thermo=thermo),
        "nvt": lambda: c.thermostat_slit(N, "nvt", steps=s2, thermo=thermo),
        "langevin": lambda: c.thermostat_slit(N, "langevin", steps=s2, thermo=thermo),
        "2d": lambda: c.gas_2d(N, steps=s2, thermo=thermo),
        "table": lambda: c.table_slit(N, steps=s2, thermo=thermo),
        "dt_reset": lambda: c.with_dt_reset(c.gas_slit(N, "lj93", steps=s2, thermo=thermo)),
        "lepton": lambda: c.lepton_slit(N, steps=s2, thermo=thermo),
        "stochastic": lambda: c.stochastic_slit(N, steps=s2, thermo=thermo),
        "ellipsoids ees": lambda: c.ellipsoid_slit(N, steps=s1, thermo=thermo),
        "region/ees sphere": lambda: c.region_ees(N, steps=s1, thermo=thermo),
        "lj liquid (pair)": lambda: c.lj_fcc_slit(N, steps=s1, thermo=thermo),
        "flow lj liquid (pair)": lambda: c.flow_lj(N, steps=s1, thermo=thermo),
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--only", default="", help="comma-separated row names")
    ap.add_argument("--src", default=str(HERE.parent / "src"), help="the wallbatch package's src directory")
    ap.add_argument("--steps-scale", type=float, default=1.0, help="multiplies every row's steps")
    ap.add_argument("--thermo", type=int, default=1, help="steps per sample (1: the panel's; 100 for comparison)")
    args = ap.parse_args()
    os.environ.setdefault("WALLBATCH_THREADS", "1")  # serial, like LAMMPS
    sys.path.insert(0, str(Path(args.src).resolve()))
    sys.path.insert(1, str(HERE))
    import common  # noqa: PLC0415 - after sys.path is set
    import suite  # noqa: PLC0415
    import wallbatch  # noqa: PLC0415
    from wallbatch.engine.engine import Engine  # noqa: PLC0415

    rows = scenes(common, args.steps_scale, args.thermo)
    only = [x.strip() for x in args.only.split(",") if x.strip()]
    print(f"wallbatch from {Path(wallbatch.__file__).parent}; load average {os.getloadavg()}", flush=True)
    print(f"{'scene':18s} {'steps':>6s} {'wallbatch':>10s} {'LAMMPS':>9s} {'ratio':>6s} {'met':>4s}  "
          f"sampled in kernel, path", flush=True)
    met = total = 0
    for name, make in rows.items():
        if only and name not in only:
            continue
        cfg = make()
        r = suite.speed(name, cfg)
        eng = Engine([common.build(suite._short(cfg))])  # how this scene samples (a short run, untimed)
        eng.run()
        calls = getattr(eng.fast, "sampled_calls", 0) if eng.fast is not None else 0
        ratio = r.get("ratio")
        ok = ratio is not None and ratio >= 1.0
        met += ok
        total += 1
        print(f"{name:18s} {r.get('steps', 0):6d} {r.get('wb_s', float('nan')):9.3f}s {r.get('lmp_s', float('nan')):8.3f}s "
              f"{(ratio or float('nan')):6.2f} {'yes' if ok else 'no':>4s}  {'yes' if calls else 'no'}, {r.get('path')}"
              f"{' ' + r['why'] if r.get('why') else ''}", flush=True)
    print(f"{met} of {total} rows at >= 1x LAMMPS; load average {os.getloadavg()}", flush=True)


if __name__ == "__main__":
    main()
