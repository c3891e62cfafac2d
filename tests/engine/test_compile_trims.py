"""What a scene kernel's compile leaves out (engine/backend.py `_plain_error_text`,
engine/compiled.py `_style_functions`): numba's messages for the overloads it rejects while typing
are formatted without colorama wrapping stdout and stderr anew for each piece, and the kernels link
the registry's forces and energies without a CPython entry point of their own; the numbers are
the same."""

from __future__ import annotations

import os
import subprocess
import sys

import numpy as np
import pytest

numba = pytest.importorskip("numba")
from numba.core import errors  # noqa: E402

from wallbatch.engine import backend  # noqa: E402
from wallbatch.engine import compiled as fast  # noqa: E402


def _colorama_setups(scheme: object, monkeypatch: pytest.MonkeyPatch) -> tuple[int, list[str]]:
    """How often numba's colour shell sets colorama up (init, reinit) while `scheme` formats one
    piece of each kind, and the pieces."""
    calls = []
    for name in ("init", "reinit"):
        real = getattr(errors, name, None)
        if real is not None:
            monkeypatch.setattr(errors, name, lambda *a, _real=real, **k: (calls.append(1), _real(*a, **k))[1])
    texts = [scheme.code("a"), scheme.errmsg("b"), scheme.filename("c"), scheme.indicate("d"),
             scheme.highlight("e")]
    monkeypatch.undo()
    return len(calls), texts


def test_rejected_overload_messages_plain(monkeypatch: pytest.MonkeyPatch) -> None:
    if not hasattr(errors, "HighlightColorScheme"):
        pytest.skip("numba without colorama: its messages are plain already")
    backend.prepare_numba()
    assert backend._plain_error_text()  # installed (or already) in a process that compiles
    n, texts = _colorama_setups(errors.termcolor(), monkeypatch)
    assert n == 0 and texts == ["a", "b", "c", "d", "e"]  # the text itself, no escape codes
    own = errors.HighlightColorScheme()  # numba's own scheme: colorama set up for every piece
    n_own, texts_own = _colorama_setups(own, monkeypatch)
    assert n_own >= 5 and all("\x1b[" in t for t in texts_own)


@pytest.mark.slow
def test_user_colour_scheme_left_alone() -> None:
    """NUMBA_COLOR_SCHEME set: wallbatch keeps numba's scheme as it is."""
    code = ("import numba.core.errors as e; from wallbatch.engine import backend;"
            "print(backend._plain_error_text(), '\\x1b[' in e.termcolor().errmsg('x'))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True,
                         env={**os.environ, "NUMBA_COLOR_SCHEME": "dark_bg"})
    assert out.stdout.split() == ["False", "True"]


@pytest.mark.slow
def test_kernel_forces_twins_give_the_same_numbers() -> None:
    """The kernels' force and energy functions (no CPython entry point, names ending in _k) are
    the same closures of styles.cutoff around the same registry functions as the Python-callable
    ones, and give their numbers: lj93 under each cut-off mode, through a jitted caller."""
    from numba import njit

    for table, twins in ((fast.MODE_FORCES, fast._K_MODE_FORCES), (fast.MODE_ENERGIES, fast._K_MODE_ENERGIES)):
        assert set(table) == set(twins) and table
        for key, public in table.items():
            twin = twins[key]
            assert twin.py_func.__code__ is public.py_func.__code__
            assert twin.py_func.__qualname__ == public.py_func.__qualname__ + "_k"
            assert twin.targetoptions.get("no_cpython_wrapper") and not public.targetoptions.get("no_cpython_wrapper")
    r = np.linspace(0.3, 2.9, 37)
    lj93 = fast.STYLE_IDS["lj93"]
    for table, twins in ((fast.MODE_FORCES, fast._K_MODE_FORCES), (fast.MODE_ENERGIES, fast._K_MODE_ENERGIES)):
        for (i, m), public in table.items():
            if i != lj93:
                continue
            twin = twins[(i, m)]

            @njit
            def call(r, f=twin):  # noqa: ANN001, ANN202
                out = np.empty_like(r)
                for k in range(r.size):
                    out[k] = f(r[k], 1.5, 1.1, 0.0, 2.5, 0.0, 2.0)
                return out

            want = np.array([public(float(x), 1.5, 1.1, 0.0, 2.5, 0.0, 2.0) for x in r])
            assert np.array_equal(call(r), want), (i, m)
            assert np.count_nonzero(want) > 20  # inside the cut-off: real numbers compared


KERNEL_MODULES = ("compiled", "pair_compiled", "asphere_compiled", "flow_compiled")


def _array_slice_copies(source: str, module: str) -> list[str]:
    """The statements `a[...] = <not a number>` (a slice or Ellipsis in the index) under the
    `if njit is not None:` blocks of a module's source, where its numba kernels live."""
    import ast

    tree = ast.parse(source)
    blocks = [n for n in tree.body if isinstance(n, ast.If) and "njit" in ast.unparse(n.test)]
    found = []
    for block in blocks:
        for node in ast.walk(block):
            if not isinstance(node, (ast.Assign, ast.AugAssign)):
                continue
            number = isinstance(node.value, ast.Constant) or (
                isinstance(node.value, ast.UnaryOp) and isinstance(node.value.operand, ast.Constant))
            for target in node.targets if isinstance(node, ast.Assign) else [node.target]:
                index = target.slice if isinstance(target, ast.Subscript) else None
                parts = index.elts if isinstance(index, ast.Tuple) else [index]
                if index is not None and not number and any(
                        isinstance(p, ast.Slice) or (isinstance(p, ast.Constant) and p.value is Ellipsis)
                        for p in parts):
                    found.append(f"{module}.py:{node.lineno}: {ast.unparse(node)}")
    return found


@pytest.mark.slow
@pytest.mark.parametrize("module", KERNEL_MODULES)
def test_kernels_copy_arrays_in_loops_not_slice_assignments(module):
    """numba compiles an array-to-array slice assignment (`a[:] = b`) with its shape-mismatch
    message (str, repr, join: ~6 s of a pair scene's first compile before `pair_compiled._copy_atoms`);
    the kernels copy arrays in plain loops (`_copy_atoms`, `compiled._copy3`) and fill with numbers."""
    from pathlib import Path

    import wallbatch.engine as engine

    assert _array_slice_copies((Path(engine.__file__).parent / f"{module}.py").read_text(), module) == []


def test_the_slice_copy_scan_finds_them():
    """The scan sees array slice assignments under the block, not fills with numbers, element
    assignments or code outside it (so the test above can fail)."""
    src = ("if njit is not None:\n    def k(a, b):\n        a[:] = b\n        a[:] = 0.0\n        a[:] = -1.0\n"
           "        a[..., 0] = b[0]\n        a[1, 0] = b[0]\n        a[:, 1] += b\n\n"
           "def python_side(a, b):\n    a[:] = b\n")
    assert _array_slice_copies(src, "m") == ["m.py:3: a[:] = b", "m.py:6: a[..., 0] = b[0]", "m.py:8: a[:, 1] += b"]
