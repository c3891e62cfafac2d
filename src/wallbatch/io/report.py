"""Reading results back: a text summary, quick plots and the config's JSON schema.

Works on the results layout of docs/reference/outputs.md, whether the Dataset comes from
`runner.run_plan` or from `xarray.open_dataset(results.nc)`. Importing this module registers the
`ds.wallbatch` accessor (`.summary()`, `.sweep_dims`, `.ok`), so results stay a plain Dataset.
matplotlib is imported only by `plot`.
"""

from __future__ import annotations

from itertools import product
from pathlib import Path
from typing import Any

import numpy as np
import xarray as xr

# Dimensions that belong to one case's outputs; every other dimension is a sweep dimension.
CASE_DIMS = ("sample", "fix", "face", "spatial", "rfix", "window")
AVG_SUFFIXES = ("_mean", "_sem", "_sem_converged")
SHOWN_MEANS = 8  # cases listed in the summary's time averages
SAMPLE_AXES = ("sample", "step", "time")
TEXT_VARS = ("status", "error")
KINDS = ("auto", "line", "heatmap")
AUTO_HEATMAP_MIN = 10  # kind='auto' draws a heat map when hue is a sweep dim with this many values


# ----------------------------------------------------------------------------- small helpers


def sweep_dims(ds: xr.Dataset) -> list[str]:
    """Sweep dimension names in declared order (the order of `status`, then any others)."""
    order = list(ds["status"].dims) if "status" in ds else []
    order += [d for d in ds.dims if d not in order]
    return [str(d) for d in order if d not in CASE_DIMS and not _is_bin_dim(ds, str(d))]


def _is_bin_dim(ds: xr.Dataset, dim: str) -> bool:
    """A profile's bin dimension `<name>_bin` (its variables also run over `window`)."""
    return dim.endswith("_bin") and any(dim in v.dims and ("window" in v.dims or name.endswith(AVG_SUFFIXES))
                                        for name, v in ds.data_vars.items() if str(name).startswith("profile_"))


def _pm(mean: float, sem: float, converged: bool = True) -> str:
    """`mean ± sem` with sem to 2 significant digits and mean to the same decimal place; a `*`
    marks an error bar whose block averaging found no plateau (a lower bound)."""
    if not np.isfinite(mean):
        return "nan"
    if not np.isfinite(sem) or sem <= 0:
        return f"{mean:.6g} ± {_fmt(sem)}" + ("" if converged else "*")
    digits = max(0, 1 - int(np.floor(np.log10(sem))))
    return f"{mean:.{digits}f} ± {sem:.{digits}f}" + ("" if converged else "*")


def ok_mask(ds: xr.Dataset) -> xr.DataArray:
    """Boolean DataArray over the sweep dims: True where the case's status is 'ok'."""
    if "status" not in ds:
        return xr.DataArray(np.ones([ds.sizes[d] for d in sweep_dims(ds)], bool),
                            dims=sweep_dims(ds), name="ok")
    return (ds["status"].astype(str) == "ok").rename("ok")


def _is_text(da: xr.DataArray) -> bool:
    return da.dtype.kind in "OUSb" or da.name in TEXT_VARS


def _fmt(v: Any) -> str:
    if isinstance(v, (bytes, np.bytes_)):
        v = v.decode()
    if isinstance(v, (float, np.floating)):
        return "nan" if not np.isfinite(v) else f"{float(v):.6g}"
    if isinstance(v, np.generic):
        v = v.item()
    return str(v)


def _values(values: Any, limit: int = 12) -> str:
    vals = [_fmt(v) for v in np.asarray(values).ravel()]
    if len(vals) > limit:
        vals = vals[: limit - 2] + ["...", vals[-1]]
    return ", ".join(vals)


def _label(da: xr.DataArray | None, name: str) -> str:
    """Axis label `long_name [units]` (units omitted when absent)."""
    attrs = da.attrs if da is not None else {}
    text = attrs.get("long_name") or name
    units = attrs.get("units")
    return f"{text} [{units}]" if units else str(text)


def _case_label(coords: dict[str, Any]) -> str:
    return ", ".join(f"{k}={_fmt(v)}" for k, v in coords.items()) or "(single case)"


# ----------------------------------------------------------------------------- the summary


