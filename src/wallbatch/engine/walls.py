"""Wall kernels on a batch: flat soft walls (post_force) and reflecting walls (post_integrate).

A kernel holds one fix for every case of a batch: per-face values are `(C,)` arrays (a number per
case) or the name of an equal-style variable (the same expression for the whole batch). Only
atoms within the cut-off of a face are touched: `np.nonzero` picks them, so the work per step
scales with the atoms near walls, not with N.
"""

from __future__ import annotations

import numpy as np

from wallbatch.engine.region_walls import RegionEESKernel, RegionWallKernel
from wallbatch.engine.state import BatchState, FaceValues
from wallbatch.engine.stochastic import StochasticKernel
from wallbatch.scene.case import Case, CustomWallSpec, ReflectSpec, SoftWallSpec, StochasticSpec
from wallbatch.geometry.quaternion import rotation_matrix
from wallbatch.styles.ees import ees_energy_force_torque, ees_torque, sigma_n
from wallbatch.styles.base import WallStyle
from wallbatch.styles.cutoff import CutoffStyle


def at_atoms(p: dict[str, np.ndarray], ci: np.ndarray) -> dict[str, np.ndarray]:
    """A face's per-case parameters (C,) at the selected atoms of cases `ci`. A (1,) array (one
    case) stays as it is: it broadcasts against the atoms' distances to the same numbers as its
    gather would give, without a gather per parameter per step."""
    return {key: val if val.shape == (1,) else val[ci] for key, val in p.items()}


def add_along(f: np.ndarray, ci: np.ndarray, ai: np.ndarray, dim: int, values: np.ndarray) -> None:
    """f[ci, ai, dim] += values, each (case, atom) once. With one case, through the atoms' 1-D view
    of that component (a third of the time of the 3-index scatter on a small run's few atoms)."""
    if f.shape[0] == 1:
        column = f[0, :, dim]  # a view
        column[ai] += values
    else:
        f[ci, ai, dim] += values


