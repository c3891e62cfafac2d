"""What two threads get from this machine's two cores, now: a probe for the two-core rows.

    python benchmarks/host_cores.py [--rounds 5]

A virtual machine's two "cores" may be two physical cores or the two hyperthreads of one core
(the host decides, and may change it from minute to minute). The difference shows in code that
keeps a core's vector units busy, as wallbatch's compiled kernels do: on two separate cores two
threads do twice the work of one; on one core's two hyperthreads they share its vector units and
do little more than one. Code that waits on the latency of each operation (a dependency chain)
gets twice the work either way. Two loops, each in one thread and then in two threads at once,
each thread on its own data:

* vector: y[i] = y[i] * a + b over 2,048 doubles (16 KB, in the L1 cache) many times (vector
  FMA throughput, no memory traffic);
* chain: x = x * a + b, each step waiting for the last (latency-bound scalar work).

Each capacity is the work of two threads per second over that of one (2.00: two free cores; about
1.0-1.3 for the vector loop: two hyperthreads of one core, or a core shared with another guest).
wallbatch's two-core rows in suite.py (threads, --jobs 2) need the vector kind of capacity; the
figure is a snapshot (a few seconds) of a host that can change from one minute to the next.

    python benchmarks/host_cores.py --pair 100000

also measures the same capacity for wallbatch's own pair kernels (`pair_probe`): two copies of the
force pass (and of the list build) of pair_threads.py's LJ liquid at once, each on its own arrays,
against one alone. Nothing is shared and nobody waits, so no split of that work over two threads
can do better on this host at that moment: the ceiling of the threads-ljcut rows.
"""

from __future__ import annotations

import argparse
import statistics
import threading
import time

import numpy as np

try:
    from numba import njit
except ImportError:  # pragma: no cover - numba is a dependency of wallbatch
    njit = None

VECTOR_ATOMS = 2048  # doubles per thread (16 KB): in L1
VECTOR_PASSES = 500_000  # ~0.1 s on one thread
CHAIN_STEPS = 50_000_000  # ~0.1 s on one thread


if njit is not None:
    @njit(nogil=True, cache=True)
    def _vector(y: np.ndarray, passes: int) -> float:
        """`passes` passes of y = y * a + b (vectorised: the core's FMA throughput)."""
        for _ in range(passes):
            for i in range(y.shape[0]):
                y[i] = y[i] * 0.999999 + 1e-7
        return y[0]

    @njit(nogil=True, cache=True)
    def _chain(n: int) -> float:
        """n steps of x = x * a + b, each waiting for the last (the FMA's latency)."""
        x = 1.0
        for _ in range(n):
            x = x * 0.999999 + 1e-7
        return x


def _timed(fn, args: tuple, out: list[float], k: int) -> None:  # noqa: ANN001
    t0 = time.perf_counter()
    fn(*args)
    out[k] = time.perf_counter() - t0


