"""LAMMPS `compute chunk/atom bin/1d` + `fix ave/chunk` as an oracle for wallbatch profiles.

`chunk_fixes` writes the two commands for a profile (LAMMPS defaults otherwise: norm all,
ave one, discard mixed, adof = dimension, cdof 0); `read_ave_chunk` parses the file fix
ave/chunk writes (format "%.17g", so every value round-trips a double) into
{step: {column: (nbins,) array}}. LAMMPS is used through its Python API (tests/lammps_oracle.py),
never copied.
"""

from __future__ import annotations

import numpy as np


def chunk_fixes(name: str, group: str, axis: str, every: int, repeat: int, freq: int, quantities: list[str],
                path: str, delta: float | None = None, bins: int | None = None) -> list[str]:
    """The LAMMPS lines of one profile: bins of `delta` (box units) or `bins` equal bins (reduced)."""
    if delta is not None:
        binning = f"bin/1d {axis} lower {delta!r} units box"
    else:
        binning = f"bin/1d {axis} lower {1.0 / bins!r} units reduced"
    return [f"compute cc_{name} {group} chunk/atom {binning}",
            f"fix ac_{name} {group} ave/chunk {every} {repeat} {freq} cc_{name} {' '.join(quantities)} "
            f"norm all file {path} format \" %.17g\""]


def read_ave_chunk(path: str) -> dict[int, dict[str, np.ndarray]]:
    """Windows of a fix ave/chunk file: step -> column name (Coord1, Ncount, quantities) -> values."""
    with open(path, encoding="utf-8") as fh:
        lines = fh.read().splitlines()
    header = [ln for ln in lines if ln.startswith("# Chunk ")][0].split()[1:]  # Chunk Coord1 Ncount ...
    out: dict[int, dict[str, np.ndarray]] = {}
    body = [ln.split() for ln in lines if ln and not ln.startswith("#")]
    i = 0
    while i < len(body):
        step, nchunk = int(body[i][0]), int(body[i][1])
        rows = np.array([[float(t) for t in r] for r in body[i + 1:i + 1 + nchunk]])
        out[step] = {col: rows[:, j] for j, col in enumerate(header)}
        i += 1 + nchunk
    return out
