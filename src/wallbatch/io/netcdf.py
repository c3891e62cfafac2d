"""Results as labelled arrays (io/results.py `Results`, or an xarray Dataset), written to NetCDF-4
(docs/reference/outputs.md).

Dimensions: one per sweep entry (in declared order), `sample`, `fix`, `face`. A run without a
sweep has no sweep dimensions. A failed case keeps its grid place with NaN outputs.

The results are built and written without xarray (netCDF4 directly, the calls xarray's writer
makes, so the file is the same and `xarray.open_dataset` reads back the Dataset that
`Results.to_xarray` gives); xarray is imported only to return or read a Dataset.
"""

from __future__ import annotations

import contextlib
import dataclasses
import datetime as _dt
import itertools
import os
from pathlib import Path
from typing import TYPE_CHECKING, Any, Iterable, Iterator, Sequence

import numpy as np

from wallbatch.version import __version__
from wallbatch.config.sweep import SweepDim
from wallbatch.engine.engine import CaseResult, sample_instants
from wallbatch.engine.profiles import output_name
from wallbatch.io.averages import add_averages, profile_variables
from wallbatch.io.results import Results, Var
from wallbatch.scene.case import Case

if TYPE_CHECKING:
    import xarray as xr

LONG_NAMES = {
    "time": "elapsed simulated time",
    "dt": "timestep in force",
    "temp": "translational temperature (d N - d degrees of freedom, d = dimension)",
    "ecouple": "energy the thermostats took from the atoms, cumulative (LAMMPS ecouple)",
    "econserve": "etot + ecouple: conserved up to integration error (LAMMPS econserve)",
    "ke": "kinetic energy",
    "pe": "potential energy (pair + walls with energy: true)",
    "etot": "total energy ke + pe",
    "atoms": "number of atoms",
    "wall_energy": "wall fix global scalar: total shifted wall energy (LAMMPS f_ID)",
    "wall_force": "wall fix global vector entry: force of the atoms on the wall along +dim (LAMMPS f_ID[i])",
    "reflect_count": "reflections at the face since the previous sample",
    "erot": "rotational kinetic energy of the ellipsoids (compute erotate/asphere)",
    "press": "pressure: kinetic + pair virial + virial of walls with virial: true (compute pressure)",
    "region_force": "wall/region fix global vector: force of the atoms on the region wall (LAMMPS f_ID[1..3])",
    "flow_crossings": "flow-wall crossings (velocity redraws) since the previous sample",
    "reflect_impulse": "momentum given to the wall along +dim since the previous sample",
    "step": "timestep number",
}


MIN_OUTPUTS = {  # per case, with `minimize:` (name: long_name)
    "min_iterations": "minimizer iterations",
    "min_evaluations": "minimizer force/energy evaluations",
    "min_stop_reason": "minimizer stopping criterion (LAMMPS wording)",
    "min_energy_before": "minimized energy (pair + walls with energy: true) before minimization",
    "min_energy": "minimized energy (pair + walls with energy: true) after minimization",
    "min_fnorm": "2-norm of the force vector after minimization",
}


def _units(case: Case) -> dict[str, str]:
    u = case.units
    impulse = "1" if u.name == "lj" else f"{u.force}*{u.time}"
    return {"time": u.time, "dt": u.time, "temp": u.temperature, "ke": u.energy, "pe": u.energy,
            "etot": u.energy, "wall_energy": u.energy, "wall_force": u.force, "atoms": "1",
            "reflect_count": "1", "reflect_impulse": impulse, "step": "1", "erot": u.energy,
            "press": u.pressure, "region_force": u.force, "flow_crossings": "1",
            "ecouple": u.energy, "econserve": u.energy}


def build_dataset(results: Iterable[CaseResult], c0: Case, *, config_text: str = "",
                  sweep_text: str = "", dims: Sequence[SweepDim] = (),
                  dump_paths: Sequence[str] | None = None) -> xr.Dataset:
    """`build_results` as an xarray Dataset."""
    return build_results(results, c0, config_text=config_text, sweep_text=sweep_text, dims=dims,
                         dump_paths=dump_paths).to_xarray()


