"""Every shipped sweep's default plots, rendered: the figure's texts name the dimensions and the
variable, multi-case plots have a legend, every text fits inside the figure and the legend does
not cover the title; failed cases are marked; `<var>_sem` gives error bands; `wallbatch plot`
without matplotlib is one line naming the `plot` extra."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import xarray as xr

from wallbatch.batch.runner import run_plan
from wallbatch.config.sweep import load_plan
from wallbatch.io import report

ROOT = Path(__file__).resolve().parents[2]
SWEEPS = sorted((ROOT / "sweeps").glob("*.yaml"))
SHORT = ["run.steps=200", "run.thermo=50"]
EXTRA = {"lj-slit-profiles-epsilon.yaml": ["output.profiles.across.freq=100", "output.profiles.across.repeat=10",
                                           "output.averages.start=100"]}


FAST = "lj93-epsilon-sigma-cutoff.yaml"  # the fast subset plots this one; the others are marked slow


@pytest.fixture(scope="module", params=[p.name if p.name == FAST else pytest.param(p.name, marks=pytest.mark.slow)
                                        for p in SWEEPS])
def shipped(request) -> tuple[str, xr.Dataset]:
    plan = load_plan(ROOT / "sweeps" / request.param, SHORT + EXTRA.get(request.param, []))
    return request.param, run_plan(plan, jobs=1, progress=False)


def _boxes_fit(fig) -> None:
    """Every visible text and the legend lie inside the figure; the legend and the suptitle do
    not overlap (constrained layout made room)."""
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    W, H = fig.bbox.width, fig.bbox.height
    boxes = {f"panel {ax.get_title()!r} with its labels and ticks": ax.get_tightbbox(renderer)
             for ax in fig.axes if ax.get_visible()}
    if fig._suptitle is not None:
        boxes["title"] = fig._suptitle.get_window_extent(renderer)
    for what, bb in boxes.items():
        assert bb.x0 >= -1 and bb.y0 >= -1 and bb.x1 <= W + 1 and bb.y1 <= H + 1, f"cut off: {what}"
    for leg in fig.legends:
        lb = leg.get_window_extent(renderer)
        assert lb.x0 >= -1 and lb.x1 <= W + 1, "legend cut off"
        if fig._suptitle is not None:
            assert not lb.overlaps(fig._suptitle.get_window_extent(renderer)), "legend covers the title"
        for ax in fig.axes:
            assert not lb.overlaps(ax.get_window_extent(renderer)), "legend covers a panel"


@pytest.mark.slow
@pytest.mark.parametrize("var", ["temp", "pe", "wall_force"])
def test_default_time_series_of_every_shipped_sweep(shipped, var, tmp_path):
    name, ds = shipped
    if var not in ds:
        pytest.skip(f"{name} has no {var}")
    path, fig = report.plot(ds, var, tmp_path / f"{var}.png", return_figure=True)
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    sdims = [d for d in report.sweep_dims(ds) if ds.sizes[d] > 1]
    panels = [ax for ax in fig.axes if ax.get_visible() and ax.get_lines()]
    faces = ds.sizes.get("face", 1) if "face" in ds[var].dims else 1
    assert len(panels) == faces
    if faces > 1:
        assert [ax.get_title() for ax in panels] == [f"face {f}" for f in ds["face"].values]
    assert {ax.get_xlabel() for ax in panels if ax.get_xlabel()} == {"step"}
    assert any(ax.get_ylabel() == var for ax in panels)
    assert ds[var].attrs["long_name"][:30] in fig._suptitle.get_text().replace("\n", " ")
    legend = [t.get_text() for t in fig.legends[0].get_texts()]
    colour_dim = next(d for d in sdims if d != "replica")
    # one entry per value of the first sweep dimension: its name, not a path list
    assert [t for t in legend if t.startswith(f"{colour_dim}=")] == [
        f"{colour_dim}={report._fmt(v)}" for v in ds[colour_dim].values]
    assert not any("walls." in t or "," in t.split("=")[0] for t in legend)
    n_lines = sum(len(ax.get_lines()) for ax in panels)
    assert n_lines <= 12 * faces  # readable: at most colours x styles per panel, never one per case
    if "replica" in sdims:
        assert "s.e. over replicas" in legend
    _boxes_fit(fig)


@pytest.mark.slow
def test_time_mean_against_each_sweep_dimension(shipped, tmp_path):
    name, ds = shipped
    for dim in [d for d in report.sweep_dims(ds) if ds.sizes[d] > 1 and d != "replica"]:
        path, fig = report.plot(ds, "temp", tmp_path / f"{dim}.png", x=dim, return_figure=True)
        ax = fig.axes[0]
        assert ax.get_xlabel() == dim  # the dimension's name, not its dotted paths
        assert ax.get_ylabel() == "temp"
        assert "time mean of translational temperature" in fig._suptitle.get_text().replace("\n", " ")
        y = ax.get_lines()[0].get_ydata()
        assert len(y) == ds.sizes[dim] and np.isfinite(y).all()
        _boxes_fit(fig)


def _synthetic(failed=((0, 1), (2, 0))) -> xr.Dataset:
    rng = np.random.default_rng(1)
    a, b, ns = 3, 2, 5
    pe = rng.normal(size=(a, b, ns))
    sem = 0.1 + rng.random((a, b, ns))
    status = np.full((a, b), "ok", dtype=object)
    for i, j in failed:
        status[i, j] = "failed"
        pe[i, j] = np.nan
    ds = xr.Dataset(
        {"pe": (("a", "b", "sample"), pe, {"units": "eV", "long_name": "potential energy"}),
         "pe_sem": (("a", "b", "sample"), sem, {"units": "eV", "long_name": "standard error of pe"}),
         "status": (("a", "b"), status), "error": (("a", "b"), np.where(status == "ok", "", "boom").astype(object))},
        coords={"a": ("a", [0.5, 1.0, 1.5]), "b": ("b", [0, 2]), "step": ("sample", np.arange(ns) * 10)})
    ds.attrs["wallbatch_version"] = "test"
    return ds


@pytest.mark.slow
def test_failed_cases_are_marked(tmp_path):
    ds = _synthetic()
    _, fig = report.plot(ds, "pe", tmp_path / "x.png", x="a", hue="b", return_figure=True)
    ax = fig.axes[0]
    marks = [ln for ln in ax.get_lines() if ln.get_label() == "failed case"]
    assert len(marks) == 1
    np.testing.assert_array_equal(marks[0].get_xdata(), [0.5, 1.5])  # (a=0.5, b=2) and (a=1.5, b=0) failed
    assert "failed case" in [t.get_text() for t in fig.legends[0].get_texts()]
    assert "2 of 6 case(s) failed (marked x): a=0.5, b=2; a=1.5, b=0" in fig._suptitle.get_text().replace("\n", " ")
    _, fig = report.plot(ds, "pe", tmp_path / "y.png", return_figure=True)
    assert "2 of 6 case(s) failed, not drawn: a=0.5, b=2; a=1.5, b=0" in fig._suptitle.get_text().replace("\n", " ")


def test_sem_variable_gives_error_band(tmp_path):
    ds = _synthetic(failed=())
    _, fig = report.plot(ds, "pe", tmp_path / "x.png", sel={"a": "1.0", "b": "2"}, return_figure=True)
    ax = fig.axes[0]
    y = ds["pe"].sel(a=1.0, b=2).values
    e = ds["pe_sem"].sel(a=1.0, b=2).values
    np.testing.assert_allclose(ax.get_lines()[0].get_ydata(), y)
    verts = ax.collections[0].get_paths()[0].vertices[:, 1]
    assert np.isclose(verts.min(), (y - e).min()) and np.isclose(verts.max(), (y + e).max())
    assert "+-1 s.e. (pe_sem)" in [t.get_text() for t in fig.legends[0].get_texts()]
    # against a sweep dim: the s.e. of the time mean of independent block means
    _, fig = report.plot(ds, "pe", tmp_path / "y.png", x="a", sel={"b": "0"}, return_figure=True)
    ax = fig.axes[0]
    want = np.sqrt((ds["pe_sem"].sel(b=0) ** 2).sum("sample")).values / 5
    mean = ds["pe"].sel(b=0).mean("sample").values
    verts = ax.collections[0].get_paths()[0].vertices[:, 1]
    assert np.isclose(verts.max(), (mean + want).max())


def test_sel_is_exact(tmp_path):
    ds = _synthetic(failed=())
    with pytest.raises(ValueError, match=r"selection a=1.1: no such value; a takes 0.5, 1, 1.5"):
        report.plot(ds, "pe", tmp_path / "x.png", sel={"a": "1.1"})
    sub = report.select(ds, {"a": "1", "b": "2"})
    assert float(sub["a"]) == 1.0 and int(sub["b"]) == 2


def test_cli_plot_without_matplotlib_is_one_line(tmp_path):
    ds = _synthetic()
    ds.to_netcdf(tmp_path / "r.nc")
    code = ("import sys; sys.modules['matplotlib'] = None; sys.argv = ['wallbatch'] + sys.argv[1:]; "
            "from wallbatch.cli import app; app()")
    res = subprocess.run([sys.executable, "-c", code, "plot", str(tmp_path / "r.nc"), "pe", "-o",
                          str(tmp_path / "p.png")], capture_output=True, text=True, timeout=120)
    assert res.returncode == 2
    assert res.stderr.strip() == "error: plot needs matplotlib: pip install matplotlib (the extra 'plot')"


@pytest.mark.slow
def test_profile_plot_of_the_shipped_profile_sweep(tmp_path):
    plan = load_plan(ROOT / "sweeps" / "lj-slit-profiles-epsilon.yaml",
                     SHORT + EXTRA["lj-slit-profiles-epsilon.yaml"])
    ds = run_plan(plan, jobs=1, progress=False)
    _, fig = report.plot(ds, "profile_across_density_number", tmp_path / "d.png", return_figure=True)
    ax = fig.axes[0]
    assert "bin centre" in ax.get_xlabel()
    assert [t.get_text() for t in fig.legends[0].get_texts() if t.get_text().startswith("epsilon=")] == [
        "epsilon=0.5", "epsilon=1", "epsilon=2", "epsilon=4"]
    assert len(ax.containers) == 4  # one series of error bars (window mean +- s.e.) per epsilon
    np.testing.assert_allclose(ax.containers[1].lines[0].get_ydata(),
                               ds["profile_across_density_number_mean"].isel(epsilon=1).values)
    _boxes_fit(fig)
    _, fig = report.plot(ds, "wall_pressure_mean", tmp_path / "p.png", return_figure=True)
    ax = fig.axes[0]
    assert ax.get_xlabel() == "epsilon" and len(ax.containers) == 2  # one per face, in colour
    assert [t.get_text() for t in fig.legends[0].get_texts() if t.get_text().startswith("face=")] == [
        "face=pore/zlo", "face=pore/zhi"]
    _boxes_fit(fig)
