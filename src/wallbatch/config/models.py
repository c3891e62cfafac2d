"""The config language (docs/reference/config.md): YAML loading with line numbers, Pydantic models,
and the cross-field checks. The models are the single source of truth for a scene; the engine
never sees raw YAML.

Every problem is reported as `file:line:col: dotted.path: message` through `ConfigError`.
"""

from __future__ import annotations

import math
import numbers
import re
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import Annotated, Any, ClassVar, Literal, Union

from pydantic import (
    ConfigDict,
    Field,
    NonNegativeFloat,
    NonNegativeInt,
    PositiveFloat,
    PositiveInt,
    PrivateAttr,
    ValidationError,
    create_model,
    field_validator,
    model_validator,
)

from wallbatch.config.base import NoBoolNumbers
from wallbatch.config.ondemand import tagged_on_demand
from wallbatch.config.profiles import Averages, Profile, check_profiles
from wallbatch.config.source import (FACES, ConfigError, SourceMap, load_yaml, model_type_errors,
                                     tuple_length_errors)
from wallbatch.styles import STYLES, WallStyle, region_styles
from wallbatch.styles import Param as StyleParam
from wallbatch.styles.cutoff import CUTOFF_MODES
from wallbatch.styles.cutoff import supported as cutoff_supported

REGION_POTENTIALS = region_styles()
THERMO_KEYWORDS = (
    "step", "time", "dt", "temp", "ke", "pe", "etot", "press", "atoms", "erot",
    "reflect_count", "reflect_impulse", "flow_crossings", "ecouple", "econserve",
)
VAR_RE = re.compile(r"^v_[A-Za-z_][A-Za-z0-9_]*$")
NAME_RE = r"^[A-Za-z_][A-Za-z0-9_\-]*$"


# ----------------------------------------------------------------------------- value types


def _finite(x: float, v: Any) -> float:
    if not math.isfinite(x):
        raise ValueError(f"expected a finite number, got {str(v)[:40]!r}")
    return x


def _number_or_name(v: Any, allow: tuple[str, ...]) -> Any:
    if isinstance(v, bool):
        raise ValueError("expected a number")
    if isinstance(v, numbers.Real):  # (NumPy's scalars too: a face list built from an array)
        return _finite(float(v), v)
    if isinstance(v, str):
        s = v.strip()
        if s in allow or VAR_RE.match(s):
            return s
        try:
            x = float(s)
        except ValueError:
            pass
        else:
            return _finite(x, v)
        raise ValueError(f"expected a number{', EDGE' if 'EDGE' in allow else ''} or a variable reference "
                         f"v_name, got {str(v)[:60]!r}")
    raise ValueError(f"expected a number or v_name, got {str(v)[:60]!r}")


def _coord(v: Any) -> Any:
    return _number_or_name(v, ("EDGE",))


def _param(v: Any) -> Any:
    return _number_or_name(v, ())


def _bound(v: Any) -> float | None:
    """dt_reset tmin/tmax: a number, or INF / NULL / null for no bound."""
    if v is None or (isinstance(v, str) and v.strip().upper() in ("INF", "NULL", "NONE")):
        return None
    if isinstance(v, bool) or not isinstance(v, (numbers.Real, str)):
        raise ValueError("expected a number, INF or NULL")
    try:
        x = float(v)
    except ValueError:
        raise ValueError(f"expected a number, INF or NULL, got {str(v)[:40]!r}") from None
    if not math.isfinite(x):
        raise ValueError("expected a finite number: write INF or NULL for no bound")
    return x


from pydantic import BeforeValidator, WithJsonSchema  # noqa: E402

from wallbatch.config.ensemble import EnsembleFix, check_ensemble, drop_fix_tag
from wallbatch.config.ensemble import expand_fix_lines as expand_ensemble_lines
from wallbatch.config.fixline import FixLineError, parse_fix_line, rstyle_hint
from wallbatch.expr import VariableError, Variables
from wallbatch.units import lattice_constant

# what the loader accepts, for the JSON schema: a number, or a string that is a number, v_name (or EDGE)
_NUMBER_TEXT = r"[+-]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][+-]?[0-9]+)?"
COORD_SCHEMA = {"anyOf": [{"type": "number"}, {"type": "string", "pattern": (
    rf"^\s*(?:EDGE|v_[A-Za-z_][A-Za-z0-9_]*|{_NUMBER_TEXT})\s*$")}]}
PARAM_SCHEMA = {"anyOf": [{"type": "number"}, {"type": "string", "pattern": (
    rf"^\s*(?:v_[A-Za-z_][A-Za-z0-9_]*|{_NUMBER_TEXT})\s*$")}]}
Coord = Annotated[Union[float, str], BeforeValidator(_coord), WithJsonSchema(COORD_SCHEMA)]
Param = Annotated[Union[float, str], BeforeValidator(_param), WithJsonSchema(PARAM_SCHEMA)]
Bound = Annotated[Union[float, None], BeforeValidator(_bound)]
Vec3 = tuple[float, float, float]


class Model(NoBoolNumbers):
    # every float finite: .inf / .nan / 'NaN' are refused ("no bound" is written INF or NULL where allowed)
    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)


# the wall models are validators built when first used (a config uses a few of the 14 wall
# styles; building them all costs tens of milliseconds of every start-up): see `wall_model`
_ON_USE = ConfigDict(defer_build=True)


# ----------------------------------------------------------------------------- scene parts


class Box(Model):
    """Simulation box, always in box (distance) units."""

    lo: Vec3
    hi: Vec3
    boundary: tuple[Literal["p", "f"], Literal["p", "f"], Literal["p", "f"]] = ("p", "p", "p")

    @field_validator("hi")
    @classmethod
    def _extent(cls, hi: Vec3, info: Any) -> Vec3:
        lo = info.data.get("lo")
        for d in range(3):
            if lo is not None and not hi[d] > lo[d]:
                raise ValueError(f"box.hi[{d}] = {hi[d]} must be greater than box.lo[{d}] = {lo[d]}")
            if lo is not None and not abs(hi[d] - lo[d]) < 1e300:
                raise ValueError(f"box length {hi[d]} - ({lo[d]}) along {'xyz'[d]} is not a finite number")
        return hi


class Lattice(Model):
    """`lattice STYLE SCALE`: in lj units scale is the reduced density, otherwise the lattice constant."""

    style: Literal["sc", "bcc", "fcc", "sq", "sq2", "hex"]  # sq, sq2, hex: 2-D (dimension: 2)
    scale: PositiveFloat


