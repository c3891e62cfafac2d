"""Scalar helpers of the compiled kernels, written once as plain Python (numba compiles them where
they are used: engine/compiled.py, engine/flow_compiled.py): np.minimum / np.maximum of two floats,
NaN propagating, without building an array."""

from __future__ import annotations


def nmin(a: float, b: float) -> float:
    """np.minimum for two scalars (NaN propagates)."""
    if a != a:
        return a
    if b != b:
        return b
    return a if a <= b else b


def nmax(a: float, b: float) -> float:
    """np.maximum for two scalars (NaN propagates)."""
    if a != a:
        return a
    if b != b:
        return b
    return a if a >= b else b
