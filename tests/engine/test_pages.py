"""pages.empty: large work arrays in their own mapping of 4 kB pages (huge pages declined)."""

from __future__ import annotations

import mmap
import sys

import numpy as np
import pytest

from wallbatch.engine import pages, pair_compiled


def _vm_flags(a: np.ndarray) -> set[str]:
    """The VmFlags of the mapping holding a's middle byte (/proc/self/smaps; NumPy advises huge
    pages from the first 2 MB boundary in an array on)."""
    addr = a.ctypes.data + a.nbytes // 2
    inside = False
    with open("/proc/self/smaps") as fh:
        for line in fh:
            head = line.split()[0]
            if "-" in head and ":" not in head:
                lo, hi = (int(t, 16) for t in head.split("-"))
                inside = lo <= addr < hi
            elif inside and line.startswith("VmFlags:"):
                return set(line.split()[1:])
    raise AssertionError("mapping not found")


@pytest.mark.parametrize("shape, dtype", [((3, 700_000), np.int32), (2_000_000, np.float64),
                                          ((600_000, 3), np.float64)])
def test_large_arrays_are_writable_contiguous_and_their_own(shape, dtype):
    a, b = pages.empty(shape, dtype), pages.empty(shape, dtype)
    assert a.shape == (shape if isinstance(shape, tuple) else (shape,)) and a.dtype == np.dtype(dtype)
    assert a.flags.c_contiguous and a.flags.writeable and a.nbytes >= pages.SMALL_BYTES
    a[...] = 1
    b[...] = 2
    assert a.sum() == a.size and b.sum() == 2 * b.size  # two arrays, two mappings


def test_small_arrays_are_plain_numpy():
    a = pages.empty((10, 3), np.float64)
    assert a.shape == (10, 3) and a.flags.owndata and a.flags.writeable


@pytest.mark.skipif(not sys.platform.startswith("linux") or not hasattr(mmap, "MADV_NOHUGEPAGE"),
                    reason="Linux's madvise flags")
def test_large_arrays_decline_huge_pages():
    """The kernel shows MADV_NOHUGEPAGE as VmFlags 'nh' (MADV_HUGEPAGE as 'hg': NumPy's own large
    arrays, where it advises them)."""
    a = pages.empty(3_000_000, np.int32)
    a[:] = 0
    assert "nh" in _vm_flags(a) and "hg" not in _vm_flags(a)
    if getattr(np._core.multiarray, "_get_madvise_hugepage", lambda: False)():
        plain = np.empty(3_000_000, np.int32)
        assert "hg" in _vm_flags(plain) and "nh" not in _vm_flags(plain)


@pytest.mark.skipif(not sys.platform.startswith("linux") or not hasattr(mmap, "MADV_NOHUGEPAGE"),
                    reason="Linux's madvise flags")
def test_threaded_pass_work_arrays_come_in_small_pages():
    """A Workspace's kept arrays (the threaded build's `aside`, the split's logs) and a fresh
    default buffer: large ones from pages.empty."""
    ws = pair_compiled.Workspace()
    kept = ws.buffer("aside", (2_000_000,), np.int32)
    assert ws.buffer("aside", (2_000_000,), np.int32) is kept  # kept while the shape holds
    assert "nh" in _vm_flags(kept)
    assert "nh" in _vm_flags(pair_compiled._fresh("x", (1_500_000,), np.float64))
