"""Start-up: lazy imports and per-scene compiled kernels (engine/compiled.py `kernel_for`)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from wallbatch.engine import compiled as fast

SRC = str(Path(__file__).resolve().parents[2] / "src")
HEAVY = ("dask", "distributed", "scipy.spatial", "scipy.special", "matplotlib")


@pytest.mark.slow
def test_import_pulls_in_no_heavy_optional_module():
    """`import wallbatch` and the engine load none of dask, distributed, scipy.spatial,
    scipy.special, matplotlib (each costs 0.2-0.5 s of start-up; they are imported where used)."""
    code = ("import sys, wallbatch, wallbatch.engine.engine, wallbatch.cli\n"
            f"print(','.join(m for m in {HEAVY!r} if m in sys.modules))")
    env = dict(os.environ, PYTHONPATH=SRC)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, check=True)
    assert out.stdout.strip() == ""


def test_dispatch_has_only_the_scene_branches():
    """The generated dispatch of a scene holds one branch per (style, cut-off mode) it uses, not
    every registered style x mode (each branch is a loop to compile)."""
    lj93, harm = fast.STYLE_IDS["lj93"], fast.STYLE_IDS["harmonic"]
    src = fast._dispatch_source(((lj93, 0),))
    assert src.count("return _face(") == 1 and f"_FORCE_{lj93}_0" in src
    src = fast._dispatch_source(((lj93, 0), (harm, 1)), extra=1)
    assert src.count("return _face(") == 3 and f"_FORCE_{harm}_1" in src and "_EXTRA_0" in src
    assert fast._region_dispatch_source(((harm, 2),)).count("return _rface(") == 1


@pytest.mark.skipif(fast.njit is None, reason="numba not importable")
def test_scene_kernels_are_distinct_and_named_for_the_cache():
    """Different specialisations are different kernels with different cache names (one numba
    index file each); the same one is built once per process."""
    lj93, harm = fast.STYLE_IDS["lj93"], fast.STYLE_IDS["harmonic"]
    a = fast.kernel_for(((lj93, 0),))
    assert fast.kernel_for(((lj93, 0),)) is a
    b = fast.kernel_for(((harm, 0),))
    c = fast.kernel_for(((lj93, 0),), parallel=True)
    d = fast.kernel_for(((lj93, 0),), fixes=False, dtr=False)
    names = {k.py_func.__qualname__ for k in (a, b, c, d)}
    assert len(names) == 4 and all(n.startswith("_run_chunk_") for n in names)
    # a scene without `fixes:` and dt/reset links stubs in their place (a shorter first compile)
    assert d.py_func.__globals__["_fix_pre"] is fast._no_fix_pre
    assert a.py_func.__globals__["_fix_pre"] is fast._fix_pre


@pytest.mark.skipif(fast.njit is None, reason="numba not importable")
def test_compile_message_once(monkeypatch, capsys):
    """A kernel not in the on-disk cache is announced on stderr once per process."""
    kernel = fast.kernel_for(((fast.STYLE_IDS["lj93"], 0),))
    monkeypatch.setattr(fast, "_ANNOUNCED", set())
    monkeypatch.setattr(fast, "_cached_on_disk", lambda k: False)
    fast.announce_compile(kernel)
    fast.announce_compile(kernel)
    err = capsys.readouterr().err
    assert err.count("compiling kernels for this scene, once") == 1
    monkeypatch.setattr(fast, "_ANNOUNCED", set())
    monkeypatch.setattr(fast, "_cached_on_disk", lambda k: True)
    fast.announce_compile(kernel)
    assert "compiling" not in capsys.readouterr().err


@pytest.mark.skipif(fast.njit is None, reason="numba not importable")
@pytest.mark.parametrize("fixes", [False, True])
def test_pair_compile_message_counts_the_shared_pair_kernels_until_they_are_built(monkeypatch, fixes):
    """A pair scene's message: its chunk kernel's estimate (longer with thermostats), plus the
    list build and force pass every pair scene shares while neither compiled nor cached."""
    from types import SimpleNamespace

    from wallbatch.engine import pair_compiled as pc

    own = pc.PAIR_FIXES_SECONDS if fixes else pc.PAIR_COMPILE_SECONDS
    fresh = SimpleNamespace(signatures=[])
    monkeypatch.setattr(pc, "build_case", fresh)
    monkeypatch.setattr(pc, "forces_case", SimpleNamespace(signatures=["built"]))
    monkeypatch.setattr(fast, "_cached_on_disk", lambda k: False)
    assert pc.compile_estimate(fixes) == own + pc.PAIR_SHARED_SECONDS == (35 if fixes else 30)
    monkeypatch.setattr(fast, "_cached_on_disk", lambda k: k is fresh)  # on disk: loads, no compile
    assert pc.compile_estimate(fixes) == own
