"""From a validated plan to a results file: split the cases into windows of consecutive cases,
build each window's cases just before it runs (in this process, in local worker processes, which
build their own cases, or on a dask.distributed cluster), run each window's same-structure cases
as batches, persist each finished case under `OUT.parts/` and free it, and assemble the NetCDF at
the end by reading the parts back one at a time. Memory is bounded by what runs (a window) plus
the output arrays themselves, not by the number of cases.

Only this process writes files; workers return results. A case's outputs do not depend on the
batch it ran in or the worker that ran it (random streams come from its sweep coordinates), so
`--jobs`, the executor and `--resume` never change a number.
"""

from __future__ import annotations

import contextlib
import ctypes
import gc
import hashlib
import json
import math
import multiprocessing
import os
import shutil
import signal
import sys
import threading
import time
from concurrent.futures import ProcessPoolExecutor, as_completed
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable, Iterator

import numpy as np

from wallbatch.version import __version__
from wallbatch.config.models import Config
from wallbatch.config.sweep import SweepCase, SweepPlan, config_to_dict
from wallbatch.engine import backend, threads
from wallbatch.engine.engine import SAMPLES_PER_CALL, CaseResult, Engine, run_cases, sample_instants
from wallbatch.io.amber import write_amber
from wallbatch.io.netcdf import build_results, write_netcdf, write_results_file
from wallbatch.io.results import Results
from wallbatch.scene.build import atom_count, build_case
from wallbatch.scene.case import Case, CaseError, structure_key

if TYPE_CHECKING:
    import xarray as xr

MAX_BATCH = 256  # cases per task: big enough to amortise Python overhead, small enough to resume
MAX_BATCH_ATOMS = 1_000_000  # atoms per task (all its cases): bounds a running batch's memory (~450 MB)
WINDOWS_PER_JOB = 4  # with several workers: windows per worker, so a worker slowed by other load takes fewer
MIN_WINDOW_ATOMS = 4_000  # ... but no smaller windows than this (a window's batch set-up and samples)
KEEP_CASES = 256  # a run of at most this many cases keeps its results in memory as well as in the parts ...
KEEP_BYTES = 64_000_000  # ... up to this many bytes of them: the final file does not read those back
WARM_ATOMS = 200_000  # warm the kernels before forking on the first case if it has at most this many atoms
MAX_STEPS = 10**12  # steps of one case (10^12 steps of one atom take days)
MAX_SAMPLES = 1_000_000  # samples of one case (each a row of every output)
PART_FORMAT = 3  # layout of a part file (a part of another layout is recomputed)


class RunError(Exception):
    """A run that cannot start or finish for a reason the user can fix: the output path, leftover
    parts, another run holding the output, a full disk. The message says what to do."""


class Interrupted(Exception):
    """The run was stopped (Ctrl-C, SIGTERM, SIGHUP); every finished case is kept in the parts."""

    def __init__(self, saved: int, total: int, parts: Path | None):
        self.saved, self.total, self.parts = saved, total, parts
        if parts is None:
            where = "finished (no output file)"
        elif saved == 0:  # (no part was written: there is no folder to point at)
            where = "finished: nothing to resume, rerun to start again"
        else:
            where = f"saved in {parts}; rerun with --resume"
        super().__init__(f"interrupted: {saved}/{total} cases {where}")


def build_one(sc: SweepCase, plan: SweepPlan | None = None) -> tuple[Case | None, str, float]:
    """Build one case: (case, "", seconds) or (None, why it cannot be built, seconds). A case that
    cannot be built (bad input, a variable that divides by zero, anything raised while building)
    fails alone, its message kept, led by the place of the key it names (`plan.placed`)."""
    t0 = time.perf_counter()
    case, error, key = None, "", None
    try:
        case = build_case(sc.config, sc.seed_key)
        structure_key(case)  # evaluates constant variables: a division by zero fails this case here
        check_size(case)
    except CaseError as exc:
        case, error, key = None, str(exc), exc.key
    except ValueError as exc:  # a variable that cannot be evaluated, a bad value met while building
        case, error = None, f"cannot set up the case: {str(exc)[:300]}"
    except (ArithmeticError, TypeError, LookupError, MemoryError, RecursionError) as exc:
        case, error = None, f"cannot set up the case: {type(exc).__name__}: {str(exc)[:300]}"
    if error and plan is not None:
        error = plan.placed(error, key)
    return case, error, time.perf_counter() - t0


def build_cases(plan: SweepPlan, seconds: list[float] | None = None) -> tuple[list[Case | None], dict[int, str]]:
    """Build every case at once (`wallbatch check`, tests, benchmarks; a run builds each window's
    cases just before it runs); a case that cannot be built is None, its message in the errors.
    `seconds`, if given, receives each case's build time."""
    built: list[Case | None] = []
    errors: dict[int, str] = {}
    for i, sc in enumerate(plan.cases):
        case, error, sec = build_one(sc, plan)
        built.append(case)
        if case is None:
            errors[i] = error
        if seconds is not None:
            seconds.append(sec)
    return built, errors


MAX_ATOMS = 100_000_000  # atoms of one case
HELD_BYTES_PER_ATOM = 80  # a built case waiting to run (measured: 73 B/atom)
RUN_BYTES_PER_ATOM = 450  # a running batch at its peak (measured: 425 B/atom, flat walls)


def memory_available() -> int:
    """Bytes a run may use: WALLBATCH_MAX_MEMORY (bytes, or with a K/M/G/T suffix) if set, else
    the memory the kernel reports available (MemAvailable)."""
    env = os.environ.get("WALLBATCH_MAX_MEMORY", "").strip().upper()
    if env:
        scale = {"K": 1e3, "M": 1e6, "G": 1e9, "T": 1e12}.get(env[-1:], 1.0)
        try:
            return int(float(env[:-1] if env[-1:] in "KMGT" else env) * scale)
        except ValueError:
            raise RunError(f"WALLBATCH_MAX_MEMORY={env}: give bytes, or a number with K, M, G or T") from None
    try:
        for line in Path("/proc/meminfo").read_text().splitlines():
            if line.startswith("MemAvailable:"):
                return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    return 1 << 62  # unknown: no limit


