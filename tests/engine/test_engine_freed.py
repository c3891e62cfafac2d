"""A finished engine is freed as soon as it is dropped (reference counting), not at Python's next
full garbage collection: its compiled path keeps the engine's plan callback weakly. A reference
cycle engine <-> path held a sweep window's cases and state arrays as garbage (up to a window's
memory), for as long as the collector's timing chose (tests/batch/test_memory.py)."""

from __future__ import annotations

import gc
import weakref

import pytest

from wallbatch.engine import compiled
from wallbatch.engine.engine import Engine

SCENE = {"seed": 3, "box": {"lo": [0, 0, 0], "hi": [6, 6, 10], "boundary": ["p", "p", "f"]},
         "atoms": [{"group": "a", "create": {"random": {"count": 50, "region": "mid"}}, "mass": 1.0,
                    "velocity": {"temperature": 1.0}}],
         "regions": {"mid": {"style": "block", "lo": [0, 0, 1.0], "hi": [6, 6, 8.5], "units": "box"}},
         "walls": {"w": {"style": "lj93", "units": "box",
                         "zlo": {"coord": "EDGE", "epsilon": 1.0, "sigma": 1.0, "cutoff": 2.5},
                         "zhi": {"coord": 9.9, "epsilon": 1.0, "sigma": 1.0, "cutoff": 2.5}}},
         "timestep": 0.005, "run": {"steps": 40, "thermo": 20}}


@pytest.mark.skipif(compiled.njit is None, reason="numba not importable")
def test_a_finished_compiled_engine_is_freed_without_the_collector(case_of, monkeypatch):
    monkeypatch.setenv("WALLBATCH_NUMBA", "1")
    engine = Engine([case_of(SCENE)])
    assert engine.fast is not None  # the compiled path, which keeps the plan callback
    res = engine.run()[0]
    assert res.status == "ok" and engine.fast.compiled_chunks > 0
    gone = weakref.ref(engine)
    was = gc.isenabled()
    gc.disable()
    try:
        del engine
        assert gone() is None  # freed by reference counting alone
    finally:
        if was:
            gc.enable()
