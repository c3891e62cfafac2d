"""Benchmark suite: each scene in wallbatch and, when the `lammps` module is installed, in LAMMPS,
in one process and one run; prints a table (scene, N, steps, seconds, atom-steps/s, speed ratio).

    python benchmarks/suite.py [--atom-steps 5e7] [--markdown FILE] [--clock wall|cpu] [--numpy] [--cold-cache]

Scenes (ideal gases have no pair forces):
  * the 27-case lj93 sweep (sweeps/lj93-epsilon-sigma-cutoff.yaml, N = 1000, 10000 steps) end to
    end: wallbatch's `run_plan` building the cases and writing its NetCDF (the compiled kernel is
    loaded, or with --cold-cache compiled, inside this timing) against LAMMPS running the same 27
    cases one after the other from this process (instance, atoms, fixes, run, close for each);
    library imports (lammps; scipy, xarray, dask, netCDF4) are done before the clocks start;
  * a gas slit with lj93, reflect, harmonic and colloid walls, N = 1e3, 1e4, 1e5, steps such that
    N x steps ~ --atom-steps (wallbatch: the engine run of the case; LAMMPS: its `run` command);
  * the lj93 gas slit, N = 1e4, with fix dt/reset every step (compare with the row without);
  * an LJ fluid slit (pair lj/cut), N = 4000 (n/a where wallbatch refuses pair forces);
  * the A/B table (`--ab`, or `--only ab` for it alone): ideal gases in a wall/region lj93 sphere
    cavity and cylinder and between four wall/flow walls, N = 1e3 and 1e4, N x steps ~
    --ab-atom-steps, each run by wallbatch compiled, by wallbatch's NumPy path (WALLBATCH_NUMBA=0,
    same process, same run) and by LAMMPS with its default settings (neighbor check yes).

`speed` is wallbatch atom-steps/s over LAMMPS atom-steps/s (> 1: wallbatch is faster). The machine
is shared and noisy: compare numbers of one run. --numpy runs wallbatch's NumPy path.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time

import numpy as np
from pathlib import Path

if "--cold-cache" in sys.argv:  # before numba is imported: compile the kernels from scratch
    os.environ["NUMBA_CACHE_DIR"] = tempfile.mkdtemp(prefix="wb_numba_")
if "--numpy" in sys.argv:
    os.environ["WALLBATCH_NUMBA"] = "0"

sys.path.insert(0, str(Path(__file__).resolve().parent))

import common  # noqa: E402
from common import (build, flow_gas, fmt, gas_slit, lammps_module, lammps_run, lj_slit, numba_state,  # noqa: E402
                    region_gas, time_wallbatch, with_dt_reset)

from wallbatch.batch.runner import build_cases, run_plan  # noqa: E402
from wallbatch.config.sweep import load_plan  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
SWEEP = ROOT / "sweeps" / "lj93-epsilon-sigma-cutoff.yaml"


def preload_libraries() -> None:
    """Import the libraries a run uses lazily (scipy.spatial for atom placement; xarray's dask probe
    and netCDF4 when writing), as `import lammps` is done for LAMMPS: library imports are not timed.
    numba's kernel load (or, with --cold-cache, compilation) still counts in the first row."""
    import importlib

    for name in ("scipy.spatial", "netCDF4", "xarray", "dask", "dask.array", "distributed"):
        try:
            importlib.import_module(name)
        except ImportError:
            pass


def sweep_row(steps: int, use_lammps: bool) -> dict:
    """The 27-case lj93 sweep end to end, both codes."""
    plan = load_plan(SWEEP, [f"run.steps={steps}", "atoms.0.create.random.count=1000",
                             "atoms.0.create.random.overlap=0.5", "run.thermo=1000"])
    cases, errors = build_cases(plan)
    assert not errors, errors
    atom_steps = sum(c.natoms for c in cases) * steps
    with tempfile.TemporaryDirectory() as tmp:
        t0 = common.CLOCK()
        ds = run_plan(plan, Path(tmp) / "sweep.nc", progress=False)
        wb = common.CLOCK() - t0
    ok = int((ds.status == "ok").sum())
    lmp = None
    if use_lammps:
        t0 = common.CLOCK()
        for c in cases:
            lammps_run(c)
        lmp = common.CLOCK() - t0
    return {"scene": f"lj93 sweep, {len(cases)} cases, end to end ({ok} ok)", "N": 1000, "steps": steps,
            "atom_steps": atom_steps, "wb": wb, "lmp": lmp}


