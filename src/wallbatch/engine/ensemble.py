"""The integrator and thermostat fixes of a batch (`fixes:`), hooked into the step like LAMMPS:

  initial_integrate  fix nvt: chain half step and velocity scaling; then every integrator's
                     v += dt/2 f/m, x += dt v on its group (atoms of no integrator never move)
  post_force         fix langevin (also at setup), then fix enforce2d (zero z force and velocity)
  final_integrate    v += dt/2 f/m on the integrated atoms; fix nvt: group temperature, chain
                     half step and scaling
  end_of_step        fix temp/berendsen (every step), temp/rescale (every N), langevin tally

`ecouple` is the energy the thermostats took out of the atoms (LAMMPS thermo keyword): the
Nose-Hoover chain's energy, the kinetic energy removed by the rescaling fixes, and minus the
work of the Langevin force (with tally); etot + ecouple is conserved up to integration error.
Each case has its own random stream per Langevin fix, so results do not depend on batching.
"""

from __future__ import annotations

import numpy as np

from wallbatch.engine.state import BatchState
from wallbatch.engine.thermostats import (
    NHChain,
    berendsen_factor,
    group_dof,
    langevin_force,
    langevin_power,
    ramped,
    rescale_factor,
    scale_group,
    temperature,
)
from wallbatch.scene.case import Case
from wallbatch.scene.ensemble import is_plain_nve


class _Fix:
    """One fix of the batch: style, group, per-case parameters (C,) and its ecouple share."""

    def __init__(self, cases: list[Case], i: int, dimension: int):
        specs = [c.fixes[i] for c in cases]
        s0 = specs[0]
        self.fix_id, self.style, self.group, self.group_name = s0.fix_id, s0.style, s0.group, s0.group_name
        self.all = bool(self.group.all())
        self.count = int(self.group.sum())
        self.dof = group_dof(self.count, dimension)
        for name in ("t_start", "t_stop", "damp", "window", "fraction", "drag"):
            setattr(self, name, np.array([getattr(s, name) for s in specs], float))
        self.every, self.zero, self.tally = s0.every, s0.zero, s0.tally
        self.removed = np.zeros(len(cases))  # berendsen / rescale: energy taken out so far
        self.chain: NHChain | None = None
        if self.style == "nvt":
            self.chain = NHChain.start(len(cases), s0.tchain, self.damp, self.dof, cases[0].units.boltz,
                                       tloop=s0.tloop, drag=self.drag)
        self.rngs = [np.random.default_rng(np.random.SeedSequence(list(s.seed))) for s in specs] \
            if self.style == "langevin" else []
        self.force: np.ndarray | None = None  # langevin: this step's force (C, N, 3)
        self.work = np.zeros(len(cases))  # langevin tally: accumulated power * dt
        self.power = np.zeros(len(cases))  # langevin tally: last F . v
        self.last_dt = np.zeros(len(cases))  # langevin tally: dt of the last step

    def target(self, s: BatchState) -> np.ndarray:
        """Ramped target temperature at the current step (LAMMPS: (n - begin) / (end - begin))."""
        return ramped(self.t_start, self.t_stop, s.context().ramp_fraction)

    def mask(self) -> np.ndarray | None:
        return None if self.all else self.group

    def temperature(self, s: BatchState) -> np.ndarray:
        return temperature(s.v, s.mass, self.mask(), self.dof, s.units.mvv2e, s.units.boltz)

    def ecouple(self) -> np.ndarray:
        if self.chain is not None:
            return self.chain.energy()
        if self.style == "langevin":
            return -(self.work - 0.5 * self.power * self.last_dt) if self.tally else np.zeros_like(self.work)
        return self.removed

    def take(self, keep: np.ndarray) -> None:
        for name in ("t_start", "t_stop", "damp", "window", "fraction", "drag", "removed", "work", "power",
                     "last_dt"):
            setattr(self, name, getattr(self, name)[keep])
        if self.chain is not None:
            self.chain.take(keep)
        if self.rngs:
            self.rngs = [r for r, k in zip(self.rngs, keep) if k]
        if self.force is not None:
            self.force = self.force[keep]