def build_results(results: Iterable[CaseResult], c0: Case, *, config_text: str = "",
                  sweep_text: str = "", dims: Sequence[SweepDim] = (),
                  dump_paths: Sequence[str] | None = None) -> Results:
    """Stack per-case results (in C order over `dims`) into the outputs.md layout; `c0` is any
    case of the plan (they share sample instants, fixes and faces).

    `results` may be an iterator (e.g. reading parts back one at a time): it is consumed once,
    each result copied into the output arrays and released, so the results are never all in
    memory twice."""
    shape = tuple(len(d.values) for d in dims)
    sweep_dims = tuple(d.name for d in dims)
    ncase = int(np.prod(shape, dtype=int))
    units = _units(c0)
    if c0.run_time is None:
        instants = np.asarray(sample_instants(c0), dtype=np.int64)
        coords: dict = {"step": ("sample", instants)}
        per_sample = ["time", "dt", "temp", "ke", "pe", "etot", "atoms", "erot", "press", "flow_crossings", "ecouple",
                      "econserve"]
    else:
        instants = np.asarray(sample_instants(c0), dtype=float)
        coords = {"time": ("sample", instants)}
        per_sample = ["step", "dt", "temp", "ke", "pe", "etot", "atoms", "erot", "press", "flow_crossings", "ecouple",
                      "econserve"]
    nsamp = len(instants)
    fixes = list(c0.fix_order)
    rfixes = [w.fix_id for w in c0.region_walls]
    faces = [f for w in c0.soft_walls for f in w.faces]
    rfaces = [f for w in c0.reflect_walls for f in w.faces]
    stats = "reflect_count" in c0.outputs or "reflect_impulse" in c0.outputs
    all_faces = faces + (rfaces if stats else [])
    if fixes:
        coords["fix"] = ("fix", np.asarray(fixes, dtype=object))
    if rfixes:
        coords["rfix"] = ("rfix", np.asarray(rfixes, dtype=object))
        coords["spatial"] = ("spatial", np.asarray(["x", "y", "z"], dtype=object))
    if all_faces:
        coords["face"] = ("face", np.asarray([f.label for f in all_faces], dtype=object))
        coords["face_fix"] = ("face", np.asarray([f.label.split("/")[0] for f in all_faces], dtype=object))
        coords["face_name"] = ("face", np.asarray([f.name for f in all_faces], dtype=object))
    coords.update(_sweep_coords(dims))

    wanted = [k for k in per_sample if k in c0.outputs or k in ("time", "dt", "step")]
    if "step" in wanted and c0.run_time is None:
        wanted.remove("step")
    tails: dict[str, tuple[int, ...]] = {name: () for name in wanted}
    if fixes:
        tails["wall_energy"] = (len(fixes),)
    if rfixes:
        tails["region_force"] = (len(rfixes), 3)
    if faces:
        tails["wall_force"] = (len(faces),)
    if stats:
        for name in ("reflect_count", "reflect_impulse"):
            if name in c0.outputs:
                tails[name] = (len(rfaces),)
    arrays = {name: np.full((ncase, nsamp) + tail, np.nan) for name, tail in tails.items()}
    for p in c0.profiles:  # output.profiles: (window, bin) per case
        for q in p.quantities:
            arrays[output_name(p.name, q)] = np.full((ncase, len(p.window_steps(int(c0.steps or 0))), p.nbins), np.nan)
    status = np.empty(ncase, dtype=object)
    error = np.empty(ncase, dtype=object)
    seconds = np.zeros(ncase)
    minimized = {name: ([""] * ncase if name == "min_stop_reason" else np.full(ncase, np.nan)) for name in MIN_OUTPUTS}
    n = 0
    for i, r in enumerate(results):  # one pass: each result copied in place, then released
        if i >= ncase:
            raise ValueError(f"more than {ncase} results for a sweep grid of shape {shape}")
        for name, arr in arrays.items():
            if name in r.data:
                arr[i] = r.data[name]
        if c0.minimize is not None:
            for name, vals in minimized.items():
                vals[i] = str(r.data.get(name, "")) if name == "min_stop_reason" else float(r.data.get(name, np.nan))
        status[i], error[i], seconds[i] = r.status, r.error, r.seconds
        n = i + 1
    if n != ncase:
        raise ValueError(f"{n} results do not fill a sweep grid of shape {shape}")

    def stacked(name: str) -> np.ndarray:
        arr = arrays.pop(name)
        return arr.reshape(shape + arr.shape[1:])

    data_vars: dict = {}
    for name in wanted:
        data_vars[name] = (sweep_dims + ("sample",), stacked(name))
    if fixes:
        data_vars["wall_energy"] = (sweep_dims + ("sample", "fix"), stacked("wall_energy"))
    if rfixes:
        data_vars["region_force"] = (sweep_dims + ("sample", "rfix", "spatial"), stacked("region_force"))
    if faces:
        wf = stacked("wall_force")
        if len(all_faces) > len(faces):
            wf = np.concatenate([wf, np.full(wf.shape[:-1] + (len(all_faces) - len(faces),), np.nan)], axis=-1)
        data_vars["wall_force"] = (sweep_dims + ("sample", "face"), wf)
    if stats:
        for name in ("reflect_count", "reflect_impulse"):
            if name in c0.outputs:
                arr = stacked(name)
                pad = np.full(arr.shape[:-1] + (len(faces),), np.nan)
                data_vars[name] = (sweep_dims + ("sample", "face"), np.concatenate([pad, arr], axis=-1))
    if c0.minimize is not None:
        for name, vals in minimized.items():
            vals = np.asarray(vals, dtype=object) if name == "min_stop_reason" else vals
            data_vars[name] = (sweep_dims, vals.reshape(shape))
    data_vars["status"] = (sweep_dims, status.reshape(shape))
    data_vars["error"] = (sweep_dims, error.reshape(shape))
    data_vars["seconds"] = (sweep_dims, seconds.reshape(shape))
    if dump_paths is not None:
        data_vars["dump_path"] = (sweep_dims, np.asarray(dump_paths, dtype=object).reshape(shape))
    pvars, pcoords = profile_variables((), c0, shape, sweep_dims, filled=arrays)  # output.profiles
    data_vars.update(pvars)
    coords.update(pcoords)
    ds = Results({k: v if isinstance(v, Var) else Var(*v) for k, v in data_vars.items()},
                 {k: v if isinstance(v, Var) else Var(*v) for k, v in coords.items()})
    for name, var in ds.variables.items():
        if name in units:
            var.attrs["units"] = units[name]
        if name in LONG_NAMES:
            var.attrs["long_name"] = LONG_NAMES[name]
    u = c0.units
    for name, long_name in MIN_OUTPUTS.items():
        if name in ds:
            unit = {"min_energy_before": u.energy, "min_energy": u.energy, "min_fnorm": u.force}.get(name, "1")
            ds[name].attrs.update(units=unit, long_name=long_name)
    ds["seconds"].attrs.update(units="s", long_name="wall-clock seconds of the case: its build, plus the running "
                                                 "time of its batch shared among the cases running at each sample")
    text_attrs = {
        "status": "ok or failed", "error": "error message of a failed case, empty when ok",
        "face": "wall face, as fixID/face", "face_fix": "fix ID of the face", "face_name": "face name (xlo ... zhi)",
        "fix": "wall fix ID", "rfix": "region wall fix ID", "spatial": "force component",
        "dump_path": "per-atom trajectory of the case (AMBER NetCDF), relative to this file",
    }
    for name, long_name in text_attrs.items():
        if name in ds:
            ds[name].attrs.update(units="1", long_name=long_name)
    for d in dims:
        ds[d.name].attrs.setdefault("long_name", f"swept {d.path}" if d.name != "replica" else "replica (random stream)")
        ds[d.name].attrs.setdefault("units", "1")
        for k in d.extra:
            ds[k].attrs.update(long_name=f"swept {ds[k].attrs['path']}", units="1")
    ds.attrs.update({
        "Conventions": "CF-1.10",
        "title": f"wallbatch results: {c0.name}",
        "units_style": c0.units.name,
        "config": config_text,
        "sweep": sweep_text,
        "wallbatch_version": __version__,
        "created": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
    })
    add_averages(ds, c0)  # <var>_mean/_sem/_sem_converged, wall_pressure_*
    return ds