def scene_row(name: str, cfg: dict, use_lammps: bool) -> dict:
    """One case: wallbatch engine run, LAMMPS `run` command."""
    try:
        case = build(cfg)
    except Exception as exc:  # noqa: BLE001 - e.g. pair forces "not supported yet"
        return {"scene": name, "N": None, "steps": cfg["run"]["steps"], "atom_steps": None, "wb": None,
                "lmp": None, "note": str(exc).splitlines()[0][:80]}
    atom_steps = case.natoms * case.steps
    wb, res = time_wallbatch(case)
    row = {"scene": name, "N": case.natoms, "steps": case.steps, "atom_steps": atom_steps, "wb": wb, "lmp": None}
    if res.status != "ok":
        row["note"] = "wallbatch: " + res.error[:80]
    if use_lammps:
        row["lmp"] = lammps_run(case)[0]
    return row


def ab_row(name: str, cfg: dict, use_lammps: bool) -> dict:
    """One case run compiled, then on the NumPy path, then in LAMMPS (interleaved in one process)."""
    case = build(cfg)
    row = {"scene": name, "N": case.natoms, "steps": case.steps, "atom_steps": case.natoms * case.steps}
    saved = os.environ.get("WALLBATCH_NUMBA")
    try:
        os.environ["WALLBATCH_NUMBA"] = "1"
        time_wallbatch(build(dict(cfg, run={**cfg["run"], "steps": 10})))  # kernel load, not timed
        row["wb"], res = time_wallbatch(case)
        os.environ["WALLBATCH_NUMBA"] = "0"
        row["np"], res_np = time_wallbatch(case)
    finally:
        if saved is None:
            os.environ.pop("WALLBATCH_NUMBA", None)
        else:
            os.environ["WALLBATCH_NUMBA"] = saved
    notes = [f"{tag}: {r.error[:60]}" for tag, r in (("numba", res), ("numpy", res_np)) if r.status != "ok"]
    if res.status == "ok" == res_np.status:
        ke, ke_np = res.data["ke"], res_np.data["ke"]
        row["dke"] = float(np.max(np.abs(ke - ke_np)) / np.max(np.abs(ke_np)))
    row["note"] = "; ".join(notes)
    row["lmp"] = lammps_run(case)[0] if use_lammps else None
    return row


def ab_table(rows: list[dict], markdown: bool) -> str:
    """scene, N, steps, seconds (numba, NumPy, LAMMPS), speed vs LAMMPS (atom-steps/s ratio) of the
    compiled and NumPy paths, gain numba/NumPy, max relative ke difference numba vs NumPy."""
    head = ["scene", "N", "steps", "numba s", "NumPy s", "LAMMPS s", "numba/LAMMPS", "NumPy/LAMMPS",
            "numba/NumPy", "ke diff"]
    lines = []
    if markdown:
        lines += ["| " + " | ".join(head) + " |", "|" + " --- |" * len(head)]
    else:
        lines.append(f"{head[0]:<34} {'N':>6} {'steps':>6} {'numba s':>8} {'NumPy s':>8} {'LMP s':>8} "
                     f"{'nb/LMP':>7} {'np/LMP':>7} {'nb/np':>6} {'ke diff':>8}")
    for r in rows:
        lmp = r.get("lmp")
        cells = [r["scene"] + (f" ({r['note']})" if r.get("note") else ""), str(r["N"]), str(r["steps"]),
                 fmt(r["wb"], ".2f"), fmt(r["np"], ".2f"), fmt(lmp, ".2f"),
                 fmt(lmp / r["wb"] if lmp else None, ".2f"), fmt(lmp / r["np"] if lmp else None, ".2f"),
                 fmt(r["np"] / r["wb"], ".1f"), fmt(r.get("dke"), ".1e")]
        if markdown:
            lines.append("| " + " | ".join(cells) + " |")
        else:
            lines.append(f"{cells[0]:<34} {cells[1]:>6} {cells[2]:>6} {cells[3]:>8} {cells[4]:>8} {cells[5]:>8} "
                         f"{cells[6]:>7} {cells[7]:>7} {cells[8]:>6} {cells[9]:>8}")
    return "\n".join(lines)


