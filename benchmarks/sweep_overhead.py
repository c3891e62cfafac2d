"""What a many-case sweep of small cases pays per case besides its steps: `wallbatch run` of a
sweep of the lj93 gas slit (N = 100, 100 steps, thermo 1: 101 samples a case) end to end in a new
process, and the per-case pieces in this process: saving a case's part and reading it back
(batch/runner.py save_part, read_part), its structure key (scene/case.py structure_key: the
runner asks three times a case, a Case computes it once), building it (the key included). For
reference, the same part as the .npz archive that parts were before PART_FORMAT 3 (`np.savez`,
one zip member per array).

    python benchmarks/sweep_overhead.py [--cases 1000]

Prints a table; compare within one run (the machine is shared and noisy).
"""

from __future__ import annotations

import argparse
import copy
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from common import gas_slit  # noqa: E402
from suite import write_yaml  # noqa: E402

from wallbatch.api import load  # noqa: E402
from wallbatch.batch.runner import build_one, read_part, save_part  # noqa: E402
from wallbatch.engine.engine import run_cases  # noqa: E402
from wallbatch.scene.case import structure_key  # noqa: E402


def sweep(cases: int) -> dict:
    cfg = gas_slit(100, "lj93", steps=100, thermo=1)
    cfg["sweep"] = {"product": {"eps": {"path": ["walls.w.zlo.epsilon", "walls.w.zhi.epsilon"],
                                        "values": {"linspace": [0.5, 2.0, cases]}}}}
    return cfg


def per_call(fn, n: int) -> float:
    """Milliseconds per call of fn(i), best of three passes of n calls (i new in every pass: the
    saves write new files, as a run does, not over the last pass's)."""
    best = np.inf
    for p in range(3):
        t0 = time.perf_counter()
        for i in range(p * n, (p + 1) * n):
            fn(i)
        best = min(best, (time.perf_counter() - t0) / n * 1e3)
    return best


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", type=int, default=1000)
    args = ap.parse_args()
    rows = []
    with tempfile.TemporaryDirectory(prefix="wb_sweep_") as tmp:
        work = Path(tmp)
        write_yaml(work / "sweep.yaml", sweep(args.cases))
        cmd = [sys.executable, "-m", "wallbatch.cli", "run", "sweep.yaml", "-o", "s.nc", "--force", "-j", "1"]
        env = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
        subprocess.run(cmd, cwd=work, env=env, check=True, capture_output=True)  # warm: kernels cached
        walls = []
        for _ in range(2):
            t0 = time.perf_counter()
            subprocess.run(cmd, cwd=work, env=env, check=True, capture_output=True)
            walls.append(time.perf_counter() - t0)
        wall = min(walls)
        rows.append((f"`wallbatch run`, {args.cases} cases, end to end", f"{wall:.2f} s",
                     f"{wall / args.cases * 1e3:.2f} ms"))

        plan = load(work / "sweep.yaml")
        case, _, _ = build_one(plan.cases[0])
        res = run_cases([case])[0]  # what a part holds
        parts = work / "parts"
        n = 200
        save = per_call(lambda i: save_part(parts, f"k{i}", res), n)
        rows.append(("save a part (this format)", "", f"{save:.3f} ms"))
        rows.append(("read a part back, checked", "", f"{per_call(lambda i: read_part(parts, f'k{i}'), n):.3f} ms"))
        npz = work / "npz"
        npz.mkdir()
        old = {f"data__{k}": v for k, v in res.data.items()}

        def savez(i: int) -> None:
            np.savez(npz / f"k{i}.npz", status=np.str_(res.status), error=np.str_(res.error),
                     seconds=np.float64(res.seconds), case_key=np.str_(f"k{i}"), digest=np.str_("0" * 64), **old)

        def loadz(i: int) -> None:
            with np.load(npz / f"k{i}.npz", allow_pickle=False) as z:
                {k: z[k] for k in z.files}  # noqa: B018

        rows.append(("  for reference: the same as an .npz (np.savez)", "", f"{per_call(savez, n):.3f} ms"))
        rows.append(("  for reference: read with np.load", "", f"{per_call(loadz, n):.3f} ms"))
        rows.append(("structure key of a case, computed (a shallow copy forgets it)", "",
                     f"{per_call(lambda i: structure_key(copy.copy(case)), n):.3f} ms"))
        rows.append(("  asked again of the same case", "", f"{per_call(lambda i: structure_key(case), n):.4f} ms"))
        rows.append(("build a case from its config", "", f"{per_call(lambda i: build_one(plan.cases[i]), n):.3f} ms"))
    width = max(len(r[0]) for r in rows)
    print(f"{'what':<{width}}  {'total':>8}  {'per case':>10}")
    for what, total, each in rows:
        print(f"{what:<{width}}  {total:>8}  {each:>10}")


if __name__ == "__main__":
    main()
