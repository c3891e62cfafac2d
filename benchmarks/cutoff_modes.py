"""The three wall cut-off treatments side by side: error and energy drift against dt, with cost.

    python benchmarks/cutoff_modes.py [--atoms 2000] [--out benchmarks/cutoff_modes.md]

Scene: the lj93 gas slit of benchmarks/common.py (ideal gas, T = 1, rc = 2.5) with
`cutoff_mode` shift (LAMMPS), force-shift and smooth (switch_on 2.0), each run by
wallbatch.convergence.convergence over 8 time units at dt = 0.016 ... 0.001 (reference 0.0005).
Per mode and dt: seconds, atom-steps/s, the energy drift per atom and unit time, and the relative
RMS error of etot and wall_force against the reference run; then the observed orders in dt.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from common import gas_slit, numba_state  # noqa: E402

from wallbatch.convergence import convergence  # noqa: E402

MODES = (("shift", None), ("force-shift", None), ("smooth", 2.0))
DTS = [0.016, 0.008, 0.004, 0.002, 0.001, 0.0005]


def scene(n: int, mode: str, switch_on: float | None) -> dict:
    cfg = gas_slit(n, "lj93", steps=1000, thermo=100, dt=0.008)
    cfg["walls"]["w"]["cutoff_mode"] = mode
    if switch_on is not None:
        cfg["walls"]["w"]["switch_on"] = switch_on
    return cfg


def order(h: list[float], err: list[float]) -> float:
    ok = [(a, b) for a, b in zip(h, err) if b > 0 and np.isfinite(b)]
    return float(np.polyfit(np.log([a for a, _ in ok]), np.log([b for _, b in ok]), 1)[0]) if len(ok) > 1 else np.nan


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--atoms", type=int, default=2000)
    ap.add_argument("--out", default=str(Path(__file__).with_name("cutoff_modes.md")))
    args = ap.parse_args()
    rows = ["| mode | dt | steps | seconds | atom-steps/s | drift/atom/time | etot error | wall_force error |",
            "| --- | --- | --- | --- | --- | --- | --- | --- |"]
    summary = ["| mode | drift order | etot order | wall_force order | seconds at dt 0.004 |",
               "| --- | --- | --- | --- | --- |"]
    for mode, on in MODES:
        rep = convergence(scene(args.atoms, mode, on), dts=DTS)
        pts = rep.points
        for i, p in enumerate(pts):
            ref = i == len(pts) - 1
            err = ["ref" if ref else f"{p.errors[k]:.2e}" for k in ("etot", "wall_force")]
            rows.append(f"| {mode} | {p.h:g} | {p.steps} | {p.seconds:.3f} | {p.atom_steps_per_s:.3g} | "
                        f"{p.drift:.2e} | {err[0]} | {err[1]} |")
        h = [p.h for p in pts[:-1]]
        t4 = next(p.seconds for p in pts if abs(p.h - 0.004) < 1e-12)
        summary.append(f"| {mode} | {order(h, [p.drift for p in pts[:-1]]):.2f} | {rep.orders['etot']:.2f} | "
                       f"{rep.orders['wall_force']:.2f} | {t4:.3f} |")
    text = (f"# Wall cut-off treatments: lj93 gas slit, {args.atoms} atoms, rc = 2.5, 8 time units\n\n"
            f"{numba_state()}\n\n" + "\n".join(summary) + "\n\n" + "\n".join(rows) + "\n")
    print(text)
    Path(args.out).write_text(text)


if __name__ == "__main__":
    main()
