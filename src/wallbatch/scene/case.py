"""A `Case`: one scene resolved into frozen arrays and specs in box units, and the key that
decides which cases may share a batch.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from wallbatch.expr import Variables
from wallbatch.styles.flat import WallStyle
from wallbatch.units import UnitSystem

Value = float | str  # a number, or the name of an equal-style variable (without v_)


class MinimizeWarning(UserWarning):
    """A minimization whose objective lacks some wall energies (LAMMPS behaviour, reproduced)."""


class CaseError(RuntimeError):
    """A case cannot run (bad input found while building, or a failure during the run)."""


@dataclass(frozen=True)
class Face:
    """One wall plane: `dim` 0/1/2, `side` -1 (lo) or +1 (hi). `coord` is a number in box units or
    a variable name whose value is multiplied by `scale` (the lattice spacing, or 1)."""

    label: str  # "fixID/face"
    name: str
    dim: int
    side: int
    coord: Value
    scale: float
    params: dict[str, Value]  # epsilon, sigma, cutoff, D0, alpha, r0 (box units; variables by name)


@dataclass(frozen=True)
class SoftWallSpec:
    """fix wall/<style>: soft flat walls."""

    fix_id: str
    style: WallStyle
    group: np.ndarray  # (N,) bool
    energy: bool
    faces: tuple[Face, ...]
    virial: bool = False  # fix_modify virial: the wall virial joins press


@dataclass(frozen=True)
class CustomWallSpec(SoftWallSpec):
    """fix wall/lepton or wall/table: a style per face (`face_styles`, from its expression or
    table); `signature` (per face: expression text, or table file, keyword, tabstyle, N) decides
    which cases may share a batch."""

    face_styles: tuple[WallStyle, ...] = ()
    signature: tuple = ()


@dataclass(frozen=True)
class ReflectSpec:
    """fix wall/reflect; `frame` lab (v -> -v, LAMMPS) or wall (v -> 2 v_wall - v)."""

    fix_id: str
    group: np.ndarray
    frame: str
    faces: tuple[Face, ...]


@dataclass(frozen=True)
class StochasticSpec(ReflectSpec):
    """fix wall/reflect/stochastic: `frame` is "stochastic/<rstyle>" (diffusive, maxwell, ccl);
    face params temp, vx, vy, vz, ax, ay, az; `seed` keys the case's random stream of this wall."""

    seed: tuple[int, ...] = ()

    @property
    def rstyle(self) -> str:
        return self.frame.split("/", 1)[1]


@dataclass(frozen=True)
class DtResetSpec:
    """fix dt/reset (physics.md §9); xmax in box units; None = no bound."""

    every: int
    group: np.ndarray
    tmin: float | None
    tmax: float | None
    xmax: float
    emax: float | None


@dataclass(frozen=True)
class PairSpec:
    """pair_style lj/cut with one atom type (physics.md §12); `skin` is the neighbor skin."""

    epsilon: float
    sigma: float
    cutoff: float
    shift: bool
    skin: float


@dataclass(frozen=True)
class RegionWallSpec:
    """fix wall/region (`potential` a flat-wall style) or wall/region/ees (`potential` None)."""

    fix_id: str
    kind: str  # "region" | "region/ees"
    region_name: str
    region: Any  # regions.RegionGeom, box units
    potential: WallStyle | None
    group: np.ndarray
    energy: bool
    params: dict[str, Value]  # epsilon, sigma, cutoff, D0, alpha, r0 (box units; variables by name)
    virial: bool = False


@dataclass(frozen=True)
class ProfileSpec:
    """output.profiles entry, resolved (LAMMPS compute chunk/atom bin/1d + fix ave/chunk, norm
    all): `nbins` bins of width `delta` [distance] along `axis` (0, 1, 2) from `lo` (the box's
    lower bound); samples every `every` steps, `repeat` of them per window, a window closing at
    every multiple of `freq` (step 0 opens none)."""

    name: str
    axis: int
    lo: float
    delta: float
    nbins: int
    every: int
    repeat: int
    freq: int
    quantities: tuple[str, ...]
    group: np.ndarray  # (N,) bool

    def window_steps(self, steps: int) -> list[int]:
        """The step at which each window's average is taken: freq, 2 freq, ... <= steps."""
        return list(range(self.freq, steps + 1, self.freq))

    def sample_steps(self, steps: int) -> list[int]:
        """Every step that contributes to some window."""
        return [w - k * self.every for w in self.window_steps(steps) for k in range(self.repeat - 1, -1, -1)]