def ab_rows(atom_steps: float, use_lammps: bool) -> list[dict]:
    """The A/B rows: region walls (sphere cavity, cylinder) and flow walls, N = 1e3 and 1e4."""
    rows = []
    print(ab_table([], False), flush=True)
    for name, make in (("wall/region lj93 sphere cavity", lambda n, st: region_gas(n, "sphere", steps=st,
                                                                                    thermo=max(1, st // 10))),
                       ("wall/region lj93 cylinder", lambda n, st: region_gas(n, "cylinder", steps=st,
                                                                               thermo=max(1, st // 10))),
                       ("wall/flow ideal gas (4 walls)", lambda n, st: flow_gas(n, steps=st, thermo=max(1, st // 10)))):
        for n in (1000, 10000):
            steps = max(100, int(atom_steps // n))
            rows.append(ab_row(name, make(n, steps), use_lammps))
            print(ab_table(rows[-1:], False).splitlines()[-1], flush=True)
    return rows


def table(rows: list[dict], markdown: bool) -> str:
    head = ["scene", "N", "steps", "wallbatch s", "wallbatch atom-steps/s", "LAMMPS s", "LAMMPS atom-steps/s",
            "speed wallbatch/LAMMPS"]
    lines = []
    if markdown:
        lines += ["| " + " | ".join(head) + " |", "|" + " --- |" * len(head)]
    else:
        lines.append(f"{head[0]:<48} {'N':>7} {'steps':>6} {'wb s':>8} {'wb a-s/s':>10} {'LMP s':>8} "
                     f"{'LMP a-s/s':>10} {'speed':>7}")
    for r in rows:
        a = r["atom_steps"]
        wb_rate = a / r["wb"] if a and r["wb"] else None
        lmp_rate = a / r["lmp"] if a and r["lmp"] else None
        speed = r["lmp"] / r["wb"] if r["wb"] and r["lmp"] else None
        cells = [r["scene"] + (f" ({r['note']})" if r.get("note") else ""), fmt(r["N"], "d") if r["N"] else "n/a",
                 str(r["steps"]), fmt(r["wb"], ".2f"), fmt(wb_rate, ".3g"), fmt(r["lmp"], ".2f"),
                 fmt(lmp_rate, ".3g"), fmt(speed, ".2f")]
        if markdown:
            lines.append("| " + " | ".join(cells) + " |")
        else:
            lines.append(f"{cells[0]:<48} {cells[1]:>7} {cells[2]:>6} {cells[3]:>8} {cells[4]:>10} {cells[5]:>8} "
                         f"{cells[6]:>10} {cells[7]:>7}")
    return "\n".join(lines)


def targets(rows: list[dict]) -> list[str]:
    """The issue's targets, met or not, from this run's rows."""
    out = []

    def line(what: str, value: float | None, goal: str, met: bool | None) -> None:
        state = "n/a" if value is None else ("met" if met else "NOT met")
        out.append(f"- {what}: {fmt(value, '.2f')} ({goal}): {state}")

    sweep = next((r for r in rows if r["scene"].startswith("lj93 sweep")), None)
    if sweep:
        v = sweep["wb"] / sweep["lmp"] if sweep["lmp"] else None
        line("27-case lj93 sweep end to end, time wallbatch/LAMMPS", v, "target <= 0.5", v is not None and v <= 0.5)
    big = max((r for r in rows if r["scene"] == "gas slit lj93"), key=lambda r: r["N"] or 0, default=None)
    if big:
        v = big["lmp"] / big["wb"] if big["lmp"] else None
        line(f"gas slit lj93 N = {big['N']}, atom-steps/s wallbatch/LAMMPS", v, "target >= 1", v is not None and v >= 1)
    lj = next((r for r in rows if r["scene"].startswith("LJ slit")), None)
    if lj:
        v = lj["lmp"] / lj["wb"] if lj["lmp"] and lj["wb"] else None
        line("LJ slit N = 4000, atom-steps/s wallbatch/LAMMPS", v, "target >= 0.5", v is not None and v >= 0.5)
    dtr = next((r for r in rows if r["scene"].startswith("gas slit lj93 + dt_reset")), None)
    if dtr:
        plain = next((r for r in rows if r["scene"] == "gas slit lj93" and r["N"] == dtr["N"]), None)
        v = dtr["wb"] / plain["wb"] - 1.0 if plain else None
        line(f"dt_reset overhead at N = {dtr['N']} (wallbatch, time with / without - 1)", v, "target <= 0.25",
             v is not None and v <= 0.25)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--atom-steps", type=float, default=5e7, help="N x steps of each gas-slit scene")
    ap.add_argument("--sweep-steps", type=int, default=10000)
    ap.add_argument("--sizes", default="1000,10000,100000")
    ap.add_argument("--lj-steps", type=int, default=1000)
    ap.add_argument("--markdown", help="also write the table (markdown) to this file")
    ap.add_argument("--numpy", action="store_true", help="wallbatch's NumPy path (WALLBATCH_NUMBA=0)")
    ap.add_argument("--cold-cache", action="store_true", help="compile numba kernels from scratch (empty cache)")
    ap.add_argument("--no-lammps", action="store_true")
    ap.add_argument("--clock", choices=("wall", "cpu"), default="wall",
                    help="wall time, or CPU time of this process (steadier on a shared machine)")
    ap.add_argument("--ab", action="store_true", help="also the A/B table (compiled vs NumPy vs LAMMPS)")
    ap.add_argument("--only", choices=("ab",), help="run only the A/B table")
    ap.add_argument("--ab-atom-steps", type=float, default=1e7, help="N x steps of each A/B scene")
    args = ap.parse_args()
    common.set_clock(args.clock)
    use_lammps = not args.no_lammps and lammps_module() is not None
    sizes = [int(float(s)) for s in args.sizes.split(",")]
    started = time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime())

    preload_libraries()
    import platform

    if args.only == "ab":
        ab = ab_rows(args.ab_atom_steps, use_lammps)
        load = ", ".join(f"{x:.1f}" for x in os.getloadavg())
        md = "\n".join([f"Run {started}, LAMMPS: {'yes' if use_lammps else 'not installed'}, {platform.machine()} "
                        f"{os.cpu_count()} cores (load average at the end {load}), one process, one measurement "
                        f"per cell, {args.clock} clock.", "", ab_table(ab, True)])
        print()
        print(md)
        if args.markdown:
            Path(args.markdown).write_text(md + "\n")
        return
    rows = [sweep_row(args.sweep_steps, use_lammps)]  # first: the kernel load/compile counts here
    print(table(rows, False), flush=True)
    for walls in ("lj93", "reflect", "harmonic", "colloid"):
        for n in sizes:
            steps = max(100, int(args.atom_steps // n))
            rows.append(scene_row(f"gas slit {walls}", gas_slit(n, walls, steps=steps, thermo=max(1, steps // 10)),
                                  use_lammps))
            print(table(rows[-1:], False).splitlines()[-1], flush=True)
    n = 10000 if 10000 in sizes else sizes[0]
    steps = max(100, int(args.atom_steps // n))
    rows.append(scene_row("gas slit lj93 + dt_reset", with_dt_reset(gas_slit(n, "lj93", steps=steps,
                                                                              thermo=max(1, steps // 10))), use_lammps))
    rows.append(scene_row("LJ slit (pair lj/cut)", lj_slit(4000, steps=args.lj_steps, thermo=max(1, args.lj_steps // 10)),
                          use_lammps))
    print(table(rows[-2:], False).splitlines()[-2:][0])
    print(table(rows[-1:], False).splitlines()[-1])
    ab = ab_rows(args.ab_atom_steps, use_lammps) if args.ab else []

    load = ", ".join(f"{x:.1f}" for x in os.getloadavg())
    header = (f"Run {started}, wallbatch path: {numba_state()}, LAMMPS: {'yes' if use_lammps else 'not installed'}, "
              f"{platform.machine()} {os.cpu_count()} cores (load average at the end {load}), one process, "
              f"one measurement per cell, {args.clock} clock{', numba cache cold' if args.cold_cache else ''}.")
    md = "\n".join([header, "", table(rows, True), "", "Targets:", *targets(rows)]
                   + (["", "A/B (compiled, NumPy path, LAMMPS defaults):", "", ab_table(ab, True)] if ab else []))
    print()
    print(md)
    if args.markdown:
        Path(args.markdown).write_text(md + "\n")


if __name__ == "__main__":
    main()
