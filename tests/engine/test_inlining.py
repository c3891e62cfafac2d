"""numba's IR inlining as wallbatch's processes run it (engine/backend.py `_cheap_ir_copies`):
the blocks of one copy of an inlined function share one copy of its variable table (Scope), where
numba's own inliner copies the whole table once per block, and a copied Loc shares its cached
source lines; the compiled functions are the same."""

from __future__ import annotations

import copy

import numpy as np
import pytest

numba = pytest.importorskip("numba")
from numba.core import inline_closurecall as icc  # noqa: E402
from numba.core import ir  # noqa: E402

from wallbatch.engine import backend  # noqa: E402


def _piece(x, n):  # noqa: ANN001, ANN202 - inlined below: several blocks (a loop and branches)
    acc = 0.0
    for i in range(n):
        if x[i] > 0.5:
            acc += x[i] * x[i]
        elif x[i] < -0.5:
            acc -= 2.0 * x[i]
        else:
            acc += np.sin(x[i])
    return acc


class _Lines(list):
    """A Loc's cached source lines (what a Loc holds once it has printed itself) that counts its
    deep copies."""

    copies = 0

    def __deepcopy__(self, memo):  # noqa: ANN001, ANN204
        type(self).copies += 1
        return _Lines(self)


def _compile_and_count(monkeypatch: pytest.MonkeyPatch) -> tuple[int, int, float, int]:
    """Compile a kernel that inlines `_piece` twice, every Loc holding its source lines, counting
    the Scope copies made while inlining and the blocks of `_piece`'s IR: (scope copies, blocks per
    copy, the kernel's value, copies of source lines)."""
    copies = []
    lines = _Lines(["    acc = 0.0\n"] * 50)
    _Lines.copies = 0
    loc_init = ir.Loc.__init__

    def init(self, *args, **kwargs):  # noqa: ANN001, ANN002, ANN003, ANN202
        loc_init(self, *args, **kwargs)
        self.lines = lines

    monkeypatch.setattr(ir.Loc, "__init__", init)

    def counted(self, memo):  # noqa: ANN001, ANN202 - copy's protocol; copies as deepcopy does
        copies.append(id(self))
        new = ir.Scope.__new__(ir.Scope)
        memo[id(self)] = new
        new.__dict__.update(copy.deepcopy(self.__dict__, memo))
        return new

    monkeypatch.setattr(ir.Scope, "__deepcopy__", counted, raising=False)
    piece = numba.njit(inline="always")(_piece)

    def kernel(x, n):  # noqa: ANN001, ANN202
        return piece(x, n) + piece(x[::-1], n)

    x = np.linspace(-1.0, 1.0, 17)
    value = numba.njit(kernel)(x, x.shape[0])
    blocks = len(numba.core.compiler.run_frontend(_piece).blocks)
    return len(copies), blocks, value, _Lines.copies


@pytest.mark.slow
def test_inlining_copies_the_scope_once_per_copy_and_compiles_the_same_function(monkeypatch):
    """Two inlines, each copying the callee's IR twice: with the shared-scope inliner each copy
    copies each Scope object of the IR once (at most two: numba's passes may leave an equal second
    one), at most 8 in all, and no Loc's source lines, against at least one Scope per block and
    copy (4 x blocks) and the lines with every Loc with numba's own, which the test also runs (so
    it fails if either is not in place). Both kernels give the Python value."""
    assert backend._cheap_ir_copies()
    x = np.linspace(-1.0, 1.0, 17)
    expected = _piece(x, 17) + _piece(x[::-1], 17)
    shared, blocks, value, lines = _compile_and_count(monkeypatch)
    assert blocks >= 6
    assert shared <= 8
    assert lines == 0
    assert value == pytest.approx(expected, rel=1e-15)
    monkeypatch.setattr(icc.InlineWorker, "inline_ir", icc.InlineWorker.inline_ir.__wrapped__)
    monkeypatch.delattr(ir.Loc, "__deepcopy__")
    own, blocks_own, value_own, lines_own = _compile_and_count(monkeypatch)
    assert own >= 4 * blocks > shared
    assert lines_own > 4 * blocks
    assert value_own == value


def test_installing_twice_or_on_another_layout_changes_nothing(monkeypatch):
    """Installed once (a second call finds it); an inliner without `inline_ir` is left alone."""
    assert backend._cheap_ir_copies()
    installed = icc.InlineWorker.inline_ir
    assert backend._cheap_ir_copies() and icc.InlineWorker.inline_ir is installed
    monkeypatch.setattr(icc, "InlineWorker", type("InlineWorker", (), {}))
    assert not backend._cheap_ir_copies()
    assert not hasattr(icc.InlineWorker, "inline_ir")
