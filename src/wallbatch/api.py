"""The public Python API: load a config, check it, run it. The command line is a thin layer over it.

    import wallbatch
    plan = wallbatch.load("sweeps/lj93-epsilon-sigma-cutoff.yaml", sets=["run.steps=200"])
    report = wallbatch.check(plan)          # every case validated and built, nothing run
    ds = wallbatch.run(plan, "out.nc", jobs=2)   # an xarray.Dataset, also written to out.nc
"""

from __future__ import annotations

import os
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from wallbatch.config.models import Config
from wallbatch.config.source import SourceMap
from wallbatch.config.sweep import SweepPlan, config_to_dict, expand, load_plan, parse_set
from wallbatch.engine import backend
from wallbatch.engine.engine import sample_instants
from wallbatch.batch.runner import build_cases, check_layout, make_tasks, run_plan
from wallbatch.scene.case import Case, StochasticSpec

if TYPE_CHECKING:
    import xarray as xr

ConfigLike = str | os.PathLike | SweepPlan | Config | Mapping[str, Any]

__all__ = ["load", "run", "check", "CheckReport", "BatchPlan"]


def _plain(value: Any) -> Any:
    """Config data from Python with NumPy's arrays and scalars as the lists and numbers of the
    config language (sweep values from np.linspace, say), so that it validates and the plan's
    sweep text can be written as YAML."""
    if isinstance(value, Mapping):
        return {k: _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return type(value)(_plain(v) for v in value)
    if type(value).__module__ == "numpy":  # ndarray -> nested lists, np.float32(1) -> 1.0 (no NumPy import)
        return _plain(value.tolist()) if hasattr(value, "tolist") else value
    return value


def load(config: ConfigLike, sets: Sequence[str] | Mapping[str, Any] = ()) -> SweepPlan:
    """A validated plan: every case of the config's sweep, each a validated `Config`.

    ``config`` is a path to a scene or sweep YAML file, a `Config`, a plain mapping in the config
    language (its numbers may be NumPy scalars and its lists NumPy arrays: sweep values from
    np.linspace, say), or a plan (returned as is when ``sets`` is empty). ``sets`` overrides values by
    dotted path, as ``--set`` does: ``["walls.zw.zlo.epsilon=2"]`` or ``{"walls.zw.zlo.epsilon": 2}``.
    One ``"path=value"`` string is one override.
    Raises `wallbatch.config.source.ConfigError` (one line per problem, with file:line:col).
    """
    if isinstance(sets, str):  # one override, not its characters one by one
        sets = [sets]
    if isinstance(config, SweepPlan):
        if sets:
            raise ValueError("sets apply to a path, a Config or a mapping, not to a loaded plan")
        return config
    if isinstance(config, (str, os.PathLike)):
        items = [f"{k}={v}" for k, v in sets.items()] if isinstance(sets, Mapping) else list(sets)
        return load_plan(Path(config), items)
    data = config_to_dict(config) if isinstance(config, Config) else _plain(dict(config))
    overrides = _plain(dict(sets)) if isinstance(sets, Mapping) else dict(parse_set(s) for s in sets)
    base_dir = getattr(config, "_base_dir", Path("."))
    return expand(data, SourceMap("<config>", {}, data), "", base_dir, overrides or None)


def run(config: ConfigLike, output: str | os.PathLike | None = None, *, sets: Sequence[str] | Mapping[str, Any] = (),
        jobs: int = 1, executor: str = "local", scheduler: str | None = None, resume: bool = False,
        fresh: bool = False, overwrite: bool = True, progress: bool | None = None,
        log: Callable[[str], None] | None = None) -> xr.Dataset:
    """Run every case of ``config`` (see `load`) and return the results as an `xarray.Dataset`.

    With ``output``, the dataset is also written there as NetCDF and each finished case is kept
    in ``OUTPUT.parts/`` until the end (``resume=True`` reuses them after an interruption).
    Parts left by an earlier run are reused with ``resume=True``, discarded with ``fresh=True``;
    with neither, `wallbatch.batch.runner.RunError` is raised. ``overwrite=False`` refuses an
    existing output. Ctrl-C raises `wallbatch.batch.runner.Interrupted` (finished cases kept).
    ``jobs`` local processes (at most the cores), or ``executor="dask"`` with a ``scheduler``
    address. ``log`` receives one-line notes (cases reused, kernels compiling).
    """
    plan = load(config, sets)
    return run_plan(plan, output, jobs=jobs, executor=executor, scheduler=scheduler, resume=resume, fresh=fresh,
                    overwrite=overwrite, progress=progress, log=log)


@dataclass
class BatchPlan:
    """One batch of same-structure cases as the engine will run it."""

    cases: list[int]  # indices into the plan's cases
    natoms: int
    units: str
    dt: float
    steps: int | None
    run_time: float | None
    samples: int
    kernels: list[str]


@dataclass
class CheckReport:
    """What `check` found: the plan, the cases that cannot be built, the batches."""

    plan: SweepPlan
    errors: dict[int, str] = field(default_factory=dict)  # case index -> message
    batches: list[BatchPlan] = field(default_factory=list)

    @property
    def ok(self) -> bool:
        return not self.errors

    @property
    def atom_steps(self) -> int:
        return sum(b.steps * b.natoms * len(b.cases) for b in self.batches if b.steps is not None)

    def lines(self, name: str = "config") -> list[str]:
        """The report as `wallbatch check` prints it."""
        n = len(self.plan.cases)
        out = [f"{name}: valid, {n} case(s)" if self.ok else
               f"{name}: the config is valid, but {len(self.errors)} of {n} case(s) cannot be built"]
        for d in self.plan.dims:
            vals = ", ".join(str(v) for v in d.values[:8]) + (" ..." if len(d.values) > 8 else "")
            out.append(f"  dimension {d.name} ({len(d.values)}): {vals}   <- {d.path}")
        for n, b in enumerate(self.batches, 1):
            length = f"steps: {b.steps}" if b.steps is not None else f"time: {b.run_time}"
            out.append(f"  batch {n}: {len(b.cases)} case(s); atoms: {b.natoms}; units: {b.units}; dt: {b.dt}; "
                       f"{length}; samples: {b.samples}")
            out.append(f"    kernels: {', '.join(b.kernels)}")
        if self.atom_steps:
            out.append(f"  total atom-steps: {self.atom_steps:,}")
        out.append(f"  {backend.describe(self.plan)}")  # NumPy or compiled, chosen for the whole plan
        return out


def kernels(case: Case) -> list[str]:
    """The fixes a case runs, in LAMMPS's words, in the order the engine applies them."""
    if case.fixes is None:
        names = ["nve/asphere" if case.shape is not None else "nve"]
    else:  # fixes: integrators and thermostats (enforce2d acts after the forces; listed here too)
        names = [f"{f.style} {f.fix_id}" for f in case.fixes]
    names += [f"wall/reflect{'/stochastic' if isinstance(w, StochasticSpec) else ''} {w.fix_id}"
              for w in case.reflect_walls]
    if case.pair is not None:
        names.append("pair lj/cut")
    names += [f"wall/{w.style.name} {w.fix_id}" for w in case.soft_walls]
    names += [f"wall/{w.kind} {w.fix_id}" for w in case.region_walls]
    names += [f"wall/flow {w.fix_id}" for w in case.flow_walls]
    if case.dt_reset is not None:
        names.append("dt/reset")
    return names


def check(config: ConfigLike, sets: Sequence[str] | Mapping[str, Any] = (), jobs: int = 1) -> CheckReport:
    """Validate every case of ``config`` and build it, without running: the plan and its batches.

    Raises `ConfigError` for an invalid config and `wallbatch.scene.case.CaseError` when the cases
    cannot share the results layout; cases that cannot be built are listed in ``errors``.
    """
    plan = load(config, sets)
    cases, errors = build_cases(plan)
    check_layout(plan, cases)
    built = {i: c for i, c in enumerate(cases) if c is not None}
    report = CheckReport(plan, dict(errors))
    for t in make_tasks(built, jobs) if built else []:
        c = built[t[0]]
        report.batches.append(BatchPlan(list(t), c.natoms, c.units.name, c.dt, c.steps, c.run_time,
                                        len(sample_instants(c)), kernels(c)))
    return report

