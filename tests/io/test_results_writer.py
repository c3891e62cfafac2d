"""The results file written without xarray (io/netcdf.py `write_netcdf` of io/results.py
`Results`) is the file xarray writes: the same netCDF4 calls in the same order with the same
arguments (dimensions, variable types, fill values, chunking and compression settings,
attributes including CF `coordinates` and bool's `dtype`, data bytes), and `xarray.open_dataset`
reads back exactly `Results.to_xarray()`. Scenes: sweeps with zip parameters and string values,
reflect statistics, a failed case, a time-based run, profiles with minimization, an object
coordinate holding None (written through xarray)."""

from __future__ import annotations

import contextlib
from pathlib import Path

import netCDF4
import numpy as np
import pytest
import xarray as xr
from factories import results_file_plans

from wallbatch import api
from wallbatch.batch.runner import run_plan
from wallbatch.io.netcdf import write_netcdf
from wallbatch.io.results import Results

REPO = Path(__file__).resolve().parents[2]
CALLS = {netCDF4.Dataset: ("createDimension", "createVariable", "setncattr", "setncattr_string", "setncatts"),
         netCDF4.Variable: ("setncattr", "setncattr_string", "setncatts", "__setitem__")}


def _norm(x):
    """A comparable form of a call argument (arrays by dtype, shape and bytes; NaN equal to NaN)."""
    if isinstance(x, dict):
        return {k: _norm(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return type(x)(_norm(v) for v in x)
    if isinstance(x, np.ndarray):
        return ("array", x.dtype.str, x.shape, tuple(x.ravel().tolist()) if x.dtype.kind == "O" else x.tobytes())
    if isinstance(x, np.generic):
        return ("scalar", x.dtype.str, "nan" if x.dtype.kind == "f" and np.isnan(x) else x.item())
    if isinstance(x, np.dtype):
        return ("dtype", x.str)
    if isinstance(x, type):
        return ("type", x.__name__)
    return x


@contextlib.contextmanager
def recording():
    """Every netCDF4 call that shapes the file, in order."""
    log, saved = [], []
    for cls, names in CALLS.items():
        for name in names:
            original = getattr(cls, name)

            def spy(self, *a, _original=original, _name=name, **k):
                log.append((_name, _norm(a), _norm(k)))
                return _original(self, *a, **k)

            saved.append((cls, name, original))
            setattr(cls, name, spy)
    try:
        yield log
    finally:
        for cls, name, original in saved:
            setattr(cls, name, original)



@pytest.fixture(scope="module")
def results():
    return {name: run_plan(plan, None, progress=False, as_xarray=False) for name, plan in results_file_plans().items()}


@pytest.mark.slow
@pytest.mark.parametrize("name", ["zip-strings-ints", "reflect-stats", "time-based", "profiles-minimize",
                                  "none-in-coordinate"])
def test_results_file_is_the_file_xarray_writes(results, name, tmp_path):
    res: Results = results[name]
    with recording() as ours:
        write_netcdf(res, tmp_path / "ours.nc")
    with recording() as xarrays:
        write_netcdf(res.to_xarray(), tmp_path / "xarray.nc")
    assert len(ours) > 20 and ours == xarrays
    with xr.open_dataset(tmp_path / "ours.nc") as back:
        assert back.identical(res.to_xarray().load()) or name == "none-in-coordinate"  # None reads back as NaN
        with xr.open_dataset(tmp_path / "xarray.nc") as ref:
            assert back.identical(ref)


def test_failed_case_message_and_nan_outputs_written_as_xarray_would(tmp_path):
    scene = (REPO / "configs" / "quickstart.yaml").read_text()
    assert "sweep:" not in scene
    path = tmp_path / "s.yaml"
    path.write_text(scene + "\nsweep:\n  product: {timestep: [0.005, 50.0]}\n")  # dt = 50: atoms fly off
    res = run_plan(api.load(path, ["run.steps=200"]), None, progress=False, as_xarray=False)
    assert res["status"].values.tolist() == ["ok", "failed"] and res["error"].values[1]
    with recording() as ours:
        write_netcdf(res, tmp_path / "ours.nc")
    with recording() as xarrays:
        write_netcdf(res.to_xarray(), tmp_path / "xarray.nc")
    assert ours == xarrays
    with xr.open_dataset(tmp_path / "ours.nc") as back:
        assert back.identical(res.to_xarray())
        assert np.isnan(back["pe"].values[1]).all() and back["error"].values[1] == res["error"].values[1]
