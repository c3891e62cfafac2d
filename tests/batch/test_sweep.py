"""Sweeps (shared/spec/config.md "Sweeps", shared/spec/outputs.md): expansion of a scene into a
labelled grid of cases, the NetCDF layout of the results, failed cases keeping their place, and
bit-identity of a case whatever batch, job count or executor runs it."""

from __future__ import annotations

import itertools
import textwrap
from pathlib import Path

import numpy as np
import pytest
import xarray as xr
from typer.testing import CliRunner

from wallbatch.cli import app
from wallbatch.config.source import ConfigError
from wallbatch.batch.runner import build_cases, case_key, make_tasks, run_plan
from wallbatch.config.sweep import SweepDim, SweepPlan, config_to_dict, load_plan, set_path

cli = CliRunner()

try:
    import distributed  # noqa: F401
    HAVE_DISTRIBUTED = True
except ImportError:  # pragma: no cover
    HAVE_DISTRIBUTED = False

# 40 gas atoms created at random (random positions and velocities: the seed matters) in a slab
# 1 < z < 8, plus one probe atom at rest at z = 5 (out of reach of both walls, no pair forces: it
# stays there). Two lj93 faces: zlo at the box edge, zhi at z = 9.9.
SCENE = """\
name: sweeptest
units: lj
seed: 7
box: {lo: [0, 0, 0], hi: [6, 6, 10], boundary: [p, p, f]}
regions:
  slab: {style: block, lo: [0, 0, 1], hi: [6, 6, 8], units: box}
atoms:
  - group: gas
    create: {random: {count: 40, overlap: 0.8, region: slab}}
    mass: 1.0
    velocity: {temperature: 1.0}
  - group: probe
    create: {positions: [[3.0, 3.0, 5.0]]}
    mass: 1.0
walls:
  zwalls:
    style: lj93
    units: box
    energy: true
    zlo: {coord: EDGE, epsilon: 1.0, sigma: 1.0, cutoff: 2.5}
    zhi: {coord: 9.9, epsilon: 1.0, sigma: 1.0, cutoff: 2.5}
run: {steps: 100, thermo: 20}
"""

# the same scene with a third wall written as a LAMMPS fix line, and its mapping-form twin
FIXLINE_WALL = '  top: "fix top all wall/lj126 zhi 9.5 1.0 1.0 2.5 units box"\n'
MAPPING_WALL = "  top: {style: lj126, units: box, zhi: {coord: 9.5, epsilon: 1.0, sigma: 1.0, cutoff: 2.5}}\n"


def _with_wall(wall: str) -> str:
    return SCENE.replace("run: {steps", wall + "run: {steps")


def scene_with_sweep(tmp_path: Path, sweep: str, name: str = "scene.yaml", scene: str = SCENE) -> Path:
    """The scene with a `sweep:` block (YAML text, indented under `sweep:`)."""
    path = tmp_path / name
    path.write_text(scene + "sweep:\n" + textwrap.indent(textwrap.dedent(sweep), "  "))
    return path


def sweep_file(tmp_path: Path, body: str, name: str = "sweep.yaml") -> Path:
    """A sweep file in tmp_path/sweeps/ naming ../configs/scene.yaml as its base."""
    (tmp_path / "configs").mkdir(exist_ok=True)
    (tmp_path / "configs" / "scene.yaml").write_text(SCENE)
    (tmp_path / "sweeps").mkdir(exist_ok=True)
    path = tmp_path / "sweeps" / name
    path.write_text("base: ../configs/scene.yaml\n" + textwrap.dedent(body))
    return path


def get_path(data, path: str):
    node = data
    for part in path.split("."):
        node = node[int(part)] if isinstance(node, (list, tuple)) else node[part]
    return node


def case_value(case, path: str):
    return get_path(config_to_dict(case.config), path)


def same(a: np.ndarray, b: np.ndarray) -> bool:
    a, b = np.asarray(a), np.asarray(b)
    if a.dtype.kind == "f" and b.dtype.kind == "f":
        return a.shape == b.shape and np.array_equal(a, b, equal_nan=True)
    return a.shape == b.shape and np.array_equal(a, b)


def assert_identical_outputs(ds1: xr.Dataset, ds2: xr.Dataset, skip=("seconds",)) -> None:
    """Every data variable (but `seconds`) and coordinate bit-identical."""
    assert set(ds1.data_vars) == set(ds2.data_vars)
    for name in ds1.data_vars:
        if name in skip:
            continue
        assert ds1[name].dims == ds2[name].dims, name
        assert same(ds1[name].values, ds2[name].values), name
    assert set(ds1.coords) == set(ds2.coords)
    for name in ds1.coords:
        assert same(ds1[name].values, ds2[name].values), name


