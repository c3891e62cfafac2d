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

The arithmetic is a set of plain functions of arrays or scalars (:func:`diffusive_normal`,
:func:`thermal_tangent`, :func:`ccl_normal`, :func:`ccl_tangent`, :func:`crossing_time`,
:func:`crossed_position`) that the compiled chunk kernel (wallbatch.engine.compiled) compiles as
they are, with the C library's log and cos (:func:`libm_log`, :func:`libm_cos`, not NumPy's SIMD
versions) and the impulse summed in atom order, so the two paths agree bit for bit.
"""

from __future__ import annotations

import math

import numpy as np

from wallbatch.engine.dt_reset import select
from wallbatch.engine.state import FaceValues

__all__ = ["RSTYLES", "StochasticKernel", "reflect_velocities", "reflect_positions", "thermal_sigma",
           "diffusive_normal", "thermal_tangent", "ccl_normal", "ccl_tangent", "crossing_time", "crossed_position",
           "libm_log", "libm_cos"]

RSTYLES = ("diffusive", "maxwell", "ccl")
SQRT2 = math.sqrt(2.0)


def libm_log(x: np.ndarray) -> np.ndarray:
    """Natural log of a 1-D array by the C library (math.log), not NumPy's SIMD log, so the NumPy
    path agrees bit for bit with the compiled one (which calls math.log); x > 0 (the few
    reflections of a step)."""
    return np.array([math.log(v) for v in np.asarray(x, dtype=np.float64).tolist()], dtype=np.float64)


def libm_cos(x: np.ndarray) -> np.ndarray:
    """cos of a 1-D array by the C library (math.cos), as :func:`libm_log`."""
    return np.array([math.cos(v) for v in np.asarray(x, dtype=np.float64).tolist()], dtype=np.float64)


def thermal_sigma(temp, mass, boltz, mvv2e):
    """sqrt(kB T / (m mvv2e)) [velocity]: the standard deviation of one velocity component
    (arrays or scalars)."""
    return np.sqrt(boltz * temp / (mass * mvv2e))


def diffusive_normal(away, sigma, uni):
    """Outgoing normal velocity of a diffusive reflection [velocity]: sigma sqrt(-2 ln U) in the
    direction ``away`` (+1 or -1), U in (0, 1]: the flux-weighted (Rayleigh) speed."""
    return away * sigma * np.sqrt(-2.0 * libm_log(uni))


def thermal_tangent(wall_v, sigma, g):
    """A tangential component of a diffusive reflection: wall velocity + sigma N(0, 1). [velocity]"""
    return wall_v + sigma * g


def ccl_normal(away, sigma, an, vn, u1, u2):
    """Outgoing normal velocity of a Cercignani-Lampis reflection (normal energy accommodation
    an, incoming normal velocity vn, uniforms u1 in (0, 1], u2 in [0, 1)) [velocity]."""
    scale = SQRT2 * sigma
    rho = np.sqrt(-an * libm_log(u1))
    m = math.sqrt(1.0 - an) * np.abs(vn) / scale
    w2 = rho * rho + m * m + 2.0 * rho * m * libm_cos(2.0 * math.pi * u2)
    return away * np.sqrt(np.maximum(w2, 0.0)) * scale


def ccl_tangent(wall_v, at, v, sigma, g):
    """A tangential component of a Cercignani-Lampis reflection (accommodation at) [velocity]."""
    return wall_v + (1.0 - at) * (v - wall_v) + math.sqrt(at * (2.0 - at)) * sigma * g


def crossing_time(x_n, coord, vn_old):
    """How long ago an atom at normal coordinate x_n, moving with normal velocity vn_old, crossed
    the wall at coord: |x_n - coord| / |vn_old| (0 if vn_old = 0). [time]"""
    vn = np.abs(vn_old)
    return select(vn > 0.0, np.abs(x_n - coord) / vn, 0.0)


def crossed_position(x_n, coord, vn_old, vn_new, t):
    """Normal coordinate after the reflection: coord + v'_n t, or the mirror image 2 coord - x_n
    when the atom had no normal velocity. [length]"""
    return select(np.abs(vn_old) > 0.0, coord + vn_new * t, 2.0 * coord - x_n)


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
        diff[:, dim] = diffusive_normal(away, sigma, uni)
        for j, d in enumerate(tang):
            diff[:, d] = thermal_tangent(u[d], sigma, g[:, j])
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
        out[:, dim] = ccl_normal(away, sigma, acc[dim], v[:, dim], u1, u2)
        for j, d in enumerate(tang):
            out[:, d] = ccl_tangent(u[d], acc[d], v[:, d], sigma, g[:, j])
        return out
    raise ValueError(f"unknown reflection rule {rstyle!r} (expected one of {', '.join(RSTYLES)})")


def reflect_positions(
    x: np.ndarray, v_old: np.ndarray, v_new: np.ndarray, dim: int, coord: float | np.ndarray
) -> np.ndarray:
    """Positions (K, 3) [length] after the reflection: the atoms crossed ``coord`` t = d/|v_n| ago
    and left it with v_new: x_n = coord + v'_n t, x_t = x_t + (v'_t - v_t) t (t = 0 if v_n = 0)."""
    x = np.asarray(x, dtype=np.float64)
    coord = np.asarray(coord, dtype=np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = crossing_time(x[:, dim], coord, v_old[:, dim])
    out = x + (v_new - v_old) * t[:, None]
    out[:, dim] = crossed_position(x[:, dim], coord, v_old[:, dim], v_new[:, dim], t)
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
                    # summed in atom order (cumsum), as the compiled path adds them
                    self.impulse[c, k] += np.cumsum(mass * (v_old[:, face.dim] - v_new[:, face.dim]))[-1] / u.ftm2v

    def take_stats(self) -> tuple[np.ndarray, np.ndarray]:
        """Reflections and impulse since the previous sample; resets the counters."""
        out = (self.count.copy(), self.impulse.copy())
        self.count[:] = 0.0
        self.impulse[:] = 0.0
        return out