class RandomCreate(Model):
    count: PositiveInt
    region: str | None = None
    overlap: NonNegativeFloat | None = None


class LatticeCreate(Model):
    region: str | None = None


class Create(Model):
    """Exactly one way of creating the group's atoms."""

    random: RandomCreate | None = None
    lattice: LatticeCreate | None = None
    positions: list[Vec3] | None = None
    file: str | None = None
    ids: str | None = None  # LAMMPS data files: the atom IDs of this group, e.g. "1:200 305"

    @field_validator("ids", mode="before")
    @classmethod
    def _ids_text(cls, v: Any) -> Any:
        if isinstance(v, int) and not isinstance(v, bool):  # YAML 1.1 reads 3:4 as the number 184
            raise ValueError(f"write atom IDs as a quoted string, e.g. ids: \"1:200 305\" (unquoted, YAML reads "
                             f"a range like 3:4 as a number; got {v})")
        return v

    @model_validator(mode="after")
    def _one(self) -> "Create":
        given = [k for k in ("random", "lattice", "positions", "file") if getattr(self, k) is not None]
        if len(given) != 1:
            raise ValueError(
                f"give exactly one of random, lattice, positions, file (got {', '.join(given) or 'none'})"
            )
        if self.ids is not None and (self.file is None or self.file.endswith(".npz")):
            raise ValueError("ids selects atoms of a LAMMPS data file: use it with file: NAME.data")
        if self.ids is not None and not re.fullmatch(r"\s*\d+([:*]\d+)?(\s+\d+([:*]\d+)?)*\s*", self.ids):
            raise ValueError(f"ids: write LAMMPS atom ID ranges like '1:200 305', got {self.ids!r}")
        if self.positions is not None and len(self.positions) == 0:
            raise ValueError("positions is empty")
        return self


class Velocity(Model):
    """Initial velocities: Maxwell-Boltzmann at `temperature` (zero net momentum), or explicit
    values. `shared`: groups whose velocities name the same label are drawn as one set (zero net
    momentum and exactly `temperature` over the set: LAMMPS's `velocity G create` on a LAMMPS group
    that spans several wallbatch groups)."""

    temperature: NonNegativeFloat | None = None
    values: Union[Vec3, list[Vec3], None] = None
    shared: Annotated[str, Field(pattern=NAME_RE)] | None = None

    @model_validator(mode="after")
    def _one(self) -> "Velocity":
        if (self.temperature is None) == (self.values is None):
            raise ValueError("give exactly one of temperature or values")
        if self.shared is not None and self.temperature is None:
            raise ValueError("shared draws the velocities of several groups as one set: it needs a temperature, "
                             "not values")
        return self


class AngMom(Model):
    values: Union[Vec3, list[Vec3]]


class AtomGroup(Model):
    group: Annotated[str, Field(pattern=NAME_RE)]
    create: Create
    mass: PositiveFloat | None = None
    radius: NonNegativeFloat | None = None
    shape: tuple[PositiveFloat, PositiveFloat, PositiveFloat] | None = None
    orientation: Union[Literal["random", "aligned"], tuple[float, float, float, float], None] = None
    angmom: AngMom | None = None
    velocity: Velocity | None = None


class Pair(Model):
    style: Literal["lj/cut"]
    epsilon: NonNegativeFloat
    sigma: PositiveFloat
    cutoff: PositiveFloat
    shift: bool = False


class Region(Model):
    # block/cylinder bounds may be infinite (an open side, LAMMPS's INF in `region`); nothing may be NaN
    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=True)

    style: Literal["block", "sphere", "cylinder"]
    side: Literal["in", "out"] = "in"
    units: Literal["lattice", "box"] = "lattice"
    lo: Union[Vec3, float, None] = None
    hi: Union[Vec3, float, None] = None
    center: Union[Vec3, tuple[float, float], None] = None
    radius: PositiveFloat | None = None
    axis: Literal["x", "y", "z"] | None = None

    @field_validator("lo", "hi", "center", "radius")
    @classmethod
    def _no_nan(cls, v: Any, info: Any) -> Any:
        values = v if isinstance(v, tuple) else (v,)
        if any(x is not None and math.isnan(x) for x in values):
            raise ValueError("expected numbers, got NaN")
        if info.field_name in ("center", "radius") and any(x is not None and math.isinf(x) for x in values):
            raise ValueError("expected a finite number")
        return v

    @model_validator(mode="after")
    def _shape(self) -> "Region":
        need = {
            "block": ("lo", "hi"),
            "sphere": ("center", "radius"),
            "cylinder": ("axis", "center", "radius", "lo", "hi"),
        }[self.style]
        missing = [k for k in need if getattr(self, k) is None]
        if missing:
            raise ValueError(f"a {self.style} region needs {', '.join(missing)}")
        if self.style == "block" and not (isinstance(self.lo, tuple) and isinstance(self.hi, tuple)):
            raise ValueError("a block region needs lo and hi as [x, y, z]")
        if self.style == "block":
            for axis, lo, hi in zip("xyz", self.lo, self.hi):
                if lo > hi:  # LAMMPS: Illegal region block xlo > xhi (an empty region)
                    raise ValueError(f"a block region needs lo <= hi on every axis: {axis}lo = {lo:g} > "
                                     f"{axis}hi = {hi:g} (LAMMPS: Illegal region block): swap them")
        if self.style == "sphere" and len(self.center) != 3:
            raise ValueError("a sphere region needs center [x, y, z]")
        if self.style == "cylinder" and (
            len(self.center) != 2 or isinstance(self.lo, tuple) or isinstance(self.hi, tuple)
        ):
            raise ValueError("a cylinder region needs center [c1, c2] and numbers lo, hi along its axis")
        if self.style == "cylinder" and self.lo > self.hi:  # LAMMPS accepts it: an empty cylinder (decisions table)
            raise ValueError(f"a cylinder region needs lo <= hi along its axis: lo = {self.lo:g} > hi = {self.hi:g} "
                             f"(an empty cylinder; LAMMPS accepts it and its wall then touches no atom): swap them")
        return self


# ----------------------------------------------------------------------------- walls


class ReflectFace(Model):
    model_config = _ON_USE

    coord: Coord


