"""First-run compile of a flat-wall scene, in CPU seconds (less noisy than wall clock on a shared
machine): `wallbatch run` of the suite's small lj93 gas slit (N = 1000, 2000 steps) on the
compiled path with an empty NUMBA_CACHE_DIR (cold), then again with the same cache (warm).
Prints cold, warm and cold - warm, user + system CPU seconds of the child and wall seconds.
`--nvt`: the same scene with a fix nvt thermostat (the kernel with the fixes' code)."""

from __future__ import annotations

import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))
from suite import SMALL, WB, gas_slit, write_yaml  # noqa: E402


def timed(cmd: list[str], cwd: Path, env: dict) -> tuple[float, float, str]:
    """(CPU seconds, wall seconds, output) of one child process."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    out = subprocess.run(cmd, cwd=cwd, env=env, capture_output=True, text=True, check=True)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return cpu, wall, out.stdout + out.stderr


def main() -> None:
    cfg = gas_slit(SMALL["n"], "lj93", steps=SMALL["steps"], thermo=100)
    if "--nvt" in sys.argv[1:]:
        cfg["fixes"] = {"t": "fix t all nvt temp 1.0 1.0 0.1"}
    with tempfile.TemporaryDirectory(prefix="wb_compile_") as tmp:
        work = Path(tmp)
        write_yaml(work / "small.yaml", cfg)
        env = dict(os.environ, NUMBA_CACHE_DIR=str(work / "numba-cache"), WALLBATCH_NUMBA="1")
        env.pop("PYTHONDONTWRITEBYTECODE", None)
        cmd = WB + ["run", "small.yaml", "-o", "small.nc", "--force", "-j", "1"]
        cold = timed(cmd, work, env)
        warm = min(timed(cmd, work, env) for _ in range(2))
    print(f"cold {cold[0]:.1f} s CPU ({cold[1]:.1f} s wall); warm {warm[0]:.1f} s CPU ({warm[1]:.1f} s wall); "
          f"compile {cold[0] - warm[0]:.1f} s CPU ({cold[1] - warm[1]:.1f} s wall)")
    print([line for line in cold[2].splitlines() if "compil" in line.lower()])


if __name__ == "__main__":
    main()
