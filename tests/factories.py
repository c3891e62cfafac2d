"""Shared scene factories for the tests: config dicts of common scenes, and one way from a scene
(dict, YAML text, path or validated Config) to a Case, a CaseResult or the results Dataset.

Import them directly (`from factories import run_one, slab_gas`; conftest.py puts tests/ on
sys.path) in module-level helpers and parametrisations, or take the conftest fixtures of the same
names in a test's arguments. Lengths are in the scene's units (lj unless given).
"""

from __future__ import annotations

import contextlib
import gc
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import xarray as xr

from wallbatch.batch.runner import run_config
from wallbatch.config.models import (
    Config,
    config_from_dict,
    load_config,
    load_config_text,
)
from wallbatch.engine.engine import CaseResult, Engine, run_cases
from wallbatch.scene.build import build_case
from wallbatch.scene.case import Case

__all__ = ["SceneLike", "atoms", "box_scene", "case_of", "config_of", "results_file_plans", "run_dataset", "run_ok",
           "run_one", "slab_gas", "slit_yaml"]

SceneLike = dict | str | Path | Config  # a config dict, YAML text, a config file, or a validated Config


def config_of(scene: SceneLike, filename: str = "<config>") -> Config:
    """The validated Config of a scene: a dict (`config_from_dict`), YAML text
    (`load_config_text`, errors naming `filename`), a path (`load_config`) or a Config as is."""
    if isinstance(scene, Config):
        return scene
    if isinstance(scene, dict):
        return config_from_dict(scene)
    if isinstance(scene, Path):
        return load_config(scene)
    return load_config_text(scene, filename)


def case_of(scene: SceneLike, seed_key: tuple[int, ...] = ()) -> Case:
    """The scene's Case (random creation seeded by the master seed and `seed_key`)."""
    return build_case(config_of(scene), seed_key)


def run_one(scene: SceneLike) -> CaseResult:
    """The engine's CaseResult of a single-case scene (`run_cases([build_case(cfg)])[0]`)."""
    return run_cases([case_of(scene)])[0]


def run_ok(scene: SceneLike) -> CaseResult:
    """`run_one`, asserting the case finished (the message is the case's error otherwise)."""
    res = run_one(scene)
    assert res.status == "ok", res.error
    return res


def run_dataset(scene: SceneLike) -> xr.Dataset:
    """The results Dataset of a single-case scene (`runner.run_config`), as `wallbatch run` writes it."""
    return run_config(config_of(scene))


def atoms(group: str, positions, velocities=None, mass: float = 1.0, **extra: Any) -> dict:
    """One atom group created at explicit positions, with explicit velocities if given."""
    g = {"group": group, "create": {"positions": [list(p) for p in positions]}, "mass": mass, **extra}
    if velocities is not None:
        g["velocity"] = {"values": [list(v) for v in velocities]}
    return g


def box_scene(atom_groups: list[dict], walls: dict | None = None, *, units: str = "lj", lo=(0.0, 0.0, 0.0),
              hi=(10.0, 10.0, 10.0), boundary=("f", "f", "f"), timestep: float | None = 0.1, steps: int = 1,
              thermo: int = 1, seed: int = 11, **extra: Any) -> dict:
    """A config dict: atom groups and walls in a box (timestep None: the unit system's default);
    `extra` top-level keys (variables, output, ...) are added last."""
    d = {"units": units, "seed": seed,
         "box": {"lo": list(lo), "hi": list(hi), "boundary": list(boundary)},
         "atoms": atom_groups, "walls": walls or {}, "timestep": timestep,
         "run": {"steps": steps, "thermo": thermo}}
    if timestep is None:
        del d["timestep"]
    d.update(extra)
    return d


def slab_gas(walls: dict, *, n: int, hi, margin: float, temperature: float, seed: int, dt: float, steps: int,
             thermo: int, output: list[str] | None = None, **extra: Any) -> dict:
    """An ideal gas between walls: n atoms (mass 1, no pair forces) created at random in the slab
    `margin` < z < hi_z - margin of a box (0, 0, 0)-`hi`, x and y periodic, z fixed, with velocities
    at `temperature`; thermo keywords `output` if given, `extra` top-level keys last."""
    d = {"units": "lj", "seed": seed,
         "box": {"lo": [0, 0, 0], "hi": list(hi), "boundary": ["p", "p", "f"]},
         "atoms": [{"group": "gas", "create": {"random": {"count": n, "region": "mid"}},
                    "mass": 1.0, "velocity": {"temperature": temperature}}],
         "regions": {"mid": {"style": "block", "lo": [0, 0, margin], "hi": [hi[0], hi[1], hi[2] - margin],
                             "units": "box"}},
         "walls": walls, "timestep": dt, "run": {"steps": steps, "thermo": thermo}}
    if output:
        d["output"] = {"thermo": output}
    d.update(extra)
    return d