def _sweep_coords(dims: Sequence[SweepDim]) -> dict[str, Var]:
    """The coordinates along the sweep dimensions: each dimension's values, and a zip's
    parameters along its dimension (extra coordinates), each with the path(s) it sets."""
    coords: dict[str, Var] = {}
    for d in dims:
        coords[d.name] = Var((d.name,), _coord_values(d.values), {"path": d.path})
        for k, (vals, paths) in d.extra.items():  # a zip's parameters along its dimension
            coords[k] = Var((d.name,), _coord_values(vals), {"path": ", ".join(paths)})
    return coords


def _coord_values(values: Sequence) -> np.ndarray:
    """One coordinate value per case along a sweep dimension. A value that is itself a list (a
    thermostat's `temp: [Tstart, Tstop]`, a position) is written as its text, `[0.8, 1.6]` (the
    case label's spelling): a 1-d coordinate needs one scalar per case."""
    if any(isinstance(v, (list, tuple, dict)) for v in values):
        return np.asarray([str(list(v) if isinstance(v, tuple) else v) for v in values], dtype=object)
    return np.asarray(values)


BLOCK_BYTES = 2_000_000  # output bytes of a block of cases when the file is written block by block


def case_bytes(c0: Case) -> int:
    """About the bytes the results file holds per case (its per-sample series and profiles):
    sets the number of cases per block of `write_results_file`, not any value."""
    nsamp = len(sample_instants(c0))
    faces = sum(len(w.faces) for w in c0.soft_walls) + sum(len(w.faces) for w in c0.reflect_walls)
    series = len(c0.outputs) + 3 + len(c0.fix_order) + 2 * faces + 3 * len(c0.region_walls)
    windows = sum(len(p.window_steps(int(c0.steps or 0))) * p.nbins * len(p.quantities) for p in c0.profiles)
    return 8 * (nsamp * series + windows) + 200


