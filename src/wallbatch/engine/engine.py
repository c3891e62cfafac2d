"""The batched NumPy engine: velocity Verlet with LAMMPS's step anatomy (physics.md §1.2).

State arrays carry a leading case axis: `x` is (C, N, 3). A batch of cases with the same
structure runs as one set of array operations; a single case is a batch of one. The run is
"advance the batch to the next sample, then sample", so a compiled path can take over a whole
chunk of steps later without touching the rest.

One step n (counter first):
  1. initial_integrate   fix nvt chain half step; v += dt/2 ftm2v f/m ; x += dt v (integrated atoms)
  2. post_integrate      wall/reflect
  3. periodic wrap, lost-atom check
  4. force clear, post_force: soft walls (energies only on sample steps), langevin, enforce2d
  5. final_integrate     v += dt/2 ftm2v f/m; fix nvt chain half step
  6. end_of_step         temp/berendsen, temp/rescale, langevin tally (engine/ensemble.py), wall/flow,
                         dt/reset when n % every == 0
A case that fails (atom behind a wall, lost, NaN, a bad variable value) leaves the batch with its
message; the others go on untouched.
"""

from __future__ import annotations

import time as _time
import weakref
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Callable

import numpy as np

from wallbatch.engine import backend
from wallbatch.engine.dt_reset import dt_candidate
from wallbatch.engine.ensemble import Ensemble
from wallbatch.engine.flow import FlowKernel
from wallbatch.engine.minimize import minimize
from wallbatch.engine.pair import PairLJCut
from wallbatch.engine.profiles import ProfileSampler
from wallbatch.engine.state import BatchState, landing_tol
from wallbatch.engine.thermostats import kinetic_sum
from wallbatch.engine.walls import build_kernels, build_region_kernels
from wallbatch.geometry.quaternion import richardson, rotational_energy
from wallbatch.scene.case import Case, structure_key

if TYPE_CHECKING:
    from wallbatch.engine.compiled import ChunkPlan

BIG = 1.0e20  # dt/reset's "no limit" (LAMMPS BIG)
PAIR = "__pair__"  # key of the pair style's (energy, virial) among the force outputs
VIRIAL = "__virial__"  # key of the total virial W (pair + walls with virial: true) for press
SAMPLES_PER_CALL = 4096  # samples recorded by one compiled call at most (their arrays: (C, S, ...))


@dataclass
class CaseResult:
    """Samples of one case: name -> array with a leading sample axis."""

    status: str
    error: str
    seconds: float
    data: dict[str, np.ndarray] = field(default_factory=dict)
    frames: dict[str, np.ndarray] = field(default_factory=dict)  # output.dump: time (F,), x/v (F, N, 3)
    # steps of the case's batch run by compiled kernels and by the NumPy loop (`wallbatch run -v`)
    compiled_steps: int = 0
    numpy_steps: int = 0


