"""Sampled every step, the outputs loop of soft faces and wall/region fixes (engine/compiled.py
`_eloop`) runs over every atom at every step: this times the scenes that report through it (flat
lj93, wall/table linear and spline, wall/lepton with 2 parameters and with 4, its parameters as an
array, the lepton kernels forced compiled; wall/region lj93 in a sphere cavity and a cylinder) for
one or more source trees, alternating between them in fresh processes, so two versions of the
package are compared in one sitting:

    flock /tmp/wb-cpu.lock python benchmarks/face_outputs.py --src /path/a/src --src /path/b/src

Prints, per tree and scene, the best of `--repeat` runs of N = 1000 atoms, `--steps` steps at
thermo 1 (after a warm-up run that loads or compiles the kernels), in ns per atom-step, and with
`--compile` the CPU seconds of a first run with empty numba and kernel caches minus a warm run
of the same scene (the compile of its kernel; `--compile-rounds` alternations between the trees).
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
N = 1000
SCENES = ("flat lj93", "table linear", "table spline", "lepton 2 params", "lepton 4 params", "region sphere",
          "region cylinder")


def config(common: object, scene: str, steps: int) -> dict:
    """The scene's config (thermo 1)."""
    c = common
    if scene == "flat lj93":
        return c.gas_slit(N, "lj93", steps=steps, thermo=1)
    if scene.startswith("region"):
        return c.region_gas(N, scene.split()[1], steps=steps, thermo=1)
    if scene.startswith("table"):
        cfg = c.table_slit(N, steps=steps, thermo=1)
        cfg["walls"]["tab"]["tabstyle"] = scene.split()[1]
        return cfg
    cfg = c.lepton_slit(N, steps=steps, thermo=1)
    if scene == "lepton 4 params":  # lj93 plus a soft exponential: its parameters go as an array
        for face in ("zlo", "zhi"):
            f = cfg["walls"]["w"][face]
            f["expression"] = c.LEPTON_LJ93 + " + k*exp(-r/l)"
            f["params"] = {**f["params"], "k": 0.1, "l": 0.5}
    return cfg


def child(scene: str, steps: int, repeat: int) -> dict:
    """Run in a child process (wallbatch from its --src): best seconds per atom-step."""
    import common  # noqa: PLC0415 - after sys.path is set
    from wallbatch.engine.engine import Engine  # noqa: PLC0415

    Engine([common.build(config(common, scene, 20))]).run()  # warm-up: kernels loaded or compiled
    case = common.build(config(common, scene, steps))
    best = float("inf")
    path = ""
    for _ in range(repeat):
        t0 = time.perf_counter()
        eng = Engine([case])
        res = eng.run()[0]
        best = min(best, time.perf_counter() - t0)
        ok = eng.fast is not None and eng.fast.sampled_calls > 0 and eng.fast.fallbacks == 0
        path = ("compiled, sampled in the kernel" if ok else "NOT sampled in the kernel") + f", {res.status}"
    return {"ns": best / (steps * N) * 1e9, "path": path}


def run_child(src: str, args: list[str], env: dict) -> tuple[dict, float]:
    """(the child's JSON answer, its CPU seconds)."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    out = subprocess.run([sys.executable, __file__, "--child", "--src", src, *args], env=env, check=True,
                         capture_output=True, text=True)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return json.loads(out.stdout.strip().splitlines()[-1]), cpu


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--src", action="append", default=[], help="a wallbatch src directory (repeatable)")
    ap.add_argument("--only", default="", help="comma-separated scene names")
    ap.add_argument("--steps", type=int, default=10000)
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--rounds", type=int, default=2, help="alternations between the trees")
    ap.add_argument("--compile", action="store_true", help="also the cold-cache compile of each scene's kernel")
    ap.add_argument("--compile-rounds", type=int, default=1, help="alternations between the trees of those compiles")
    ap.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    ap.add_argument("--scene", default="", help=argparse.SUPPRESS)
    args = ap.parse_args()
    srcs = args.src or [str(HERE.parent / "src")]
    if args.child:
        sys.path.insert(0, str(Path(srcs[0]).resolve()))
        sys.path.insert(1, str(HERE))
        print(json.dumps(child(args.scene, args.steps, args.repeat)))
        return
    scenes = [s.strip() for s in args.only.split(",") if s.strip()] or list(SCENES)
    env = dict(os.environ, WALLBATCH_THREADS="1", WALLBATCH_LEPTON_COMPILED="always", WALLBATCH_NUMBA="1")
    print(f"load average {os.getloadavg()}", flush=True)
    caches = tempfile.TemporaryDirectory(prefix="wb_face_outputs_")  # each tree's kernels, kept over the rounds
    for scene in scenes:
        for rnd in range(args.rounds):
            for i, src in enumerate(srcs):
                tree_env = dict(env, NUMBA_CACHE_DIR=f"{caches.name}/numba{i}",
                                WALLBATCH_CACHE_DIR=f"{caches.name}/wb{i}")
                ans, _ = run_child(src, ["--scene", scene, "--steps", str(args.steps), "--repeat", str(args.repeat)],
                                   tree_env)
                print(f"{scene:16s} round {rnd}  {ans['ns']:7.2f} ns per atom-step  {ans['path']:36s} {src}",
                      flush=True)
    if args.compile:
        for scene, _rnd, src in ((s, r, t) for s in scenes for r in range(args.compile_rounds) for t in srcs):
            with tempfile.TemporaryDirectory(prefix="wb_face_outputs_") as tmp:
                cold_env = dict(env, NUMBA_CACHE_DIR=str(Path(tmp) / "numba"),
                                WALLBATCH_CACHE_DIR=str(Path(tmp) / "wb"))
                cargs = ["--scene", scene, "--steps", "20", "--repeat", "1"]
                _, cold = run_child(src, cargs, cold_env)
                _, warm = run_child(src, cargs, cold_env)
            print(f"{scene:16s} compile {cold - warm:6.1f} s CPU (cold {cold:.1f}, warm {warm:.1f})  {src}", flush=True)
    caches.cleanup()
    print(f"load average {os.getloadavg()}", flush=True)


if __name__ == "__main__":
    main()