def _capacity(fn, args_of) -> float:  # noqa: ANN001
    """Work per second of two threads at once over one thread's (each thread its own data)."""
    out = [0.0, 0.0]
    _timed(fn, args_of(0), out, 0)
    one = out[0]
    threads = [threading.Thread(target=_timed, args=(fn, args_of(k), out, k)) for k in range(2)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    return 2.0 * one / max(out)


def probe(rounds: int = 3) -> dict[str, list[float]]:
    """Each loop's two-thread capacity (`_capacity`), `rounds` times in turns: {"vector": [...],
    "chain": [...]}; empty lists without numba."""
    if njit is None:
        return {"vector": [], "chain": []}
    data = [np.ones(VECTOR_ATOMS), np.ones(VECTOR_ATOMS)]
    _vector(data[0], 1)  # compile (or load from numba's cache) before timing
    _chain(1)
    got: dict[str, list[float]] = {"vector": [], "chain": []}
    for _ in range(rounds):
        got["vector"].append(_capacity(_vector, lambda k: (data[k], VECTOR_PASSES)))
        got["chain"].append(_capacity(_chain, lambda k: (CHAIN_STEPS,)))
    return got


def pair_probe(n: int = 100_000, rounds: int = 3) -> dict[str, list[float]]:
    """`_capacity` of wallbatch's pair kernels (pair_compiled's `forces_case` and `build_case`) on
    pair_threads.py's LJ liquid slit of about n atoms, `rounds` times in turns: {"pair forces":
    [...], "pair build": [...]}; each thread runs its own copy (positions, list, forces). Raises if
    a copy run beside the other gives other forces or another list than one run alone (then the
    copies were not independent). Empty lists without numba."""
    from wallbatch.engine import pair_compiled as pc  # noqa: PLC0415 - wallbatch only for this probe

    if njit is None or not pc.enabled():
        return {"pair forces": [], "pair build": []}
    import pair_threads  # noqa: PLC0415 - benchmarks/pair_threads.py: the scene

    pair, x0, reach, lj, room = pair_threads.liquid_pair(n)
    copies = [(x0.copy(), np.empty(len(x0), np.int32), np.empty(len(x0) + 1, np.int64), np.empty(room, np.int32),
               np.zeros_like(x0)) for _ in range(2)]

    def build(x, owner, first, neigh, f) -> None:  # noqa: ANN001
        if pc.build_case(x, pair.box_lo, pair.length, pair.periodic, reach, owner, first, neigh) < 0:
            raise RuntimeError("pair_probe: the list outgrew its room")

    def forces(x, owner, first, neigh, f) -> None:  # noqa: ANN001
        f[:] = 0.0
        pc.forces_case(x, f, owner, first, neigh, *lj, False)

    got: dict[str, list[float]] = {"pair forces": [], "pair build": []}
    for fn in (build, forces):  # (the list first: the force pass reads it)
        for k in range(2):
            fn(*copies[k])
    alone = [a.copy() for a in copies[0][1:]]
    for _ in range(rounds):
        got["pair build"].append(_capacity(build, lambda k: copies[k]))
        got["pair forces"].append(_capacity(forces, lambda k: copies[k]))
    for k in range(2):
        m = int(copies[k][2][-1])
        if not (np.array_equal(copies[k][1], alone[0]) and np.array_equal(copies[k][2], alone[1])
                and np.array_equal(copies[k][3][:m], alone[2][:m]) and np.array_equal(copies[k][4], alone[3])):
            raise RuntimeError("pair_probe: a copy run beside the other differs from one run alone")
    return got


def pair_summary(got: dict[str, list[float]]) -> str:
    """One line: the pair kernels' median capacities (`pair_probe`) and their ranges."""
    if not got["pair forces"]:
        return "pair kernels' probe not run (no numba)"
    parts = [f"{name} {statistics.median(v):.2f}x ({min(v):.2f}-{max(v):.2f})" for name, v in got.items()]
    return "two copies of wallbatch's pair kernels at once vs one alone: " + ", ".join(parts)


def medians(got: dict[str, list[float]]) -> tuple[float, float]:
    """(vector, chain): each loop's median capacity over the rounds of a `probe`."""
    return statistics.median(got["vector"]), statistics.median(got["chain"])


def summary(got: dict[str, list[float]]) -> str:
    """One line: each loop's median capacity and its range over the rounds."""
    if not got["vector"]:
        return "two-core probe not run (no numba)"
    parts = []
    for name in ("vector", "chain"):
        v = got[name]
        parts.append(f"{name} {statistics.median(v):.2f}x ({min(v):.2f}-{max(v):.2f})")
    return "two threads vs one on this host: " + ", ".join(parts) + " (2.00: two free cores)"


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=5, help="measurements of each loop, in turns")
    ap.add_argument("--pair", type=int, default=0, metavar="N",
                    help="also probe wallbatch's pair kernels on the LJ liquid of about N atoms (pair_probe)")
    args = ap.parse_args(argv)
    if args.rounds < 1:
        ap.error(f"--rounds {args.rounds}: give a whole number of measurements, 1 or more")
    if args.pair < 0:
        ap.error(f"--pair {args.pair}: give a number of atoms (about 100000 for the threads-ljcut rows' scene)")
    print(summary(probe(args.rounds)))
    if args.pair:
        print(pair_summary(pair_probe(args.pair, args.rounds)))


if __name__ == "__main__":
    main()