def subplan(plan: SweepPlan, **keep) -> SweepPlan:
    """The grid of `plan` restricted to the given coordinate values per dimension (same cases,
    same seeds), as a plan of its own."""
    dims = [SweepDim(d.name, [v for v in d.values if v in keep.get(d.name, d.values)], d.paths,
                     {k: ([x for x, v in zip(vals, d.values) if v in keep.get(d.name, d.values)], p)
                      for k, (vals, p) in d.extra.items()})
            for d in plan.dims]
    cases = [c for c in plan.cases if all(c.coords[k] in vals for k, vals in keep.items())]
    return SweepPlan(dims, cases, plan.base_text, plan.sweep_text)


def numeric_vars(ds: xr.Dataset) -> list[str]:
    return [n for n in ds.data_vars if ds[n].dtype.kind == "f" and n != "seconds"]


# ============================================================================================
# expansion


def test_product_value_forms_counts_and_coords(tmp_path):
    path = scene_with_sweep(tmp_path, """\
        product:
          epsilon: {path: walls.zwalls.zlo.epsilon, values: [0.5, 1.0]}
          sigma: {path: walls.zwalls.zhi.sigma, values: {linspace: [0.8, 1.2, 3]}}
          temp0: {path: atoms.0.velocity.temperature, values: {logspace: [-1, 1, 3]}}
          n: {path: atoms.0.create.random.count, values: {range: [30, 50, 10]}}
          cut: {path: walls.zwalls.zlo.cutoff, values: {range: [2.0, 3.0, 0.25]}}
        """)
    plan = load_plan(path)
    expected = {
        "epsilon": [0.5, 1.0],
        "sigma": [0.8, 1.0, 1.2],
        "temp0": [0.1, 1.0, 10.0],
        "n": [30, 40],  # [a, b) like numpy.arange; whole numbers stay integers
        "cut": [2.0, 2.25, 2.5, 2.75],
    }
    assert [d.name for d in plan.dims] == list(expected)
    for d in plan.dims:
        np.testing.assert_allclose(d.values, expected[d.name], rtol=1e-12)
    assert [type(v) for v in plan.dims[3].values] == [int, int]
    assert plan.shape == (2, 3, 3, 2, 4)
    assert len(plan.cases) == 2 * 3 * 3 * 2 * 4
    paths = {"epsilon": "walls.zwalls.zlo.epsilon", "sigma": "walls.zwalls.zhi.sigma",
             "temp0": "atoms.0.velocity.temperature", "n": "atoms.0.create.random.count",
             "cut": "walls.zwalls.zlo.cutoff"}
    # C order over the dimensions; each case's validated config holds its coordinates
    grid = list(itertools.product(*(d.values for d in plan.dims)))
    for case, values in zip(plan.cases, grid):
        assert list(case.coords) == list(expected)
        assert tuple(case.coords.values()) == values
        for name, value in case.coords.items():
            assert case_value(case, paths[name]) == pytest.approx(value, rel=1e-12)
        # the untouched values stay those of the scene
        assert case_value(case, "walls.zwalls.zhi.epsilon") == 1.0
        assert case_value(case, "walls.zwalls.zlo.sigma") == 1.0
    assert plan.cases[0].config.atoms[0].create.random.count == 30


def test_cases_share_the_sections_no_swept_path_writes(tmp_path):
    """A 10,000-case sweep must not hold 10,000 copies of the scene: sections that no swept path
    writes into are one shared object over the cases; swept sections are each case's own."""
    path = scene_with_sweep(tmp_path, """\
        product:
          epsilon: {path: walls.zwalls.zlo.epsilon, values: [0.5, 1.0, 2.0]}
        """)
    plan = load_plan(path)
    first, *rest = (c.config for c in plan.cases)
    for cfg in rest:
        assert cfg.atoms is first.atoms and cfg.box is first.box and cfg.run is first.run
        assert cfg.walls is not first.walls
    assert [c.config.walls["zwalls"].zlo.epsilon for c in plan.cases] == [0.5, 1.0, 2.0]
    assert all(c.config.walls["zwalls"].zhi.epsilon == 1.0 for c in plan.cases)