def slit_yaml(name: str, count: int, steps: int, thermo: int) -> str:
    """The YAML text of a small lj93 gas slit (6 x 6 x 10 box, walls at 0 and 9.9): the scene the
    run, resume, interrupt and hostile-input tests write to a file and then vary as text."""
    return f"""\
name: {name}
units: lj
seed: 3
box: {{lo: [0, 0, 0], hi: [6, 6, 10], boundary: [p, p, f]}}
regions:
  slab: {{style: block, lo: [0, 0, 1], hi: [6, 6, 8], units: box}}
atoms:
  - group: gas
    create: {{random: {{count: {count}, overlap: 0.8, region: slab}}}}
    mass: 1.0
    velocity: {{temperature: 1.0}}
walls:
  zwalls:
    style: lj93
    units: box
    energy: true
    zlo: {{coord: EDGE, epsilon: 1.0, sigma: 1.0, cutoff: 2.5}}
    zhi: {{coord: 9.9, epsilon: 1.0, sigma: 1.0, cutoff: 2.5}}
run: {{steps: {steps}, thermo: {thermo}}}
"""


def results_file_plans() -> dict:
    """Shipped sweeps and scenes that exercise every kind of results-file content, by name, each a
    loaded plan (`api.load`) shortened to run in about a second: zip parameters with string and
    integer values, reflect statistics (3 x 3 x 3 grid), a time-based run, profiles after a
    minimization, an object coordinate holding None. The results-file writer tests run them."""
    from wallbatch import api  # noqa: PLC0415 (api sits above what the other factories import)

    repo = Path(__file__).resolve().parents[1]
    return {
        "zip-strings-ints": api.load(repo / "sweeps" / "box-height-atoms-zip.yaml", ["run.steps=100"]),
        "reflect-stats": api.load(repo / "sweeps" / "reflect-swiggle-amplitude-period.yaml", ["run.steps=100"]),
        "time-based": api.load(repo / "configs" / "dt-reset-rescue.yaml"),
        "profiles-minimize": api.load(repo / "configs" / "lj-slit-profiles.yaml",
                                      ["run.steps=1000", "output.averages.start=500"]),
        "none-in-coordinate": api.load(repo / "sweeps" / "lj93-slit-cutoff-modes.yaml", ["run.steps=100"]),
    }


def run_numpy_and_compiled(monkeypatch: Any, cases: list[Case]) -> tuple[list[CaseResult], list[CaseResult], Engine]:
    """The same cases run as one batch on the NumPy path (WALLBATCH_NUMBA=0, the reference) and
    on the compiled path: (NumPy results, compiled results, the compiled run's engine)."""
    monkeypatch.setenv("WALLBATCH_NUMBA", "0")
    ref_engine = Engine(cases)
    assert ref_engine.fast is None
    ref = ref_engine.run()
    monkeypatch.setenv("WALLBATCH_NUMBA", "1")
    eng = Engine(cases)
    return ref, eng.run(), eng


def assert_same_results(ref: list[CaseResult], got: list[CaseResult], rtol: float = 0.0) -> None:
    """Same statuses, errors and output variables; values bit for bit (rtol 0) or within rtol of
    each variable's largest magnitude, NaN where the reference has NaN."""
    assert [r.status for r in got] == [r.status for r in ref]
    assert [r.error for r in got] == [r.error for r in ref]
    for a, b in zip(ref, got):
        assert a.data.keys() == b.data.keys()
        for name in a.data:
            x, y = a.data[name], b.data[name]
            assert np.shape(x) == np.shape(y), name
            if rtol == 0.0:
                np.testing.assert_array_equal(y, x, err_msg=name)
            else:
                assert np.array_equal(np.isnan(x), np.isnan(y)), name
                scale = np.nanmax(np.abs(x)) if np.isfinite(x).any() else 0.0
                np.testing.assert_allclose(y, x, rtol=0, atol=rtol * max(scale, 1e-300), equal_nan=True, err_msg=name)


@contextlib.contextmanager
def cyclic_garbage(save: bool = True) -> Iterator[dict]:
    """Count the reference cycles the block leaves: what earlier code left is collected first
    (objects with finalizers may take two passes), the collector is off during the block, then one
    collection counts what only it could free. Yields a dict filled on exit: `found` (objects the
    collection found) and, with `save`, `kinds` (their type names, from gc.DEBUG_SAVEALL)."""
    while gc.collect():
        pass
    enabled = gc.isenabled()
    gc.disable()
    if save:
        gc.set_debug(gc.DEBUG_SAVEALL)
    out: dict = {}
    try:
        yield out
        out["found"] = gc.collect()
        out["kinds"] = sorted({type(o).__qualname__ for o in gc.garbage})
    finally:
        gc.set_debug(0)
        gc.garbage.clear()
        if enabled:
            gc.enable()
