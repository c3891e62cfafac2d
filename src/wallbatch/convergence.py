"""Speed against error for any scene: `wallbatch convergence`.

One case of a config is run at a ladder of timesteps over the same simulated time, sampled at the
same instants (or, for a scene with fix dt/reset, at a ladder of dt/reset's ``xmax``). For every
sampled output the error of each run is measured against the finest run of the ladder, and the
observed order p is fitted (error ~ h^p, h = dt or xmax), next to the cost (seconds,
atom-steps/s) and the energy drift, so a user picks the cheapest timestep that meets a tolerance.

Error of an output: the relative RMS difference to the reference over all samples (and faces,
fixes): ``sqrt(mean((a - b)^2)) / sqrt(mean(b^2))``. Energy drift: ``|slope|`` of a least-squares
line through etot(t), per atom [energy/time]. Observed order: the least-squares slope of
log(error) against log(h) over the non-reference runs with a positive error.
"""

from __future__ import annotations

import copy
import math
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import xarray as xr

from wallbatch.api import load
from wallbatch.batch.runner import run_plan
from wallbatch.config.models import config_from_dict
from wallbatch.config.source import ConfigError
from wallbatch.config.sweep import SweepCase, SweepPlan, config_to_dict
from wallbatch.lammps.export import select_case
from wallbatch.scene.build import build_case
from wallbatch.units import UNIT_SYSTEMS

NOT_COMPARED = ("step", "time", "dt", "atoms", "status", "error", "seconds", "dump_path")
LEVELS = (2.0, 1.0, 0.5, 0.25, 0.125)  # default ladder: the scene's dt (or xmax) times these


class ConvergenceError(ValueError):
    """A scene or ladder that cannot be compared run against run."""


@dataclass
class Point:
    """One run of the ladder: its h (dt or xmax), cost and errors against the reference."""

    h: float
    steps: int
    seconds: float
    natoms: int
    drift: float  # |d etot/dt| per atom [energy/time], NaN without etot
    errors: dict[str, float] = field(default_factory=dict)  # output -> relative RMS error (0 for the reference)
    status: str = "ok"

    @property
    def atom_steps_per_s(self) -> float:
        return self.natoms * self.steps / self.seconds if self.seconds > 0 else math.nan


class UnknownOutput(ConvergenceError):
    """An output name (`recommend`'s, `convergence`'s ``outputs``) that the ladder does not compare."""


def _check_names(names: Sequence[str], compared: Sequence[str]) -> None:
    """UnknownOutput naming those of `names` not among the `compared` outputs (and listing them)."""
    unknown = [n for n in names if n not in compared]
    if unknown:
        raise UnknownOutput(f"no output named {', '.join(unknown)}; outputs: {', '.join(compared)}")


@dataclass
class ConvergenceReport:
    """The ladder's runs, the observed orders, and the results with a ``dt`` (or ``xmax``) dimension."""

    dim: str  # "dt" or "xmax"
    points: list[Point]  # coarsest first; the last one is the reference
    orders: dict[str, float]
    dataset: xr.Dataset

    @property
    def outputs(self) -> list[str]:
        return list(self.orders)

    def recommend(self, rtol: float, outputs: Sequence[str] | None = None) -> Point | None:
        """The cheapest (largest h) non-reference run whose error is <= rtol for every output
        (or for the named ones); None when none meets it."""
        names = list(outputs) if outputs else self.outputs
        _check_names(names, self.outputs)
        ok = [p for p in self.points[:-1] if p.status == "ok"
              and all(not (p.errors.get(n, math.nan) > rtol) for n in names)]
        return max(ok, key=lambda p: p.h) if ok else None

    def table(self) -> str:
        """A Markdown table, one row per run, then the observed orders."""
        head = [self.dim, "steps", "seconds", "atom-steps/s", "drift/atom/time"] + self.outputs
        rows = ["| " + " | ".join(head) + " |", "|" + " --- |" * len(head)]
        for i, p in enumerate(self.points):
            ref = i == len(self.points) - 1
            errs = ["ref" if ref else f"{p.errors.get(n, math.nan):.2e}" for n in self.outputs]
            rows.append("| " + " | ".join([f"{p.h:g}", str(p.steps), f"{p.seconds:.3f}", f"{p.atom_steps_per_s:.3g}",
                                           f"{p.drift:.2e}"] + errs) + " |")
        orders = ", ".join(f"{n} {o:.2f}" for n, o in self.orders.items())
        drift = _order([p.h for p in self.points[:-1]], [p.drift for p in self.points[:-1]])
        return "\n".join(rows) + f"\n\nobserved order in {self.dim}: {orders}; energy drift {drift:.2f}"


