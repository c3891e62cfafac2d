"""The results file written block by block from the parts (io/netcdf.py `write_results_file`,
what `wallbatch run` writes) holds the very file `write_netcdf(build_results(...))` writes: the same
dimensions in the same order, variable types, chunking, attributes and value bytes (averages
computed per block: they are per case), whatever the block size; the final pass holds about one
block of cases, not the whole grid; an interrupt while writing keeps every part."""

from __future__ import annotations

import itertools
import tracemalloc
from pathlib import Path

import netCDF4
import numpy as np
import pytest
import xarray as xr
from factories import results_file_plans

from wallbatch.batch.runner import PART_SUFFIX, Interrupted, _first_case, parts_dir, run_plan
from wallbatch.config.sweep import SweepDim
from wallbatch.engine.engine import CaseResult
from wallbatch.io import netcdf
from wallbatch.io.netcdf import (
    build_results,
    case_blocks,
    case_bytes,
    write_netcdf,
    write_results_file,
)


@pytest.fixture(scope="module")
def runs():
    """Per plan: (plan, first case, every case's result in plan order)."""
    out = {}
    for name, plan in results_file_plans().items():
        got: dict[int, CaseResult] = {}
        run_plan(plan, None, progress=False, as_xarray=False, on_result=lambda i, r: got.__setitem__(i, r))
        out[name] = (plan, _first_case(plan, set()), [got[i] for i in range(len(plan.cases))])
    return out


def _content(path: Path) -> dict:
    """Everything of a file but its creation time: dimensions in order, global attributes, and per
    variable its dims, type, storage, attributes and value bytes."""
    with netCDF4.Dataset(path) as nc:
        nc.set_auto_mask(False)
        out: dict = {"dims": [(k, len(d)) for k, d in nc.dimensions.items()],
                     "attrs": repr([(k, nc.getncattr(k)) for k in nc.ncattrs() if k != "created"]),
                     "order": list(nc.variables)}
        for k, v in nc.variables.items():
            a = np.asarray(v[...])
            out[k] = (v.dimensions, str(v.dtype), v.chunking(), repr([(n, v.getncattr(n)) for n in v.ncattrs()]),
                      a.dtype.str, a.shape, a.tobytes() if a.dtype.kind != "O" else a.tolist())
    return out


@pytest.mark.slow
@pytest.mark.parametrize("name", ["zip-strings-ints", "reflect-stats", "time-based", "profiles-minimize",
                                  "none-in-coordinate"])
def test_streamed_file_is_the_file_of_the_whole_results(runs, name, tmp_path):
    plan, c0, results = runs[name]
    kw = dict(config_text=plan.base_text, sweep_text=plan.sweep_text, dims=plan.dims)
    ref = build_results(iter(results), c0, **kw)
    write_netcdf(ref, tmp_path / "whole.nc")
    whole = _content(tmp_path / "whole.nc")
    assert len(whole["order"]) > 15
    for cases in (1, 2, 4, 5, 10**6):  # blocks of 1, 2, 4, 5 cases (rectangles of the 3x3x3 grid), all
        out = tmp_path / f"b{cases}.nc"
        summary = write_results_file(iter(results), c0, out, block_bytes=cases * case_bytes(c0), **kw)
        assert _content(out) == whole, cases
        assert not Path(str(out) + ".tmp").exists()
        assert list(summary.variables) == ["status", "error", "seconds"] + [d.name for d in plan.dims] + [
            k for d in plan.dims for k in d.extra]
        for k in ("status", "error", "seconds"):
            assert summary[k].dims == ref[k].dims and summary[k].data.tolist() == ref[k].data.tolist()
    if name != "none-in-coordinate":  # None reads back as NaN
        with xr.open_dataset(tmp_path / "b2.nc") as back:
            assert back.drop_attrs().identical(ref.to_xarray().drop_attrs())


