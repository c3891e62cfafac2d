"""Profiles, time averages with error bars and wall pressure in the results Dataset.

* `profile_<name>_<quantity>` (sweep..., window, <name>_bin): one LAMMPS fix ave/chunk average
  per window; coords `<name>_bin` (bin centres, box units) and `window_step`.
* `<var>_mean`, `<var>_sem`, `<var>_sem_converged` for every per-sample output but step, time
  and dt (over samples at or after `output.averages`), and for every profile (over windows whose
  step is at or after it): the sample mean and its block-averaged standard error
  (wallbatch.stats: Flyvbjerg-Petersen blocking with a documented plateau rule).
* `wall_pressure_mean` / `_sem` / `_sem_converged` (sweep..., face): the normal force on the face
  over its area, positive when the fluid pushes the wall outward (-F/A on lo faces, +F/A on hi
  faces), in the unit system's pressure units. Soft walls: from `wall_force` at each sample.
  Reflect walls: from `reflect_impulse` (needs it in output.thermo), impulse over the interval
  since the previous sample per interval; the mean is total impulse / total time.
"""

from __future__ import annotations

from typing import Any, Sequence

import numpy as np
import xarray as xr

from wallbatch.engine.profiles import output_name
from wallbatch.scene.case import Case
from wallbatch.stats import block_average

NOT_AVERAGED = {"step", "time", "dt"}

PROFILE_LONG = {
    "density/number": "number density",
    "density/mass": "mass density",
    "temp": "temperature (dimension degrees of freedom per atom)",
    "vx": "mean x velocity", "vy": "mean y velocity", "vz": "mean z velocity",
}


def profile_units(case: Case, quantity: str) -> str:
    """Units attribute of a profile quantity in the case's unit system (density/mass in g/cm^3 for
    real and metal, as LAMMPS fix ave/chunk)."""
    u = case.units
    d = int(case.dimension)
    if quantity == "density/number":
        return "1" if u.name == "lj" else f"{u.distance}^-{d}"
    if quantity == "density/mass":
        return "1" if u.name == "lj" else ("g/cm^3" if d == 3 else "1e-8 g/cm^2")  # LAMMPS mv2d
    if quantity == "temp":
        return u.temperature
    return u.velocity


def profile_variables(results: Sequence[Any], case: Case, shape: tuple[int, ...],
                      sweep_dims: tuple[str, ...], filled: dict[str, np.ndarray] | None = None) -> tuple[dict, dict]:
    """Data variables and coords of every profile window, stacked over the cases (C order);
    `filled` (name -> (cases, window, bin) array) gives arrays already stacked (then `results`
    is not read)."""
    data_vars: dict = {}
    coords: dict = {}
    steps = int(case.steps or 0)
    for p in case.profiles:
        wins = p.window_steps(steps)
        bdim = f"{p.name}_bin"
        centres = p.lo + (np.arange(p.nbins) + 0.5) * p.delta
        coords[bdim] = xr.Variable((bdim,), centres, attrs={
            "units": case.units.distance, "long_name": f"{'xyz'[p.axis]} of the bin centre (profile {p.name})"})
        coords["window_step"] = xr.Variable(("window",), np.asarray(wins, np.int64), attrs={
            "units": "1", "long_name": "timestep at which the window's average is taken (LAMMPS Nfreq step)"})
        for q in p.quantities:
            name = output_name(p.name, q)
            if filled is not None:
                arr = filled[name]
            else:
                arr = np.full((len(results), len(wins), p.nbins), np.nan)
                for i, r in enumerate(results):
                    if name in r.data:
                        arr[i] = r.data[name]
            data_vars[name] = xr.Variable(sweep_dims + ("window", bdim), arr.reshape(shape + arr.shape[1:]), attrs={
                "units": profile_units(case, q),
                "long_name": f"{PROFILE_LONG[q]} along {'xyz'[p.axis]}",
                "comment": f"window averages of {p.repeat} samples every {p.every} steps ending at window_step, "
                           f"as LAMMPS fix ave/chunk norm all; empty bins are 0"})
    return data_vars, coords


def _stats(da: xr.DataArray, dim: str) -> tuple[xr.DataArray, xr.DataArray, xr.DataArray]:
    """Mean, sem, converged of `da` along `dim` (block averaging, vectorised over the rest)."""
    moved = da.transpose(..., dim)
    res = block_average(moved.values)
    rest = moved.dims[:-1]
    return (xr.DataArray(res.mean, dims=rest), xr.DataArray(res.sem, dims=rest),
            xr.DataArray(res.converged, dims=rest))