def test_multi_path_entry_sets_every_path(tmp_path):
    path = scene_with_sweep(tmp_path, """\
        product:
          epsilon: {path: [walls.zwalls.zlo.epsilon, walls.zwalls.zhi.epsilon], values: [0.5, 2.0, 3.0]}
        """)
    plan = load_plan(path)
    assert [d.name for d in plan.dims] == ["epsilon"]
    assert plan.dims[0].paths == ("walls.zwalls.zlo.epsilon", "walls.zwalls.zhi.epsilon")
    assert [c.coords["epsilon"] for c in plan.cases] == [0.5, 2.0, 3.0]
    for case in plan.cases:
        eps = case.coords["epsilon"]
        assert case_value(case, "walls.zwalls.zlo.epsilon") == eps
        assert case_value(case, "walls.zwalls.zhi.epsilon") == eps


def test_shorthand_names_dimension_after_last_part(tmp_path):
    path = scene_with_sweep(tmp_path, """\
        product:
          walls.zwalls.zlo.epsilon: [0.5, 1.0]
          walls.zwalls.zhi.sigma: {linspace: [0.9, 1.1, 3]}
        """)
    plan = load_plan(path)
    assert [d.name for d in plan.dims] == ["epsilon", "sigma"]
    assert plan.dims[0].paths == ("walls.zwalls.zlo.epsilon",)
    assert plan.dims[1].paths == ("walls.zwalls.zhi.sigma",)
    assert len(plan.cases) == 6
    for case in plan.cases:
        assert case_value(case, "walls.zwalls.zlo.epsilon") == case.coords["epsilon"]
        assert case_value(case, "walls.zwalls.zhi.sigma") == case.coords["sigma"]


def test_two_shorthands_with_same_last_part_ask_for_names(tmp_path):
    path = scene_with_sweep(tmp_path, """\
        product:
          walls.zwalls.zlo.epsilon: [0.5, 1.0]
          walls.zwalls.zhi.epsilon: [0.5, 1.0]
        """)
    with pytest.raises(ConfigError) as err:
        load_plan(path)
    msg = str(err.value)
    assert "walls.zwalls.zlo.epsilon" in msg and "walls.zwalls.zhi.epsilon" in msg
    assert "'epsilon'" in msg
    assert "name" in msg  # asks for {path: ..., values: ...} with distinct names


def test_zip_is_one_dimension_with_extra_coordinates(tmp_path):
    path = scene_with_sweep(tmp_path, """\
        product:
          epsilon: {path: walls.zwalls.zlo.epsilon, values: [0.5, 1.0]}
        zip:
          dim: geometry
          params:
            n: {path: atoms.0.create.random.count, values: [20, 30, 40]}
            top: {path: walls.zwalls.zhi.coord, values: [8.5, 9.0, 9.5]}
            hot: {path: [atoms.0.velocity.temperature, walls.zwalls.zhi.sigma], values: [1.0, 1.1, 1.2]}
        """)
    plan = load_plan(path)
    assert [d.name for d in plan.dims] == ["epsilon", "geometry"]
    geo = plan.dims[1]
    assert geo.values == [0, 1, 2]
    assert set(geo.extra) == {"n", "top", "hot"}
    assert geo.extra["n"] == ([20, 30, 40], ("atoms.0.create.random.count",))
    assert geo.extra["hot"][1] == ("atoms.0.velocity.temperature", "walls.zwalls.zhi.sigma")
    assert len(plan.cases) == 6
    for case in plan.cases:
        k = case.coords["geometry"]
        assert case_value(case, "atoms.0.create.random.count") == [20, 30, 40][k]
        assert case_value(case, "walls.zwalls.zhi.coord") == [8.5, 9.0, 9.5][k]
        assert case_value(case, "atoms.0.velocity.temperature") == [1.0, 1.1, 1.2][k]
        assert case_value(case, "walls.zwalls.zhi.sigma") == [1.0, 1.1, 1.2][k]
        assert case_value(case, "walls.zwalls.zlo.epsilon") == case.coords["epsilon"]


def test_zip_length_mismatch_is_an_error(tmp_path):
    path = scene_with_sweep(tmp_path, """\
        zip:
          dim: geometry
          params:
            n: {path: atoms.0.create.random.count, values: [20, 30, 40]}
            top: {path: walls.zwalls.zhi.coord, values: [8.5, 9.0]}
        """)
    with pytest.raises(ConfigError) as err:
        load_plan(path)
    msg = str(err.value)
    assert "zip" in msg and "equal length" in msg
    assert "n: 3" in msg and "top: 2" in msg


