"""Thermostat kernels: pure, vectorised functions over a batch of C cases of N atoms.

Velocities are (C, N, 3), masses (C, N), group masks (N,) bool (the group is the same in every
case of a batch); every physical parameter (target temperature, damping time, window, ...) is a
per-case array (C,), so a temperature x damp sweep runs as one batch. Nothing here keeps hidden
state: the Nose-Hoover chain variables live in an `NHChain` the caller owns.

Units: temperatures in the unit system's temperature unit, times in its time unit; `boltz`,
`mvv2e`, `ftm2v` are the LAMMPS conversion constants (units.py).

What each LAMMPS fix does and where in the step (velocity Verlet):
  fix nvt            initial_integrate: chain half step + velocity scaling, then v += dt/2 f/m, x += dt v;
                     final_integrate:   v += dt/2 f/m, group temperature, chain half step + scaling.
  fix langevin       post_force (and at setup): f += -m v / (damp ftm2v) + random force.
  fix temp/berendsen end_of_step, every step: v *= sqrt(1 + dt/damp (T_target/T - 1)).
  fix temp/rescale   end_of_step, every `every` steps: if |T - T_target| > window,
                     v *= sqrt(T_new / T) with T_new = T - fraction (T - T_target).
Temperatures of a fix are those of its group with dof = dim * N_group - dim (compute temp).

The per-atom and per-case arithmetic is written as plain functions (`atom_mv2`, `dot3`, `ramped`,
`langevin_drag`, `langevin_amplitude`, `langevin_random`, `nh_half_step`, `berendsen_factor`,
`rescale_factor`; branches through `select`, np.where for arrays) that the compiled chunk path
(wallbatch.engine.compiled) compiles as they are, and sums over atoms are NumPy's own pairwise
sums (`pairwise_sum` is their order, for the compiled path), so both paths agree bit for bit.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from wallbatch.engine.dt_reset import select

# ----------------------------------------------------------------------------- shared arithmetic


def atom_mv2(m, v0, v1, v2):
    """m |v|^2 of one atom (or elementwise), components summed x, y, z in that order."""
    return m * (v0 * v0 + v1 * v1 + v2 * v2)


def dot3(a0, a1, a2, b0, b1, b2):
    """a . b of 3-vectors given by components (elementwise), summed x, y, z in that order."""
    return a0 * b0 + a1 * b1 + a2 * b2


def pairwise_sum(a, lo, n):
    """sum(a[lo:lo + n]) in the order of NumPy's np.add.reduce over a contiguous float64 axis
    (its pairwise summation: runs of at most 128 values summed with 8 partial sums, longer runs
    split in two halves summed separately), so a compiled loop reproduces `x.sum(axis=-1)` bit for
    bit. NumPy's recursion is written with an explicit stack (numba caches it that way)."""
    slo = np.empty(64, np.int64)  # the recursion's frames: start, length, state, left half's sum
    sn = np.empty(64, np.int64)
    sst = np.empty(64, np.int64)
    sval = np.empty(64)
    top = 0
    slo[0], sn[0], sst[0] = lo, n, 0
    ret = 0.0
    while top >= 0:
        lo1, m, state = slo[top], sn[top], sst[top]
        if m < 8:
            ret = 0.0
            for i in range(lo1, lo1 + m):
                ret += a[i]
            top -= 1
        elif m <= 128:
            r0, r1, r2, r3 = a[lo1], a[lo1 + 1], a[lo1 + 2], a[lo1 + 3]
            r4, r5, r6, r7 = a[lo1 + 4], a[lo1 + 5], a[lo1 + 6], a[lo1 + 7]
            i = lo1 + 8
            end8 = lo1 + m - m % 8
            while i < end8:
                r0 += a[i]
                r1 += a[i + 1]
                r2 += a[i + 2]
                r3 += a[i + 3]
                r4 += a[i + 4]
                r5 += a[i + 5]
                r6 += a[i + 6]
                r7 += a[i + 7]
                i += 8
            ret = ((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))
            while i < lo1 + m:
                ret += a[i]
                i += 1
            top -= 1
        else:
            n2 = m // 2
            n2 -= n2 % 8
            if state == 0:  # first the left half
                sst[top] = 1
                top += 1
                slo[top], sn[top], sst[top] = lo1, n2, 0
            elif state == 1:  # keep its sum, then the right half
                sval[top] = ret
                sst[top] = 2
                top += 1
                slo[top], sn[top], sst[top] = lo1 + n2, m - n2, 0
            else:
                ret = sval[top] + ret
                top -= 1
    return ret


