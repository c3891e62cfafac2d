"""The compiled chunk kernel survives numba's disk cache: a second process loads it and runs."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

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
    """The lj93 and morse scene kernels, each compiled in a process of its own (no disk cache
    hit), then both loaded from the disk cache by a third, which runs them: the same results as
    the NumPy engine. Regressions: the morse kernel's sampled energies were NaN (it called the
    lj93 kernel's `_sample_faces`, compiled under the same symbol); and after the thermostats
    joined the chunk kernel, a kernel loaded from the disk cache referenced the recursive
    pairwise_sum (the kinetic sum of every sample) through an unresolved symbol and the loading
    process crashed (SIGSEGV / LLVM "Symbol not found"); thermostats.pairwise_sum is iterative now."""
    tests = str(Path(__file__).resolve().parents[1])
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path), "PYTHONPATH": str(Path(tests).parent / "src")}
    script = TWO_SCENES.format(tests=tests)

    def start(scenes: str) -> subprocess.Popen:
        return subprocess.Popen([sys.executable, "-c", script, scenes], stdout=subprocess.PIPE,
                                stderr=subprocess.PIPE, text=True, env=env)

    def answer(proc: subprocess.Popen) -> list:
        out, err = proc.communicate(timeout=1800)
        assert proc.returncode == 0, err[-2000:]
        return json.loads(out.strip().splitlines()[-1])

    # the two compiling processes run at once (two cores: the compiles overlap), the third after both
    first = [start("lj93"), start("morse")]
    alone = [answer(proc)[0] for proc in first]
    assert [r["hits"] for r in alone] == [0, 0]  # each compiled its kernel
    assert alone[0]["diff"] == 0.0 and alone[1]["diff"] < 1e-12
    both = answer(start("lj93,morse"))
    assert [r["hits"] for r in both] == [1, 1]  # both loaded from the disk cache
    assert both[0]["diff"] == 0.0
    assert both[1]["diff"] < 1e-12  # morse: exp/expm1 of NumPy and of the C library (not NaN)
