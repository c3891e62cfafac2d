"""Per-atom trajectories in the AMBER NetCDF convention, version 1.0 (docs/reference/outputs.md,
"Per-atom trajectories").

One file per case, NetCDF-3 64-bit offset (as MDAnalysis requires), readable by MDAnalysis
(`NCDFReader`), VMD and OVITO. The convention fixes the units: coordinates and cell lengths in
angstrom, time in picosecond, velocities in angstrom/picosecond. `real` (Angstrom, fs) and
`metal` (Angstrom, ps) runs are converted; `lj` runs are written in reduced units as they are and
say so in the global attribute `wallbatch_units`.
"""

from __future__ import annotations

import os
import uuid
from pathlib import Path

import netCDF4
import numpy as np

from wallbatch.version import __version__

CONVENTION = "AMBER"
CONVENTION_VERSION = "1.0"

LJ_NOTE = "lj (reduced: sigma, tau); the convention's angstrom/picosecond labels do not apply"

# units -> (time factor to ps, velocity factor to Angstrom/ps, wallbatch_units text)
_CONVERSIONS: dict[str, tuple[float, float, str]] = {
    "real": (1.0e-3, 1.0e3,
             "real: converted from Angstrom, fs, Angstrom/fs to angstrom, picosecond "
             "(time / 1000), angstrom/picosecond (velocities * 1000)"),
    "metal": (1.0, 1.0,
              "metal: Angstrom, ps, Angstrom/ps are the convention's angstrom, picosecond, "
              "angstrom/picosecond; values written unchanged"),
    "lj": (1.0, 1.0, LJ_NOTE),
}


def _chars(text: str, width: int) -> np.ndarray:
    """A fixed-width char (S1) array of `text`, space padded."""
    return np.array(list(text.ljust(width)[:width]), dtype="S1")


def _frames(name: str, a: np.ndarray | None, nframes: int) -> np.ndarray | None:
    if a is None:
        return None
    a = np.asarray(a, dtype=float)
    if a.ndim != 3 or a.shape[0] != nframes or a.shape[2] != 3:
        raise ValueError(f"{name} must have shape (frames={nframes}, atoms, 3), got {a.shape}")
    return a


def _box(name: str, a: np.ndarray, nframes: int) -> np.ndarray:
    a = np.asarray(a, dtype=float)
    if a.shape == (3,):
        return np.broadcast_to(a, (nframes, 3))
    if a.shape == (nframes, 3):
        return a
    raise ValueError(f"{name} must have shape (3,) or ({nframes}, 3), got {a.shape}")


def write_amber(path: str | Path, time: np.ndarray, x: np.ndarray | None, v: np.ndarray | None,
                box_lo: np.ndarray, box_hi: np.ndarray, units: str, title: str = "wallbatch") -> Path:
    """Write one case's frames. time (F,) in the run's time units; x, v (F, N, 3) in the run's
    distance and velocity units (either may be None if not dumped). units: 'lj' | 'real' | 'metal'.
    box_lo, box_hi: (3,) for a fixed box or (F, 3) per frame. Positions are written as given.
    Writes atomically (temporary file renamed into place). Returns the path."""
    if units not in _CONVERSIONS:
        raise ValueError(f"units must be one of {sorted(_CONVERSIONS)}, got {units!r}")
    t_factor, v_factor, note = _CONVERSIONS[units]
    path = Path(path)

    time = np.asarray(time, dtype=float)
    if time.ndim != 1:
        raise ValueError(f"time must have shape (frames,), got {time.shape}")
    nframes = time.shape[0]
    x = _frames("x", x, nframes)
    v = _frames("v", v, nframes)
    if x is None and v is None:
        raise ValueError("nothing to write: both x and v are None")
    if x is not None and v is not None and x.shape != v.shape:
        raise ValueError(f"x {x.shape} and v {v.shape} differ in shape")
    natoms = (x if x is not None else v).shape[1]
    lengths = _box("box_hi", box_hi, nframes) - _box("box_lo", box_lo, nframes)

    path.parent.mkdir(parents=True, exist_ok=True)
    # a unique sibling name (same filesystem, so the rename is atomic; default permissions)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.{uuid.uuid4().hex}.tmp")
    try:
        with netCDF4.Dataset(tmp, "w", clobber=True, format="NETCDF3_64BIT_OFFSET") as nc:
            nc.set_auto_maskandscale(False)
            nc.Conventions = CONVENTION
            nc.ConventionVersion = CONVENTION_VERSION
            nc.program = "wallbatch"
            nc.programVersion = str(__version__)
            nc.title = title
            nc.wallbatch_units = note

            nc.createDimension("frame", None)
            nc.createDimension("atom", natoms)
            nc.createDimension("spatial", 3)
            nc.createDimension("cell_spatial", 3)
            nc.createDimension("cell_angular", 3)
            nc.createDimension("label", 5)

            var = nc.createVariable("spatial", "S1", ("spatial",))
            var[:] = _chars("xyz", 3)
            var = nc.createVariable("cell_spatial", "S1", ("cell_spatial",))
            var[:] = _chars("abc", 3)
            var = nc.createVariable("cell_angular", "S1", ("cell_angular", "label"))
            var[:] = np.stack([_chars(s, 5) for s in ("alpha", "beta", "gamma")])

            t_var = nc.createVariable("time", "f4", ("frame",))
            t_var.units = "picosecond"
            if x is not None:
                x_var = nc.createVariable("coordinates", "f4", ("frame", "atom", "spatial"))
                x_var.units = "angstrom"
            if v is not None:
                v_var = nc.createVariable("velocities", "f4", ("frame", "atom", "spatial"))
                v_var.units = "angstrom/picosecond"
                v_var.scale_factor = 1.0
                v_var.set_auto_maskandscale(False)
            cl_var = nc.createVariable("cell_lengths", "f8", ("frame", "cell_spatial"))
            cl_var.units = "angstrom"
            ca_var = nc.createVariable("cell_angles", "f8", ("frame", "cell_angular"))
            ca_var.units = "degree"

            if nframes:
                t_var[:] = (time * t_factor).astype(np.float32)
                if x is not None:
                    x_var[:] = x.astype(np.float32)
                if v is not None:
                    v_var[:] = (v * v_factor).astype(np.float32)
                cl_var[:] = lengths
                ca_var[:] = np.full((nframes, 3), 90.0)
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    return path
