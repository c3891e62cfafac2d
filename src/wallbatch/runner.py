"""From a validated plan to a results file: build every case, run them in batches, write NetCDF."""

from __future__ import annotations

from pathlib import Path

import xarray as xr

from .config import Config
from .engine import CaseResult, run_cases, structure_key
from .output import build_dataset, write_netcdf
from .scene import Case, CaseError, build_case
from .sweep import SweepCase, SweepPlan


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
            case.units.name)


def run_plan(plan: SweepPlan, output: str | Path | None = None) -> xr.Dataset:
    """Run every case of a plan; write `output` if given; return the results Dataset."""
    cases, errors = build_cases(plan)
    good = [c for c in cases if c is not None]
    if not good:
        raise CaseError("no case could be built: " + "; ".join(sorted(set(errors.values())))[:2000])
    ref = _layout(good[0])
    for sc, c in zip(plan.cases, cases):
        if c is not None and _layout(c) != ref:
            raise CaseError(f"case {sc.label} changes the sample instants, outputs or walls of the results "
                            f"(e.g. run.steps or a wall style): such values cannot be swept into one file")
    runnable = [i for i, c in enumerate(cases) if c is not None]
    results: list[CaseResult] = [CaseResult("failed", errors.get(i, ""), 0.0, {}) for i in range(len(cases))]
    for i, res in zip(runnable, run_cases([cases[i] for i in runnable])):
        results[i] = res
    ds = build_dataset(results, good[0], config_text=plan.base_text, sweep_text=plan.sweep_text,
                       dims=plan.dims)
    if output is not None:
        write_netcdf(ds, output)
    return ds


def run_config(cfg: Config, config_text: str = "", output: str | Path | None = None) -> xr.Dataset:
    """Run one validated scene (no sweep); write `output` if given; return the results Dataset."""
    plan = SweepPlan([], [SweepCase((), {}, cfg, ())], config_text, "")
    return run_plan(plan, output)


__all__ = ["run_plan", "run_config", "build_cases", "structure_key"]
