"""Both cores for one compiled chunk: the same chunk kernel run on parts of the batch in threads.

The compiled chunk kernel (engine/compiled.py) releases the GIL, so Python threads run it in
parallel. `run_kernel` calls it as the caller would, on parts that do not interact within a chunk:

- several cases: each thread takes a contiguous run of cases. Cases never interact, so every
  case's numbers are those of one call, whatever the split (any scene the kernel runs but those
  with `fixes:`, whose arrays are laid out per fix, and wall/flow or wall/reflect/stochastic,
  which run one case per call, their generators drawn from atom after atom: for these
  `compiled.FastPath._chunk` gives runs of cases to threads itself, with `split_edges` and
  `call_parts`);
- one case: contiguous runs of atoms, split at multiples of ALIGN atoms (the kernel's blocks
  stay the same blocks), OVERSPLIT runs per thread, each thread taking the next run not yet
  taken (a thread on a core slowed by other work takes fewer), when the atoms do not couple
  within a chunk: flat and
  region soft walls (tables and wall/lepton too), wall/reflect without statistics (their sums
  would add in another order), variables; not fix dt/reset (the smallest dt over the atoms),
  wall/flow, wall/reflect/stochastic or `fixes:`. The
  per-case counters the kernel advances (step, dt, time, the reflect walls' previous positions)
  are copies per run; the first run's are kept (the others' must agree).

Per-atom arithmetic is the same operations in the same order either way, so results are bit for
bit those of one thread. Anything this module does not recognise (an argument it does not know,
a small chunk) is one plain call.

The ellipsoid kernel (engine/asphere_compiled.py) splits its chunks with the same rule and pieces
(`run_kernel` with its own `plan` built on `split_edges`, and its own axis tables).

Threads: WALLBATCH_THREADS if set (1 = one thread), else the cores this process may use; a
`--jobs N` worker process defaults to its share of the cores (`set_default`).
"""

from __future__ import annotations

import functools
import inspect
import os
import threading
from collections.abc import Callable
from typing import Any

import numpy as np

ENV = "WALLBATCH_THREADS"
ALIGN = 256  # atom splits at multiples of this (a multiple of compiled.BLOCK: the blocks are unchanged)
MIN_WORK = 200_000  # atom-steps per thread below which one call is faster than starting threads
OVERSPLIT = 4  # runs of atoms per thread in an atom split: a thread takes the next run when done with one
TIME_MODE_STEPS = 100  # steps assumed for a time-based chunk (its step count is not known before)

# the chunk kernel's arguments (compiled._make_run_chunk), by name
CASE_AXIS = frozenset({"x", "v", "f", "mass", "radius", "dt", "atime", "atimestep", "step", "sf_val", "rf_val",
                       "rf_prev", "rf_stat", "dtr_par", "xo", "vo", "fo", "rg_val", "st_val", "st_stat",
                       "lp_val"})  # leading axis: cases
ATOM_AXIS = {"x": 1, "v": 1, "f": 1, "mass": 1, "radius": 1, "xo": 1, "vo": 1, "fo": 1, "groups": 1}
COUNTERS = ("dt", "atime", "atimestep", "step", "rf_prev", "rf_stat")  # per-case state the kernel writes
SHARED = frozenset({"nsteps", "time_mode", "target", "tol", "lo", "hi", "periodic", "sf_meta", "groups", "rf_meta",
                    "stats", "dtr_every", "dtr_group", "ftm2v", "mvv2e", "rg_meta", "rg_geo", "fl_int", "fl_f",
                    "fl_walls", "fl_grp", "fl_phys", "fl_pend", "fl_prev", "fl_cross", "fl_rng", "fx", "fx_rng",
                    "tb_meta", "tb_par", "tb_data", "st_meta", "st_flag", "st_rng", "mrow"})
# the sample arrays of a sampled chunk (compiled._sample_arrays): sm[0] shared, the others by case
SAMPLES = "sm"
KNOWN = CASE_AXIS | SHARED | {SAMPLES}

_default: int | None = None  # set_default (a --jobs worker); None: the usable cores
splits = {"cases": 0, "atoms": 0}  # calls split so far, by kind (tests and benchmarks read these)