def _put(ds: xr.Dataset, name: str, stats: tuple, units: str, long_name: str, where: str) -> None:
    """Store mean, sem and converged of `name`; `where` (the averaged range) goes to `comment`."""
    mean, sem, conv = stats
    for suffix, value, unit, long in (
            ("_mean", mean, units, f"time mean of {long_name}"),
            ("_sem", sem, units, f"standard error of the time mean of {long_name}"),
            ("_sem_converged", conv, "1", f"block averaging of {name} reached a plateau")):
        ds[name + suffix] = value
        ds[name + suffix].attrs.update(units=unit, long_name=long, comment=where)
    ds[f"{name}_sem"].attrs["comment"] = f"{where}; block averaging (Flyvbjerg-Petersen), see docs/howto/profiles.md"
    ds[f"{name}_sem_converged"].attrs["comment"] = "false: no plateau, the sem is a lower bound (run longer)"


def add_averages(ds: xr.Dataset, case: Case) -> None:
    """Add `_mean`/`_sem`/`_sem_converged` of every averaged output and the wall pressure."""
    start = case.average_start
    if "sample" in ds.dims:
        axis = ds["step"] if case.run_time is None else ds["time"]
        if "sample" not in axis.dims:  # time-based run: time is a coordinate of sample
            axis = ds.coords["time"]
        keep = np.asarray(axis.values, float) >= start - 1e-9 * max(1.0, abs(start))
        sub = ds.isel(sample=np.nonzero(keep)[0])
        where = f"samples at or after {'step' if case.run_time is None else 'time'} {start:g}"
        for name in list(ds.data_vars):
            da = ds[name]
            if "sample" not in da.dims or name in NOT_AVERAGED or da.dtype.kind not in "fiu":
                continue
            _put(ds, name, _stats(sub[name], "sample"), da.attrs.get("units", "1"), name, where)
        _wall_pressure(ds, case, keep)
    if "window" in ds.dims:
        keepw = ds["window_step"].values >= start
        if case.run_time is None:
            sub = ds.isel(window=np.nonzero(keepw)[0])
            for name in list(ds.data_vars):
                if name.startswith("profile_") and "window" in ds[name].dims:
                    da = ds[name]
                    _put(ds, name, _stats(sub[name], "window"), da.attrs.get("units", "1"),
                         da.attrs.get("long_name", name), f"windows at or after step {start:g}")


def _wall_pressure(ds: xr.Dataset, case: Case, keep: np.ndarray) -> None:
    """wall_pressure_mean/_sem per face (soft walls from wall_force, reflect from reflect_impulse)."""
    if "face" not in ds.dims:
        return
    u = case.units
    lengths = case.box_hi - case.box_lo
    faces = [f for w in case.soft_walls for f in w.faces] + [f for w in case.reflect_walls for f in w.faces]
    labels = list(ds["face"].values)
    by_label = {f.label: f for f in faces}
    sign = np.array([float(by_label[lab].side) for lab in labels])
    plane = lengths[:case.dimension]  # 2-D: a face's "area" is the length of the other in-plane side
    area = np.array([float(np.prod(np.delete(plane, by_label[lab].dim))) for lab in labels])
    factor = xr.DataArray(sign / area * u.nktv2p, dims=("face",))
    idx = np.nonzero(keep)[0]
    soft = set(f.label for w in case.soft_walls for f in w.faces)
    is_soft = xr.DataArray(np.array([lab in soft for lab in labels]), dims=("face",))
    mean = sem = conv = None
    if "wall_force" in ds:
        p = (ds["wall_force"] * factor).isel(sample=idx)
        mean, sem, conv = _stats(p, "sample")
    if "reflect_impulse" in ds and len(idx) >= 2:
        # interval k runs from sample k-1 to k: keep those that start at or after averages.start
        iv = idx[1:]
        t = ds["time"]  # a variable (sweep..., sample), or the sample coordinate of a time-based run
        dt = xr.DataArray(t.isel(sample=iv).values - t.isel(sample=iv - 1).values, dims=t.dims)
        imp = ds["reflect_impulse"].isel(sample=iv)
        force = imp / dt
        rm, rs, rc = _stats(force * factor, "sample")
        rm = (imp.sum("sample") / dt.sum("sample")) * factor
        if mean is None:
            mean, sem, conv = rm, rs, rc
        else:
            mean = xr.where(is_soft, mean, rm)
            sem = xr.where(is_soft, sem, rs)
            conv = xr.where(is_soft, conv, rc)
    if mean is None:
        return
    where = f"samples at or after {'step' if case.run_time is None else 'time'} {case.average_start:g}"
    order = [d for d in mean.dims if d != "face"] + ["face"]
    mean, sem, conv = (a.transpose(*order) for a in (mean, sem, conv))
    _put(ds, "wall_pressure", (mean, sem, conv), u.pressure, "wall pressure", where)
    ds["wall_pressure_mean"].attrs["comment"] = (
        f"{where}; normal force on the face over its area, > 0 when the atoms push the wall outward "
        f"(-wall_force/area on lo faces, +wall_force/area on hi faces; reflect faces: impulse over time)")
