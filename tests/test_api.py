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