def test_replicas_last_and_dims_in_declared_order(tmp_path):
    # zip written before product: the declared order is kept; replica always comes last
    path = scene_with_sweep(tmp_path, """\
        replicas: 3
        zip:
          dim: geometry
          params:
            n: {path: atoms.0.create.random.count, values: [20, 30]}
        product:
          sigma: {path: walls.zwalls.zhi.sigma, values: [0.9, 1.1]}
          epsilon: {path: walls.zwalls.zlo.epsilon, values: [0.5, 1.0, 2.0]}
        """)
    plan = load_plan(path)
    assert [d.name for d in plan.dims] == ["geometry", "sigma", "epsilon", "replica"]
    assert plan.shape == (2, 2, 3, 3)
    assert plan.dims[-1].values == [0, 1, 2]
    # replicas differ only by their random stream: same config, different seed key
    reps = [c for c in plan.cases if c.coords["geometry"] == 0 and c.coords["sigma"] == 0.9
            and c.coords["epsilon"] == 0.5]
    assert [c.coords["replica"] for c in reps] == [0, 1, 2]
    assert config_to_dict(reps[0].config) == config_to_dict(reps[1].config) == config_to_dict(reps[2].config)
    assert len({c.seed_key for c in reps}) == 3
    assert len({c.seed_key for c in plan.cases}) == len(plan.cases)


def test_sweep_file_with_base_and_set(tmp_path):
    path = sweep_file(tmp_path, """\
        set: {run.steps: 60, walls.zwalls.zhi.epsilon: 1.5}
        sweep:
          product:
            walls.zwalls.zlo.epsilon: [0.5, 1.0]
        """)
    plan = load_plan(path)
    assert "name: sweeptest" in plan.base_text  # the base is read relative to the sweep file
    assert [d.name for d in plan.dims] == ["epsilon"]
    assert len(plan.cases) == 2
    for case in plan.cases:
        assert case.config.run.steps == 60
        assert case_value(case, "walls.zwalls.zhi.epsilon") == 1.5
        assert case_value(case, "walls.zwalls.zlo.epsilon") == case.coords["epsilon"]
    assert "walls.zwalls.zlo.epsilon" in plan.sweep_text


def test_sweep_file_takes_only_base_set_sweep(tmp_path):
    path = sweep_file(tmp_path, "steps: 10\nsweep: {product: {walls.zwalls.zlo.epsilon: [1.0]}}\n")
    with pytest.raises(ConfigError, match="base, set and sweep"):
        load_plan(path)


def test_overrides_through_load_plan(tmp_path):
    path = sweep_file(tmp_path, """\
        set: {run.steps: 60}
        sweep:
          product:
            walls.zwalls.zlo.epsilon: [0.5, 1.0]
        """)
    plan = load_plan(path, ["run.steps=40", "walls.zwalls.zhi.sigma=1.25", "atoms.0.create.random.count=25"])
    for case in plan.cases:
        assert case.config.run.steps == 40  # --set wins over the sweep file's set:
        assert case_value(case, "walls.zwalls.zhi.sigma") == 1.25
        assert case.config.atoms[0].create.random.count == 25
        assert case_value(case, "walls.zwalls.zlo.epsilon") == case.coords["epsilon"]
    # a scene with its own sweep: key takes overrides too
    plan2 = load_plan(scene_with_sweep(tmp_path, "product: {walls.zwalls.zlo.epsilon: [0.5]}\n"), ["run.thermo=10"])
    assert plan2.cases[0].config.run.thermo == 10
    with pytest.raises(ConfigError, match="path=value"):
        load_plan(path, ["run.steps"])


def test_overrides_through_cli(tmp_path):
    path = sweep_file(tmp_path, """\
        sweep:
          product:
            walls.zwalls.zlo.epsilon: [0.5, 1.0]
        """)
    res = cli.invoke(app, ["check", str(path), "--set", "run.steps=40", "--set", "run.thermo=10", "-j", "1"])
    assert res.exit_code == 0, res.output
    assert "2 case(s)" in res.output
    assert "steps: 40" in res.output and "samples: 5" in res.output
    out = tmp_path / "out.nc"
    res = cli.invoke(app, ["run", str(path), "-o", str(out), "-j", "1", "--set", "run.steps=40",
                           "--set", "walls.zwalls.zhi.epsilon=1.5"])
    assert res.exit_code == 0, res.output
    with xr.open_dataset(out) as ds:
        ds.load()
    assert ds["step"].values.tolist() == [0, 20, 40]
    ref = run_plan(load_plan(path, ["run.steps=40", "walls.zwalls.zhi.epsilon=1.5"]))
    assert_identical_outputs(ds, ref)