class Engine:
    """Runs one batch of same-structure cases and collects their samples."""

    def __init__(self, cases: list[Case]):
        self.cases = cases
        c0 = cases[0]
        self.outputs = c0.outputs
        self.state = BatchState(cases)
        self.soft, self.reflect = build_kernels(cases, c0.outputs)
        self.dt_reset = c0.dt_reset
        if self.dt_reset is not None:
            self.dtr_xmax = np.array([c.dt_reset.xmax for c in cases])
            self.dtr_emax = np.array([c.dt_reset.emax or 0.0 for c in cases])
            self.dtr_tmin = np.array([np.nan if c.dt_reset.tmin is None else c.dt_reset.tmin for c in cases])
            self.dtr_tmax = np.array([np.nan if c.dt_reset.tmax is None else c.dt_reset.tmax for c in cases])
        self.errors: dict[int, str] = {}
        self._dtfm_key: tuple[np.ndarray, np.ndarray] | None = None  # (mass, dt) of the kept half_kick
        self._dtfm: np.ndarray | None = None
        self.dump_fields = c0.dump_fields
        self.frames: list[tuple] = []  # (rows, time, x, v) per dump instant
        self.samples: list[dict[str, np.ndarray]] = []  # per sample: name -> (C_live, ...) arrays
        self.sample_rows: list[np.ndarray] = []  # the live rows of each of them
        self.sample_index: list[int] = []  # and its index on the schedule
        # samples recorded S at a time (compiled chunks): (first index, live rows, name -> (C_live, S, ...))
        self.sample_blocks: list[tuple[int, np.ndarray, dict[str, np.ndarray]]] = []
        self.nsampled = 0  # samples recorded so far
        # the compiled path (compiled.py) runs only scenes without pair, ees, wall/region/ees, ellipsoids;
        # asphere_compiled.py runs ellipsoids between wall/ees faces
        self.pair = None  # pair.PairLJCut
        if c0.pair is not None:
            self.pair = PairLJCut(np.array([c.pair.epsilon for c in cases]), np.array([c.pair.sigma for c in cases]),
                                  np.array([c.pair.cutoff for c in cases]), box_lo=c0.box_lo, box_hi=c0.box_hi,
                                  periodic=self._pair_periodic(c0), shift=c0.pair.shift, skin=c0.pair.skin)
        self.flow: list = []  # flow.FlowKernel per wall/flow fix
        if c0.flow_walls:
            for i in range(len(c0.flow_walls)):
                rngs = [np.random.default_rng(np.random.SeedSequence(list(c.flow_seeds[i]))) for c in cases]
                self.flow.append(FlowKernel([c.flow_walls[i] for c in cases], rngs, c0.box_lo, c0.box_hi, c0.units))
        self.ees: list = [w for w in self.soft if w.style.needs_shape]  # wall/ees (ellipsoids)
        self.region_walls: list = build_region_kernels(cases)  # wall/region and wall/region/ees
        self.min_info: dict[int, dict[str, np.ndarray]] = {}  # case -> minimization results
        # fixes: integrator groups, thermostats, 2-D (None: fix nve on all atoms, 3-D)
        self.ensemble = Ensemble(cases, self.state) if Ensemble.needed(c0) else None
        self.profiles = ProfileSampler(cases) if c0.profiles else None  # output.profiles
        # compiled chunks of steps, or None (compiled.eligible: which scenes and fixes; ellipsoids
        # between wall/ees faces: asphere_compiled.eligible)
        # (imported only then: numba and the kernels cost ~0.6 s; backend.py: small plans run NumPy)
        self.fast = None
        self.compiled_steps = 0  # steps the compiled path ran (`_compiled`), and the NumPy loop (`step`)
        self.numpy_steps = 0
        if backend.numba_allowed():
            from wallbatch.engine.asphere_compiled import attach_asphere_path
            from wallbatch.engine.compiled import attach_fast_path

            plans = _weak_method(self.compiled_plan)  # the path keeps it: no engine <-> path cycle
            self.fast = attach_fast_path(plans) or attach_asphere_path(plans)
            if self.fast is None and self.pair is not None:  # pair scenes: fused chunks (pair_compiled.py)
                from wallbatch.engine.pair_compiled import attach_pair_chunks

                self.fast = attach_pair_chunks(plans, self.pair)

    def compiled_plan(self) -> ChunkPlan:
        """What the compiled path would run now: the flat walls, reflect walls and dt/reset with
        their per-case arrays, the NumPy steps it hands back to, and what else the scene has."""
        from wallbatch.engine.compiled import ChunkPlan

        s = self.state
        others = tuple(name for name, present in (
            ("pair", self.pair is not None),
            ("ellipsoids", s.quat is not None or s.angmom is not None or s.torque is not None)) if present)
        dtr = None
        if self.dt_reset is not None:
            dtr = np.stack([self.dtr_xmax, self.dtr_emax, self.dtr_tmin, self.dtr_tmax], axis=1)
        return ChunkPlan(state=s, soft=tuple(self.soft), reflect=tuple(self.reflect), dt_reset=self.dt_reset,
                         dt_reset_params=dtr, others=others, compute_outputs=lambda: self.compute_forces(True),
                         finish_step=self.finish_step, advance_numpy=self.advance_numpy,
                         region=tuple(self.region_walls), flow=tuple(self.flow), ensemble=self.ensemble,
                         record_samples=self.record_samples, outputs=tuple(self.outputs),
                         samples=lambda c0=self.cases[0]: len(sample_instants(c0)) - 1)  # the case, not the engine

    # -- the step ----------------------------------------------------------------------------

    def initial_integrate(self, dt: np.ndarray, dtfm: np.ndarray) -> None:
        """fix nve, first half: v += dtfm f (dtfm = dt/2 ftm2v / m, shape (C, N, 1)); x += dt v.
        With ellipsoids, fix nve/asphere (physics.md §11.2): also L += dt/2 ftm2v torque, then the
        Richardson quaternion step over dt."""
        s = self.state
        if self.ensemble is not None:
            self.ensemble.initial_integrate(s, dt, dtfm)
        else:
            s.v += dtfm * s.f
            s.x += dt[:, None, None] * s.v
        if s.quat is not None:
            s.angmom += ((0.5 * s.units.ftm2v) * dt)[:, None, None] * s.torque
            s.quat = richardson(s.quat, s.angmom, s.inertia, (0.5 * dt)[:, None])

    def final_integrate(self, dtfm: np.ndarray, dt: np.ndarray) -> None:
        """fix nve (and nve/asphere), second half: v += dtfm f; L += dt/2 ftm2v torque."""
        s = self.state
        if self.ensemble is not None:
            self.ensemble.final_integrate(s, dtfm)
        else:
            s.v += dtfm * s.f
        if s.quat is not None:
            s.angmom += ((0.5 * s.units.ftm2v) * dt)[:, None, None] * s.torque

    @staticmethod
    def _pair_periodic(case) -> np.ndarray:
        """Periodic dimensions for the pair's minimum image: in 2-D every atom has z = 0 and the
        thin periodic z never wraps a pair, so z is left out (its length may be below 2 rc)."""
        periodic = np.array(case.periodic, dtype=bool)
        if case.dimension == 2:
            periodic[2] = False
        return periodic

    def wrap(self) -> None:
        """Wrap periodic dimensions every step (x -= L past hi, x += L below lo, as LAMMPS)."""
        s = self.state
        for d in s.periodic:
            lo, hi = s.box_lo[d], s.box_hi[d]
            length = hi - lo
            xd = s.x[:, :, d]  # a view: updated in place where the condition holds
            # most steps nothing crosses: two reductions say so (a NaN fails both tests and goes on)
            if xd.size == 0 or (xd.max() < hi and xd.min() >= lo):
                continue
            np.subtract(xd, length, out=xd, where=xd >= hi)
            np.add(xd, length, out=xd, where=xd < lo)

    def check_lost(self) -> None:
        """Fail cases with atoms outside a fixed boundary (LAMMPS: Lost atoms). Runs after the wall
        forces, so an atom behind a wall reports that wall first."""
        s = self.state
        for d in s.fixed:
            xd = s.x[:, :, d]
            # pre-test on the extremes (a NaN position is not lost here: a NaN extreme fails both
            # tests and the full test below passes over it)
            if xd.size == 0 or (xd.min() >= s.box_lo[d] and xd.max() <= s.box_hi[d]):
                continue
            lost = (xd < s.box_lo[d]) | (xd > s.box_hi[d])
            if lost.any():
                ci, ai = np.nonzero(lost)
                first = {}
                for c, a in zip(ci.tolist(), ai.tolist()):
                    first.setdefault(c, a)
                s.fail(np.array(sorted(first)), lambda c, d=d: (
                    f"atom ID {first[c] + 1} left the box through the fixed {'xyz'[d]} boundary at step "
                    f"{int(s.step[c])} (LAMMPS: Lost atoms): put a wall on that face, or make it periodic"))

    def compute_forces(self, outputs: bool) -> dict[str, tuple[np.ndarray, ...]]:
        """Force (and torque) clear, pair forces, then post_force walls; with `outputs`, the pair's
        energy and virial (key PAIR) and each wall fix's scalar and vector (key fix-ID)."""
        s = self.state
        s.f.fill(0.0)
        if s.torque is not None:
            s.torque.fill(0.0)
        out: dict[str, tuple[np.ndarray, ...]] = {}
        if self.pair is not None:
            res = self.pair.compute(s.x, s.f, outputs)
            if outputs:
                out[PAIR] = res
        for w in self.soft + self.region_walls:
            res = w.apply(s, outputs)
            if outputs:
                out[w.fix_id] = res
        if outputs and "press" in self.outputs:
            virial = out[PAIR][1].copy() if PAIR in out else np.zeros(s.ncases)
            for w in self.soft + self.region_walls:
                if getattr(w, "virial", False):
                    virial += w.last_virial
            out[VIRIAL] = (virial,)
        return out

    def end_of_step(self) -> None:
        """fix wall/flow: redraw the velocity of atoms that crossed a flow wall (positions were
        wrapped this step, so each crossing redraws once: the decisions table)."""
        s = self.state
        for w in self.flow:
            w.end_of_step(s.x, s.v, s.mass)

    def reset_dt(self) -> np.ndarray:
        """fix dt/reset (physics.md §9): the largest dt (C,) that moves no group atom more than xmax."""
        s, u, spec = self.state, self.state.units, self.dt_reset
        v, f = s.v, s.f
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            dt = dt_candidate(v[..., 0], v[..., 1], v[..., 2], f[..., 0], f[..., 1], f[..., 2], s.mass,
                              float(u.ftm2v), float(u.mvv2e), self.dtr_xmax[:, None], self.dtr_emax[:, None])
        if not spec.group.all():
            dt = np.where(spec.group, dt, np.inf)
        new = np.minimum(dt.min(axis=1), BIG) if dt.shape[1] else np.full(s.ncases, BIG)
        new = np.where(np.isnan(self.dtr_tmin), new, np.maximum(new, self.dtr_tmin))
        return np.where(np.isnan(self.dtr_tmax), new, np.minimum(new, self.dtr_tmax))

    def half_kick(self, dt: np.ndarray) -> np.ndarray:
        """dtfm = dt/2 ftm2v / m (C, N, 3), the same for x, y and z (a full array: the kicks
        v += dtfm f then run over contiguous memory). Kept from step to step while dt and the
        live cases stay the same."""
        s = self.state
        key = self._dtfm_key
        if key is None or key[0] is not s.mass or key[1].shape != dt.shape or not (key[1] == dt).all():
            per_atom = (0.5 * s.units.ftm2v) * dt[:, None] / s.mass
            self._dtfm = np.repeat(per_atom[:, :, None], 3, axis=2)
            self._dtfm_key = (s.mass, dt.copy())
        return self._dtfm

    def step(self, dt: np.ndarray, outputs: bool, active: np.ndarray | None = None) -> dict[str, np.ndarray]:
        """One velocity-Verlet step of every live case (`active` cases only advance in time)."""
        s = self.state
        self.numpy_steps += 1
        s.step += 1 if active is None else active
        s.var_step = {}
        s.ctx = None
        dtfm = self.half_kick(dt)
        self.initial_integrate(dt, dtfm)
        for w in self.reflect:
            w.apply(s, dt)
        self.wrap()
        out = self.compute_forces(outputs)
        if self.ensemble is not None:
            self.ensemble.post_force(s, active)  # langevin, enforce2d
        self.check_lost()
        self.final_integrate(dtfm, dt)
        if self.ensemble is not None:
            self.ensemble.end_of_step(s, active)  # temp/berendsen, temp/rescale, langevin tally
        self.end_of_step()
        if self.dt_reset is not None:
            due = s.step % self.dt_reset.every == 0
            if active is not None:
                due &= active.astype(bool)
            if due.any():
                s.set_dt(np.where(due, self.reset_dt(), s.dt))
        return out

    # -- samples -----------------------------------------------------------------------------

    def sample(self, out: dict[str, tuple[np.ndarray, ...]]) -> None:
        """Record the thermo outputs of every live case at the current step (`out`: the force
        outputs of this step, see compute_forces)."""
        s = self.state
        bad = ~(np.isfinite(s.x).all(axis=(1, 2)) & np.isfinite(s.v).all(axis=(1, 2)))
        if bad.any():
            s.fail(np.nonzero(bad)[0], lambda c: (
                f"positions or velocities became NaN/inf by step {int(s.step[c])}: the timestep is too "
                f"large for these forces (lower timestep, or add dt_reset)"))
        erot = None
        if s.quat is not None:  # compute erotate/asphere joins ke, so etot is the conserved total
            erot = s.units.mvv2e * rotational_energy(s.quat, s.angmom, s.inertia).sum(axis=1)
        reflect = None
        if self.reflect and self.reflect[0].stats:
            counts, impulses = zip(*(w.take_stats() for w in self.reflect))
            reflect = (np.concatenate(counts, axis=1), np.concatenate(impulses, axis=1))
        rec = self.record(
            step=s.step, time=s.time, dt=s.dt.copy(), mv2=kinetic_sum(s.v, s.mass), out=out, reflect=reflect,
            crossings=sum(w.take_crossings() for w in self.flow) if self.flow else None,
            ecouple=self.ensemble.ecouple(s.ncases) if self.ensemble is not None else None, erot=erot)
        self.samples.append(rec)
        self.sample_rows.append(s.rows.copy())
        self.sample_index.append(self.nsampled)
        self.nsampled += 1

    def record(self, step: np.ndarray, time: np.ndarray, dt: np.ndarray, mv2: np.ndarray,
               out: dict[str, tuple[np.ndarray, ...]], reflect: tuple[np.ndarray, np.ndarray] | None = None,
               crossings: np.ndarray | None = None, ecouple: np.ndarray | None = None,
               erot: np.ndarray | None = None) -> dict[str, np.ndarray]:
        """The thermo record of samples from their ingredients, arrays with a leading shape L: (C,)
        for one sample (Engine.sample), (C, S) for S samples of a compiled chunk. mv2: sum m v^2
        (translational); `out`: the force outputs (compute_forces: fix-ID -> (scalar L, vector
        (L, faces) or (L, 3)), PAIR, VIRIAL); reflect: counts and impulses (L, faces); crossings:
        flow redraws (L,); ecouple: the thermostats' exchanged energy (L,); erot: rotational ke."""
        u = self.state.units
        lead = np.shape(mv2)
        n = self.state.x.shape[1]
        ke = 0.5 * u.mvv2e * mv2  # translational
        dim = self.cases[0].dimension
        dof = dim * n - dim  # compute temp: the centre of mass's dof removed
        rec: dict[str, np.ndarray] = {
            "step": step.astype(float), "time": time, "dt": dt,
            "temp": 2.0 * ke / (dof * u.boltz) if dof > 0 else np.zeros(lead),
            "atoms": np.full(lead, float(n)),
        }
        if erot is not None:
            rec["erot"] = erot
            ke = ke + erot
        pe = out[PAIR][0].copy() if PAIR in out else np.zeros(lead)
        scalar_fixes = self.soft + self.region_walls
        if scalar_fixes:
            by_id = {w.fix_id: w for w in scalar_fixes}
            rec["wall_energy"] = np.stack([out[fid][0] for fid in self.cases[0].fix_order], axis=-1)
            for fid in self.cases[0].fix_order:
                if by_id[fid].energy_to_pe:
                    pe = pe + out[fid][0]
        if self.soft:
            rec["wall_force"] = np.concatenate([out[w.fix_id][1] for w in self.soft], axis=-1)
        if self.region_walls:
            rec["region_force"] = np.stack([out[w.fix_id][1] for w in self.region_walls], axis=-2)
        if reflect is not None:
            rec["reflect_count"], rec["reflect_impulse"] = reflect
        if crossings is not None:
            rec["flow_crossings"] = crossings
        if VIRIAL in out:  # LAMMPS compute pressure: (sum m v^2 + W) / (3 V), translational ke
            volume = float(np.prod((self.state.box_hi - self.state.box_lo)[:dim]))  # 2-D: the area
            rec["press"] = (u.mvv2e * mv2 + out[VIRIAL][0]) / (dim * volume) * u.nktv2p
        rec["ke"] = ke
        rec["pe"] = pe
        rec["etot"] = pe + ke
        # thermostats' exchanged energy (LAMMPS ecouple) and etot + ecouple (econserve)
        rec["ecouple"] = ecouple if ecouple is not None else np.zeros(lead)
        rec["econserve"] = rec["etot"] + rec["ecouple"]
        return rec

    def record_samples(self, out: dict[str, tuple[np.ndarray, ...]], virial: np.ndarray | None = None,
                       pair: tuple[np.ndarray, np.ndarray] | None = None, **ingredients: np.ndarray) -> None:
        """Append S samples of every live case computed by a compiled chunk: `record`'s
        ingredients with a leading (C, S), the total virial W (C, S) when press is an output, the
        pair style's (energy, virial) (C, S) in a pair scene."""
        if pair is not None:
            out = {**out, PAIR: pair}
        if virial is not None:
            out = {**out, VIRIAL: (virial,)}
        self.record_block(self.record(out=out, **ingredients))

    def record_block(self, rec: dict[str, np.ndarray]) -> None:
        """Append S samples of every live case at once (rec: name -> (C, S, ...) arrays, from
        `record`; the compiled path's sampled chunks)."""
        nsamp = next(iter(rec.values())).shape[1]
        self.sample_blocks.append((self.nsampled, self.state.rows.copy(), rec))
        self.nsampled += nsamp

    def drop_failed(self) -> None:
        s = self.state
        if not s.failed:
            return
        for c, msg in s.failed.items():
            self.errors[int(s.rows[c])] = msg
        keep = np.array([c not in s.failed for c in range(s.ncases)])
        s.failed = {}
        s.take(keep)
        for w in self.soft + self.reflect + self.region_walls + self.flow:
            w.take(keep)
        if self.pair is not None:
            self.pair.take(keep)
        if self.ensemble is not None:
            self.ensemble.take(keep)
        if self.dt_reset is not None:
            for name in ("dtr_xmax", "dtr_emax", "dtr_tmin", "dtr_tmax"):
                setattr(self, name, getattr(self, name)[keep])

    # -- the run -----------------------------------------------------------------------------

    def setup(self) -> None:
        """Forces and outputs at step 0, then dt/reset (after all forces: the decisions table)."""
        s = self.state
        for w in self.reflect:
            w.setup(s)
        for w in self.flow:
            w.setup(s.x)
        out = self.compute_forces(True)
        if self.ensemble is not None:
            self.ensemble.setup(s)  # langevin and enforce2d forces, chain masses
        if self.dt_reset is not None:
            s.set_dt(self.reset_dt())
        self.finish_step(out, sample=True)

    def finish_step(self, out: dict[str, np.ndarray], sample: bool) -> None:
        """Drop the cases that failed during the step (and their rows of `out`), then sample."""
        s = self.state
        if s.failed:
            keep = np.array([c not in s.failed for c in range(s.ncases)])
            out = {k: tuple(a[keep] for a in val) for k, val in out.items()}
            self.drop_failed()
        if sample and s.ncases:
            self.sample(out)
            self.drop_failed()

    def advance(self, nsteps: int, sample: bool = True) -> None:
        """Advance every live case by nsteps steps, then sample (outputs computed on the last step)."""
        if self.fast is not None and self._compiled(self.fast.advance, nsteps, sample):
            return
        self.advance_numpy(nsteps, sample)

    def _compiled(self, call: Callable[..., Any], *args: Any) -> Any:
        """`call(*args)`, a call of the compiled path, counting the steps its kernels ran in
        `compiled_steps`: the steps the live cases advanced less those the NumPy loop ran inside it
        (a chunk handed back in part)."""
        s = self.state
        before, numpy_before = (int(s.step.max()) if s.ncases else 0), self.numpy_steps
        done = call(*args)
        if done and s.ncases:
            self.compiled_steps += max(0, int(s.step.max()) - before - (self.numpy_steps - numpy_before))
        return done

    def advance_numpy(self, nsteps: int, sample: bool = True) -> None:
        """Engine.advance in NumPy, step by step."""
        for i in range(nsteps):
            if self.state.ncases == 0:
                return
            last = sample and i == nsteps - 1
            self.finish_step(self.step(self.state.dt, outputs=last), sample=last)

    def dump_frame(self) -> None:
        """Record positions/velocities of every live case (output.dump)."""
        s = self.state
        self.frames.append((s.rows.copy(), s.time.copy(), s.x.copy() if "x" in self.dump_fields else None,
                            s.v.copy() if "v" in self.dump_fields else None))

    def advance_to_time(self, target: float) -> None:
        """Step until every live case's time reaches `target`, clipping the last dt to land on it."""
        if self.fast is not None and self._compiled(self.fast.advance_to_time, target):
            return
        s = self.state
        tol = landing_tol(target)
        while s.ncases and np.any(s.time < target - tol):
            now = s.time
            active = now < target - tol
            base = s.dt.copy()
            step_dt = np.where(active, np.minimum(base, target - now), 0.0)
            landing = active & (base >= target - now - tol)
            done_after = ~np.any(active & ~landing)
            s.set_dt(step_dt)
            out = self.step(s.dt, outputs=done_after, active=active.astype(np.int64))
            # land exactly, then restore the dt in force (dt/reset may have changed it). The time
            # accumulator closes only where the run lands or dt changes: at a fixed dt the time is
            # atime + n dt from the step count, as in step-based runs, not a sum of n additions
            new_base = np.where(s.dt != step_dt, s.dt, base)
            close = landing | (new_base != s.dt)
            s.atime = np.where(landing, target, np.where(close, s.time, s.atime))
            s.atimestep = np.where(close, s.step, s.atimestep)
            s.dt = new_base
            self.finish_step(out, sample=done_after)
            if done_after:
                return

    def minimize(self) -> None:
        """LAMMPS `minimize` before the run (issue 8): pair and soft/region wall forces act; the
        objective holds the pair energy and the energies of walls with `energy: true` only (LAMMPS:
        fix_modify energy). Reflect, flow and dt/reset are skipped; orientations are not minimized.
        Walls with variables that change with the step see LAMMPS's clock at each evaluation (the
        minimizer's iteration as the step, ramp over maxiter, fire's dt; BatchState.set_min_clock);
        the clock is back at step 0 and the case's dt afterwards. Per case: min_iterations,
        min_evaluations, min_stop_reason, min_energy_before, min_energy, min_fnorm."""
        s = self.state
        scalar_fixes = self.soft + self.region_walls

        def objective(x: np.ndarray, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            s.x[rows] = x
            self.wrap()
            out = self.compute_forces(True)
            energy = out[PAIR][0].copy() if PAIR in out else np.zeros(s.ncases)
            for w in scalar_fixes:
                if w.energy_to_pe:
                    energy += out[w.fix_id][0]
            return energy[rows], s.f[rows].copy()

        settings = self.cases[0].minimize
        moving = self._walls_use_time()  # LAMMPS's step (and fire's dt) at each evaluation: the wall moves
        step0, dt0 = s.step.copy(), s.dt.copy()

        def clock(steps: np.ndarray, dt: np.ndarray | None) -> None:
            s.min_iteration = steps  # (messages: "in minimize iteration N")
            if moving:
                s.set_min_clock(steps, dt, settings.maxiter)

        try:
            res = minimize(s.x.copy(), objective, settings, mass=s.mass, ftm2v=s.units.ftm2v, clock=clock,
                           moving=moving)
        finally:
            s.min_iteration = None
            if moving:
                s.end_min_clock(step0, dt0)
        s.x[:] = res.x
        self.wrap()
        for j, row in enumerate(s.rows.tolist()):
            self.min_info[row] = {
                "min_iterations": np.float64(res.iterations[j]), "min_evaluations": np.float64(res.evaluations[j]),
                "min_stop_reason": np.str_(res.stop_reason[j]), "min_energy_before": np.float64(res.energy_before[j]),
                "min_energy": np.float64(res.energy_after[j]), "min_fnorm": np.float64(res.fnorm2[j]),
            }
        self.drop_failed()

    def _walls_use_time(self) -> bool:
        """A wall acting in `minimize` (flat soft or region wall) has a position or parameter from a
        variable that changes with the step (step, time, ramp, ... transitively)."""
        names = [v for w in self.soft for face in w.faces for v in [face.coord, *face.params.values()]]
        names += [v for w in self.region_walls for v in w.params.values()]
        return any(self.state.variables.depends_on_time(n) for n in names if isinstance(n, str))

    def _charge(self, since: float) -> float:
        """Share the wall-clock seconds since `since` among the live cases (each case's `seconds`
        is the time it was running, divided among the cases running with it)."""
        now = _time.perf_counter()
        rows = self.state.rows
        if len(rows):
            self.case_seconds[rows] += (now - since) / len(rows)
        return now

    def run(self) -> list[CaseResult]:
        t = _time.perf_counter()
        self.case_seconds = np.zeros(len(self.cases))
        c0 = self.cases[0]
        with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
            if c0.minimize is not None:
                self.minimize()
                t = self._charge(t)
            if self.state.ncases == 0:
                return self._collect(self.case_seconds)
            self.setup()
            t = self._charge(t)
            if c0.run_time is None:
                samples = set(sample_instants(c0))
                dumps = set(range(0, c0.steps + 1, c0.dump_every)) if c0.dump_every else set()
                profile = set(self.profiles.instants) if self.profiles else set()  # never step 0
                if 0 in dumps:
                    self.dump_frame()
                done = 0
                instants = sorted(samples | dumps | profile)[1:]
                i = 0
                while i < len(instants):
                    # a run of sample instants in one compiled call, if the fast path records samples
                    # itself (compiled.sampled_eligible): up to the next dump or profile instant,
                    # included if it is a sample instant too
                    j = i
                    while j < len(instants) and j - i < SAMPLES_PER_CALL:
                        j += 1
                        if instants[j - 1] in dumps or instants[j - 1] in profile:
                            j -= instants[j - 1] not in samples
                            break
                    sampled = getattr(self.fast, "advance_sampled", None)
                    ran = 0
                    if j > i and sampled is not None and self.state.ncases:
                        # a far first sample: the steps before its last kernel call first, in calls
                        # of their own (a Ctrl-C is seen between calls)
                        lead = self.fast.lead_steps(np.array(instants[i:j], np.int64) - done)
                        if lead:
                            self.advance(lead, sample=False)
                            done += lead
                        if self.state.ncases:
                            ran = self._compiled(sampled, np.array(instants[i:j], np.int64) - done)
                    if ran:
                        done = instants[i + ran - 1]
                        i += ran
                        if done in dumps and self.state.ncases:
                            self.dump_frame()
                        if done in profile:
                            self.profiles.sample(self.state)
                        t = self._charge(t)
                        continue
                    target = instants[i]
                    self.advance(target - done, sample=target in samples)
                    done = target
                    if target in dumps and self.state.ncases:
                        self.dump_frame()
                    if target in profile:
                        self.profiles.sample(self.state)
                    t = self._charge(t)
                    i += 1
            else:
                for target in sample_instants(c0)[1:]:
                    self.advance_to_time(target)
                    t = self._charge(t)
        return self._collect(self.case_seconds)

    def _collect(self, seconds: np.ndarray) -> list[CaseResult]:
        """Per-case samples on the full schedule (NaN where a case had failed); `seconds` per case."""
        C = len(self.cases)
        c0 = self.cases[0]
        nsamp = len(sample_instants(c0))
        results = []
        if self.samples:
            names, shapes = self.samples[0].keys(), {k: v.shape[1:] for k, v in self.samples[0].items()}
        elif self.sample_blocks:
            names, shapes = self.sample_blocks[0][2].keys(), {k: v.shape[2:] for k, v in self.sample_blocks[0][2].items()}
        else:
            names, shapes = [], {}
        stacked = {}
        for name in names:
            arr = np.full((C, nsamp) + shapes[name], np.nan)
            for k, rec, rows in zip(self.sample_index, self.samples, self.sample_rows):
                arr[rows, k] = rec[name]
            for k0, rows, rec in self.sample_blocks:
                block = rec[name]
                arr[rows, k0:k0 + block.shape[1]] = block
            stacked[name] = arr
        picks: list[list[tuple]] = [[] for _ in range(C)]  # per case: (time, x, v) of its frames
        for rows, t, x, v in self.frames:
            for j, c in enumerate(rows.tolist()):
                picks[c].append((t[j], None if x is None else x[j], None if v is None else v[j]))
        frames: list[dict[str, np.ndarray]] = []
        for p in picks:
            fr = {"time": np.array([f[0] for f in p])} if p else {}
            for k, name in ((1, "x"), (2, "v")):
                if p and name in self.dump_fields:
                    fr[name] = np.stack([f[k] for f in p])
            frames.append(fr)
        for c in range(C):
            if c in self.errors:
                data = {k: np.full_like(v[c], np.nan) for k, v in stacked.items()}
                results.append(CaseResult("failed", self.errors[c], float(seconds[c]), data, frames[c]))
            else:
                results.append(CaseResult("ok", "", float(seconds[c]), {k: v[c] for k, v in stacked.items()},
                                          frames[c]))
            results[-1].compiled_steps, results[-1].numpy_steps = self.compiled_steps, self.numpy_steps
            results[-1].data.update(self.min_info.get(c, {}))
            if self.profiles is not None:
                results[-1].data.update(self.profiles.case_data(c, failed=c in self.errors))
        return results


def sample_steps(steps: int, every: int) -> list[int]:
    """Sample steps: 0, every `every` steps, and the last step (0: first and last only)."""
    if every <= 0:
        return sorted({0, steps})
    return sorted(set(range(0, steps + 1, every)) | {steps})


def sample_times(total: float, every: float) -> list[float]:
    """Sample times: 0, every `every` time units (exact multiples), and the end time."""
    if every <= 0:
        return [0.0, total]
    n = int(np.floor(total / every + 1e-9))
    times = [k * every for k in range(n + 1)]
    if total - times[-1] > 1e-9 * every:
        times.append(total)
    return times


def sample_instants(case: Case) -> list:
    """The case's sample steps (step-based run) or sample times (run to a simulated time)."""
    if case.run_time is None:
        return sample_steps(case.steps, int(case.thermo))
    return sample_times(case.run_time, float(case.thermo) if case.thermo_is_time else 0.0)


def _weak_method(method: Callable[[], Any]) -> Callable[[], Any]:
    """`method` (a bound method) as a callable that does not keep its object alive. The compiled
    path keeps its engine's plan callback; with the bound method itself, engine and path would be a
    reference cycle, and a finished batch (its cases and state arrays: a window of a sweep, up to
    hundreds of MB) would stay in memory until Python's next full garbage collection, whose timing
    depends on everything else the process holds."""
    ref = weakref.WeakMethod(method)

    def call() -> Any:
        bound = ref()
        if bound is None:
            raise ReferenceError("the engine of this compiled path is gone")
        return bound()

    return call


def run_batch(cases: list[Case]) -> list[CaseResult]:
    """Run cases that share a structure as one batch."""
    return Engine(cases).run()


def run_cases(cases: list[Case]) -> list[CaseResult]:
    """Run any cases: group them into batches by structure, return results in input order."""
    batches: dict[tuple, list[int]] = {}
    for i, c in enumerate(cases):
        batches.setdefault(structure_key(c), []).append(i)
    results: list[CaseResult | None] = [None] * len(cases)
    for idx in batches.values():
        try:
            batch = run_batch([cases[i] for i in idx])
        except Exception as exc:  # a bug must not take down the other batches: fail these cases
            msg = f"internal error ({type(exc).__name__}: {exc}); please report it with the config"
            batch = [CaseResult("failed", msg, 0.0, {}) for _ in idx]
        for i, res in zip(idx, batch):
            results[i] = res
    return results  # type: ignore[return-value]
