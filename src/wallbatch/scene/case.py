"""A `Case`: one scene resolved into frozen arrays and specs in box units, and the key that
decides which cases may share a batch.
"""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from wallbatch.expr import Variables
from wallbatch.styles.base import WallStyle
from wallbatch.units import UnitSystem

Value = float | str  # a number, or the name of an equal-style variable (without v_)


# ----------------------------------------------------------------------------- structure key rules


def per_case(**kwargs: Any) -> Any:
    """A dataclass field whose value may differ between the cases of one batch: it stays out of
    `structure_key` (the engine holds it per case)."""
    return field(metadata={"per_case": True}, **kwargs)


def keyed(key: Callable[[Any], Any], owner: bool = False, **kwargs: Any) -> Any:
    """A dataclass field that joins `structure_key` as key(value) (key(the whole object) with
    `owner`): only the part that must be equal across a batch (e.g. a variable's name but not a
    number)."""
    return field(metadata={"key": key, "owner": owner}, **kwargs)


def _value_key(v: Any) -> Any:
    """A number or a variable name: variables must match, numbers may differ per case."""
    return v if isinstance(v, str) else "#"


def _params_key(params: dict[str, Any]) -> tuple:
    return tuple((k, _value_key(v)) for k, v in sorted(params.items()))


def _name_key(obj: Any) -> Any:
    """A registry entry (wall style) by its name."""
    return None if obj is None else obj.name




class MinimizeWarning(UserWarning):
    """A minimization whose objective lacks some wall energies (LAMMPS behaviour, reproduced)."""


class CaseError(RuntimeError):
    """A case cannot run (bad input found while building, or a failure during the run).

    `key`: the dotted config key (`atoms.0.create.random`) the message is led by (`KEY: why`), for
    a message not yet placed in the config's text: `SweepPlan.placed` puts the file:line:col (or
    the sweep entry, or the `--set` argument) in front of it. None for a message that names no
    key, or that already starts with its place."""

    def __init__(self, message: str, key: str | None = None):
        super().__init__(message)
        self.key = key

    def __reduce__(self):  # (kept across processes: the default would drop `key`)
        return type(self), (str(self), self.key)


@dataclass(frozen=True)
class Face:
    """One wall plane: `dim` 0/1/2, `side` -1 (lo) or +1 (hi). `coord` is a number in box units or
    a variable name whose value is multiplied by `scale` (the lattice spacing, or 1)."""

    label: str  # "fixID/face"
    name: str
    dim: int
    side: int
    coord: Value = keyed(_value_key)
    scale: float
    params: dict[str, Value] = keyed(_params_key)  # the style's parameters (box units; variables by name)


@dataclass(frozen=True)
class SoftWallSpec:
    """fix wall/<style>: soft flat walls."""

    fix_id: str
    style: WallStyle = keyed(_name_key)
    group: np.ndarray  # (N,) bool
    energy: bool
    faces: tuple[Face, ...]
    virial: bool = False  # fix_modify virial: the wall virial joins press
    # cut-off treatment (styles.cutoff): shift | force-shift | smooth; smooth's r_on is the faces'
    # params["switch_on"] (a number per case)
    cutoff_mode: str = "shift"


@dataclass(frozen=True)
class CustomWallSpec(SoftWallSpec):
    """fix wall/lepton or wall/table: a style per face (`face_styles`, from its expression or
    table); `signature` (per face: expression text, or table file, keyword, tabstyle, N) decides
    which cases may share a batch."""

    face_styles: tuple[WallStyle, ...] = keyed(lambda styles: tuple(_name_key(s) for s in styles), default=())
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

    seed: tuple[int, ...] = per_case(default=())

    @property
    def rstyle(self) -> str:
        return self.frame.split("/", 1)[1]


@dataclass(frozen=True)
class DtResetSpec:
    """fix dt/reset (physics.md §9); xmax in box units; None = no bound."""

    every: int
    group: np.ndarray
    tmin: float | None = per_case()
    tmax: float | None = per_case()
    xmax: float = per_case()
    emax: float | None = per_case()


@dataclass(frozen=True)
class PairSpec:
    """pair_style lj/cut with one atom type (physics.md §12); `skin` is the neighbor skin."""

    epsilon: float = per_case()
    sigma: float = per_case()
    cutoff: float = per_case()
    shift: bool
    skin: float