@dataclass(frozen=True)
class Case:
    """One runnable scene: the engine's input."""

    name: str
    units: UnitSystem
    box_lo: np.ndarray  # (3,)
    box_hi: np.ndarray
    periodic: np.ndarray  # (3,) bool
    x: np.ndarray  # (N, 3)
    v: np.ndarray  # (N, 3)
    mass: np.ndarray  # (N,)
    radius: np.ndarray  # (N,)
    atom_group: np.ndarray  # (N,) index into group_names (creation group)
    group_names: tuple[str, ...]
    dt: float
    variables: Variables
    variable_text: tuple[tuple[str, str], ...]
    soft_walls: tuple[SoftWallSpec, ...]
    reflect_walls: tuple[ReflectSpec, ...]
    dt_reset: DtResetSpec | None
    steps: int | None  # run length in steps, or None for a time-based run
    run_time: float | None
    thermo: int | float  # int: every n steps (0 = first and last); float: every that much time
    thermo_is_time: bool
    outputs: tuple[str, ...]
    dump_every: int = 0  # output.dump: a frame every that many steps (0: no dump)
    dump_fields: tuple[str, ...] = ()
    # ellipsoids (None when no atom has a shape): semi-axes (N,3) (0 for point atoms), unit
    # quaternions (N,4) (w, x, y, z), space-frame angular momentum (N,3)
    shape: np.ndarray | None = None
    quat: np.ndarray | None = None
    angmom: np.ndarray | None = None
    pair: PairSpec | None = None
    region_walls: tuple[RegionWallSpec, ...] = ()
    flow_walls: tuple = ()  # flow.FlowSpec per wall/flow fix
    flow_seeds: tuple[tuple[int, ...], ...] = ()  # random stream key per flow wall
    fix_order: tuple[str, ...] = ()  # fixes with a global scalar (soft, ees, region), config order
    minimize: Any = None  # minimize.MinSettings, or None
    # integrators and thermostats (scene.ensemble.EnsembleFixSpec, config order); None: fix nve on all
    fixes: tuple | None = None
    dimension: int = 3  # 2: enforce2d, temperatures over 2 dof per atom
    profiles: tuple[ProfileSpec, ...] = ()  # output.profiles
    average_start: float = 0.0  # output.averages: first step (time for a time-based run) averaged

    @property
    def natoms(self) -> int:
        return self.x.shape[0]




@dataclass(frozen=True)
class FlowSpec:
    """One fix wall/flow of one case, resolved: walls (K,) ascending absolute coordinates along
    `axis` in box units; vflow [velocity] > 0; temperature [temperature] > 0."""

    fix_id: str
    group: np.ndarray  # (N,) bool
    axis: int  # 0, 1, 2
    vflow: float
    temperature: float
    walls: np.ndarray  # (K,)
    rule: str = "exact"  # "exact" | "lammps"




@dataclass(frozen=True)
class MinSettings:
    """``minimize etol ftol maxiter maxeval`` with ``min_style`` and ``min_modify dmax``.

    etol [-] relative energy change, ftol [force] on the force 2-norm, dmax [length] largest
    move of any coordinate in one line search (cg) or one step (fire), timestep [time] the
    initial fire timestep (LAMMPS's current ``timestep``), norm: LAMMPS ``thermo_modify norm``
    (energies divided by N inside the algorithm).
    """

    etol: float
    ftol: float
    maxiter: int
    maxeval: int
    style: str = "cg"
    dmax: float = 0.1
    timestep: float | None = None
    norm: bool = False

    def __post_init__(self) -> None:
        if self.style not in ("cg", "fire"):
            raise ValueError(f"min style must be 'cg' or 'fire', not {self.style!r}")
        if not (self.etol >= 0 and self.ftol >= 0):
            raise ValueError("etol and ftol must be >= 0")
        if self.maxiter < 0 or self.maxeval < 0:
            raise ValueError("maxiter and maxeval must be >= 0")
        if not self.dmax > 0:
            raise ValueError("dmax must be > 0")
        if self.style == "fire" and not (self.timestep is not None and self.timestep > 0):
            raise ValueError("min style fire needs a timestep > 0")




def structure_key(case: Case) -> tuple:
    """Cases with equal keys can share a batch: same atoms, groups, fixes, variables, schedule."""
    def faces(spec):
        return tuple((f.name, f.scale, tuple(sorted(f.params)),
                      f.coord if isinstance(f.coord, str) else "#",
                      tuple(v if isinstance(v, str) else "#" for v in f.params.values())) for f in spec.faces)

    variables = tuple((k, "#" if case.variables.constant_value(k) is not None else text)
                      for k, text in case.variable_text)  # numeric constants may differ per case
    return (
        case.units.name, case.natoms, case.atom_group.tobytes(), tuple(case.periodic),
        tuple(case.box_lo), tuple(case.box_hi), variables,
        tuple((w.fix_id, w.style.name, w.group.tobytes(), w.energy, faces(w), getattr(w, "signature", ()))
              for w in case.soft_walls),
        tuple((w.fix_id, w.frame, w.group.tobytes(), faces(w)) for w in case.reflect_walls),
        None if case.dt_reset is None else (case.dt_reset.every, case.dt_reset.group.tobytes()),
        case.steps, case.run_time, case.thermo, case.thermo_is_time, case.outputs, case.dump_every,
        case.dump_fields, case.fix_order, case.shape is not None,
        None if case.pair is None else (case.pair.shift, case.pair.skin),  # parameters may differ per case
        tuple((w.fix_id, w.kind, w.region, None if w.potential is None else w.potential.name, w.group.tobytes(),
               w.energy, tuple((k, v if isinstance(v, str) else "#") for k, v in sorted(w.params.items())))
              for w in case.region_walls),
        tuple((w.fix_id, w.group.tobytes(), w.axis, w.walls.tobytes(), w.rule) for w in case.flow_walls),
        None if case.minimize is None else case.minimize.style,
        None if case.fixes is None else tuple(f.structure() for f in case.fixes), case.dimension,
        tuple((p.name, p.axis, p.lo, p.delta, p.nbins, p.every, p.repeat, p.freq, p.quantities, p.group.tobytes())
              for p in case.profiles),
    )


