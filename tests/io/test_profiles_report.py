"""Profiles and averages in `wallbatch show`, `wallbatch plot` and the `ds.wallbatch` accessor."""

from __future__ import annotations

import re

import matplotlib
import numpy as np
import pytest
import xarray as xr
from matplotlib.container import ErrorbarContainer
from typer.testing import CliRunner

from wallbatch.api import run
from wallbatch.cli import app
from wallbatch.io.netcdf import write_netcdf
from wallbatch.io.report import _pm, plot, summary, sweep_dims

matplotlib.use("Agg")


@pytest.fixture(scope="module")
def results(tmp_path_factory) -> tuple[xr.Dataset, str]:
    cfg = {
        "box": {"lo": [0, 0, 0], "hi": [6, 6, 8], "boundary": ["p", "p", "f"]},
        "regions": {"slab": {"style": "block", "lo": [0, 0, 2], "hi": [6, 6, 6], "units": "box"}},
        "atoms": [{"group": "gas", "create": {"random": {"count": 150, "region": "slab"}}, "mass": 1.0,
                   "velocity": {"temperature": 1.0}}],
        "walls": {"w": {"style": "harmonic", "units": "box", "zlo": [-1.0, 5.0, 1.0, 3.0],
                        "zhi": [9.0, 5.0, 1.0, 3.0]}},
        "run": {"steps": 1000, "thermo": 10},
        "output": {"profiles": {"across": {"axis": "z", "bins": 8, "every": 5, "repeat": 4, "freq": 20,
                                           "quantities": ["density/number", "temp"]}},
                   "averages": {"start": 200}},
        "sweep": {"product": {"k": {"path": ["walls.w.zlo.epsilon", "walls.w.zhi.epsilon"], "values": [5.0, 10.0]}}},
    }
    ds = run(cfg)
    path = tmp_path_factory.mktemp("prof") / "r.nc"
    write_netcdf(ds, path)
    return xr.open_dataset(path), str(path)


def test_plus_minus_format():
    assert _pm(1.23456, 0.0123) == "1.235 ± 0.012"
    assert _pm(587.18, 0.53, False) == "587.18 ± 0.53*"
    assert _pm(12345.0, 230.0) == "12345 ± 230"
    assert _pm(float("nan"), 1.0) == "nan"


def test_window_and_bins_are_not_sweep_dims(results):
    ds, _ = results
    assert sweep_dims(ds) == ["k"]


def test_show_prints_means_with_errors(results):
    ds, path = results
    text = summary(ds)
    assert "Time averages over samples at or after step 200" in text
    assert re.search(r"window\s+50\s+profile windows ending at step 20, 40", text)
    assert re.search(r"across_bin\s+8\s+bin centres 0\.5 \.\. 7\.5", text)
    m, e = ds["temp_mean"].sel(k=5.0).item(), ds["temp_sem"].sel(k=5.0).item()
    line = [ln for ln in text.splitlines() if ln.strip().startswith("temp ") and "±" in ln][0]
    assert _pm(m, e, bool(ds["temp_sem_converged"].sel(k=5.0))) in line
    assert re.search(r"wall_pressure\s+w/zlo [0-9.]+ ± [0-9.]+\*?\s+w/zhi", text)
    out = CliRunner().invoke(app, ["show", path])
    assert out.exit_code == 0 and "Time averages" in out.output


def test_accessor_profile_and_mean(results):
    ds, _ = results
    prof = ds.wallbatch.profile("across", "density/number")
    assert prof.dims == ("k", "window", "across_bin") and prof.name == "profile_across_density_number"
    # every window holds the 150 atoms: sum(density) * bin volume = N
    np.testing.assert_allclose((prof * 36.0).sum("across_bin").values, 150.0, rtol=1e-12)
    m = ds.wallbatch.mean("wall_pressure")
    assert set(m.data_vars) == {"mean", "sem", "converged"} and m["mean"].dims == ("k", "face")
    np.testing.assert_array_equal(ds.wallbatch.mean("temp_mean")["sem"].values, ds["temp_sem"].values)
    pm = ds.wallbatch.mean("profile_across_temp")
    keep = ds["window_step"].values >= 200
    windows = ds["profile_across_temp"].isel(window=keep)
    empty = (ds["profile_across_density_number"].isel(window=keep) == 0).any("window").values
    assert empty.any()  # the bins at the walls: no atom in some window, so no mean temperature
    np.testing.assert_allclose(pm["mean"].values, np.where(empty, np.nan, windows.mean("window").values), rtol=1e-12)
    with pytest.raises(KeyError, match="profiles here: profile_across_density_number"):
        ds.wallbatch.profile("across", "vx")
    with pytest.raises(KeyError, match="no time average"):
        ds.wallbatch.mean("status")


@pytest.mark.slow
def test_profile_plot_has_error_bars_per_hue(results, tmp_path):
    ds, path = results
    out, fig = plot(ds, "profile_across_density_number", tmp_path / "p.png", hue="k", return_figure=True)
    ax = fig.axes[0]
    bars = [c for c in ax.containers if isinstance(c, ErrorbarContainer)]
    assert len(bars) == 2  # one per k
    x, y = bars[0].lines[0].get_data()
    np.testing.assert_allclose(x, ds["across_bin"].values)
    np.testing.assert_allclose(y, ds["profile_across_density_number_mean"].isel(k=0).values)
    assert "bin centre" in ax.get_xlabel()
    cli = CliRunner().invoke(app, ["plot", path, "profile_across_density_number", "--hue", "k", "-o",
                                   str(tmp_path / "c.png")])
    assert cli.exit_code == 0, cli.output
    assert (tmp_path / "c.png").stat().st_size > 1000


def test_plot_refuses_a_dimension_selected_twice(results, tmp_path):
    """`--sel k=5 --sel k=10` drew k=10 alone, the first selection silently dropped."""
    _, path = results
    cli = CliRunner().invoke(app, ["plot", path, "temp", "--sel", "k=5", "--sel", "k=10", "-o",
                                   str(tmp_path / "twice.png")])
    assert cli.exit_code == 2
    assert cli.output.strip() == "error: --sel k=10: k is already selected (k=5); give one value per dimension"
    assert not (tmp_path / "twice.png").exists()


def test_sweep_plot_of_mean_has_error_bars(results, tmp_path):
    ds, _ = results
    _, fig = plot(ds, "wall_pressure_mean", tmp_path / "w.png", return_figure=True)  # x: the sweep dim
    bars = [c for c in fig.axes[0].containers if isinstance(c, ErrorbarContainer)]
    assert len(bars) == 2  # one per face
    seg = bars[0].lines[2][0].get_segments()[0]  # the first error bar: mean -+ sem at k = 5
    mean = ds["wall_pressure_mean"].isel(k=0, face=0).item()
    sem = ds["wall_pressure_sem"].isel(k=0, face=0).item()
    np.testing.assert_allclose([seg[0][1], seg[1][1]], [mean - sem, mean + sem], rtol=1e-12)
