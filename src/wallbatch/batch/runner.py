"""From a validated plan to a results file: build every case, split same-structure cases into
batches, run them (in this process, in local worker processes or on a dask.distributed cluster),
persist each finished case under `OUT.parts/`, and assemble the NetCDF at the end.

Only this process writes files; workers return results. A case's outputs do not depend on the
batch it ran in or the worker that ran it (random streams come from its sweep coordinates), so
`--jobs`, the executor and `--resume` never change a number.
"""

from __future__ import annotations

import contextlib
import ctypes
import hashlib
import json
import math
import os
import shutil
import signal
import sys
import threading
import time
from concurrent.futures import ProcessPoolExecutor, as_completed
from concurrent.futures.process import BrokenProcessPool
from pathlib import Path
from typing import Callable, Iterator

import numpy as np
import xarray as xr

from wallbatch.version import __version__
from wallbatch.config.models import Config, lattice_spacing
from wallbatch.config.sweep import SweepCase, SweepPlan, config_to_dict
from wallbatch.engine import compiled
from wallbatch.engine.engine import CaseResult, run_cases
from wallbatch.io.amber import write_amber
from wallbatch.io.netcdf import build_dataset, write_netcdf
from wallbatch.scene.build import build_case
from wallbatch.scene.case import Case, CaseError, structure_key

MAX_BATCH = 256  # cases per task: big enough to amortise Python overhead, small enough to resume
MAX_BATCH_ATOMS = 1_000_000  # atoms per task (all its cases): bounds a running batch's memory (~450 MB)
MAX_STEPS = 10**12  # steps of one case (10^12 steps of one atom take days)
MAX_SAMPLES = 1_000_000  # samples of one case (each a row of every output)
PART_FORMAT = 2  # layout of a part file (a part of another layout is recomputed)


class RunError(Exception):
    """A run that cannot start or finish for a reason the user can fix: the output path, leftover
    parts, another run holding the output, a full disk. The message says what to do."""


class Interrupted(Exception):
    """The run was stopped (Ctrl-C, SIGTERM, SIGHUP); every finished case is kept in the parts."""

    def __init__(self, saved: int, total: int, parts: Path | None):
        self.saved, self.total, self.parts = saved, total, parts
        where = f"saved in {parts}; rerun with --resume" if parts is not None else "finished (no output file)"
        super().__init__(f"interrupted: {saved}/{total} cases {where}")


def build_cases(plan: SweepPlan, seconds: list[float] | None = None) -> tuple[list[Case | None], dict[int, str]]:
    """Build every case; a case that cannot be built (bad input, a variable that divides by zero,
    anything raised while building) fails alone, its message kept. `seconds`, if given, receives
    each case's build time."""
    built: list[Case | None] = []
    errors: dict[int, str] = {}
    for i, sc in enumerate(plan.cases):
        t0 = time.perf_counter()
        try:
            case = build_case(sc.config, sc.seed_key)
            structure_key(case)  # evaluates constant variables: a division by zero fails this case here
            check_size(case)
            built.append(case)
        except CaseError as exc:
            built.append(None)
            errors[i] = str(exc)
        except ValueError as exc:  # a variable that cannot be evaluated, a bad value met while building
            built.append(None)
            errors[i] = f"cannot set up the case: {str(exc)[:300]}"
        except (ArithmeticError, TypeError, LookupError, MemoryError, RecursionError) as exc:
            built.append(None)
            errors[i] = f"cannot set up the case: {type(exc).__name__}: {str(exc)[:300]}"
        if seconds is not None:
            seconds.append(time.perf_counter() - t0)
    return built, errors


MAX_ATOMS = 100_000_000  # atoms of one case
HELD_BYTES_PER_ATOM = 80  # a built case waiting to run (measured: 73 B/atom)
RUN_BYTES_PER_ATOM = 450  # a running batch at its peak (measured: 425 B/atom, flat walls)
LATTICE_BASIS = {"sc": 1, "bcc": 2, "fcc": 4}


