"""numba's set-up in a process that runs compiled (engine/backend.py prepare_numba): a kernel
loaded from the disk cache loads none of numba's registries (~0.2 s of every process's start-up);
a kernel compiled loads them with the BLAS probe of numba.np.arraymath skipped (no scipy.linalg,
~0.3 s); the probe is restored for later BLAS uses, and the results are the same bits as with
numba's own set-up."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

PROBE = """
import json, sys
import numpy as np
from wallbatch.config.models import config_from_dict
from wallbatch.engine import backend
from wallbatch.engine.engine import Engine
from wallbatch.scene.build import build_case
if sys.argv[1] == "numba-own":  # numba's own set-up: its BLAS probe imports scipy.linalg
    backend._numba_prepared = True
d = {"seed": 3, "box": {"lo": [0, 0, 0], "hi": [6, 6, 10], "boundary": ["p", "p", "f"]},
     "atoms": [{"group": "a", "create": {"random": {"count": 300, "region": "mid"}}, "mass": 1.0,
                "velocity": {"temperature": 1.5}}],
     "regions": {"mid": {"style": "block", "lo": [0, 0, 1.0], "hi": [6, 6, 8.5], "units": "box"}},
     "walls": {"w": {"style": "lj93", "units": "box", "energy": True,
                     "zlo": {"coord": "EDGE", "epsilon": 1.0, "sigma": 1.0, "cutoff": 2.5},
                     "zhi": {"coord": 9.9, "epsilon": 1.0, "sigma": 1.0, "cutoff": 2.5}}},
     "timestep": 0.005, "run": {"steps": 400, "thermo": 100}}
engine = Engine([build_case(config_from_dict(d))])
res = engine.run()[0]
assert res.status == "ok" and engine.fast.compiled_chunks > 0 and engine.fast.fallbacks == 0
loaded = "numba.np.arraymath" in sys.modules  # numba's registries (arraymath among them) loaded
out = {"registries": loaded, "scipy_linalg": "scipy.linalg" in sys.modules, "f2py": "numpy.f2py" in sys.modules,
       "data": {k: [float(x).hex() for x in np.ravel(v)] for k, v in sorted(res.data.items())}}
if loaded:  # (importing it here would run the probe itself)
    import numba.np.arraymath as am, numba.np.linalg as nl
    out["have_blas"] = am._HAVE_BLAS
    out["probe"] = [f.__module__ + "." + f.__name__ for f in (nl.ensure_blas, am.ensure_blas)]
if sys.argv[3] == "then-harmonic":  # then a scene whose kernel is not in the cache: numba compiles it
    for face in ("zlo", "zhi"):
        d["walls"]["w"][face]["epsilon"] = 5.0
    d["walls"]["w"]["style"] = "harmonic"
    case = build_case(config_from_dict(d))
    engine = Engine([case])
    got = engine.run()[0]
    assert got.status == "ok" and engine.fast.compiled_chunks > 0 and engine.fast.fallbacks == 0
    with backend.plan_path(False):
        ref = Engine([case]).run()[0]
    out["then"] = {"registries": "numba.np.arraymath" in sys.modules, "scipy_linalg": "scipy.linalg" in sys.modules,
                   "same_bits_as_numpy": all(np.array_equal(got.data[k], ref.data[k]) for k in ref.data)}
if sys.argv[2] == "dot":  # a BLAS use after the set-up: compiled with scipy's BLAS, as numba does it
    from numba import njit
    dot = njit(lambda a, b: np.dot(a, b))
    a, b = np.arange(12.0).reshape(3, 4), np.linspace(0.5, 2.0, 4)
    out["dot"] = dot(a, b).tolist() == (a @ b).tolist()
    out["scipy_linalg_after_dot"] = "scipy.linalg" in sys.modules
print(json.dumps(out))
"""


def start(setup: str, dot: str = "", cache: Path | None = None, then: str = "") -> subprocess.Popen:
    """A probe process (its answer: `answer`); `cache`: numba's cache folder (NUMBA_CACHE_DIR);
    `then`: "then-harmonic" runs a harmonic-wall scene after the lj93 one."""
    env = {**os.environ, "WALLBATCH_NUMBA": "1", "WALLBATCH_THREADS": "1",
           "PYTHONPATH": str(Path(__file__).resolve().parents[2] / "src")}
    if cache is not None:
        env["NUMBA_CACHE_DIR"] = str(cache)
    return subprocess.Popen([sys.executable, "-c", PROBE, setup, dot or "-", then or "-"], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, env=env)


def answer(proc: subprocess.Popen) -> dict:
    out, err = proc.communicate(timeout=900)
    assert proc.returncode == 0, err[-3000:]
    return json.loads(out.splitlines()[-1])


def probe(setup: str, dot: str = "", cache: Path | None = None, then: str = "") -> dict:
    return answer(start(setup, dot, cache, then))


@pytest.fixture(scope="module")
def cold_then_warm(tmp_path_factory) -> tuple[dict, dict]:
    """Two probe processes on a new numba cache, one after the other: the first finds it empty and
    compiles the lj93 scene's kernels, the second loads them, then compiles a harmonic-wall scene's."""
    cache = tmp_path_factory.mktemp("numba-cache")
    return probe("wallbatch", "dot", cache), probe("wallbatch", "dot", cache, "then-harmonic")


@pytest.mark.slow  # a compile on an empty numba cache (~20 s)
def test_a_compile_loads_the_registries_without_scipy_linalg(cold_then_warm):
    cold, _ = cold_then_warm
    assert cold["registries"] is True
    assert cold["scipy_linalg"] is False and cold["f2py"] is False
    assert cold["have_blas"] is False  # what the skipped probe answered
    assert cold["probe"] == ["numba.np.linalg.ensure_blas"] * 2  # restored in both modules
    assert cold["dot"] is True and cold["scipy_linalg_after_dot"] is True  # np.dot found scipy's BLAS


@pytest.mark.slow  # a compile on an empty numba cache (~20 s)
def test_a_run_of_cached_kernels_loads_no_registries_and_a_later_blas_use_still_works(cold_then_warm):
    cold, warm = cold_then_warm
    assert warm["registries"] is False  # only numba's runtime was set up to load them
    assert warm["scipy_linalg"] is False and warm["f2py"] is False
    assert warm["dot"] is True and warm["scipy_linalg_after_dot"] is True  # np.dot found scipy's BLAS
    assert warm["data"] == cold["data"]


@pytest.mark.slow  # a compile on an empty numba cache (~20 s)
def test_a_compile_after_cached_loads_loads_the_registries_without_scipy_linalg(cold_then_warm):
    _, warm = cold_then_warm
    assert warm["registries"] is False  # before the harmonic scene: loads only
    assert warm["then"] == {"registries": True, "scipy_linalg": False, "same_bits_as_numpy": True}


@pytest.mark.slow
def test_the_results_are_the_bits_of_numbas_own_set_up():
    procs = start("wallbatch"), start("numba-own")  # two processes at once (two cores)
    ours, own = (answer(p) for p in procs)
    assert own["registries"] is True and own["scipy_linalg"] is True and own["have_blas"] is True  # numba's way
    assert ours["scipy_linalg"] is False
    assert len(ours["data"]["etot"]) == 5
    assert ours["data"] == own["data"]