def _faces_from_positional(data: Any, order: tuple[str, ...]) -> Any:
    """Turn `zlo: [coord, eps, sigma, rc]` (the LAMMPS argument order) into a mapping."""
    if not isinstance(data, dict):
        return data
    out = dict(data)
    for face in FACES:
        val = out.get(face)
        if isinstance(val, (list, tuple)):
            if len(val) != len(order):
                raise ValueError(
                    f"{face}: the positional form takes {len(order)} values ({' '.join(order)}), got {len(val)}"
                )
            out[face] = dict(zip(order, val))
    return out


class _FaceWall(Model):
    model_config = _ON_USE  # and its subclasses

    group: str = "all"
    units: Literal["lattice", "box"] = "lattice"
    energy: bool = False
    virial: bool = False
    pbc: bool = False

    _order: tuple[str, ...] = PrivateAttr(default=FACES)

    @model_validator(mode="wrap")
    @classmethod
    def _keep_order(cls, data: Any, handler: Any) -> Any:
        """Remember the order the faces were written in: it is the order of the output vector."""
        model = handler(data)
        if isinstance(data, dict):
            model._order = tuple(k for k in data if k in FACES)
        elif isinstance(data, _FaceWall):
            model._order = data._order
        return model

    def faces(self) -> list[tuple[str, Any]]:
        """(face name, face model) in config order."""
        return [(f, getattr(self, f)) for f in self._order if getattr(self, f) is not None]

    @model_validator(mode="after")
    def _need_face(self) -> "_FaceWall":
        if not any(getattr(self, f) is not None for f in FACES):
            raise ValueError(f"no walls defined: give at least one face ({' '.join(FACES)})")
        return self


class SoftWall(_FaceWall):
    """Base of the flat soft wall models, one per registered style (`WALL_MODELS`), generated from
    the style registry: faces take `coord` and the style's parameters in LAMMPS order, as a
    mapping or positionally."""

    _style: ClassVar[WallStyle]
    cutoff_mode: Literal[CUTOFF_MODES] = Field(  # type: ignore[valid-type]
        "shift", description="cut-off treatment: shift (LAMMPS: energy shifted, force jumps at the cut-off), "
        "force-shift (force and energy go to 0 at the cut-off) or smooth (quintic switch from switch_on)")
    switch_on: NonNegativeFloat | None = Field(
        None, description="smooth: where the switch starts, 0 <= switch_on < cutoff (box units) [distance]")

    @model_validator(mode="before")
    @classmethod
    def _positional(cls, data: Any) -> Any:
        return _faces_from_positional(data, cls._style.positional)


def _param_type(p: StyleParam) -> Any:
    """The Pydantic type of one style parameter by its kind: a number or v_name (`variable`), else
    a number (> 0 when `positive`; lower bounds of numbers are checked in check_scene); a word
    (non-empty text), one of `choices`, an integer (>= `min`, <= `max`), or a mapping of names to numbers."""
    if p.kind == "word":
        return Annotated[str, Field(min_length=1)]
    if p.kind == "choice":
        return Literal[p.choices]  # type: ignore[valid-type]
    if p.kind == "integer":
        bounds = {k: int(v) for k, v in (("ge", p.min), ("le", p.max)) if v is not None}
        return Annotated[int, Field(**bounds)] if bounds else int
    if p.kind == "mapping":
        return dict[str, float]
    if p.variable:
        return Param
    return PositiveFloat if p.positive else float


def _param_description(p: StyleParam) -> str:
    unit = f" [{p.unit}]" if p.unit and p.numeric else ""
    return f"{p.doc}{unit}" + (" (may be v_name)" if p.variable else "")


def _optional_elsewhere(name: str) -> list[str]:
    """Styles that may leave parameter `name` out."""
    return [s.name for s in STYLES.values() if any(q.name == name and not q.required for q in s.parameters)]


class _FaceBase(Model):
    """Base of the registry styles' face models (built on first use, `wall_model`)."""

    model_config = _ON_USE


def _face_model(style: WallStyle) -> type[Model]:
    """The face model of a style: coord and its parameters. A required parameter that another
    style may leave out is checked here, with a message naming the styles that may."""
    fields: dict[str, Any] = {"coord": (Coord, Field(description="wall position: a number, EDGE or v_name"))}
    late: list[str] = []
    for p in style.parameters:
        desc = _param_description(p)
        if p.kind == "mapping":
            fields[p.name] = (_param_type(p), Field(default={}, description=desc))
        elif p.required and not _optional_elsewhere(p.name):
            fields[p.name] = (_param_type(p), Field(description=desc))
        else:
            fields[p.name] = (_param_type(p) | None, Field(default=None, description=desc))
            if p.required:
                late.append(p.name)

    def _required(self: Any) -> Any:
        for name in late:
            if getattr(self, name) is None:
                others = _optional_elsewhere(name)
                raise ValueError(f"{name} is required for style {style.name} (only {', '.join(others)} may leave "
                                 f"it out)")
        return self

    validators = {"_required": model_validator(mode="after")(_required)} if late else {}
    return create_model(f"{style.name.capitalize()}Face", __base__=_FaceBase, __validators__=validators,
                        __doc__=f"One face of wall/{style.name}: `{' '.join(style.positional)}` (LAMMPS order).",
                        **fields)


def _wall_model(style: WallStyle) -> type[SoftWall]:
    """The wall model of a style: `style`, the faces, and the common keys of _FaceWall."""
    face = _face_model(style)
    model = create_model(
        f"{style.name.capitalize()}Wall", __base__=SoftWall,
        __doc__=f"fix {style.lammps}: {style.doc}",
        style=(Literal[style.name], Field(description=f"fix {style.lammps}")),  # type: ignore[valid-type]
        **{p.name: (_param_type(p), Field(description=_param_description(p))) for p in style.wall_parameters},
        **{f: (face | None, Field(default=None, description=f"the {f} wall")) for f in FACES})
    model._style = style
    return model


class _WallModels(Mapping):
    """style name -> wall model of every registered style (STYLES, the one place a style is
    defined), each model made from its registry entry when first asked for."""

    def __init__(self) -> None:
        self._made: dict[str, type[SoftWall]] = {}

    def __getitem__(self, name: str) -> type[SoftWall]:
        model = self._made.get(name)
        if model is None:
            model = self._made[name] = _wall_model(STYLES[name])
        return model

    def __iter__(self) -> Iterator[str]:
        return iter(STYLES)

    def __len__(self) -> int:
        return len(STYLES)

    def made(self) -> tuple[str, ...]:
        """The styles whose models exist so far."""
        return tuple(self._made)


# one model per registered wall style with per-face parameters
WALL_MODELS = _WallModels()