def libm_exp(x: np.ndarray) -> np.ndarray:
    """exp of a 1-D array by the C library's exp (math.exp), not NumPy's SIMD exp, so the chain
    agrees bit for bit with the compiled path (which calls math.exp); for the few values (C,) of
    a chain step."""
    return np.array([math.exp(v) for v in x.tolist()], dtype=float)


def ramped(t_start, t_stop, fraction):
    """Target temperature t_start + fraction (t_stop - t_start) (fraction: of the run done)."""
    return t_start + fraction * (t_stop - t_start)

# ----------------------------------------------------------------------------- temperature


def group_dof(count: int, dimension: int = 3) -> int:
    """Degrees of freedom of LAMMPS `compute temp` on a group of `count` atoms: dim N - dim (the
    centre-of-mass motion, `extra_dof` = dimension by default)."""
    return dimension * count - dimension


def kinetic_sum(v: np.ndarray, mass: np.ndarray, mask: np.ndarray | None = None) -> np.ndarray:
    """sum_i m_i |v_i|^2 over the group atoms (mass * velocity^2 units), shape (C,)."""
    mv2 = atom_mv2(mass, v[..., 0], v[..., 1], v[..., 2])
    if mask is not None and not mask.all():
        mv2 = np.where(mask, mv2, 0.0)
    return mv2.sum(axis=1)


def temperature(v: np.ndarray, mass: np.ndarray, mask: np.ndarray | None, dof: float, mvv2e: float,
                boltz: float) -> np.ndarray:
    """Kinetic temperature (C,) of the group: T = mvv2e sum m v^2 / (dof kB); 0 when dof <= 0."""
    if dof <= 0:
        return np.zeros(v.shape[0])
    return kinetic_sum(v, mass, mask) * (mvv2e / (dof * boltz))


def ramp(t_start: np.ndarray, t_stop: np.ndarray, step: np.ndarray, begin: int, end: int) -> np.ndarray:
    """Target temperature at `step` of a run from `begin` to `end`: linear from Tstart to Tstop
    (LAMMPS: delta = (step - begin) / (end - begin), 0 when the run has no steps)."""
    delta = np.asarray(step - begin, float)
    if end != begin:
        delta = delta / (end - begin)
    else:
        delta = np.zeros_like(delta)
    return t_start + delta * (t_stop - t_start)


def scale_group(v: np.ndarray, factor: np.ndarray, mask: np.ndarray | None) -> None:
    """v *= factor (C,) for the group atoms, in place."""
    f = factor[:, None, None]
    if mask is None or mask.all():
        v *= f
    else:
        v[:, mask] *= f


# ----------------------------------------------------------------------------- Nose-Hoover chain


