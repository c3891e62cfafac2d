"""`fixes:` (integrators and thermostats) and `dimension:` of a config: the mapping-form models,
the LAMMPS fix-line form, and the cross-field checks.

```yaml
dimension: 2
fixes:
  move: {style: nve, group: mobile}
  bath: {style: langevin, group: mobile, temp: [1.5, 1.5], damp: 0.5, seed: 412513, zero: true}
  nh:   "fix nh fluid nvt temp 1.0 1.0 0.1"
```
Mapping keys mirror the fix line's arguments. Absent `fixes:` means `{nve: {style: nve, group: all}}`.
"""

from __future__ import annotations

from typing import Annotated, Any, Literal

from pydantic import (
    ConfigDict,
    Field,
    NonNegativeFloat,
    PositiveFloat,
    PositiveInt,
    field_validator,
)

from wallbatch.config.base import NoBoolNumbers
from wallbatch.config.fixline import FixLineError, _Words
from wallbatch.config.ondemand import tagged_on_demand

INTEGRATORS = ("nve", "nve/asphere", "nvt")
THERMOSTATS = ("nvt", "langevin", "temp/berendsen", "temp/rescale")
FIX_STYLES = ("nve", "nve/asphere", "nvt", "langevin", "temp/berendsen", "temp/rescale", "enforce2d")
DEFAULT_FIXES = {"nve": {"style": "nve", "group": "all"}}

GroupName = Annotated[str, Field(pattern=r"^[A-Za-z_][A-Za-z0-9_\-]*$")]
Temps = tuple[NonNegativeFloat, NonNegativeFloat]


class _Fix(NoBoolNumbers):
    # built when a config first uses the style (EnsembleFix)
    model_config = ConfigDict(extra="forbid", frozen=True, defer_build=True)

    group: GroupName = "all"


class NveFix(_Fix):
    """fix nve: velocity Verlet for the group (ellipsoids: fix nve/asphere)."""

    style: Literal["nve"]


class NveAsphereFix(_Fix):
    """fix nve/asphere: velocity Verlet plus the Richardson rotation step (ellipsoids)."""

    style: Literal["nve/asphere"]


class NvtFix(_Fix):
    """`fix nvt temp Tstart Tstop Tdamp [tchain N] [tloop N] [drag D]`: Nose-Hoover chain."""

    style: Literal["nvt"]
    temp: tuple[PositiveFloat, PositiveFloat]
    damp: PositiveFloat
    tchain: PositiveInt = 3
    tloop: PositiveInt = 1
    drag: NonNegativeFloat = 0.0


class LangevinFix(_Fix):
    """`fix langevin Tstart Tstop damp seed [zero yes] [tally yes]`: drag plus random force."""

    style: Literal["langevin"]
    temp: Temps
    damp: PositiveFloat
    seed: Annotated[int, Field(gt=0, le=900_000_000)]
    zero: bool = False
    tally: bool = False
    omega: bool = False

    @field_validator("omega")
    @classmethod
    def _omega(cls, v: bool) -> bool:
        if v:
            raise ValueError("omega yes (thermostatting the rotation of finite-size particles) is not "
                             "supported: remove it")
        return v


class BerendsenFix(_Fix):
    """fix temp/berendsen Tstart Tstop damp: v *= sqrt(1 + dt/damp (T_target/T - 1)) every step."""

    style: Literal["temp/berendsen"]
    temp: Temps
    damp: PositiveFloat


class RescaleFix(_Fix):
    """fix temp/rescale N Tstart Tstop window fraction."""

    style: Literal["temp/rescale"]
    every: PositiveInt
    temp: Temps
    window: NonNegativeFloat
    fraction: Annotated[float, Field(gt=0.0, le=1.0)]


class Enforce2dFix(_Fix):
    """fix enforce2d: zero the z velocity and force of the group (2-D runs)."""

    style: Literal["enforce2d"]


FIX_MODELS: dict[str, type[_Fix]] = {  # FIX_STYLES' models, in its order
    "nve": NveFix, "nve/asphere": NveAsphereFix, "nvt": NvtFix, "langevin": LangevinFix,
    "temp/berendsen": BerendsenFix, "temp/rescale": RescaleFix, "enforce2d": Enforce2dFix}