def _order(h: Sequence[float], err: Sequence[float]) -> float:
    """Least-squares slope of log(err) against log(h) over the positive, finite errors."""
    pts = [(math.log(a), math.log(b)) for a, b in zip(h, err) if b > 0 and math.isfinite(b)]
    if len(pts) < 2:
        return math.nan
    x, y = np.array(pts).T
    return float(np.polyfit(x, y, 1)[0])


def _ratio(total: float, h: float, what: str) -> int:
    n = total / h
    k = round(n)
    if k < 1 or abs(n - k) > 1e-9 * max(1.0, n):
        raise ConvergenceError(f"{what} = {total:g} is not a whole number of steps of {h:g}: choose timesteps that "
                               f"divide it (e.g. the scene's timestep times 2, 1, 1/2, 1/4, ...)")
    return k


def _ladder_configs(data: dict, dim: str, values: Sequence[float], dt0: float) -> list[dict]:
    """The config of every run: same simulated time and sample instants, timestep (or xmax) changed."""
    out = []
    for h in values:
        d = copy.deepcopy(data)
        d.get("output", {}).pop("dump", None)
        if dim == "xmax":
            d["dt_reset"]["xmax"] = h
        else:
            d["timestep"] = h
            run = d["run"]
            if run.get("steps") is not None:
                total = run["steps"] * dt0
                run["steps"] = _ratio(total, h, "the run's simulated time (run.steps x timestep)")
                if isinstance(run.get("thermo"), int) and run["thermo"] > 0:
                    run["thermo"] = _ratio(run["thermo"] * dt0, h, "the sample interval (run.thermo x timestep)")
        out.append(d)
    return out


def _errors(ds: xr.Dataset, ref: xr.Dataset) -> dict[str, float]:
    out = {}
    for name, var in ref.data_vars.items():
        if name in NOT_COMPARED or "sample" not in var.dims or var.dtype.kind not in "fiu":
            continue
        a, b = np.asarray(ds[name], float), np.asarray(var, float)
        scale = math.sqrt(float(np.mean(b * b)))
        out[name] = math.sqrt(float(np.mean((a - b) ** 2))) / scale if scale > 0 else math.nan
    return out


def _drift(ds: xr.Dataset, natoms: int) -> float:
    if "etot" not in ds or ds.sizes.get("sample", 0) < 2:
        return math.nan
    t, e = np.asarray(ds["time"], float), np.asarray(ds["etot"], float)
    if not (np.all(np.isfinite(t)) and np.all(np.isfinite(e))):
        return math.nan
    return abs(float(np.polyfit(t, e, 1)[0])) / natoms


