"""LAMMPS probes for wall fixes acting on many independent atoms (no pair forces).

`probe_wall` places atoms at given distances from one face of a box, runs ``run 0`` (forces
and the fix's energy and vector) or ``run 1`` under ``fix nve`` (positions and velocities after
one step) and returns float64 arrays ordered by atom. LAMMPS is used through its Python API only.
"""

from __future__ import annotations

import numpy as np

from lammps_oracle import _load_lammps

__all__ = ["probe_wall"]


def probe_wall(
    fix: str,
    r: np.ndarray,
    face: str = "zlo",
    v: np.ndarray | None = None,
    steps: int = 0,
    dt: float = 0.005,
    units: str = "lj",
    mass: float = 1.0,
    half: float = 5.0,
    extra: tuple[str, ...] = (),
) -> dict[str, np.ndarray | float]:
    """Atoms at distances r from ``face`` (a box [-half, half] along the face's axis, periodic
    otherwise); ``fix`` is the text after ``fix w all``. Returns energy (the fix's scalar),
    vector (its 3 components, or fewer), f, x, v (N, 3)."""
    lammps = _load_lammps()
    r = np.asarray(r, dtype=np.float64)
    n = r.size
    dim = "xyz".index(face[0])
    lo = face[1:] == "lo"
    lmp = lammps.lammps(cmdargs=["-log", "none", "-screen", "none", "-nocite"])
    try:
        bnd = ["p", "p", "p"]
        bnd[dim] = "f"
        ext = [(0.0, float(max(n, 1))), (0.0, 10.0), (0.0, 10.0)]
        ext[dim] = (-half, half)
        other = [d for d in range(3) if d != dim]
        for cmd in [
            f"units {units}", "atom_style atomic", "atom_modify map array",
            f"boundary {' '.join(bnd)}",
            "region b block " + " ".join(f"{a!r} {b!r}" for a, b in ext),
            "create_box 1 b", f"mass 1 {mass!r}", f"timestep {dt!r}", *extra,
        ]:  # fmt: skip
            lmp.command(cmd)
        x = np.zeros((n, 3))
        x[:, other[0]] = np.arange(n) + 0.5
        x[:, other[1]] = 5.0
        x[:, dim] = -half + r if lo else half - r
        vel = np.zeros((n, 3)) if v is None else np.broadcast_to(np.asarray(v, float), (n, 3)).copy()
        lmp.create_atoms(n, None, [1] * n, x.ravel().tolist(), vel.ravel().tolist())
        if steps:
            lmp.command("fix nve all nve")
        lmp.command(f"fix w all {fix}")
        if "reflect" not in fix.split()[0]:
            lmp.command("fix_modify w energy yes")
        lmp.command(f"run {steps}")
        ids = lmp.numpy.extract_atom("id")[:n].copy()
        order = np.argsort(ids)
        out: dict[str, np.ndarray | float] = {
            "f": lmp.numpy.extract_atom("f")[:n].copy()[order],
            "x": lmp.numpy.extract_atom("x")[:n].copy()[order],
            "v": lmp.numpy.extract_atom("v")[:n].copy()[order],
        }
        try:
            out["energy"] = float(lmp.extract_fix("w", 0, 0))
            out["vector"] = np.array([lmp.extract_fix("w", 0, 1, i) for i in range(1)])
        except Exception:  # noqa: BLE001 - fixes without a scalar (reflect/stochastic)
            pass
        return out
    finally:
        lmp.close()