class SoftWallKernel:
    """fix wall/lj93 | lj126 | lj1043 | colloid | harmonic | morse over a batch (physics.md §3-4)."""

    def __init__(self, specs: list[SoftWallSpec]):
        s0 = specs[0]
        self.fix_id: str = s0.fix_id
        self.style: WallStyle = s0.style
        self.cutoff = CutoffStyle(s0.style, s0.cutoff_mode)  # the style under the wall's cut-off mode
        self.group: np.ndarray = s0.group
        self.all_atoms = bool(s0.group.all())
        self.energy_to_pe: bool = s0.energy
        self.virial: bool = s0.virial  # fix_modify virial: sum of F r, set on output steps
        self.last_virial: np.ndarray | None = None
        self.faces = [FaceValues([s.faces[i] for s in specs]) for i in range(len(s0.faces))]

    def take(self, keep: np.ndarray) -> None:
        for face in self.faces:
            face.take(keep)

    def apply(self, state: "BatchState", outputs: bool) -> tuple[np.ndarray, np.ndarray] | None:
        """Add wall forces to state.f. With `outputs`, return the fix's global scalar (C,) (shifted
        energy) and vector (C, faces) (sum of side*F = force of the atoms on each wall, §3.2)."""
        C = state.ncases
        energy = np.zeros(C) if outputs else None
        vector = np.zeros((C, len(self.faces))) if outputs else None
        if outputs and self.virial:
            self.last_virial = np.zeros(C)
        for k, face in enumerate(self.faces):
            p, ci, ai, r = self.face_atoms(state, face)
            if ci.size == 0:
                continue
            pa = at_atoms(p, ci)
            if self.style.needs_radius:
                pa["radius"] = state.radius[ci, ai]
            limit = self.style.too_close(pa)
            if np.ndim(limit) == 0 and not r.min() <= limit:  # one reduction where the limit is one number
                bad = None
            else:
                bad = r <= limit
            if bad is not None and bad.any():
                self._fail_inside(state, ci[bad], ai[bad], r[bad], face.name)
                ok = ~bad
                ci, ai, r = ci[ok], ai[ok], r[ok]
                pa = {key: val[ok] if val.shape == ok.shape else val for key, val in pa.items()}
            f = self.cutoff.force(r, pa)
            add_along(state.f, ci, ai, face.dim, -face.side * f)
            if outputs:
                e_shifted = self.cutoff.energy(r, pa)  # E(r) - E(rc) without cancellation (shift)
                energy += np.bincount(ci, weights=e_shifted, minlength=C)
                vector[:, k] = np.bincount(ci, weights=face.side * f, minlength=C)
                if self.virial:  # +F r on the (dim, dim) component, lo and hi alike (physics.md §3.4)
                    self.last_virial += np.bincount(ci, weights=f * r, minlength=C)
        return (energy, vector) if outputs else None

    def face_atoms(self, state: "BatchState", face: FaceValues) -> tuple[dict[str, np.ndarray], np.ndarray,
                                                                         np.ndarray, np.ndarray]:
        """This step's parameters of a face (C,) and its group atoms within the cut-off: case and
        atom indices and their distance delta from the wall (§3.2). A variable epsilon, sigma, D0
        or r0 below 0 fails its case (LAMMPS: Variable evaluation in fix wall gave bad value)."""
        if face.constant:  # numbers only (the usual case): nothing to evaluate or check this step
            coord, p = face.coord, face.params
        else:
            coord = face.position(state)
            p = {key: face.param(key, state) for key in face.params}
            for prm in self.style.parameters:  # variables only: constants are checked up front
                key, low = prm.name, prm.min
                if low is not None and isinstance(face.params.get(key), str) and np.any(bad := p[key] < low):
                    state.fail(np.nonzero(bad)[0],
                               lambda c: f"walls.{self.fix_id} {face.name}: variable {key} evaluated to "
                               f"{p[key][c]:g} < {low:g}: Variable evaluation in fix wall gave bad value")
        pos = state.x[:, :, face.dim]
        delta = pos - coord[:, None] if face.side < 0 else coord[:, None] - pos
        near = delta < p["cutoff"][:, None]
        if not self.all_atoms:
            near &= self.group
        flat = near.ravel().nonzero()[0]  # c * N + a (1-D: cheaper than 2-D nonzero and indexing)
        if near.shape[0] == 1:  # one case: the flat index is the atom's
            ci, ai = np.zeros(flat.size, flat.dtype), flat
        else:
            ci, ai = np.divmod(flat, near.shape[1])
        return p, ci, ai, delta.ravel()[flat]

    def _fail_inside(self, state: "BatchState", ci: np.ndarray, ai: np.ndarray, r: np.ndarray,
                     face: str) -> None:
        what = ("its surface touches or crosses the wall" if self.style.needs_radius or self.style.needs_shape
                else "it is on or behind the wall")
        first: dict[int, tuple[int, float]] = {}
        for c, a, d in zip(ci.tolist(), ai.tolist(), r.tolist()):
            first.setdefault(c, (a, d))
        state.fail(np.array(sorted(first)), lambda c: (
            f"walls.{self.fix_id} (wall/{self.style.name} {face}): atom ID {first[c][0] + 1} at distance "
            f"{first[c][1]:.6g} from the wall {state.at(c)}: {what} "
            f"(LAMMPS: Particle on or inside fix wall surface)"))


