"""The public API: wallbatch.load / check / run, on a shipped config."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import wallbatch
from wallbatch.config.source import ConfigError

ROOT = Path(__file__).resolve().parents[1]


def test_load_applies_sets_and_expands_the_sweep():
    plan = wallbatch.load(ROOT / "sweeps/lj93-epsilon-sigma-cutoff.yaml", sets=["run.steps=20"])
    assert len(plan.cases) == 27
    assert {sc.config.run.steps for sc in plan.cases} == {20}
    again = wallbatch.load(ROOT / "sweeps/lj93-epsilon-sigma-cutoff.yaml", sets={"run.steps": 20})
    one = wallbatch.load(ROOT / "configs/quickstart.yaml", sets="run.steps=20")  # was "--set r: write path=value"
    assert one.cases[0].config.run.steps == 20
    assert [sc.coords for sc in again.cases] == [sc.coords for sc in plan.cases]


def test_check_lists_batches_without_running():
    report = wallbatch.check(ROOT / "configs/quickstart.yaml")
    assert report.ok and len(report.batches) == 1
    b = report.batches[0]
    assert b.kernels[0] == "nve" and any(k.startswith("wall/lj93") for k in b.kernels)
    assert report.atom_steps == b.steps * b.natoms


def test_check_names_pair_forces():
    report = wallbatch.check(ROOT / "configs/lj-liquid-slit.yaml")
    assert "pair lj/cut" in report.batches[0].kernels


def test_run_a_config_object_equals_running_its_path(tmp_path):
    plan = wallbatch.load(ROOT / "configs/quickstart.yaml", sets=["run.steps=50"])
    from_path = wallbatch.run(plan, tmp_path / "a.nc", progress=False)
    from_config = wallbatch.run(plan.cases[0].config, progress=False)
    np.testing.assert_array_equal(from_path["pe"].values, from_config["pe"].values)
    assert (tmp_path / "a.nc").exists()


def test_load_reports_bad_values_with_their_place():
    with pytest.raises(ConfigError, match="cutoff"):
        wallbatch.load(ROOT / "configs/quickstart.yaml", sets=["walls.zwalls.zlo.cutoff=-1"])


def test_numpy_scalars_are_numbers_in_a_config_built_in_python():
    """A wall face or a dt_reset bound taken from a NumPy array (np.float32, np.int16) is a number,
    as a float is (np.float32 was refused as "expected a number or v_name, got '1.0'"); a NumPy
    bool stays refused."""
    box = {"lo": [0, 0, 0], "hi": [6, 6, 8], "boundary": ["p", "p", "f"]}
    atoms = [{"group": "g", "mass": 1.0, "create": {"random": {"count": 20}}}]
    eps = np.linspace(0.5, 1.0, 3, dtype=np.float32)

    def config(face: list, tmax=None) -> dict:
        out = {"box": box, "atoms": atoms, "run": {"steps": 10},
               "walls": {"w": {"style": "lj93", "units": "box", "zlo": face}}}
        if tmax is not None:
            out["dt_reset"] = {"every": 1, "tmin": None, "tmax": tmax, "xmax": 0.05, "units": "box"}
        return out

    plan = wallbatch.load(config(["EDGE", eps[1], np.int16(1), np.float32(2.5)], tmax=np.float32(0.01)))
    face = plan.cases[0].config.walls["w"].zlo
    assert (face.epsilon, face.sigma, face.cutoff) == (0.75, 1.0, 2.5)
    assert plan.cases[0].config.dt_reset.tmax == pytest.approx(0.01)
    with pytest.raises(ConfigError, match="walls.w.zlo.epsilon"):
        wallbatch.load(config(["EDGE", np.bool_(True), 1.0, 2.5]))


def test_sweep_values_and_sets_may_be_numpy_arrays(tmp_path):
    """`values: np.linspace(...)` (an array, or a list of np.float32) and sets with NumPy values: the
    plan is the one of the same plain lists (an array raised yaml's RepresenterError)."""
    base = {"box": {"lo": [0, 0, 0], "hi": [6, 6, 8], "boundary": ["p", "p", "f"]},
            "atoms": [{"group": "g", "mass": 1.0, "create": {"random": {"count": 20}}}],
            "walls": {"w": {"style": "lj93", "units": "box",
                            "zlo": {"coord": "EDGE", "epsilon": 1.0, "sigma": 1.0, "cutoff": 2.5}}},
            "run": {"steps": 10, "thermo": 5}}

    def swept(values) -> dict:
        return {**base, "sweep": {"product": {"eps": {"path": "walls.w.zlo.epsilon", "values": values}}}}

    plain = wallbatch.load(swept([0.5, 1.0, 1.5]))
    for values in (np.linspace(0.5, 1.5, 3), np.linspace(0.5, 1.5, 3, dtype=np.float32),
                   list(np.linspace(0.5, 1.5, 3, dtype=np.float32))):
        plan = wallbatch.load(swept(values))
        assert [c.coords for c in plan.cases] == [c.coords for c in plain.cases]
        assert [c.config.model_dump() for c in plan.cases] == [c.config.model_dump() for c in plain.cases]
    plan = wallbatch.load(base, {"walls.w.zlo.epsilon": np.float32(3.0), "box.hi": np.array([6.0, 6.0, 9.0])})
    assert plan.cases[0].config.walls["w"].zlo.epsilon == 3.0 and plan.cases[0].config.box.hi == (6.0, 6.0, 9.0)
    ds = wallbatch.run(swept(np.linspace(0.5, 1.5, 3)), tmp_path / "np.nc", progress=False)
    np.testing.assert_array_equal(ds["eps"].values, [0.5, 1.0, 1.5])
