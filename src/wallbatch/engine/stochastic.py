"""Thermal walls (LAMMPS ``fix wall/reflect/stochastic diffusive|maxwell|ccl``): velocity sampling.

An atom found behind the wall after the drift has crossed it a time t = d / |v_n| ago (d: how
far behind, v_n: its normal velocity). It leaves the wall with a new velocity v' drawn from the
wall's rule and is placed where it would be had it left the wall at the crossing with v':
x_n = coord + v'_n t, x_t += (v'_t - v_t) t (pinned against LAMMPS). With sigma = sqrt(kB T /
(m mvv2e)) [velocity] the thermal speed of the atom's mass at the wall temperature T and u the
wall's (tangential) velocity:

* ``diffusive``: v'_n = sigma sqrt(-2 ln U) away from the wall (the flux-weighted, Rayleigh
  distribution), v'_t = u_t + sigma N(0, 1) for both tangential components;
* ``maxwell`` with accommodation a: with probability a diffusive, otherwise specular
  (v'_n = -v_n, v'_t = v_t);
* ``ccl`` (Cercignani-Lampis, Lord's sampling) with tangential velocity accommodations a_t and
  normal kinetic-energy accommodation a_n: v'_t = u_t + (1 - a_t)(v_t - u_t) +
  sigma sqrt(a_t (2 - a_t)) N(0, 1); in units of sqrt(2) sigma the normal speed is
  w' = sqrt(rho^2 + m^2 + 2 rho m cos(theta)), rho = sqrt(-a_n ln U1), theta = 2 pi U2,
  m = sqrt(1 - a_n) |v_n| / (sqrt(2) sigma).

Random numbers come from one ``numpy.random.Generator`` per case and wall (as for flow walls);
per call the draws are, for the K reflected atoms in atom order: ``diffusive`` U (K,), N (K, 2);
``maxwell`` the choice (K,), then U (K,), N (K, 2) for every atom (so the count does not depend
on the choice); ``ccl`` U1 (K,), U2 (K,), N (K, 2). Uniforms are taken as 1 - random() in (0, 1].
"""

from __future__ import annotations

import math

import numpy as np

from wallbatch.engine.state import FaceValues

__all__ = ["RSTYLES", "StochasticKernel", "reflect_velocities", "reflect_positions", "thermal_sigma"]

RSTYLES = ("diffusive", "maxwell", "ccl")


def thermal_sigma(temp: float | np.ndarray, mass: np.ndarray, boltz: float, mvv2e: float) -> np.ndarray:
    """sqrt(kB T / (m mvv2e)) [velocity]: the standard deviation of one velocity component."""
    return np.sqrt(boltz * np.asarray(temp, dtype=np.float64) / (np.asarray(mass, dtype=np.float64) * mvv2e))


def reflect_velocities(
    rstyle: str,
    rng: np.random.Generator,
    v: np.ndarray,
    dim: int,
    side: int,
    sigma: np.ndarray,
    wall_velocity: np.ndarray,
    accom: np.ndarray | float | None = None,
) -> np.ndarray:
    """New velocities (K, 3) [velocity] for K atoms with velocities ``v`` (K, 3) hitting a wall
    normal to axis ``dim`` on side ``side`` (-1 lo face: atoms leave towards +; +1 hi face).

    sigma (K,) [velocity] from :func:`thermal_sigma`; wall_velocity (3,) (its normal component
    is ignored); accom: None (diffusive), a number (maxwell) or (3,) per axis (ccl, the entry of
    ``dim`` is the normal energy accommodation).
    """
    v = np.asarray(v, dtype=np.float64)
    k = v.shape[0]
    sigma = np.broadcast_to(np.asarray(sigma, dtype=np.float64), (k,))
    u = np.asarray(wall_velocity, dtype=np.float64)
    tang = [d for d in range(3) if d != dim]
    out = v.copy()
    away = -float(side)  # direction of the outgoing normal velocity
    if rstyle in ("diffusive", "maxwell"):
        choose = rng.random(k) if rstyle == "maxwell" else None
        uni = 1.0 - rng.random(k)
        g = rng.standard_normal((k, 2))
        diff = np.empty_like(v)
        diff[:, dim] = away * sigma * np.sqrt(-2.0 * np.log(uni))
        for j, d in enumerate(tang):
            diff[:, d] = u[d] + sigma * g[:, j]
        if choose is None:
            return diff
        a = float(np.asarray(accom, dtype=np.float64).reshape(-1)[0])
        spec = v.copy()
        spec[:, dim] = -v[:, dim]
        return np.where((choose < a)[:, None], diff, spec)
    if rstyle == "ccl":
        acc = np.broadcast_to(np.asarray(accom, dtype=np.float64), (3,))
        u1 = 1.0 - rng.random(k)
        u2 = rng.random(k)
        g = rng.standard_normal((k, 2))
        an = acc[dim]
        scale = math.sqrt(2.0) * sigma
        rho = np.sqrt(-an * np.log(u1))
        m = math.sqrt(1.0 - an) * np.abs(v[:, dim]) / scale
        w2 = rho * rho + m * m + 2.0 * rho * m * np.cos(2.0 * math.pi * u2)
        out[:, dim] = away * np.sqrt(np.maximum(w2, 0.0)) * scale
        for j, d in enumerate(tang):
            at = acc[d]
            out[:, d] = u[d] + (1.0 - at) * (v[:, d] - u[d]) + math.sqrt(at * (2.0 - at)) * sigma * g[:, j]
        return out
    raise ValueError(f"unknown reflection rule {rstyle!r} (expected one of {', '.join(RSTYLES)})")