@dataclass
class NHChain:
    """State of C Nose-Hoover chains of length M (LAMMPS fix nvt temp, Martyna-Tuckerman-Klein).

    eta (C, M): thermostat positions [1]; eta_dot (C, M+1): their velocities [1/time], with a
    trailing zero column (the chain's end); eta_dotdot (C, M); eta_mass (C, M) [energy time^2];
    t_current (C,): the group temperature the chain last saw, carried between the half steps
    and updated by the scaling (LAMMPS does not recompute it at initial_integrate).
    """

    eta: np.ndarray
    eta_dot: np.ndarray
    eta_dotdot: np.ndarray
    eta_mass: np.ndarray
    t_current: np.ndarray
    t_target: np.ndarray
    t_freq: np.ndarray  # 1 / damp (C,)
    dof: float
    boltz: float
    tloop: int = 1
    drag: np.ndarray | float = 0.0

    @classmethod
    def start(cls, ncases: int, tchain: int, damp: np.ndarray, dof: float, boltz: float,
              tloop: int = 1, drag: np.ndarray | float = 0.0) -> NHChain:
        """A chain at rest (eta = eta_dot = 0), as at `fix nvt` creation."""
        z = np.zeros((ncases, tchain))
        return cls(z.copy(), np.zeros((ncases, tchain + 1)), z.copy(), z.copy(), np.zeros(ncases),
                   np.zeros(ncases), 1.0 / np.asarray(damp, float), float(dof), float(boltz), int(tloop),
                   drag)

    def take(self, keep: np.ndarray) -> None:
        """Keep only the rows `keep` (failed cases leave the batch)."""
        for name in ("eta", "eta_dot", "eta_dotdot", "eta_mass", "t_current", "t_target", "t_freq"):
            setattr(self, name, getattr(self, name)[keep])
        if isinstance(self.drag, np.ndarray):
            self.drag = self.drag[keep]

    @property
    def ke_target(self) -> np.ndarray:
        return self.dof * self.boltz * self.t_target

    def _masses(self) -> None:
        """Q_0 = dof kB T / w^2, Q_k = kB T / w^2 (k >= 1), w = 1/damp."""
        w2 = self.t_freq * self.t_freq
        self.eta_mass[:, 0] = self.dof * self.boltz * self.t_target / w2
        self.eta_mass[:, 1:] = (self.boltz * self.t_target / w2)[:, None]

    def setup(self, t_current: np.ndarray, t_target: np.ndarray) -> None:
        """At the start of a run: current temperature, target, masses and the forces on chain
        members 1..M-1 (member 0's is computed at each half step)."""
        self.t_current = np.array(t_current, float)
        self.t_target = np.array(t_target, float)
        self._masses()
        kt = self.boltz * self.t_target
        for k in range(1, self.eta.shape[1]):
            self.eta_dotdot[:, k] = (self.eta_mass[:, k - 1] * self.eta_dot[:, k - 1] ** 2 - kt) / self.eta_mass[:, k]

    def half_step(self, dt: np.ndarray, t_target: np.ndarray) -> np.ndarray:
        """Advance the chain by dt/2 (Trotter splitting, `tloop` sub-steps) and return the factor
        (C,) that scales the group velocities; t_current is updated for that scaling. The caller
        scales v (see scale_group); the factor is the product over the sub-steps."""
        self.t_target = np.array(t_target, float)
        drag = np.broadcast_to(np.asarray(self.drag, float), self.t_current.shape)
        with np.errstate(divide="ignore", invalid="ignore"):
            total, self.t_current = nh_half_step(self.eta.T, self.eta_dot.T, self.eta_dotdot.T, self.eta_mass.T,
                                                 np.asarray(self.t_current, float), self.t_target, self.t_freq,
                                                 self.dof, self.boltz, self.tloop, drag, np.asarray(dt, float))
        return total

    def energy(self) -> np.ndarray:
        """Energy of the chain (C,), LAMMPS fix nvt's scalar (its `ecouple` share):
        dof kB T eta_0 + Q_0 eta_dot_0^2 / 2 + sum_{k>=1} (kB T eta_k + Q_k eta_dot_k^2 / 2)."""
        M = self.eta.shape[1]
        kt = self.boltz * self.t_target
        ed = self.eta_dot[:, :M]
        e = self.ke_target * self.eta[:, 0] + 0.5 * self.eta_mass[:, 0] * ed[:, 0] ** 2
        for k in range(1, M):
            e = e + kt * self.eta[:, k] + 0.5 * self.eta_mass[:, k] * ed[:, k] ** 2
        return e


def nh_half_step(eta, ed, edd, Q, t_current, t_target, t_freq, dof, boltz, tloop, drag, dt):
    """One half step dt/2 of Nose-Hoover chains (NHChain.half_step; LAMMPS fix nvt's
    nhc_temp_integrate). The chain member is the FIRST index: eta, edd, Q (M, ...), ed (M + 1, ...);
    the rest are per-case values: NumPy passes the (C, M) arrays transposed and (C,) values, the
    compiled path one case's (M,) rows and scalars. Chain arrays are updated in place; returns
    (velocity factor, the new t_current). The masses Q follow t_target (NHChain._masses)."""
    M = eta.shape[0]
    w2 = t_freq * t_freq
    Q[0] = dof * boltz * t_target / w2
    for k in range(1, M):
        Q[k] = boltz * t_target / w2
    kt = boltz * t_target
    ke_target = dof * kt
    nc = 1.0 / tloop
    dt4, dt8, dthalf = 0.25 * dt, 0.125 * dt, 0.5 * dt
    drag = 1.0 - dt * t_freq * drag / tloop
    edd[0] = select(Q[0] > 0, (dof * boltz * t_current - ke_target) / Q[0], 0.0)
    total = 1.0
    for _ in range(tloop):
        for k in range(M - 1, 0, -1):  # from the chain's end down to member 1
            e = libm_exp(-nc * dt8 * ed[k + 1])
            ed[k] = (ed[k] * e + edd[k] * nc * dt4) * drag * e
        e = libm_exp(-nc * dt8 * ed[1])
        ed[0] = (ed[0] * e + edd[0] * nc * dt4) * drag * e
        factor = libm_exp(-nc * dthalf * ed[0])
        total = total * factor
        t_current = t_current * factor * factor
        edd[0] = select(Q[0] > 0, (dof * boltz * t_current - ke_target) / Q[0], 0.0)
        for k in range(M):
            eta[k] += (nc * dthalf) * ed[k]
        ed[0] = (ed[0] * e + edd[0] * nc * dt4) * e
        for k in range(1, M):  # back up the chain
            e = libm_exp(-nc * dt8 * ed[k + 1])
            edd[k] = (Q[k - 1] * ed[k - 1] ** 2 - kt) / Q[k]
            ed[k] = (ed[k] * e + edd[k] * nc * dt4) * e
    return total, t_current


