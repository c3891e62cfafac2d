"""One large lj/cut case on one thread and on two: wallbatch (WALLBATCH_THREADS) and LAMMPS
(serial `lmp` and `mpiexec -np 2 lmp`), in one run.

    python benchmarks/pair_threads.py [--atoms 32000 100000] [--atom-steps 5e6] [--repeat 2] [--no-lammps]
                                      [--fix langevin|nvt|berendsen] [--variant reflect|reflect-stats|dt-reset]

Scene: the LJ liquid slit of benchmarks/pair_lj.py (fcc at rho 0.8 melted at T = 2, lj/cut 2.5
shifted, neighbor skin 0.3 checked every step, lj93 walls at the z edges, dt 0.005), thermo
every steps / 10; with `--fix`, held at T = 1 by that thermostat (benchmarks/common.py's
THERMOSTATS: its sums over all atoms run between the threads' parts of each step); with
`--variant`, wall/reflect faces in place of the lj93 walls (with reflect statistics too) or fix
dt/reset (VARIANTS: the last two keep a case over threads on the per-step path). Each
wallbatch run is a new process (WALLBATCH_THREADS=k, NUMBA_NUM_THREADS=k)
that warms its kernels on a 10-step run, then times `Engine([case]).run()`; the one- and
two-thread runs alternate (`--repeat` rounds, best of each), and the final kinetic and potential
energy of both must be the same bits. Each run also reports its CPU seconds, its page faults, the
CPU seconds the rest of the machine used meanwhile and the seconds the hypervisor stole from the
machine's virtual cores (both from /proc/stat: another process on a core, or a core not run for a
few milliseconds, slows the threaded run most, the other thread waiting at the next meeting;
after a starved chunk the engine runs 4 chunks on one thread); `--show-runs` prints every run. LAMMPS runs the scene exported by wallbatch
(`wallbatch export-lammps`, LAMMPS's default neighbor settings: every 1 delay 0 check yes), serial
and with `mpiexec -np 2`, its "Loop time" timed. The machine may be shared: compare within one run.
"""

from __future__ import annotations

import argparse
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

CHILD = """
import os, resource, sys, time
sys.path.insert(0, {here!r})
import common
from wallbatch.engine.engine import Engine
import pair_threads
n, steps, fix, variant = {n}, {steps}, {fix!r}, {variant!r}
warm = pair_threads.scene(n, 10, fix, variant)
warm["run"]["thermo"] = 10
Engine([common.build(warm)]).run()
case = common.build(pair_threads.scene(n, steps, fix, variant))
def busy():  # (CPU seconds the machine's processes used, seconds the hypervisor stole) so far
    try:
        v = [int(t) for t in open("/proc/stat").readline().split()[1:]]
    except OSError:
        return 0.0, 0.0
    steal = v[7] if len(v) > 7 else 0
    tck = os.sysconf("SC_CLK_TCK")
    return (sum(v) - v[3] - v[4] - steal) / tck, steal / tck
(b0, s0), r0 = busy(), resource.getrusage(resource.RUSAGE_SELF)
t0 = time.perf_counter()
eng = Engine([case])
res = eng.run()[0]
sec = time.perf_counter() - t0
(b1, s1), r1 = busy(), resource.getrusage(resource.RUSAGE_SELF)
cpu = r1.ru_utime + r1.ru_stime - r0.ru_utime - r0.ru_stime
fast = eng.fast
print("RESULT", sec, res.status, case.natoms, getattr(fast, "threaded_chunks", 0),
      float(res.data["ke"][-1]).hex(), float(res.data["pe"][-1]).hex(), cpu, max(0.0, b1 - b0 - cpu),
      r1.ru_minflt - r0.ru_minflt, s1 - s0)
"""


VARIANTS = {  # --variant: what a pair case over threads runs otherwise (reflect-stats, dt-reset: per-step path)
    "reflect": "wall/reflect faces in place of the lj93 walls (split like them)",
    "reflect-stats": "wall/reflect faces with reflect_count and reflect_impulse output (per-step path on threads)",
    "dt-reset": "fix dt/reset every 10 steps, xmax 0.05, tmax 0.005 (per-step path on threads)",
}


