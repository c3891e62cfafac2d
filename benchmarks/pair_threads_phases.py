"""Where the time of one large lj/cut case goes on one thread and on two: per-phase seconds of each
thread over the timed `Engine([case]).run()` of benchmarks/pair_threads.py's scene.

    WALLBATCH_THREADS=2 python benchmarks/pair_threads_phases.py [--atoms 100000] [--steps 50]

Wraps pair_compiled's phases (list build parts, force parts, sampled pass, tails, step starts,
split set-up) with timers recording (thread, phase, start, end); prints per thread the phases'
totals and counts, and the main thread's waits at the meetings. Timers add a little overhead:
compare phases, not the run's total, with pair_threads.py.

    python benchmarks/pair_threads_phases.py --serial [--rounds 5]

runs the two-thread split with its parts one after the other on one thread (the split's own cost,
without two threads slowing each other down), in turns with the one-thread fused chunk, in one
process: the CPU seconds of each (medians over the rounds) and their ratio, then the phases of the
last serial run.
"""

from __future__ import annotations

import argparse
import collections
import sys
import threading
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

import common  # noqa: E402

from wallbatch.engine import backend  # noqa: E402
from wallbatch.engine import pair_compiled as pc  # noqa: E402
from wallbatch.engine.engine import Engine  # noqa: E402

EVENTS: list[tuple[str, str, float, float, float]] = []


def timed(name: str, fn):  # noqa: ANN001, ANN201
    def wrapper(*a, **k):  # noqa: ANN002, ANN003, ANN202
        t0, c0 = time.perf_counter(), time.thread_time()
        try:
            return fn(*a, **k)
        finally:
            EVENTS.append((threading.current_thread().name, name, t0, time.perf_counter(), time.thread_time() - c0))
    return wrapper


def install() -> None:
    for name in ("_scan", "_bin", "bin_threaded", "_bin_cells", "_bin_scatter", "_join", "_touch", "_mixed", "_first_marks", "_row_sums", "forces_part", "forces_case", "_pre_step",
                 "_replay_atoms", "build_threaded", "_rebalance", "_chunk_threaded"):
        if hasattr(pc, name):
            setattr(pc, name, timed(name, getattr(pc, name)))
    for cls, meth in ((pc.RowSplit, "__init__"), (pc.Crew, "__call__")):
        setattr(cls, meth, timed(f"{cls.__name__}.{meth}", getattr(cls, meth)))
    orig = pc._chunk_steps

    def steps(kernel, args, parts, crew, *more):  # noqa: ANN001, ANN002, ANN202
        return orig(TimedKernel("kernel(tail)", kernel), args, parts, crew, *more)
    pc._chunk_steps = steps


class TimedKernel:
    """A compiled kernel timed as `name`, whose calls go to its resolved entry point as the
    kernel's own would (`backend.resolved`): a plain wrapper would be typed by numba at every call
    (~2 ms for the pair chunk kernel's arguments), which is not the run's cost."""

    def __init__(self, name: str, kernel) -> None:  # noqa: ANN001
        self.name, self.kernel, self.py_func = name, kernel, kernel.py_func

    def __call__(self, *args):  # noqa: ANN002, ANN204
        return timed(self.name, self.kernel)(*args)

    def resolved(self, args: tuple):  # noqa: ANN201
        return timed(self.name, backend.resolved(self.kernel, args))


def serial_against_one(n: int, steps: int, rounds: int) -> None:
    """CPU seconds of the one-thread chunk and of the two-part split run serially (`--serial`), in
    turns; leaves the serial split in place for the phases that follow."""
    import statistics  # noqa: PLC0415

    from wallbatch.engine import threads  # noqa: PLC0415

    in_threads, crew = threads._in_threads, pc.Crew.__call__
    serial = {"Crew": lambda self, calls: [c() for c in calls], "in": lambda calls: [c() for c in calls]}
    cpu: dict[str, list[float]] = {"one thread": [], "split, serial": []}
    for _ in range(rounds):
        for way in cpu:
            split = way != "one thread"
            threads.count = (lambda: 2) if split else (lambda: 1)
            pc.Crew.__call__ = serial["Crew"] if split else crew
            threads._in_threads = serial["in"] if split else in_threads
            case = common.build(common.lj_fcc_slit(n, steps=steps, thermo=max(1, steps // 10)))
            eng = Engine([case])
            c0 = time.process_time()
            eng.run()
            cpu[way].append(time.process_time() - c0)
            if split and eng.fast.threaded_chunks == 0:
                raise SystemExit("the split did not run: is the case large enough for two parts?")
    one, two = (statistics.median(v) for v in cpu.values())
    print(f"CPU seconds, medians of {rounds}: one thread {one:.3f}, split run serially {two:.3f} "
          f"({two / one:.2f}x the work)")
    threads.count = lambda: 2  # the phases below: the serial split


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--atoms", type=int, default=100000)
    ap.add_argument("--steps", type=int, default=50)
    ap.add_argument("--no-busy-skip", action="store_true", help="thread every chunk (THREAD_MIN_USE = 0)")
    ap.add_argument("--serial", action="store_true",
                    help="the split's parts one after the other on one thread, against the one-thread chunk")
    ap.add_argument("--rounds", type=int, default=5, help="with --serial: runs of each, in turns")
    args = ap.parse_args()
    if args.no_busy_skip or args.serial:
        pc.THREAD_MIN_USE = 0.0
    n, steps = args.atoms, args.steps
    Engine([common.build(common.lj_fcc_slit(n, steps=10, thermo=10))]).run()
    case = common.build(common.lj_fcc_slit(n, steps=steps, thermo=max(1, steps // 10)))
    if args.serial:
        serial_against_one(n, steps, args.rounds)
        case = common.build(common.lj_fcc_slit(n, steps=steps, thermo=max(1, steps // 10)))
    install()
    EVENTS.clear()
    t0, c0 = time.perf_counter(), time.process_time()
    eng = Engine([case])
    eng.run()
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    print(f"N {case.natoms}, {steps} steps: wall {wall:.3f} s, CPU {cpu:.3f} s")
    print(f"chunks over threads {eng.fast.threaded_chunks}")
    tot: dict[tuple[str, str], list[float]] = collections.defaultdict(lambda: [0.0, 0, 0.0])
    for th, name, a, b, c in EVENTS:
        tot[th, name][0] += b - a
        tot[th, name][1] += 1
        tot[th, name][2] += c
    for th in sorted({k[0] for k in tot}):
        print(f"thread {th}:")
        for (t, name), (sec, cnt, c) in sorted(tot.items(), key=lambda kv: -kv[1][0]):
            if t == th:
                print(f"  {name:22s} {sec * 1e3:8.1f} ms (CPU {c * 1e3:7.1f})  {cnt:5d} calls  "
                      f"{sec / cnt * 1e3:7.2f} ms/call")


if __name__ == "__main__":
    main()
