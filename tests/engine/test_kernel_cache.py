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