def estimate_atoms(cfg: Config) -> int:
    """Atoms a config will create, from the config alone (an upper bound for lattices: the whole
    box; atoms files are not opened and count 0 here)."""
    n = 0
    for g in cfg.atoms:
        c = g.create
        if c.random is not None:
            n += c.random.count
        elif c.positions is not None:
            n += len(c.positions)
        elif c.lattice is not None and cfg.lattice is not None:
            spacing = lattice_spacing(cfg)
            volume = float(np.prod(np.subtract(cfg.box.hi, cfg.box.lo)))
            if spacing and spacing > 0:
                n += int(min(volume / spacing ** 3 * LATTICE_BASIS.get(cfg.lattice.style, 4), 1e18))
    return n


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
    """Refuse, before building anything, a plan whose atoms cannot fit in memory: every case is
    built first (HELD_BYTES_PER_ATOM each), then the running batches need RUN_BYTES_PER_ATOM."""
    atoms = [estimate_atoms(sc.config) for sc in plan.cases]
    if not atoms:
        return
    big = max(range(len(atoms)), key=atoms.__getitem__)
    if atoms[big] > MAX_ATOMS:
        which = f"case {plan.cases[big].label}" if plan.dims else "the scene"
        raise RunError(f"{which} would create {atoms[big]:,} atoms, more than the limit of {MAX_ATOMS:,}")
    total = sum(atoms)
    running = max(atoms[big], min(atoms[big] * MAX_BATCH, MAX_BATCH_ATOMS)) * max(1, jobs)  # tasks at once
    need = HELD_BYTES_PER_ATOM * total + RUN_BYTES_PER_ATOM * min(total, running)
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


def _layout(case: Case) -> tuple:
    """What must agree between cases for their results to share one dataset."""
    return (case.steps, case.run_time, case.thermo, case.thermo_is_time, case.outputs,
            tuple((w.fix_id, tuple(f.label for f in w.faces)) for w in case.soft_walls),
            tuple((w.fix_id, tuple(f.label for f in w.faces)) for w in case.reflect_walls),
            case.units.name,
            tuple((p.name, p.axis, p.lo, p.delta, p.nbins, p.every, p.repeat, p.freq, p.quantities)
                  for p in case.profiles), case.average_start)