class _HardWall(_FaceWall):
    """A wall that only moves atoms (wall/reflect, wall/reflect/stochastic): it has no energy or
    virial, and LAMMPS refuses fix_modify energy / virial on it."""

    _lammps: ClassVar[str] = "wall/reflect"

    @field_validator("energy", "virial")
    @classmethod
    def _no_fix_modify(cls, v: bool, info: Any) -> bool:
        if v:
            raise ValueError(f"{cls._lammps} has no {info.field_name}: it moves atoms and stores no energy "
                             f"(LAMMPS: Fix ID {cls._lammps} does not support fix_modify {info.field_name} "
                             f"command): leave {info.field_name} out")
        return v


class ReflectWall(_HardWall):
    """fix wall/reflect: faces take only a coord. `frame: wall` reflects in a moving wall's frame."""

    style: Literal["reflect"]
    frame: Literal["lab", "wall"] = "lab"
    xlo: ReflectFace | None = None
    xhi: ReflectFace | None = None
    ylo: ReflectFace | None = None
    yhi: ReflectFace | None = None
    zlo: ReflectFace | None = None
    zhi: ReflectFace | None = None

    @model_validator(mode="before")
    @classmethod
    def _bare_coords(cls, data: Any) -> Any:
        if isinstance(data, dict):
            data = {k: ({"coord": v} if k in FACES and not isinstance(v, dict) else v) for k, v in data.items()}
        return data


class StochasticFace(Model):
    """One face of wall/reflect/stochastic: position, wall temperature, wall velocity (in the wall's
    plane) and accommodation coefficients (none for diffusive, one for maxwell, three for ccl)."""

    model_config = _ON_USE

    coord: Union[float, Literal["EDGE"]]
    temp: PositiveFloat
    vel: Vec3 = (0.0, 0.0, 0.0)
    accom: Union[float, Vec3, None] = None


class StochasticWall(_HardWall):
    """fix wall/reflect/stochastic rstyle seed face args: thermal walls (diffusive, maxwell, ccl)."""

    _lammps: ClassVar[str] = "wall/reflect/stochastic"

    style: Literal["reflect/stochastic"]
    rstyle: Literal["diffusive", "maxwell", "ccl"]
    seed: Annotated[int, Field(ge=1)]
    xlo: StochasticFace | None = None
    xhi: StochasticFace | None = None
    ylo: StochasticFace | None = None
    yhi: StochasticFace | None = None
    zlo: StochasticFace | None = None
    zhi: StochasticFace | None = None

    @model_validator(mode="after")
    def _accommodation(self) -> "StochasticWall":
        for name in FACES:
            face = getattr(self, name)
            if face is None:
                continue
            a = face.accom
            if self.rstyle == "diffusive" and a is not None:
                raise ValueError(f"{name}: accom is not used by rstyle diffusive (leave it out)")
            if self.rstyle == "maxwell" and not isinstance(a, float):
                raise ValueError(f"{name}: rstyle maxwell needs one accommodation coefficient, accom: a")
            if self.rstyle == "ccl" and not isinstance(a, tuple):
                raise ValueError(f"{name}: rstyle ccl needs three accommodation coefficients, accom: [ax, ay, az]")
            values = () if a is None else (a,) if isinstance(a, float) else a
            if any(not 0.0 <= x <= 1.0 for x in values):
                raise ValueError(f"{name}: accommodation coefficients must be between 0 and 1, got {a}")
            dim = "xyz".index(name[0])
            if face.vel[dim] != 0.0:
                raise ValueError(f"{name}: the wall velocity must lie in the wall's plane: vel[{dim}] "
                                 f"({name[0]}) must be 0, got {face.vel[dim]}")
        return self

    @field_validator("rstyle", mode="before")
    @classmethod
    def _long_name(cls, v: Any) -> Any:
        if rstyle_hint(v):
            raise ValueError(f"Input should be 'diffusive', 'maxwell' or 'ccl'{rstyle_hint(v)}")
        return v


class FlowWall(Model):
    """fix wall/flow (docs/physics.md §8)."""

    model_config = _ON_USE

    style: Literal["flow"]
    group: str = "all"
    axis: Literal["x", "y", "z"]
    vflow: PositiveFloat
    temperature: PositiveFloat
    seed: Annotated[int, Field(ge=1, le=900000000)]
    coords: Annotated[list[float], Field(min_length=1)]
    units: Literal["lattice", "box"] = "lattice"
    rule: Literal["exact", "lammps"] = "exact"


class _RegionWallHead(Model):
    model_config = _ON_USE  # and RegionWall

    style: Literal["region"]
    group: str = "all"
    region: str
    potential: Literal[REGION_POTENTIALS]  # type: ignore[valid-type]


class RegionEESWall(Model):
    """fix wall/region/ees."""

    model_config = _ON_USE

    style: Literal["region/ees"]
    group: str = "all"
    region: str
    epsilon: Param
    sigma: Param
    cutoff: PositiveFloat
    energy: bool = False


# the region wall takes the parameters of every region-capable style (checked per potential in
# _check_region_wall)
REGION_PARAMS: tuple[str, ...] = tuple(dict.fromkeys(
    p.name for n in REGION_POTENTIALS for p in STYLES[n].parameters if p.name != "cutoff"))
RegionWall = create_model(
    "RegionWall", __base__=_RegionWallHead, __doc__="fix wall/region with a soft potential (a flat wall style).",
    **{k: (Param | None, Field(default=None, description=f"{k} of the potential (as its flat wall style)"))
       for k in REGION_PARAMS},
    cutoff=(PositiveFloat, ...), energy=(bool, False), virial=(bool, False),
    cutoff_mode=(Literal[CUTOFF_MODES], Field("shift", description="cut-off treatment, as for flat walls")),  # type: ignore[valid-type]
    switch_on=(NonNegativeFloat | None, Field(None, description="smooth: where the switch starts [distance]")))

OTHER_WALLS: dict[str, type[Model]] = {"reflect": ReflectWall, "reflect/stochastic": StochasticWall, "flow": FlowWall,
                                       "region": RegionWall, "region/ees": RegionEESWall}
WALL_STYLES: tuple[str, ...] = (*STYLES, *OTHER_WALLS)  # every `style:` of a wall, in the schema's order


def wall_model(style: str) -> type[Model]:
    """The model of wall style `style` (KeyError if there is none), built on first use."""
    return OTHER_WALLS[style] if style in OTHER_WALLS else WALL_MODELS[style]


# a wall under `walls:`: validated by the model of its style alone (built on first use)
Wall = tagged_on_demand(WALL_STYLES, wall_model)