def reflect_positions(
    x: np.ndarray, v_old: np.ndarray, v_new: np.ndarray, dim: int, coord: float | np.ndarray
) -> np.ndarray:
    """Positions (K, 3) [length] after the reflection: the atoms crossed ``coord`` t = d/|v_n| ago
    and left it with v_new: x_n = coord + v'_n t, x_t = x_t + (v'_t - v_t) t (t = 0 if v_n = 0)."""
    x = np.asarray(x, dtype=np.float64)
    coord = np.asarray(coord, dtype=np.float64)
    depth = np.abs(x[:, dim] - coord)
    vn = np.abs(v_old[:, dim])
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.where(vn > 0.0, depth / vn, 0.0)
    out = x + (v_new - v_old) * t[:, None]
    out[:, dim] = np.where(vn > 0.0, coord + v_new[:, dim] * t, 2.0 * coord - x[:, dim])
    return out


# ---------------------------------------------------------------------------------------------
# The batch kernel


class StochasticKernel:
    """fix wall/reflect/stochastic over a batch (post_integrate, like wall/reflect): atoms past a
    face get a velocity from the wall's rule and the crossing position; per case one random
    stream per wall (seeded from the config seed, the case's sweep key and the wall's seed).
    Counts and impulses (momentum given to the wall along +dim, force*time) as for wall/reflect."""

    def __init__(self, specs: list, stats: bool):
        s0 = specs[0]
        self.fix_id = s0.fix_id
        self.group = s0.group
        self.all_atoms = bool(s0.group.all())
        self.frame = s0.frame
        self.rstyle = s0.frame.split("/", 1)[1]
        self.faces = [FaceValues([s.faces[i] for s in specs]) for i in range(len(s0.faces))]
        self.rngs = [np.random.default_rng(np.random.SeedSequence(list(s.seed))) for s in specs]
        self.stats = stats
        self.count: np.ndarray | None = None
        self.impulse: np.ndarray | None = None

    def take(self, keep: np.ndarray) -> None:
        for face in self.faces:
            face.take(keep)
        self.rngs = [self.rngs[i] for i in np.nonzero(keep)[0]]
        if self.count is not None:
            self.count, self.impulse = self.count[keep], self.impulse[keep]

    def setup(self, state) -> None:
        if self.stats:
            self.count = np.zeros((state.ncases, len(self.faces)))
            self.impulse = np.zeros((state.ncases, len(self.faces)))

    def apply(self, state, dt: np.ndarray) -> None:
        u = state.units
        for k, face in enumerate(self.faces):
            coord = face.position(state)
            pos = state.x[:, :, face.dim]
            out = pos < coord[:, None] if face.side < 0 else pos > coord[:, None]
            if not self.all_atoms:
                out &= self.group
            cases = np.nonzero(out.any(axis=1))[0]
            if cases.size == 0:
                continue
            p = {key: face.param(key, state) for key in face.params}
            for c in cases.tolist():
                ai = np.nonzero(out[c])[0]
                v_old = state.v[c, ai]
                mass = state.mass[c, ai]
                sigma = thermal_sigma(p["temp"][c], mass, u.boltz, u.mvv2e)
                wall_v = np.array([p["vx"][c], p["vy"][c], p["vz"][c]])
                accom = np.array([p["ax"][c], p["ay"][c], p["az"][c]])
                v_new = reflect_velocities(self.rstyle, self.rngs[c], v_old, face.dim, face.side, sigma, wall_v,
                                           accom[0] if self.rstyle == "maxwell" else accom)
                state.x[c, ai] = reflect_positions(state.x[c, ai], v_old, v_new, face.dim, coord[c])
                state.v[c, ai] = v_new
                if self.stats:
                    self.count[c, k] += ai.size
                    self.impulse[c, k] += np.sum(mass * (v_old[:, face.dim] - v_new[:, face.dim])) / u.ftm2v

    def take_stats(self) -> tuple[np.ndarray, np.ndarray]:
        """Reflections and impulse since the previous sample; resets the counters."""
        out = (self.count.copy(), self.impulse.copy())
        self.count[:] = 0.0
        self.impulse[:] = 0.0
        return out