@dataclass(frozen=True)
class RegionWallSpec:
    """fix wall/region (`potential` a flat-wall style) or wall/region/ees (`potential` None)."""

    fix_id: str
    kind: str  # "region" | "region/ees"
    region_name: str
    region: Any  # regions.RegionGeom, box units
    potential: WallStyle | None = keyed(_name_key)
    group: np.ndarray
    energy: bool
    params: dict[str, Value] = keyed(_params_key)  # the potential's parameters (box units; variables by name)
    virial: bool = False
    cutoff_mode: str = "shift"  # as SoftWallSpec; smooth's r_on is params["switch_on"]


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

    name: str = per_case()
    units: UnitSystem = keyed(_name_key)
    box_lo: np.ndarray  # (3,)
    box_hi: np.ndarray
    periodic: np.ndarray  # (3,) bool
    x: np.ndarray = per_case()  # (N, 3)
    v: np.ndarray = per_case()  # (N, 3)
    mass: np.ndarray = per_case()  # (N,)
    radius: np.ndarray = per_case()  # (N,)
    atom_group: np.ndarray  # (N,) index into group_names (creation group)
    group_names: tuple[str, ...]
    dt: float = per_case()
    variables: Variables = per_case()  # joins the key through variable_text
    # (name, text): the texts must match, except numeric constants (a value per case)
    variable_text: tuple[tuple[str, str], ...] = keyed(lambda case: _variable_texts(case), owner=True)
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
    shape: np.ndarray | None = keyed(lambda v: v is not None, default=None)
    quat: np.ndarray | None = per_case(default=None)
    angmom: np.ndarray | None = per_case(default=None)
    pair: PairSpec | None = None
    region_walls: tuple[RegionWallSpec, ...] = ()
    flow_walls: tuple = ()  # FlowSpec per wall/flow fix
    flow_seeds: tuple[tuple[int, ...], ...] = per_case(default=())  # random stream key per flow wall
    fix_order: tuple[str, ...] = ()  # fixes with a global scalar (soft, ees, region), config order
    minimize: Any = None  # MinSettings, or None
    # integrators and thermostats (scene.ensemble.EnsembleFixSpec, config order); None: fix nve on all
    fixes: tuple | None = keyed(lambda v: None if v is None else tuple(f.structure() for f in v), default=None)
    dimension: int = 3  # 2: enforce2d, temperatures over 2 dof per atom
    profiles: tuple[ProfileSpec, ...] = ()  # output.profiles
    # output.averages: first step (time for a time-based run) averaged
    average_start: float = per_case(default=0.0)

    @property
    def natoms(self) -> int:
        return self.x.shape[0]

    def __getstate__(self) -> dict:
        """Pickled (a case sent to a cluster worker) without its remembered structure key: the
        receiver takes it again if it needs it."""
        return {k: v for k, v in self.__dict__.items() if k != _KEY_MEMO}




@dataclass(frozen=True)
class FlowSpec:
    """One fix wall/flow of one case, resolved: walls (K,) ascending absolute coordinates along
    `axis` in box units; vflow [velocity] > 0; temperature [temperature] > 0."""

    fix_id: str
    group: np.ndarray  # (N,) bool
    axis: int  # 0, 1, 2
    vflow: float = per_case()
    temperature: float = per_case()
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

    etol: float = per_case()
    ftol: float = per_case()
    maxiter: int = per_case()
    maxeval: int = per_case()
    style: str = "cg"
    dmax: float = per_case(default=0.1)
    timestep: float | None = per_case(default=None)
    norm: bool = per_case(default=False)

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




_PLAIN = (bool, int, float, str, np.generic, type(None))  # scalars join the key as they are


def key_of(value: Any) -> Any:
    """The structure-key form of a value: arrays by dtype, shape and bytes; dataclasses field by
    field (see `_fields_key`); tuples, lists and dicts elementwise; plain scalars as they are."""
    if isinstance(value, np.ndarray):
        return (value.dtype.str, value.shape, value.tobytes())
    if isinstance(value, _PLAIN):
        return value
    if isinstance(value, (tuple, list)):
        return tuple(key_of(v) for v in value)
    if isinstance(value, dict):
        return tuple((k, key_of(v)) for k, v in value.items())
    if _key_fields(type(value)) is not None:  # a dataclass instance
        return (type(value).__name__, _fields_key(value))
    raise TypeError(f"structure_key: no rule for a {type(value).__name__}: declare its field per_case() or "
                    f"keyed(...) in wallbatch.scene.case")


@functools.cache
def _key_fields(cls: type) -> tuple[tuple[str, Callable[[Any], Any] | None, bool], ...] | None:
    """The fields of a dataclass that join its key, as (name, keyed rule or None, rule takes the
    whole object), once per class; None for a class that is not a dataclass."""
    if not dataclasses.is_dataclass(cls):
        return None
    return tuple((f.name, f.metadata.get("key"), bool(f.metadata.get("owner")))
                 for f in dataclasses.fields(cls) if not f.metadata.get("per_case"))


def _fields_key(obj: Any) -> tuple:
    """(field name, key) for every field of a dataclass that is not declared per_case(); a field
    declared keyed(f) joins as f(value)."""
    out = []
    for name, rule, owner in _key_fields(type(obj)):
        value = getattr(obj, name)
        if rule is None:
            out.append((name, key_of(value)))
        else:
            out.append((name, rule(obj) if owner else rule(value)))
    return tuple(out)


def _variable_texts(case: Case) -> tuple:
    """Variables join by text, except numeric constants, whose values may differ per case."""
    return tuple((k, "#" if case.variables.constant_value(k) is not None else text) for k, text in case.variable_text)


_KEY_MEMO = "_structure_key"  # where a Case keeps its key once taken (not a field: not in its pickle)


def structure_key(case: Case) -> tuple:
    """Cases with equal keys can share a batch: same atoms, groups, fixes, variables, schedule.

    Derived from the dataclass declarations: every field of the Case (and of its specs, field by
    field) joins the key unless declared per_case(); keyed(f) fields join as f(value). Taken once
    per Case object (a sweep's runner asks for it three times a case: the build check, the tasks,
    the engine's batches); a Case is frozen and its arrays are not written after it is built."""
    key = case.__dict__.get(_KEY_MEMO)
    if key is None:
        key = _fields_key(case)
        object.__setattr__(case, _KEY_MEMO, key)
    return key


