"""`wallbatch convergence`: errors against the finest run, observed orders, the recommended dt."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import xarray as xr
from typer.testing import CliRunner

from wallbatch.cli import app
from wallbatch.convergence import ConvergenceError, convergence

ROOT = Path(__file__).resolve().parents[1]
HARMONIC = ROOT / "configs/harmonic-confinement.yaml"


def reflect_scene() -> dict:
    """Ideal gas pushed up by a long-range harmonic wall against a reflecting lid: the reflection
    happens between steps under a force, a first-order error in dt."""
    return {
        "name": "reflect-under-force", "seed": 3,
        "box": {"lo": [0, 0, 0], "hi": [10, 10, 12], "boundary": ["p", "p", "f"]},
        "atoms": [{"group": "g", "create": {"random": {"count": 200}}, "mass": 1.0,
                   "velocity": {"temperature": 1.0}}],
        "walls": {
            "push": {"style": "harmonic", "units": "box", "energy": True,
                     "zlo": {"coord": -1.0, "epsilon": 0.1, "sigma": 1.0, "cutoff": 20.0}},
            "lid": {"style": "reflect", "units": "box", "zlo": "EDGE", "zhi": "EDGE"},
        },
        "output": {"thermo": ["step", "time", "ke", "pe", "etot"]},
        "run": {"steps": 2000, "thermo": 200},
    }


@pytest.fixture(scope="module")
def harmonic():
    return convergence(HARMONIC)


@pytest.mark.slow
def test_force_continuous_walls_converge_with_order_two(harmonic):
    assert harmonic.dim == "dt"
    assert [p.h for p in harmonic.points] == pytest.approx([0.01, 0.005, 0.0025, 0.00125, 0.000625])
    for name in ("ke", "pe", "wall_force"):
        assert 1.8 < harmonic.orders[name] < 2.6, (name, harmonic.orders)
    # the error falls with dt, and the reference is the last point
    errs = [p.errors["wall_force"] for p in harmonic.points[:-1]]
    assert all(a > b for a, b in zip(errs, errs[1:]))
    assert harmonic.points[-1].errors["wall_force"] == 0.0


@pytest.mark.slow
def test_reflection_under_a_force_is_first_order():
    report = convergence(reflect_scene())
    for name in ("ke", "wall_force"):
        assert 0.8 < report.orders[name] < 1.5, report.orders


@pytest.mark.slow
def test_the_recommended_dt_meets_the_tolerance_against_a_finer_run(harmonic):
    rtol = 2e-4
    best = harmonic.recommend(rtol)
    assert best is not None and best.h == pytest.approx(0.0025)  # 0.005 misses wall_force (4.6e-4)
    # check with an independent, 8x finer reference than the ladder's
    check = convergence(HARMONIC, dts=[best.h, best.h / 2, best.h / 64])
    assert max(check.points[0].errors.values()) <= rtol


def test_the_dataset_has_a_dt_dimension(harmonic, tmp_path):
    ds = harmonic.dataset
    assert ds.sizes["dt"] == 5 and "dt" in ds.coords and "step" in ds.data_vars
    np.testing.assert_allclose(ds["time"].values[0], ds["time"].values[-1], rtol=0, atol=1e-12)
    assert list(ds["step"].values[:, -1]) == [1000, 2000, 4000, 8000, 16000]
    ds.to_netcdf(tmp_path / "c.nc")
    assert xr.open_dataset(tmp_path / "c.nc").sizes["dt"] == 5


def test_bad_ladders_are_refused():
    with pytest.raises(ConvergenceError, match="whole number of steps"):
        convergence(HARMONIC, dts=[0.01, 0.003, 0.001])
    with pytest.raises(ConvergenceError, match="at least three"):
        convergence(HARMONIC, dts=[0.01, 0.005])
    with pytest.raises(ConvergenceError, match="dt_reset"):
        convergence(HARMONIC, xmaxs=[0.1, 0.05, 0.025])
    with pytest.raises(ConvergenceError, match="run: {time"):
        convergence({**reflect_scene(), "dt_reset": {"every": 1, "xmax": 0.05, "units": "box"}})


@pytest.mark.slow
def test_cli_prints_orders_and_the_choice(tmp_path):
    out = tmp_path / "conv.nc"
    res = CliRunner().invoke(app, ["convergence", str(HARMONIC), "--dt", "0.01,0.005,0.0025,0.000625",
                                   "--rtol", "1e-3", "-o", str(out)])
    assert res.exit_code == 0, res.output
    assert "observed order in dt" in res.output
    assert "cheapest dt with every error <= 0.001: 0.005" in res.output
    assert xr.open_dataset(out).sizes["dt"] == 4
    bad = CliRunner().invoke(app, ["convergence", str(HARMONIC), "--dt", "0.01,x"])
    assert bad.exit_code == 2 and "--dt 0.01,x" in bad.output


def test_the_dataset_keeps_the_config_the_time_and_the_ladder_units(harmonic, tmp_path):
    """The file has the provenance of every results file (the config as YAML text, `created`) and
    its `dt` coordinate its units, as every variable of a results file."""
    harmonic.dataset.to_netcdf(tmp_path / "c.nc")
    ds = xr.open_dataset(tmp_path / "c.nc")
    assert "name: harmonic" in ds.attrs["config"]
    assert ds.attrs["created"]
    assert ds["dt"].attrs["units"] == "1"  # lj
    real = convergence(HARMONIC, sets=["units=real", "timestep=1.0", "run.steps=40", "run.thermo=10"],
                       dts=[2.0, 1.0, 0.5])
    assert real.dataset["dt"].attrs["units"] == "fs"


@pytest.mark.parametrize("rtol", ["-1", "0", "nan", "inf"])
def test_cli_refuses_a_tolerance_that_is_no_positive_number_before_running(rtol):
    """`--rtol nan` printed "cheapest dt with every error <= nan: 0.01" (every comparison false
    reads as met); -1 ran the whole ladder to say that no dt meets it. Refused before any run."""
    res = CliRunner().invoke(app, ["convergence", str(HARMONIC), "--rtol", rtol])
    assert res.exit_code == 2
    assert f"--rtol {float(rtol):g}: give a positive relative error, e.g. --rtol 1e-4" in res.output
    assert "observed order" not in res.output


def test_cli_output_and_plot_paths_as_run_treats_them(tmp_path):
    """`-o` into a missing folder was "unexpected PermissionError ... a wallbatch bug" after the
    whole ladder ran (and `--plot` likewise); an existing file was overwritten silently. Folders are
    made, as by `run -o` and `plot -o`; an existing file needs --force; an input is refused."""
    out, png = tmp_path / "new" / "conv.nc", tmp_path / "figs" / "conv.png"
    args = ["convergence", str(HARMONIC), "--dt", "0.01,0.005,0.0025"]
    res = CliRunner().invoke(app, [*args, "-o", str(out), "--plot", str(png)])
    assert res.exit_code == 0, res.output
    assert xr.open_dataset(out).sizes["dt"] == 3 and png.stat().st_size > 0
    again = CliRunner().invoke(app, [*args, "-o", str(out)])
    assert again.exit_code == 2 and f"{out} exists: add --force to overwrite it" in again.output
    assert "observed order" not in again.output
    assert CliRunner().invoke(app, [*args, "-o", str(out), "--force"]).exit_code == 0
    inp = CliRunner().invoke(app, [*args, "-o", str(HARMONIC)])
    assert inp.exit_code == 2 and "is an input of this run" in inp.output


def test_an_unknown_output_is_refused_after_the_first_run_not_the_ladder(monkeypatch):
    """`outputs` (the CLI's --var) naming no compared output stops after the warm-up run, naming
    the outputs there are; before, the whole ladder ran and `recommend` refused it at the end."""
    import wallbatch.convergence as conv

    calls = []
    real = conv.run_plan
    monkeypatch.setattr(conv, "run_plan", lambda *a, **k: calls.append(1) or real(*a, **k))
    with pytest.raises(conv.UnknownOutput, match=r"no output named nope; outputs: .*\bke\b"):
        convergence(reflect_scene(), dts=[0.005, 0.0025, 0.00125], outputs=["ke", "nope"])
    assert len(calls) == 1
    calls.clear()
    ok = convergence(reflect_scene(), dts=[0.005, 0.0025, 0.00125], outputs=["ke"])
    assert len(calls) == 4 and ok.recommend(1.0, ["ke"]) is not None


def test_cli_unknown_var_names_the_option():
    res = CliRunner().invoke(app, ["convergence", str(HARMONIC), "--var", "nope", "--rtol", "1e-3"])
    assert res.exit_code == 2
    assert "error: --var nope: no output named nope; outputs: " in res.output
    assert "observed order" not in res.output  # the ladder did not run