def test_path_that_does_not_exist_is_a_clear_error(tmp_path):
    path = scene_with_sweep(tmp_path, "product: {walls.nowall.zlo.epsilon: [0.5, 1.0]}\n")
    with pytest.raises(ConfigError, match=r"walls\.nowall\.zlo\.epsilon: walls\.nowall does not exist"):
        load_plan(path)
    path = scene_with_sweep(tmp_path, "product: {atoms.5.mass: [1.0]}\n")
    with pytest.raises(ConfigError, match=r"atoms\.5 does not exist"):
        load_plan(path)
    # a misspelt last key: each case is validated and the key named
    path = scene_with_sweep(tmp_path, "product: {walls.zwalls.zlo.epsilonn: [0.5]}\n")
    with pytest.raises(ConfigError, match=r"walls\.zwalls\.zlo\.epsilonn: unknown key"):
        load_plan(path)
    # through --set, on the command line: exit code 2 and the message
    plain = tmp_path / "plain.yaml"
    plain.write_text(SCENE)
    res = cli.invoke(app, ["check", str(plain), "--set", "walls.nowall.zlo.epsilon=2"])
    assert res.exit_code == 2
    assert "walls.nowall does not exist" in res.output


def test_invalid_case_names_its_coordinates_and_field_before_running(tmp_path, monkeypatch):
    import wallbatch.engine.engine
    import wallbatch.batch.runner

    def boom(*a, **k):  # nothing may run
        raise AssertionError("a case ran")

    monkeypatch.setattr(wallbatch.batch.runner, "run_cases", boom)
    monkeypatch.setattr(wallbatch.engine.engine, "run_cases", boom)
    path = scene_with_sweep(tmp_path, """\
        product:
          cutoff: {path: [walls.zwalls.zlo.cutoff, walls.zwalls.zhi.cutoff], values: [2.5, -1.0]}
        """)
    with pytest.raises(ConfigError) as err:
        load_plan(path)
    problems = err.value.problems
    assert any("cutoff=-1.0" in p and "walls.zwalls.zlo.cutoff" in p for p in problems), problems
    assert any("cutoff=-1.0" in p and "walls.zwalls.zhi.cutoff" in p for p in problems), problems
    assert not any("cutoff=2.5" in p for p in problems)
    out = tmp_path / "out.nc"
    res = cli.invoke(app, ["run", str(path), "-o", str(out), "-j", "1"])
    assert res.exit_code == 2
    assert "cutoff=-1.0" in res.output and "walls.zwalls.zlo.cutoff" in res.output
    assert not out.exists() and not (tmp_path / "out.nc.parts").exists()


@pytest.mark.parametrize("wall", [FIXLINE_WALL, MAPPING_WALL], ids=["fixline", "mapping"])
def test_wall_written_as_fix_line_is_swept_by_model_path(tmp_path, wall):
    path = scene_with_sweep(tmp_path, "product: {walls.top.zhi.epsilon: [0.5, 2.0]}\n", scene=_with_wall(wall))
    plan = load_plan(path)
    assert [d.name for d in plan.dims] == ["epsilon"]
    assert [case_value(c, "walls.top.zhi.epsilon") for c in plan.cases] == [0.5, 2.0]
    assert [c.config.walls["top"].zhi.epsilon for c in plan.cases] == [0.5, 2.0]


def test_fix_line_wall_sweep_equals_mapping_form(tmp_path):
    sweep = "product: {walls.top.zhi.epsilon: [0.5, 2.0]}\n"
    a = load_plan(scene_with_sweep(tmp_path, sweep, "a.yaml", _with_wall(FIXLINE_WALL)))
    b = load_plan(scene_with_sweep(tmp_path, sweep, "b.yaml", _with_wall(MAPPING_WALL)))
    assert [config_to_dict(c.config) for c in a.cases] == [config_to_dict(c.config) for c in b.cases]
    ds_a, ds_b = run_plan(a), run_plan(b)
    assert (ds_a["status"] == "ok").all()
    assert_identical_outputs(ds_a, ds_b)
    # the swept strength matters (the gas reaches the top wall)
    top = ds_a["wall_energy"].sel(fix="top")
    assert not same(top.sel(epsilon=0.5).values, top.sel(epsilon=2.0).values)


def test_set_path_on_lists_and_values():
    data = {"a": {"b": [1, 2, 3]}, "c": 5}
    set_path(data, "a.b.1", 7)
    set_path(data, "a.b.-1", 9)
    assert data == {"a": {"b": [1, 7, 9]}, "c": 5}
    with pytest.raises(ConfigError, match="not an index"):
        set_path(data, "a.b.3", 0)
    with pytest.raises(ConfigError, match="is a value"):
        set_path(data, "c.d", 0)