def summary(ds: xr.Dataset, errors: int = 5, slowest: int = 5) -> str:
    """A readable text summary of a results Dataset: header attributes, dimensions (sweep values
    and paths), status counts and the commonest error messages, per-variable ranges over the ok
    cases, and the slowest cases."""
    sdims = sweep_dims(ds)
    ok = ok_mask(ds)
    lines: list[str] = [str(ds.attrs.get("title", "wallbatch results"))]
    head = [f"{key}: {ds.attrs[attr]}" for key, attr in
            (("units_style", "units_style"), ("version", "wallbatch_version"), ("created", "created"))
            if attr in ds.attrs]
    if head:
        lines.append("  " + "   ".join(head))

    lines += ["", "Dimensions:"]
    width = max([len(str(d)) for d in ds.dims] + [4])
    for d in sdims + [d for d in CASE_DIMS if d in ds.dims]:
        n = ds.sizes[d]
        line = f"  {d:<{width}}  {n:>5}"
        if d in sdims:
            path = ds[d].attrs.get("path", "") if d in ds.coords else ""
            vals = _values(ds[d].values) if d in ds.coords else f"0 .. {n - 1}"
            line += f"  sweep {path}: {vals}" if path else f"  sweep: {vals}"
            extra = [c for c in ds.coords if c != d and ds[c].dims == (d,)]
            for c in extra:
                line += f"\n  {'':<{width}}  {'':>5}    {c} ({ds[c].attrs.get('path', '')}): {_values(ds[c].values)}"
        elif d == "sample":
            for c in ("step", "time"):
                if c in ds.coords and ds[c].dims == ("sample",):
                    vals = ds[c].values
                    units = ds[c].attrs.get("units")
                    unit = f" [{units}]" if units and units != "1" else ""
                    line += f"  {c}: {_fmt(vals.min())} .. {_fmt(vals.max())}{unit}" if vals.size else ""
                    break
        elif d == "window" and "window_step" in ds.coords:
            line += f"  profile windows ending at step {_values(ds['window_step'].values, 6)}"
        elif d in ds.coords:
            line += f"  {_values(ds[d].values)}"
        lines.append(line)
    for d in ds.dims:
        if _is_bin_dim(ds, str(d)):
            c = ds[d].values
            lines.append(f"  {str(d):<{width}}  {ds.sizes[d]:>5}  bin centres {_fmt(c.min())} .. {_fmt(c.max())}")

    total = int(ok.size)
    n_ok = int(ok.sum())
    lines += ["", f"Status: {n_ok} ok, {total - n_ok} failed (of {total} case{'s' if total != 1 else ''})"]
    if total - n_ok and "error" in ds:
        err = ds["error"].astype(str)
        groups: dict[str, list[dict]] = {}
        for idx in np.ndindex(*ok.shape):
            if bool(ok.values[idx]):
                continue
            msg = str(err.values[idx]) or "(no message)"
            groups.setdefault(msg, []).append({d: ds[d].values[i] if d in ds.coords else i
                                               for d, i in zip(ok.dims, idx)})
        lines.append("Errors:")
        for msg, where in sorted(groups.items(), key=lambda kv: -len(kv[1]))[:errors]:
            first = msg.strip().splitlines()[0] if msg.strip() else msg
            if len(first) > 200:
                first = first[:197] + "..."
            lines.append(f"  {len(where)} x {first}")
            lines.append(f"      e.g. {_case_label(where[0])}")
        if len(groups) > errors:
            lines.append(f"  ... and {len(groups) - errors} other message(s)")

    lines += ["", "Variables (over ok cases):"]
    rows = []
    for name, da in ds.data_vars.items():
        if _is_text(da) or (str(name).endswith(AVG_SUFFIXES) and not str(name).startswith("profile_")):
            continue
        vals = np.asarray(da.where(ok).values if set(ok.dims) <= set(da.dims) else da.values, float)
        finite = vals[np.isfinite(vals)]
        stats = ("min %s  max %s  mean %s" % tuple(_fmt(f(finite)) for f in (np.min, np.max, np.mean))
                 if finite.size else "no finite values")
        rows.append((str(name), "(" + ", ".join(map(str, da.dims)) + ")", f"[{da.attrs.get('units', '?')}]", stats))
    if rows:
        w = [max(len(r[i]) for r in rows) for i in range(3)]
        lines += [f"  {r[0]:<{w[0]}}  {r[1]:<{w[1]}}  {r[2]:<{w[2]}}  {r[3]}" for r in rows]
    lines += _averages_section(ds, sdims, ok)

    if "seconds" in ds:
        sec = ds["seconds"]
        flat = np.asarray(sec.values, float).ravel()
        order = [i for i in np.argsort(-np.nan_to_num(flat, nan=-np.inf), kind="stable")][:slowest]
        lines += ["", f"Slowest case{'s' if len(order) != 1 else ''}:"]
        for i in order:
            idx = np.unravel_index(i, sec.shape) if sec.ndim else ()
            coords = {d: ds[d].values[j] if d in ds.coords else j for d, j in zip(sec.dims, idx)}
            status = str(ds["status"].values[idx]) if "status" in ds else ""
            lines.append(f"  {_fmt(flat[i]):>10} s  {_case_label(coords)}" + (f"  ({status})" if status else ""))
    return "\n".join(lines) + "\n"