# a fix under `fixes:`: validated by the model of its style alone (built on first use)
EnsembleFix = tagged_on_demand(FIX_STYLES, FIX_MODELS.__getitem__)


# ----------------------------------------------------------------------------- fix lines


def _yes_no(w: _Words, i: int) -> bool:
    if i + 1 >= len(w):
        raise w.error(i, f"missing value after {w[i]}: write '{w[i]} yes' or '{w[i]} no'")
    if w[i + 1] not in ("yes", "no"):
        raise w.error(i + 1, f"bad {w[i]} value: write '{w[i]} yes' or '{w[i]} no'")
    return w[i + 1] == "yes"


def _need(w: _Words, n: int, usage: str) -> None:
    if len(w) < n:
        raise w.missing(f"too few arguments: write '{usage}'")


def parse_ensemble_line(text: str, fix_id: str) -> dict:
    """Parse 'fix ID group style args...' of an integrator/thermostat into the mapping form.
    Raises FixLineError naming the word and its 1-based position."""
    if not isinstance(text, str):
        raise FixLineError(f"a fix line must be a string, not {type(text).__name__}")
    w = _Words(text)
    if len(w) == 0:
        raise FixLineError("empty fix line: write 'fix ID group-ID style args ...'", line=text)
    if w[0] != "fix":
        raise w.error(0, "a fix line must start with 'fix': write 'fix ID group-ID style args ...'")
    if len(w) < 4:
        raise w.missing("missing fix ID, group-ID or style: write e.g. 'fix 1 all nve'")
    if w[1] != fix_id:
        raise w.error(1, f"the fix ID must equal the mapping key {fix_id!r} the line is written under: "
                         f"write 'fix {fix_id} ...' or rename the key to {w[1]!r}")
    group = w.identifier(2, "the group-ID")
    style = w[3]
    if style not in FIX_STYLES:
        raise w.error(3, f"unknown or unsupported fix style; supported under fixes: {', '.join(FIX_STYLES)}")
    out: dict[str, Any] = {"style": style, "group": group}
    if style in ("nve", "nve/asphere", "enforce2d"):
        if len(w) > 4:
            raise w.error(4, f"fix {style} takes no arguments")
        return out
    if style == "nvt":
        usage = "fix ID group nvt temp Tstart Tstop Tdamp [tchain N] [tloop N] [drag D]"
        i, seen_temp = 4, False
        while i < len(w):
            key = w[i]
            if key == "temp":
                _need(w, i + 4, usage)
                out["temp"] = [w.number(i + 1, "Tstart"), w.number(i + 2, "Tstop")]
                out["damp"] = w.number(i + 3, "Tdamp")
                seen_temp, i = True, i + 4
            elif key in ("tchain", "tloop"):
                _need(w, i + 2, usage)
                out[key] = w.integer(i + 1, key)
                i += 2
            elif key == "drag":
                _need(w, i + 2, usage)
                out["drag"] = w.number(i + 1, "drag")
                i += 2
            else:
                raise w.error(i, f"unsupported fix nvt keyword; write '{usage}'")
        if not seen_temp:
            raise w.missing(f"fix nvt needs 'temp Tstart Tstop Tdamp': write '{usage}'")
        return out
    if style == "langevin":
        usage = "fix ID group langevin Tstart Tstop damp seed [zero yes] [tally yes]"
        _need(w, 8, usage)
        out["temp"] = [w.number(4, "Tstart"), w.number(5, "Tstop")]
        out["damp"] = w.number(6, "damp")
        out["seed"] = w.integer(7, "seed")
        i = 8
        while i < len(w):
            if w[i] in ("zero", "tally", "omega"):
                out[w[i]] = _yes_no(w, i)
                i += 2
            else:
                raise w.error(i, f"unsupported fix langevin keyword (supported: zero, tally); write '{usage}'")
        return out
    if style == "temp/berendsen":
        usage = "fix ID group temp/berendsen Tstart Tstop damp"
        _need(w, 7, usage)
        if len(w) > 7:
            raise w.error(7, f"too many arguments: write '{usage}'")
        return {**out, "temp": [w.number(4, "Tstart"), w.number(5, "Tstop")], "damp": w.number(6, "damp")}
    usage = "fix ID group temp/rescale N Tstart Tstop window fraction"
    _need(w, 9, usage)
    if len(w) > 9:
        raise w.error(9, f"too many arguments: write '{usage}'")
    return {**out, "every": w.integer(4, "N"), "temp": [w.number(5, "Tstart"), w.number(6, "Tstop")],
            "window": w.number(7, "window"), "fraction": w.number(8, "fraction")}


