"""AMBER NetCDF 1.0 trajectories (wallbatch.io.amber), read back with netCDF4 (and MDAnalysis if
it happens to be installed)."""

from __future__ import annotations

import netCDF4
import numpy as np
import pytest

import wallbatch
from wallbatch.io.amber import LJ_NOTE, write_amber

F, N = 3, 4
BOX_LO = np.array([-1.0, 0.0, 2.0])
BOX_HI = np.array([9.0, 5.5, 14.0])


def _data(seed: int = 0):
    rng = np.random.default_rng(seed)
    time = np.array([0.0, 2.0, 4.0])
    x = BOX_LO + rng.random((F, N, 3)) * (BOX_HI - BOX_LO)
    v = rng.normal(size=(F, N, 3)) * 0.01
    return time, x, v


def _chars(var) -> list[str]:
    a = np.asarray(var[:])
    if a.ndim == 1:
        return [b"".join(a).decode()]
    return [b"".join(row).decode() for row in a]


@pytest.mark.parametrize("units", ["lj", "real", "metal"])
def test_convention_layout(tmp_path, units):
    time, x, v = _data()
    out = write_amber(tmp_path / f"{units}.nc", time, x, v, BOX_LO, BOX_HI, units, title="case 0")
    assert out == tmp_path / f"{units}.nc"
    with netCDF4.Dataset(out) as nc:
        assert nc.file_format == "NETCDF3_64BIT_OFFSET"
        assert nc.Conventions == "AMBER"
        assert nc.ConventionVersion == "1.0"
        assert nc.program == "wallbatch"
        assert nc.programVersion == wallbatch.__version__
        assert nc.title == "case 0"
        assert isinstance(nc.wallbatch_units, str) and nc.wallbatch_units.startswith(units)

        dims = nc.dimensions
        assert dims["frame"].isunlimited() and len(dims["frame"]) == F
        assert len(dims["atom"]) == N
        for name, size in [("spatial", 3), ("cell_spatial", 3), ("cell_angular", 3), ("label", 5)]:
            assert len(dims[name]) == size and not dims[name].isunlimited()

        var = nc.variables
        expect = {
            "spatial": ("S1", ("spatial",), None),
            "cell_spatial": ("S1", ("cell_spatial",), None),
            "cell_angular": ("S1", ("cell_angular", "label"), None),
            "time": ("float32", ("frame",), "picosecond"),
            "coordinates": ("float32", ("frame", "atom", "spatial"), "angstrom"),
            "velocities": ("float32", ("frame", "atom", "spatial"), "angstrom/picosecond"),
            "cell_lengths": ("float64", ("frame", "cell_spatial"), "angstrom"),
            "cell_angles": ("float64", ("frame", "cell_angular"), "degree"),
        }
        assert set(expect) <= set(var)
        for name, (dtype, vdims, vunits) in expect.items():
            assert np.dtype(var[name].dtype) == np.dtype(dtype), name
            assert var[name].dimensions == vdims, name
            if vunits is not None:
                assert var[name].units == vunits, name
        assert var["velocities"].scale_factor == 1.0

        assert _chars(var["spatial"]) == ["xyz"]
        assert _chars(var["cell_spatial"]) == ["abc"]
        assert _chars(var["cell_angular"]) == ["alpha", "beta ", "gamma"]

        assert var["time"].shape == (F,)
        assert var["coordinates"].shape == (F, N, 3)
        np.testing.assert_array_equal(var["coordinates"][:], x.astype(np.float32))
        lengths = np.asarray(var["cell_lengths"][:])
        np.testing.assert_array_equal(lengths, np.tile([10.0, 5.5, 12.0], (F, 1)))
        np.testing.assert_array_equal(var["cell_angles"][:], np.full((F, 3), 90.0))


def test_real_conversion_exact(tmp_path):
    time = np.array([0.0, 2.0])
    x = np.zeros((2, 1, 3))
    v = np.full((2, 1, 3), 0.01)
    out = write_amber(tmp_path / "real.nc", time, x, v, np.zeros(3), np.full(3, 10.0), "real")
    with netCDF4.Dataset(out) as nc:
        nc.set_auto_maskandscale(False)
        t = nc["time"][:]
        vel = nc["velocities"][:]
        assert "1000" in nc.wallbatch_units
    np.testing.assert_array_equal(t, np.array([0.0, 0.002], dtype=np.float32))
    assert t[1] == np.float32(0.002)
    np.testing.assert_allclose(vel, 10.0, rtol=1e-6)
    assert np.all(np.abs(vel - 10.0) <= np.spacing(np.float32(10.0)))