def _averages_section(ds: xr.Dataset, sdims: list[str], ok: xr.DataArray) -> list[str]:
    """Means with their block-averaged standard errors, per case (the first SHOWN_MEANS ok
    cases); profiles are left to `ds.wallbatch.profile` and `wallbatch plot`."""
    names = [str(n)[:-5] for n in ds.data_vars if str(n).endswith("_mean") and not str(n).startswith("profile_")
             and f"{str(n)[:-5]}_sem" in ds]
    if not names:
        return []
    where = ds[f"{names[0]}_mean"].attrs.get("comment", "")
    where = f" over {where}" if where else ""
    lines = ["", f"Time averages{where} (± standard error from block averaging; * = no plateau, a lower bound):"]
    cases = [idx for idx in np.ndindex(*ok.shape) if bool(ok.values[idx])] if ok.ndim else [()]
    for idx in cases[:SHOWN_MEANS]:
        coords = {d: ds[d].values[i] if d in ds.coords else i for d, i in zip(ok.dims, idx)}
        if sdims:
            lines.append(f"  {_case_label(coords)}")
        pick = dict(zip(ok.dims, idx))
        for name in names:
            m = ds[f"{name}_mean"].isel({k: v for k, v in pick.items() if k in ds[f"{name}_mean"].dims})
            e = ds[f"{name}_sem"].isel({k: v for k, v in pick.items() if k in ds[f"{name}_sem"].dims})
            c = (ds[f"{name}_sem_converged"].isel({k: v for k, v in pick.items()
                                                    if k in ds[f"{name}_sem_converged"].dims})
                 if f"{name}_sem_converged" in ds else xr.ones_like(m, dtype=bool))
            units = ds[f"{name}_mean"].attrs.get("units", "")
            unit = f" [{units}]" if units and units != "1" else ""
            if m.ndim == 0:
                text = _pm(float(m), float(e), bool(c))
            else:
                entry = m.dims[0] if m.ndim == 1 else None
                parts = []
                for j in np.ndindex(*m.shape):
                    label = "/".join(_fmt(ds[d].values[k]) if d in ds.coords else str(k) for d, k in zip(m.dims, j))
                    parts.append(f"{label} {_pm(float(m.values[j]), float(e.values[j]), bool(c.values[j]))}")
                text = "   ".join(parts) if entry else "; ".join(parts)
            lines.append(f"    {name:<16}{unit:<12} {text}")
    if len(cases) > SHOWN_MEANS:
        lines.append(f"  ... and {len(cases) - SHOWN_MEANS} more case(s): ds.wallbatch.mean(NAME) gives them all")
    return lines