def convergence(config: Any, *, case: str | None = None, dts: Sequence[float] | None = None,
                xmaxs: Sequence[float] | None = None, sets: Sequence[str] | Mapping[str, Any] = (),
                jobs: int = 1, outputs: Sequence[str] | None = None) -> ConvergenceReport:
    """Run one case of ``config`` at a ladder of timesteps (or dt/reset ``xmax`` values) and
    measure errors against the finest run; see the module docstring for the definitions.

    ``dts``/``xmaxs``: the ladder (any order; the smallest is the reference); default: the
    scene's value times 2, 1, 1/2, 1/4, 1/8. ``case`` selects a case of a sweep (an index or
    ``name=value,...``). ``outputs``: names the caller will ask `recommend` about, checked against
    the compared outputs after the first (warm-up) run, before the ladder runs.
    """
    plan = load(config, sets)
    sc: SweepCase = select_case(plan, case)
    cfg = sc.config
    data = config_to_dict(cfg)
    if cfg.dt_reset is not None:
        if dts:
            raise ConvergenceError("the scene has dt_reset, which sets the timestep: give --xmax values, not --dt")
        if cfg.run.time is None:
            raise ConvergenceError("a dt_reset scene is compared over a fixed simulated time: write "
                                   "run: {time: T, thermo: {time: S}} instead of run.steps")
        dim, h0, ladder = "xmax", cfg.dt_reset.xmax, xmaxs
    else:
        if xmaxs:
            raise ConvergenceError("--xmax needs a scene with dt_reset; give --dt values instead")
        dim, ladder = "dt", dts
        h0 = cfg.timestep if cfg.timestep is not None else UNIT_SYSTEMS[cfg.units].dt
    values = sorted({float(v) for v in (ladder or [h0 * f for f in LEVELS])}, reverse=True)
    if len(values) < 3 or any(not (v > 0 and math.isfinite(v)) for v in values):
        raise ConvergenceError(f"give at least three positive {dim} values (got {values})")
    configs = _ladder_configs(data, dim, values, h0 if dim == "dt" else 0.0)
    base_dir = getattr(cfg, "_base_dir", Path("."))
    runs: list[xr.Dataset] = []
    natoms = 0
    for i, d in enumerate(configs):
        try:
            c = config_from_dict(d, base_dir)
        except ConfigError as exc:
            raise ConvergenceError(f"{dim} = {values[i]:g}: {exc}") from None
        one = SweepPlan([], [SweepCase((), {}, c, sc.seed_key)], "", "")
        natoms = build_case(c, sc.seed_key).natoms
        if i == 0:  # warm-up: load (or compile) the kernels before anything is timed
            first = run_plan(one, None, jobs=1, progress=False)
            _check_names(outputs or (), list(_errors(first, first)))
        runs.append(run_plan(one, None, jobs=1, progress=False))
    ref = runs[-1]
    if str(ref["status"].values) != "ok":
        raise ConvergenceError(f"the reference run ({dim} = {values[-1]:g}) failed: {ref['error'].values}")
    points = []
    for h, ds in zip(values, runs):
        steps = int(np.asarray(ds["step"])[-1])
        points.append(Point(h, steps, float(ds["seconds"]), natoms, _drift(ds, natoms), _errors(ds, ref),
                            str(ds["status"].values)))
    names = list(points[0].errors)
    orders = {n: _order([p.h for p in points[:-1]], [p.errors[n] for p in points[:-1]]) for n in names}
    dataset = _combine(runs, dim, values)
    u = UNIT_SYSTEMS[cfg.units]
    dataset[dim].attrs["units"] = u.time if dim == "dt" else (u.distance if cfg.dt_reset.units == "box" else "lattice")
    # the provenance every results file carries (outputs.md): the run's config and sweep as YAML
    # text, the case compared and when; concat drops what differs between runs ("created")
    dataset.attrs.update(config=plan.base_text, sweep=plan.sweep_text, created=runs[-1].attrs.get("created", ""))
    if case is not None:
        dataset.attrs["convergence_case"] = str(case)
    return ConvergenceReport(dim, points, orders, dataset)


def _combine(runs: list[xr.Dataset], dim: str, values: list[float]) -> xr.Dataset:
    """One dataset with a leading ``dim`` dimension; ``step`` becomes a variable (it differs per run)."""
    parts = []
    for ds in runs:
        ds = ds.reset_coords("step") if "step" in ds.coords else ds
        if dim == "dt" and "dt" in ds:
            ds = ds.drop_vars("dt")  # the per-sample timestep is the dimension's value
        parts.append(ds)
    out = xr.concat(parts, dim=dim, data_vars="all", coords="minimal", compat="override",
                    combine_attrs="drop_conflicts")
    out = out.assign_coords({dim: (dim, np.asarray(values, float))})
    out[dim].attrs["long_name"] = "timestep" if dim == "dt" else "fix dt/reset xmax"
    return out


def plot(report: ConvergenceReport, path: str | os.PathLike) -> Path:
    """Error against cost (log-log) per output, and energy drift against cost."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    pts = report.points[:-1]
    cost = [p.seconds for p in pts]
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.4), constrained_layout=True)
    for n in report.outputs:
        errs = [p.errors[n] for p in pts]
        if any(e > 0 for e in errs):
            axes[0].loglog(cost, errs, "o-", label=f"{n} (order {report.orders[n]:.2f})")
    for p in pts:
        axes[0].annotate(f"{report.dim}={p.h:g}", (p.seconds, max(p.errors.values(), default=1.0) or 1.0),
                         fontsize=7, xytext=(3, 3), textcoords="offset points")
    axes[0].set(xlabel="cost [s]", ylabel="relative RMS error vs the finest run", title="error against cost")
    axes[1].loglog(cost, [p.drift for p in pts], "s-")
    axes[1].set(xlabel="cost [s]", ylabel="|d etot/dt| per atom", title="energy drift against cost")
    for ax in axes:
        ax.grid(True, which="both", alpha=0.3)
    if report.outputs:
        axes[0].legend(fontsize=8)
    Path(path).parent.mkdir(parents=True, exist_ok=True)  # as `wallbatch plot` does
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return Path(path)