def case_blocks(shape: tuple[int, ...], size: int) -> Iterator[tuple[slice, ...]]:
    """Blocks of at most `size` cases (but at least one) of a sweep grid of `shape`, in order:
    each a rectangle of the grid (one slice per dimension) whose cases are consecutive in C
    order, so the cases of a block come one after the other from the parts. A grid without
    dimensions (no sweep) is one block ()."""
    if not shape:
        yield ()
        return
    size = max(1, size)
    inner, j = 1, len(shape)  # the trailing dimensions j.. fit whole in a block
    while j > 0 and inner * shape[j - 1] <= size:
        inner *= shape[j - 1]
        j -= 1
    if j == 0:
        yield tuple(slice(0, n) for n in shape)
        return
    step = max(1, size // inner)  # along dimension j - 1
    tail = tuple(slice(0, n) for n in shape[j:])
    for lead in np.ndindex(*shape[:j - 1]):
        for a in range(0, shape[j - 1], step):
            yield tuple(slice(i, i + 1) for i in lead) + (slice(a, min(a + step, shape[j - 1])),) + tail


def _block_dims(dims: Sequence[SweepDim], block: tuple[slice, ...]) -> list[SweepDim]:
    """The sweep dimensions restricted to a block of the grid."""
    return [dataclasses.replace(d, values=list(d.values[s]),
                                extra={k: (list(vals[s]), paths) for k, (vals, paths) in d.extra.items()})
            for d, s in zip(dims, block)]


def write_results_file(results: Iterable[CaseResult], c0: Case, path: str | Path, *, config_text: str = "",
                       sweep_text: str = "", dims: Sequence[SweepDim] = (), dump_paths: Sequence[str] | None = None,
                       block_bytes: int = BLOCK_BYTES) -> Results:
    """Write the results file of per-case results (in C order over `dims`, e.g. read back from
    the parts one at a time) block by block, never holding more than a block of cases (about
    `block_bytes` of outputs): the variables are created first, as `write_netcdf` of
    `build_results` creates them, then each block (a rectangle of the grid, see `case_blocks`)
    is built by `build_results` (its averages too: they are per case) and written in its place.
    The file holds the same values as `write_netcdf(build_results(...))` (atomic too: a
    temporary file renamed into place). Returns the per-case status, error and seconds with the
    sweep coordinates (what a caller needs to report failures), not the outputs."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    shape = tuple(len(d.values) for d in dims)
    ncase = int(np.prod(shape, dtype=int))
    coords = _sweep_coords(dims)
    if not all(_plain(v.data) for v in coords.values()):  # e.g. None among the values: xarray writes it
        ds = build_results(results, c0, config_text=config_text, sweep_text=sweep_text, dims=dims,
                           dump_paths=dump_paths)
        write_netcdf(ds, path)
        return _summary(ds, coords)
    swept = {d.name: axis for axis, d in enumerate(dims)}
    size = max(1, block_bytes // case_bytes(c0))
    tmp = path.with_name(path.name + ".tmp")
    status = np.empty(ncase, dtype=object)
    error = np.empty(ncase, dtype=object)
    seconds = np.zeros(ncase)
    nc = None
    first: Results | None = None
    stream = iter(results)
    try:
        start = 0
        for block in case_blocks(shape, size):
            count = int(np.prod([s.stop - s.start for s in block], dtype=int))
            ds = build_results(itertools.islice(stream, count), c0, config_text=config_text, sweep_text=sweep_text,
                               dims=_block_dims(dims, block),
                               dump_paths=None if dump_paths is None else dump_paths[start:start + count])
            if nc is None:  # the file, its dimensions and variables, as write_netcdf makes them
                first = ds
                layout = Results({}, {})  # the first block with the whole grid's sweep coordinates
                layout.variables = {name: Var(v.dims, coords[name].data, v.attrs) if name in coords else v
                                    for name, v in ds.variables.items()}
                layout.coord_names, layout.attrs = ds.coord_names, ds.attrs
                bad = [name for name, v in layout.variables.items() if not _plain(v.data)]
                if bad:
                    raise ValueError(f"{bad[0]}: values the results file cannot hold ({layout[bad[0]].data.dtype})")
                sizes = {name: len(dims[swept[name]].values) if name in swept else n for name, n in ds.dims.items()}
                nc, attrs_of = _create_file(tmp, layout, sizes)
                variables = {}
                for name, v in layout.variables.items():
                    var = variables[name] = _create_variable(nc, name, v, attrs_of[name])
                    if name in coords or not swept.keys() & set(v.dims):  # whole: sweep coordinates, sample ...
                        var[...] = _file_data(v.data)
            for name, v in ds.variables.items():
                if name in coords or not swept.keys() & set(v.dims):
                    continue
                if not _plain(v.data):
                    raise ValueError(f"{name}: values the results file cannot hold ({v.data.dtype})")
                variables[name][tuple(block[swept[d]] if d in swept else slice(None) for d in v.dims)] = \
                    _file_data(v.data)
            status[start:start + count] = ds["status"].data.ravel()
            error[start:start + count] = ds["error"].data.ravel()
            seconds[start:start + count] = ds["seconds"].data.ravel()
            start += count
        if next(stream, None) is not None:
            raise ValueError(f"more than {ncase} results for a sweep grid of shape {shape}")
        nc.close()
        nc = None
        os.replace(tmp, path)
    except BaseException:
        if nc is not None:
            with contextlib.suppress(Exception):
                nc.close()
        with contextlib.suppress(OSError):
            tmp.unlink()
        raise
    assert first is not None
    out = Results({"status": Var(first["status"].dims, status.reshape(shape), first["status"].attrs),
                   "error": Var(first["error"].dims, error.reshape(shape), first["error"].attrs),
                   "seconds": Var(first["seconds"].dims, seconds.reshape(shape), first["seconds"].attrs)},
                  {name: Var(v.dims, v.data, first[name].attrs) for name, v in coords.items()})
    out.attrs.update(first.attrs)
    return out


def _summary(ds: Results, coords: dict[str, Var]) -> Results:
    """The per-case status, error and seconds of `ds` with its sweep coordinates."""
    out = Results({name: ds[name] for name in ("status", "error", "seconds")}, {name: ds[name] for name in coords})
    out.attrs.update(ds.attrs)
    return out


def write_netcdf(ds: Results | xr.Dataset, path: str | Path) -> Path:
    """Write atomically (a temporary file renamed into place), NetCDF-4. `Results` of plain
    arrays (float64, int64, bool, strings) are written with netCDF4 directly, making the calls
    xarray's writer makes; anything else (an xarray Dataset, an object array holding None)
    goes through xarray."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + ".tmp")
    if isinstance(ds, Results) and all(_plain(v.data) for v in ds.variables.values()):
        _write_results(ds, tmp)
    else:
        xds = ds.to_xarray() if isinstance(ds, Results) else ds
        encoding = {name: {"dtype": str} for name in ("status", "error", "dump_path", "min_stop_reason")
                    if name in xds}
        xds.to_netcdf(tmp, format="NETCDF4", engine="netcdf4", encoding=encoding)
    os.replace(tmp, path)
    return path


def _plain(data: np.ndarray) -> bool:
    """An array `_write_results` writes as xarray would: float64, int64, bool, str (fixed-width
    unicode, or objects that are all str)."""
    kind = data.dtype.kind
    if kind in "fi":
        return data.dtype.itemsize == 8
    if kind in "bU":
        return True
    return kind == "O" and all(isinstance(x, str) for x in data.flat)


def _write_results(ds: Results, path: Path) -> None:
    """`Results` to NetCDF-4 with netCDF4, as xarray's `to_netcdf(engine="netcdf4")` does: global
    attributes, dimensions in order of first use, then each variable (contiguous=False, default
    chunks, no compression) with its attributes; floats get _FillValue NaN; bool is stored as
    int8 with attribute dtype = "bool"; strings as variable-length strings; non-dimension
    coordinates are named in each variable's `coordinates` attribute (CF), or globally when no
    variable carries them."""
    nc, attrs_of = _create_file(path, ds, ds.dims)
    try:
        for name, v in ds.variables.items():
            _create_variable(nc, name, v, attrs_of[name])[...] = _file_data(v.data)
    finally:
        nc.close()


def _file_attrs(ds: Results) -> tuple[dict[str, Any], dict[str, dict[str, Any]]]:
    """(global attributes, attributes of each variable) as written: the CF `coordinates`
    attribute added where xarray adds it, bool variables marked dtype = "bool"."""
    variables = ds.variables
    non_dim = {k for k in ds.coord_names if k not in variables[k].dims}
    attrs_of: dict[str, dict[str, Any]] = {k: dict(v.attrs) for k, v in variables.items()}
    written: set[str] = set()
    for k, v in variables.items():
        if "coordinates" in attrs_of[k]:
            written.update(str(attrs_of[k]["coordinates"]).split())
            continue
        if k in non_dim or k in v.dims:
            continue
        names = sorted(c for c in non_dim if set(variables[c].dims) <= set(v.dims))
        if names:
            attrs_of[k]["coordinates"] = " ".join(names)
            written.update(names)
    global_attrs = dict(ds.attrs)
    loose = non_dim - written
    if loose and "coordinates" not in global_attrs:
        global_attrs["coordinates"] = " ".join(sorted(loose))
    for k, v in variables.items():
        if v.data.dtype.kind == "b":
            attrs_of[k]["dtype"] = "bool"
    return global_attrs, attrs_of


def _create_file(path: Path, ds: Results, sizes: dict[str, int]) -> tuple[Any, dict[str, dict[str, Any]]]:
    """A new NetCDF-4 file holding the global attributes of `ds` and its dimensions (in order of
    first use; `sizes` gives their lengths), its variables still to be created; and the
    attributes each variable will carry (`_file_attrs`)."""
    import netCDF4

    global_attrs, attrs_of = _file_attrs(ds)
    nc = netCDF4.Dataset(path, mode="w", clobber=True, diskless=False, persist=False, format="NETCDF4")
    try:
        for key, value in global_attrs.items():
            if isinstance(value, list) and value and all(isinstance(x, str) for x in value):
                nc.setncattr_string(key, value)
            else:
                nc.setncattr(key, value)
        for name in ds.dims:
            nc.createDimension(name, size=sizes[name])
    except BaseException:
        nc.close()
        raise
    return nc, attrs_of


def _create_variable(nc: Any, name: str, v: Var, attrs: dict[str, Any]) -> Any:
    """Create variable `name` (`v`'s dims and type) in `nc` (made by _create_file) with `attrs`;
    returns it, ready to take `_file_data` of its values."""
    data, fill = v.data, None
    kind = data.dtype.kind
    if kind == "b":
        data = data.astype("i1")
    if kind in "OU":
        datatype: Any = str
    else:
        datatype = data.dtype.newbyteorder("=") if data.dtype.byteorder not in "=|" else data.dtype
        if kind == "f":
            fill = np.array(np.nan, dtype=datatype)[()]
    var = nc.createVariable(varname=name, datatype=datatype, dimensions=v.dims, zlib=False, complevel=4,
                            shuffle=True, fletcher32=False, contiguous=False, chunksizes=None,
                            endian="native", least_significant_digit=None, fill_value=fill)
    var.setncatts(attrs)
    var.set_auto_maskandscale(False)
    return var


def _file_data(data: np.ndarray) -> np.ndarray:
    """Values as stored: bool as int8."""
    return data.astype("i1") if data.dtype.kind == "b" else data
