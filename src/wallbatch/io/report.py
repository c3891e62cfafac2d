"""Reading results back: a text summary, quick plots and the config's JSON schema.

Works on the results layout of docs/reference/outputs.md, whether the Dataset comes from
`runner.run_plan` or from `xarray.open_dataset(results.nc)`. Importing this module registers the
`ds.wallbatch` accessor (`.summary()`, `.sweep_dims`, `.ok`), so results stay a plain Dataset.
matplotlib is imported only by `plot`.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import xarray as xr

from wallbatch.io.results import _defer_dask_import

_defer_dask_import()  # xarray would import dask (~1 s) to ask whether an array is a dask array

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


def _exact(key: str, value: float, values: np.ndarray, text: Any) -> np.ndarray:
    """Positions where a numeric coordinate equals `value` (to 1e-9 relative, so that 0.1 matches
    the stored 0.1 of a linspace); an error listing the values when there is none."""
    vals = np.asarray(values, float)
    hits = np.flatnonzero(np.isclose(vals, value, rtol=1e-9, atol=1e-12))
    if not hits.size:
        raise ValueError(f"selection {key}={text}: no such value; {key} takes {_values(values, 50)}")
    return hits


def select(ds: xr.Dataset, sel: dict[str, Any] | None) -> xr.Dataset:
    """Apply command-line selections `{name: "value"}`, matched exactly (an error lists the valid
    values): a dimension with a coordinate (sweep dims, `fix`, `face`), a dimension without one by
    position (`sample=3`) or a 1-d coordinate (`step=100`, `time=2.5`, `face_name=zlo`, a zip's
    parameter)."""
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
            hits = _exact(key, float(value), coord.values, text)
        else:
            strings = np.asarray(coord.values).astype(str)
            hits = np.flatnonzero(strings == str(value))
            if not hits.size:
                raise ValueError(f"selection {key}={text}: no such value; {key} takes {_values(strings, 50)}")
        ds = ds.isel({dim: int(hits[0]) if hits.size == 1 else hits})
    return ds


# ----------------------------------------------------------------------------- plotting


FACET_DIMS = ("face", "fix", "spatial", "rfix")  # per-case entries drawn as panels, in this priority
MAX_FACETS = 6
MAX_LEGEND = 12  # more hue values than this: a colour bar instead of a legend
STYLES = ("-", "--", ":", "-.")


def _colors(n: int) -> list:
    """Distinct colours for n hue values: tab10 up to 10, else sampled from viridis."""
    from matplotlib import colormaps

    if n <= 10:
        return [colormaps["tab10"](k) for k in range(n)]
    return [colormaps["viridis"](k / (n - 1)) for k in range(n)]


def _opt(name: str, value: Any, cli: bool) -> str:
    """An argument as the user wrote it: `--x time` on the command line, `x=time` in Python."""
    return f"--{name} {value}" if cli else f"{name}={value}"


def _heatmap_needs(options: tuple[str, ...], what: str, cli: bool) -> str:
    """"kind='heatmap' needs x and hue ..." (`--kind heatmap needs --x and --hue ...` on the command line)."""
    names = " and ".join(f"--{o}" if cli else o for o in options)
    return f"{_opt('kind', 'heatmap' if cli else repr('heatmap'), cli)} needs {names} {what}"


def _sample_axis(ds: xr.Dataset, x: str | None, cli: bool = False) -> str:
    """Name of the variable/coordinate giving the x values of a time series."""
    if x in ("step", "time"):
        if x not in ds.variables:
            raise ValueError(f"{_opt('x', x, cli)}: this results file has no {x}")
        return x
    for name in ("step", "time"):
        if name in ds.coords and ds[name].dims == ("sample",):
            return name
    return "step" if "step" in ds.variables else "time"


def _axis_label(ds: xr.Dataset, name: str) -> str:
    """A short axis label: the variable or dimension name (a profile's bins: their description),
    with its units unless dimensionless."""
    attrs = ds[name].attrs if name in ds.variables else {}
    units = attrs.get("units")
    text = attrs.get("long_name", name) if _is_bin_dim(ds, name) else name
    return f"{text} [{units}]" if units and units != "1" else text


def _coord_value(ds: xr.Dataset, dim: str, i: int) -> Any:
    return ds[dim].values[i] if dim in ds.coords else i


def _wrap(text: str, width: int = 80) -> str:
    import textwrap

    return "\n".join(textwrap.wrap(text, width)) or text


def plot(ds: xr.Dataset, var: str, out: str | Path, x: str | None = None, hue: str | None = None,
         sel: dict[str, str] | None = None, kind: str = "auto", return_figure: bool = False,
         title: str | None = None, cli: bool = False):
    """Plot `var` of a results Dataset to `out` (format from its suffix, PNG by default).

    `sel` (strings, as from `--sel epsilon=1.0`) picks cases/entries first, by exact value (see
    `select`). Then `x` None, 'sample', 'step' or 'time' draws a time series; `x` a sweep dimension
    draws the time mean against it (`<var>_mean` of the file, from `output.averages` on, with
    `<var>_sem`; the mean of the samples when a selection left fewer) (or, with `kind='heatmap'` or
    'auto' and a `hue` sweep dim of many values, a heat map over (`x`, `hue`)). Lines:

    - one panel per wall face (or fix / region-force component) when there are several;
    - colour: `hue` (default: the first sweep dimension left), with a legend (a colour bar when
      it has more than MAX_LEGEND values); line style: the next sweep dimension (up to 4 values);
    - replicas are averaged, the band is +- one standard error over them; any further dimension
      is averaged too, its band the min-max range, and the title says so;
    - `<var>_sem` in the file (a block-average standard error) gives the band where nothing is
      averaged;
    - failed cases are marked (a red x at their x in sweep plots; named in a note otherwise).

    Returns the written path, or `(path, figure)` when `return_figure` is true. `cli` (for
    `wallbatch plot`): errors name the options as typed there (`--x time`), not `x=time`.
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    if kind not in KINDS:
        raise ValueError(f"{_opt('kind', kind if cli else repr(kind), cli)}: choose one of {', '.join(KINDS)}")
    plottable = [str(n) for n, v in ds.data_vars.items() if not _is_text(v)]
    if var not in ds.data_vars or var not in plottable:
        raise ValueError(f"unknown variable {var!r}; plottable variables: {', '.join(plottable)}")
    sdims = sweep_dims(ds)
    if x is None and "sample" not in ds[var].dims and var.endswith("_mean") and sdims:
        bins = [d for d in ds[var].dims if _is_bin_dim(ds, str(d))]
        x = None if bins else next((d for d in sdims if d in ds[var].dims), None)  # a mean against the sweep
    var_bins = [str(d) for d in ds[var].dims if _is_bin_dim(ds, str(d))]
    if x is not None and x not in SAMPLE_AXES and x not in sdims and x not in var_bins:
        raise ValueError(f"{_opt('x', x, cli)}: give one of {', '.join(list(SAMPLE_AXES) + sdims + var_bins)}")
    if hue is not None and hue not in ds.dims:
        raise ValueError(f"{_opt('hue', hue, cli)}: unknown dimension; valid: {', '.join(map(str, ds.dims))}")
    if hue is not None and hue == x:
        raise ValueError(f"{'--hue and --x' if cli else 'hue and x'} are both {x}: give different dimensions")
    sub = select(ds, sel)
    if x is not None and x in sdims and x not in sub[var].dims:
        raise ValueError(f"{_opt('x', x, cli)}: {x} was selected away by {'--sel' if cli else 'sel'}; "
                         f"drop {x} from the selection")
    if hue is not None and hue not in sub[var].dims:
        raise ValueError(f"{_opt('hue', hue, cli)}: {var} has no dimension {hue} after selection; "
                         f"remaining: {', '.join(map(str, sub[var].dims)) or 'none'}")
    ok = ok_mask(sub)
    da = sub[var].where(ok) if "status" in sub else sub[var]
    da.attrs = sub[var].attrs
    # the standard error of `var`: `<var>_sem`, or `<X>_sem` for a block average `<X>_mean`
    sem_name = f"{var}_sem" if f"{var}_sem" in sub.data_vars else (
        f"{var[:-5]}_sem" if var.endswith("_mean") and f"{var[:-5]}_sem" in sub.data_vars else "")
    if sem_name and set(sub[sem_name].dims) != set(sub[var].dims):
        sem_name = ""  # e.g. pe_sem is the error of the block average pe_mean, not of each sample of pe
    sem = (sub[sem_name].where(ok) if "status" in sub else sub[sem_name]) if sem_name else None
    chosen = {k: _fmt(sub[k].values) for k in (sel or {}) if k in sub.coords and sub[k].ndim == 0}
    suffix = _case_label(chosen) if chosen else ""
    long_name = da.attrs.get("long_name", var)

    bins = [str(d) for d in da.dims if _is_bin_dim(ds, str(d))]
    if bins and (x is None or x == bins[0]):  # a profile against its bin centres
        if kind == "heatmap":
            raise ValueError(_heatmap_needs(("x", "hue"), "to be two sweep dimensions", cli))
        base = var[:-5] if var.endswith("_mean") else var
        if f"{base}_mean" in sub and f"{base}_sem" in sub:  # the window mean with its standard error
            da, sem, sem_name = sub[f"{base}_mean"], sub[f"{base}_sem"], f"{base}_sem"
            if "status" in sub:
                da, sem = da.where(ok), sem.where(ok)
            what = f"{base}: window mean"
        else:
            da, sem, what = (da.mean("window", skipna=True) if "window" in da.dims else da), None, f"{base}: window mean"
        da.attrs = sub[base].attrs if base in sub else sub[var].attrs
        along, xdata, xlabel, marker = bins[0], sub[bins[0]], _axis_label(sub, bins[0]), "o"
    elif x is None or x in SAMPLE_AXES:
        if kind == "heatmap":
            raise ValueError(_heatmap_needs(("x", "hue"), "to be two sweep dimensions", cli))
        against = (f"plot it against a sweep dimension ({_opt('x', '<' + '|'.join(sdims) + '>', cli)})" if sdims else
                   "this file has no sweep dimension to plot it against (one case: `wallbatch show` prints it)")
        if "sample" not in da.dims and "sample" in ds[var].dims:
            raise ValueError(f"the selection {sel} leaves {var} a single sample: {against}, or select fewer samples")
        if "sample" not in da.dims:
            raise ValueError(f"{var} has no sample dimension (dims: {', '.join(map(str, da.dims)) or 'none'}): "
                             f"{against}")
        xname = _sample_axis(sub, x, cli)
        along, xdata, xlabel, what = "sample", sub[xname], _axis_label(sub, xname), long_name
        marker = ""
    else:
        along, what = x, (f"time mean of {long_name}" if "sample" in da.dims else long_name)
        mean_name, sem_of_mean = f"{var}_mean", f"{var}_sem"
        if ("sample" in da.dims and sub.sizes["sample"] == ds.sizes["sample"] and mean_name in sub.data_vars
                and sem_of_mean in sub.data_vars):
            # the time mean the file holds (samples from output.averages on, as `show` prints it)
            # with its block-averaged standard error, not a mean over every sample
            da = sub[mean_name].where(ok) if "status" in sub else sub[mean_name]
            sem = sub[sem_of_mean].where(ok) if "status" in sub else sub[sem_of_mean]
            sem_name = sem_of_mean
            since = str(sub[mean_name].attrs.get("comment", "")).split(";")[0]
            what += f" ({since})" if since else ""
            da.attrs = sub[var].attrs
        elif "sample" in da.dims:
            n = da.count("sample")
            if sem is not None and "sample" in sem.dims:  # s.e. of a mean of independent block means
                sem = np.sqrt((sem ** 2).sum("sample", skipna=True)) / n.where(n > 0)
            da = da.mean("sample", skipna=True, keep_attrs=True)
        xdata = sub[x] if x in sub.coords else xr.DataArray(np.arange(sub.sizes[x]), dims=[x])
        xlabel, marker = _axis_label(sub, x), "o"
        if kind == "auto":
            kind = "heatmap" if (hue in sdims and da.sizes.get(hue, 0) >= AUTO_HEATMAP_MIN) else "line"

    fig = Figure(figsize=(7.5, 4.8), layout="constrained")
    FigureCanvasAgg(fig)
    if kind == "heatmap":
        if hue is None or hue not in sdims:
            raise ValueError(_heatmap_needs(("hue",), f"to be a second sweep dimension; sweep dims: "
                                                        f"{', '.join(sdims)}", cli))
        mean = da
        if "replica" in mean.dims and "replica" not in (x, hue):
            mean = mean.mean("replica", skipna=True, keep_attrs=True)
            what += " (mean over replicas)"
        extra = [d for d in mean.dims if d not in (x, hue) and mean.sizes[d] > 1]
        if extra:
            raise ValueError(f"a heat map of {var} over ({x}, {hue}) has more dimensions left: "
                             f"{', '.join(map(str, extra))}; pick one value of each with --sel DIM=VALUE"
                             f"{'' if cli else ' (sel= in Python)'}")
        mean = mean.squeeze([d for d in mean.dims if d not in (x, hue)], drop=True)
        ax = fig.add_subplot()
        _heatmap(ax, fig, sub, mean.transpose(hue, x), x, hue, _axis_label(sub, var))
        ax.set_title(title or _wrap(what + (f"  ({suffix})" if suffix else "")), fontsize="medium")
        return _save(fig, out, return_figure)

    # panels, colour, style, averaged dims
    rest = [str(d) for d in da.dims if d != along and da.sizes[d] > 1]
    points = along != "sample"  # markers with error bars against a sweep dim or bin centres
    facet = None if points else next((d for d in FACET_DIMS if d in rest and d != hue), None)
    if facet is not None and da.sizes[facet] > MAX_FACETS:
        raise ValueError(f"{var} has {da.sizes[facet]} {facet} entries: pick one with "
                         f"{'--sel ' + facet + '=VALUE' if cli else 'sel={' + repr(facet) + ': VALUE}'}")
    lines = [d for d in rest if d != facet and d != "replica"]
    lines = [d for d in lines if d in FACET_DIMS] + [d for d in lines if d not in FACET_DIMS]  # never averaged
    if hue is None:
        hue = lines[0] if lines else None
    if hue is not None and hue not in rest:
        hue = None  # a single value left: nothing to colour
    if hue is not None:
        lines = [hue] + [d for d in lines if d != hue]
    style = lines[1] if len(lines) > 1 and da.sizes[lines[1]] <= len(STYLES) else None
    averaged = [d for d in rest if d not in (facet, hue, style)]
    notes = []
    band_kind = ""
    if "replica" in averaged:
        band_kind = "s.e. over replicas"
        notes.append(f"mean of {da.sizes['replica']} replicas, band: +-1 s.e.")
    others = [d for d in averaged if d != "replica"]
    if others:
        notes.append("mean over " + ", ".join(f"{d} ({da.sizes[d]} values)" for d in others) + ", band: range")
        band_kind = band_kind or "range"
    failed = ~ok if "status" in sub else None

    facets = list(range(da.sizes[facet])) if facet else [None]
    ncols = 2 if len(facets) == 4 else min(len(facets), 3)
    grid = fig.subplots(-(-len(facets) // ncols), ncols, sharex=True, squeeze=False)
    axes = list(grid.ravel())
    for extra_ax in axes[len(facets):]:
        extra_ax.set_visible(False)
    axes = axes[:len(facets)]
    hue_n = da.sizes[hue] if hue else 1
    colors = _colors(hue_n)
    numeric_x = np.asarray(xdata.values).dtype.kind in "iuf"
    for panel, ax in zip(facets, axes):
        part = da.isel({facet: panel}) if facet else da
        part_sem = sem.isel({facet: panel}) if (facet and sem is not None and facet in sem.dims) else sem
        for h in range(hue_n):
            for st in range(da.sizes[style] if style else 1):
                pick = {k: v for k, v in ((hue, h), (style, st)) if k is not None}
                y = part.isel(pick)
                lo = hi = None
                if "replica" in averaged:
                    n = y.count("replica")
                    err = y.std("replica", ddof=1, skipna=True) / np.sqrt(n.where(n > 1))
                    y = y.mean("replica", skipna=True)
                    lo, hi = y - err, y + err
                if others:
                    lo = (lo if lo is not None else y).min(others, skipna=True)
                    hi = (hi if hi is not None else y).max(others, skipna=True)
                    y = y.mean(others, skipna=True)
                elif not averaged and part_sem is not None:
                    e = part_sem.isel({k: v for k, v in pick.items() if k in part_sem.dims})
                    e = e.squeeze([d for d in e.dims if d != along and e.sizes[d] == 1], drop=True)
                    if e.dims == (along,):
                        lo, hi, band_kind = y - e, y + e, f"+-1 s.e. ({sem_name})"
                y = y.squeeze([d for d in y.dims if d != along], drop=True) if y.ndim > 1 else y
                yv = np.asarray(y.transpose(along).values if y.ndim else y.values, float)
                xv = np.asarray(xdata.values) if numeric_x else np.arange(yv.size)
                xv = xv if np.ndim(xv) == 1 and xv.size == yv.size else np.arange(yv.size)
                kw: dict[str, Any] = {"color": colors[h], "linestyle": STYLES[st] if style else "-"}
                if marker:
                    kw.update(marker=marker, markersize=4)
                lov = hiv = None
                if lo is not None:
                    lov = np.asarray(lo.squeeze(drop=True).values, float).reshape(-1)
                    hiv = np.asarray(hi.squeeze(drop=True).values, float).reshape(-1)
                    if lov.size != yv.size:
                        lov = hiv = None
                if lov is not None and points:  # error bars: y - lo below, hi - y above
                    ax.errorbar(xv, yv, yerr=[yv - lov, hiv - yv], capsize=2, **kw)
                    continue
                ax.plot(xv, yv, **kw)
                if lov is not None:
                    ax.fill_between(xv, lov, hiv, color=colors[h], alpha=0.2, linewidth=0)
        if failed is not None and bool(failed.any()):
            _mark_failed(ax, sub, failed, along, xdata, numeric_x)
        if not numeric_x:
            ax.set_xticks(range(xdata.size), [_fmt(v) for v in np.asarray(xdata.values)], rotation=30)
        if axes.index(ax) + ncols >= len(facets):  # no panel below this one
            ax.set_xlabel(xlabel)
        if facet:
            ax.set_title(f"{facet} {_fmt(_coord_value(sub, facet, panel))}", fontsize="medium")
    for row in grid:
        row[0].set_ylabel(_axis_label(sub, var))
    _legend(fig, axes[-1], sub, hue, style, colors, band_kind)
    if failed is not None and bool(failed.any()):
        bad = [_case_label({d: _coord_value(sub, d, i) for d, i in zip(failed.dims, idx)})
               for idx in zip(*np.nonzero(np.asarray(failed.values)))] if failed.ndim else ["(single case)"]
        notes.append(f"{len(bad)} of {failed.size} case(s) failed" + (
            f" (marked x): {'; '.join(bad[:3])}{' ...' if len(bad) > 3 else ''}" if along != "sample"
            else f", not drawn: {'; '.join(bad[:3])}{' ...' if len(bad) > 3 else ''}"))
    head = title or (what + (f"  ({suffix})" if suffix else ""))
    fig.suptitle("\n".join(_wrap(t, 60) for t in [head] + notes), fontsize="medium")
    return _save(fig, out, return_figure)


def _mark_failed(ax, ds: xr.Dataset, failed: xr.DataArray, along: str, xdata: xr.DataArray, numeric_x: bool) -> None:
    """Red crosses at the bottom of the axes where a failed case sits on the x axis."""
    if along not in failed.dims:
        return
    any_failed = np.asarray(failed.any([d for d in failed.dims if d != along]).values, bool) if failed.ndim > 1 \
        else np.asarray(failed.values, bool)
    xv = np.asarray(xdata.values, float) if numeric_x else np.arange(any_failed.size, dtype=float)
    if any_failed.any():
        ax.plot(xv[any_failed], np.full(int(any_failed.sum()), 0.03), linestyle="none", marker="x", color="red",
                markersize=8, transform=ax.get_xaxis_transform(), label="failed case", clip_on=False)


def _legend(fig, ax, ds: xr.Dataset, hue: str | None, style: str | None, colors: list, band: str) -> None:
    """Legend entries: one per hue value (or a colour bar for many), one per line style, the band
    and failed-case marks."""
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    colour: list = []
    if hue is not None and len(colors) > MAX_LEGEND:
        import matplotlib as mpl

        vals = np.asarray(ds[hue].values, float) if hue in ds.coords and ds[hue].dtype.kind in "iuf" \
            else np.arange(len(colors), dtype=float)
        norm = mpl.colors.Normalize(vmin=float(np.nanmin(vals)), vmax=float(np.nanmax(vals)))
        bar = fig.colorbar(mpl.cm.ScalarMappable(norm=norm, cmap="viridis"), ax=fig.axes)
        bar.set_label(_axis_label(ds, hue))
    elif hue is not None:
        colour = [Line2D([], [], color=c, label=f"{hue}={_fmt(_coord_value(ds, hue, i))}")
                  for i, c in enumerate(colors)]
    styles = [Line2D([], [], color="black", linestyle=STYLES[i], label=f"{style}={_fmt(_coord_value(ds, style, i))}")
              for i in range(ds.sizes[style])] if style is not None else []
    extra: list = []
    if band:
        extra.append(Patch(color="grey", alpha=0.3, label=band))
    if any(line.get_label() == "failed case" for a in fig.axes for line in a.get_lines()):
        extra.append(Line2D([], [], color="red", marker="x", linestyle="none", label="failed case"))
    rows = [r for r in (colour, styles, extra) if r]
    if not rows:
        return
    ncols = min(max(len(r) for r in rows), 6)
    rows = [r[k:k + ncols] for r in rows for k in range(0, len(r), ncols)]  # a group per row
    blank = Line2D([], [], linestyle="none", label=" ")
    handles = [row[c] if c < len(row) else blank for c in range(ncols) for row in rows]  # column-major
    fig.legend(handles=handles, fontsize="small", loc="outside lower center", ncols=ncols)


def _save(fig, out: str | Path, return_figure: bool):
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=120)
    return (out, fig) if return_figure else out


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
    ax.set_xlabel(_axis_label(ds, x))
    ax.set_ylabel(_axis_label(ds, y))


# ----------------------------------------------------------------------------- JSON schema


__all__ = ["summary", "plot", "select", "sweep_dims", "ok_mask", "WallbatchAccessor"]