class EESWallKernel(SoftWallKernel):
    """fix wall/ees over a batch (physics.md §4.7): ellipsoids against flat faces. The normal
    n = -side e_dim points from the wall into the allowed region; sigma_n is the centre-to-tangent
    plane distance along n. Force -side F along dim, torque T_w (n x A S^2 A^T n), energy
    unshifted (LAMMPS); an atom with delta <= sigma_n is on or inside the wall."""

    def apply(self, state: "BatchState", outputs: bool) -> tuple[np.ndarray, np.ndarray] | None:
        C = state.ncases
        energy = np.zeros(C) if outputs else None
        vector = np.zeros((C, len(self.faces))) if outputs else None
        for k, face in enumerate(self.faces):
            p, ci, ai, r = self.face_atoms(state, face)
            if ci.size == 0:
                continue
            normal = np.zeros(3)
            normal[face.dim] = -face.side
            q, shape = state.quat[ci, ai], state.shape[ci, ai]
            rot = rotation_matrix(q)  # once for sigma_n and the torque
            sn = sigma_n(q, shape, normal, rot)
            bad = r <= sn
            if bad.any():
                self._fail_inside(state, ci[bad], ai[bad], r[bad], face.name)
                ok = ~bad
                ci, ai, r, sn, q, shape, rot = ci[ok], ai[ok], r[ok], sn[ok], q[ok], shape[ok], rot[ok]
            e, f, tw = ees_energy_force_torque(r, sn, p["epsilon"][ci], p["sigma"][ci])
            add_along(state.f, ci, ai, face.dim, -face.side * f)
            state.torque[ci, ai] += ees_torque(q, shape, normal, tw, rot)
            if outputs:
                energy += np.bincount(ci, weights=e, minlength=C)
                vector[:, k] = np.bincount(ci, weights=face.side * f, minlength=C)
        return (energy, vector) if outputs else None


class CustomWallKernel(SoftWallKernel):
    """fix wall/lepton and wall/table over a batch: the soft-wall kernel run face by face, each
    face with its own style (expression or table); outputs as for the other soft walls."""

    def __init__(self, specs: list[CustomWallSpec]):
        super().__init__(specs)
        self.face_styles = specs[0].face_styles
        self.face_cutoffs = [CutoffStyle(st, specs[0].cutoff_mode) for st in self.face_styles]

    def apply(self, state: "BatchState", outputs: bool) -> tuple[np.ndarray, np.ndarray] | None:
        faces, style, cutoff = self.faces, self.style, self.cutoff
        C = state.ncases
        energy = np.zeros(C) if outputs else None
        vector = np.zeros((C, len(faces))) if outputs else None
        virial = np.zeros(C) if outputs and self.virial else None
        try:
            for k, (face, face_style, face_cutoff) in enumerate(zip(faces, self.face_styles, self.face_cutoffs)):
                self.faces, self.style, self.cutoff = [face], face_style, face_cutoff
                res = super().apply(state, outputs)
                if outputs:
                    energy += res[0]
                    vector[:, k] = res[1][:, 0]
                    if virial is not None:
                        virial += self.last_virial
        finally:
            self.faces, self.style, self.cutoff = faces, style, cutoff
        if virial is not None:
            self.last_virial = virial
        return (energy, vector) if outputs else None

    def _fail_inside(self, state: "BatchState", ci: np.ndarray, ai: np.ndarray, r: np.ndarray, face: str) -> None:
        nearer = self.style.too_close_message()
        if nearer is None:
            super()._fail_inside(state, ci, ai, r, face)
            return
        first: dict[int, tuple[int, float]] = {}
        for c, a, d in zip(ci.tolist(), ai.tolist(), r.tolist()):
            first.setdefault(c, (a, d))
        state.fail(np.array(sorted(first)), lambda c: (
            f"walls.{self.fix_id} ({self.style.lammps} {face}): atom {first[c][0]} at distance {first[c][1]:.6g} "
            f"from the wall {state.at(c)} is {nearer}"))