class Ensemble:
    """Integrators and thermostats of one batch, in config order."""

    def __init__(self, cases: list[Case], state: BatchState):
        c0 = cases[0]
        self.dimension = c0.dimension
        self.fixes = [_Fix(cases, i, c0.dimension) for i in range(len(c0.fixes))]
        n = c0.natoms
        self.integrated = np.zeros(n, bool)
        for f in self.fixes:
            if f.style in ("nve", "nve/asphere", "nvt"):
                self.integrated |= f.group
        self.moving = None if self.integrated.all() else self.integrated  # None: every atom
        self.nvt = [f for f in self.fixes if f.style == "nvt"]
        self.langevin = [f for f in self.fixes if f.style == "langevin"]
        self.enforce2d = [f for f in self.fixes if f.style == "enforce2d"]
        self.rescalers = [f for f in self.fixes if f.style in ("temp/berendsen", "temp/rescale")]
        self.live: np.ndarray | None = None  # this step's advancing cases (None: all)

    @staticmethod
    def needed(case: Case) -> bool:
        """False when the case runs plain velocity Verlet on every atom in 3-D (the built-in step)."""
        return case.dimension != 3 or not is_plain_nve(case.fixes)

    # -- hooks -----------------------------------------------------------------------------

    def setup(self, s: BatchState) -> None:
        """At the start of the run, after the setup forces: Langevin and enforce2d forces, the
        chains' current temperatures and masses, the Langevin tally's first power."""
        self.post_force(s)
        for f in self.nvt:
            f.chain.setup(f.temperature(s), f.target(s))
        for f in self.langevin:
            if f.tally:
                f.last_dt = s.dt.copy()
                f.power = langevin_power(f.force, s.v)
                f.work = 0.5 * f.power * s.dt

    def initial_integrate(self, s: BatchState, dt: np.ndarray, dtfm: np.ndarray) -> None:
        for f in self.nvt:
            scale_group(s.v, f.chain.half_step(dt, f.target(s)), f.mask())
        m = self.moving
        if m is None:
            s.v += dtfm * s.f
            s.x += dt[:, None, None] * s.v
        else:
            s.v[:, m] += dtfm[:, m] * s.f[:, m]
            s.x[:, m] += dt[:, None, None] * s.v[:, m]

    def post_force(self, s: BatchState, active: np.ndarray | None = None) -> None:
        """Langevin forces, then enforce2d. `active` (C,) marks the cases that advance this step
        (a run to a time): the others draw no random numbers and keep the Langevin force of their
        last step (their other forces are recomputed at the same positions), so that their next
        step starts from the forces it would have had alone: neither a case's random stream nor its
        trajectory depends on the batch it runs in."""
        self.live = None if active is None or np.all(active > 0) else active > 0  # for this step's later hooks
        for f in self.langevin:
            if not f.rngs:
                continue
            idx = np.nonzero(f.group)[0]
            live = np.ones(s.ncases, bool) if self.live is None else self.live
            u = np.full(s.x.shape, 0.5)  # atoms outside the group (and idle cases) get no random force
            for c in np.nonzero(live)[0]:
                u[c, idx] = f.rngs[c].random((len(idx), 3))
            dt = np.where(s.dt > 0, s.dt, 1.0)  # an idle case has dt = 0
            last = f.force
            f.force = langevin_force(s.v, s.mass, f.mask(), f.target(s), f.damp, dt, u, s.units.ftm2v,
                                     s.units.mvv2e, s.units.boltz, zero=f.zero)
            if not live.all() and last is not None:
                f.force[~live] = last[~live]
            s.f += f.force
        for f in self.enforce2d:
            if f.all:
                s.f[:, :, 2] = 0.0
                s.v[:, :, 2] = 0.0
            else:
                s.f[:, f.group, 2] = 0.0
                s.v[:, f.group, 2] = 0.0

    def final_integrate(self, s: BatchState, dtfm: np.ndarray) -> None:
        m = self.moving
        if m is None:
            s.v += dtfm * s.f
        else:
            s.v[:, m] += dtfm[:, m] * s.f[:, m]
        for f in self.nvt:
            t_now = f.temperature(s)  # an idle case keeps its carried value (bit-identity across batches)
            f.chain.t_current = t_now if self.live is None else np.where(self.live, t_now, f.chain.t_current)
            scale_group(s.v, f.chain.half_step(s.dt, f.target(s)), f.mask())

    def end_of_step(self, s: BatchState, active: np.ndarray | None = None) -> None:
        for f in self.rescalers:
            if f.style == "temp/rescale" and not np.any(s.step % f.every == 0):
                continue
            t_now = f.temperature(s)
            if f.dof < 1:
                continue  # LAMMPS: nothing to do
            zero = t_now == 0.0
            if zero.any():
                s.fail(np.nonzero(zero)[0], lambda c, f=f: (
                    f"fixes.{f.fix_id}: the temperature of group '{f.group_name}' is 0 at step {int(s.step[c])} "
                    f"(LAMMPS: computed temperature for fix {f.style} cannot be 0.0): give them velocities"))
            if f.style == "temp/berendsen":
                factor, removed = berendsen_factor(t_now, f.target(s), s.dt, f.damp, f.dof, s.units.boltz)
            else:
                factor, removed = rescale_factor(t_now, f.target(s), f.window, f.fraction, f.dof, s.units.boltz)
                due = s.step % f.every == 0
                factor, removed = np.where(due, factor, 1.0), np.where(due, removed, 0.0)
            if active is not None:
                factor, removed = np.where(active > 0, factor, 1.0), np.where(active > 0, removed, 0.0)
            scale_group(s.v, factor, f.mask())
            f.removed = f.removed + removed
        for f in self.langevin:
            if f.tally:
                power = langevin_power(f.force, s.v)
                live = np.ones(s.ncases, bool) if self.live is None else self.live
                f.last_dt = np.where(live, s.dt, f.last_dt)
                f.power = np.where(live, power, f.power)
                f.work = f.work + np.where(live, power * s.dt, 0.0)

    def ecouple(self, ncases: int) -> np.ndarray:
        total = np.zeros(ncases)
        for f in self.fixes:
            if f.style in ("nvt", "langevin", "temp/berendsen", "temp/rescale"):
                total = total + f.ecouple()
        return total

    def take(self, keep: np.ndarray) -> None:
        self.live = None
        for f in self.fixes:
            f.take(keep)