# ----------------------------------------------------------------------------- the rest


class Minimize(Model):
    """LAMMPS `minimize etol ftol maxiter maxeval` with `min_style` (cg default, or fire), run
    before `run:`; `dmax` is `min_modify dmax` (max distance an atom moves in one line-search step)."""

    style: Literal["cg", "fire"] = "cg"
    etol: NonNegativeFloat = 1.0e-4
    ftol: NonNegativeFloat = 1.0e-6
    maxiter: PositiveInt = 1000
    maxeval: PositiveInt = 10000
    dmax: PositiveFloat = 0.1


class DtReset(Model):
    """fix dt/reset (docs/physics.md §9)."""

    every: PositiveInt
    group: str = "all"
    tmin: Bound = None
    tmax: Bound = None
    xmax: PositiveFloat
    emax: PositiveFloat | None = None
    units: Literal["lattice", "box"] = "lattice"

    @model_validator(mode="after")
    def _bounds(self) -> "DtReset":
        for k in ("tmin", "tmax"):
            v = getattr(self, k)
            if v is not None and v < 0:
                raise ValueError(f"{k} must be >= 0 (or INF/NULL for no bound)")
        if self.tmin is not None and self.tmax is not None and self.tmin >= self.tmax:
            raise ValueError(f"tmin ({self.tmin}) must be smaller than tmax ({self.tmax})")
        return self


class TimeInterval(Model):
    time: PositiveFloat


class Run(Model):
    """Run length (`steps` or simulated `time`) and sampling interval (`thermo`)."""

    steps: NonNegativeInt | None = None
    time: PositiveFloat | None = None
    thermo: Union[NonNegativeInt, TimeInterval] = 0

    @model_validator(mode="after")
    def _one(self) -> "Run":
        if (self.steps is None) == (self.time is None):
            raise ValueError("give exactly one of steps or time")
        return self


class Dump(Model):
    every: PositiveInt
    fields: list[Literal["x", "v"]] = ["x", "v"]

    @field_validator("fields")
    @classmethod
    def _some_fields(cls, v: list[str]) -> list[str]:
        """At least one of x, v, each once (an empty list had nothing to write: the run failed)."""
        if not v:
            raise ValueError("give the per-atom fields to write: [x], [v] or [x, v]")
        if len(set(v)) != len(v):
            raise ValueError(f"{v}: each field once ([x], [v] or [x, v])")
        return v


class Output(Model):
    thermo: list[Literal[THERMO_KEYWORDS]] = ["step", "time", "dt", "temp", "ke", "pe", "etot"]  # type: ignore[valid-type]
    dump: Dump | None = None
    profiles: dict[str, Profile] = {}  # name -> binned axis (config/profiles.py)
    averages: Averages | None = None


class Config(Model):
    """One scene (docs/reference/config.md)."""

    name: str = "wallbatch"
    units: Literal["lj", "real", "metal"] = "lj"
    seed: NonNegativeInt = 0
    box: Box
    lattice: Lattice | None = None
    atoms: Annotated[list[AtomGroup], Field(min_length=1)]
    pair: Pair | None = None
    timestep: PositiveFloat | None = None
    variables: dict[Annotated[str, Field(pattern=r"^[A-Za-z_][A-Za-z0-9_]*$")], Union[float, str]] = {}
    regions: dict[str, Region] = {}
    walls: dict[str, Wall] = {}
    dt_reset: DtReset | None = None
    minimize: Minimize | None = None
    dimension: Literal[2, 3] = 3
    fixes: dict[str, EnsembleFix] | None = None  # integrators and thermostats; None: nve on all
    run: Run
    output: Output = Output()
    sweep: dict[str, Any] | None = None
    _base_dir: Path = PrivateAttr(default=Path("."))  # folder that relative `file:` paths start from
    _srcmap: Any = PrivateAttr(default=None)  # where each value stands, for errors found when building



# ----------------------------------------------------------------------------- loading and checks

NOT_YET: dict[str, str] = {}  # features whose schema exists but the engine does not run yet


def _expand_fix_lines(data: Any, srcmap: SourceMap) -> Any:
    """Walls given as LAMMPS fix lines (or `{fix: ..., energy: true}`) become the mapping form;
    a line that cannot be read is reported at its own wall."""
    if not isinstance(data, dict) or not isinstance(data.get("walls"), dict):
        return data
    walls, problems = {}, []
    for fid, w in data["walls"].items():
        try:
            if isinstance(w, str):
                w = parse_fix_line(w, str(fid))
            elif isinstance(w, dict) and "fix" in w:
                w = {**parse_fix_line(str(w["fix"]), str(fid)), **{k: v for k, v in w.items() if k != "fix"}}
        except FixLineError as exc:  # (at the `fix:` key when there is one: a --set of it is named there)
            problems.append(srcmap.format(("walls", fid) + (("fix",) if isinstance(w, dict) else ()), str(exc)))
        walls[str(fid)] = w  # a LAMMPS fix-ID may be a number (`1:`): IDs are strings
    if problems:
        raise ConfigError(problems)
    return {**data, "walls": walls}


def _tag_message(err: dict, loc: tuple) -> tuple[str, tuple]:
    """The message and place of a discriminated union's error (an unknown or missing `style:` of a
    wall or fix), instead of pydantic's wording about tags."""
    ctx = err.get("ctx") or {}
    key = str(ctx.get("discriminator", "style")).strip("'")
    expected = str(ctx.get("expected_tags", "")).replace("'", "")
    if err["type"] == "union_tag_invalid":
        return f"unknown {key} {ctx.get('tag')!r}: one of {expected}", loc + (key,)
    alt = " or fix: 'fix ID group wall/STYLE ...' (a LAMMPS fix line)" if loc[:1] == ("walls",) else ""
    return f"no {key}: give {key}: (see docs/reference/config.md){alt}", loc


