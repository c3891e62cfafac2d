"""The compiled chunk kernel survives numba's disk cache: a second process loads it and runs."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

PROBE = """
import json, sys
from wallbatch.config.models import config_from_dict
from wallbatch.engine import compiled
from wallbatch.engine.engine import Engine
from wallbatch.scene.build import build_case
d = {"seed": 3, "box": {"lo": [0, 0, 0], "hi": [5, 5, 9], "boundary": ["p", "p", "f"]},
     "atoms": [{"group": "a", "create": {"random": {"count": 40, "region": "mid"}}, "mass": 1.0,
                "velocity": {"temperature": 1.0}}],
     "regions": {"mid": {"style": "block", "lo": [0, 0, 1.4], "hi": [5, 5, 7.6], "units": "box"}},
     "walls": {"w": {"style": "lj93", "units": "box", "energy": True,
                     "zlo": {"coord": 0.0, "epsilon": 1.0, "sigma": 1.0, "cutoff": 2.5},
                     "zhi": {"coord": 9.0, "epsilon": 1.0, "sigma": 1.0, "cutoff": 2.5}}},
     "timestep": 0.002, "run": {"steps": 100, "thermo": 50}}
engine = Engine([build_case(config_from_dict(d))])
res = engine.run()[0]
assert res.status == "ok" and engine.fast.compiled_chunks > 0 and engine.fast.fallbacks == 0
k = engine.fast.kernel  # the scene kernel (kernel_for)
print(json.dumps({"hits": sum(k.stats.cache_hits.values()), "etot": res.data["etot"].tolist()}))
"""


@pytest.mark.slow
def test_builtin_chunk_kernel_loads_from_disk_in_a_second_process(tmp_path):
    """Regression: after the thermostats joined the chunk kernel, a kernel loaded from the disk
    cache referenced the recursive pairwise_sum through an unresolved symbol and the second
    process crashed (SIGSEGV / LLVM "Symbol not found"); thermostats.pairwise_sum is iterative now."""
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path), "WALLBATCH_NUMBA": "1",
           "PYTHONPATH": str(Path(__file__).resolve().parents[2] / "src")}
    runs = []
    for _ in range(2):
        proc = subprocess.run([sys.executable, "-c", PROBE], capture_output=True, text=True, env=env, timeout=1800)
        assert proc.returncode == 0, proc.stderr[-2000:]
        runs.append(json.loads(proc.stdout))
    assert runs[0]["hits"] == 0 and runs[1]["hits"] >= 1  # the second process loaded it
    assert runs[0]["etot"] == runs[1]["etot"]


def test_pieces_compiled_on_their_own_have_names_of_their_own():
    """numba names a compiled function by module, name, argument types and a per-process count,
    and a kernel loaded from the disk cache brings its callees along: two different callees of one
    name compiled in two processes could share a symbol, and a process loading both kernels would
    link both to one. So the cut-off closures of every style and mode, and the per-scene pieces
    compiled on their own (not inlined), have distinct names."""
    from wallbatch.engine import compiled as fast

    if fast.njit is None:
        pytest.skip("numba not importable")
    names = [d.py_func.__qualname__ for d in (*fast.MODE_FORCES.values(), *fast.MODE_ENERGIES.values())]
    assert len(set(names)) == len(names)
    lj93, morse = fast.STYLE_IDS["lj93"], fast.STYLE_IDS["morse"]
    a = fast.pieces_for(((lj93, 0),), region=((lj93, 0),))
    b = fast.pieces_for(((morse, 0),), region=((morse, 0),))
    for piece in ("sample_faces", "sample_regions", "region_walls"):
        assert getattr(a, piece).py_func.__qualname__ != getattr(b, piece).py_func.__qualname__, piece


TWO_SCENES = """
import json, os, sys
import numpy as np
sys.path[:0] = [os.path.join({tests!r}), os.path.join({tests!r}, "engine")]
import test_compiled_samples as T
from factories import run_numpy_and_compiled
from wallbatch.config.models import config_from_dict
from wallbatch.scene.build import build_case

class Env:
    def setenv(self, key, value):
        os.environ[key] = value

out = []
for name in sys.argv[1].split(","):
    make, key, values = {{"lj93": (T.lj93, "epsilon", [0.5, 1.0]), "morse": (T.morse, "D0", [0.3, 1.0])}}[name]
    ref, got, eng = run_numpy_and_compiled(Env(), [build_case(config_from_dict(d)) for d in T.swept(make, key, values)])
    diff = max(float(np.max(np.abs(a.data[v] - b.data[v]))) for a, b in zip(ref, got)
               for v in ("wall_energy", "wall_force", "ke"))
    out.append({{"scene": name, "diff": diff, "hits": sum(eng.fast.kernel.stats.cache_hits.values())}})
print(json.dumps(out))
"""


@pytest.mark.slow
def test_kernels_compiled_in_two_processes_load_together(tmp_path):
    """Regression: the lj93 and morse scene kernels, each compiled in a process of its own, then
    both loaded from the disk cache by a third: the morse kernel's sampled energies were NaN (it
    called the lj93 kernel's `_sample_faces`, compiled under the same symbol)."""
    tests = str(Path(__file__).resolve().parents[1])
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path), "PYTHONPATH": str(Path(tests).parent / "src")}
    script = TWO_SCENES.format(tests=tests)
    runs = []
    for scenes in ("lj93", "morse", "lj93,morse"):
        proc = subprocess.run([sys.executable, "-c", script, scenes], capture_output=True, text=True, env=env,
                              timeout=1800)
        assert proc.returncode == 0, proc.stderr[-2000:]
        runs.append(json.loads(proc.stdout.strip().splitlines()[-1]))
    both = runs[2]
    assert [r["hits"] for r in both] == [1, 1]  # both loaded from the disk cache
    assert both[0]["diff"] == 0.0
    assert both[1]["diff"] < 1e-12  # morse: exp/expm1 of NumPy and of the C library (not NaN)