def test_index_into_vector_field_like_spec_example(tmp_path):
    # paths address the JSON form of the model: vectors are lists, indexed by integers
    path = scene_with_sweep(tmp_path, """\
        zip:
          dim: geometry
          params:
            lz: {path: box.hi.2, values: [10.0, 12.0]}
            top: {path: walls.zwalls.zhi.coord, values: [9.9, 11.9]}
        """)
    plan = load_plan(path)
    assert [c.config.box.hi[2] for c in plan.cases] == [10.0, 12.0]
    assert load_plan(path, ["regions.slab.hi.2=7.5"]).cases[0].config.regions["slab"].hi[2] == 7.5


def test_dimension_named_like_an_output_variable_is_rejected_before_running(tmp_path):
    path = scene_with_sweep(tmp_path, """\
        product:
          temp: {path: atoms.0.velocity.temperature, values: [1.0, 2.0]}
        """)
    try:
        plan = load_plan(path)
    except ConfigError as exc:
        assert "temp" in str(exc)
        return
    ds = run_plan(plan)  # otherwise it must give a usable dataset
    assert ds["temp"].dims[-1] == "sample"


def test_zip_parameter_named_like_a_dimension_is_rejected(tmp_path):
    path = scene_with_sweep(tmp_path, """\
        product:
          epsilon: {path: walls.zwalls.zlo.epsilon, values: [0.5, 1.0]}
        zip:
          dim: geometry
          params:
            epsilon: {path: walls.zwalls.zhi.epsilon, values: [2.0, 3.0, 4.0]}
        """, scene=SCENE.replace("steps: 100", "steps: 10"))
    try:
        plan = load_plan(path)
    except ConfigError as exc:
        assert "epsilon" in str(exc)
        return
    ds = run_plan(plan)
    assert ds["epsilon"].dims == ("epsilon",)
    assert ds["epsilon"].values.tolist() == [0.5, 1.0]


def test_check_rejects_what_run_rejects(tmp_path):
    path = scene_with_sweep(tmp_path, "product: {run.thermo: [10, 20]}\n")
    res = cli.invoke(app, ["run", str(path), "-o", str(tmp_path / "out.nc"), "-j", "1"])
    assert res.exit_code == 2 and "thermo=20" in res.output  # run: refused before anything runs
    res = cli.invoke(app, ["check", str(path), "-j", "1"])
    assert res.exit_code != 0
    assert "thermo=20" in res.output


# ============================================================================================
# results


@pytest.fixture(scope="module")
def grid_run(tmp_path_factory):
    """A 2 x 2 x 2 grid (product, zip, replicas) written to NetCDF: (plan, returned ds, file ds)."""
    tmp = tmp_path_factory.mktemp("grid")
    path = scene_with_sweep(tmp, """\
        product:
          epsilon: {path: [walls.zwalls.zlo.epsilon, walls.zwalls.zhi.epsilon], values: [0.5, 1.0]}
        zip:
          dim: geometry
          params:
            n: {path: atoms.0.create.random.count, values: [30, 40]}
            t0: {path: atoms.0.velocity.temperature, values: [1.0, 1.5]}
        replicas: 2
        """)
    plan = load_plan(path)
    out = tmp / "out.nc"
    ds = run_plan(plan, out, jobs=1)
    with xr.open_dataset(out) as f:
        f.load()
    return plan, ds, f, out


def test_netcdf_round_trip_dims_and_selection(grid_run):
    plan, ds, f, out = grid_run
    assert not out.with_name("out.nc.parts").exists()  # parts are removed once the file is written
    assert dict(f.sizes) == {"epsilon": 2, "geometry": 2, "replica": 2, "sample": 6, "fix": 1, "face": 2}
    assert f["wall_energy"].dims == ("epsilon", "geometry", "replica", "sample", "fix")
    assert f["wall_force"].dims == ("epsilon", "geometry", "replica", "sample", "face")
    for name in ("time", "dt", "temp", "ke", "pe", "etot"):
        assert f[name].dims == ("epsilon", "geometry", "replica", "sample"), name
    for name in ("status", "error", "seconds"):
        assert f[name].dims == ("epsilon", "geometry", "replica"), name
    assert f["epsilon"].values.tolist() == [0.5, 1.0]
    assert f["geometry"].values.tolist() == [0, 1]
    assert f["replica"].values.tolist() == [0, 1]
    # selectable by value
    sel = f.wall_energy.sel(epsilon=1.0)
    assert sel.dims == ("geometry", "replica", "sample", "fix")
    assert same(sel.values, ds.wall_energy.sel(epsilon=1.0).values)
    assert same(f.pe.sel(epsilon=0.5, geometry=1, replica=0).values,
                ds.pe.values[0, 1, 0])
    assert_identical_outputs(f, ds)
    assert (f["status"] == "ok").all()
    assert (f["error"] == "").all()
    assert (f["seconds"] > 0).all()
    assert f["seconds"].attrs["units"] == "s"