# ----------------------------------------------------------------------------- velocity rescaling


def berendsen_factor(t_current: np.ndarray, t_target: np.ndarray, dt: np.ndarray, damp: np.ndarray,
                     dof: float, boltz: float) -> tuple[np.ndarray, np.ndarray]:
    """fix temp/berendsen: lambda = sqrt(1 + dt/damp (T_target/T - 1)) from the group's current
    temperature T, and the energy it removes, (1 - lambda^2) T dof kB / 2 (C,). Rows with T = 0
    get lambda = 1 (the caller refuses them: LAMMPS errors)."""
    lam = select(t_current > 0, np.sqrt(1.0 + dt / damp * (t_target / t_current - 1.0)), 1.0)
    removed = t_current * (1.0 - lam * lam) * (0.5 * boltz * dof)
    return lam, removed


def rescale_factor(t_current: np.ndarray, t_target: np.ndarray, window: np.ndarray, fraction: np.ndarray,
                   dof: float, boltz: float) -> tuple[np.ndarray, np.ndarray]:
    """fix temp/rescale: outside the window |T - T_target| > window, move T by `fraction` of the
    way to the target, T_new = T - fraction (T - T_target), by v *= sqrt(T_new / T). Returns the
    factor (1 inside the window) and the energy removed, (T - T_new) dof kB / 2 (C,)."""
    outside = np.abs(t_current - t_target) > window
    t_new = t_current - fraction * (t_current - t_target)
    factor = select(outside & (t_current > 0), np.sqrt(t_new / t_current), 1.0)
    removed = select(outside & (t_current > 0), (t_current - t_new) * (0.5 * boltz * dof), 0.0)
    return factor, removed


# ----------------------------------------------------------------------------- Langevin


def langevin_force(v: np.ndarray, mass: np.ndarray, mask: np.ndarray | None, t_target: np.ndarray,
                   damp: np.ndarray, dt: np.ndarray, uniform: np.ndarray, ftm2v: float, mvv2e: float,
                   boltz: float, zero: bool = False) -> np.ndarray:
    """fix langevin's force (C, N, 3) on the group (zero elsewhere): drag -m v / (damp ftm2v) plus
    a random force sqrt(24 kB T m / (damp dt mvv2e)) / ftm2v (u - 1/2), u uniform in [0, 1)
    (`uniform`, (C, N, 3)); variance 2 kB T m / (damp dt) per component, the fluctuation-dissipation
    value for a force held over one step. With `zero`, the random forces of the group sum to zero
    (their mean over the group atoms is removed), so the thermostat conserves the momentum."""
    damp = np.asarray(damp, float)[:, None]
    g1 = langevin_drag(mass, damp, ftm2v)  # (C, N)
    amp = langevin_amplitude(damp, np.asarray(dt, float)[:, None], ftm2v, mvv2e, boltz)
    fran = langevin_random(np.sqrt(mass)[:, :, None], amp[:, :, None],
                           np.sqrt(np.asarray(t_target, float))[:, None, None], uniform)
    sel = np.ones(v.shape[1], bool) if mask is None else mask
    if zero:
        count = int(sel.sum())
        if count:
            mean = np.where(sel[None, :, None], fran, 0.0).sum(axis=1) / count
            fran = fran - mean[:, None, :]
    force = g1[:, :, None] * v + fran
    if not sel.all():
        force = np.where(sel[None, :, None], force, 0.0)
    return force


def langevin_drag(mass, damp, ftm2v):
    """fix langevin's drag coefficient -m / (damp ftm2v) [force / velocity], elementwise."""
    return -mass / damp / ftm2v


def langevin_amplitude(damp, dt, ftm2v, mvv2e, boltz):
    """sqrt(24 kB / (damp dt mvv2e)) / ftm2v: the random force's amplitude per sqrt(m T)."""
    return np.sqrt(24.0 * boltz / damp / dt / mvv2e) / ftm2v


def langevin_random(sqrt_mass, amplitude, sqrt_t, u):
    """One random force component sqrt(m) amplitude sqrt(T) (u - 1/2), u uniform in [0, 1)."""
    return sqrt_mass * amplitude * sqrt_t * (u - 0.5)


def langevin_power(force: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Power the Langevin force puts into the group, sum_i F_i . v_i (C,) [energy/time]."""
    return dot3(force[..., 0], force[..., 1], force[..., 2], v[..., 0], v[..., 1], v[..., 2]).sum(axis=1)