def usable_cores() -> int:
    """Cores this process may run on."""
    try:
        return len(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        return os.cpu_count() or 1


def parse(text: str) -> int:
    """The thread count of a WALLBATCH_THREADS value: a whole number >= 1 (ValueError otherwise)."""
    try:
        n = int(text.strip())
    except ValueError:
        n = 0
    if n < 1:
        raise ValueError(f"{ENV}={text!r}: give a whole number of threads, 1 or more (1: one thread)")
    return n


def count() -> int:
    """Threads a compiled chunk may use: WALLBATCH_THREADS, else `set_default`'s, else the usable cores."""
    env = os.environ.get(ENV, "").strip()
    if env:
        return parse(env)
    return _default if _default is not None else usable_cores()


def set_default(n: int | None) -> None:
    """The thread count when WALLBATCH_THREADS is unset (None: the usable cores); a `--jobs N`
    worker sets its share of the cores."""
    global _default
    _default = None if n is None else max(1, int(n))


def _names(kernel: Any) -> tuple[str, ...] | None:
    """The kernel's parameter names (numba dispatchers: those of their Python function)."""
    fn = getattr(kernel, "py_func", kernel)
    try:
        return _signature_names(fn)
    except (TypeError, ValueError):
        return None


@functools.lru_cache(maxsize=64)
def _signature_names(fn: Callable[..., Any]) -> tuple[str, ...]:
    return tuple(inspect.signature(fn).parameters)


def plan_split(named: dict[str, Any], threads: int) -> tuple[str, list[slice]] | None:
    """How to split a kernel call: ("cases" | "atoms", the parts) or None for one call."""
    if threads < 2 or set(named) != KNOWN:
        return None
    x = named["x"]
    ncase, natom = x.shape[0], x.shape[1]
    fx = named["fx"]
    if not isinstance(fx, tuple) or not fx or np.shape(fx[0])[0] != 0:  # `fixes:`: per-fix layout
        return None
    flow = int(np.asarray(named["fl_int"]).reshape(-1)[0]) if np.size(named["fl_int"]) else 0
    if flow != 0 or np.shape(named["st_meta"])[0] != 0:  # wall/flow, wall/reflect/stochastic: one case per
        return None  # call, its generator drawn from atom after atom
    steps = TIME_MODE_STEPS if named["time_mode"] else int(named["nsteps"])
    # atoms coupled within the chunk (dt/reset) or sums in another order (statistics, samples): cases only
    atoms = not (int(named["dtr_every"]) != 0 or bool(named["stats"]) or np.size(named[SAMPLES][0]))
    return split_edges(ncase, natom, steps, threads, atoms)


def split_edges(ncase: int, natom: int, steps: int, threads: int, atoms: bool = True) -> tuple[str, list[slice]] | None:
    """The parts of a chunk of `steps` steps of ncase cases of natom atoms over at most `threads`
    threads, each with at least MIN_WORK atom-steps: ("cases", runs of cases) for two cases or
    more, else, if `atoms` (nothing couples the atoms within the chunk), ("atoms", runs of atoms
    split at multiples of ALIGN); None: one call."""
    work = ncase * natom * max(1, steps)
    n = min(threads, work // MIN_WORK)
    if n < 2:
        return None
    if ncase >= 2:
        n = min(n, ncase)
        edges = [ncase * k // n for k in range(n + 1)]
        return "cases", [slice(edges[k], edges[k + 1]) for k in range(n)]
    if not atoms:
        return None
    blocks = -(-natom // ALIGN)
    if min(n, blocks) < 2:
        return None
    # more runs than threads (each still MIN_WORK atom-steps): a thread slowed by other work takes fewer
    n = min(n * OVERSPLIT, blocks, work // MIN_WORK)
    edges = [min(natom, ALIGN * (blocks * k // n)) for k in range(n + 1)]
    return "atoms", [slice(edges[k], edges[k + 1]) for k in range(n)]


def case_part(named: dict[str, Any], c: slice, case_axis: frozenset[str] = CASE_AXIS) -> dict[str, Any]:
    """The arguments of cases c: those named in `case_axis` sliced along their first axis (the
    sample arrays `sm` of the flat kernel: all but its first), the others as they are."""
    part = {k: (v[c] if k in case_axis else v) for k, v in named.items()}
    if SAMPLES in named:
        sm = named[SAMPLES]
        part[SAMPLES] = (sm[0],) + tuple(a[c] for a in sm[1:])
    return part


def atom_part(named: dict[str, Any], a: slice, atom_axis: dict[str, int] = ATOM_AXIS,
              counters: tuple[str, ...] = COUNTERS) -> dict[str, Any]:
    """The arguments of atoms a: those named in `atom_axis` sliced along that axis (groups
    (G, N): a contiguous copy), the per-case `counters` the kernel writes copied, the others as
    they are."""
    part = {}
    for k, v in named.items():
        if k in atom_axis:
            idx = (slice(None),) * atom_axis[k] + (a,)
            v = np.ascontiguousarray(v[idx]) if k == "groups" else v[idx]  # groups (G, N): a copy
        elif k in counters:
            v = v.copy()
        part[k] = v
    return part


def call_parts(kernel: Callable[..., int], names: tuple[str, ...], pieces: list[dict[str, Any]], kind: str,
               nthreads: int | None = None) -> int:
    """kernel(*piece) for every piece (arguments by name) on `nthreads` threads (this one and
    helpers; default one per piece), each taking the next piece not yet taken; the first nonzero
    status in piece order (0 if none)."""
    statuses = _in_threads([lambda p=p: kernel(*(p[k] for k in names)) for p in pieces], nthreads)
    splits[kind] += 1
    return next((st for st in statuses if st != 0), 0)


def _in_threads(calls: list[Callable[[], int]], nthreads: int | None = None) -> list[int]:
    """Run the calls on `nthreads` threads (default: one per call), this one among them, each
    thread taking the next call not yet taken (in list order) until none is left; their results
    in list order (an exception is re-raised)."""
    out: list[Any] = [None] * len(calls)
    taken = iter(range(len(calls)))  # the calls not yet taken, in order (a lock around next())
    lock = threading.Lock()

    def work() -> None:
        while True:
            with lock:
                k = next(taken, None)
            if k is None:
                return
            try:
                out[k] = calls[k]()
            except BaseException as exc:  # noqa: BLE001 - handed to the calling thread
                out[k] = exc

    n = len(calls) if nthreads is None else max(1, min(nthreads, len(calls)))
    helpers = [threading.Thread(target=work, name=f"wallbatch-chunk-{k}", daemon=True) for k in range(1, n)]
    for t in helpers:
        t.start()
    work()
    for t in helpers:
        t.join()
    for r in out:
        if isinstance(r, BaseException):
            raise r
    return out


def run_kernel(kernel: Callable[..., int], args: tuple, threads: int | None = None,
               plan: Callable[[dict[str, Any], int], tuple[str, list[slice]] | None] = plan_split,
               case_axis: frozenset[str] = CASE_AXIS, atom_axis: dict[str, int] = ATOM_AXIS,
               counters: tuple[str, ...] = COUNTERS) -> int:
    """`kernel(*args)` (a compiled chunk kernel), split over `threads` threads (default `count()`)
    where the parts do not interact; returns the kernel's status (the first nonzero one of the
    parts). The results are bit for bit those of the one call. `plan` (arguments by name,
    threads -> the parts or None) and the axis tables are the flat kernel's unless given (the
    ellipsoid kernel passes its own)."""
    names = _names(kernel)
    if names is None or len(names) != len(args):
        return kernel(*args)
    named = dict(zip(names, args))
    nthreads = count() if threads is None else threads
    how = plan(named, nthreads)
    if how is None:
        return kernel(*args)
    return run_split(kernel, names, named, how, case_axis, atom_axis, counters, nthreads)


def run_split(kernel: Callable[..., int], names: tuple[str, ...], named: dict[str, Any],
              how: tuple[str, list[slice]], case_axis: frozenset[str] = CASE_AXIS,
              atom_axis: dict[str, int] = ATOM_AXIS, counters: tuple[str, ...] = COUNTERS,
              nthreads: int | None = None) -> int:
    """The kernel (arguments `named`, in the order `names`) on the parts `how` (`split_edges`)
    in `nthreads` threads (default one per part), its arguments cut by `case_part` / `atom_part`
    with the kernel's own axis tables; the first nonzero status. After an atom split the
    per-case `counters` each part advanced must agree: the first part's are kept."""
    kind, parts = how
    pieces = [case_part(named, p, case_axis) if kind == "cases" else atom_part(named, p, atom_axis, counters)
              for p in parts]
    bad = call_parts(kernel, names, pieces, kind, nthreads)
    if kind == "atoms" and bad == 0:
        first = pieces[0]
        for k in counters:
            if any(not np.array_equal(first[k], p[k], equal_nan=True) for p in pieces[1:]):
                return 3  # cannot happen for atoms that do not couple; the NumPy loop re-runs the chunk
            named[k][...] = first[k]
    return bad