def test_netcdf_coordinate_attrs_and_zip_extra_coords(grid_run):
    plan, ds, f, _ = grid_run
    assert f["epsilon"].attrs["path"] == "walls.zwalls.zlo.epsilon, walls.zwalls.zhi.epsilon"
    assert f["n"].dims == ("geometry",) and f["n"].values.tolist() == [30, 40]
    assert f["t0"].dims == ("geometry",) and f["t0"].values.tolist() == [1.0, 1.5]
    assert f["n"].attrs["path"] == "atoms.0.create.random.count"
    assert f["t0"].attrs["path"] == "atoms.0.velocity.temperature"
    assert "atoms.0.create.random.count" in f["geometry"].attrs["path"]
    assert "path" in f["replica"].attrs
    for name in ("epsilon", "geometry", "n", "t0", "replica"):
        assert f[name].attrs.get("units") and f[name].attrs.get("long_name"), name
    # the zip's parameters really differ along geometry: more atoms, hotter gas
    assert (f["ke"].isel(sample=0).sel(geometry=1) > f["ke"].isel(sample=0).sel(geometry=0)).all()
    assert "geometry" in f.attrs["sweep"] and f.attrs["config"] == plan.base_text


def test_replicas_are_independent_streams(grid_run):
    _, _, f, _ = grid_run
    ke0 = f["ke"].isel(sample=0)
    assert not same(ke0.sel(replica=0).values, ke0.sel(replica=1).values)


FAIL_SWEEP = "product: {walls.zwalls.zhi.coord: %s}\n"


def test_failed_case_keeps_its_place_and_spares_the_others(tmp_path):
    # zhi at z = 4 has the probe (z = 5) and part of the gas behind it: that case fails
    plan = load_plan(scene_with_sweep(tmp_path, FAIL_SWEEP % "[9.9, 4.0, 9.5]", "a.yaml"))
    out = tmp_path / "out.nc"
    run_plan(plan, out, jobs=1)
    with xr.open_dataset(out) as ds:
        ds.load()
    assert ds["coord"].values.tolist() == [9.9, 4.0, 9.5]
    assert ds["status"].values.tolist() == ["ok", "failed", "ok"]
    err = ds["error"].sel(coord=4.0).item()
    assert "zhi" in err and "behind" in err
    assert ds["error"].sel(coord=9.9).item() == "" and ds["error"].sel(coord=9.5).item() == ""
    for name in numeric_vars(ds):
        assert np.isnan(ds[name].sel(coord=4.0).values).all(), name
        assert not np.isnan(ds[name].sel(coord=9.9).values).any(), name
    # the others: identical to a run without the failing case
    ref = run_plan(load_plan(scene_with_sweep(tmp_path, FAIL_SWEEP % "[9.9, 9.5]", "b.yaml")))
    assert_identical_outputs(ds.sel(coord=[9.9, 9.5]), ref)


def test_set_that_makes_one_case_fail_via_cli(tmp_path):
    path = sweep_file(tmp_path, "sweep:\n  " + FAIL_SWEEP % "[9.9, 9.0]")
    # the probe moved to z = 9.3: behind the zhi wall at 9.0, in front of the one at 9.9
    probe = "atoms.1.create.positions=[[3.0, 3.0, 9.3]]"
    out = tmp_path / "out.nc"
    res = cli.invoke(app, ["run", str(path), "-o", str(out), "-j", "1", "--set", probe])
    assert res.exit_code == 1, res.output  # a failed case: exit 1, the file is still written
    assert "1 of 2 case(s) ok" in res.output
    with xr.open_dataset(out) as ds:
        ds.load()
    assert ds["status"].values.tolist() == ["ok", "failed"]
    assert "behind" in ds["error"].sel(coord=9.0).item()
    assert np.isnan(ds["pe"].sel(coord=9.0).values).all()
    # without --set both cases run
    assert (run_plan(load_plan(path))["status"] == "ok").all()
    # the ok case equals a run of it alone, with the same --set
    alone = sweep_file(tmp_path, "sweep:\n  " + FAIL_SWEEP % "[9.9]", "alone.yaml")
    ref = run_plan(load_plan(alone, [probe]))
    assert_identical_outputs(ds.sel(coord=[9.9]), ref)


# ============================================================================================
# bit-identity: a case's numbers never depend on the batch, the jobs or the executor