def validate_data(data: Any, srcmap: SourceMap, base: Path | None = None, *, cross: bool = True) -> Config:
    """Validate loaded YAML data into a Config, then run the cross-field checks (relative table
    files of wall/table start from `base`); `cross=False` leaves those checks out (a sweep's base,
    whose cases are checked whole once their `set:` and swept values are in)."""
    data = _expand_fix_lines(data, srcmap)
    data, problems = expand_ensemble_lines(data, srcmap)
    if problems:
        raise ConfigError(problems)
    try:
        cfg = Config.model_validate(data)
    except ValidationError as exc:
        problems = []
        for err in model_type_errors(tuple_length_errors(exc.errors(include_url=False))):
            msg = err["msg"]
            msg = msg.removeprefix("Value error, ")
            if err["type"] == "extra_forbidden" and err["loc"][-1] == "fld":
                msg = "fld (lubrication models, fix wall ... fld yes) is not supported: remove it"
            elif err["type"] == "extra_forbidden":
                msg = "unknown key (misspelled? see docs/reference/config.md for the valid keys)"
            loc = drop_fix_tag(tuple(err["loc"]))
            if err["type"] in ("union_tag_invalid", "union_tag_not_found"):  # style: of a wall or a fix
                msg, loc = _tag_message(err, loc)
            problems.append(srcmap.format(loc, msg))
        raise ConfigError(problems) from None
    if base is not None:
        cfg._base_dir = base
    cfg._srcmap = srcmap
    problems = [srcmap.format(path, msg) for path, msg in check_scene(cfg)] if cross else []
    if problems:
        raise ConfigError(problems)
    return cfg


def load_config(path: str | Path) -> Config:
    """Read, parse and validate a config file; raise ConfigError naming file:line:col and field."""
    path = Path(path)
    try:
        text = path.read_text()
    except OSError as exc:
        raise ConfigError([f"{path}: cannot read the config: {exc.strerror}"]) from None
    return load_config_text(text, str(path), base=path.parent)


def load_config_text(text: str, filename: str = "<config>", base: Path = Path(".")) -> Config:
    """Parse and validate YAML text; relative `file:` paths start from `base`."""
    data, srcmap = load_yaml(text, filename)
    cfg = validate_data(data, srcmap, base)
    cfg._base_dir = base
    return cfg


def config_from_dict(data: dict, base: Path = Path(".")) -> Config:
    """Validate an already-loaded mapping (no line numbers: errors name the field path)."""
    cfg = validate_data(data, SourceMap("<dict>", {}, data), base)
    cfg._base_dir = base
    return cfg


def _var_refs(value: Any) -> list[str]:
    return [value[2:]] if isinstance(value, str) and value.startswith("v_") else []


def check_scene(cfg: Config) -> list[tuple[tuple, str]]:
    """Cross-field checks that the models cannot do alone: (path, message) per problem."""
    problems: list[tuple[tuple, str]] = []
    add = lambda path, msg: problems.append((path, msg))  # noqa: E731
    groups = ["all"]
    for i, g in enumerate(cfg.atoms):
        if g.group in groups:
            add(("atoms", i, "group"), f"group name '{g.group}' is {'reserved' if g.group == 'all' else 'used twice'}")
        groups.append(g.group)
        if g.shape is None and (g.orientation is not None or g.angmom is not None):
            add(("atoms", i, "orientation" if g.orientation is not None else "angmom"),
                "orientation and angmom are for ellipsoids: give the group a shape [a, b, c] (semi-axes)")
        c = g.create
        region = (c.random.region if c.random else None) or (c.lattice.region if c.lattice else None)
        if region is not None and region not in cfg.regions:
            key = "random" if c.random else "lattice"
            add(("atoms", i, "create", key, "region"), f"unknown region '{region}' (define it under regions:)")
        if c.lattice is not None and cfg.lattice is None:
            add(("atoms", i, "create", "lattice"), "lattice creation needs a `lattice:` (style and scale)")
        if c.file is None and g.mass is None:
            add(("atoms", i, "mass"), "mass is required (or give per-atom masses in a create.file .npz)")
        if g.velocity is not None and g.velocity.values is not None and c.positions is not None:
            vals = g.velocity.values
            if isinstance(vals, list) and len(vals) not in (len(c.positions),):
                add(("atoms", i, "velocity", "values"),
                    f"{len(vals)} velocities for {len(c.positions)} atoms: give one 3-vector, or one per atom")
    for name, region in cfg.regions.items():
        if region.units == "lattice" and cfg.lattice is None:
            add(("regions", name, "units"), _LATTICE_MSG)
    _check_creation_regions(cfg, add)
    _check_shared_velocities(cfg, add)

    try:
        Variables(cfg.variables)
    except VariableError as exc:
        add(("variables",) + ((exc.variable,) if exc.variable in cfg.variables else ()), str(exc))

    def check_var(path: tuple, value: Any) -> None:
        for ref in _var_refs(value):
            if ref not in cfg.variables:
                add(path, f"unknown variable v_{ref} (define it under variables:)")

    if cfg.output.dump is not None and cfg.run.time is not None:
        add(("output", "dump"), "per-atom dumps count steps: they need a step-based run (run: {steps: N})")
    radius_groups = {g.group for g in cfg.atoms if g.radius and g.radius > 0}
    shape_groups = {g.group for g in cfg.atoms if g.shape is not None}
    file_groups = {g.group for g in cfg.atoms if g.create.file is not None}  # per-atom data checked later

    def members_without(wall_group: str, having: set[str]) -> list[str]:
        members = [g.group for g in cfg.atoms] if wall_group == "all" else [wall_group]
        return [g for g in members if g in groups and g not in having and g not in file_groups]

    for fid, wall in cfg.walls.items():
        if wall.group not in groups:
            add(("walls", fid, "group"), f"unknown group '{wall.group}' (groups: {', '.join(groups)})")
        if wall.style in NOT_YET:
            add(("walls", fid, "style"), f"not supported yet: {NOT_YET[wall.style]}")
            continue
        entry = wall_style_entry(wall)
        if entry is not None or wall.style == "region/ees":
            if entry is not None and entry.needs_radius and (bad := members_without(wall.group, radius_groups)):
                add(("walls", fid, "group"), f"{_fix_name(wall)} requires extended particles: give group(s) "
                    f"{', '.join(bad)} a radius > 0")
            needs_shape = wall.style == "region/ees" or (entry is not None and entry.needs_shape)
            if needs_shape and (bad := members_without(wall.group, shape_groups)):
                add(("walls", fid, "group"), f"{_fix_name(wall)} requires ellipsoids (LAMMPS: requires extended "
                    f"particles): give group(s) {', '.join(bad)} a shape [a, b, c], or set this wall's group")
        _check_cutoff_mode(fid, wall, entry, add)
        if wall.style in ("region", "region/ees"):
            _check_region_wall(cfg, fid, wall, add, check_var)
            continue
        if wall.style == "flow":
            _check_flow_wall(cfg, fid, wall, add)
            continue
        if entry is not None and entry.per_face:
            _check_per_face_wall(cfg, fid, wall, entry, add)
        edges = wall.style != "reflect/stochastic" and all(getattr(f, "coord", None) == "EDGE" for _, f in wall.faces())
        if wall.units == "lattice" and cfg.lattice is None and not edges:  # EDGE alone: nothing to scale
            add(("walls", fid), _LATTICE_MSG)
        for face, spec in wall.faces():
            dim = "xyz".index(face[0])
            if cfg.box.boundary[dim] == "p" and not wall.pbc and not (dim == 2 and cfg.dimension == 2):
                # (a z face in 2-D: refused as such, `check_ensemble`; z must stay periodic there)
                add(("walls", fid, face),
                    f"cannot use a {face} wall in periodic {face[0]} dimension: make box.boundary "
                    f"{face[0]} 'f', or set pbc: true on this wall")
            scale = 1.0 if wall.units == "box" else lattice_spacing(cfg)
            coord = getattr(spec, "coord", None)
            if isinstance(coord, float) and scale is not None and not getattr(wall, "pbc", False) \
                    and math.isfinite(coord):
                lo, hi, at = float(cfg.box.lo[dim]), float(cfg.box.hi[dim]), coord * scale
                if (face.endswith("lo") and at > hi) or (face.endswith("hi") and at < lo):
                    add(("walls", fid, face, "coord"),
                        f"the {face} wall at {at:g} (box units) lies past the box ({lo:g} .. {hi:g} in "
                        f"{face[0]}): every atom would be behind it; put it inside the box or use EDGE")
            for key, value in spec.model_dump().items():
                if key == "coord" or entry is None or entry.param(key).numeric:
                    check_var(("walls", fid, face, key), value)
                    _check_min(entry, key, value, ("walls", fid, face, key), add)
    if cfg.dt_reset is not None:
        if cfg.dt_reset.group not in groups:
            add(("dt_reset", "group"), f"unknown group '{cfg.dt_reset.group}'")
        if cfg.dt_reset.units == "lattice" and cfg.lattice is None:
            add(("dt_reset",), _LATTICE_MSG)
    if isinstance(cfg.run.thermo, TimeInterval) and cfg.run.time is None:
        add(("run", "thermo"), "time-based sampling (thermo: {time: ...}) needs a time-based run (run: {time: ...})")
    if cfg.run.time is not None and isinstance(cfg.run.thermo, int) and cfg.run.thermo > 0:
        add(("run", "thermo"), "a run to a simulated time samples at times: write thermo: {time: INTERVAL} "
            "(or 0 for the first and last instant only)")
    styles = {w.style for w in cfg.walls.values()}
    for key, needs, what in (("reflect_count", "reflect", "a reflect wall"),
                             ("reflect_impulse", "reflect", "a reflect wall"),
                             ("flow_crossings", "flow", "a flow wall")):
        if key in cfg.output.thermo and needs not in styles and not (needs == "reflect" and "reflect/stochastic" in styles):
            add(("output", "thermo"), f"{key} needs {what} in the scene")
    if "erot" in cfg.output.thermo and not shape_groups and not file_groups:
        add(("output", "thermo"), "erot is the rotational energy of ellipsoids: no group has a shape")
    problems.extend(check_ensemble(cfg))  # fixes: and dimension:
    problems += check_profiles(cfg, groups)
    return problems