def check_memory(plan: SweepPlan, jobs: int) -> None:
    """Refuse, before building anything, a plan whose running windows cannot fit in memory: the
    cases of a window are built just before it runs (HELD_BYTES_PER_ATOM each) and run as batches
    (RUN_BYTES_PER_ATOM); `jobs` windows run at once. Finished cases go to the parts, so the
    number of cases does not add up."""
    atoms = [atom_count(sc.config) for sc in plan.cases]
    if not atoms:
        return
    big = max(range(len(atoms)), key=atoms.__getitem__)
    if atoms[big] > MAX_ATOMS:
        which = f"case {plan.cases[big].label}" if plan.dims else "the scene"
        raise RunError(f"{which} would create {atoms[big]:,} atoms, more than the limit of {MAX_ATOMS:,}")
    total = sum(atoms)
    running = max(atoms[big], min(atoms[big] * MAX_BATCH, MAX_BATCH_ATOMS)) * max(1, jobs)  # windows at once
    need = (HELD_BYTES_PER_ATOM + RUN_BYTES_PER_ATOM) * min(total, running)
    have = memory_available()
    if need > have:
        raise RunError(f"the {len(atoms)} case(s) create {total:,} atoms: about {_size(need)} in memory, more "
                       f"than the {_size(have)} available (WALLBATCH_MAX_MEMORY sets the limit); run fewer "
                       f"cases or atoms at a time")


def _size(nbytes: float) -> str:
    for unit, scale in (("TB", 1e12), ("GB", 1e9), ("MB", 1e6), ("kB", 1e3)):
        if nbytes >= scale:
            return f"{nbytes / scale:.1f} {unit}"
    return f"{nbytes:.0f} bytes"


def check_size(case: Case) -> None:
    """Refuse a case whose run length or number of samples is beyond reason before anything is
    allocated for it."""
    if case.natoms < 1:
        raise CaseError("the scene has no atoms: check atoms: (an empty atoms file, a region outside the box?)")
    if case.run_time is None:
        if case.steps > MAX_STEPS:
            raise CaseError(f"run.steps = {case.steps:,} is more than the limit of {MAX_STEPS:,}")
        samples = case.steps // int(case.thermo) + 2 if int(case.thermo) > 0 else 2
    else:
        every = float(case.thermo) if case.thermo_is_time else 0.0
        samples = case.run_time / every + 2 if every > 0 else 2
        if case.run_time / case.dt > MAX_STEPS:
            raise CaseError(f"run.time = {case.run_time} is {case.run_time / case.dt:.3g} steps of dt = {case.dt}: "
                            f"more than the limit of {MAX_STEPS:,}")
    if samples > MAX_SAMPLES:
        raise CaseError(f"run.thermo makes {samples:,.0f} samples: more than the limit of {MAX_SAMPLES:,}; sample "
                        f"less often")


def _layout(case: Case) -> tuple[tuple[str, Any], ...]:
    """What must agree between cases for their results to share one dataset: (the config keys
    that set it, its value) pairs (`layout_difference` names the first that differs)."""
    def faces(walls: list) -> tuple:
        return tuple((w.fix_id, tuple(f.label for f in w.faces)) for w in walls)

    profiles: list[tuple[str, Any]] = [("output.profiles (their names)", tuple(p.name for p in case.profiles))]
    for p in case.profiles:
        at = f"output.profiles.{p.name}"
        profiles += [(f"{at}.axis", p.axis), (f"{at}.bins or delta (its bins)", (p.lo, p.delta, p.nbins)),
                     (f"{at}.every, repeat or freq (its windows)", (p.every, p.repeat, p.freq)),
                     (f"{at}.quantities", p.quantities)]
    return (("run.steps", case.steps), ("run.time", case.run_time),
            ("run.thermo", (case.thermo, case.thermo_is_time)), ("the outputs (output.thermo)", case.outputs),
            ("the wall fixes or their faces (walls:)", faces(case.soft_walls)),
            ("the reflecting walls or their faces (walls:)", faces(case.reflect_walls)), ("units", case.units.name),
            *profiles, ("output.averages.start", case.average_start))


def layout_difference(label: str, layout: tuple, ref_label: str, ref: tuple) -> str:
    """The message for case `label` whose results layout differs from that of case `ref_label`."""
    what = next((k for (k, v), (k2, v2) in zip(layout, ref) if k != k2 or v != v2), "the results' layout")
    return (f"case {label} differs from case {ref_label} in {what}: the cases of a sweep share one results file, "
            f"so they must share its sample instants, outputs, walls and profile windows; sweep it in separate runs")


def check_layout(plan: SweepPlan, cases: list[Case | None]) -> None:
    """All cases must share sample instants, outputs and wall faces to share one results file."""
    good = [(sc, c) for sc, c in zip(plan.cases, cases) if c is not None]
    if not good:
        return
    ref_case, ref = good[0][0], _layout(good[0][1])
    for sc, c in good[1:]:
        if _layout(c) != ref:
            raise CaseError(layout_difference(sc.label, _layout(c), ref_case.label, ref))


