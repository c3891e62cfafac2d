"""wall/lepton against the built-in style it spells out: the lj93 gas slit of the suite with its
two lj93 faces written as the expression eps*(2/15*(sig/r)^9-(sig/r)^3).

    python benchmarks/lepton.py [--n 100000] [--steps 300] [--markdown FILE]

Rows (one process; wall-clock seconds of the engine run of one case):
  * built-in lj93, compiled path (its kernel loaded from numba's on-disk cache beforehand);
  * wall/lepton, compiled path: the kernel generated from the expression and inlined in the chunk
    kernel (WALLBATCH_LEPTON_COMPILED=always); compiled the first time on a machine, then loaded
    from the disk cache: timed apart (a short run before the timed one);
  * both on the NumPy path (WALLBATCH_NUMBA=0 equivalent: the engine without its fast path).

`vs built-in` is the built-in compiled time over the row's time (1 = as fast).
"""

from __future__ import annotations

import argparse
import copy
import os
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from common import gas_slit  # noqa: E402
from common import time_engine as run  # noqa: E402

from wallbatch.engine import compiled  # noqa: E402

EXPR = "eps*(2/15*(sig/r)^9-(sig/r)^3)"


def lepton_scene(cfg: dict) -> dict:
    out = copy.deepcopy(cfg)
    wall = out["walls"]["w"]
    for face in ("zlo", "zhi"):
        f = wall[face]
        wall[face] = {"coord": f["coord"], "cutoff": f["cutoff"], "expression": EXPR,
                      "params": {"eps": f["epsilon"], "sig": f["sigma"]}}
    wall["style"] = "lepton"
    out["name"] += "-lepton"
    return out


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--n", type=int, default=100_000)
    ap.add_argument("--steps", type=int, default=300)
    ap.add_argument("--markdown", type=Path)
    args = ap.parse_args()
    os.environ["WALLBATCH_LEPTON_COMPILED"] = "always"
    base = gas_slit(args.n, "lj93", steps=args.steps, thermo=args.steps)
    lep = lepton_scene(base)
    short = copy.deepcopy(base)
    short["run"] = {"steps": 5, "thermo": 5}
    run(short, False)  # load the built-in kernel from the on-disk cache
    t0 = time.perf_counter()
    run(lepton_scene(short), False)  # generate and compile (or load from the disk cache) the lepton chunk kernel
    compile_s = time.perf_counter() - t0
    rows = []
    t_builtin, e = run(base, False)
    assert e.fast is not None and e.fast.compiled_chunks > 0
    rows.append(("lj93 built-in", "compiled", t_builtin))
    t, e = run(lep, False)
    assert e.fast is not None and e.fast.compiled_chunks > 0 and e.fast.fallbacks == 0
    rows.append(("lj93 as wall/lepton", "compiled", t))
    rows.append(("lj93 built-in", "numpy", run(base, True)[0]))
    rows.append(("lj93 as wall/lepton", "numpy", run(lep, True)[0]))
    atom_steps = args.n * args.steps
    lines = [f"gas slit, N = {args.n}, {args.steps} steps ({atom_steps:.2g} atom-steps); lepton "
             f"kernel (compiled once per machine, then loaded): {compile_s:.1f} s; numba {compiled.enabled()}",
             "", "| wall | path | seconds | ns/atom-step | vs built-in |", "| --- | --- | --- | --- | --- |"]
    for name, path, secs in rows:
        lines.append(f"| {name} | {path} | {secs:.2f} | {secs / atom_steps * 1e9:.1f} | {t_builtin / secs:.2f} |")
    text = "\n".join(lines)
    print(text)
    if args.markdown:
        args.markdown.write_text(text + "\n")


if __name__ == "__main__":
    main()
