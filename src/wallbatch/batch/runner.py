"""From a validated plan to a results file: build every case, split same-structure cases into
batches, run them (in this process, in local worker processes or on a dask.distributed cluster),
persist each finished case under `OUT.parts/`, and assemble the NetCDF at the end.

Only this process writes files; workers return results. A case's outputs do not depend on the
batch it ran in or the worker that ran it (random streams come from its sweep coordinates), so
`--jobs`, the executor and `--resume` never change a number.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import shutil
import sys
import time
from concurrent.futures import ProcessPoolExecutor, as_completed
from pathlib import Path
from typing import Callable, Iterator

import numpy as np
import xarray as xr

from wallbatch.version import __version__
from wallbatch.config.models import Config
from wallbatch.config.sweep import SweepCase, SweepPlan, config_to_dict
from wallbatch.engine.engine import CaseResult, run_cases
from wallbatch.io.amber import write_amber
from wallbatch.io.netcdf import build_dataset, write_netcdf
from wallbatch.scene.build import build_case
from wallbatch.scene.case import Case, CaseError, structure_key

MAX_BATCH = 256  # cases per task: big enough to amortise Python overhead, small enough to resume


def build_cases(plan: SweepPlan) -> tuple[list[Case | None], dict[int, str]]:
    """Build every case; a case that cannot be built fails alone (its message kept)."""
    built: list[Case | None] = []
    errors: dict[int, str] = {}
    for i, sc in enumerate(plan.cases):
        try:
            built.append(build_case(sc.config, sc.seed_key))
        except CaseError as exc:
            built.append(None)
            errors[i] = str(exc)
    return built, errors


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
    MAX_BATCH cases each), so every worker gets work and each task is still one batch."""
    groups: dict[tuple, list[int]] = {}
    for i, c in cases.items():
        groups.setdefault(structure_key(c), []).append(i)
    tasks = []
    for idx in groups.values():
        size = min(MAX_BATCH, max(1, math.ceil(len(idx) / max(1, jobs))))
        tasks.extend(idx[k:k + size] for k in range(0, len(idx), size))
    return tasks


# ----------------------------------------------------------------------------- executors


def _run_task(cases: list[Case]) -> list[CaseResult]:
    return run_cases(cases)


def execute(tasks: list[list[Case]], jobs: int = 1, executor: str = "local",
            scheduler: str | None = None) -> Iterator[tuple[int, list[CaseResult]]]:
    """Run tasks; yield (task index, results) as each finishes."""
    if executor == "dask":
        from distributed import Client
        from distributed import as_completed as dask_completed

        with Client(scheduler) as client:
            futures = {client.submit(_run_task, t, pure=False): k for k, t in enumerate(tasks)}
            for fut in dask_completed(futures):
                yield futures[fut], fut.result()
    elif jobs <= 1 or len(tasks) <= 1:
        for k, t in enumerate(tasks):
            yield k, _run_task(t)
    else:
        with ProcessPoolExecutor(max_workers=jobs) as pool:
            futures = {pool.submit(_run_task, t): k for k, t in enumerate(tasks)}
            for fut in as_completed(futures):
                yield futures[fut], fut.result()


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


def save_part(folder: Path, key: str, res: CaseResult) -> None:
    """One finished case as a small .npz, written atomically."""
    folder.mkdir(parents=True, exist_ok=True)
    tmp = folder / f".{key}.tmp.npz"
    arrays = {f"data__{k}": v for k, v in res.data.items()}
    np.savez(tmp, status=np.str_(res.status), error=np.str_(res.error), seconds=np.float64(res.seconds), **arrays)
    os.replace(tmp, folder / f"{key}.npz")


def load_part(folder: Path, key: str) -> CaseResult | None:
    path = folder / f"{key}.npz"
    if not path.exists():
        return None
    try:
        with np.load(path, allow_pickle=False) as z:
            data = {k[6:]: z[k] for k in z.files if k.startswith("data__")}
            return CaseResult(str(z["status"]), str(z["error"]), float(z["seconds"]), data)
    except (OSError, ValueError, KeyError):
        return None  # a damaged part is simply recomputed


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


def run_plan(plan: SweepPlan, output: str | Path | None = None, *, jobs: int = 1, executor: str = "local",
             scheduler: str | None = None, resume: bool = False, progress: bool | None = None,
             on_result: Callable[[int, CaseResult], None] | None = None) -> xr.Dataset:
    """Run every case of a plan; write `output` if given; return the results Dataset.

    With `output`, each finished case is persisted under OUT.parts/ as it completes; `resume`
    reuses the parts whose case (full config and seed) is unchanged. The parts are removed once
    the final file is written."""
    cases, errors = build_cases(plan)
    good = [c for c in cases if c is not None]
    if not good:
        raise CaseError("no case could be built: " + "; ".join(sorted(set(errors.values())))[:2000])
    check_layout(plan, cases)
    results: list[CaseResult | None] = [None] * len(cases)
    for i, msg in errors.items():
        results[i] = CaseResult("failed", msg, 0.0, {})
    parts = parts_dir(Path(output)) if output is not None else None
    keys = [case_key(sc) for sc in plan.cases]
    if parts is not None and not resume:
        for old in (parts, Path(output).with_name(Path(output).stem + ".dump")):
            if old.exists():
                shutil.rmtree(old)
    if parts is not None and resume:
        for i in range(len(cases)):
            if results[i] is None and (res := load_part(parts, keys[i])) is not None:
                results[i] = res
    todo = {i: c for i, c in enumerate(cases) if c is not None and results[i] is None}
    bar = Progress(len(cases), progress)
    bar.update([r for r in results if r is not None])
    tasks = make_tasks(todo, jobs)
    dumps = good[0].dump_every > 0 and output is not None
    for k, batch in execute([[todo[i] for i in t] for t in tasks], jobs, executor, scheduler):
        for i, res in zip(tasks[k], batch):
            if dumps:
                write_dump(dump_path(Path(output), plan.cases[i]), cases[i], res)
                res.frames = {}
            results[i] = res
            if parts is not None:
                save_part(parts, keys[i], res)
            if on_result is not None:
                on_result(i, res)
        bar.update(batch)
    paths = None
    if dumps:
        paths = [str(dump_path(Path(output), sc).relative_to(Path(output).parent)) if (
            dump_path(Path(output), sc).exists()) else "" for sc in plan.cases]
    ds = build_dataset(results, good[0], config_text=plan.base_text, sweep_text=plan.sweep_text, dims=plan.dims,
                       dump_paths=paths)
    if output is not None:
        write_netcdf(ds, output)
        if parts is not None and parts.exists():
            shutil.rmtree(parts)
    return ds


def run_config(cfg: Config, config_text: str = "", output: str | Path | None = None) -> xr.Dataset:
    """Run one validated scene (no sweep); write `output` if given; return the results Dataset."""
    plan = SweepPlan([], [SweepCase((), {}, cfg, ())], config_text, "")
    return run_plan(plan, output)