def make_tasks(cases: dict[int, Case], jobs: int) -> list[list[int]]:
    """Group case indices by structure, then split each group into about `jobs` tasks (at most
    MAX_BATCH cases and MAX_BATCH_ATOMS atoms each), so every worker gets work, each task is
    still one batch and the memory of a running batch stays bounded."""
    groups: dict[tuple, list[int]] = {}
    for i, c in cases.items():
        groups.setdefault(structure_key(c), []).append(i)
    tasks = []
    for idx in groups.values():
        by_atoms = max(1, MAX_BATCH_ATOMS // max(1, cases[idx[0]].natoms))  # same structure: same atoms
        size = min(MAX_BATCH, by_atoms, max(1, math.ceil(len(idx) / max(1, jobs))))
        tasks.extend(idx[k:k + size] for k in range(0, len(idx), size))
    return tasks


@dataclass
class Outcome:
    """What a window returns for one of its cases: the result; whether the case was built (a case
    that cannot be built is not saved as a part); its results layout; for a case that dumps
    frames, (box_lo, box_hi, units name, case name) for the trajectory file."""

    result: CaseResult
    built: bool
    layout: tuple | None = None
    dump: tuple | None = None


_PLAN: SweepPlan | None = None  # the running plan: forked workers inherit it and build their own cases
_FIRST: Case | None = None  # its first case, built before forking (the kernels are loaded on it)


def make_windows(plan: SweepPlan, todo: list[int], jobs: int) -> list[list[int]]:
    """Consecutive cases to build and run together (a task): at most MAX_BATCH cases and
    MAX_BATCH_ATOMS atoms (as the config implies; atoms files count 1), so a running window's
    memory stays bounded. One worker: windows as large as that. Several: about
    len(todo)/(jobs x WINDOWS_PER_JOB) cases each, but windows of at least MIN_WINDOW_ATOMS
    atoms, so every worker gets work and one slowed by other load on the machine takes fewer
    windows (the results do not depend on the windows)."""
    if not todo:
        return []
    size = math.ceil(len(todo) / max(1, jobs))
    if jobs > 1:
        per_case = max(1, atom_count(plan.cases[todo[0]].config))
        count = min(jobs * WINDOWS_PER_JOB, max(jobs, len(todo) * per_case // MIN_WINDOW_ATOMS))
        size = math.ceil(len(todo) / count)
    size = min(MAX_BATCH, max(1, size))
    windows: list[list[int]] = []
    cur: list[int] = []
    atoms = 0
    for i in todo:
        n = max(1, atom_count(plan.cases[i].config))
        if cur and (len(cur) >= size or atoms + n > MAX_BATCH_ATOMS):
            windows.append(cur)
            cur, atoms = [], 0
        cur.append(i)
        atoms += n
    windows.append(cur)
    return windows


def _run_window(items: list, plan: SweepPlan | None = None, compiled: bool | None = None) -> list[Outcome]:
    """Build a window's cases (items: indices into `plan`, or the running plan a forked worker
    inherited, built here; or (case, error, seconds) built by the parent), run its same-structure
    cases as batches, and return one Outcome per item; the built cases are freed on return.
    `compiled`: the plan's engine path (engine/backend.py) for a worker that did not inherit it."""
    with backend.plan_path(compiled):
        out: list[Outcome | None] = [None] * len(items)
        for where, outcomes in _window_parts(items, plan):
            for k, o in zip(where, outcomes):
                out[k] = o
        return out  # type: ignore[return-value]


def _window_parts(items: list, plan: SweepPlan | None) -> Iterator[tuple[list[int], list[Outcome]]]:
    """A window's outcomes as they come: (positions in `items`, their outcomes), first the cases
    that cannot be built, then each same-structure batch as it finishes (`_run_window`; the
    local one-process run saves each batch's parts at once, so a kill loses no finished batch)."""
    source = plan if plan is not None else _PLAN
    built = [build_one(source.cases[it], source) if isinstance(it, int) else it for it in items]  # type: ignore[union-attr]
    cases: dict[int, Case] = {}
    failed: list[int] = []
    for k, (case, _error, _sec) in enumerate(built):
        if case is None:
            failed.append(k)
        else:
            cases[k] = case
    if failed:
        yield failed, [Outcome(CaseResult("failed", built[k][1], built[k][2], {}), False) for k in failed]
    for task in make_tasks(cases, 1):
        outcomes = []
        for k, res in zip(task, _run_task([cases[k] for k in task])):
            c = cases[k]
            res.seconds += built[k][2]
            outcomes.append(Outcome(res, True, _layout(c), (c.box_lo, c.box_hi, c.units.name, c.name)
                                    if c.dump_every > 0 else None))
        yield task, outcomes


def _run_window_on_cluster(items: list, compiled: bool | None = None) -> list[Outcome]:
    """`_run_window` in a dask worker (`compiled`: the plan's engine path): one thread per task
    unless WALLBATCH_THREADS says otherwise (the cluster runs as many tasks at once as it has
    worker threads)."""
    threads.set_default(1)
    return _run_window(items, None, compiled)


def _warm_compiler(case: Case | None = None) -> None:
    """Before forking workers, load the kernels they will run in this process: they inherit them
    instead of each loading them from the on-disk cache (or compiling them, each at once). With
    `case` (the first case of the run, up to WARM_ATOMS atoms) one step of it on a throw-away
    engine loads exactly its kernels; otherwise numba's compiler is initialised (its type and
    target contexts, `_set_up_numba`) and the workers load their kernels (~0.2 s each). Small plans (NumPy
    path, engine/backend.py) import no numba."""
    if not backend.numba_allowed() or _fork_context() is None:
        return
    _set_up_numba()
    from wallbatch.engine import compiled

    if not compiled.enabled():
        return
    if case is not None and case.natoms <= WARM_ATOMS:
        with contextlib.suppress(Exception), np.errstate(all="ignore"):
            engine = Engine([case])
            if engine.fast is not None:
                engine.setup()
                # the kernel the run will use: time-based, samples recorded in the kernel or not
                if case.run_time is not None:
                    engine.advance_to_time(float(engine.state.time[0] + engine.state.dt[0]))
                elif engine.fast.samples_in_kernel(np.asarray(sample_instants(case)[1:SAMPLES_PER_CALL + 1])):
                    engine.fast.advance_sampled(np.array([1]))
                else:
                    engine.advance(1, sample=False)
                return


def _set_up_numba() -> None:
    """In a process about to run compiled kernels: import them and set numba up (backend.prepare_numba)
    with the garbage collector paused. numba leaves ~50k long-lived objects, and the
    collections its set-up triggers walk them again and again; if the caller froze its own
    start-up (gc.freeze: the command line does), numba's objects join it."""
    if not backend.numba_allowed() or ("wallbatch.engine.compiled" in sys.modules and backend.numba_prepared()):
        return  # a NumPy plan, or numba set up already
    frozen, enabled = gc.get_freeze_count() > 0, gc.isenabled()
    gc.disable()
    try:
        from wallbatch.engine import compiled

        compiled.enabled()  # numba imports; backend.prepare_numba sets up its cache loads
    finally:
        if frozen:
            gc.freeze()
        if enabled:
            gc.enable()


def _fork_context() -> Any:
    """The fork start method where the platform has it (workers then inherit the plan), else None."""
    return multiprocessing.get_context("fork") if "fork" in multiprocessing.get_all_start_methods() else None


# ----------------------------------------------------------------------------- executors


def _run_task(cases: list[Case]) -> list[CaseResult]:
    """Run one task (one batch); if the batch breaks as a whole (an error in its setup that
    belongs to some case), run its cases one by one so that only the guilty case fails."""
    results = run_cases(cases)
    if len(cases) > 1 and all(r.status == "failed" and r.error.startswith("internal error") for r in results):
        results = [run_cases([c])[0] for c in cases]
    return results


def usable_cores() -> int:
    """Cores this process may run on."""
    return threads.usable_cores()


def _watch_parent(parent: int) -> None:
    while True:
        time.sleep(0.5)
        if os.getppid() != parent:
            os._exit(1)


def _worker_init(parent: int, nthreads: int = 1) -> None:
    """In each worker: Ctrl-C is the parent's business (it stops the workers), and a worker dies
    with its parent (Linux parent-death signal, and a watcher thread elsewhere); its compiled
    chunks use `nthreads` threads unless WALLBATCH_THREADS says otherwise."""
    threads.set_default(nthreads)
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    for sig in (signal.SIGTERM, signal.SIGHUP):  # not the parent's handlers (inherited by fork): end now
        signal.signal(sig, signal.SIG_DFL)
    with contextlib.suppress(Exception):
        ctypes.CDLL(None, use_errno=True).prctl(1, signal.SIGKILL)  # PR_SET_PDEATHSIG
    if os.getppid() != parent:
        os._exit(1)
    threading.Thread(target=_watch_parent, args=(parent,), daemon=True, name="wallbatch-parent-watch").start()


def _stop_pool(pool: ProcessPoolExecutor) -> None:
    """Cancel pending tasks and end the workers now (they hold no state worth keeping), then wait
    for the pool's manager thread to end: CPython 3.11's exit handler for process pools wakes
    every manager thread still registered, and one ending at that moment can close its wake-up
    pipe in between ("Bad file descriptor" and a traceback after an interrupted run's message)."""
    procs = list((getattr(pool, "_processes", None) or {}).values())
    manager = getattr(pool, "_executor_manager_thread", None)
    pool.shutdown(wait=False, cancel_futures=True)
    for p in procs:
        with contextlib.suppress(Exception):
            p.terminate()
    deadline = time.monotonic() + 3.0
    for p in procs:
        with contextlib.suppress(Exception):
            p.join(max(0.0, deadline - time.monotonic()))
            if p.is_alive():
                p.kill()
                p.join(1.0)
    if isinstance(manager, threading.Thread) and manager is not threading.current_thread():
        manager.join(2.0)  # (it sees its workers gone and ends)


@contextlib.contextmanager
def _frozen_for_fork() -> Iterator[None]:
    """While forking workers: every object of this process in the collector's permanent
    generation (gc.freeze, as Python's documentation advises before fork), so a worker's
    collections never walk what it inherited (numba's ~300k objects: time, and copy-on-write
    copies of the pages they touch). This process is as it was afterwards (gc.unfreeze), unless
    something was frozen before (the command line freezes its start-up): then it stays frozen."""
    frozen_before = gc.get_freeze_count() > 0
    gc.freeze()
    try:
        yield
    finally:
        if not frozen_before:
            gc.unfreeze()


def _whole(tasks: list[list], k: int, outcomes: list[Outcome]) -> tuple[int, list[int], list[Outcome]]:
    """What `execute` yields for window k run as one task: (k, every position in it, its outcomes)."""
    return k, list(range(len(tasks[k]))), outcomes


def execute(tasks: list[list], jobs: int = 1, executor: str = "local",
            scheduler: str | None = None, plan: SweepPlan | None = None
            ) -> Iterator[tuple[int, list[int], list[Outcome]]]:
    """Run windows (see `_run_window`; in this process from `plan`); yield (window index, positions
    in it, their outcomes) as each finishes (in this process: as each of its batches finishes).
    Local workers each get an equal share of the cores as threads, and inherit the kernels loaded
    here on the run's first case (_FIRST, see _warm_compiler). Closing the generator early (an
    interrupt) cancels the pending tasks and stops the workers."""
    if executor == "dask":
        from distributed import Client
        from distributed import as_completed as dask_completed

        with Client(scheduler) as client:
            path = backend.numba_allowed()  # the plan's engine path travels with each task
            futures = {client.submit(_run_window_on_cluster, t, path, pure=False): k for k, t in enumerate(tasks)}
            try:
                for fut in dask_completed(futures):
                    yield _whole(tasks, futures[fut], fut.result())
            except BaseException:
                client.cancel(list(futures))
                raise
    elif jobs <= 1 or len(tasks) <= 1:
        _set_up_numba()
        for k, t in enumerate(tasks):
            for where, outcomes in _window_parts(t, plan):
                yield k, where, outcomes
    else:
        _warm_compiler(_FIRST)
        workers = min(jobs, len(tasks))
        pool = ProcessPoolExecutor(max_workers=workers, mp_context=_fork_context(), initializer=_worker_init,
                                   initargs=(os.getpid(), max(1, usable_cores() // workers)))
        try:
            with _frozen_for_fork():  # the pool forks its workers at the first submit
                futures = {pool.submit(_run_window, t, None, backend.numba_allowed()): k for k, t in enumerate(tasks)}
            for fut in as_completed(futures):
                yield _whole(tasks, futures[fut], fut.result())
        except BaseException:
            _stop_pool(pool)
            raise
        # every task is done: the workers exit while this process merges the parts (the pool's
        # manager thread joins them; a worker left when the process ends gets its parent-death
        # signal)
        pool.shutdown(wait=False)


@contextlib.contextmanager
def stop_on_signals() -> Iterator[None]:
    """While running: SIGTERM and SIGHUP stop the run as Ctrl-C does (KeyboardInterrupt), so
    finished parts are kept and the workers are stopped. Only in the main thread."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def stop(signum, frame):
        raise KeyboardInterrupt(signal.Signals(signum).name)

    saved = {sig: signal.signal(sig, stop) for sig in (signal.SIGTERM, signal.SIGHUP)}
    try:
        yield
    finally:
        for sig, handler in saved.items():
            signal.signal(sig, handler)


# ----------------------------------------------------------------------------- resume


def _input_files(data: Any, base_dir: Path, memo: dict[tuple, str]) -> dict[str, str]:
    """The files a case reads (every `file:` of its config: atoms files, wall/table files) as
    their resolved path -> a hash of their content ('missing' if they cannot be read). `memo`
    keeps one hash per (path, size, modification time), so a sweep hashes each file once."""
    found: dict[str, str] = {}
    stack = [data]
    while stack:
        node = stack.pop()
        if isinstance(node, dict):
            for k, v in node.items():
                if k == "file" and isinstance(v, str):
                    path = Path(v) if Path(v).is_absolute() else base_dir / v
                    try:
                        st = path.stat()
                        key = (str(path.resolve()), st.st_size, st.st_mtime_ns, st.st_ino)
                        if key not in memo:
                            h = hashlib.sha256()
                            with open(path, "rb") as fh:
                                for block in iter(lambda: fh.read(1 << 20), b""):
                                    h.update(block)
                            memo[key] = h.hexdigest()
                        found[key[0]] = memo[key]
                    except OSError:
                        found[str(path)] = "missing"
                else:
                    stack.append(v)
        elif isinstance(node, list):
            stack.extend(node)
    return found


def case_key(sc: SweepCase, memo: dict[tuple, str] | None = None) -> str:
    """Identity of a case for resuming: its full validated config, random stream and the content
    of the files it reads (an atoms or table file edited between an interrupt and `--resume`
    makes its cases differ). `memo` (see `_input_files`) shares file hashes between cases."""
    data = config_to_dict(sc.config)
    files = _input_files(data, Path(getattr(sc.config, "_base_dir", Path("."))), {} if memo is None else memo)
    blob = json.dumps([data, sc.seed_key, __version__] + ([files] if files else []), sort_keys=True, default=str)
    return hashlib.sha256(blob.encode()).hexdigest()[:24]


def parts_dir(output: Path) -> Path:
    return output.with_name(output.name + ".parts")


def dump_path(output: Path, sc: SweepCase) -> Path:
    """Trajectory file of a case: OUT.dump/<coordinates>.nc (OUT.dump/case.nc without a sweep)."""
    name = "_".join(f"{k}={v}" for k, v in sc.coords.items()) or "case"
    safe = "".join(ch if ch.isalnum() or ch in "=._-" else "-" for ch in name)
    return output.with_name(output.stem + ".dump") / f"{safe}.nc"


def write_dump(path: Path, box: tuple, res: CaseResult) -> None:
    """The frames of a case as AMBER NetCDF; box = (box_lo, box_hi, units name, case name)."""
    if res.frames.get("time") is not None and len(res.frames["time"]):
        lo, hi, units, name = box
        write_amber(path, res.frames["time"], res.frames.get("x"), res.frames.get("v"), lo, hi, units,
                    title=f"wallbatch {name}")


def _digest(key: str, status: str, error: str, seconds: float, data: dict[str, np.ndarray]) -> str:
    """Content hash of a part: its case key, status, message, seconds and every array."""
    h = hashlib.sha256(f"{PART_FORMAT}|{key}|{status}|{error}|{seconds!r}".encode())
    for name in sorted(data):
        arr = np.ascontiguousarray(data[name])
        h.update(f"|{name}|{arr.dtype.str}|{arr.shape}|".encode())
        h.update(arr.tobytes())
    return h.hexdigest()


def _part_path(folder: Path, name: str) -> str:
    """A part's path as a string: a pathlib path interns each of its parts (sys.intern), one new
    interned string per case, and the interpreter's table of interned strings then grows (a
    few MB at once in a process with NumPy, numba and SciPy loaded) at a moment that depends on
    everything else the process has interned."""
    return os.path.join(folder, name)


PART_SUFFIX = ".part"  # a finished case's file in OUT.nc.parts/ (format PART_FORMAT, `save_part`)
OLD_PART_SUFFIX = ".npz"  # the parts of wallbatch versions before PART_FORMAT 3 (reported, recomputed)
_PART_MAGIC = b"WBPART\x00" + bytes([PART_FORMAT])  # 8 bytes: the file kind and PART_FORMAT


def part_bytes(key: str, res: CaseResult, digest: str) -> bytes:
    """A part's bytes: _PART_MAGIC, the length of a JSON header (8 bytes, little-endian), the header
    (status, error, seconds, case key, content hash, and each array's name, dtype, shape, offset
    and length), then the arrays' bytes in C order, one after the other. One write and one read a
    part, where an .npz (a zip member per array) cost ~1.9 ms to write and ~1.4 ms to read."""
    index, blobs, offset = [], [], 0
    for name, value in res.data.items():
        arr = np.ascontiguousarray(value)
        if arr.dtype.hasobject:
            raise TypeError(f"results array {name!r} holds Python objects; parts store plain dtypes only")
        raw = arr.tobytes()
        index.append([name, arr.dtype.str, list(arr.shape), offset, len(raw)])
        blobs.append(raw)
        offset += len(raw)
    head = json.dumps({"status": res.status, "error": res.error, "seconds": float(res.seconds), "case_key": key,
                       "digest": digest, "arrays": index}).encode()
    return b"".join([_PART_MAGIC, len(head).to_bytes(8, "little"), head, *blobs])


def parse_part(raw: bytes) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
    """The header and the arrays of a part's bytes (`part_bytes`); a file of another kind or
    format, a truncated or inconsistent one: ValueError."""
    if raw[:8] != _PART_MAGIC:
        raise ValueError("not a wallbatch part of this format")
    size = int.from_bytes(raw[8:16], "little")
    if 16 + size > len(raw):
        raise ValueError("truncated header")
    head = json.loads(raw[16:16 + size].decode())
    base = 16 + size
    data: dict[str, np.ndarray] = {}
    for name, dtype_str, shape, offset, length in head["arrays"]:
        dtype = np.dtype(dtype_str)
        count = math.prod(shape)
        if dtype.hasobject or count * dtype.itemsize != length or base + offset + length > len(raw):
            raise ValueError(f"array {name!r} does not fit the file")
        data[name] = np.frombuffer(raw, dtype, count, base + offset).reshape(shape).copy()
    return head, data


def _write_bytes(path: str, blob: bytes) -> None:
    """Write a new file (a part's temporary)."""
    with open(path, "wb") as fh:
        fh.write(blob)


def save_part(folder: Path, key: str, res: CaseResult) -> None:
    """One finished case as a small file (`part_bytes`) carrying its case key and a content hash,
    written to a temporary file and renamed (a part is complete or absent). Disk full: RunError."""
    tmp = _part_path(folder, f".{key}.tmp{PART_SUFFIX}")
    blob = part_bytes(key, res, _digest(key, res.status, res.error, float(res.seconds), res.data))
    try:
        folder.mkdir(parents=True, exist_ok=True)
        _write_bytes(tmp, blob)
        os.replace(tmp, _part_path(folder, f"{key}{PART_SUFFIX}"))
    except OSError as exc:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise RunError(f"cannot save a finished case in {folder}: {exc.strerror or exc}"
                       + ("; free some space, then rerun with --resume (the finished cases are kept)"
                          if getattr(exc, "errno", None) == 28 else "")) from None


def read_part(folder: Path, key: str) -> tuple[CaseResult | None, str]:
    """The part of a case, checked: (result, "") or (None, why it is not usable) - "" when absent."""
    path = _part_path(folder, f"{key}{PART_SUFFIX}")
    if not os.path.exists(path):
        old = os.path.exists(_part_path(folder, f"{key}{OLD_PART_SUFFIX}"))
        return None, "written by an older wallbatch" if old else ""
    try:
        with open(path, "rb") as fh:
            head, data = parse_part(fh.read())
        status, error, seconds = str(head["status"]), str(head["error"]), float(head["seconds"])
        stored_key, digest = str(head["case_key"]), str(head["digest"])
    except Exception as exc:  # noqa: BLE001 - any unreadable file (truncated, bit flip, empty) is recomputed
        return None, f"damaged ({type(exc).__name__})"
    if stored_key != key:
        return None, "belongs to another case"
    if digest != _digest(key, status, error, seconds, data):
        return None, "damaged (content hash differs)"
    return CaseResult(status, error, seconds, data), ""


def load_part(folder: Path, key: str) -> CaseResult | None:
    """The checked part of a case, or None (absent, damaged or foreign: recomputed)."""
    return read_part(folder, key)[0]


# ----------------------------------------------------------------------------- progress


class Progress:
    """Cases done, failed and an ETA on stderr; silent when stderr is not a terminal."""

    def __init__(self, total: int, enabled: bool | None = None):
        self.total, self.done, self.failed = total, 0, 0
        self.enabled = sys.stderr.isatty() if enabled is None else enabled
        self.t0 = time.perf_counter()

    def update(self, results: list[CaseResult]) -> None:
        self.done += len(results)
        self.failed += sum(r.status == "failed" for r in results)
        if not self.enabled:
            return
        elapsed = time.perf_counter() - self.t0
        eta = elapsed / self.done * (self.total - self.done) if self.done else float("nan")
        width = 30
        filled = int(width * self.done / max(self.total, 1))
        sys.stderr.write(f"\r[{'#' * filled}{'.' * (width - filled)}] {self.done}/{self.total} cases, "
                         f"{self.failed} failed, ETA {eta:5.0f} s ")
        if self.done >= self.total:
            sys.stderr.write("\n")
        sys.stderr.flush()


# ----------------------------------------------------------------------------- the run


NETCDF_MAGIC = (b"\x89HDF\r\n\x1a\n", b"CDF\x01", b"CDF\x02", b"CDF\x05")


def is_netcdf(path: Path) -> bool:
    """True if `path` starts like a NetCDF-4 (HDF5) or classic NetCDF file."""
    try:
        with open(path, "rb") as fh:
            head = fh.read(8)
    except OSError:
        return False
    return any(head.startswith(m) for m in NETCDF_MAGIC)


def check_output(output: Path, inputs: tuple[str, ...] = (), overwrite: bool = True) -> None:
    """Refuse an output path that would destroy something: an input of the run, a directory, a
    file that is not a results file, an existing results file (unless `overwrite`)."""
    out = output.resolve()
    if str(out) in {str(Path(p).resolve()) for p in inputs}:
        raise RunError(f"-o {output} is an input of this run: choose another name for the results "
                       f"(e.g. {output.with_suffix('.nc').name if output.suffix != '.nc' else 'results.nc'})")
    if out.is_dir():
        raise RunError(f"-o {output} is a directory: give a file name, e.g. {output / 'results.nc'}")
    parent = out.parent
    while not parent.exists() and parent != parent.parent:
        parent = parent.parent
    if not os.access(parent, os.W_OK):
        raise RunError(f"-o {output}: cannot write in {parent} (permission denied)")
    if out.exists():
        if not is_netcdf(out):
            raise RunError(f"-o {output} exists and is not a results file: refusing to overwrite it")
        if not overwrite:
            raise RunError(f"{output} exists: add --force to overwrite it, or choose another -o")
    parts = parts_dir(out)
    if parts.exists() and not parts.is_dir():
        raise RunError(f"{parts} exists and is not a folder of parts: move it away")


@contextlib.contextmanager
def output_lock(output: Path) -> Iterator[Path]:
    """`OUT.lock` holding this process's PID while the run owns OUT and its parts; a second run
    on the same output refuses (a lock whose process is gone is taken over)."""
    lock = output.with_name(output.name + ".lock")
    lock.parent.mkdir(parents=True, exist_ok=True)
    for _ in range(3):
        try:
            fd = os.open(lock, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o644)
        except FileExistsError:
            try:
                pid = int(lock.read_text().split()[0])
            except (OSError, ValueError, IndexError):
                pid = 0
            if pid > 0 and pid != os.getpid() and _alive(pid):
                raise RunError(f"{output} is being written by another wallbatch run (PID {pid}, lock file "
                               f"{lock}): wait for it or choose another -o") from None
            with contextlib.suppress(FileNotFoundError):
                lock.unlink()  # stale: its process is gone
            continue
        except OSError as exc:
            raise RunError(f"cannot create the lock file {lock}: {exc.strerror}") from None
        with os.fdopen(fd, "w") as fh:
            fh.write(f"{os.getpid()}\n")
        break
    else:
        raise RunError(f"cannot take the lock file {lock}: remove it if no wallbatch run is using {output}")
    try:
        yield lock
    finally:
        with contextlib.suppress(OSError, ValueError):
            if int(lock.read_text().split()[0]) == os.getpid():
                lock.unlink()


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def run_plan(plan: SweepPlan, output: str | Path | None = None, *, jobs: int = 1, executor: str = "local",
             scheduler: str | None = None, resume: bool = False, fresh: bool = False, overwrite: bool = True,
             progress: bool | None = None, on_result: Callable[[int, CaseResult], None] | None = None,
             log: Callable[[str], None] | None = None, as_xarray: bool = True,
             summary: bool = False) -> xr.Dataset | Results:
    """Run every case of a plan; write `output` if given; return the results Dataset (with
    `as_xarray=False` the plain `io.results.Results`: xarray is not imported). With `output` and
    `summary`, the results file is written block by block from the parts (the outputs of all
    cases are never in memory at once) and only each case's status, error and seconds are
    returned, with the sweep coordinates.

    With `output`, each finished case is persisted under OUT.parts/ as it completes and a lock file
    OUT.lock keeps other runs away. Parts left by an earlier run: `resume` reuses those whose case
    (full config and seed) is unchanged, `fresh` discards them, neither refuses (RunError). The
    parts are removed once the final file is written. Ctrl-C, SIGTERM or SIGHUP stop the workers
    and raise `Interrupted` (every finished case stays in the parts). `log` receives one-line
    notes (cases reused, kernels compiling, jobs capped)."""
    with backend.plan_path(backend.choose(plan)):  # small plans run NumPy only (engine/backend.py)
        res = _run_plan(plan, output, jobs, executor, scheduler, resume, fresh, overwrite, progress, on_result, log,
                        summary)
    return res.to_xarray() if as_xarray else res


def _run_plan(plan: SweepPlan, output: str | Path | None, jobs: int, executor: str, scheduler: str | None,
              resume: bool, fresh: bool, overwrite: bool, progress: bool | None,
              on_result: Callable[[int, CaseResult], None] | None, log: Callable[[str], None] | None,
              summary: bool = False) -> Results:
    say = log or (lambda msg: None)
    if output is None:
        return _run(plan, None, jobs, executor, scheduler, False, progress, on_result, say)
    output = Path(output)
    # resuming continues a run that was writing this output: its old version may be replaced
    check_output(output, plan.inputs, overwrite or (resume and parts_dir(output).is_dir()))
    with output_lock(output):
        parts = parts_dir(output)
        if parts.exists() and not resume:
            found = sum(1 for p in parts.iterdir()
                        if p.suffix in (PART_SUFFIX, OLD_PART_SUFFIX) and not p.name.startswith("."))
            if not fresh:
                raise RunError(f"{parts} holds {found} finished case(s) of an earlier run: add --resume to reuse "
                               f"them, or --fresh to discard them")
            shutil.rmtree(parts)
        dump = output.with_name(output.stem + ".dump")
        if dump.exists() and not resume:
            if dump.is_dir():
                shutil.rmtree(dump)
            else:
                dump.unlink()
        return _run(plan, output, jobs, executor, scheduler, resume, progress, on_result, say, summary)


def _run(plan: SweepPlan, output: Path | None, jobs: int, executor: str, scheduler: str | None, resume: bool,
         progress: bool | None, on_result: Callable[[int, CaseResult], None] | None,
         say: Callable[[str], None], summary: bool = False) -> Results:
    global _PLAN, _FIRST
    try:
        threads.count()
    except ValueError as exc:  # a WALLBATCH_THREADS that is not a number of threads
        raise RunError(str(exc)) from None
    total = len(plan.cases)
    parts = parts_dir(output) if output is not None else None
    saved: set[int] = set()  # cases whose part exists (their results are read back at the end)
    held: dict[int, CaseResult] = {}  # results not in a part: cases that cannot be built, runs without output
    # (and, for a small run, KEEP_BYTES of results also saved in parts: not read back at the end)
    keep = KEEP_BYTES if total <= KEEP_CASES else 0
    unbuilt: set[int] = set()  # cases that cannot be built
    finished = 0  # cases run (without an output file)
    try:
        with stop_on_signals():
            check_memory(plan, jobs if executor == "local" else 1)
            memo: dict[tuple, str] = {}
            keys = [case_key(sc, memo) for sc in plan.cases] if parts is not None else []
            if parts is not None and resume:
                bad: dict[str, int] = {}
                for i in range(total):
                    res, why = read_part(parts, keys[i])  # checked, then dropped: read again at the end
                    if res is not None:
                        saved.add(i)
                    elif why:
                        bad[why] = bad.get(why, 0) + 1
                note = "; ".join(f"{n} part(s) {why}: recomputed" for why, n in bad.items())
                say(f"resuming: {len(saved)} of {total} case(s) reused from {parts}" + (f"; {note}" if note else ""))
            todo = [i for i in range(total) if i not in saved]
            bar = Progress(total, progress)
            bar.update([CaseResult("ok", "", 0.0, {})] * len(saved))
            cores = usable_cores()
            if executor == "local" and jobs > cores:
                say(f"--jobs {jobs} capped at {cores} (the cores this machine lets the run use)")
                jobs = cores
            windows = make_windows(plan, todo, jobs)
            if executor == "local" and jobs > len(windows) > 0:
                jobs = len(windows)
            # forked local workers build their own cases from the plan they inherit; elsewhere the
            # cases travel to the workers
            local = executor == "local" and (jobs <= 1 or len(windows) <= 1 or _fork_context() is not None)
            tasks = [w if local else [build_one(plan.cases[i], plan) for i in w] for w in windows]
            layout: tuple | None = None
            layout_case = -1
            built = len(saved)  # cases built (or reused)
            _PLAN = plan  # for forked workers
            # the first case that builds, built once: forked workers inherit the kernels loaded on
            # it; run here, it runs in the first window as built; the results layout comes from it
            failed: dict[int, tuple] = {}  # cases before it that cannot be built, as built
            first = _first_built(plan, set(), windows[0], failed) if local and windows else None
            if first is not None and (jobs <= 1 or len(tasks) <= 1):
                failed[first[0]] = (first[1], "", first[2])
                tasks[0] = [failed.get(i, i) for i in tasks[0]]
            _FIRST = first[1] if first is not None else None
            runs = execute(tasks, jobs, executor, scheduler, plan=plan)
            try:
                for k, where, outcomes in _worker_deaths(runs, parts, saved):
                    for i, out in zip([windows[k][p] for p in where], outcomes):
                        res = out.result
                        if not out.built:
                            unbuilt.add(i)
                        elif layout is None:
                            layout, layout_case = out.layout, i
                        elif out.layout != layout:
                            if parts is not None and not resume and parts.exists():
                                shutil.rmtree(parts)  # an invalid sweep: leave nothing to resume
                            seen = {i: out.layout, layout_case: layout}
                            a, b = sorted(seen)  # (named in plan order, as `check` names them)
                            raise CaseError(layout_difference(plan.cases[b].label, seen[b], plan.cases[a].label,
                                                              seen[a]))
                        built += out.built
                        if out.dump is not None and output is not None:
                            write_dump(dump_path(output, plan.cases[i]), out.dump, res)
                        res.frames = {}
                        if parts is not None and out.built:
                            save_part(parts, keys[i], res)
                            saved.add(i)
                            size = sum(a.nbytes for a in res.data.values())
                            if size <= keep:
                                keep -= size
                                held[i] = res
                        else:
                            held[i] = res
                        finished += 1
                        if on_result is not None:
                            on_result(i, res)
                    bar.update([o.result for o in outcomes])
            finally:
                runs.close()
                _PLAN = _FIRST = None
            c0 = first[1] if first is not None else _first_case(plan, unbuilt)
            if built == 0 or c0 is None:
                raise CaseError(_no_case_message(plan, {i: held[i].error for i in sorted(unbuilt)}))
            paths = None
            if c0.dump_every > 0 and output is not None:
                paths = [str(dump_path(output, sc).relative_to(output.parent)) if (
                    dump_path(output, sc).exists()) else "" for sc in plan.cases]
            stream = output is not None and summary
            if not stream:
                ds = build_results(_results(total, held, parts, keys), c0, config_text=plan.base_text,
                                   sweep_text=plan.sweep_text, dims=plan.dims, dump_paths=paths)
            if output is not None:
                try:
                    if stream:  # block by block from the parts: the outputs are never all in memory
                        ds = write_results_file(_results(total, held, parts, keys), c0, output,
                                                config_text=plan.base_text, sweep_text=plan.sweep_text,
                                                dims=plan.dims, dump_paths=paths)
                    else:
                        write_netcdf(ds, output)
                except (OSError, RuntimeError) as exc:
                    tmp = output.with_name(output.name + ".tmp")
                    with contextlib.suppress(OSError):
                        tmp.unlink()
                    full = getattr(exc, "errno", None) == 28 or "HDF error" in str(exc) or \
                        _free_bytes(output.parent) < 1 << 20
                    raise RunError(f"cannot write {output}: {getattr(exc, 'strerror', None) or exc}"
                                   + (" (disk full?)" if full else "")
                                   + f"; the {len(saved)} finished case(s) are kept in {parts}: free space or "
                                     f"choose another -o, then rerun with --resume") from None
                if parts.exists():
                    shutil.rmtree(parts)
            return ds
    except KeyboardInterrupt:
        raise Interrupted(len(saved) if parts is not None else finished, total, parts) from None


def _first_case(plan: SweepPlan, unbuilt: set[int]) -> Case | None:
    """The first case that can be built (the results layout and units come from it): built again
    here, one case; cases known not to build are skipped."""
    found = _first_built(plan, unbuilt)
    return found[1] if found is not None else None


def _first_built(plan: SweepPlan, unbuilt: set[int], upto: list[int] | None = None,
                 failed: dict[int, tuple] | None = None) -> tuple[int, Case, float] | None:
    """(index, case, seconds to build it) of the first case that can be built, skipping those known
    not to build (and looking no further than the last index of `upto`, if given); `failed`, if
    given, receives build_one's answer for each case met before it that cannot be built. Building
    is deterministic: the same case whenever it is asked."""
    last = max(upto) if upto else len(plan.cases) - 1
    for i, sc in enumerate(plan.cases[:last + 1]):
        if i in unbuilt:
            continue
        case, error, sec = build_one(sc, plan)
        if case is not None:
            return i, case, sec
        if failed is not None:
            failed[i] = (None, error, sec)
    return None


def _results(total: int, held: dict[int, CaseResult], parts: Path | None, keys: list[str]) -> Iterator[CaseResult]:
    """Every case's result in plan order, one at a time: from memory (released as it goes) or
    read back from its part, so the results are never all in memory twice (but a small run's,
    see KEEP_CASES)."""
    for i in range(total):
        res = held.pop(i, None)
        if res is None and parts is not None:
            res, why = read_part(parts, keys[i])
            if res is None:
                raise RunError(f"the part of case {i} in {parts} {why or 'is missing'} since it was written: rerun "
                               f"with --resume to recompute it")
        yield res if res is not None else CaseResult("failed", "no result", 0.0, {})


def _worker_deaths(runs: Iterator[tuple[int, list[int], list[Outcome]]], parts: Path | None,
                   saved: set[int]) -> Iterator[tuple[int, list[int], list[Outcome]]]:
    """Results as they come; a worker process that died (killed, out of memory) is a RunError
    that says what was kept."""
    try:
        yield from runs
    except BrokenProcessPool:
        kept = f"the {len(saved)} finished case(s) are kept in {parts}; rerun with --resume" if parts else \
            "no output file was given, nothing was kept"
        raise RunError(f"a worker process died (killed, or out of memory?): {kept}") from None


def _free_bytes(folder: Path) -> int:
    try:
        st = os.statvfs(folder)
    except OSError:
        return 1 << 62
    return st.f_bavail * st.f_frsize


def _no_case_message(plan: SweepPlan, errors: dict[int, str]) -> str:
    """No case could be built: each message once, with the cases it concerns."""
    by_msg: dict[str, list[str]] = {}
    for i, msg in errors.items():
        by_msg.setdefault(msg, []).append(plan.cases[i].label)
    lines = []
    for msg, labels in by_msg.items():
        where = "" if len(plan.cases) == 1 else (
            " (every case)" if len(labels) == len(plan.cases) else f" (cases {'; '.join(labels[:4])}"
                                                                   f"{' ...' if len(labels) > 4 else ''})")
        lines.append(msg[:500] + where)
    return "no case could be built: " + "\n  ".join(lines[:10])


def run_config(cfg: Config, config_text: str = "", output: str | Path | None = None) -> xr.Dataset:
    """Run one validated scene (no sweep); write `output` if given; return the results Dataset."""
    plan = SweepPlan([], [SweepCase((), {}, cfg, ())], config_text, "")
    return run_plan(plan, output)
