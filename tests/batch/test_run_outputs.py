"""Progress reporting and per-atom dumps through a real run."""

from __future__ import annotations

import io
import sys

import netCDF4
import numpy as np
import xarray as xr

from wallbatch.engine.engine import CaseResult
from wallbatch.batch.runner import Progress, run_plan
from wallbatch.config.sweep import load_plan

SCENE = """\
name: dump-test
box: {lo: [0, 0, 0], hi: [10, 10, 10], boundary: [p, p, f]}
atoms:
  - group: g
    create: {positions: [[1.0, 2.0, 5.0], [3.0, 4.0, 6.0]]}
    mass: 2.0
    velocity: {values: [[0.5, 0.0, 0.1], [0.0, -0.2, 0.0]]}
walls:
  zw: {style: harmonic, units: box, zlo: [EDGE, 1.0, 1.0, 2.0], zhi: [EDGE, 1.0, 1.0, 2.0]}
timestep: 0.01
run: {steps: 20, thermo: 10}
output:
  dump: {every: 5, fields: [x, v]}
sweep:
  product:
    walls.zw.zlo.epsilon: [1.0, 2.0]
"""


def test_progress_is_quiet_off_a_terminal(monkeypatch):
    buf = io.StringIO()
    monkeypatch.setattr(sys, "stderr", buf)
    bar = Progress(3)  # StringIO is not a terminal
    bar.update([CaseResult("ok", "", 0.0), CaseResult("failed", "x", 0.0)])
    assert buf.getvalue() == ""
    assert (bar.done, bar.failed) == (2, 1)


def test_progress_counts_and_eta_on_a_terminal(monkeypatch):
    buf = io.StringIO()
    monkeypatch.setattr(sys, "stderr", buf)
    bar = Progress(4, enabled=True)
    bar.update([CaseResult("ok", "", 0.0)])
    bar.update([CaseResult("failed", "x", 0.0)] * 3)
    text = buf.getvalue()
    assert "1/4 cases, 0 failed" in text and "4/4 cases, 3 failed" in text and "ETA" in text
    assert text.endswith("\n")


def test_dump_writes_one_trajectory_per_case(tmp_path):
    cfg = tmp_path / "scene.yaml"
    cfg.write_text(SCENE)
    out = tmp_path / "res.nc"
    ds = run_plan(load_plan(cfg), out)
    paths = ds["dump_path"].values.tolist()
    assert paths == ["res.dump/epsilon=1.0.nc", "res.dump/epsilon=2.0.nc"]
    with xr.open_dataset(out) as back:
        assert back["dump_path"].values.tolist() == paths
    with netCDF4.Dataset(tmp_path / paths[0]) as nc:
        assert nc.Conventions == "AMBER" and nc.ConventionVersion == "1.0"
        assert nc.dimensions["frame"].size == 5  # steps 0, 5, 10, 15, 20
        np.testing.assert_allclose(nc["time"][:], [0.0, 0.05, 0.1, 0.15, 0.2], rtol=1e-6)
        x0 = nc["coordinates"][0]
        np.testing.assert_allclose(x0, [[1.0, 2.0, 5.0], [3.0, 4.0, 6.0]], rtol=1e-6)
        # free flight in x for atom 0 (no x force): x = 1 + 0.5 t
        np.testing.assert_allclose(nc["coordinates"][:, 0, 0], 1.0 + 0.5 * nc["time"][:], rtol=1e-6)
        np.testing.assert_allclose(nc["velocities"][:, 1, 1], -0.2, rtol=1e-6)
        np.testing.assert_allclose(nc["cell_lengths"][0], [10, 10, 10])
