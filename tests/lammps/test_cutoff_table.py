"""Export of a non-shift `cutoff_mode` wall as a LAMMPS `fix wall/table` (issue 20, export piece).

LAMMPS has no force-continuous wall cut-off, so a flat soft wall with `force-shift` or `smooth` is
written as a spline wall/table sampled from wallbatch's treated energy and force; `validate`
compares within TABLE_FACTOR x the table's measured interpolation error.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest
import yaml
from lammps_oracle import requires_lammps

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "styles"))
from test_cutoff import gas

from wallbatch.config.models import config_from_dict
from wallbatch.config.sweep import load_plan
from wallbatch.engine.engine import run_cases
from wallbatch.lammps.export import (
    TABLE_N,
    ExportError,
    check_exportable,
    export_selected,
    write_export,
)
from wallbatch.lammps.validate import TABLE_FACTOR, validate_case
from wallbatch.scene.build import build_case
from wallbatch.styles import STYLES
from wallbatch.styles.cutoff import CutoffStyle
from wallbatch.styles.table import WallTable, read_table

MODES = [("force-shift", None), ("smooth", 2.0)]


@pytest.fixture(autouse=True)
def _numpy_path(monkeypatch):
    monkeypatch.setenv("WALLBATCH_NUMBA", "0")


def plan_of(tmp_path: Path, d: dict):
    path = tmp_path / "cfg.yaml"
    path.write_text(yaml.safe_dump(d))
    return load_plan(path)


def small_gas(mode: str, on: float | None) -> dict:
    d = gas(mode, on, count=50, steps=500, thermo=50)
    d["name"] = "slit"
    return d


@pytest.mark.slow
@pytest.mark.parametrize("mode,on", MODES)
def test_export_writes_the_treated_wall_as_a_table(tmp_path, mode, on):
    exp = export_selected(plan_of(tmp_path, small_gas(mode, on)))
    fix = [line for line in exp.script.splitlines() if line.startswith("fix") and "wall/table" in line]
    n = TABLE_N[mode]
    assert fix == [(f"fix             w all wall/table spline {n} zhi 10.0 table.slit w_zhi 2.5 "
                    f"zlo 0.0 table.slit w_zlo 2.5 units box")]
    assert "fix_modify      w energy yes" in exp.script
    header = exp.script.split("\n\nunits")[0]
    assert f"cutoff_mode {mode}" in header and "interpolation error" in header
    assert list(exp.files) == ["table.slit"]
    write_export(exp, tmp_path / "out")
    table_path = tmp_path / "out" / "table.slit"
    assert table_path.read_text() == exp.files["table.slit"]
    p = {"epsilon": 1.0, "sigma": 1.0, "cutoff": 2.5, **({"switch_on": on} if on else {})}
    treated = CutoffStyle(STYLES["lj93"], mode)
    for face in ("zlo", "zhi"):
        data = read_table(table_path, f"w_{face}")
        assert len(data.r) == n and data.r[-1] == 2.5
        if on is None:
            assert data.r[0] == 0.5
        else:  # shifted by less than a step so that switch_on is a grid point
            assert abs(data.r[0] - 0.5) < 2.0 / n and np.min(np.abs(data.r - on)) < 1e-12
        e, f = treated.energy_force(data.r, p)
        np.testing.assert_array_equal(data.e, e)  # 17 digits: the same doubles
        np.testing.assert_array_equal(data.f, f)
        assert data.e[-1] == 0.0 and abs(data.f[-1]) < 1e-15  # both modes vanish at rc
        # LAMMPS's spline lookup of this file (styles.table pins it) against the exact function
        # error relative to |F| + max|F| over [sigma, rc] (the documented measure), at other points
        table = WallTable.build(data, "spline", n)
        r = np.linspace(data.r[0], 2.5, 7919)
        et, ft = table.shifted_energy_force(r, 2.5)
        e, f = treated.energy_force(r, p)
        fs, es = np.max(np.abs(f[r >= 1.0])), np.max(np.abs(e[r >= 1.0]))
        assert np.all(np.abs(ft - f) <= exp.table_rtol * (np.abs(f) + fs))
        assert np.all(np.abs(et - e) <= exp.table_rtol * (np.abs(e) + es))
    assert 1e-12 < exp.table_rtol < 1e-8  # 1e-10 (force-shift), 4e-9 (smooth: kinks of d2F/dr2)


def test_variable_parameter_is_refused_and_constant_one_written(tmp_path):
    d = small_gas("force-shift", None)
    d["variables"] = {"eps": "1.0 + ramp(0.0, 0.5)"}
    d["walls"]["w"]["zhi"]["epsilon"] = "v_eps"
    with pytest.raises(ExportError, match=r"walls\.w\.zhi\.epsilon: v_eps changes during the run and cutoff_mode "
                                          r"force-shift is exported as a LAMMPS wall/table"):
        export_selected(plan_of(tmp_path, d))
    d["variables"] = {"eps": "1.5"}
    exp = export_selected(plan_of(tmp_path, d))
    data = read_table(_written(exp, tmp_path), "w_zhi")
    e, _ = CutoffStyle(STYLES["lj93"], "force-shift").energy_force(data.r, {"epsilon": 1.5, "sigma": 1.0,
                                                                             "cutoff": 2.5})
    np.testing.assert_array_equal(data.e, e)
    assert any("v_eps is constant" in n for n in exp.notes)


def _written(exp, tmp_path: Path) -> Path:
    write_export(exp, tmp_path / "w")
    return tmp_path / "w" / next(iter(exp.files))


def test_walls_that_cannot_be_one_table_are_refused():
    d = gas("force-shift", None, style="colloid")  # the energy depends on each particle's radius
    with pytest.raises(ExportError, match=r"walls\.w: cutoff_mode force-shift on wall/colloid .* cannot be"):
        check_exportable(config_from_dict(d))
    check_exportable(config_from_dict(gas("force-shift")))
    check_exportable(config_from_dict(gas("smooth", 2.0)))


@requires_lammps
@pytest.mark.lammps
@pytest.mark.parametrize("mode,on", MODES)
def test_validate_through_the_table(tmp_path, mode, on):
    """LAMMPS running the table agrees with wallbatch's exact treated wall within TABLE_FACTOR x
    the table's error (< 1e-6), on a slit whose walls really act, while shift differs by far more."""
    plan = plan_of(tmp_path, small_gas(mode, on))
    exp = export_selected(plan)
    rep = validate_case(plan.cases[0])  # default rtol 1e-9: raised to the table's tolerance
    assert rep.ok, (rep.errors, rep.rows)
    assert rep.rtol == TABLE_FACTOR * exp.table_rtol and rep.rtol < 1e-6
    labels = {r.output for r in rep.rows}
    assert {"pe", "etot", "wall_energy[w]", "wall_force[w/zlo]", "wall_force[w/zhi]"} <= labels
    assert any("wall/table" in n for n in rep.notes)
    # the comparison is not vacuous: the walls act, and the cut-off treatment shows beyond the tolerance
    treated = run_cases([build_case(plan.cases[0].config, plan.cases[0].seed_key)])[0]
    shifted = run_cases([build_case(config_from_dict(small_gas("shift", None)), plan.cases[0].seed_key)])[0]
    assert np.all(np.abs(treated.data["wall_force"]).max(axis=0) > 1.0)
    diff = np.abs(treated.data["wall_energy"] - shifted.data["wall_energy"]).max()
    assert diff > 1e3 * rep.rtol * np.abs(treated.data["wall_energy"]).max()