def check_layout(plan: SweepPlan, cases: list[Case | None]) -> None:
    """All cases must share sample instants, outputs and wall faces to share one results file."""
    good = [c for c in cases if c is not None]
    if not good:
        return
    ref = _layout(good[0])
    for sc, c in zip(plan.cases, cases):
        if c is not None and _layout(c) != ref:
            raise CaseError(f"case {sc.label} changes the sample instants, outputs or walls of the results "
                            f"(e.g. run.steps, run.thermo or a wall style): such values cannot be swept into one file")


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
    try:
        return len(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        return os.cpu_count() or 1


def _watch_parent(parent: int) -> None:
    while True:
        time.sleep(0.5)
        if os.getppid() != parent:
            os._exit(1)


def _worker_init(parent: int) -> None:
    """In each worker: Ctrl-C is the parent's business (it stops the workers), and a worker dies
    with its parent (Linux parent-death signal, and a watcher thread elsewhere)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    for sig in (signal.SIGTERM, signal.SIGHUP):  # not the parent's handlers (inherited by fork): end now
        signal.signal(sig, signal.SIG_DFL)
    with contextlib.suppress(Exception):
        ctypes.CDLL(None, use_errno=True).prctl(1, signal.SIGKILL)  # PR_SET_PDEATHSIG
    if os.getppid() != parent:
        os._exit(1)
    threading.Thread(target=_watch_parent, args=(parent,), daemon=True, name="wallbatch-parent-watch").start()


def _stop_pool(pool: ProcessPoolExecutor) -> None:
    """Cancel pending tasks and end the workers now (they hold no state worth keeping)."""
    procs = list((getattr(pool, "_processes", None) or {}).values())
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


def execute(tasks: list[list[Case]], jobs: int = 1, executor: str = "local",
            scheduler: str | None = None) -> Iterator[tuple[int, list[CaseResult]]]:
    """Run tasks; yield (task index, results) as each finishes. Closing the generator early (an
    interrupt) cancels the pending tasks and stops the workers."""
    if executor == "dask":
        from distributed import Client
        from distributed import as_completed as dask_completed

        with Client(scheduler) as client:
            futures = {client.submit(_run_task, t, pure=False): k for k, t in enumerate(tasks)}
            try:
                for fut in dask_completed(futures):
                    yield futures[fut], fut.result()
            except BaseException:
                client.cancel(list(futures))
                raise
    elif jobs <= 1 or len(tasks) <= 1:
        for k, t in enumerate(tasks):
            yield k, _run_task(t)
    else:
        pool = ProcessPoolExecutor(max_workers=min(jobs, len(tasks)), initializer=_worker_init,
                                   initargs=(os.getpid(),))
        try:
            futures = {pool.submit(_run_task, t): k for k, t in enumerate(tasks)}
            for fut in as_completed(futures):
                yield futures[fut], fut.result()
        except BaseException:
            _stop_pool(pool)
            raise
        pool.shutdown(wait=True)


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


def case_key(sc: SweepCase) -> str:
    """Identity of a case for resuming: its full validated config and random stream."""
    blob = json.dumps([config_to_dict(sc.config), sc.seed_key, __version__], sort_keys=True, default=str)
    return hashlib.sha256(blob.encode()).hexdigest()[:24]


def parts_dir(output: Path) -> Path:
    return output.with_name(output.name + ".parts")


def dump_path(output: Path, sc: SweepCase) -> Path:
    """Trajectory file of a case: OUT.dump/<coordinates>.nc (OUT.dump/case.nc without a sweep)."""
    name = "_".join(f"{k}={v}" for k, v in sc.coords.items()) or "case"
    safe = "".join(ch if ch.isalnum() or ch in "=._-" else "-" for ch in name)
    return output.with_name(output.stem + ".dump") / f"{safe}.nc"


def write_dump(path: Path, case: Case, res: CaseResult) -> None:
    if res.frames.get("time") is not None and len(res.frames["time"]):
        write_amber(path, res.frames["time"], res.frames.get("x"), res.frames.get("v"), case.box_lo, case.box_hi,
                    case.units.name, title=f"wallbatch {case.name}")


def _digest(key: str, status: str, error: str, seconds: float, data: dict[str, np.ndarray]) -> str:
    """Content hash of a part: its case key, status, message, seconds and every array."""
    h = hashlib.sha256(f"{PART_FORMAT}|{key}|{status}|{error}|{seconds!r}".encode())
    for name in sorted(data):
        arr = np.ascontiguousarray(data[name])
        h.update(f"|{name}|{arr.dtype.str}|{arr.shape}|".encode())
        h.update(arr.tobytes())
    return h.hexdigest()


def save_part(folder: Path, key: str, res: CaseResult) -> None:
    """One finished case as a small .npz carrying its case key and a content hash, written to a
    temporary file and renamed (a part is complete or absent). Disk full: RunError."""
    tmp = folder / f".{key}.tmp.npz"
    arrays = {f"data__{k}": v for k, v in res.data.items()}
    digest = _digest(key, res.status, res.error, float(res.seconds), res.data)
    try:
        folder.mkdir(parents=True, exist_ok=True)
        np.savez(tmp, status=np.str_(res.status), error=np.str_(res.error), seconds=np.float64(res.seconds),
                 case_key=np.str_(key), digest=np.str_(digest), **arrays)
        os.replace(tmp, folder / f"{key}.npz")
    except OSError as exc:
        with contextlib.suppress(OSError):
            tmp.unlink()
        raise RunError(f"cannot save a finished case in {folder}: {exc.strerror or exc}"
                       + ("; free some space, then rerun with --resume (the finished cases are kept)"
                          if getattr(exc, "errno", None) == 28 else "")) from None


def read_part(folder: Path, key: str) -> tuple[CaseResult | None, str]:
    """The part of a case, checked: (result, "") or (None, why it is not usable) - "" when absent."""
    path = folder / f"{key}.npz"
    if not path.exists():
        return None, ""
    try:
        with np.load(path, allow_pickle=False) as z:
            data = {k[6:]: z[k] for k in z.files if k.startswith("data__")}
            status, error, seconds = str(z["status"]), str(z["error"]), float(z["seconds"])
            stored_key = str(z["case_key"]) if "case_key" in z.files else ""
            digest = str(z["digest"]) if "digest" in z.files else ""
    except Exception as exc:  # noqa: BLE001 - any unreadable file (truncated, bit flip, empty) is recomputed
        return None, f"damaged ({type(exc).__name__})"
    if stored_key != key:
        return None, "belongs to another case" if stored_key else "has no case key (older format)"
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
             log: Callable[[str], None] | None = None) -> xr.Dataset:
    """Run every case of a plan; write `output` if given; return the results Dataset.

    With `output`, each finished case is persisted under OUT.parts/ as it completes and a lock file
    OUT.lock keeps other runs away. Parts left by an earlier run: `resume` reuses those whose case
    (full config and seed) is unchanged, `fresh` discards them, neither refuses (RunError). The
    parts are removed once the final file is written. Ctrl-C, SIGTERM or SIGHUP stop the workers
    and raise `Interrupted` (every finished case stays in the parts). `log` receives one-line
    notes (cases reused, kernels compiling, jobs capped)."""
    say = log or (lambda msg: None)
    if output is None:
        return _run(plan, None, jobs, executor, scheduler, False, progress, on_result, say)
    output = Path(output)
    # resuming continues a run that was writing this output: its old version may be replaced
    check_output(output, plan.inputs, overwrite or (resume and parts_dir(output).is_dir()))
    with output_lock(output):
        parts = parts_dir(output)
        if parts.exists() and not resume:
            found = sum(1 for p in parts.glob("*.npz") if not p.name.startswith("."))
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
        return _run(plan, output, jobs, executor, scheduler, resume, progress, on_result, say)


def _run(plan: SweepPlan, output: Path | None, jobs: int, executor: str, scheduler: str | None, resume: bool,
         progress: bool | None, on_result: Callable[[int, CaseResult], None] | None,
         say: Callable[[str], None]) -> xr.Dataset:
    total = len(plan.cases)
    parts = parts_dir(output) if output is not None else None
    saved: set[int] = set()  # cases whose part exists
    finished = 0  # cases run (without an output file)
    try:
        with stop_on_signals():
            check_memory(plan, jobs if executor == "local" else 1)
            build_seconds: list[float] = []
            cases, errors = build_cases(plan, build_seconds)
            good = [c for c in cases if c is not None]
            if not good:
                raise CaseError(_no_case_message(plan, errors))
            check_layout(plan, cases)
            results: list[CaseResult | None] = [None] * len(cases)
            for i, msg in errors.items():
                results[i] = CaseResult("failed", msg, build_seconds[i], {})
            keys = [case_key(sc) for sc in plan.cases]
            if parts is not None and resume:
                bad: dict[str, int] = {}
                for i in range(len(cases)):
                    if results[i] is None:
                        res, why = read_part(parts, keys[i])
                        if res is not None:
                            results[i] = res
                            saved.add(i)
                        elif why:
                            bad[why] = bad.get(why, 0) + 1
                note = "; ".join(f"{n} part(s) {why}: recomputed" for why, n in bad.items())
                say(f"resuming: {len(saved)} of {total} case(s) reused from {parts}" + (f"; {note}" if note else ""))
            todo = {i: c for i, c in enumerate(cases) if c is not None and results[i] is None}
            bar = Progress(len(cases), progress)
            bar.update([r for r in results if r is not None])
            cores = usable_cores()
            if executor == "local" and jobs > cores:
                say(f"--jobs {jobs} capped at {cores} (the cores this machine lets the run use)")
                jobs = cores
            tasks = make_tasks(todo, jobs)
            if executor == "local" and jobs > len(tasks) > 0:
                jobs = len(tasks)
            dumps = good[0].dump_every > 0 and output is not None
            runs = execute([[todo[i] for i in t] for t in tasks], jobs, executor, scheduler)
            try:
                for k, batch in _worker_deaths(runs, parts, saved):
                    for i, res in zip(tasks[k], batch):
                        res.seconds += build_seconds[i]
                        if dumps:
                            write_dump(dump_path(output, plan.cases[i]), cases[i], res)
                            res.frames = {}
                        results[i] = res
                        if parts is not None:
                            save_part(parts, keys[i], res)
                            saved.add(i)
                        finished += 1
                        if on_result is not None:
                            on_result(i, res)
                    bar.update(batch)
            finally:
                runs.close()
            paths = None
            if dumps:
                paths = [str(dump_path(output, sc).relative_to(output.parent)) if (
                    dump_path(output, sc).exists()) else "" for sc in plan.cases]
            ds = build_dataset(results, good[0], config_text=plan.base_text, sweep_text=plan.sweep_text,
                               dims=plan.dims, dump_paths=paths)
            if output is not None:
                try:
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


def _worker_deaths(runs: Iterator[tuple[int, list[CaseResult]]], parts: Path | None,
                   saved: set[int]) -> Iterator[tuple[int, list[CaseResult]]]:
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