@xr.register_dataset_accessor("wallbatch")
class WallbatchAccessor:
    """`ds.wallbatch`: helpers for a wallbatch results Dataset."""

    def __init__(self, ds: xr.Dataset) -> None:
        self._ds = ds

    def summary(self, **kwargs: Any) -> str:
        return summary(self._ds, **kwargs)

    @property
    def sweep_dims(self) -> list[str]:
        return sweep_dims(self._ds)

    @property
    def ok(self) -> xr.DataArray:
        return ok_mask(self._ds)

    def plot(self, var: str, out: str | Path, **kwargs: Any):
        return plot(self._ds, var, out, **kwargs)

    def profile(self, name: str, quantity: str) -> xr.DataArray:
        """The windows of profile `name`'s `quantity` (`density/number`, `temp`, ...): the
        DataArray `profile_<name>_<quantity>` (sweep..., window, <name>_bin)."""
        var = f"profile_{name}_{quantity.replace('/', '_')}"
        if var not in self._ds:
            have = sorted(str(v) for v in self._ds.data_vars if str(v).startswith("profile_")
                          and not str(v).endswith(AVG_SUFFIXES))
            raise KeyError(f"no profile {name!r} with quantity {quantity!r} ({var}); profiles here: "
                           f"{', '.join(have) or 'none (add output.profiles to the config)'}")
        return self._ds[var]

    def mean(self, var: str) -> xr.Dataset:
        """Time average of `var` (a thermo/wall output, `wall_pressure`, or a profile variable):
        a Dataset with `mean`, `sem` (block-averaged standard error) and `converged`."""
        base = var[:-5] if var.endswith("_mean") else var
        if f"{base}_mean" not in self._ds:
            have = sorted(str(v)[:-5] for v in self._ds.data_vars if str(v).endswith("_mean"))
            raise KeyError(f"no time average of {var!r}; averaged here: {', '.join(have) or 'none'}")
        out = xr.Dataset({"mean": self._ds[f"{base}_mean"], "sem": self._ds[f"{base}_sem"]})
        if f"{base}_sem_converged" in self._ds:
            out["converged"] = self._ds[f"{base}_sem_converged"]
        return out


# ----------------------------------------------------------------------------- selection


def _parse_value(key: str, text: Any, coord: xr.DataArray) -> Any:
    kind = coord.dtype.kind
    if kind in "iuf":
        if not isinstance(text, str):
            return text
        try:
            return int(text) if kind in "iu" and text.strip().lstrip("+-").isdigit() else float(text)
        except ValueError:
            raise ValueError(f"selection {key}={text}: not a number; {key} takes {_values(coord.values)}") from None
    if kind == "b":
        low = str(text).strip().lower()
        if low in ("true", "1", "yes"):
            return True
        if low in ("false", "0", "no"):
            return False
        raise ValueError(f"selection {key}={text}: write true or false")
    return text if not isinstance(text, bytes) else text.decode()


def _nearest_ok(key: str, value: float, values: np.ndarray, text: Any) -> None:
    """Refuse a numeric selection far outside the coordinate's values."""
    vals = np.unique(np.asarray(values, float))
    vals = vals[np.isfinite(vals)]
    if not vals.size:
        return
    slack = np.max(np.diff(vals)) / 2 if vals.size > 1 else 1e-9 * max(1.0, abs(vals[0]))
    if value < vals[0] - slack or value > vals[-1] + slack:
        raise ValueError(f"selection {key}={text}: outside the values of {key} ({_values(values)})")


def select(ds: xr.Dataset, sel: dict[str, Any] | None) -> xr.Dataset:
    """Apply command-line selections `{name: "value"}`: a dimension with a coordinate (sweep dims,
    `fix`, `face`; numeric values to the nearest), a dimension without one by position (`sample=3`)
    or a 1-d coordinate (`step=100`, `time=2.5`, `face_name=zlo`, a zip's parameter)."""
    for key, text in (sel or {}).items():
        if key in ds.dims and key in ds.coords:
            coord = ds[key]
        elif key in ds.dims:  # dimension without coordinate: a position
            try:
                pos = int(str(text))
            except ValueError:
                raise ValueError(f"selection {key}={text}: {key} has no coordinate, give a position "
                                 f"0..{ds.sizes[key] - 1}") from None
            if not -ds.sizes[key] <= pos < ds.sizes[key]:
                raise ValueError(f"selection {key}={text}: position outside 0..{ds.sizes[key] - 1}")
            ds = ds.isel({key: pos})
            continue
        elif key in ds.coords and ds[key].ndim == 1:
            coord = ds[key]
        else:
            names = sorted({str(d) for d in ds.dims} | {str(c) for c in ds.coords if ds[c].ndim == 1})
            raise ValueError(f"selection {key}={text}: no dimension or coordinate {key}; "
                             f"valid: {', '.join(names)}")
        dim = coord.dims[0]
        value = _parse_value(key, text, coord)
        if coord.dtype.kind in "iuf":
            _nearest_ok(key, float(value), coord.values, text)
            index = ds.indexes.get(key) if key == dim else None
            if index is not None and (index.is_monotonic_increasing or index.is_monotonic_decreasing) \
                    and index.is_unique:
                ds = ds.sel({key: value}, method="nearest")
            else:
                ds = ds.isel({dim: int(np.nanargmin(np.abs(np.asarray(coord.values, float) - float(value))))})
        else:
            strings = np.asarray(coord.values).astype(str)
            hits = np.flatnonzero(strings == str(value))
            if not hits.size:
                raise ValueError(f"selection {key}={text}: no such value; {key} takes {_values(strings, 50)}")
            ds = ds.isel({dim: int(hits[0]) if hits.size == 1 else hits})
    return ds