def to_ensemble_line(fix_id: str, fix: Any) -> str:
    """The LAMMPS fix line of a validated fix model (export)."""
    def num(x: float) -> str:
        return repr(float(x))

    head = f"fix {fix_id} {fix.group} {fix.style}"
    if fix.style in ("nve", "nve/asphere", "enforce2d"):
        return head
    if fix.style == "nvt":
        return (f"{head} temp {num(fix.temp[0])} {num(fix.temp[1])} {num(fix.damp)} tchain {fix.tchain} "
                f"tloop {fix.tloop} drag {num(fix.drag)}")
    if fix.style == "langevin":
        return (f"{head} {num(fix.temp[0])} {num(fix.temp[1])} {num(fix.damp)} {fix.seed} "
                f"zero {'yes' if fix.zero else 'no'} tally {'yes' if fix.tally else 'no'}")
    if fix.style == "temp/berendsen":
        return f"{head} {num(fix.temp[0])} {num(fix.temp[1])} {num(fix.damp)}"
    return f"{head} {fix.every} {num(fix.temp[0])} {num(fix.temp[1])} {num(fix.window)} {num(fix.fraction)}"


def expand_fix_lines(data: Any, srcmap: Any) -> tuple[Any, list[str]]:
    """Fixes written as LAMMPS lines become the mapping form; an unknown style is reported at its
    `style` key. Returns (data, problems)."""
    if not isinstance(data, dict) or not isinstance(data.get("fixes"), dict):
        return data, []
    fixes, problems = {}, []
    for fid, f in data["fixes"].items():
        try:
            if isinstance(f, str):
                f = parse_ensemble_line(f, str(fid))
        except FixLineError as exc:
            problems.append(srcmap.format(("fixes", fid), str(exc)))
        if isinstance(f, dict) and "style" in f and f["style"] not in FIX_STYLES:
            problems.append(srcmap.format(("fixes", fid, "style"), f"unknown fix style {f['style']!r}; supported "
                                          f"under fixes: {', '.join(FIX_STYLES)}"))
        fixes[str(fid)] = f
    return {**data, "fixes": fixes}, problems


def drop_fix_tag(loc: tuple) -> tuple:
    """A validation error's location without the union tag Pydantic puts after a fix-ID
    (fixes.nh.nvt.damp -> fixes.nh.damp)."""
    if len(loc) > 2 and loc[0] == "fixes" and loc[2] in FIX_STYLES:
        return loc[:2] + loc[3:]
    return loc


