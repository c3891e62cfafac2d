"""Batch state: positions, velocities, forces, clocks and variables of C cases of N atoms, and the
per-face values of a fix over a batch.
"""

from __future__ import annotations

from typing import Callable

import numpy as np

from wallbatch.expr import EvalContext, VariableError, Variables
from wallbatch.geometry.quaternion import inertia
from wallbatch.scene.case import Case, Face
from wallbatch.units import UnitSystem


def landing_tol(target: float) -> float:
    """A run to the simulated time `target` [time]: a case whose time is within this of it has
    arrived (Engine.advance_to_time, the compiled chunks' time mode and the pair chunks' count of
    the steps before a landing all use it)."""
    return 1e-12 * max(1.0, abs(target))


class BatchState:
    """Positions, velocities, forces and clocks of C cases of N atoms, plus failure bookkeeping."""

    def __init__(self, cases: list[Case]):
        c0 = cases[0]
        self.units: UnitSystem = c0.units
        self.rows = np.arange(len(cases))  # original index of each live row
        self.x = np.stack([c.x for c in cases]).astype(float)
        self.v = np.stack([c.v for c in cases]).astype(float)
        self.f = np.zeros_like(self.x)
        self.mass = np.stack([c.mass for c in cases])
        self.radius = np.stack([c.radius for c in cases])
        self.box_lo, self.box_hi = c0.box_lo, c0.box_hi
        self.periodic = np.nonzero(c0.periodic)[0]
        self.fixed = np.nonzero(~c0.periodic)[0]
        self.dt = np.array([c.dt for c in cases], float)
        self.atime = np.zeros(len(cases))  # LAMMPS time accumulator: time = atime + (step - atimestep) dt
        self.atimestep = np.zeros(len(cases), np.int64)
        self.step = np.zeros(len(cases), np.int64)
        self.variables: Variables = c0.variables
        # constant variables whose value differs between the cases: per-case arrays
        consts = {k: np.array([c.variables.constant_value(k) for c in cases]) for k, _ in c0.variable_text
                  if c0.variables.constant_value(k) is not None}
        self.var_values = {k: v for k, v in consts.items() if np.any(v != v[0])}
        self.var_static: dict[str, np.ndarray] = {}
        self.var_step: dict[str, np.ndarray] = {}
        self.ctx: EvalContext | None = None  # this step's variable context
        # vdisplace/swiggle/cwiggle: LAMMPS's (n - b) dt, or elapsed simulated time when dt varies
        self.elapsed_is_time = c0.dt_reset is not None or c0.run_time is not None
        self.end_step = c0.steps or 0
        self.min_iteration: np.ndarray | None = None  # during Engine.minimize: each case's iteration (C,)
        self.run_time = c0.run_time
        # during `minimize` (set_min_clock): its maxiter, LAMMPS's run length while it minimizes
        self.min_maxiter: int | None = None
        self.failed: dict[int, str] = {}  # live row -> message, pending removal
        # ellipsoids only (None otherwise): quaternions (C,N,4), angular momentum, torque, semi-axes
        # and principal moments of inertia (C,N,3)
        self.quat: np.ndarray | None = None
        self.angmom: np.ndarray | None = None
        self.torque: np.ndarray | None = None
        self.shape: np.ndarray | None = None
        self.inertia: np.ndarray | None = None
        if c0.shape is not None:
            self.quat = np.stack([c.quat for c in cases]).astype(float)
            self.angmom = np.stack([c.angmom for c in cases]).astype(float)
            self.torque = np.zeros_like(self.angmom)
            self.shape = np.stack([c.shape for c in cases]).astype(float)
            self.inertia = inertia(self.mass, self.shape)

    @property
    def ncases(self) -> int:
        return self.x.shape[0]

    @property
    def time(self) -> np.ndarray:
        return self.atime + (self.step - self.atimestep) * self.dt

    def set_dt(self, new_dt: np.ndarray) -> None:
        """Change the timestep, closing the time accumulator first (as fix dt/reset does)."""
        changed = new_dt != self.dt
        if changed.any():
            self.atime = np.where(changed, self.time, self.atime)
            self.atimestep = np.where(changed, self.step, self.atimestep)
            self.dt = np.where(changed, new_dt, self.dt)

    # -- variables -------------------------------------------------------------------------

    def context(self, steps: np.ndarray | None = None) -> EvalContext:
        """What variables see at the current step (built once per step, see `variable`), or, with
        `steps` (an (S, C) array of later steps at the current dt), at each of those steps (the
        compiled path's per-step wall values; not cached)."""
        if steps is None and self.ctx is not None:
            return self.ctx
        step = self.step if steps is None else steps
        time = self.atime + (step - self.atimestep) * self.dt
        steps_done = step.astype(float)
        end_step = self.end_step
        if self.min_maxiter is not None:  # minimize: a run of maxiter steps, (n - b) dt elapsed
            end_step = self.min_maxiter
            ramp = steps_done / end_step if end_step > 0 else np.zeros(self.ncases)
            elapsed = steps_done * self.dt
        else:
            if self.run_time is not None:
                ramp = time / self.run_time
            else:
                ramp = steps_done / self.end_step if self.end_step > 0 else np.zeros(self.ncases)
            elapsed = time if self.elapsed_is_time else steps_done * self.dt
        ctx = EvalContext(step=step, begin_step=0, end_step=end_step, dt=self.dt, time=time,
                          elapsed_time=elapsed, ramp_fraction=ramp, box_lo=tuple(self.box_lo),
                          box_hi=tuple(self.box_hi), atoms=self.x.shape[1], values=self.var_values)
        if steps is None:
            self.ctx = ctx
        return ctx

    def set_min_clock(self, steps: np.ndarray, dt: np.ndarray | None, maxiter: int) -> None:
        """What variables see at a force evaluation of `minimize` (LAMMPS's clock there): the step
        counter at the minimizer's count (0, then one more per iteration), `ramp` over maxiter
        steps, and with fire its current timestep as `dt` (`time` = step dt, as LAMMPS's fire,
        which changes the timestep without closing the time accumulator). Before a run only: the
        time accumulator is still at step 0, time 0. `end_min_clock` puts the clock back."""
        self.step = np.asarray(steps, np.int64)
        if dt is not None:
            self.dt = np.asarray(dt, float)
        self.min_maxiter = int(maxiter)
        self.var_step = {}
        self.ctx = None

    def end_min_clock(self, step: np.ndarray, dt: np.ndarray) -> None:
        """Back to the run's clock (`step`, `dt`: what they were before `minimize`)."""
        self.step, self.dt, self.min_maxiter = step, dt, None
        self.var_step = {}
        self.ctx = None

    def at(self, c: int) -> str:
        """When case c is, for messages: "at step N", or during `minimize` "in minimize iteration
        N" (LAMMPS's minimizer counts its iterations as steps)."""
        if self.min_iteration is not None:
            return f"in minimize iteration {int(self.min_iteration[c])}"
        return f"at step {int(self.step[c])}"

    def variable(self, name: str) -> np.ndarray:
        """Value (C,) of an equal-style variable at the current step; constants are evaluated once."""
        cache = self.var_step if self.variables.depends_on_time(name) else self.var_static
        if name not in cache:
            try:
                value = self.variables.evaluate(name, self.context())
            except VariableError:
                value = self._variable_per_case(name)
            cache[name] = np.broadcast_to(np.asarray(value, float), (self.ncases,))
        return cache[name]

    def _variable_per_case(self, name: str) -> np.ndarray:
        """Slow path after an evaluation error: find the cases that fail, fail them, NaN there."""
        out = np.full(self.ncases, np.nan)
        ctx = self.context()
        for c in range(self.ncases):
            one = EvalContext(**{k: (v[c:c + 1] if isinstance(v, np.ndarray) else v) for k, v in vars(ctx).items()
                                 if k != "values"}, values={k: v[c:c + 1] for k, v in ctx.values.items()})
            try:
                out[c] = self.variables.evaluate(name, one)[0]
            except VariableError as exc:
                self.fail(np.array([c]), lambda _c, e=exc: f"variables.{name} {self.at(_c)}: {e}")
        return out

    # -- failures --------------------------------------------------------------------------

    def fail(self, rows: np.ndarray, message: Callable[[int], str]) -> None:
        for c in np.atleast_1d(rows).tolist():
            self.failed.setdefault(int(c), message(int(c)))

    def take(self, keep: np.ndarray) -> None:
        for name in ("rows", "x", "v", "f", "mass", "radius", "dt", "atime", "atimestep", "step"):
            setattr(self, name, getattr(self, name)[keep])
        if self.quat is not None:
            for name in ("quat", "angmom", "torque", "shape", "inertia"):
                setattr(self, name, getattr(self, name)[keep])
        self.var_static = {k: v[keep] for k, v in self.var_static.items()}
        self.var_values = {k: v[keep] for k, v in self.var_values.items()}
        self.ctx = None
        self.var_step = {}




