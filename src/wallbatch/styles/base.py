"""What a wall style is: its parameters (`Param`) and its registry entry (`WallStyle`).

Everything else (the config face models and their positional form, the fix-line reader and
writer, the LAMMPS export, the parameter checks, the compiled kernel dispatch and the per-style
tests) is derived from these entries; see docs/developer.md, "Adding a wall style".
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

Params = Mapping[str, np.ndarray | float]
# f(r, p0, p1, p2, rc, radius): plain arithmetic on floats or broadcastable arrays
ScalarFn = Callable[..., np.ndarray]

MAX_COMPILED_PARAMS = 3  # the compiled path carries p0, p1, p2 per face (besides coord and cutoff)


@dataclass(frozen=True)
class Param:
    """One per-face argument of a wall style, in LAMMPS argument order.

    ``unit`` is the unit kind (``energy``, ``distance``, ``energy/distance^2``, ``1/distance``,
    ``energy/distance^3``), used by docs and exports. ``min`` is a lower bound (``value >= min``)
    checked on numbers in the config and, for variables, each step (LAMMPS: "Variable evaluation
    in fix wall gave bad value"); ``positive`` asks ``value > 0`` (the cutoff). ``variable``: an
    equal-style variable ``v_name`` is accepted. ``required=False``: the config may leave it out
    (LAMMPS still reads a word there: ``placeholder`` is written for it).
    """

    name: str
    unit: str
    min: float | None = None
    max: float | None = None  # an upper bound of an ``integer`` (a table's points: memory)
    positive: bool = False
    variable: bool = True
    required: bool = True
    placeholder: float | None = None  # written for an omitted optional argument (LAMMPS reads a word)
    doc: str = ""
    lammps_variable_note: str | None = None  # LAMMPS does not use a variable here: the export's decision row
    # what the value is: ``number`` (the default; a float, or v_name where ``variable``), ``word``
    # (a string: an expression, a file name; ``quoted``: written in double quotes in a fix line),
    # ``choice`` (one of ``choices``), ``integer`` (>= ``min``, <= ``max``), or ``mapping`` (names -> numbers,
    # a config key with no word of its own in the fix line, e.g. wall/lepton's params)
    kind: str = "number"
    choices: tuple[str, ...] = ()
    quoted: bool = False

    @property
    def numeric(self) -> bool:
        return self.kind == "number"


def cutoff_param() -> Param:
    """The last argument of every flat soft style: the cut-off distance rc > 0 (a number)."""
    return Param("cutoff", "distance", positive=True, variable=False, doc="cut-off distance rc: no force beyond it")


def _missing(*_: object) -> np.ndarray:
    raise TypeError("this wall style has no closed form in r alone (see its kernel)")


@dataclass(frozen=True)
class WallStyle:
    """One registry entry: a wall style and everything the rest of the code derives from it.

    * ``name``: the config's ``style:`` value; ``lammps``: the LAMMPS fix style (``wall/NAME``).
    * ``parameters``: per-face arguments after ``coord``, in LAMMPS order (the last is the cutoff).
    * ``force(r, p0, p1, p2, rc, radius)`` [force], F = -dE/dr, F > 0 repulsive, and
      ``energy(...)`` [energy] (unshifted): plain arithmetic on floats *and* arrays, with p0..p2
      the non-cutoff parameters in order (0.0 where a style has fewer) and ``radius`` the
      particle radius (styles that ``needs_radius``). ``force`` is jit-compiled as is by
      wallbatch.engine.compiled, so it must not branch on arrays.
    * ``shifted_fn(...)``: E(r) - E(rc) without cancellation as r -> rc (same arguments).
    * ``shifted``: the reported energy is E(r) - E(rc) (False: E(r), e.g. wall/ees).
    * ``needs_radius`` / ``needs_shape``: atoms need a radius > 0 / ellipsoid semi-axes.
    * ``region``: usable as the potential of wall/region; ``compiled``: the numba path may run it.
    * ``virial``: the fix has a virial contribution (fix_modify virial).
    * ``decision``: a decisions-table row the LAMMPS export prints for a case using the style.
    """

    name: str
    parameters: tuple[Param, ...]
    force: ScalarFn = _missing
    energy: ScalarFn = _missing
    shifted_fn: ScalarFn | None = None
    shifted: bool = True
    needs_radius: bool = False
    needs_shape: bool = False
    region: bool = True
    compiled: bool = True
    virial: bool = True
    decision: str | None = None
    region_quirk: bool = False  # LAMMPS's wall/region with this potential differs (decision row region_NAME)
    # the numba path can compile shifted_fn (the smooth cut-off's force needs E(r) - E(rc)); False:
    # cutoff_mode smooth of this style runs in NumPy
    compiled_shifted: bool = True
    doc: str = ""
    lammps: str = field(default="")
    # words of the fix line between the style and the first face, also keys of the wall's config
    # mapping (wall/table: tabstyle N)
    wall_parameters: tuple[Param, ...] = ()
    # the style of each face is built from the face's own values (an expression, a table file):
    # see face_style, check_face, fix_face, lammps_face, example (wall/lepton, wall/table)
    per_face: bool = False
    # the sign of LAMMPS's per-face fix vector against wallbatch's wall_force (the force on the
    # wall): -1 where LAMMPS reports the force on the atoms (wall/lepton)
    lammps_force_sign: float = 1.0

    def __post_init__(self) -> None:
        if not self.lammps:
            object.__setattr__(self, "lammps", f"wall/{self.name}")
        if len(self.args_names) > MAX_COMPILED_PARAMS:
            object.__setattr__(self, "compiled", False)

    # -- names ---------------------------------------------------------------------------------

    @property
    def params(self) -> tuple[str, ...]:
        """Per-face argument names after coord, in LAMMPS order (cutoff last): the words of a face
        in a fix line (parameters of kind ``mapping`` have none)."""
        return tuple(p.name for p in self.parameters if p.kind != "mapping")

    @property
    def face_keys(self) -> tuple[str, ...]:
        """Every key of a face's config mapping besides coord (``params`` and the mappings)."""
        return tuple(p.name for p in self.parameters)

    @cached_property  # read at every NumPy step (args)
    def args_names(self) -> tuple[str, ...]:
        """The parameters passed as p0, p1, p2 (the numbers, but the cutoff)."""
        return tuple(p.name for p in self.parameters if p.name != "cutoff" and p.numeric)

    @property
    def positional(self) -> tuple[str, ...]:
        """The positional face form `[coord, ...]` of the config and of the fix line."""
        return ("coord",) + self.params

    def param(self, name: str) -> Param:
        return next(p for p in self.parameters + self.wall_parameters if p.name == name)

    # -- styles built per face (per_face: wall/lepton, wall/table) -------------------------------

    def face_style(self, face: Mapping, wall: Mapping, base_dir: str) -> tuple[WallStyle, dict, object]:
        """(the face's own style, its numeric parameters (cutoff included), a signature: what
        decides which cases share a batch) from the face's config values ``face`` (coord and the
        parameters), the wall's (``wall``: its wall_parameters) and the config's folder (relative
        files). Raises ValueError (a message for the user) when the face cannot be built."""
        raise NotImplementedError(f"wall/{self.name} has one style for every face")

    def check_face(self, face: Mapping, wall: Mapping, base_dir: str) -> list[tuple[str, str]]:
        """Problems of one face before anything runs, as (face key, message) pairs."""
        return []

    def fix_face(self, face: Mapping) -> dict:
        """A face's config values -> the values of its fix-line words (``params`` and the other
        mappings folded into the words they belong to)."""
        return {k: v for k, v in face.items() if k == "coord" or k in self.params}

    def lammps_face(self, face: Mapping, params: Mapping[str, float], signature: object) -> dict:
        """A face's fix-line values for a LAMMPS script of one case: ``face`` its config values,
        ``params`` this case's numbers, ``signature`` as from face_style (a table's absolute path)."""
        return self.fix_face({**face, **params})

    def example(self, directory: str) -> tuple[dict, dict]:
        """(wall keys, face values besides coord) of a working wall of this style for the tests
        parametrised over the registry (files written into ``directory``)."""
        raise NotImplementedError

    # -- evaluation on a parameter mapping (the NumPy engine, tests) ------------------------------

    def args(self, p: Params) -> tuple:
        """(p0, p1, p2, rc, radius) from a mapping of parameter names (missing optional ones: 0)."""
        vals = [p.get(n, 0.0) for n in self.args_names]
        vals += [0.0] * (MAX_COMPILED_PARAMS - len(vals))
        return (*vals, p.get("cutoff", np.inf), p.get("radius", 0.0))

    def energy_force(self, r, p: Params) -> tuple[np.ndarray, np.ndarray]:
        """(E(r), F(r)) unshifted. [energy], [force]"""
        a = self.args(p)
        return self.energy(r, *a), self.force(r, *a)

    def too_close(self, p: Params) -> np.ndarray | float:
        """Threshold t: an atom within the cut-off with delta <= t is "on or inside" the wall.

        0, or the particle radius for styles that need one (colloid).
        """
        return p["radius"] if self.needs_radius else 0.0

    def generated_force(self) -> str | None:
        """Python source of ``kernel(r, p0, p1, p2, rc, radius)``, this style's force F(r)
        [force] for the compiled path, for styles made per face from an expression or a table
        (wall/lepton, wall/table); None for the registry's built-in styles (compiled from
        ``force`` itself) and for faces the compiled path cannot run."""
        return None

    def generated_vector_force(self) -> str | None:
        """Python source of ``kernel(r, p)``, the force F(r) [force] with the parameters as one
        array p (in ``args_names`` order), for per-face styles with more parameters than the
        compiled path's p0, p1, p2 (wall/lepton); None otherwise."""
        return None

    def generated_energy(self) -> str | None:
        """Python source of ``energy(...)``, the unshifted energy E(r) [energy] in the form of
        the style's generated force (``generated_force`` or ``generated_vector_force``), for the
        compiled path's samples; None where there is no generated force."""
        return None

    def too_close_message(self) -> str | None:
        """How a case that fails because an atom is "on or inside" the wall (too_close) is
        described after "atom A at distance D from the wall at step S is", or None for the
        engine's usual message."""
        return None

    def shifted_energy(self, r, p: Params) -> np.ndarray:
        """The reported energy: E(r) - E(rc), rc = p["cutoff"] (E(r) if ``shifted`` is False). [energy]

        The offset uses the same (per-atom) parameters, e.g. colloid's own radius. Computed
        without cancellation as r -> rc by ``shifted_fn`` when the style has one.
        """
        a = self.args(p)
        if not self.shifted:
            return self.energy(r, *a)
        if self.shifted_fn is not None:
            return self.shifted_fn(r, *a)
        return self.energy(r, *a) - self.energy(a[3], *a)


def shifted_energy_force(style: WallStyle, r, p: Params) -> tuple[np.ndarray, np.ndarray]:
    """(E(r) - E(rc), F(r)) for ``style``, rc = p["cutoff"]. [energy], [force]

    See :meth:`WallStyle.shifted_energy`; for a style with ``shifted=False`` the energy is
    returned unshifted.
    """
    return style.shifted_energy(r, p), style.force(r, *style.args(p))
