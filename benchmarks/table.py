"""wall/table against LAMMPS fix wall/table and against the built-in style it tabulates: the lj93
gas slit of the suite with both faces read from a table of lj93 (eps 1, sigma 1, 0.3 <= r <= 3,
2000 points, resampled onto N = 2000), linear and spline.

    python benchmarks/table.py [--n 100000] [--steps 300] [--markdown FILE]

Rows (one process; seconds of the run of one case, the same initial state everywhere):
  * built-in lj93, compiled path (its kernel loaded from numba's on-disk cache beforehand);
  * wall/table linear / spline, compiled path (default settings): the scene kernel with the
    tables as its data (no per-table compile); loaded, or compiled once per kind of scene, by a
    short run first, timed apart (`kernel`);
  * the same on the NumPy path;
  * LAMMPS fix wall/table with the same table file, tabstyle and N (seconds of its `run`).

`vs LAMMPS` is the LAMMPS time over the row's time (> 1: wallbatch faster).
"""

from __future__ import annotations

import argparse
import copy
import os
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from common import build, gas_slit, lammps_module, lammps_run  # noqa: E402
from common import time_engine as run  # noqa: E402

from wallbatch.engine import compiled, threads  # noqa: E402
from wallbatch.styles import STYLES  # noqa: E402
from wallbatch.styles.table import tabulate, write_table  # noqa: E402

N_TABLE = 2000


def table_scene(cfg: dict, path: str, tabstyle: str) -> dict:
    out = copy.deepcopy(cfg)
    wall = out["walls"]["w"]
    for face in ("zlo", "zhi"):
        wall[face] = {"coord": wall[face]["coord"], "file": path, "keyword": "LJ93", "cutoff": 2.5}
    wall.update(style="table", tabstyle=tabstyle, N=N_TABLE)
    out["name"] += f"-table-{tabstyle}"
    return out


def lammps_table(cfg: dict, path: str, tabstyle: str) -> float:
    """Seconds of LAMMPS's run of the built-in scene with its lj93 fix replaced by wall/table."""
    case = build(cfg)
    lo, hi = float(case.box_lo[2]), float(case.box_hi[2])
    line = (f"fix w all wall/table {tabstyle} {N_TABLE} zlo {lo!r} {path} LJ93 2.5 zhi {hi!r} {path} LJ93 2.5 "
            "units box")
    import common  # noqa: PLC0415 - the module whose lammps_run reads lammps_commands

    original = common.lammps_commands
    common.lammps_commands = lambda c: [line if cmd.startswith("fix w all wall/lj93") else cmd for cmd in original(c)]
    try:
        seconds, thermo = lammps_run(case)
    finally:
        common.lammps_commands = original
    assert any(k.startswith("f_w") for k in thermo)
    return seconds


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--n", type=int, default=100_000)
    ap.add_argument("--steps", type=int, default=300)
    ap.add_argument("--markdown", type=Path)
    args = ap.parse_args()
    tmp = tempfile.mkdtemp(prefix="wb_table_bench_")
    path = os.path.join(tmp, "lj93.table")
    r, e, f = tabulate(lambda r: STYLES["lj93"].energy_force(r, {"epsilon": 1.0, "sigma": 1.0}), 0.3, 3.0, N_TABLE)
    write_table(path, "LJ93", r, e, f)
    base = gas_slit(args.n, "lj93", steps=args.steps, thermo=args.steps)
    short = copy.deepcopy(base)
    short["run"] = {"steps": 5, "thermo": 5}
    run(short, False)  # load the built-in kernel from the on-disk cache
    t_builtin, e = run(base, False)
    assert e.fast is not None and e.fast.compiled_chunks > 0
    rows = [("lj93 built-in", "compiled", t_builtin, None)]
    kernel = {}
    for tabstyle in ("linear", "spline"):
        t0 = time.perf_counter()
        run(table_scene(short, path, tabstyle), False)  # compile (first time) or load the table kernel
        kernel[tabstyle] = time.perf_counter() - t0
        t_lmp = lammps_table(base, path, tabstyle) if lammps_module() is not None else None
        t, e = run(table_scene(base, path, tabstyle), False)
        assert e.fast is not None and e.fast.compiled_chunks > 0 and e.fast.fallbacks == 0
        rows.append((f"lj93 as wall/table {tabstyle}", "compiled", t, t_lmp))
        rows.append((f"lj93 as wall/table {tabstyle}", "numpy", run(table_scene(base, path, tabstyle), True)[0], t_lmp))
        if t_lmp is not None:
            rows.append((f"LAMMPS fix wall/table {tabstyle}", "lammps", t_lmp, t_lmp))
    atom_steps = args.n * args.steps
    lines = [f"gas slit, N = {args.n}, {args.steps} steps ({atom_steps:.2g} atom-steps), table of {N_TABLE} points; "
             f"kernel compile or load before the timed runs: "
             + ", ".join(f"{k} {v:.1f} s" for k, v in kernel.items())
             + f"; numba {compiled.enabled()}, threads {threads.count()} (WALLBATCH_THREADS)",
             "", "| wall | path | seconds | ns/atom-step | vs built-in | vs LAMMPS |",
             "| --- | --- | --- | --- | --- | --- |"]
    for name, kind, secs, t_lmp in rows:
        vs = f"{t_lmp / secs:.2f}" if t_lmp is not None else "-"
        lines.append(f"| {name} | {kind} | {secs:.3f} | {secs / atom_steps * 1e9:.1f} | {t_builtin / secs:.2f} | {vs} |")
    text = "\n".join(lines)
    print(text)
    if args.markdown:
        args.markdown.write_text(text + "\n")


if __name__ == "__main__":
    main()
