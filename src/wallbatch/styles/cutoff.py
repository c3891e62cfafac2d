"""Cut-off treatments of a wall style (docs/physics.md §17): one wrapper around any registered style.

LAMMPS's wall fixes shift only the energy at the cut-off rc (``shift``); the force jumps by F(rc)
there, which lowers the order of velocity Verlet's energy error. Two force-continuous treatments
compose with any style's ``force`` F = -dE/dr and ``shifted_fn`` E(r) - E(rc):

* ``shift`` (default, LAMMPS): E_s = E(r) - E(rc), F_s = F(r).
* ``force-shift``: E_fs = E(r) - E(rc) + (r - rc) F(rc), F_fs = F(r) - F(rc): both vanish at rc.
* ``smooth``: E_sm = S(r) (E(r) - E(rc)), F_sm = S F - S' (E(r) - E(rc)), with the C2 quintic switch
  S(x) = 1 - 10 x^3 + 15 x^4 - 6 x^5, x = (r - r_on)/(rc - r_on) clipped to [0, 1] (r_on = the
  wall's ``switch_on``): E, F and dF/dr are continuous at r_on and vanish at rc; below r_on the
  result is ``shift`` bit for bit (S = 1, S' = 0 exactly).

The wrappers are closures built by :func:`cutoff_functions` from the style's own functions, plain
arithmetic on floats or arrays: the NumPy kernels call them with the Python functions, the compiled
path (wallbatch.engine.compiled) jit-compiles the same closures around the jit-compiled functions,
so both paths do the same operations in the same order. Every function takes the style's arguments
``(r, p0, p1, p2, rc, radius)`` plus ``r_on`` [distance] (ignored unless ``smooth``).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from wallbatch.styles.base import Params, WallStyle

SHIFT, FORCE_SHIFT, SMOOTH = 0, 1, 2
CUTOFF_MODES: tuple[str, ...] = ("shift", "force-shift", "smooth")  # index = the mode number
MODE_IDS: dict[str, int] = {m: i for i, m in enumerate(CUTOFF_MODES)}

WrappedFn = Callable[..., np.ndarray]  # f(r, p0, p1, p2, rc, radius, r_on)


def switch(r, r_on, rc):
    """(S, dS/dr) of the quintic switch on [r_on, rc]: S = 1 below r_on, 0 at and beyond rc. [-], [1/distance]

    S = 1 - 10 x^3 + 15 x^4 - 6 x^5 = (1 - x)^3 (1 + 3 x + 6 x^2), dS/dr = -30 x^2 (1 - x)^2 / (rc - r_on),
    with x = (r - r_on)/(rc - r_on) and 1 - x = (rc - r)/(rc - r_on) each formed from an exact
    difference and clipped to [0, 1], so S keeps its relative accuracy as r -> rc (where the
    smooth energy S (E(r) - E(rc)) goes to 0).
    """
    w = rc - r_on
    x = np.minimum(np.maximum((r - r_on) / w, 0.0), 1.0)
    om = np.minimum(np.maximum((rc - r) / w, 0.0), 1.0)
    s = om * om * om * (1.0 + x * (3.0 + 6.0 * x))
    ds = -30.0 * (x * x) * (om * om) / w
    return s, ds


def supported(style: WallStyle) -> bool:
    """True if the style can take a non-default cut-off mode: it has F(r) and E(r) - E(rc) in r
    alone, and shifts its energy at the cut-off (wall/ees does neither)."""
    return style.shifted and style.shifted_fn is not None


def cutoff_functions(force: Callable, shifted: Callable, mode: int,
                     switch_fn: Callable = switch) -> tuple[WrappedFn, WrappedFn]:
    """(force, energy) of a style under cut-off ``mode`` (SHIFT, FORCE_SHIFT or SMOOTH), built from
    its ``force`` F(r) and ``shifted`` E(r) - E(rc). [force], [energy]

    ``force``, ``shifted`` and ``switch_fn`` (:func:`switch`) may be Python functions (NumPy) or
    numba-compiled ones (the compiled path jit-compiles the returned closures); ``mode`` is fixed per closure, so each mode gets its
    own straight-line arithmetic.
    """
    if mode == SHIFT:
        def f_shift(r, p0, p1, p2, rc, radius, r_on):
            return force(r, p0, p1, p2, rc, radius)

        def e_shift(r, p0, p1, p2, rc, radius, r_on):
            return shifted(r, p0, p1, p2, rc, radius)
        return f_shift, e_shift
    if mode == FORCE_SHIFT:
        def f_fs(r, p0, p1, p2, rc, radius, r_on):
            return force(r, p0, p1, p2, rc, radius) - force(rc, p0, p1, p2, rc, radius)

        def e_fs(r, p0, p1, p2, rc, radius, r_on):
            return shifted(r, p0, p1, p2, rc, radius) + (r - rc) * force(rc, p0, p1, p2, rc, radius)
        return f_fs, e_fs
    if mode == SMOOTH:
        def f_sm(r, p0, p1, p2, rc, radius, r_on):
            s, ds = switch_fn(r, r_on, rc)
            return s * force(r, p0, p1, p2, rc, radius) - ds * shifted(r, p0, p1, p2, rc, radius)

        def e_sm(r, p0, p1, p2, rc, radius, r_on):
            s, _ = switch_fn(r, r_on, rc)
            return s * shifted(r, p0, p1, p2, rc, radius)
        return f_sm, e_sm
    raise ValueError(f"unknown cut-off mode {mode!r} (0 shift, 1 force-shift, 2 smooth)")


class CutoffStyle:
    """A registered style composed with a cut-off mode: ``force(r, p)`` and ``energy(r, p)`` on a
    parameter mapping (as :class:`WallStyle`; ``p["switch_on"]`` is r_on for ``smooth``).

    ``shift`` returns exactly what the style itself gives (``WallStyle.shifted_energy`` and
    ``force``), so the LAMMPS default is unchanged bit for bit.
    """

    def __init__(self, style: WallStyle, mode: str = "shift"):
        if mode not in MODE_IDS:
            raise ValueError(f"cutoff_mode must be one of {', '.join(CUTOFF_MODES)}, not {mode!r}")
        if mode != "shift" and not supported(style):
            raise ValueError(f"wall/{style.name} takes only cutoff_mode shift")
        self.style = style
        self.mode = mode
        self.mode_id = MODE_IDS[mode]
        if mode != "shift":
            self._force, self._energy = cutoff_functions(style.force, style.shifted_fn, self.mode_id)

    def _args(self, p: Params) -> tuple:
        return (*self.style.args(p), p.get("switch_on", 0.0))

    def force(self, r, p: Params) -> np.ndarray:
        """F(r) under the cut-off mode, F > 0 repulsive. [force]"""
        if self.mode_id == SHIFT:
            return self.style.force(r, *self.style.args(p))
        return self._force(r, *self._args(p))

    def energy(self, r, p: Params) -> np.ndarray:
        """The reported energy under the cut-off mode (``shift``: E(r) - E(rc)). [energy]"""
        if self.mode_id == SHIFT:
            return self.style.shifted_energy(r, p)
        return self._energy(r, *self._args(p))

    def energy_force(self, r, p: Params) -> tuple[np.ndarray, np.ndarray]:
        """(energy, force) under the cut-off mode. [energy], [force]"""
        return self.energy(r, p), self.force(r, p)


__all__ = ["CUTOFF_MODES", "MODE_IDS", "SHIFT", "FORCE_SHIFT", "SMOOTH", "CutoffStyle", "cutoff_functions",
           "supported", "switch"]
