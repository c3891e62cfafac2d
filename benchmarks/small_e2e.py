"""Helper `small` (issue 15): the start-up and the end-to-end time of one small `wallbatch run`
(benchmarks/suite.py's end-to-end-small scene: lj93 gas slit, N = 1000, 2000 steps), split into
interpreter start, imports and the whole run; best of `--repeat` new processes, wall and CPU
(user + sys) seconds. The CPU time is steadier than the wall time on a loaded machine.

    PYTHONPATH=$PWD/src python benchmarks/small_e2e.py [--repeat 7] [--src /work/main/src --src $PWD/src]

With --src (one or more source trees), the wallbatch rows are run once per tree (PYTHONPATH set to
it), interleaved with the others, so trees are compared within one run.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))
from common import gas_slit  # noqa: E402


def timed(cmd: list[str], cwd: Path, src: Path | None = None) -> tuple[float, float]:
    """(wall, cpu) seconds of one child process (with PYTHONPATH=src if given)."""
    env = dict(os.environ)
    env.pop("PYTHONDONTWRITEBYTECODE", None)
    if src is not None:
        env["PYTHONPATH"] = str(src)
    t0 = time.perf_counter()
    proc = subprocess.Popen(cmd, cwd=cwd, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - t0
    if os.waitstatus_to_exitcode(status) != 0:
        raise RuntimeError(f"{cmd} failed: {proc.stderr.read().decode()}")
    return wall, usage.ru_utime + usage.ru_stime


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeat", type=int, default=7)
    ap.add_argument("--src", type=Path, action="append", default=None, help="source tree(s) to compare")
    args = ap.parse_args()
    import yaml

    py = sys.executable
    rows = {
        "python -c pass": [py, "-c", "pass"],
        "import numpy, pydantic, typer": [py, "-c", "import numpy, pydantic, typer"],
        "import wallbatch.cli": [py, "-c", "import wallbatch.cli"],
        "wallbatch run --help": [py, "-m", "wallbatch.cli", "run", "--help"],
        "wallbatch run (N=1000, 2000 steps)": [py, "-m", "wallbatch.cli", "run", "small.yaml", "-o", "small.nc",
                                               "--force", "-j", "1"],
    }
    srcs: dict[str, Path | None] = {"": None}
    if args.src:
        srcs = {f" [{i}]": p.resolve() for i, p in enumerate(args.src)}
        for i, p in enumerate(args.src):
            print(f"[{i}] {p.resolve()}")
    jobs = [(name + tag, cmd, src) for name, cmd in rows.items() for tag, src in srcs.items()
            if name.startswith(("import wallbatch", "wallbatch")) or tag == next(iter(srcs))]
    with tempfile.TemporaryDirectory(prefix="wb_small_") as tmp:
        work = Path(tmp)
        (work / "small.yaml").write_text(yaml.safe_dump(gas_slit(1000, "lj93", steps=2000, thermo=100),
                                                        sort_keys=False))
        for _, cmd, src in jobs:
            timed(cmd, work, src)  # warm
        best = {name: [float("inf"), float("inf")] for name, _, _ in jobs}
        for _ in range(args.repeat):  # interleaved: the load drifts alike for every row
            for name, cmd, src in jobs:
                w, c = timed(cmd, work, src)
                best[name] = [min(best[name][0], w), min(best[name][1], c)]
    print(f"{'':44s} {'wall s':>8s} {'cpu s':>8s}   (best of {args.repeat}; load {os.getloadavg()[0]:.1f})")
    for name, (w, c) in best.items():
        print(f"{name:44s} {w:8.3f} {c:8.3f}")


if __name__ == "__main__":
    main()