# ----------------------------------------------------------------------------- plotting


def _combos(da: xr.DataArray, dims: list[str]) -> list[dict[str, int]]:
    return [dict(zip(dims, idx)) for idx in product(*(range(da.sizes[d]) for d in dims))]


def _coord_value(ds: xr.Dataset, dim: str, i: int) -> Any:
    return ds[dim].values[i] if dim in ds.coords else i


def _colors(n: int) -> list:
    """Distinct colours for n hue values: tab10 up to 10, else sampled from viridis."""
    from matplotlib import colormaps

    if n <= 10:
        return [colormaps["tab10"](k) for k in range(n)]
    return [colormaps["viridis"](k / (n - 1)) for k in range(n)]


def _sample_axis(ds: xr.Dataset, x: str | None) -> str:
    """Name of the variable/coordinate giving the x values of a time series."""
    if x in ("step", "time"):
        if x not in ds.variables:
            raise ValueError(f"x={x}: this results file has no {x}")
        return x
    for name in ("step", "time"):
        if name in ds.coords and ds[name].dims == ("sample",):
            return name
    return "step" if "step" in ds.variables else "time"


def plot(ds: xr.Dataset, var: str, out: str | Path, x: str | None = None, hue: str | None = None,
         sel: dict[str, str] | None = None, kind: str = "auto", return_figure: bool = False,
         title: str | None = None):
    """Plot `var` of a results Dataset to `out` (format from its suffix, PNG by default).

    `sel` (strings, as from `--sel epsilon=1.0`) picks cases/entries first (see `select`). Then:
    - `x` None, 'sample', 'step' or 'time': a time series, one line per remaining case and
      fix/face entry, coloured by `hue` if given;
    - `x` a sweep dimension: the time mean over the samples against `x`, one line per remaining
      combination (coloured by `hue`), or with `kind='heatmap'` (or 'auto' and a `hue` sweep dim
      with many values) a pcolormesh of the time mean over (`x`, `hue`) with a colour bar;
      remaining replicas are averaged in a heat map.
    Returns the written path, or `(path, figure)` when `return_figure` is true.
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    if kind not in KINDS:
        raise ValueError(f"kind={kind!r}: choose one of {', '.join(KINDS)}")
    plottable = [str(n) for n, v in ds.data_vars.items() if not _is_text(v)]
    if var not in ds.data_vars or var not in plottable:
        raise ValueError(f"unknown variable {var!r}; plottable variables: {', '.join(plottable)}")
    sdims = sweep_dims(ds)
    if x is None and "sample" not in ds[var].dims and var.endswith("_mean") and sdims:
        bins = [d for d in ds[var].dims if _is_bin_dim(ds, str(d))]
        x = None if bins else next((d for d in sdims if d in ds[var].dims), None)  # a mean against the sweep
    if x is not None and x not in SAMPLE_AXES and x not in sdims:
        raise ValueError(f"x={x}: give one of {', '.join(list(SAMPLE_AXES) + sdims)}")
    if hue is not None and hue not in ds.dims:
        raise ValueError(f"hue={hue}: unknown dimension; valid: {', '.join(map(str, ds.dims))}")
    if hue is not None and hue == x:
        raise ValueError(f"hue and x are both {x}: give different dimensions")
    sub = select(ds, sel)
    if x is not None and x in sdims and x not in sub[var].dims:
        raise ValueError(f"x={x}: {x} was selected away by sel; drop {x} from the selection")
    if hue is not None and hue not in sub[var].dims:
        raise ValueError(f"hue={hue}: {var} has no dimension {hue} after selection; "
                         f"remaining: {', '.join(map(str, sub[var].dims)) or 'none'}")
    da = sub[var].where(ok_mask(sub)) if "status" in sub else sub[var]
    da.attrs = sub[var].attrs
    chosen = {k: _fmt(sub[k].values) for k in (sel or {}) if k in sub.coords and sub[k].ndim == 0}
    suffix = _case_label(chosen) if chosen else ""

    fig = Figure(figsize=(7.5, 4.8), layout="constrained")
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()

    bins = [str(d) for d in da.dims if _is_bin_dim(ds, str(d))]
    if bins and (x is None or x == bins[0]):
        _profile_lines(ax, sub, var, da, bins[0], hue)
        ax.set_title(title or (f"{var}" + (f"  ({suffix})" if suffix else "")))
    elif x is None or x in SAMPLE_AXES:
        if kind == "heatmap":
            raise ValueError("kind='heatmap' needs x and hue to be two sweep dimensions")
        if "sample" not in da.dims and "sample" in ds[var].dims:
            raise ValueError(f"the selection {sel} leaves {var} a single sample: plot it against a sweep "
                             f"dimension (x=<{'|'.join(sdims) or 'sweep dim'}>) or select fewer samples")
        if "sample" not in da.dims:
            raise ValueError(f"{var} has no sample dimension (dims: {', '.join(map(str, da.dims)) or 'none'}): "
                             f"plot it against a sweep dimension with x=<{'|'.join(sdims) or 'sweep dim'}>")
        xname = _sample_axis(sub, x)
        xdata = sub[xname]
        rest = [str(d) for d in da.dims if d != "sample"]
        _lines(ax, sub, da, xdata, rest, hue, style="-")
        ax.set_xlabel(_label(xdata, xname))
        ax.set_ylabel(_label(da, var))
        ax.set_title(title or (f"{var}" + (f"  ({suffix})" if suffix else "")))
    else:
        mean = da.mean("sample", skipna=True, keep_attrs=True) if "sample" in da.dims else da
        rest = [str(d) for d in mean.dims if d != x]
        if kind == "auto":
            kind = "heatmap" if (hue in sdims and mean.sizes.get(hue, 0) >= AUTO_HEATMAP_MIN) else "line"
        what = f"time mean of {var}" if "sample" in da.dims else var
        if kind == "heatmap":
            if hue is None or hue not in sdims:
                raise ValueError(f"kind='heatmap' needs hue to be a second sweep dimension; "
                                 f"sweep dims: {', '.join(sdims)}")
            if "replica" in mean.dims and "replica" not in (x, hue):
                mean = mean.mean("replica", skipna=True, keep_attrs=True)
                what += " (mean over replicas)"
            extra = [d for d in mean.dims if d not in (x, hue) and mean.sizes[d] > 1]
            if extra:
                raise ValueError(f"a heat map of {var} over ({x}, {hue}) has more dimensions left: "
                                 f"{', '.join(map(str, extra))}; pick one value of each with sel")
            mean = mean.squeeze([d for d in mean.dims if d not in (x, hue)], drop=True)
            _heatmap(ax, fig, sub, mean.transpose(hue, x), x, hue, _label(da, what))
        else:
            xdata = sub[x] if x in sub.coords else xr.DataArray(np.arange(sub.sizes[x]), dims=[x])
            err = None
            if var.endswith("_mean") and f"{var[:-5]}_sem" in sub:  # error bars: the block-averaged sem
                err = sub[f"{var[:-5]}_sem"].where(ok_mask(sub)) if "status" in sub else sub[f"{var[:-5]}_sem"]
                what += " (± standard error)"
            _lines(ax, sub, mean, xdata, rest, hue, style="o-", err=err)
            ax.set_xlabel(_label(sub[x] if x in sub.coords else None, x))
            ax.set_ylabel(_label(da, what))
        ax.set_title(title or (what + (f"  ({suffix})" if suffix else "")))

    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=120)
    return (out, fig) if return_figure else out


def _profile_lines(ax, ds: xr.Dataset, var: str, da: xr.DataArray, bdim: str, hue: str | None) -> None:
    """A profile against its bin centres: the window mean with its standard error as error bars
    (from `<var>_mean`/`_sem`; a windows variable without them is averaged over its windows)."""
    base = var[:-5] if var.endswith("_mean") else var
    ok = ok_mask(ds) if "status" in ds else None
    if f"{base}_mean" in ds and f"{base}_sem" in ds:
        mean, err = ds[f"{base}_mean"], ds[f"{base}_sem"]
        if ok is not None:
            mean, err = mean.where(ok), err.where(ok)
        what = f"{base} (window mean ± standard error)"
    else:
        mean = da.mean("window", skipna=True) if "window" in da.dims else da
        err, what = None, f"{base} (window mean)"
    mean.attrs = ds[base].attrs if base in ds else da.attrs
    rest = [str(d) for d in mean.dims if d != bdim]
    _lines(ax, ds, mean, ds[bdim], rest, hue, style="o-", err=err)
    ax.set_xlabel(_label(ds[bdim], bdim))
    ax.set_ylabel(_label(mean, what))


def _lines(ax, ds: xr.Dataset, da: xr.DataArray, xdata: xr.DataArray, rest: list[str],
           hue: str | None, style: str, err: xr.DataArray | None = None) -> None:
    """One line per combination of the `rest` dims of `da` along the remaining axis (the sample or
    sweep dim that `xdata` runs along); colour by `hue`; `err` (same dims as `da`) draws error bars."""
    along = [d for d in da.dims if d not in rest]
    numeric_x = np.asarray(xdata.values).dtype.kind in "iuf"
    colors = _colors(da.sizes[hue]) if hue else []
    combos = _combos(da, rest)
    others = [d for d in rest if d != hue]
    seen_hue: set[int] = set()
    for combo in combos:
        y = np.asarray(da.isel(combo).transpose(*along).values, float)
        xv = xdata.isel({k: v for k, v in combo.items() if k in xdata.dims})
        xv = np.asarray(xv.values) if numeric_x else np.arange(y.size)
        kw: dict[str, Any] = {}
        if hue:
            h = combo[hue]
            kw["color"] = colors[h]
            if h not in seen_hue:
                kw["label"] = f"{hue}={_fmt(_coord_value(ds, hue, h))}"
                seen_hue.add(h)
            if others:
                kw["alpha"] = 0.8
        elif len(combos) > 1:
            kw["label"] = _case_label({d: _coord_value(ds, d, combo[d]) for d in rest})
        if err is not None:
            e = np.asarray(err.isel(combo).transpose(*along).values, float)
            ax.errorbar(xv, y, yerr=e, fmt=style, markersize=4, capsize=2, **kw)
        else:
            ax.plot(xv, y, style, markersize=4, **kw)
    if not numeric_x:
        ax.set_xticks(range(xdata.size), [_fmt(v) for v in np.asarray(xdata.values)], rotation=30)
    n_labels = len(seen_hue) if hue else (len(combos) if len(combos) > 1 else 0)
    if 0 < n_labels <= 15:
        ax.legend(fontsize="small")


def _heatmap(ax, fig, ds: xr.Dataset, grid: xr.DataArray, x: str, y: str, label: str) -> None:
    def axis(dim: str) -> tuple[np.ndarray, list[str] | None]:
        vals = np.asarray(ds[dim].values) if dim in ds.coords else np.arange(ds.sizes[dim])
        if vals.dtype.kind in "iuf" and vals.size == np.unique(vals).size:
            return vals.astype(float), None
        return np.arange(vals.size, dtype=float), [_fmt(v) for v in vals]

    xv, xt = axis(x)
    yv, yt = axis(y)
    z = np.asarray(grid.values, float)
    ix, iy = np.argsort(xv, kind="stable"), np.argsort(yv, kind="stable")
    mesh = ax.pcolormesh(xv[ix], yv[iy], z[np.ix_(iy, ix)], shading="nearest", cmap="viridis")
    cbar = fig.colorbar(mesh, ax=ax)
    cbar.set_label(label)
    if xt:
        ax.set_xticks(xv, xt, rotation=30)
    if yt:
        ax.set_yticks(yv, yt)
    ax.set_xlabel(_label(ds[x] if x in ds.coords else None, x))
    ax.set_ylabel(_label(ds[y] if y in ds.coords else None, y))


# ----------------------------------------------------------------------------- JSON schema


__all__ = ["summary", "plot", "select", "sweep_dims", "ok_mask", "WallbatchAccessor"]