def check_ensemble(cfg: Any) -> list[tuple[tuple, str]]:
    """Cross-field checks of `fixes:` and `dimension:` (path, message)."""
    problems: list[tuple[tuple, str]] = []
    add = lambda path, msg: problems.append((path, msg))
    groups = ["all"] + [g.group for g in cfg.atoms]
    fixes = cfg.fixes if cfg.fixes is not None else {}
    integrated: dict[str, str] = {}  # atom group -> fix-ID that integrates it
    ellipsoids = any(g.shape is not None for g in cfg.atoms)
    for fid, fix in fixes.items():
        if fid in cfg.walls:
            add(("fixes", fid), f"fix-ID '{fid}' is also a wall's: LAMMPS fix-IDs are unique, rename one")
        if fix.group not in groups:
            add(("fixes", fid, "group"), f"unknown group '{fix.group}' (groups: {', '.join(groups)})")
            continue
        members = [g for g in groups[1:]] if fix.group == "all" else [fix.group]
        if fix.style in INTEGRATORS:
            twice = [g for g in members if g in integrated]
            if twice:
                add(("fixes", fid, "group"), f"group '{twice[0]}' is already integrated by fix "
                    f"'{integrated[twice[0]]}': an atom integrated twice moves twice per step (LAMMPS only "
                    f"warns); give each atom one integrator")
            for g in members:
                integrated.setdefault(g, fid)
        if ellipsoids and fix.style in THERMOSTATS:
            add(("fixes", fid, "style"), f"fix {fix.style} on ellipsoids is not supported (it would thermostat "
                "only their translation); run ellipsoids with nve/asphere")
        if fix.style == "nve/asphere":
            flat = [g.group for g in cfg.atoms if g.group in members and g.shape is None and g.create.file is None]
            if flat:
                add(("fixes", fid, "group"), f"fix nve/asphere requires ellipsoids: group(s) {', '.join(flat)} "
                    "have no shape")
        if fix.style == "enforce2d" and cfg.dimension != 2:
            add(("fixes", fid, "style"), "fix enforce2d is for 2-D runs: set dimension: 2")
    if ellipsoids and cfg.fixes is not None:
        left = [g for g in groups[1:] if g not in integrated]
        if left:
            add(("fixes",), f"group(s) {', '.join(left)} are integrated by no fix: frozen atoms are not supported "
                "in scenes with ellipsoids (integrate every atom with nve or nve/asphere)")
    if cfg.dimension == 2:
        if cfg.box.boundary[2] != "p":
            add(("box", "boundary"), "a 2-D run (dimension: 2) needs a periodic z boundary, as LAMMPS")
        if not cfg.box.lo[2] < 0.0 < cfg.box.hi[2]:
            add(("box", "lo"), f"a 2-D run (dimension: 2) has its atoms at z = 0: the box's z range "
                f"({cfg.box.lo[2]:g} to {cfg.box.hi[2]:g}) must straddle 0, e.g. -0.5 to 0.5 (LAMMPS: Create_box "
                f"region zlo/zhi for 2d simulation must straddle 0.0)")
        for i, group in enumerate(cfg.atoms):
            pos = group.create.positions
            off = [k for k, p in enumerate(pos or []) if p[2] != 0.0]
            if off:
                add(("atoms", i, "create", "positions", off[0]), f"z = {pos[off[0]][2]:g} in a 2-D run (dimension: "
                    f"2): every atom has z = 0 (LAMMPS: Create_atoms single for 2d simulation requires z coord = 0.0)")
        for fid, wall in cfg.walls.items():
            zfaces = [f for f in ("zlo", "zhi") if getattr(wall, f, None) is not None]
            if zfaces:
                add(("walls", fid, zfaces[0]), f"a {zfaces[0]} wall in a 2-D run (dimension: 2): 2-D walls act "
                    "in x and y only")
            elif getattr(wall, "style", None) == "flow" and getattr(wall, "axis", None) == "z":
                add(("walls", fid, "axis"), "a z flow wall in a 2-D run (dimension: 2)")
        if ellipsoids:
            add(("dimension",), "ellipsoids (shape) are 3-D only")
        if cfg.lattice is not None and cfg.lattice.style == "hex":
            for fid, wall in cfg.walls.items():
                if getattr(wall, "units", "box") == "lattice":
                    add(("walls", fid, "units"), "lattice hex has different x and y spacings (a, sqrt(3) a): give "
                        "this wall's coordinates in box units (units: box)")
            for name, region in cfg.regions.items():
                if region.units == "lattice":
                    add(("regions", name, "units"), "lattice hex has different x and y spacings (a, sqrt(3) a): "
                        "give this region in box units (units: box)")
        if cfg.lattice is not None and cfg.lattice.style not in ("sq", "sq2", "hex"):
            add(("lattice", "style"), f"lattice {cfg.lattice.style} is 3-D: a 2-D run uses sq, sq2 or hex")
    elif cfg.lattice is not None and cfg.lattice.style in ("sq", "sq2", "hex"):
        add(("lattice", "style"), f"lattice {cfg.lattice.style} is 2-D: set dimension: 2 (3-D: sc, bcc, fcc)")
    return problems
