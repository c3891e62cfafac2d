"""The suite's end-to-end-small scene (lj93 gas slit, N = 1000, 2000 steps, `wallbatch run` in a
new process, warm) run from one or more source trees, interleaved, so that the trees meet the
same load: min and median wall seconds, min and median CPU seconds (user + sys, steadier on a
shared machine) and peak memory of each.

    python benchmarks/small_case.py 9 /path/to/main/src /path/to/branch/src
"""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))
from common import gas_slit  # noqa: E402 - the suite's scenes


def main(argv: list[str]) -> None:
    runs = int(argv[0]) if argv else 5
    trees = argv[1:] or [str(Path(__file__).resolve().parents[1] / "src")]
    import yaml

    cfg = gas_slit(1000, "lj93", steps=2000, thermo=100)
    stats: dict[str, tuple[list[float], list[float], list[float]]] = {t: ([], [], []) for t in trees}
    with tempfile.TemporaryDirectory(prefix="wb_small_") as tmp:
        (Path(tmp) / "small.yaml").write_text(yaml.safe_dump(cfg, sort_keys=False))
        cmd = [sys.executable, "-m", "wallbatch.cli", "run", "small.yaml", "-o", "small.nc", "--force", "-j", "1"]
        for i in range(runs + 1):  # the first round warms the page cache and the .pyc files
            for tree in trees:
                env = dict(os.environ, PYTHONPATH=tree)
                env.pop("PYTHONDONTWRITEBYTECODE", None)
                t0 = time.perf_counter()
                proc = subprocess.Popen(cmd, cwd=tmp, env=env, stdout=subprocess.DEVNULL)
                _, status, usage = os.wait4(proc.pid, 0)
                wall = time.perf_counter() - t0
                if os.waitstatus_to_exitcode(status) != 0:
                    raise SystemExit(f"{tree}: wallbatch run failed")
                if i:
                    w, c, m = stats[tree]
                    w.append(wall)
                    c.append(usage.ru_utime + usage.ru_stime)
                    m.append(usage.ru_maxrss / 1024)
    for tree, (w, c, m) in stats.items():
        w.sort()
        c.sort()
        print(f"{tree}: wall min {w[0]:.3f} s, median {w[len(w) // 2]:.3f} s; CPU min {c[0]:.3f} s, "
              f"median {c[len(c) // 2]:.3f} s; peak {max(m):.0f} MB")


if __name__ == "__main__":
    main(sys.argv[1:])