def _fix_name(wall: Any) -> str:
    return f"wall/{wall.style}" if wall.style != "region" else f"wall/region {wall.potential}"


def wall_style_entry(wall: Any) -> WallStyle | None:
    """The registry entry of a wall model: its style, or a region wall's potential (None for
    reflect, flow and region/ees)."""
    if wall.style == "region":
        return STYLES[wall.potential]
    return STYLES.get(wall.style)


def _check_min(entry: WallStyle | None, key: str, value: Any, path: tuple, add: Any) -> None:
    """A number below the parameter's lower bound (LAMMPS refuses it when the fix is created)."""
    if entry is None or key not in entry.params:
        return
    p = entry.param(key)
    if p.min is not None and isinstance(value, float) and value < p.min:
        add(path, f"{key} must be >= {p.min:g}")
    elif p.positive and isinstance(value, float) and not value > 0:
        add(path, f"{key} must be > 0")


def _check_cutoff_mode(fid: str, wall: Any, entry: WallStyle | None, add: Any) -> None:
    """cutoff_mode and switch_on (docs/physics.md §17): smooth needs 0 <= switch_on < every cut-off
    of the wall, switch_on is refused without smooth, and wall/ees takes only shift."""
    mode = getattr(wall, "cutoff_mode", "shift")
    r_on = getattr(wall, "switch_on", None)
    if mode != "shift" and entry is not None and not cutoff_supported(entry):
        add(("walls", fid, "cutoff_mode"), f"{_fix_name(wall)} takes only cutoff_mode: shift (its energy depends on "
            f"more than the distance)")
    if r_on is not None and mode != "smooth":
        add(("walls", fid, "switch_on"), f"switch_on is where the smooth switch starts: it needs cutoff_mode: smooth "
            f"(this wall has {mode})")
    if mode == "smooth" and r_on is None:
        add(("walls", fid, "cutoff_mode"), "cutoff_mode: smooth needs switch_on (where the switch starts, "
            "0 <= switch_on < cutoff)")
    if mode == "smooth" and r_on is not None:
        cuts = ([("", wall.cutoff)] if wall.style == "region"
                else [(f" ({face})", spec.cutoff) for face, spec in wall.faces()])
        for where, rc in cuts:
            if isinstance(rc, float) and not r_on < rc:
                add(("walls", fid, "switch_on"), f"switch_on = {r_on:g} must be smaller than the cut-off{where} "
                    f"{rc:g}")