@pytest.fixture(scope="module")
def many(tmp_path_factory):
    """4 epsilons x 3 replicas with random creation, one structure; (path, plan, dataset)."""
    tmp = tmp_path_factory.mktemp("many")
    path = scene_with_sweep(tmp, """\
        product:
          epsilon: {path: [walls.zwalls.zlo.epsilon, walls.zwalls.zhi.epsilon], values: [0.5, 1.0, 1.5, 2.0]}
        replicas: 3
        """)
    plan = load_plan(path)
    return tmp, plan, run_plan(plan, jobs=1)


def _case(ds: xr.Dataset, **coords) -> xr.Dataset:
    return ds.sel(**coords).drop_vars(list(coords))


def test_many_cases_share_one_batch(many):
    _, plan, ds = many
    cases, errors = build_cases(plan)
    assert not errors
    tasks = make_tasks(dict(enumerate(cases)), jobs=1)
    assert tasks == [list(range(12))]  # all twelve in one batch: batch neighbours are real
    assert len(make_tasks(dict(enumerate(cases)), jobs=2)) == 2
    assert (ds["status"] == "ok").all()


def test_case_identical_alone_in_pair_and_in_many(many):
    tmp, plan, ds = many
    target = {"epsilon": 1.0, "replica": 1}
    alone = run_plan(subplan(plan, epsilon=[1.0], replica=[1]))
    pair = run_plan(subplan(plan, epsilon=[1.0, 2.0], replica=[1]))
    assert_identical_outputs(_case(alone, **target), _case(ds, **target))
    assert_identical_outputs(_case(pair, **target), _case(ds, **target))
    # a different plan file whose grid contains the same coordinates: same seed, same numbers
    other = load_plan(scene_with_sweep(tmp, """\
        product:
          epsilon: {path: [walls.zwalls.zlo.epsilon, walls.zwalls.zhi.epsilon], values: [1.0, 3.0]}
        replicas: 2
        """, "other.yaml"))
    hit = next(c for c in other.cases if c.coords == target)
    assert hit.seed_key == next(c for c in plan.cases if c.coords == target).seed_key
    assert case_key(hit) == case_key(next(c for c in plan.cases if c.coords == target))
    ds_other = run_plan(other)
    assert_identical_outputs(_case(ds_other, **target), _case(ds, **target))
    # and every case of the big run is as it is alone, for the first replicas of two epsilons
    for eps in (0.5, 2.0):
        one = run_plan(subplan(plan, epsilon=[eps], replica=[0]))
        assert_identical_outputs(_case(one, epsilon=eps, replica=0), _case(ds, epsilon=eps, replica=0))


def test_jobs_2_process_pool_is_bit_identical(many):
    _, plan, ds = many
    ds2 = run_plan(plan, jobs=2)
    assert_identical_outputs(ds2, ds)


@pytest.mark.skipif(not HAVE_DISTRIBUTED, reason="dask.distributed is not installed")
@pytest.mark.slow  # starts a dask.distributed cluster: 2-7 s
def test_dask_executor_is_bit_identical(many):
    from distributed import LocalCluster

    _, plan, ds = many
    with LocalCluster(n_workers=1, threads_per_worker=1, processes=True, host="127.0.0.1",
                      dashboard_address=None) as cluster:
        assert cluster.scheduler_address.startswith("tcp://127.0.0.1:")
        dds = run_plan(plan, executor="dask", scheduler=cluster.scheduler_address)
    assert_identical_outputs(dds, ds)


def test_swept_numeric_variable_shares_a_batch_and_stays_bit_identical(tmp_path):
    """Cases differing only by a numeric variable run as one batch; each case equals its run
    alone and the same sweep written on the wall coordinate itself."""
    scene = (SCENE.replace("zhi: {coord: 9.9,", "zhi: {coord: v_ztop,")
             .replace("\nwalls:\n", "\nvariables:\n  ztop: 9.9\nwalls:\n"))
    a = load_plan(scene_with_sweep(tmp_path, "product:\n  coord: {path: variables.ztop, values: [9.9, 9.5, 9.0]}\n",
                                   "a.yaml", scene))
    b = load_plan(scene_with_sweep(tmp_path, FAIL_SWEEP % "[9.9, 9.5, 9.0]", "b.yaml"))
    cases, _ = build_cases(a)
    assert make_tasks(dict(enumerate(cases)), jobs=1) == [[0, 1, 2]]
    ds_a = run_plan(a)
    assert (ds_a["status"] == "ok").all()
    assert_identical_outputs(ds_a, run_plan(b))
    one = run_plan(subplan(a, coord=[9.5]))
    assert_identical_outputs(one, ds_a.sel(coord=[9.5]))
