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

from wallbatch.engine.profiles import output_name
from wallbatch.io.results import Results, Var
from wallbatch.scene.case import Case
from wallbatch.stats import block_average

NOT_AVERAGED = {"step", "time", "dt"}
# counts and sums over the interval since the previous sample: the first sample (step 0) holds no
# interval (its 0 is no measurement), so their means run over the intervals that start at or
# after averages.start, as the wall pressure of reflect walls
INTERVAL = {"reflect_count", "reflect_impulse", "flow_crossings"}

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
        coords[bdim] = Var((bdim,), centres, {
            "units": case.units.distance, "long_name": f"{'xyz'[p.axis]} of the bin centre (profile {p.name})"})
        coords["window_step"] = Var(("window",), np.asarray(wins, np.int64), {
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
            data_vars[name] = Var(sweep_dims + ("window", bdim), arr.reshape(shape + arr.shape[1:]), {
                "units": profile_units(case, q),
                "long_name": f"{PROFILE_LONG[q]} along {'xyz'[p.axis]}",
                "comment": f"window averages of {p.repeat} samples every {p.every} steps ending at window_step, "
                           f"as LAMMPS fix ave/chunk norm all; empty bins are 0"})
    return data_vars, coords


def _isel(v: Var, dim: str, idx: np.ndarray) -> Var:
    """`v` at positions `idx` along `dim` (a copy, as xarray's isel with an index array)."""
    key = tuple(idx if d == dim else slice(None) for d in v.dims)
    return Var(v.dims, v.data[key])


def _stats(v: Var, dim: str) -> tuple[Var, Var, Var]:
    """Mean, sem, converged of `v` along `dim` (block averaging, vectorised over the rest): `dim`
    moved last (a view, as xarray's transpose), the others in order."""
    axis = v.dims.index(dim)
    rest = v.dims[:axis] + v.dims[axis + 1:]
    moved = np.transpose(v.data, [k for k in range(len(v.dims)) if k != axis] + [axis])
    res = block_average(moved)
    return Var(rest, res.mean), Var(rest, res.sem), Var(rest, res.converged)


def _put(ds: Results, name: str, stats: tuple, units: str, long_name: str, where: str) -> None:
    """Store mean, sem and converged of `name`; `where` (the averaged range) goes to `comment`."""
    mean, sem, conv = stats
    for suffix, value, unit, long in (
            ("_mean", mean, units, f"time mean of {long_name}"),
            ("_sem", sem, units, f"standard error of the time mean of {long_name}"),
            ("_sem_converged", conv, "1", f"block averaging of {name} reached a plateau")):
        ds[name + suffix] = Var(value.dims, value.data, {"units": unit, "long_name": long, "comment": where})
    ds[f"{name}_sem"].attrs["comment"] = f"{where}; block averaging (Flyvbjerg-Petersen), see docs/howto/profiles.md"
    ds[f"{name}_sem_converged"].attrs["comment"] = "false: no plateau, the sem is a lower bound (run longer)"


def add_averages(ds: Results, case: Case) -> None:
    """Add `_mean`/`_sem`/`_sem_converged` of every averaged output and the wall pressure."""
    start = case.average_start
    dims = ds.dims
    if "sample" in dims:
        axis = ds["step"] if case.run_time is None else ds["time"]
        keep = np.asarray(axis.values, float) >= start - 1e-9 * max(1.0, abs(start))
        idx = np.nonzero(keep)[0]
        at = f"{'step' if case.run_time is None else 'time'} {start:g}"
        where = f"samples at or after {at}"
        for name in ds.data_vars:
            v = ds[name]
            if "sample" not in v.dims or name in NOT_AVERAGED or v.data.dtype.kind not in "fiu":
                continue
            if name in INTERVAL:
                _put(ds, name, _stats(_isel(v, "sample", idx[1:]), "sample"), v.attrs.get("units", "1"), name,
                     f"sampling intervals that start at or after {at}")
                continue
            _put(ds, name, _stats(_isel(v, "sample", idx), "sample"), v.attrs.get("units", "1"), name, where)
        _wall_pressure(ds, case, keep)
    if "window" in dims:
        keepw = ds["window_step"].values >= start
        if case.run_time is None:
            idx = np.nonzero(keepw)[0]
            empty = _empty_bins(ds, case, idx)
            for name in ds.data_vars:
                if name.startswith("profile_") and "window" in ds[name].dims:
                    v = ds[name]
                    windows = _isel(v, "window", idx)
                    stats = _stats(windows, "window")
                    where = f"windows at or after step {start:g}"
                    if name in empty:  # an intensive quantity of a bin that was empty in some window
                        gone, counts = empty[name]
                        pooled = _pooled(windows, _isel(ds[counts], "window", idx), "window") if counts else None
                        stats = tuple(Var(a.dims, np.where(gone, b.data if pooled else fill, a.data))
                                      for a, b, fill in zip(stats, pooled or stats, (np.nan, np.nan, False)))
                        where += ("; in bins that held no atom in some of these windows, the windows pooled "
                                  "(weighted by the atoms counted; NaN if none ever)" if pooled else
                                  "; NaN in bins that held no atom in some of these windows")
                    _put(ds, name, stats, v.attrs.get("units", "1"), v.attrs.get("long_name", name), where)


INTENSIVE = ("temp", "vx", "vy", "vz")  # per-atom averages: 0 in an empty bin's window, as LAMMPS writes


def _empty_bins(ds: Results, case: Case, idx: np.ndarray) -> dict[str, tuple[np.ndarray, str | None]]:
    """For each intensive profile variable (temp, vx, vy, vz), the bins (sweep..., bin) that held
    no atom in one of the windows `idx` or more (the window's 0, LAMMPS's value there, is no
    temperature or velocity, so the plain mean of the windows would be wrong there), and the
    variable whose windows weigh them by the atoms counted (the profile's density/number), None
    without it. Empty windows are seen in the profile's own density (density/number or
    density/mass, 0 exactly when empty); without one, a temperature of exactly 0 counts as empty
    (velocities are then not checked)."""
    out: dict[str, tuple[np.ndarray, str | None]] = {}
    for p in case.profiles:
        dens = next((output_name(p.name, q) for q in ("density/number", "density/mass") if q in p.quantities), None)
        counts = output_name(p.name, "density/number") if "density/number" in p.quantities else None
        for q in p.quantities:
            if q not in INTENSIVE:
                continue
            name = output_name(p.name, q)
            probe = dens if dens is not None else (name if q == "temp" else None)
            if probe is None or probe not in ds.data_vars:
                continue
            v = _isel(ds[probe], "window", idx)
            axis = v.dims.index("window")
            out[name] = (np.any(v.data == 0.0, axis=axis), counts if counts in ds.data_vars else None)
    return out


def _pooled(v: Var, n: Var, dim: str) -> tuple[Var, Var, Var]:
    """Mean, sem and converged of the windows `v` pooled along `dim` with weights `n` (the atoms
    counted in each, up to a constant: a density/number): R = sum(n v) / sum(n), what one window
    over all of them would give (LAMMPS norm all: sum m v^2 over the atoms counted, for temp). Its
    error is that of a ratio estimator: the block-averaged sem of z = (n v - R n) / mean(n), whose
    mean is R's first-order error. NaN (flag false) where no window counted an atom."""
    axis = v.dims.index(dim)
    rest = v.dims[:axis] + v.dims[axis + 1:]
    x, w = np.moveaxis(v.data, axis, -1), np.moveaxis(n.data, axis, -1)
    total = w.sum(axis=-1)
    with np.errstate(invalid="ignore", divide="ignore"):
        wx = w * x
        ratio = np.where(total > 0, wx.sum(axis=-1) / total, np.nan)
        z = (wx - ratio[..., None] * w) / (total[..., None] / w.shape[-1])
    res = block_average(z)
    none = ~(total > 0)
    return (Var(rest, ratio), Var(rest, np.where(none, np.nan, res.sem)),
            Var(rest, np.where(none, False, res.converged)))


def _nansum(v: Var, dim: str) -> Var:
    """Sum over `dim` with NaN as 0 (xarray's sum of floats)."""
    axis = v.dims.index(dim)
    return Var(v.dims[:axis] + v.dims[axis + 1:], np.sum(np.where(np.isnan(v.data), 0.0, v.data), axis=axis))


def _wall_pressure(ds: Results, case: Case, keep: np.ndarray) -> None:
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
    factor = sign / area * u.nktv2p  # along face, the last dim of every face variable
    idx = np.nonzero(keep)[0]
    soft = set(f.label for w in case.soft_walls for f in w.faces)
    is_soft = np.array([lab in soft for lab in labels])
    mean = sem = conv = None
    if "wall_force" in ds:
        wf = ds["wall_force"]
        mean, sem, conv = _stats(_isel(Var(wf.dims, wf.data * factor), "sample", idx), "sample")
    if "reflect_impulse" in ds and len(idx) >= 2:
        # interval k runs from sample k-1 to k: keep those that start at or after averages.start
        iv = idx[1:]
        t = ds["time"]  # a variable (sweep..., sample), or the sample coordinate of a time-based run
        dt = Var(t.dims, _isel(t, "sample", iv).data - _isel(t, "sample", iv - 1).data)
        imp = _isel(ds["reflect_impulse"], "sample", iv)
        per_face = dt.data[..., None]  # dt's dims are imp's without face
        rm, rs, rc = _stats(Var(imp.dims, imp.data / per_face * factor), "sample")
        total = _nansum(imp, "sample")
        with np.errstate(invalid="ignore", divide="ignore"):  # a failed case: 0 / 0, NaN
            rm = Var(total.dims, total.data / _nansum(dt, "sample").data[..., None] * factor)
        if mean is None:
            mean, sem, conv = rm, rs, rc
        else:
            mean = Var(mean.dims, np.where(is_soft, mean.data, rm.data))
            sem = Var(sem.dims, np.where(is_soft, sem.data, rs.data))
            conv = Var(conv.dims, np.where(is_soft, conv.data, rc.data))
    if mean is None:
        return
    where = f"samples at or after {'step' if case.run_time is None else 'time'} {case.average_start:g}"
    _put(ds, "wall_pressure", (mean, sem, conv), u.pressure, "wall pressure", where)
    ds["wall_pressure_mean"].attrs["comment"] = (
        f"{where}; normal force on the face over its area, > 0 when the atoms push the wall outward "
        f"(-wall_force/area on lo faces, +wall_force/area on hi faces; reflect faces: impulse over time)")