def _check_creation_regions(cfg: "Config", add: Any) -> None:
    """A region atoms are created in (create.random.region, create.lattice.region) with no volume
    inside the box creates no atom, and one a wall/region acts from has every atom outside its
    surface (LAMMPS stops: Particle outside surface of region used in fix wall/region): refused at
    the region. One lying partly outside the box is fine (the atoms are placed in the part inside,
    as LAMMPS clips; a wall/region acts where its surface is)."""
    users: dict[str, list[str]] = {}
    walls: dict[str, list[str]] = {}
    for i, g in enumerate(cfg.atoms):
        for key in ("random", "lattice"):
            spec = getattr(g.create, key)
            if spec is not None and spec.region in cfg.regions:
                users.setdefault(spec.region, []).append(f"atoms.{i}.create.{key} (group {g.group})")
    for fid, wall in cfg.walls.items():
        if getattr(wall, "style", None) in ("region", "region/ees") and wall.region in cfg.regions:
            walls.setdefault(wall.region, []).append(f"walls.{fid} (wall/{wall.style})")
    if not users and not walls:
        return
    from wallbatch.geometry.regions import RegionGeom  # noqa: PLC0415 - numpy geometry, only when needed

    lo, hi = list(cfg.box.lo), list(cfg.box.hi)
    if cfg.dimension == 2:  # atoms are created in the plane z = 0
        lo[2] = hi[2] = 0.0
    for name in list(users) + [n for n in walls if n not in users]:
        region = cfg.regions[name]
        if region.units == "lattice" and cfg.lattice is None:
            continue  # reported above
        geom = RegionGeom.from_config(region, None if region.units == "box" else lattice_spacing(cfg))
        if not geom.misses_box(lo, hi):
            continue
        box = f"box lo {_fmt_vec(cfg.box.lo)} hi {_fmt_vec(cfg.box.hi)}"
        if region.units == "lattice":
            box += f"; the region's numbers are lattice units, times the lattice spacing {lattice_spacing(cfg):g}"
        if cfg.dimension == 2:
            box += "; a 2-D run creates its atoms in the plane z = 0"
        effects = []
        if name in users:
            effects.append(f"{' and '.join(users[name])} would create no atom")
        if name in walls:
            effects.append(f"{' and '.join(walls[name])} would find every atom outside its surface (LAMMPS stops: "
                           f"Particle outside surface of region used in fix wall/region)")
        what = ", and ".join(effects)
        if region.side == "in":
            add(("regions", name), f"region {name} lies wholly outside the box ({box}), so {what}: move or resize "
                f"the region so that part of it is in the box, or enlarge the box")
        else:
            add(("regions", name), f"region {name} (side: out) leaves nothing of the box: its {region.style} holds "
                f"the whole box ({box}), so {what}: shrink or move the {region.style}, or use side: in")


def _check_shared_velocities(cfg: "Config", add: Any) -> None:
    """The groups of one `velocity.shared` set are drawn at one temperature: each gives the same."""
    first: dict[str, tuple[int, str, float]] = {}
    for i, g in enumerate(cfg.atoms):
        vel = g.velocity
        if vel is None or vel.shared is None:
            continue
        if vel.shared not in first:
            first[vel.shared] = (i, g.group, float(vel.temperature))
            continue
        j, other, temp = first[vel.shared]
        if float(vel.temperature) != temp:
            add(("atoms", i, "velocity", "temperature"),
                f"group {g.group} shares the velocity set '{vel.shared}' with group {other} (atoms.{j}), drawn at "
                f"temperature {temp:g}, but gives {float(vel.temperature):g}: give every group of a set the same "
                f"temperature, or another shared label")


def _fmt_vec(v: Any) -> str:
    return "[" + ", ".join(f"{float(x):g}" for x in v) + "]"


def _check_region_wall(cfg: "Config", fid: str, wall: Any, add: Any, check_var: Any) -> None:
    """wall/region and wall/region/ees: the region exists, the potential's parameters are given."""
    if wall.region not in cfg.regions:
        add(("walls", fid, "region"), f"unknown region '{wall.region}' (LAMMPS: Region {wall.region} for fix "
            f"wall/{wall.style} does not exist): define it under regions:")
    entry = wall_style_entry(wall)
    if entry is not None:
        takes = entry.args_names
        need = tuple(p.name for p in entry.parameters if p.required and p.name != "cutoff")
        for k in need:
            if getattr(wall, k) is None:
                add(("walls", fid, k), f"potential {wall.potential} needs {k} ({', '.join(need)}, cutoff)")
        for k in REGION_PARAMS:
            if getattr(wall, k) is not None and k not in takes:
                add(("walls", fid, k), f"potential {wall.potential} does not take {k} (it takes {', '.join(need)}, "
                    f"cutoff)")
    for k in REGION_PARAMS if wall.style == "region" else ("epsilon", "sigma"):
        value = getattr(wall, k, None)
        check_var(("walls", fid, k), value)
        if wall.style == "region/ees":
            if isinstance(value, float) and value < 0:
                add(("walls", fid, k), f"{k} must be >= 0")
        else:
            _check_min(entry, k, value, ("walls", fid, k), add)


def _check_per_face_wall(cfg: "Config", fid: str, wall: Any, entry: WallStyle, add: Any) -> None:
    """A style built per face (wall/lepton, wall/table): the entry's own checks of each face
    (an expression parses and is finite, a table file reads, ...)."""
    values = wall.model_dump()
    for face, spec in wall.faces():
        for key, message in entry.check_face(spec.model_dump(), values, str(cfg._base_dir)):
            add(("walls", fid, face, *key.split(".")), message)


def _check_flow_wall(cfg: "Config", fid: str, wall: Any, add: Any) -> None:
    """fix wall/flow restrictions (physics.md §8.6)."""
    dim = "xyz".index(wall.axis)
    if cfg.box.boundary[dim] != "p":
        add(("walls", fid, "axis"), f"wall/flow cannot be used with a non-periodic boundary along the flow axis "
            f"{wall.axis}: make box.boundary {wall.axis} 'p'")
    if wall.units == "lattice" and cfg.lattice is None:
        add(("walls", fid), _LATTICE_MSG)
        return
    scale = 1.0 if wall.units == "box" else lattice_spacing(cfg)
    w = [cfg.box.lo[dim]] + [c * scale for c in wall.coords] + [cfg.box.hi[dim]]
    if any(b <= a for a, b in zip(w, w[1:])):
        add(("walls", fid, "coords"), f"flow wall coordinates must be strictly increasing and strictly inside the "
            f"box ({cfg.box.lo[dim]:g} .. {cfg.box.hi[dim]:g} along {wall.axis}), got "
            f"{[c * scale for c in wall.coords]} (LAMMPS: Wrong fix wall/flow wall ordering or some walls are "
            f"outside simulation domain)")


def lattice_spacing(cfg: "Config") -> float | None:
    """The lattice spacing of `lattice:` in box units (physics.md §2.1), or None without one."""
    if cfg.lattice is None:
        return None
    return lattice_constant(cfg.lattice.style, cfg.lattice.scale, cfg.units)


_LATTICE_MSG = (
    "units: lattice (the default, as in LAMMPS) needs a `lattice:` in the config; "
    "add `units: box` here or define `lattice: {style: fcc, scale: ...}`"
)