def scene(n: int, steps: int, fix: str | None = None, variant: str | None = None) -> dict:
    """The benchmark's scene: the LJ liquid slit of n atoms, with the thermostat `fix` if given,
    changed as `variant` (VARIANTS) says."""
    import common  # noqa: PLC0415

    cfg = common.lj_fcc_slit(n, steps=steps, thermo=max(1, steps // 10))
    if variant in ("reflect", "reflect-stats"):
        cfg["walls"] = {"pore": {"style": "reflect", "units": "box", "zlo": "EDGE", "zhi": "EDGE"}}
        if variant == "reflect-stats":
            cfg["output"] = {"thermo": ["reflect_count", "reflect_impulse"]}
    elif variant == "dt-reset":
        cfg["dt_reset"] = {"every": 10, "tmin": None, "tmax": 0.005, "xmax": 0.05, "units": "box"}
    return common.with_fixes(cfg, common.THERMOSTATS[fix], fix) if fix else cfg


def liquid_pair(n: int) -> tuple:
    """The inputs of wallbatch's pair kernels on `scene`'s liquid of about n atoms, melted (10
    steps) and with the kernels compiled or loaded: (the engine's pair, positions (N, 3), the list
    reach cutoff + skin, `forces_case`'s parameters (24 eps, 4 eps, sigma^2, rc^2, offset 0,
    length, periodic), a list capacity with room to spare)."""
    import numpy as np  # noqa: PLC0415
    from wallbatch.engine.engine import Engine  # noqa: PLC0415

    import common  # noqa: PLC0415

    eng = Engine([common.build(scene(n, 10))])
    eng.run()
    pair = eng.pair
    x = np.ascontiguousarray(eng.state.x[0])
    eps, sig, rc = float(pair.epsilon[0]), float(pair.sigma[0]), float(pair.cutoff[0])
    lj = (24.0 * eps, 4.0 * eps, sig * sig, rc * rc, 0.0, pair.length, pair.periodic)
    return pair, x, float(pair.cutoff[0] + pair.skin), lj, 2 * len(pair._neigh[0]) + 16 * len(x)


def wallbatch_run(n: int, steps: int, threads: int, fix: str | None = None, variant: str | None = None
                  ) -> tuple[float, int, int, str, float, float, int, float]:
    """(seconds, atoms, chunks run over threads, final ke and pe as hex, CPU seconds, other
    processes' CPU seconds meanwhile, page faults, seconds the hypervisor stole from the machine's
    cores meanwhile: /proc/stat's steal, time a virtual core was ready but not run) of one child
    process (`fix`: a thermostat; `variant`: VARIANTS)."""
    env = dict(os.environ, WALLBATCH_THREADS=str(threads), NUMBA_NUM_THREADS=str(threads))
    child = CHILD.format(here=str(HERE), n=n, steps=steps, fix=fix, variant=variant)
    out = subprocess.run([sys.executable, "-c", child], env=env,
                         capture_output=True, text=True, check=True).stdout
    f = next(ln.split()[1:] for ln in out.splitlines() if ln.startswith("RESULT"))
    if f[1] != "ok":
        raise RuntimeError(f"wallbatch run: {f[1]}")
    return float(f[0]), int(f[2]), int(f[3]), f"{f[4]} {f[5]}", float(f[6]), float(f[7]), int(f[8]), float(f[9])


def lmp_binary() -> str | None:
    own = Path(sys.prefix) / "bin" / "lmp"
    return str(own) if own.exists() else shutil.which("lmp")


def lammps_runs(n: int, steps: int, repeat: int, fix: str | None = None, variant: str | None = None
                ) -> dict[int, float]:
    """Best "Loop time" [s] of LAMMPS serial (1) and `mpiexec -np 2` (2) on the exported scene."""
    import common  # noqa: PLC0415

    lmp = lmp_binary()
    if lmp is None:
        return {}
    mpiexec = Path(sys.prefix) / "bin" / "mpiexec"
    cfg = scene(n, steps, fix, variant)
    best: dict[int, float] = {}
    with tempfile.TemporaryDirectory(prefix="wb_pairthr_") as tmp:
        setup, nrun, _ = common.lammps_script(cfg, None, tmp)
        (Path(tmp) / "in.bench").write_text("\n".join(setup + [f"run {nrun}"]) + "\n")
        cmds = {1: [lmp]}
        if mpiexec.exists():
            cmds[2] = [str(mpiexec), "-np", "2", lmp]
        for _ in range(repeat):
            for k, cmd in cmds.items():
                subprocess.run(cmd + ["-in", "in.bench", "-log", "log.bench", "-screen", "none", "-nocite"],
                               cwd=tmp, check=True, capture_output=True)
                log = (Path(tmp) / "log.bench").read_text()
                sec = float(re.search(r"Loop time of ([0-9.eE+-]+)", log).group(1))
                best[k] = min(best.get(k, sec), sec)
    return best


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--atoms", type=int, nargs="+", default=[32000, 100000])
    ap.add_argument("--atom-steps", type=float, default=5e6, help="atoms x steps of each run")
    ap.add_argument("--repeat", type=int, default=2, help="rounds of 1 and 2 threads, interleaved (best of each)")
    ap.add_argument("--no-lammps", action="store_true")
    ap.add_argument("--show-runs", action="store_true", help="print every run (seconds, CPU, others' CPU, faults)")
    ap.add_argument("--fix", choices=["langevin", "nvt", "berendsen"],
                    help="hold the liquid at T = 1 by this thermostat")
    ap.add_argument("--variant", choices=sorted(VARIANTS), help="; ".join(f"{k}: {v}" for k, v in VARIANTS.items()))
    args = ap.parse_args()
    load = os.getloadavg()[0]
    print(f"# {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}, {os.cpu_count()} cores, load {load:.2f}"
          + (f"; fix {args.fix}" if args.fix else "") + (f"; {VARIANTS[args.variant]}" if args.variant else ""))
    print(f"| N | steps | wb 1 thread [s] | wb 2 threads [s] | 2/1 | same bits | LAMMPS serial [s] | LAMMPS np 2 [s] "
          f"| LAMMPS 2/1 | wb 2 thr vs LAMMPS np 2 |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    for n in args.atoms:
        steps = max(20, int(args.atom_steps // n))
        best: dict[int, float] = {}
        bits: dict[int, set[str]] = {1: set(), 2: set()}
        atoms = threaded = 0
        runs: list[str] = []
        for _ in range(args.repeat):
            for k in (1, 2):
                sec, atoms, thr, b, cpu, others, faults, steal = wallbatch_run(n, steps, k, args.fix, args.variant)
                best[k] = min(best.get(k, sec), sec)
                bits[k].add(b)
                threaded = max(threaded, thr) if k == 2 else threaded
                runs.append(f"  N {atoms}, {k} thread{'s' if k > 1 else ''}: {sec:.3f} s, CPU {cpu:.3f} s, "
                            f"other processes' CPU {others:.2f} s, stolen by the hypervisor {steal:.2f} s, "
                            f"{faults} page faults"
                            + (f", {thr} chunks over threads" if k > 1 else ""))
        same = "yes" if len(bits[1] | bits[2]) == 1 else "NO"
        lmp = {} if args.no_lammps else lammps_runs(n, steps, args.repeat, args.fix, args.variant)
        l1, l2 = lmp.get(1), lmp.get(2)
        f = lambda v, spec: "n/a" if v is None else format(v, spec)  # noqa: E731
        vs = None if l2 is None else l2 / best[2]
        print(f"| {atoms} | {steps} | {best[1]:.2f} | {best[2]:.2f} | {best[1] / best[2]:.2f}x | {same} "
              f"| {f(l1, '.2f')} | {f(l2, '.2f')} | {f(None if l1 is None or l2 is None else l1 / l2, '.2f')}"
              f"{'' if l2 is None else 'x'} | {f(vs, '.2f')}{'' if vs is None else 'x'} |")
        if args.show_runs:
            print("\n".join(runs))
        if threaded == 0:
            print(f"  (N = {atoms}: the two-thread run did not split its chunks)")


if __name__ == "__main__":
    main()