Stacked = np.ndarray | str  # per-case numbers (C,), or a variable name


def stack_values(values: list[float | str], what: str) -> Stacked:
    """Per-case values of one field: numbers stack into an array; a variable must be the same
    variable in every case of a batch."""
    if all(isinstance(v, float) for v in values):
        return np.asarray(values, dtype=float)
    if all(v == values[0] for v in values):
        return values[0]
    raise ValueError(f"{what}: cases mixing numbers and variables cannot share a batch")


class FaceValues:
    """The values of one face over a batch, resolved each step through `value()`."""

    def __init__(self, faces: list[Face]):
        f0 = faces[0]
        self.label, self.name, self.dim, self.side, self.scale = f0.label, f0.name, f0.dim, f0.side, f0.scale
        self.coord = stack_values([f.coord for f in faces], f"{f0.label} coord")
        self.params = {k: stack_values([f.params[k] for f in faces], f"{f0.label} {k}") for k in f0.params}
        # numbers only, no variable: position() and param() are these arrays at every step
        self.constant = all(isinstance(v, np.ndarray) for v in (self.coord, *self.params.values()))

    def take(self, keep: np.ndarray) -> None:
        if isinstance(self.coord, np.ndarray):
            self.coord = self.coord[keep]
        for k, v in self.params.items():
            if isinstance(v, np.ndarray):
                self.params[k] = v[keep]

    def position(self, state: "BatchState") -> np.ndarray:
        """Wall position (C,) in box units at the current step."""
        if isinstance(self.coord, np.ndarray):
            return self.coord
        return state.variable(self.coord) * self.scale

    def param(self, key: str, state: "BatchState") -> np.ndarray:
        v = self.params[key]
        return v if isinstance(v, np.ndarray) else state.variable(v)