@pytest.mark.parametrize("shape", [(), (1,), (7,), (3, 3, 3), (4, 5), (2, 1, 9), (10, 2)])
@pytest.mark.parametrize("size", [1, 2, 3, 4, 5, 9, 10, 1000])
def test_blocks_cover_the_grid_in_order_as_rectangles(shape, size):
    flat = []
    for block in case_blocks(shape, size):
        idx = np.arange(int(np.prod(shape, dtype=int))).reshape(shape)[block].ravel()
        assert 1 <= idx.size <= max(1, size)
        assert np.array_equal(idx, np.arange(idx[0], idx[0] + idx.size))  # consecutive in C order
        flat.extend(idx.tolist())
    assert flat == list(range(int(np.prod(shape, dtype=int))))


@pytest.mark.slow  # over 2.5 s
def test_final_pass_holds_about_one_block(runs, tmp_path):
    """2,000 cases streamed from a generator: the traced peak is a few blocks, while the whole
    output arrays would take 2,000 x case_bytes."""
    plan, c0, results = runs["profiles-minimize"]  # one case: its result stands for 2,000
    dims = [SweepDim("k", list(np.linspace(0.1, 1.0, 2000)), ("walls.w.zlo.epsilon",))]
    template = results[0]

    def stream():
        for _ in range(2000):
            yield CaseResult(template.status, template.error, template.seconds,
                             {k: np.array(v, copy=True) for k, v in template.data.items()})

    whole = 2000 * case_bytes(c0)
    block = 50 * case_bytes(c0)
    tracemalloc.start()
    try:
        base = tracemalloc.get_traced_memory()[0]
        write_results_file(stream(), c0, tmp_path / "big.nc", dims=dims, block_bytes=block)
        peak = tracemalloc.get_traced_memory()[1] - base
    finally:
        tracemalloc.stop()
    assert whole > 10e6
    assert peak < 0.25 * whole, f"{peak / 1e6:.1f} MB traced for {whole / 1e6:.1f} MB of outputs"
    with xr.open_dataset(tmp_path / "big.nc") as back:
        assert back.sizes["k"] == 2000
        np.testing.assert_array_equal(back["ke"].values[1999], template.data["ke"])
        assert np.isfinite(back["ke_mean"].values[0])
        np.testing.assert_array_equal(back["ke_mean"].values, back["ke_mean"].values[0])
        assert (back["min_stop_reason"].values == back["min_stop_reason"].values[0]).all()


@pytest.mark.slow
def test_interrupt_while_writing_keeps_every_part_and_resume_finishes(runs, tmp_path, monkeypatch):
    plan, _, _ = runs["reflect-stats"]
    out = tmp_path / "r.nc"
    real = netcdf._file_data
    calls = itertools.count()

    def stop_later(data):
        if next(calls) == 40:  # in the second block of a 27-case run written 2 cases at a time
            raise KeyboardInterrupt
        return real(data)

    monkeypatch.setattr(netcdf, "BLOCK_BYTES", 2 * case_bytes(_first_case(plan, set())))
    monkeypatch.setattr(netcdf, "_file_data", stop_later)
    monkeypatch.setattr(netcdf.write_results_file, "__kwdefaults__",
                        {**netcdf.write_results_file.__kwdefaults__, "block_bytes": netcdf.BLOCK_BYTES})
    with pytest.raises(Interrupted, match="interrupted: 27/27 cases saved in"):
        run_plan(plan, out, progress=False, as_xarray=False, summary=True)
    assert len(list(parts_dir(out).glob(f"*{PART_SUFFIX}"))) == 27
    assert not out.exists() and not Path(str(out) + ".tmp").exists()
    monkeypatch.setattr(netcdf, "_file_data", real)
    summary = run_plan(plan, out, resume=True, progress=False, as_xarray=False, summary=True)
    assert not parts_dir(out).exists() and (summary["status"].data == "ok").all()
    whole = run_plan(plan, None, progress=False)
    with xr.open_dataset(out) as back:
        for k in ("ke", "pe", "reflect_impulse", "ke_mean", "wall_pressure_mean", "wall_pressure_sem"):
            np.testing.assert_array_equal(back[k].values, whole[k].values)
