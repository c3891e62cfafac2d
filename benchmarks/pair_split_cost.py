"""What splitting one case's pair work in two parts costs, the parts run one after the other on
one thread (no second core, so no contention): the force pass (`forces_threaded` against
`forces_case`) and the list build (`build_threaded` plus its `RowSplit` against `build_case`), on
benchmarks/pair_threads.py's LJ liquid slit, medians of `--rounds` in turns.

    python benchmarks/pair_split_cost.py [--atoms 100000] [--rounds 7]

Also prints how much of the split pass is logged (additions to atoms another part touches first,
replayed in list order to keep the bits of one thread) and how many rows are mixed, and checks that
the split gives the forces and list of the whole, bit for bit.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

import pair_threads  # noqa: E402

from wallbatch.engine import pair_compiled as pc  # noqa: E402


def serial(calls: list) -> list:
    """The parts one after the other on this thread (a `Crew`'s interface)."""
    return [c() for c in calls]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--atoms", type=int, default=100_000)
    ap.add_argument("--rounds", type=int, default=7)
    args = ap.parse_args()
    if not pc.enabled():
        raise SystemExit("numba is not importable: no compiled pair kernels to measure")
    pair, x, reach, lj, room = pair_threads.liquid_pair(args.atoms)
    n = len(x)
    whole = (np.empty(n, np.int32), np.empty(n + 1, np.int64), np.empty(room, np.int32))
    split = (np.empty(n, np.int32), np.empty(n + 1, np.int64), np.empty(room, np.int32))
    marks, rows = np.zeros((2, n), np.uint8), np.empty(3, np.int64)
    box = (x, pair.box_lo, pair.length, pair.periodic, reach)
    m = pc.build_case(*box, *whole)
    pc.build_threaded(*box, *split, 2, serial, marks, rows)
    parts = pc.RowSplit(*split, 2, serial, marks, rows)
    f_whole, f_split = np.zeros_like(x), np.zeros_like(x)
    t: dict[str, list[float]] = {k: [] for k in ("force pass", "force pass, split", "list build",
                                                 "list build, split", "RowSplit")}
    for _ in range(args.rounds):
        c0 = time.thread_time()
        f_whole[:] = 0.0
        pc.forces_case(x, f_whole, *whole, *lj, False)
        c1 = time.thread_time()
        f_split[:] = 0.0
        pc.forces_threaded(x, f_split, *split, parts, *lj, serial)
        c2 = time.thread_time()
        pc.build_case(*box, *whole)
        c3 = time.thread_time()
        marks[:] = 0
        pc.build_threaded(*box, *split, 2, serial, marks, rows)
        c4 = time.thread_time()
        parts = pc.RowSplit(*split, 2, serial, marks, rows, reuse=parts)
        c5 = time.thread_time()
        for k, dt in zip(t, (c1 - c0, c2 - c1, c3 - c2, c4 - c3, c5 - c4)):
            t[k].append(dt)
    same = np.array_equal(f_whole, f_split) and np.array_equal(whole[1], split[1]) and \
        np.array_equal(whole[2][:m], split[2][:m])
    med = {k: statistics.median(v) * 1e3 for k, v in t.items()}
    print(f"# N = {n}, {m:,} pairs; {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}; CPU ms, medians of "
          f"{args.rounds}; same forces and list bits: {'yes' if same else 'NO'}")
    print(f"# logged additions {int(parts.logs[-1]):,} ({parts.logs[-1] / m:.1%} of the pairs), mixed rows "
          f"{int(parts.mixed.sum()):,} ({parts.mixed.sum() / n:.1%})")
    print("| work | whole [ms] | split, parts in turn [ms] | split / whole |")
    print("| --- | --- | --- | --- |")
    print(f"| force pass | {med['force pass']:.2f} | {med['force pass, split']:.2f} | "
          f"{med['force pass, split'] / med['force pass']:.3f} |")
    print(f"| list build | {med['list build']:.2f} | {med['list build, split']:.2f} | "
          f"{med['list build, split'] / med['list build']:.3f} |")
    both = med["list build, split"] + med["RowSplit"]
    print(f"| list build + RowSplit | {med['list build']:.2f} | {both:.2f} | {both / med['list build']:.3f} |")
    if not same:
        raise SystemExit("the split differs from the whole")


if __name__ == "__main__":
    main()
