"""Large work arrays in small memory pages.

NumPy asks Linux for transparent huge pages (madvise MADV_HUGEPAGE) on every array of 4 MB or
more. On a machine whose huge pages are granted on request (`/sys/kernel/mm/transparent_hugepage`
`enabled` and `defrag` = madvise, the common default), the first touch of such an array can wait
for the kernel to free and zero a 2 MB page, and two threads touching one array at once wait for
each other: measured here, the first write of a fresh 32 MB array took 33-68 ms on one thread
and 52 ms on two (6 ms once mapped), against 17 ms and 9 ms in 4 kB pages. The neighbor lists and
the threaded pair pass's work arrays are written once per build, front to back (or part by part,
each thread its own range), so huge pages buy them little and cost them most on their first
build: they come from `empty`, which maps them in 4 kB pages.
"""

from __future__ import annotations

import mmap
from typing import Any

import numpy as np

SMALL_BYTES = 4 << 20  # below this NumPy maps an array as any other allocation: np.empty


def empty(shape: int | tuple, dtype: Any) -> np.ndarray:
    """An uninitialised C-contiguous array of `shape`, `dtype`; from SMALL_BYTES on, in its own
    anonymous mapping of 4 kB pages (huge pages declined: MADV_NOHUGEPAGE where Linux has it),
    faulted in on first touch by whichever thread writes there. Freed with the array."""
    dt = np.dtype(dtype)
    shape = (shape,) if isinstance(shape, (int, np.integer)) else tuple(int(s) for s in shape)
    count = int(np.prod(shape, dtype=np.int64))
    nbytes = count * dt.itemsize
    if nbytes < SMALL_BYTES:
        return np.empty(shape, dt)
    buf = mmap.mmap(-1, nbytes)
    advice = getattr(mmap, "MADV_NOHUGEPAGE", None)
    if advice is not None:
        try:
            buf.madvise(advice)
        except OSError:  # (a kernel without transparent huge pages)
            pass
    return np.frombuffer(buf, dt, count).reshape(shape)