class ReflectKernel:
    """fix wall/reflect (physics.md §7): after the drift, an atom past a wall is mirrored about it
    and its normal velocity flipped (frame lab, LAMMPS) or reflected in the wall's frame
    (frame wall: v -> 2 v_wall - v, v_wall = the wall's displacement over the step / dt)."""

    def __init__(self, specs: list[ReflectSpec], stats: bool):
        s0 = specs[0]
        self.fix_id = s0.fix_id
        self.group = s0.group
        self.all_atoms = bool(s0.group.all())
        self.frame = s0.frame
        self.faces = [FaceValues([s.faces[i] for s in specs]) for i in range(len(s0.faces))]
        self.stats = stats
        self.previous: list[np.ndarray | None] = [None] * len(self.faces)
        self.count: np.ndarray | None = None
        self.impulse: np.ndarray | None = None

    def take(self, keep: np.ndarray) -> None:
        for face in self.faces:
            face.take(keep)
        self.previous = [p[keep] if p is not None else None for p in self.previous]
        if self.count is not None:
            self.count, self.impulse = self.count[keep], self.impulse[keep]

    def setup(self, state: "BatchState") -> None:
        self.previous = [face.position(state).copy() for face in self.faces]
        if self.stats:
            self.count = np.zeros((state.ncases, len(self.faces)))
            self.impulse = np.zeros((state.ncases, len(self.faces)))

    def apply(self, state: "BatchState", dt: np.ndarray) -> None:
        for k, face in enumerate(self.faces):
            coord = face.position(state)
            pos = state.x[:, :, face.dim]
            out = pos < coord[:, None] if face.side < 0 else pos > coord[:, None]
            if not self.all_atoms:
                out &= self.group
            ci, ai = np.nonzero(out)
            if ci.size:
                c = coord[ci]
                state.x[ci, ai, face.dim] = 2.0 * c - state.x[ci, ai, face.dim]
                v_before = state.v[ci, ai, face.dim]
                if self.frame == "wall":
                    with np.errstate(divide="ignore", invalid="ignore"):
                        v_wall = np.where(dt > 0, (coord - self.previous[k]) / dt, 0.0)
                    v_after = 2.0 * v_wall[ci] - v_before
                else:
                    v_after = -v_before
                state.v[ci, ai, face.dim] = v_after
                if self.stats:
                    C = state.ncases
                    self.count[:, k] += np.bincount(ci, minlength=C)
                    # momentum given to the wall along +dim, in force*time units
                    dp = state.mass[ci, ai] * (v_before - v_after) / state.units.ftm2v
                    self.impulse[:, k] += np.bincount(ci, weights=dp, minlength=C)
            self.previous[k] = coord if isinstance(face.coord, np.ndarray) else coord.copy()

    def take_stats(self) -> tuple[np.ndarray, np.ndarray]:
        """Reflections and impulse since the previous sample; resets the counters."""
        out = (self.count.copy(), self.impulse.copy())
        self.count[:] = 0.0
        self.impulse[:] = 0.0
        return out


def build_kernels(cases: list[Case], outputs: tuple[str, ...]) -> tuple[list[SoftWallKernel], list[ReflectKernel]]:
    """Flat soft walls (wall/ees included, as EESWallKernel) and reflecting walls of a batch."""
    def kind(spec: SoftWallSpec) -> type:
        if isinstance(spec, CustomWallSpec):
            return CustomWallKernel
        return EESWallKernel if spec.style.needs_shape else SoftWallKernel

    soft = [kind(cases[0].soft_walls[i])([c.soft_walls[i] for c in cases]) for i in range(len(cases[0].soft_walls))]
    stats = "reflect_count" in outputs or "reflect_impulse" in outputs
    reflect = [(StochasticKernel if isinstance(cases[0].reflect_walls[i], StochasticSpec) else ReflectKernel)(
        [c.reflect_walls[i] for c in cases], stats) for i in range(len(cases[0].reflect_walls))]
    return soft, reflect



def build_region_kernels(cases: list[Case]) -> list:
    """wall/region and wall/region/ees kernels of a batch, in config order."""
    kernels = []
    for i, spec in enumerate(cases[0].region_walls):
        kind = RegionEESKernel if spec.kind == "region/ees" else RegionWallKernel
        kernels.append(kind([c.region_walls[i] for c in cases]))
    return kernels
