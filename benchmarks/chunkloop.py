"""Thermostats, 2-D and sampling every step on the compiled chunk path, against LAMMPS.

Scenes (benchmarks/common.py gas_slit: ideal gas, lj93 walls, density 0.1, T = 1, dt 0.005):
  * thermostatted slit, N = 1e3 and 1e4: fix langevin (with nve), nvt, temp/berendsen,
    temp/rescale; LAMMPS runs the same fixes with its defaults (thermo every steps/10);
  * sampling every step: one case N = 1000 (thermo 1), and C = 100 cases N = 1000 as one batch
    (thermo 1); LAMMPS prints thermo every step with the same quantities (step time dt ke pe
    etotal and the wall fix's per-face forces).
Ratios are wallbatch atom-steps/s over LAMMPS atom-steps/s, measured in one process, interleaved.

    PYTHONPATH=src python benchmarks/chunkloop.py [--steps 2000] [--cpu]
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile

sys.path.insert(0, os.path.dirname(__file__))

import common  # noqa: E402
import numpy as np  # noqa: E402
from common import _num, build, gas_slit, lammps_commands, lammps_module, time_wallbatch  # noqa: E402

from wallbatch.engine.engine import Engine  # noqa: E402

THERMOSTATS = {  # wallbatch `fixes:` and the LAMMPS fix lines that replace `fix nve all nve`
    "langevin": ({"a": "fix a all nve", "t": "fix t all langevin 1.0 1.0 0.5 48279"},
                 ["fix nve all nve", "fix t all langevin 1.0 1.0 0.5 48279"]),
    "nvt": ({"t": "fix t all nvt temp 1.0 1.0 0.5"}, ["fix t all nvt temp 1.0 1.0 0.5"]),
    "temp/berendsen": ({"a": "fix a all nve", "t": "fix t all temp/berendsen 1.0 1.0 0.5"},
                       ["fix nve all nve", "fix t all temp/berendsen 1.0 1.0 0.5"]),
    "temp/rescale": ({"a": "fix a all nve", "t": "fix t all temp/rescale 100 1.0 1.0 0.02 0.5"},
                     ["fix nve all nve", "fix t all temp/rescale 100 1.0 1.0 0.02 0.5"]),
}


def lammps_seconds(case, fix_lines: list[str] | None = None) -> float:
    """Seconds of LAMMPS's `run` for the case, with `fix nve all nve` replaced by fix_lines."""
    lammps = lammps_module()
    with tempfile.TemporaryDirectory(prefix="wb_chunkloop_") as tmp:
        lmp = lammps.lammps(cmdargs=["-log", os.path.join(tmp, "log.lammps"), "-screen", "none", "-nocite"])
        try:
            lo, hi = case.box_lo, case.box_hi
            for c in ["units lj", "atom_style atomic", "atom_modify map array",
                      "boundary " + " ".join("p" if p else "f" for p in case.periodic),
                      "region box block " + " ".join(f"{_num(lo[d])} {_num(hi[d])}" for d in range(3)) + " units box",
                      "create_box 1 box"]:
                lmp.command(c)
            n = case.natoms
            lmp.create_atoms(n, list(range(1, n + 1)), [1] * n, case.x.ravel().tolist(), case.v.ravel().tolist())
            lmp.command(f"mass 1 {_num(case.mass[0])}")
            for c in lammps_commands(case):
                if c == "fix nve all nve" and fix_lines:
                    for line in fix_lines:
                        lmp.command(line)
                else:
                    lmp.command(c)
            t0 = common.CLOCK()
            lmp.command(f"run {int(case.steps)}")
            return common.CLOCK() - t0
        finally:
            lmp.close()


def thermostat_rows(ns: list[int], steps: int) -> list[tuple]:
    rows = []
    for n in ns:
        for name, (fixes, lines) in THERMOSTATS.items():
            cfg = dict(gas_slit(n, steps=steps, thermo=max(1, steps // 10)), fixes=fixes)
            time_wallbatch(build(dict(cfg, run={"steps": 20, "thermo": 10})))  # kernel load, not timed
            case = build(cfg)
            wb, res = time_wallbatch(case)
            assert res.status == "ok", res.error
            lmp = lammps_seconds(case, lines)
            rows.append((f"{name} slit", n, steps, wb, lmp))
    return rows


def sampling_rows(steps: int) -> list[tuple]:
    rows = []
    cfg = gas_slit(1000, steps=steps, thermo=1)
    time_wallbatch(build(dict(cfg, run={"steps": 20, "thermo": 1})))
    case = build(cfg)
    wb, res = time_wallbatch(case)
    rows.append(("lj93 slit, thermo 1, one case", 1000, steps, wb, lammps_seconds(case)))
    cases = [build(dict(cfg, seed=7 + i)) for i in range(100)]
    t0 = common.CLOCK()
    out = Engine(cases).run()
    wb100 = common.CLOCK() - t0
    assert all(r.status == "ok" for r in out)
    # per atom-step: the batch ran 100 x the atom-steps of the LAMMPS run
    rows.append(("lj93 slit, thermo 1, C = 100 batch", 1000, steps, wb100 / 100, lammps_seconds(case)))
    lang = THERMOSTATS["langevin"]
    cfg = dict(gas_slit(1000, steps=steps, thermo=1), fixes=lang[0])
    time_wallbatch(build(dict(cfg, run={"steps": 20, "thermo": 1})))
    case = build(cfg)
    wb, res = time_wallbatch(case)
    rows.append(("langevin slit, thermo 1, one case", 1000, steps, wb, lammps_seconds(case, lang[1])))
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=2000)
    ap.add_argument("--sample-steps", type=int, default=1000)
    ap.add_argument("--cpu", action="store_true", help="CPU time of this process instead of wall time")
    ap.add_argument("--only", choices=["thermostats", "sampling"], default=None)
    args = ap.parse_args()
    if args.cpu:
        common.set_clock("cpu")
    if lammps_module() is None:
        sys.exit("LAMMPS's Python module is not importable")
    rows = []
    if args.only in (None, "thermostats"):
        rows += thermostat_rows([1000, 10000], args.steps)
    if args.only in (None, "sampling"):
        rows += sampling_rows(args.sample_steps)
    print(f"{'scene':40s} {'N':>6s} {'steps':>6s} {'wallbatch s':>12s} {'LAMMPS s':>10s} {'ratio':>7s}")
    for name, n, steps, wb, lmp in rows:
        print(f"{name:40s} {n:6d} {steps:6d} {wb:12.4f} {lmp:10.4f} {lmp / wb:7.2f}x")
    print(f"(ratio = LAMMPS seconds / wallbatch seconds for the same atom-steps; load: {os.getloadavg()[0]:.2f})")
    _ = np


if __name__ == "__main__":
    main()
