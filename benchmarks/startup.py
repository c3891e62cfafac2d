"""Start-up benchmark: `wallbatch run` end to end (a new process: imports, config, build, run,
NetCDF written) on a 100-atom, 100-step lj93 slit, warm (kernels already cached), against
LAMMPS's whole process (`lmp -in`) on the same scene exported by `wallbatch export-lammps`.

    python benchmarks/startup.py [--repeat 5] [--markdown results.md]

Prints one row: the median wall-clock seconds and the median CPU seconds (user + sys of the
child process, steadier on a shared machine) of each. Target: wallbatch <= 1.0 s warm.
"""

from __future__ import annotations

import argparse
import os
import platform
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

SCENE = """\
name: startup
units: lj
seed: 1
box: {lo: [0, 0, 0], hi: [10, 10, 10], boundary: [p, p, f]}
atoms:
  - group: gas
    create: {random: {count: 100}}
    mass: 1.0
    velocity: {temperature: 1.0}
walls:
  zw:
    style: lj93
    units: box
    zlo: {coord: -0.5, epsilon: 1.0, sigma: 1.0, cutoff: 2.5}
    zhi: {coord: 10.5, epsilon: 1.0, sigma: 1.0, cutoff: 2.5}
run: {steps: 100, thermo: 10}
"""


def timed(cmd: list[str], cwd: Path, env: dict | None = None) -> tuple[float, float]:
    """(wall seconds, CPU seconds user + sys) of one child process; fails loudly if it fails."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    res = subprocess.run(cmd, cwd=cwd, capture_output=True, text=True, env=env)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if res.returncode != 0:
        raise SystemExit(f"{' '.join(cmd)} failed ({res.returncode}):\n{res.stdout}\n{res.stderr}")
    return wall, (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--markdown", type=Path, help="append the row to this Markdown file")
    args = ap.parse_args()
    wb = [sys.executable, "-m", "wallbatch.cli"]
    lmp = shutil.which("lmp")
    with tempfile.TemporaryDirectory(prefix="wb_startup_") as tmp:
        work = Path(tmp)
        (work / "startup.yaml").write_text(SCENE)
        run = wb + ["run", "startup.yaml", "-o", "startup.nc", "--force", "-j", "1"]
        timed(run, work)  # warm: kernels cached, files in the page cache
        rows = [timed(run, work) for _ in range(args.repeat)]
        lrows = []
        if lmp:
            subprocess.run(wb + ["export-lammps", "startup.yaml", "-o", "lmp"], cwd=work, check=True,
                           capture_output=True)
            script = next((work / "lmp").glob("in.*")).name
            cmd = [lmp, "-in", script, "-log", "none", "-screen", "none", "-nocite"]
            timed(cmd, work / "lmp")
            lrows = [timed(cmd, work / "lmp") for _ in range(args.repeat)]
    wall = statistics.median(r[0] for r in rows)
    cpu = statistics.median(r[1] for r in rows)
    lwall = statistics.median(r[0] for r in lrows) if lrows else float("nan")
    lcpu = statistics.median(r[1] for r in lrows) if lrows else float("nan")
    load = ", ".join(f"{x:.1f}" for x in os.getloadavg())
    head = (f"startup.py {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}, {platform.machine()} "
            f"{os.cpu_count()} cores, load average {load}, median of {args.repeat}")
    row = (f"| wallbatch run, 100 atoms, 100 steps, end to end (warm) | {wall:.2f} | {cpu:.2f} | "
           f"{lwall:.2f} | {lcpu:.2f} | {'yes' if wall <= 1.0 else 'no'} |")
    table = ("| scene | wallbatch wall s | wallbatch CPU s | LAMMPS process wall s | LAMMPS CPU s | "
             "<= 1.0 s |\n| --- | --- | --- | --- | --- | --- |\n" + row)
    print(head)
    print(table)
    if args.markdown:
        with args.markdown.open("a") as fh:
            fh.write(f"\n{head}\n\n{table}\n")


if __name__ == "__main__":
    main()
