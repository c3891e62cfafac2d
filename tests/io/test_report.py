"""report.py: text summary, ds.wallbatch accessor, plots, config JSON schema."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest
import xarray as xr

from wallbatch.config.schema import config_json_schema
from wallbatch.io import report
from wallbatch.io.netcdf import write_netcdf
from wallbatch.batch.runner import run_plan
from wallbatch.config.sweep import load_plan

CONFIGS = Path(__file__).resolve().parents[2] / "configs"
PNG = b"\x89PNG\r\n\x1a\n"

SWEEP = f"""\
base: {CONFIGS / 'lj93-slit.yaml'}
set: {{run.steps: 100, run.thermo: 50, atoms.0.create.random.count: 40}}
sweep:
  product:
    epsilon: {{path: walls.zwalls.zlo.epsilon, values: [0.5, 1.0, 2.0]}}
    sigma:   {{path: walls.zwalls.zlo.sigma, values: {{linspace: [0.8, 1.2, 2]}}}}
  replicas: 2
"""


@pytest.fixture(scope="module")
def sweep_ds(tmp_path_factory) -> xr.Dataset:
    path = tmp_path_factory.mktemp("sweep") / "sweep.yaml"
    path.write_text(SWEEP)
    return run_plan(load_plan(path))


def synthetic(failed: tuple[tuple[int, int], ...] = ((0, 1), (2, 0)), time_based: bool = False,
              n_a: int = 3, n_b: int = 2) -> xr.Dataset:
    """The outputs.md layout over sweep dims (a, b), with chosen failed cases (NaN outputs)."""
    rng = np.random.default_rng(0)
    nsamp = 4
    shape = (n_a, n_b, nsamp)
    temp = 1.0 + np.arange(np.prod(shape), dtype=float).reshape(shape)
    pe = rng.normal(size=shape)
    wf = rng.normal(size=shape + (2,))
    status = np.full((n_a, n_b), "ok", dtype=object)
    error = np.full((n_a, n_b), "", dtype=object)
    seconds = np.linspace(1.0, 2.0, n_a * n_b).reshape(n_a, n_b)
    for i, j in failed:
        temp[i, j] = pe[i, j] = wf[i, j] = np.nan
        status[i, j], error[i, j] = "failed", "boom: wall blew up"
    sd = ("a", "b", "sample")
    instants = np.arange(nsamp) * 10
    coords = {"a": ("a", np.linspace(0.5, 1.5, n_a), {"path": "walls.w.zlo.epsilon", "units": "1",
                                                       "long_name": "swept walls.w.zlo.epsilon"}),
              "b": ("b", np.arange(n_b) * 2, {"path": "seed", "units": "1", "long_name": "b"}),
              "fix": ("fix", np.array(["w"], dtype=object)),
              "face": ("face", np.array(["w/zlo", "w/zhi"], dtype=object))}
    data = {"temp": (sd, temp, {"units": "K", "long_name": "temperature"}),
            "pe": (sd, pe, {"units": "eV", "long_name": "potential energy"}),
            "wall_force": (sd + ("face",), wf, {"units": "eV/Angstrom", "long_name": "wall force"}),
            "status": (("a", "b"), status), "error": (("a", "b"), error),
            "seconds": (("a", "b"), seconds, {"units": "s", "long_name": "seconds"})}
    if time_based:
        coords["time"] = ("sample", instants * 0.5, {"units": "ps", "long_name": "elapsed simulated time"})
        data["step"] = (sd, np.broadcast_to(instants, shape).astype(float), {"units": "1", "long_name": "step"})
    else:
        coords["step"] = ("sample", instants.astype(np.int64), {"units": "1", "long_name": "timestep number"})
        data["time"] = (sd, np.broadcast_to(instants * 0.5, shape).copy(), {"units": "ps", "long_name": "time"})
    ds = xr.Dataset(data, coords=coords)
    ds.attrs.update(title="wallbatch results: synthetic", units_style="metal", wallbatch_version="9.9",
                    created="2026-01-01T00:00:00+00:00")
    return ds


def _plot(ds, var, tmp_path, **kw):
    path, fig = report.plot(ds, var, tmp_path / f"{var}.png", return_figure=True, **kw)
    data = path.read_bytes()
    assert len(data) > 0 and data[:8] == PNG
    return fig


# ----------------------------------------------------------------------------- summary


def test_summary_real_sweep(sweep_ds):
    text = report.summary(sweep_ds)
    assert text.startswith("wallbatch results: lj93-slit")
    assert "units_style: lj" in text and "version: 0.1.0" in text and "created: " in text
    assert re.search(r"epsilon\s+3\s+sweep walls\.zwalls\.zlo\.epsilon: 0\.5, 1, 2", text)
    assert re.search(r"sigma\s+2\s+sweep walls\.zwalls\.zlo\.sigma: 0\.8, 1\.2", text)
    assert re.search(r"replica\s+2\s+sweep seed: 0, 1", text)
    assert re.search(r"sample\s+3\s+step: 0 \.\. 100", text)
    assert re.search(r"face\s+2\s+zwalls/zlo, zwalls/zhi", text)
    assert "Status: 12 ok, 0 failed (of 12 cases)" in text
    temp = sweep_ds["temp"].values
    line = next(ln for ln in text.splitlines() if ln.strip().startswith("temp "))
    assert "(epsilon, sigma, replica, sample)" in line and "[1]" in line
    assert f"min {temp.min():.6g}" in line and f"max {temp.max():.6g}" in line and f"mean {temp.mean():.6g}" in line
    assert not any(ln.strip().startswith(("status", "error")) for ln in text.split("Variables")[1].splitlines())
    slow = text.split("Slowest cases:")[1].strip().splitlines()
    assert len(slow) == 5 and all("epsilon=" in ln and "sigma=" in ln and "replica=" in ln for ln in slow)


def test_summary_failed_cases_and_ranges():
    ds = synthetic()
    text = report.summary(ds)
    assert "Status: 4 ok, 2 failed (of 6 cases)" in text
    assert "2 x boom: wall blew up" in text and "e.g. a=0.5, b=2" in text
    ok = np.array([[1, 0], [1, 1], [0, 1]], bool)
    temp = ds["temp"].values[ok]
    line = next(ln for ln in text.splitlines() if ln.strip().startswith("temp "))
    assert f"min {temp.min():.6g}  max {temp.max():.6g}  mean {temp.mean():.6g}" in line and "[K]" in line
    slow = text.split("Slowest cases:")[1].strip().splitlines()
    assert slow[0].split()[0] == "2" and "a=1.5, b=2" in slow[0] and "(ok)" in slow[0]
    assert "a=1.5, b=0" in slow[1] and "(failed)" in slow[1]


@pytest.mark.slow
def test_summary_single_case_and_netcdf_round_trip(sweep_ds, tmp_path):
    single = sweep_ds.isel(epsilon=0, sigma=0, replica=0, drop=True)
    text = report.summary(single)
    assert "Status: 1 ok, 0 failed (of 1 case)" in text and "(single case)" in text
    assert "sweep" not in text.split("Status")[0]
    path = write_netcdf(sweep_ds, tmp_path / "r.nc")
    with xr.open_dataset(path) as back:
        assert back.wallbatch.summary() == report.summary(sweep_ds)
        assert back.wallbatch.ok.all()


# ----------------------------------------------------------------------------- accessor


def test_accessor(sweep_ds):
    acc = sweep_ds.wallbatch
    assert acc.sweep_dims == ["epsilon", "sigma", "replica"]
    assert acc.ok.dtype == bool and acc.ok.dims == ("epsilon", "sigma", "replica") and bool(acc.ok.all())
    assert acc.summary() == report.summary(sweep_ds)
    ds = synthetic()
    assert ds.wallbatch.sweep_dims == ["a", "b"]
    np.testing.assert_array_equal(ds.wallbatch.ok.values, [[True, False], [True, True], [False, True]])
    region = ds.expand_dims(rfix=["r"], spatial=["x", "y", "z"])
    assert region.wallbatch.sweep_dims == ["a", "b"]


# ----------------------------------------------------------------------------- plots


@pytest.mark.slow
def test_time_series_colour_style_and_replica_mean(sweep_ds, tmp_path):
    """3 epsilons (colour) x 2 sigmas (line style), the 2 replicas averaged with a +-1 s.e. band."""
    fig = _plot(sweep_ds, "temp", tmp_path, hue="epsilon")
    ax = fig.axes[0]
    assert len(ax.get_lines()) == 6
    texts = [t.get_text() for t in fig.legends[0].get_texts()]  # one row per group, filled column by column
    assert [t for t in texts if t.strip()] == ["epsilon=0.5", "sigma=0.8", "s.e. over replicas", "epsilon=1",
                                               "sigma=1.2", "epsilon=2"]
    assert fig.legends[0]._ncols == 3
    assert ax.get_xlabel() == "step" and ax.get_ylabel() == "temp"
    assert "translational temperature" in fig._suptitle.get_text()
    assert "mean of 2 replicas, band: +-1 s.e." in fig._suptitle.get_text()
    colors = {tuple(ln.get_color()) if not isinstance(ln.get_color(), str) else ln.get_color() for ln in ax.get_lines()}
    assert len(colors) == 3
    assert [ln.get_linestyle() for ln in ax.get_lines()] == ["-", "--"] * 3
    np.testing.assert_array_equal(ax.get_lines()[0].get_xdata(), [0, 50, 100])
    temp = sweep_ds["temp"].isel(epsilon=0, sigma=1)
    np.testing.assert_allclose(ax.get_lines()[1].get_ydata(), temp.mean("replica").values)
    band = ax.collections[1].get_paths()[0].vertices[:, 1]  # fill_between polygon: y - se, then y + se
    se = (temp.std("replica", ddof=1) / np.sqrt(2)).values
    assert np.isclose(band.min(), (temp.mean("replica").values - se).min())


@pytest.mark.slow
def test_time_series_faces_and_selection(sweep_ds, tmp_path):
    sel = {"epsilon": "1.0", "sigma": "1.2", "replica": "1"}
    fig = _plot(sweep_ds, "wall_force", tmp_path, sel=sel)
    assert len(fig.axes) == 2 and [a.get_title() for a in fig.axes] == ["face zwalls/zlo", "face zwalls/zhi"]
    want = sweep_ds["wall_force"].sel(epsilon=1.0, sigma=1.2, replica=1).transpose("face", "sample").values
    np.testing.assert_allclose(fig.axes[0].get_lines()[0].get_ydata(), want[0])
    np.testing.assert_allclose(fig.axes[1].get_lines()[0].get_ydata(), want[1])
    assert "epsilon=1" in fig._suptitle.get_text()
    ax = _plot(sweep_ds, "wall_force", tmp_path, sel={**sel, "face": "zwalls/zhi"}).axes[0]
    np.testing.assert_allclose(ax.get_lines()[0].get_ydata(), want[1])
    assert len(ax.get_lines()) == 1


@pytest.mark.slow
def test_time_series_time_axis(tmp_path):
    ds = synthetic(time_based=True)
    ax = _plot(ds, "pe", tmp_path).axes[0]
    assert len(ax.get_lines()) == 6 and ax.get_xlabel() == "time [ps]"
    np.testing.assert_allclose(ax.get_lines()[0].get_xdata(), [0, 5, 10, 15])
    assert ax.get_ylabel() == "pe [eV]"
    ax = _plot(ds, "pe", tmp_path, x="step", sel={"a": "1.0"}).axes[0]
    assert len(ax.get_lines()) == 2 and ax.get_xlabel() == "step"


@pytest.mark.slow
def test_summary_plot_against_sweep_dim(sweep_ds, tmp_path):
    ax = _plot(sweep_ds, "pe", tmp_path, x="epsilon", hue="sigma", sel={"replica": "0"}).axes[0]
    lines = [ln for ln in ax.get_lines() if ln.get_marker() == "o"]  # the others: error-bar caps
    assert len(lines) == 2
    mean = sweep_ds["pe_mean"].sel(replica=0)  # no averages.start here: the mean of every sample
    np.testing.assert_allclose(mean, sweep_ds["pe"].sel(replica=0).mean("sample"))
    np.testing.assert_allclose(lines[0].get_xdata(), [0.5, 1.0, 2.0])
    np.testing.assert_allclose(lines[1].get_ydata(), mean.isel(sigma=1).values)
    fig = ax.figure
    assert ax.get_xlabel() == "epsilon" and "time mean of potential energy" in fig._suptitle.get_text()
    texts = [t.get_text() for t in fig.legends[0].get_texts()]
    assert [t for t in texts if t.startswith("sigma")] == ["sigma=0.8", "sigma=1.2"]
    assert "+-1 s.e. (pe_sem)" in texts  # nothing averaged: the error bars are pe_sem
    ax = _plot(sweep_ds, "seconds", tmp_path, x="sigma").axes[0]  # no sample dim: plotted as is
    # colour epsilon, replicas averaged: one error-bar series (mean +- s.e. over the 2 replicas) per epsilon
    assert len(ax.containers) == 3 and ax.get_ylabel() == "seconds [s]"
    sec = sweep_ds["seconds"].isel(epsilon=0)
    np.testing.assert_allclose(ax.containers[0].lines[0].get_ydata(), sec.mean("replica").values)


def test_failed_cases_are_gaps(tmp_path):
    ds = synthetic()
    ax = _plot(ds, "temp", tmp_path, x="a", hue="b").axes[0]
    y = ax.get_lines()[1].get_ydata()  # b=2: a=0.5 failed
    assert np.isnan(y[0]) and np.isfinite(y[1:]).all()


@pytest.mark.slow
def test_heatmap(sweep_ds, tmp_path):
    fig = _plot(sweep_ds, "pe", tmp_path, x="epsilon", hue="sigma", kind="heatmap")
    ax = fig.axes[0]
    assert len(fig.axes) == 2  # plot and colour bar
    mesh = ax.collections[0]
    want = sweep_ds["pe"].mean(["sample", "replica"]).transpose("sigma", "epsilon").values
    np.testing.assert_allclose(np.asarray(mesh.get_array()).reshape(want.shape), want)
    assert "mean over replicas" in ax.get_title().replace("\n", " ")
    assert fig.axes[1].get_ylabel() == "pe"  # dimensionless (lj): no unit shown


@pytest.mark.slow
def test_auto_heatmap_for_many_hue_values(tmp_path):
    ds = synthetic(failed=(), n_a=3, n_b=12)
    fig = _plot(ds, "temp", tmp_path, x="a", hue="b")
    assert len(fig.axes) == 2 and not fig.axes[0].get_lines()
    fig = _plot(ds, "temp", tmp_path, x="a", hue="b", kind="line")
    assert len(fig.axes[0].get_lines()) == 12


@pytest.mark.parametrize("kwargs, match", [
    (dict(var="nope"), r"unknown variable 'nope'; plottable variables: .*temp.*pe"),
    (dict(var="status"), r"unknown variable 'status'"),
    (dict(var="pe", x="volume"), r"^x=volume: give one of sample, step, time, epsilon, sigma, replica"),
    (dict(var="pe", hue="colour"), r"hue=colour: unknown dimension; valid: epsilon, sigma, replica"),
    (dict(var="pe", x="epsilon", hue="epsilon"), r"hue and x are both epsilon"),
    (dict(var="pe", sel={"temperature": "1"}), r"no dimension or coordinate temperature; valid: .*epsilon"),
    (dict(var="pe", sel={"epsilon": "big"}), r"epsilon=big: not a number; epsilon takes 0.5, 1, 2"),
    (dict(var="pe", sel={"epsilon": "7"}), r"epsilon=7: no such value; epsilon takes 0.5, 1, 2"),
    (dict(var="pe", sel={"epsilon": "0.9"}), r"epsilon=0.9: no such value; epsilon takes 0.5, 1, 2"),
    (dict(var="wall_force", sel={"face": "zwalls/xlo"}), r"face takes zwalls/zlo, zwalls/zhi"),
    (dict(var="pe", sel={"sample": "9"}), r"position outside 0..2"),
    (dict(var="pe", sel={"step": "50"}), r"leaves pe a single sample"),
    (dict(var="seconds"), r"seconds has no sample dimension.*x=<epsilon\|sigma\|replica>"),
    (dict(var="pe", kind="pie"), r"kind='pie': choose one of auto, line, heatmap"),
    (dict(var="pe", kind="heatmap"), r"heatmap' needs x and hue to be two sweep dimensions"),
    (dict(var="pe", x="epsilon", kind="heatmap"), r"needs hue to be a second sweep dimension"),
    (dict(var="wall_force", x="epsilon", hue="sigma", kind="heatmap"),
     r"more dimensions left: face; pick one value of each with --sel DIM=VALUE \(sel= in Python\)"),
    (dict(var="pe", kind="heatmap"), r"^kind='heatmap' needs x and hue to be two"),
    (dict(var="pe", x="epsilon", sel={"epsilon": "1"}), r"x=epsilon: epsilon was selected away"),
])
def test_plot_errors(sweep_ds, tmp_path, kwargs, match):
    var = kwargs.pop("var")
    with pytest.raises(ValueError, match=match):
        report.plot(sweep_ds, var, tmp_path / "x.png", **kwargs)
    assert not (tmp_path / "x.png").exists()


@pytest.mark.parametrize("args, message", [
    (["pe", "--x", "volume"], "error: --x volume: give one of sample, step, time, epsilon, sigma, replica"),
    (["pe", "--hue", "colour"],
     "error: --hue colour: unknown dimension; valid: epsilon, sigma, replica, sample, fix, face"),
    (["pe", "--x", "epsilon", "--hue", "epsilon"], "error: --hue and --x are both epsilon: give different dimensions"),
    (["pe", "--x", "epsilon", "--sel", "epsilon=1"],
     "error: --x epsilon: epsilon was selected away by --sel; drop epsilon from the selection"),
    (["pe", "--kind", "pie"], "error: --kind pie: choose one of auto, line, heatmap"),
    (["pe", "--kind", "heatmap"], "error: --kind heatmap needs --x and --hue to be two sweep dimensions"),
    (["seconds"], "error: seconds has no sample dimension (dims: epsilon, sigma, replica): plot it against a "
                  "sweep dimension (--x <epsilon|sigma|replica>)"),
    (["wall_force", "--x", "epsilon", "--hue", "sigma", "--kind", "heatmap"],
     "error: a heat map of wall_force over (epsilon, sigma) has more dimensions left: face; pick one value of "
     "each with --sel DIM=VALUE"),
])
def test_cli_plot_errors_name_the_options_typed(sweep_ds, tmp_path, args, message):
    """`wallbatch plot` errors name the option as typed (`--x volume`); they said `x=volume`, the
    Python keyword, which the command line has no spelling for."""
    from typer.testing import CliRunner

    from wallbatch.cli import app

    results = write_netcdf(sweep_ds, tmp_path / "r.nc")
    got = CliRunner().invoke(app, ["plot", str(results), *args, "-o", str(tmp_path / "x.png")])
    assert got.exit_code == 2
    assert " ".join(got.output.split()) == message
    assert not (tmp_path / "x.png").exists()


def test_plot_errors_of_a_single_case_name_no_sweep_dimension(sweep_ds, tmp_path):
    """A file of one case (no sweep dimension): a variable without samples is not to be plotted
    against a sweep dimension it does not have (the message used to offer x=<sweep dim>)."""
    one = sweep_ds.isel(epsilon=0, sigma=0, replica=0, drop=True)
    assert report.sweep_dims(one) == []
    for var, sel, match in (("seconds", None, r"seconds has no sample dimension \(dims: none\): this file has no sweep "
                             r"dimension to plot it against \(one case: `wallbatch show` prints it\)"),
                            ("pe", {"step": "50"}, r"leaves pe a single sample: this file has no sweep dimension.*"
                             r", or select fewer samples")):
        with pytest.raises(ValueError, match=match) as err:
            report.plot(one, var, tmp_path / "x.png", sel=sel)
        assert "x=<" not in str(err.value)


def test_select_by_coordinate(sweep_ds):
    sub = report.select(sweep_ds, {"step": "50", "face_name": "zlo", "sigma": "0.8"})
    assert "sample" not in sub.dims and int(sub["step"]) == 50
    assert "face" not in sub.dims and str(sub["face"].values) == "zwalls/zlo"
    assert float(sub["sigma"]) == 0.8


# ----------------------------------------------------------------------------- schema


def test_config_json_schema():
    schema = config_json_schema()
    back = json.loads(json.dumps(schema))
    assert back == schema
    assert schema["$schema"].startswith("https://json-schema.org/") and schema["title"] == "wallbatch config"
    for key in ("box", "atoms", "walls", "run", "units", "regions", "output", "sweep"):
        assert key in schema["properties"], key
    assert {"box", "atoms", "run"} <= set(schema["required"])
    sweep_ref = schema["properties"]["sweep"]["anyOf"][0]["$ref"]
    sweep = schema["$defs"][sweep_ref.split("/")[-1]]
    assert {"product", "zip", "replicas"} <= set(sweep["properties"])
    refs = set(re.findall(r'"#/\$defs/([^"]+)"', json.dumps(schema)))
    assert refs <= set(schema["$defs"]), refs - set(schema["$defs"])


def test_plot_against_a_sweep_dim_is_the_time_mean_of_the_file(tmp_path):
    """`plot VAR --x DIM` draws `VAR_mean` (from `output.averages` on, what `show` prints) with
    `VAR_sem` as error bars: it drew the mean over every sample, equilibration included."""
    ds = synthetic(failed=())
    ds["temp"][...] = np.where(ds["step"] < 10, 5.0, 1.0)  # an equilibration spike before step 10
    ds["temp_mean"] = ds["temp"].where(ds["step"] >= 10).mean("sample")
    ds["temp_sem"] = xr.full_like(ds["temp_mean"], 0.25)
    ds["temp_mean"].attrs["comment"] = "samples at or after step 10"
    fig = _plot(ds, "temp", tmp_path, x="a", sel={"b": "0"})
    ax = fig.axes[0]
    line = next(ln for ln in ax.get_lines() if ln.get_marker() == "o")
    np.testing.assert_allclose(line.get_ydata(), 1.0)
    assert "(samples at or after step 10)" in fig._suptitle.get_text().replace("\n", " ")
    assert ax.containers and np.isclose(np.ptp(ax.containers[0][2][0].get_segments()[0][:, 1]), 0.5)