@pytest.mark.parametrize("units", ["metal", "lj"])
def test_metal_and_lj_unchanged(tmp_path, units):
    time, x, v = _data(1)
    out = write_amber(tmp_path / "t.nc", time, x, v, BOX_LO, BOX_HI, units)
    with netCDF4.Dataset(out) as nc:
        nc.set_auto_maskandscale(False)
        np.testing.assert_array_equal(nc["time"][:], time.astype(np.float32))
        np.testing.assert_array_equal(nc["velocities"][:], v.astype(np.float32))
        np.testing.assert_array_equal(nc["coordinates"][:], x.astype(np.float32))
        if units == "lj":
            assert nc.wallbatch_units == LJ_NOTE
        else:
            assert "unchanged" in nc.wallbatch_units


def test_velocities_omitted(tmp_path):
    time, x, _ = _data()
    out = write_amber(tmp_path / "x.nc", time, x, None, BOX_LO, BOX_HI, "metal")
    with netCDF4.Dataset(out) as nc:
        assert "velocities" not in nc.variables
        assert "coordinates" in nc.variables
        assert len(nc.dimensions["frame"]) == F


def test_coordinates_omitted(tmp_path):
    time, _, v = _data()
    out = write_amber(tmp_path / "v.nc", time, None, v, BOX_LO, BOX_HI, "real")
    with netCDF4.Dataset(out) as nc:
        assert "coordinates" not in nc.variables
        assert len(nc.dimensions["atom"]) == N
        assert nc["velocities"].shape == (F, N, 3)


def test_per_frame_box(tmp_path):
    time, x, v = _data()
    lo = np.tile(BOX_LO, (F, 1))
    hi = np.tile(BOX_HI, (F, 1)) + np.arange(F)[:, None]
    out = write_amber(tmp_path / "b.nc", time, x, v, lo, hi, "metal")
    with netCDF4.Dataset(out) as nc:
        np.testing.assert_array_equal(nc["cell_lengths"][:], hi - lo)


def test_atomic_write_leaves_no_temp(tmp_path):
    time, x, v = _data()
    target = tmp_path / "sub" / "traj.nc"
    write_amber(target, time, x, v, BOX_LO, BOX_HI, "real")
    # overwrite in place: still one file, no temporaries
    write_amber(target, time[:2], x[:2], v[:2], BOX_LO, BOX_HI, "real")
    assert [p.name for p in target.parent.iterdir()] == ["traj.nc"]
    with netCDF4.Dataset(target) as nc:
        assert len(nc.dimensions["frame"]) == 2


def test_failed_write_leaves_nothing(tmp_path, monkeypatch):
    time, x, v = _data()
    target = tmp_path / "traj.nc"

    def boom(*args, **kwargs):
        raise OSError("disk full")

    monkeypatch.setattr("wallbatch.io.amber.os.replace", boom)
    with pytest.raises(OSError, match="disk full"):
        write_amber(target, time, x, v, BOX_LO, BOX_HI, "real")
    assert list(tmp_path.iterdir()) == []


def test_bad_input(tmp_path):
    time, x, v = _data()
    with pytest.raises(ValueError):
        write_amber(tmp_path / "a.nc", time, x, v, BOX_LO, BOX_HI, "si")
    with pytest.raises(ValueError):
        write_amber(tmp_path / "a.nc", time, None, None, BOX_LO, BOX_HI, "lj")
    with pytest.raises(ValueError):
        write_amber(tmp_path / "a.nc", time[:2], x, v, BOX_LO, BOX_HI, "lj")
    assert list(tmp_path.iterdir()) == []


def test_mdanalysis_reads(tmp_path):
    trj = pytest.importorskip("MDAnalysis.coordinates.TRJ")
    time, x, v = _data()
    out = write_amber(tmp_path / "md.nc", time, x, v, BOX_LO, BOX_HI, "real")
    reader = trj.NCDFReader(str(out))
    try:
        assert reader.n_frames == F
        assert reader.n_atoms == N
        for i, ts in enumerate(reader):
            np.testing.assert_allclose(ts.positions, x[i], rtol=1e-6)
            np.testing.assert_allclose(ts.velocities, v[i] * 1000.0, rtol=1e-5)
            np.testing.assert_allclose(ts.dimensions, [10.0, 5.5, 12.0, 90.0, 90.0, 90.0])
            assert ts.time == pytest.approx(time[i] / 1000.0, rel=1e-6)
    finally:
        reader.close()
