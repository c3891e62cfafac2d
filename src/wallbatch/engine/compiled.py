"""Compiled chunks of steps (numba) for scenes of flat walls, behind Engine.advance.

The NumPy engine (engine.py, walls.py) is the reference; this module runs the same arithmetic,
operation for operation and in the same order per atom, in one compiled call per chunk of steps
(the steps between two samples; a long chunk in calls of `call_steps`), so results agree with
NumPy bit for bit (morse, whose exp and expm1 come from another libm, to ~1e-15). One step of one
atom is engine.Engine.step:

  v += dtfm f ; x += dt v ; wall/reflect ; periodic wrap ; f = 0 ; soft faces f[dim] -= side F(r) ;
  lost-atom test ; v += dtfm f ; (fix dt/reset: the atom's largest dt)

Layout: per case, the atoms are copied into structure-of-arrays buffers and a step is a few
simple passes over a block of BLOCK atoms (kick-drift with the periodic wrap and the force clear,
one branch-free pass per reflect face, one branch-free pass per soft face with the style fixed at
compile time, lost test, kick), which the compiler
vectorises (AVX2/AVX-512). Steps run in windows: every step of a window on one block (it stays in
L1 cache), then the next block. Without dt/reset a window is the whole chunk. With dt/reset the
smallest dt over the atoms couples them every step; a window of WINDOW steps runs at the current
dt and keeps each step's smallest candidate, and if one of them would change dt the window is
undone and run step by step up to that step (exact either way). Time-based runs go step by step.
The kernel computes forces only: on the last step of a sampled chunk the outputs (energies, wall
forces, virial) come from the NumPy `Engine.compute_forces` at the final positions, where the
NumPy loop computes them too.

The force of each soft face is the registry's own function (wallbatch.styles: `WallStyle.force`,
plain arithmetic on floats or arrays) compiled by numba; the dispatch from a face's style number
to its function is generated from the registry (`_dispatch_source`), so a newly registered style
with `compiled=True` runs here without further code. fix dt/reset's per-atom dt is
wallbatch.engine.dt_reset.dt_candidate, the function the NumPy engine calls.

The engine hands over an explicit `ChunkPlan` (its kernels with their style entries and per-face
values, dt/reset parameters, callbacks for the NumPy outputs and steps, and what else the scene
has); this module reads nothing else of the engine. Eligibility is a whitelist: soft flat walls
of compiled styles, wall/reflect, dt/reset and equal-style variables (their per-step values are computed in NumPy
before the chunk, vectorised over steps; not when the step's dt can change inside the chunk).
wall/region fixes of compiled styles with constant parameters run in the kernel too (their contacts
per atom as RegionGeom.contacts lists them, the force the registry's function; `_region_contacts`).
One wall/flow fix (step-based runs without dt/reset) runs in the kernel as well, one case per call
with the case's own generator (`_flow_step`; numba's Generator draws NumPy's streams), step by
step over all atoms. `fixes:` (nvt, langevin, temp/berendsen, temp/rescale, enforce2d;
`fixes_eligible`) run in the kernel with engine/thermostats.py's functions (`_fix_pre`,
`_fix_post_force`, `_fix_end`; step by step when a thermostat couples the atoms, one case per call
with the case's generator of each langevin fix); nve or nvt on some groups only leaves the other
atoms where they are (`_K_FROZEN`: the kick and drift keep their v and x, selects in the same
loops). wall/table faces run in every scene kernel with their tables as data
(`_table_faces`: one concatenated array, styles.table's lookups jitted; no compile per table);
wall/lepton faces with the force generated from each expression (`kernel_for`'s `extra`, compiled
once per set of expressions and cached on disk). wall/reflect/stochastic fixes run after the
wall/reflect faces (`_stochastic_faces`: one case per call with the case's generators, one block
of all atoms so the draws follow atom order, each fix's faces from its own generator,
engine/stochastic.py's functions; in sampled chunks their counters are recorded at each sample
after the wall/reflect ones). Anything else (pair forces, ees, wall/region/ees, ellipsoids,
several flow fixes) runs in NumPy. A chunk that
meets trouble (an atom on/behind a wall, a lost atom, a non-finite value, a variable error or a
negative variable parameter) leaves the state as it was at its start and is handed back to the
NumPy loop, which re-runs it and reports exactly as always. `WALLBATCH_NUMBA=0` (or numba not
importable) selects the NumPy path everywhere. Kernels are built per kind of scene (`kernel_for`:
only the styles, cut-off modes, region and flow code it has; KERNEL_FLAGS leave out the code of
what it does not use: wall/reflect, fixes, dt/reset, time-based runs, in-kernel samples, ...; the
arguments only that code reads are None in such a kernel: `SceneKernel`) and cached on disk by
numba under their own names; a kernel not yet cached is announced on stderr before it compiles.
"""

from __future__ import annotations

import functools
import hashlib
import inspect
import math
import os
import types
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from wallbatch.engine import backend
from wallbatch.engine import dt_reset as _dtr
from wallbatch.engine import scalar as _scalar
from wallbatch.engine import stochastic as _st
from wallbatch.engine import thermostats as _th
from wallbatch.engine import threads
from wallbatch.engine.dt_reset import BIG, dt_candidate
from wallbatch.engine.state import BatchState, landing_tol
from wallbatch.engine.region_walls import RegionWallKernel
from wallbatch.engine.stochastic import RSTYLES, StochasticKernel
from wallbatch.engine.walls import CustomWallKernel, ReflectKernel, SoftWallKernel
from wallbatch.expr import VariableError
from wallbatch.scene.case import DtResetSpec
from wallbatch.styles import STYLES, WallStyle
from wallbatch.styles import cutoff as _cutoff
from wallbatch.styles import flat as _flat
from wallbatch.styles.cutoff import CUTOFF_MODES, FORCE_SHIFT, SHIFT, SMOOTH, cutoff_functions
from wallbatch.styles.cutoff import supported as cutoff_supported
from wallbatch.styles.lepton import HELPERS_IMPORT, generated_module, generated_path
from wallbatch.styles.lepton import _helpers as _lepton_helpers
from wallbatch.styles.table import TableWallStyle, linear_lookup, spline_lookup

try:  # numba is a dependency, but the NumPy path must keep working without it
    from numba import njit
    from numba.cpython.unsafe.numbers import trailing_zeros as _trailing_zeros
    from numba.extending import overload
except Exception:  # noqa: BLE001 - any import failure means "no compiled path"
    njit = None

# the styles the kernel runs, numbered in registry order (sf_meta's style column)
COMPILED_STYLES: tuple[WallStyle, ...] = tuple(s for s in STYLES.values() if s.compiled)
STYLE_IDS: dict[str, int] = {s.name: i for i, s in enumerate(COMPILED_STYLES)}
TABLE_STYLE = -1  # sf_meta's style column of a wall/table face (its table: the kernel's tb arrays)
# the table lookups compiled into a scene kernel with wall/table faces: part of its cache key
_TABLE_SOURCE = "# wall/table\n" + inspect.getsource(linear_lookup) + inspect.getsource(spline_lookup)
BLOCK = 256  # atoms per block: a block's buffers stay in L1 cache over a window of steps
WINDOW = 64  # steps per speculative window under dt/reset
# wall/region geometries in the kernel (rg_meta's kind column)
REGION_KINDS: dict[tuple[str, str], int] = {("block", "in"): 0, ("block", "out"): 1, ("sphere", "in"): 2,
                                            ("sphere", "out"): 3, ("cylinder", "in"): 4, ("cylinder", "out"): 5}
# this file's code and the generated kernels' helpers: part of the key of the generated lepton chunk kernels
_SOURCE_DIGEST = hashlib.sha256(Path(__file__).read_bytes() + inspect.getsource(_lepton_helpers).encode()).hexdigest()[:16]
COMPILE_SECONDS = 10  # the message's estimate for one scene kernel (flat walls: 8.8-10.4 s on a 2-core AVX2 host,
# 4-5 s on AVX-512 hosts; an estimate that errs long rather than short)
COMPILE_SECONDS_FIXES = 12  # the same with thermostats or dt/reset in the kernel (fix nvt: measured 11-12 s CPU, others up to ~14 s)
VALUE_BUDGET = 4_000_000  # per-step wall values held at once (doubles); longer chunks are split
SAMPLE_BUDGET = 4_000_000  # sample outputs of a sampled chunk held at once (doubles): fewer samples per call
# atom-steps of one kernel call (~0.1 s of a flat-wall scene): a longer chunk or run of samples takes
# several calls, so a Ctrl-C (handled between calls: a kernel call does not return to Python
# before its end) stops the run within about that long; the results do not depend on the split
CALL_WORK = 10_000_000
# what one atom-step of the pair and the ellipsoid kernels costs in flat-wall atom-steps (measured:
# ~4.6 ns flat, ~95 ns ellipsoids between ees walls, ~285 ns an LJ fluid at density 0.6)
PAIR_STEP_COST = 25
ASPHERE_STEP_COST = 10
# the fewest steps of a call, whatever CALL_WORK gives: each call copies every atom's state into
# the kernel's buffers and back (measured at N = 1e6 flat: ~35 ns an atom, some 7 atom-steps; an
# ellipsoid ~1.2 atom-steps; a pair case's copies are small beside a step), which these keep to a
# few per cent. A large case's call is longer than ~0.1 s then (flat N = 1e6: ~1 s)
FLAT_MIN_CALL_STEPS = 200
ASPHERE_MIN_CALL_STEPS = 50
PAIR_MIN_CALL_STEPS = 10
MAX_CHAIN = 10  # the longest Nose-Hoover chain counted in that budget (longer ones only take more memory)
# fixes of `fixes:` in the kernel (fx_meta's kind column); nve is the kernel's own integrator
FIX_LANGEVIN, FIX_NVT, FIX_BERENDSEN, FIX_RESCALE, FIX_ENFORCE2D = 0, 1, 2, 3, 4
FIX_KINDS: dict[str, int] = {"langevin": FIX_LANGEVIN, "nvt": FIX_NVT, "temp/berendsen": FIX_BERENDSEN,
                             "temp/rescale": FIX_RESCALE, "enforce2d": FIX_ENFORCE2D}
# What a scene kernel compiles (`kernel_for`): the chunk loop and the block step read these module
# flags as constants (numba freezes globals), and numba's dead-branch pruning drops a feature's
# code before typing when its flag is False in the kernel's re-linked globals. True here: all of it.
KERNEL_FLAGS = ("_K_REFLECT", "_K_STOCHASTIC", "_K_TABLES", "_K_VECTOR", "_K_REGION", "_K_FIXES", "_K_DTR",
                "_K_FLOW", "_K_TIME", "_K_SAMPLES")
_K_REFLECT = _K_STOCHASTIC = _K_TABLES = _K_VECTOR = _K_REGION = True
_K_FIXES = _K_DTR = _K_FLOW = _K_TIME = _K_SAMPLES = True
# True in a 2-D scene's kernel (`two_d_eligible`): the step integrates x and y only (z stays 0:
# v_z = f_z = 0 at the chunk's start and enforce2d zeroes them every step, so z's updates are the
# identity); False here: all three dimensions
_K_2D = False
# True in the kernel of a scene whose integrators leave some atoms out (`fixes:` with nve or nvt on
# some groups only: Ensemble.moving): the kick and drift keep those atoms' v and x as they are, bit
# for bit (the force clear, wrap and walls still see them); False here: every atom is integrated
_K_FROZEN = False
# The chunk kernel's arguments read only by the code of one of those features: a scene kernel
# without it gets None in their place (`SceneKernel`), so its compiled entry point neither unboxes
# them nor holds them (fewer arguments to convert and release: a shorter first compile)
FLAG_ARGS: dict[str, tuple[str, ...]] = {
    "_K_REFLECT": ("rf_meta", "rf_val", "rf_prev", "rf_stat"),
    "_K_STOCHASTIC": ("st_meta", "st_val", "st_stat", "st_flag", "st_rng"),
    "_K_TABLES": ("tb_meta", "tb_par", "tb_data"), "_K_VECTOR": ("lp_val",),
    "_K_REGION": ("rg_meta", "rg_geo", "rg_val"), "_K_FIXES": ("fx", "fx_rng"), "_K_DTR": ("dtr_par",),
    "_K_FLOW": ("fl_int", "fl_f", "fl_walls", "fl_grp", "fl_phys", "fl_pend", "fl_prev", "fl_cross", "fl_rng"),
    "_K_SAMPLES": ("sm",)}



def enabled() -> bool:
    """True if the compiled path may be used: numba imports and backend.use_numba()."""
    return njit is not None and backend.use_numba()


# ----------------------------------------------------------------------------- compiled kernels


def _branches(pairs: tuple[tuple[int, int], ...], extra: int | tuple[int, ...]) -> list[tuple[str, str, bool, str]]:
    """(condition, force name, radius flag, comment) of each branch of a generated dispatch: the
    (style number, cut-off mode) pairs of a scene, then generated wall/lepton forces (`extra`: how
    many, or their numbers j; styles len(COMPILED_STYLES) + j, mode shift)."""
    n = len(COMPILED_STYLES)
    out = [(f"style == {i} and mode == {m}", f"_FORCE_{i}_{m}", bool(COMPILED_STYLES[i].needs_radius),
             f"{COMPILED_STYLES[i].name} {CUTOFF_MODES[m]}") for i, m in pairs]
    js = range(extra) if isinstance(extra, int) else extra
    out += [(f"style == {n + j} and mode == {SHIFT}", f"_EXTRA_{j}", False, "wall/lepton") for j in js]
    return out


VECTOR_MARK = "# parameters as an array\n"  # first line of a generated force kernel(r, p) in `extra`


def _vector_dispatch_source(extra: tuple[str, ...]) -> str:
    """Python source of `_vector_faces(j, ...)`: one branch per generated force of `extra` with its
    parameters as an array (wall/lepton with more than 3 parameters; style -2 - j), each a
    literal call of the face loop `_face` with that force (`_VEXTRA_j`: force(r, pv), in the
    registry's signature with the array pv as p0) inlined."""
    lines = ["def _vector_faces(j, X, F, RAD, groups, g, d, side, coord, pv, cut, u0, u1):"]
    k = 0
    for j, src in enumerate(extra):
        if src.startswith(VECTOR_MARK):
            lines.append(f"    {'if' if k == 0 else 'elif'} j == {j}:  # wall/lepton, parameters as an array")
            lines.append(f"        return _face(_VEXTRA_{j}, False, X, F, RAD, groups, g, d, side, coord, pv, "
                         "0.0, 0.0, cut, 0.0, u0, u1)")
            k += 1
    lines.append("    return 0")
    return "\n".join(lines) + "\n"


def _vector_outputs_source(extra: tuple[str, ...]) -> str:
    """Python source of `_vector_out(j, ...)`, the outputs of sampled chunks of the faces of
    `_vector_faces`: the output loop `_eface` with force `_VEXTRA_j` and unshifted energy
    `_VEENERGY_j` (E(r, pv)) less E(rc, pv), computed once per call; NaNs for a force without a
    generated energy."""
    lines = ["def _vector_out(j, X, RAD, groups, g, d, side, coord, pv, cut, n):"]
    k = 0
    for j, src in enumerate(extra):
        if src.startswith(VECTOR_MARK) and "\ndef energy(" in src:
            lines.append(f"    {'if' if k == 0 else 'elif'} j == {j}:  # wall/lepton, parameters as an array")
            lines.append(f"        return _eface(_VEXTRA_{j}, _VEENERGY_{j}, False, X, RAD, groups, g, d, side, "
                         f"coord, pv, 0.0, 0.0, cut, 0.0, n, _VEENERGY_{j}(cut, pv, 0.0, 0.0, cut, 0.0, 0.0))")
            k += 1
    lines.append("    return _nan, _nan, _nan")
    return "\n".join(lines) + "\n"


def _dispatch_source(pairs: tuple[tuple[int, int], ...], extra: int | tuple[int, ...] = 0) -> str:
    """Python source of `_soft_face(style, mode, ...)`: one branch per (style number, cut-off mode)
    pair of the scene (wallbatch.styles.cutoff) and per generated force, each a literal call of the
    generic face loop with that pair's force function and radius flag, so every pair gets its own
    loop with its force inlined. Only the scene's pairs: each branch costs compile time."""
    lines = ["def _soft_face(style, mode, X, F, RAD, groups, g, d, side, coord, p0, p1, p2, cut, ron, u0, u1):"]
    for k, (cond, force, rad, note) in enumerate(_branches(pairs, extra)):
        lines.append(f"    {'if' if k == 0 else 'elif'} {cond}:  # {note}")
        lines.append(f"        return _face({force}, {rad}, X, F, RAD, groups, g, d, side, coord, p0, p1, p2, cut, "
                     "ron, u0, u1)")
    lines.append("    return 0")
    return "\n".join(lines) + "\n"


def _region_dispatch_source(pairs: tuple[tuple[int, int], ...]) -> str:
    """Python source of `_region_force(style, mode, ...)`: as `_dispatch_source`, one branch per
    (style, cut-off mode) pair of the scene's wall/region fixes calling the region-contact force
    loop with that force inlined."""
    lines = ["def _region_force(style, mode, F, RAD, RB, nslot, u0, u1, p0, p1, p2, cut, ron):"]
    for k, (cond, force, rad, note) in enumerate(_branches(pairs, 0)):
        lines.append(f"    {'if' if k == 0 else 'elif'} {cond}:  # {note}")
        lines.append(f"        return _rface({force}, {rad}, F, RAD, RB, nslot, u0, u1, p0, p1, p2, cut, ron)")
    lines.append("    return 0")
    return "\n".join(lines) + "\n"


# the two output dispatches of sampled chunks (`_outputs_source`): function, its arguments after
# (style, mode) (passed on to the loop as they are, then the energy offset e0), the output loop,
# the number of outputs
_OUTPUTS = {"face": ("_face_out", "X, RAD, groups, g, d, side, coord, p0, p1, p2, cut, ron, n", "_eface", 3),
            "region": ("_region_out", "RAD, RB, nslot, n, p0, p1, p2, cut, ron", "_rout", 5)}


def _outputs_source(pairs: tuple[tuple[int, int], ...], kind: str = "face", extra: tuple[int, ...] = ()) -> str:
    """Python source of the outputs dispatch of sampled chunks: `_face_out(style, mode, ...)` for
    flat soft faces (kind "face", output loop `_eface`) or `_region_out(style, mode, ...)` for the
    contacts of a wall/region fix (kind "region", `_rout`). As `_dispatch_source`, one branch per
    (style, cut-off mode) pair whose energy the kernel computes (`energy_compiled`; its energy
    under the mode, offset 0) and per generated wall/lepton force j of `extra` with a generated
    energy (`_EEXTRA_j`: the unshifted E(r), less the offset E(rc) computed once per call), each
    calling the output loop with that force and energy inlined; NaNs for any other pair
    (`sampled_eligible` keeps those scenes out)."""
    name, args, loop, nout = _OUTPUTS[kind]
    lines = [f"def {name}(style, mode, {args}):"]
    k = 0
    for (cond, force, rad, note), (i, m) in zip(_branches(pairs, 0), pairs):
        if not energy_compiled(COMPILED_STYLES[i]):
            continue
        lines.append(f"    {'if' if k == 0 else 'elif'} {cond}:  # {note}")
        lines.append(f"        return {loop}({force}, _ENERGY_{i}_{m}, {rad}, {args}, 0.0)")
        k += 1
    for cond, force, rad, note in _branches((), extra):
        j = force.rpartition("_")[2]
        lines.append(f"    {'if' if k == 0 else 'elif'} {cond}:  # {note}")
        lines.append(f"        return {loop}({force}, _EEXTRA_{j}, {rad}, {args}, "
                     f"_EEXTRA_{j}(cut, p0, p1, p2, cut, 0.0, ron))")
        k += 1
    lines.append("    return " + ", ".join(["_nan"] * nout))
    return "\n".join(lines) + "\n"


def energy_compiled(st: WallStyle) -> bool:
    """Whether the kernel computes the style's reported energy (sampled chunks): a shifted
    energy with a compiled E(r) - E(rc) (`shifted_fn`, `compiled_shifted`)."""
    return st.shifted and st.shifted_fn is not None and st.compiled_shifted


def _modes(st: WallStyle) -> tuple[int, ...]:
    """The cut-off modes the compiled path runs for a style (smooth needs a compiled shifted_fn)."""
    if not cutoff_supported(st):
        return (SHIFT,)
    return (SHIFT, FORCE_SHIFT, SMOOTH) if st.compiled_shifted else (SHIFT, FORCE_SHIFT)


def _fingerprint(pairs: tuple[tuple[int, int], ...], flow: bool, parallel: bool, source: str) -> int:
    """A number that changes with a scene kernel's specialisation (its generated `source`, the
    pairs, flow, parallel) and the source of every function compiled into it from outside this
    file (forces, cut-offs, dt_candidate, the flow solver): the closure value of `_run_chunk`, so
    part of its on-disk cache key (numba keys a cached function by its own file only)."""
    h = hashlib.sha256()
    h.update(f"{source}:{flow}:{parallel}:".encode())
    for i, m in pairs:
        st = COMPILED_STYLES[i]
        h.update(f"{st.name}:{st.needs_radius}:{m}:".encode())
        h.update(inspect.getsource(st.force).encode())
        if len(_modes(st)) > 1 or energy_compiled(st):
            h.update(inspect.getsource(st.shifted_fn).encode())
        h.update(inspect.getsource(inspect.getmodule(st.force)).encode())  # helpers beside the style's functions
    h.update(inspect.getsource(_cutoff).encode())
    h.update(inspect.getsource(dt_candidate).encode())
    h.update(inspect.getsource(_th).encode())
    h.update(inspect.getsource(_scalar).encode())
    if flow:
        from wallbatch.engine import flow_compiled  # lazy: scipy.special, only for flow walls

        h.update(inspect.getsource(flow_compiled).encode())
    return int(h.hexdigest()[:15], 16)


if njit is not None:
    # error_model="numpy": x/0 gives inf/nan as in NumPy (no zero-division checks, so loops vectorise)
    # no cfunc wrapper to build (each costs a compile of its own): nothing here is called as a
    # first-class function; the per-scene pieces (`_SCENE`), called from compiled code only, have no
    # CPython wrapper either, nor do the kernels' copies of the registry's forces (`_style_functions`;
    # FORCES, MODE_FORCES and MODE_ENERGIES keep theirs: tests call them)
    _INNER = {"nogil": True, "error_model": "numpy", "no_cfunc_wrapper": True}
    _SCENE = {**_INNER, "no_cpython_wrapper": True}
    jit = njit(cache=True, nogil=True, error_model="numpy", no_cfunc_wrapper=True)
    # called from compiled code only: no CPython wrapper either (the fixes' take the 14-tuple fx,
    # whose wrapper alone costs a good part of a second to compile); numba gives such a function
    # no Python entry point, and calling it from Python crashes the process: tests call them
    # through a jitted caller
    jit_inner = njit(cache=True, nogil=True, error_model="numpy", no_cfunc_wrapper=True, no_cpython_wrapper=True)
    inline = njit(cache=True, nogil=True, error_model="numpy", inline="always")  # inlined in numba IR

    @overload(_dtr.select)
    def _select_scalar(cond, a, b):  # noqa: ANN001, ANN202
        """dt_reset.select for scalars: a if cond else b (np.where's value, without an array)."""
        return lambda cond, a, b: a if cond else b

    @overload(_th.libm_exp)
    def _libm_exp(x):  # noqa: ANN001, ANN202
        """thermostats.libm_exp for a scalar: math.exp (the C library's exp)."""
        return lambda x: math.exp(x)

    _dg_series = njit(**_INNER)(_flat._colloid_dg_series)
    _dg_closed = njit(**_INNER)(_flat._colloid_dg_closed)

    @overload(_flat.colloid_dg)
    def _colloid_dg_scalar(r, big_r, rc, h, b, dct):  # noqa: ANN001, ANN202
        """styles.flat.colloid_dg for floats: the same series / closed form choice, per value."""
        def impl(r, big_r, rc, h, b, dct):  # noqa: ANN001, ANN202
            x = big_r / r
            dx = -x * h
            if (x if x >= b else b) < _flat._G_SWITCH:
                return _dg_series(x, b, dx)
            d = (r - big_r) / r
            return _dg_closed(x, b, dx, d * (1.0 + x), dct * (1.0 + b), d + x * dct)
        return impl

    @overload(_st.libm_log)
    def _libm_log(x):  # noqa: ANN001, ANN202
        """stochastic.libm_log for a scalar: math.log (the C library's log)."""
        return lambda x: math.log(x)

    @overload(_st.libm_cos)
    def _libm_cos(x):  # noqa: ANN001, ANN202
        """stochastic.libm_cos for a scalar: math.cos (the C library's cos)."""
        return lambda x: math.cos(x)

    _nmin = inline(_scalar.nmin)  # np.minimum / np.maximum of two floats (engine/scalar.py)
    _nmax = inline(_scalar.nmax)

    def _renamed(fn: Any, name: str) -> Any:
        """A copy of the Python function `fn` (same code, globals, closure) named `name`. numba's
        symbol of a compiled function is its module, name, argument types and a number counted
        per process, and a kernel loaded from the disk cache brings the functions it calls with
        it: two different functions of one name (styles.cutoff's closures of two styles, the
        pieces of two scenes) compiled in two processes can get one symbol, and a process that
        loads both kernels links both to one of them. So every function compiled on its own
        (not inlined) whose code differs by style or scene gets a name of its own."""
        out = types.FunctionType(fn.__code__, fn.__globals__, fn.__name__, fn.__defaults__, fn.__closure__)
        out.__kwdefaults__ = fn.__kwdefaults__
        out.__qualname__ = name
        return out

    def _style_functions(options: dict[str, Any], suffix: str = "") -> tuple[tuple, dict, dict, Any]:
        """The registry's force functions compiled as they are (the same code), and
        each style's force and reported energy under each cut-off mode it runs: styles.cutoff's
        closures around the compiled force and, for force-shift and smooth, E(r) - E(rc) (the
        energies: as the NumPy CutoffStyle.energy; sampled chunks). Returns (forces,
        mode_forces, mode_energies, switch), numba dispatchers with `options`; `suffix` ends the
        names of the ones compiled with other options (`_renamed`)."""
        forces = tuple(njit(**options)(_renamed(st.force, st.force.__qualname__ + suffix) if suffix else st.force)
                       for st in COMPILED_STYLES)
        shifted = {i: njit(**options)(st.shifted_fn) for i, st in enumerate(COMPILED_STYLES)
                   if len(_modes(st)) > 1 or energy_compiled(st)}
        switch = njit(**options)(_cutoff.switch)
        mode_forces = {(i, m): njit(**options)(_renamed(
            cutoff_functions(forces[i], shifted[i] if len(_modes(st)) > 1 else forces[i], m, switch)[0],
            f"force_{st.name}_{m}{suffix}")) for i, st in enumerate(COMPILED_STYLES) for m in _modes(st)}
        mode_energies = {(i, m): njit(**options)(_renamed(
            cutoff_functions(forces[i], shifted[i], m, switch)[1], f"energy_{st.name}_{m}{suffix}"))
            for i, st in enumerate(COMPILED_STYLES) if energy_compiled(st) for m in _modes(st)}
        return forces, mode_forces, mode_energies, switch

    # for Python callers (tests): each with numba's CPython entry point
    FORCES, MODE_FORCES, MODE_ENERGIES, _ = _style_functions(_INNER)
    # what the scene kernels link in: the same functions without a CPython entry point (each costs
    # a compile of its own, ~0.04 s; from compiled code only, see `jit_inner`), named apart from
    # the ones above
    _K_MODE_FORCES, _K_MODE_ENERGIES, _switch = _style_functions(_SCENE, "_k")[1:]
    _dt_candidate = njit(nogil=True, error_model="numpy", inline="always")(dt_candidate)

    @inline
    def _face(force, use_radius, X, F, RAD, groups, g, d, side, coord, p0, p1, p2, cut, ron, u0, u1):
        """One soft face over atoms u0..u1-1 (walls.SoftWallKernel.apply): r = distance into the
        allowed region; where r < rc (and the atom is in the group), F[d] -= side F(r). Returns the
        number of atoms on or behind the wall (r <= 0; with use_radius: r <= radius). `force` and
        `use_radius` are literals at every call (_soft_face, _vector_faces), so each style gets its
        own loop; p0, p1, p2 go to the force as they are (floats, or a wall/lepton face's
        parameter array as p0: `_vector_args`)."""
        sidef = float(side)
        sign = -sidef  # r = (x - coord) * sign: x - coord (lo face) or coord - x (hi face), exactly
        nbad = 0
        for i in range(u0, u1):
            r = (X[d, i] - coord) * sign
            rad = RAD[i] if use_radius else 0.0
            near = (r < cut) & (groups[g, i] != 0)
            nbad += near & (r <= rad)
            fi = F[d, i]
            if near:
                fi = fi - sidef * force(r, p0, p1, p2, cut, rad, ron)
            F[d, i] = fi
        return nbad


    @inline
    def _eloop(at, contact, force, energy, use_radius, src, RAD, nslot, n, p0, p1, p2, cut, ron, e0):
        """The outputs of one soft face or wall/region fix over a case's n atoms, from its contacts
        slot by slot (a flat face: one slot), as walls.SoftWallKernel.apply and
        RegionWallKernel.apply sum them with np.bincount, contact by contact in (slot, atom)
        order: (sum of E(r) - e0, sum of (F(r) / q) c over the contacts: the force on the wall
        x, y, z, sum of F(r) r: the virial). `at(src, j, i, cut)`: is atom i a contact in slot j;
        `contact(src, j, i)` -> (r, q, c0, c1, c2) of a contact, read from the geometry's data src
        (a flat face: `_flat_at`, `_flat_contact`, q = 1, c = (side, 0, 0); a region:
        `_region_at`, `_region_contact`, q = r, c = its delta). `force` and `energy` take the
        registry's force arguments (r, p0, p1, p2, rc, radius, r_on), whatever p0, p1, p2 are
        (floats; a wall/lepton face's parameter array; a wall/table face's rows): E is the energy
        under the cut-off mode (e0 = 0) or an unshifted energy whose offset e0 at the cut-off the
        caller computes once (wall/lepton: E(rc); wall/table: E_lin(rc)). All are literals at
        every call, so each gets its own loop."""
        e = 0.0
        f0 = 0.0
        f1 = 0.0
        f2 = 0.0
        vir = 0.0
        for j in range(nslot):
            for i in range(n):
                if at(src, j, i, cut):
                    r, q, c0, c1, c2 = contact(src, j, i)
                    rad = RAD[i] if use_radius else 0.0
                    fi = force(r, p0, p1, p2, cut, rad, ron)
                    e += energy(r, p0, p1, p2, cut, rad, ron) - e0
                    s = fi / q
                    f0 += s * c0
                    f1 += s * c1
                    f2 += s * c2
                    vir += fi * r
        return e, f0, f1, f2, vir

    @inline
    def _flat_at(src, j, i, cut):
        """Whether atom i is a contact of a flat face (`_eloop`; src = X, groups, g, d, side, coord):
        its distance into the allowed region r < rc and the atom in the group."""
        X, groups, g, d, sidef, coord = src
        return (X[d, i] - coord) * -sidef < cut and groups[g, i] != 0  # the group read only within rc

    @inline
    def _flat_contact(src, j, i):
        """A flat face's contact with atom i (`_eloop`): r (x - coord on a lo face, coord - x on a
        hi face, exactly), and the force on the wall per unit F(r): side along its axis (only the
        first component is reported)."""
        X, groups, g, d, sidef, coord = src
        return (X[d, i] - coord) * -sidef, 1.0, sidef, 0.0, 0.0

    @inline
    def _region_at(RB, j, i, cut):
        """Whether atom i has a contact in slot j of a wall/region fix's RB (`_region_contacts`)."""
        return RB[j, 0, i] != 0.0

    @inline
    def _region_contact(RB, j, i):
        """A wall/region contact (`_eloop`): r, and the force on the wall per unit F(r): delta / r."""
        r = RB[j, 1, i]
        return r, r, RB[j, 2, i], RB[j, 3, i], RB[j, 4, i]

    @inline
    def _eface(force, energy, use_radius, X, RAD, groups, g, d, side, coord, p0, p1, p2, cut, ron, n, e0):
        """The outputs of one flat soft face over a case's n atoms (walls.SoftWallKernel.apply with
        outputs), the contacts loop `_eloop` on the face's own contacts: (sum of E(r) - e0, sum of
        side F(r): the force on the wall, sum of F(r) r: the virial)."""
        e, fs, _f1, _f2, vir = _eloop(_flat_at, _flat_contact, force, energy, use_radius,
                                      (X, groups, g, d, float(side), coord), RAD, 1, n, p0, p1, p2, cut, ron, e0)
        return e, fs, vir

    @inline
    def _rout(force, energy, use_radius, RAD, RB, nslot, n, p0, p1, p2, cut, ron, e0):
        """The outputs of a wall/region fix from a case's contacts in RB (all n atoms, slot by
        slot: RegionGeom.contacts' order), the contacts loop `_eloop`: (energy less e0 per
        contact, sum of (F(r)/r) delta x, y, z, sum of F(r) r)."""
        return _eloop(_region_at, _region_contact, force, energy, use_radius, RB, RAD, nslot, n, p0, p1, p2, cut,
                      ron, e0)

    def _sample_faces(c, si, X, RAD, groups, sf_meta, sf_val, tb, lp, out):
        """Every soft face's outputs (`_eface`, through the scene's `_face_out` dispatch; wall/table
        faces: `_table_out` on the tables tb; wall/lepton faces with their parameters as an array:
        `_vector_out` on this case's rows of lp) of case c at the current positions into out[k] =
        (energy, force on the wall, virial). Compiled per scene by `kernel_for`."""
        n = X.shape[1]
        for k in range(sf_meta.shape[0]):
            style, g, d, side = sf_meta[k, 0], sf_meta[k, 3], sf_meta[k, 1], sf_meta[k, 2]
            coord, cut = sf_val[c, si, k, 0], sf_val[c, si, k, 4]
            if _K_VECTOR and style < TABLE_STYLE:
                e, fs, vir = _vector_out(-2 - style, X, RAD, groups, g, d, side, coord, lp[c, k], cut, n)
            elif style == TABLE_STYLE:
                e, fs, vir = _table_out(tb, k, X, RAD, groups, g, d, side, coord, cut, n)
            else:
                e, fs, vir = _face_out(style, sf_meta[k, 4], X, RAD, groups, g, d, side, coord, sf_val[c, si, k, 1],
                                       sf_val[c, si, k, 2], sf_val[c, si, k, 3], cut, sf_val[c, si, k, 5], n)
            out[k, 0] = e
            out[k, 1] = fs
            out[k, 2] = vir

    def _sample_regions(c, X, RAD, groups, rg_meta, rg_geo, rg_val, RB, out):
        """Every wall/region fix's outputs of case c at the current positions into out[k] =
        (energy, force on the wall x, y, z, virial); RB (6, 5, N): the case's contacts. Compiled per
        scene by `kernel_for` with the scene's `_region_out` dispatch."""
        n = X.shape[1]
        for k in range(rg_meta.shape[0]):
            cut = rg_val[c, k, 3]
            nslot, _ = _region_contacts(rg_meta[k, 0], rg_meta[k, 1], rg_geo[k], X, groups, rg_meta[k, 3], cut, 0, n,
                                        RB)
            e, f0, f1, f2, vir = _region_out(rg_meta[k, 2], rg_meta[k, 4], RAD, RB, nslot, n, rg_val[c, k, 0],
                                             rg_val[c, k, 1], rg_val[c, k, 2], cut, rg_val[c, k, 4])
            out[k, 0] = e
            out[k, 1] = -f0
            out[k, 2] = -f1
            out[k, 3] = -f2
            out[k, 4] = vir

    @inline
    def _no_vector_faces(j, X, F, RAD, groups, g, d, side, coord, pv, cut, u0, u1):
        """`_vector_faces` of a scene without such faces: nothing (never called)."""
        return 0

    @inline
    def _no_vector_out(j, X, RAD, groups, g, d, side, coord, pv, cut, n):
        """`_vector_out` of a scene without such faces: nothing (never called)."""
        return 0.0, 0.0, 0.0

    def _vector_args(fn: Any) -> Any:
        """A generated wall/lepton function fn(r, p) of a face with its parameters as an array
        (force [force] or unshifted energy [energy]) in the registry's force signature, the array
        as p0: so its faces run the loops of every other face (`_face`, `_eface`)."""
        def positional(r, pv, p1, p2, rc, radius, r_on):
            return fn(r, pv)
        return positional

    # -- fix wall/table: tables as data (styles.table.WallTable.kernel_rows), one compiled loop for any table
    _table_linear = njit(nogil=True, error_model="numpy", inline="always")(linear_lookup)
    _table_spline = njit(nogil=True, error_model="numpy", inline="always")(spline_lookup)

    @inline
    def _table_face(linear, X, F, groups, g, d, side, coord, cut, grid, tf, td, lo, invdelta, deltasq6, u0, u1,
                    MB):
        """One wall/table face over atoms u0..u1-1 (as `_face`, shift mode): F(r) by the table's
        linear or spline lookup (WallTable.lookup's arithmetic: the same functions, jitted) on
        its rows grid, tf (force), td (dF or F2). Returns the number of atoms nearer than the
        table's reach, one interval below its first distance lo (WallTable.below; the NumPy
        path then reports them). `linear` is a literal.

        Two passes, so no branch depends on where an atom is (a gas near a wall: ~10% of the
        atoms, in random order, a mispredicted branch every few atoms): a branch-free pass marks
        the group atoms within the cut-off in the bytes MB (it vectorises); then, 64 atoms at a
        time, their marks are packed into the bits of one word (8 bytes at once: the byte-to-bit
        multiply) and only the marked atoms are visited, lowest bit first (atom order), each with
        its table lookup. (Faster than a branch per atom, a branch-free lookup of every atom and
        a list of the atoms within the cut-off: benchmarks/table.py.) So it is a loop of its own,
        not `_face` (whose forces are branch-free arithmetic); and it calls the lookups directly
        rather than the outputs' `_table_force` on a tuple of rows, which measured ~9% slower
        (spline, sampled every step) and a longer compile (benchmarks/face_outputs.py)."""
        sidef = float(side)
        sign = -sidef
        n2 = grid.shape[0] - 2
        nb = u1 - u0
        for i in range(u0, u1):
            r = (X[d, i] - coord) * sign
            MB[i - u0] = (r < cut) & (groups[g, i] != 0)
        nw = (nb + np.uint64(7)) >> np.uint64(3)
        for i in range(nb, nw << np.uint64(3)):
            MB[i] = 0
        W = MB.view(np.uint64)
        nwi = np.int64(nw)
        nbad = 0
        for w0 in range(0, nwi, 8):
            bits = np.uint64(0)
            for w in range(w0, min(w0 + 8, nwi)):  # bit 8 (w - w0) + k: atom 8 w + k
                bits |= ((W[w] * np.uint64(0x0102040810204080)) >> np.uint64(56)) << np.uint64(8 * (w - w0))
            base = u0 + np.uint64(8 * w0)
            while bits != np.uint64(0):
                i = base + _trailing_zeros(bits)
                bits &= bits - np.uint64(1)
                r = (X[d, i] - coord) * sign
                x = (r - lo) * invdelta
                if x > -1.0:  # (WallTable.below) the first interval reaches one interval below lo
                    j = min(int(x), n2)  # truncates toward 0, as LAMMPS's index
                    if linear:
                        fr = _table_linear(r, j, grid, tf, td, invdelta)
                    else:
                        fr = _table_spline(r, j, grid, tf, td, invdelta, deltasq6)
                    F[d, i] = F[d, i] - sidef * fr
                else:
                    nbad += 1
        return nbad

    @inline
    def _table_faces(tb, k, X, F, groups, g, d, side, coord, cut, u0, u1):
        """Soft face k of the scene, a wall/table face: its rows in tb = (tb_meta (K, 3) int:
        offset, N, linear; tb_par (K, 3): lo, 1/delta, delta^2/6; tb_data: every table's rows;
        MB: scratch bytes, a block's atoms rounded up to 64, for `_table_face`)."""
        off, n = tb[0][k, 0], tb[0][k, 1]
        data = tb[2]
        grid, tf, td = data[off:off + n], data[off + n:off + 2 * n], data[off + 2 * n:off + 3 * n]
        lo, invdelta, deltasq6 = tb[1][k, 0], tb[1][k, 1], tb[1][k, 2]
        if tb[0][k, 2] != 0:
            return _table_face(True, X, F, groups, g, d, side, coord, cut, grid, tf, td, lo, invdelta, deltasq6,
                               u0, u1, tb[3])
        return _table_face(False, X, F, groups, g, d, side, coord, cut, grid, tf, td, lo, invdelta, deltasq6,
                           u0, u1, tb[3])

    @inline
    def _no_table_faces(tb, k, X, F, groups, g, d, side, coord, cut, u0, u1):
        """`_table_faces` of a scene without wall/table faces: nothing (never called)."""
        return 0

    def _table_lookup(y: int, dy: int) -> Any:
        """The lookup of a wall/table face's row y (its derivative row dy) at r in the registry's
        force signature (`_eface`): rows = (grid, F, dF or F2, E, dE or E2) of its table
        (WallTable.kernel_rows), par = (lo, 1/delta, delta^2/6, N - 2), linear: the table's linear
        or spline lookup (styles.table's functions, jitted). y, dy = 1, 2: F(r) [force]; 3, 4:
        the unshifted E(r) [energy]."""
        def lookup(r, rows, par, linear, rc, radius, r_on):
            j = min(int((r - par[0]) * par[1]), par[3])
            if linear:
                return _table_linear(r, j, rows[0], rows[y], rows[dy], par[1])
            return _table_spline(r, j, rows[0], rows[y], rows[dy], par[1], par[2])
        return lookup

    _table_force = njit(nogil=True, error_model="numpy", inline="always")(_table_lookup(1, 2))
    _table_energy = njit(nogil=True, error_model="numpy", inline="always")(_table_lookup(3, 4))

    @inline
    def _table_out(tb, k, X, RAD, groups, g, d, side, coord, cut, n):
        """The outputs of wall/table face k over a case's n atoms (walls.CustomWallKernel.apply
        with outputs): the output loop `_eface` of every soft face with the table's force and
        energy lookups (its rows 1-2 and 3-4), less the offset E_lin(rc), the linear lookup on
        rows 3 and 5 at the cut-off (WallTable.offset)."""
        off, nt = tb[0][k, 0], tb[0][k, 1]
        data = tb[2]
        grid, te, tdl = data[off:off + nt], data[off + 3 * nt:off + 4 * nt], data[off + 5 * nt:off + 6 * nt]
        rows = (grid, data[off + nt:off + 2 * nt], data[off + 2 * nt:off + 3 * nt], te, data[off + 4 * nt:off + 5 * nt])
        lo, invdelta = tb[1][k, 0], tb[1][k, 1]
        par = (lo, invdelta, tb[1][k, 2], nt - 2)
        shift = _table_linear(cut, min(int((cut - lo) * invdelta), nt - 2), grid, te, tdl, invdelta)
        return _eface(_table_force, _table_energy, False, X, RAD, groups, g, d, side, coord, rows, par,
                      tb[0][k, 2] != 0, cut, 0.0, n, shift)

    @inline
    def _no_table_out(tb, k, X, RAD, groups, g, d, side, coord, cut, n):
        """`_table_out` of a scene without wall/table faces: nothing (never called)."""
        return math.nan, math.nan, math.nan

    # -- fix wall/reflect/stochastic (stochastic.StochasticKernel.apply): the same plain functions
    _st_sigma = njit(nogil=True, error_model="numpy", inline="always")(_st.thermal_sigma)
    _st_dnormal = njit(nogil=True, error_model="numpy", inline="always")(_st.diffusive_normal)
    _st_tangent = njit(nogil=True, error_model="numpy", inline="always")(_st.thermal_tangent)
    _st_cnormal = njit(nogil=True, error_model="numpy", inline="always")(_st.ccl_normal)
    _st_ctangent = njit(nogil=True, error_model="numpy", inline="always")(_st.ccl_tangent)
    _st_time = njit(nogil=True, error_model="numpy", inline="always")(_st.crossing_time)
    _st_position = njit(nogil=True, error_model="numpy", inline="always")(_st.crossed_position)

    @inline
    def _stochastic_faces(c, u0, u1, X, V, M, groups, st, ftm2v, mvv2e):
        """fix wall/reflect/stochastic's faces on atoms u0..u1-1 (every atom of the case: the
        chunk runs one block, one case per call), after the wall/reflect faces. st = (st_meta (K, 4)
        int: dim, side, group row, rule (RSTYLES index), the face's fix among the batch's
        wall/reflect/stochastic fixes; st_val (C, K, 9): coord, temp, vx, vy, vz, ax, ay, az, kB;
        st_stat (C, K, 2): reflections, impulse; stats flag (1,) int; the case's generators, one
        per fix; scratch: SI (N,) int, SD (4, N)). Per face, fix after fix: the atoms past it in atom
        order, then the draws of StochasticKernel.apply in its order from its fix's generator, then
        its arithmetic atom by atom."""
        st_meta, st_val, st_stat, st_flag, rngs, SI, SD = st
        for k in range(st_meta.shape[0]):
            d, side, g, rule = st_meta[k, 0], st_meta[k, 1], st_meta[k, 2], st_meta[k, 3]
            rng = rngs[st_meta[k, 4]]
            coord = st_val[c, k, 0]
            n = 0
            for i in range(u0, u1):
                pos = X[d, i]
                if ((pos < coord) if side < 0 else (pos > coord)) and groups[g, i] != 0:
                    SI[n] = i
                    n += 1
            if n == 0:
                continue
            # the draws one number at a time into scratch rows (the same stream as NumPy's arrays of n)
            ua, ub, g0, g1 = SD[0], SD[1], SD[2], SD[3]
            if rule == 2:  # ccl: U1 in (0, 1], U2, N (n, 2)
                for j in range(n):
                    ua[j] = 1.0 - rng.random()
                for j in range(n):
                    ub[j] = rng.random()
            elif rule == 1:  # maxwell: the choice, U, N (n, 2)
                for j in range(n):
                    ub[j] = rng.random()
                for j in range(n):
                    ua[j] = 1.0 - rng.random()
            else:  # diffusive: U, N (n, 2)
                for j in range(n):
                    ua[j] = 1.0 - rng.random()
            for j in range(n):  # N (n, 2) in C order
                g0[j] = rng.standard_normal()
                g1[j] = rng.standard_normal()
            t0 = 1 if d == 0 else 0  # the tangential axes in increasing order
            t1 = 1 if d == 2 else 2
            away = -float(side)
            temp, kb = st_val[c, k, 1], st_val[c, k, 8]
            w0, w1 = st_val[c, k, 2 + t0], st_val[c, k, 2 + t1]
            an, a0, a1 = st_val[c, k, 5 + d], st_val[c, k, 5 + t0], st_val[c, k, 5 + t1]
            acc = st_val[c, k, 5]  # maxwell's one coefficient
            imp = 0.0
            for j in range(n):
                i = SI[j]
                vn, v0, v1 = V[d, i], V[t0, i], V[t1, i]
                sigma = _st_sigma(temp, M[i], kb, mvv2e)
                if rule == 2:
                    nn = _st_cnormal(away, sigma, an, vn, ua[j], ub[j])
                    n0 = _st_ctangent(w0, a0, v0, sigma, g0[j])
                    n1 = _st_ctangent(w1, a1, v1, sigma, g1[j])
                elif rule == 1 and not ub[j] < acc:  # maxwell, specular
                    nn, n0, n1 = -vn, v0, v1
                else:
                    nn = _st_dnormal(away, sigma, ua[j])
                    n0 = _st_tangent(w0, sigma, g0[j])
                    n1 = _st_tangent(w1, sigma, g1[j])
                t = _st_time(X[d, i], coord, vn)
                X[t0, i] = X[t0, i] + (n0 - v0) * t
                X[t1, i] = X[t1, i] + (n1 - v1) * t
                X[d, i] = _st_position(X[d, i], coord, vn, nn, t)
                V[d, i], V[t0, i], V[t1, i] = nn, n0, n1
                dp = M[i] * (vn - nn)
                imp = dp if j == 0 else imp + dp  # in atom order (StochasticKernel.apply's cumsum)
            if st_flag[0] != 0:
                st_stat[c, k, 0] += n
                st_stat[c, k, 1] += imp / ftm2v
        return 0

    @inline
    def _no_stochastic_faces(c, u0, u1, X, V, M, groups, st, ftm2v, mvv2e):
        """`_stochastic_faces` of a scene without wall/reflect/stochastic: nothing (never called)."""
        return 0

    # -- fix wall/region (region_walls.RegionWallKernel.apply; geometry of regions.RegionGeom) ------
    # A region's contacts of one block of atoms go into RB[slot, :, i - u0] = (flag, r, delta x, y, z)
    # (flag 1.0: a contact), one slot per part of RegionGeom.contacts in its order (block in: xlo,
    # xhi, ylo, yhi, zlo, zhi; cylinder in: curved wall, lo cap, hi cap; every other region: one),
    # then one force pass per slot adds (F(r) / r) delta to F, so each atom adds its contacts in the
    # order np.add.at does. rg_meta rows: kind (REGION_KINDS), axis, style number, group row, mode;
    # rg_geo rows: lo x y z, hi x y z, radius, centre (sphere x y z; cylinder the two other dims).

    @inline
    def _clip(a, lo, hi):
        """np.clip for scalars: min(max(a, lo), hi)."""
        return _nmin(_nmax(a, lo), hi)

    @inline
    def _slot(RB, j, b, r, d0, d1, d2):
        RB[j, 0, b] = 1.0
        RB[j, 1, b] = r
        RB[j, 2, b] = d0
        RB[j, 3, b] = d1
        RB[j, 4, b] = d2

    @inline
    def _block_contacts(kind, geo, X, groups, g, cut, u0, u1, RB):
        """`_region_contacts` of a block region (kind 0: inside, six faces; 1: outside, one)."""
        nwrong = 0
        for i in range(u0, u1):
            if groups[g, i] == 0:
                continue
            b = i - u0
            x0, x1, x2 = X[0, i], X[1, i], X[2, i]
            if kind == 0:
                ins = True
                for d in range(3):
                    ins = ins & (X[d, i] >= geo[d]) & (X[d, i] <= geo[3 + d])
                if not ins:
                    nwrong += 1
                    continue
                for d in range(3):
                    dlo = X[d, i] - geo[d]
                    dhi = geo[3 + d] - X[d, i]
                    if dlo < cut:
                        _slot(RB, 2 * d, b, dlo, 1.0 * dlo if d == 0 else 0.0, 1.0 * dlo if d == 1 else 0.0,
                              1.0 * dlo if d == 2 else 0.0)
                    if dhi < cut:
                        _slot(RB, 2 * d + 1, b, dhi, -dhi if d == 0 else 0.0, -dhi if d == 1 else 0.0,
                              -dhi if d == 2 else 0.0)
            else:
                strictly = ((x0 > geo[0]) & (x0 < geo[3]) & (x1 > geo[1]) & (x1 < geo[4])
                            & (x2 > geo[2]) & (x2 < geo[5]))
                inside = ((x0 >= geo[0]) & (x0 <= geo[3]) & (x1 >= geo[1]) & (x1 <= geo[4])
                          & (x2 >= geo[2]) & (x2 <= geo[5]))
                if inside:
                    nwrong += 1
                    continue
                d0 = x0 - _clip(x0, geo[0], geo[3])
                d1 = x1 - _clip(x1, geo[1], geo[4])
                d2 = x2 - _clip(x2, geo[2], geo[5])
                r = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
                if (not strictly) and r < cut:
                    _slot(RB, 0, b, r, d0, d1, d2)
        return nwrong

    @inline
    def _sphere_contacts(kind, geo, X, groups, g, cut, u0, u1, RB):
        """`_region_contacts` of a sphere (kind 2: inside, 3: outside). Branch-free: every atom's
        slot is written (flag 0.0 where no contact), so the loop vectorises."""
        nwrong = 0
        R, cx, cy, cz = geo[6], geo[7], geo[8], geo[9]
        x0, x1, x2, mask = X[0], X[1], X[2], groups[g]  # rows: the loop vectorises
        for i in range(u0, u1):
            b = i - u0
            ing = mask[i] != 0
            d0, d1, d2 = x0[i] - cx, x1[i] - cy, x2[i] - cz
            rho = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
            inner = rho <= R  # (NaN: not inner)
            if kind == 2:
                wrong = ing & (not inner)
                r = R - rho
                con = ing & inner & (rho > 0.0) & (r < cut)
            else:
                wrong = ing & inner
                r = rho - R
                con = ing & (not inner) & (r < cut)
            nwrong += wrong
            s = 1.0 - R / rho
            _slot(RB, 0, b, r, d0 * s, d1 * s, d2 * s)
            RB[0, 0, b] = 1.0 if con else 0.0
        return nwrong

    @inline
    def _cylinder_contacts(kind, ax, geo, X, groups, g, cut, u0, u1, RB):
        """`_region_contacts` of a cylinder along axis ax, centre (geo[7], geo[8]) in the two other
        dimensions, from geo[0] to geo[3] along ax (kind 4: inside, curved wall and two caps; 5:
        outside, one)."""
        nwrong = 0
        R, lo, hi = geo[6], geo[0], geo[3]
        o1 = 1 if ax == 0 else 0
        o2 = 1 if ax == 2 else 2
        for i in range(u0, u1):
            if groups[g, i] == 0:
                continue
            b = i - u0
            e1 = X[o1, i] - geo[7]
            e2 = X[o2, i] - geo[8]
            rho = math.sqrt(e1 * e1 + e2 * e2)
            a = X[ax, i]
            ins = (rho <= R) & (a >= lo) & (a <= hi)
            if kind == 4:
                if not ins:
                    nwrong += 1
                    continue
                rw = R - rho
                if rho > 0.0 and rw < cut:
                    s = 1.0 - R / rho
                    c1, c2 = e1 * s, e2 * s
                    _slot(RB, 0, b, rw, c1 if o1 == 0 else 0.0, c1 if o1 == 1 else (c2 if o2 == 1 else 0.0),
                          c2 if o2 == 2 else 0.0)
                dlo = a - lo
                dhi = hi - a
                if dlo < cut:
                    _slot(RB, 1, b, dlo, 1.0 * dlo if ax == 0 else 0.0, 1.0 * dlo if ax == 1 else 0.0,
                          1.0 * dlo if ax == 2 else 0.0)
                if dhi < cut:
                    _slot(RB, 2, b, dhi, -dhi if ax == 0 else 0.0, -dhi if ax == 1 else 0.0,
                          -dhi if ax == 2 else 0.0)
            else:
                if ins:
                    nwrong += 1
                    continue
                strictly = (rho < R) & (a > lo) & (a < hi)
                rim = 1.0 - R / rho if rho > R else 0.0
                c1, c2 = e1 * rim, e2 * rim
                ca = a - _clip(a, lo, hi)
                d0 = ca if ax == 0 else c1
                d1 = ca if ax == 1 else (c1 if o1 == 1 else c2)
                d2 = ca if ax == 2 else c2
                r = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
                if (not strictly) and r < cut:
                    _slot(RB, 0, b, r, d0, d1, d2)
        return nwrong

    @jit
    def _region_contacts(kind, ax, geo, X, groups, g, cut, u0, u1, RB):
        """The region's contacts of atoms u0..u1-1 (group g) into RB; returns (slots used, number
        of group atoms on the wrong side of the region). One atom loop per shape (the shape's
        branches stay out of the loop)."""
        nslot = 6 if kind == 0 else (3 if kind == 4 else 1)
        if kind == 2 or kind == 3:  # spheres write every atom's slot
            return nslot, _sphere_contacts(kind, geo, X, groups, g, cut, u0, u1, RB)
        for j in range(nslot):
            for i in range(u0, u1):
                RB[j, 0, i - u0] = 0.0
        if kind <= 1:
            nwrong = _block_contacts(kind, geo, X, groups, g, cut, u0, u1, RB)
        else:
            nwrong = _cylinder_contacts(kind, ax, geo, X, groups, g, cut, u0, u1, RB)
        return nslot, nwrong

    @inline
    def _rface(force, use_radius, F, RAD, RB, nslot, u0, u1, p0, p1, p2, cut, ron):
        """The forces of a region's contacts in RB (RegionWallKernel.apply): F += (F(r) / r) delta,
        slot by slot. Returns the number of contacts too close (r <= 0; use_radius: r <= radius)."""
        nbad = 0
        for j in range(nslot):  # branch-free (selects): every atom's force is computed, contacts add it
            for i in range(u0, u1):
                b = i - u0
                on = RB[j, 0, b] != 0.0
                r = RB[j, 1, b] if on else cut  # (not a contact: a harmless r, its force unused)
                rad = RAD[i] if use_radius else 0.0
                nbad += on & (r <= rad)
                s = force(r, p0, p1, p2, cut, rad, ron) / r
                F[0, i] = F[0, i] + s * RB[j, 2, b] if on else F[0, i]
                F[1, i] = F[1, i] + s * RB[j, 3, b] if on else F[1, i]
                F[2, i] = F[2, i] + s * RB[j, 4, b] if on else F[2, i]
        return nbad

    def _region_walls(c, u0, u1, X, F, RAD, groups, rg_meta, rg_geo, rg_val, RB):
        """Every wall/region fix on atoms u0..u1-1 of case c, in order; returns the number of
        atoms on the wrong side or too close (the NumPy loop then reports them). Compiled per
        scene by `kernel_for`, with the scene's `_region_force` dispatch."""
        nbad = 0
        for k in range(rg_meta.shape[0]):
            cut = rg_val[c, k, 3]
            nslot, nwrong = _region_contacts(rg_meta[k, 0], rg_meta[k, 1], rg_geo[k], X, groups, rg_meta[k, 3],
                                             cut, u0, u1, RB)
            nbad += nwrong
            nbad += _region_force(rg_meta[k, 2], rg_meta[k, 4], F, RAD, RB, nslot, u0, u1, rg_val[c, k, 0],
                                  rg_val[c, k, 1], rg_val[c, k, 2], cut, rg_val[c, k, 4])
        return nbad

    # -- thermostats and enforce2d (engine/ensemble.py; arithmetic of engine/thermostats.py) ---------
    # fx_meta rows (K, 8): kind (FIX_KINDS), group row, every, flags (1: zero, 2: tally), the fix's
    # number j among the batch's fixes of its kind (langevin, nvt; 0, 1, ...), and for fix nvt its
    # chain's offset o, length m and tloop; fx_val (C, K, 6): t_start, t_stop, damp, window,
    # fraction, dof; fx_acc (C, K, 4) (in and out): removed energy, tally work, last power, last dt.
    # Any number of langevin fixes, fix l with its own generator (rngs[l]), drag row G1[l] and force
    # rows FR[3 l .. 3 l + 2], FL[3 l .. 3 l + 2] (x, y, z); any number of nvt fixes, their chains
    # side by side, fix j's in eta, eta_dotdot, eta_mass columns o .. o + m - 1, eta_dot columns
    # o + j .. o + j + m (one member more each) and t_current, t_target, t_freq, drag column j.
    _th_mv2 = inline(_th.atom_mv2)
    _th_dot3 = inline(_th.dot3)
    _th_ramped = inline(_th.ramped)
    _th_drag = inline(_th.langevin_drag)
    _th_amp = inline(_th.langevin_amplitude)
    _th_random = inline(_th.langevin_random)
    _th_berendsen = jit(_th.berendsen_factor)
    _th_rescale = jit(_th.rescale_factor)
    _th_nh = jit(_th.nh_half_step)
    _th_pairwise = jit_inner(_th.pairwise_sum)  # called from kernels only

    @inline
    def _mv2_sum(M, V, KS, n):
        """sum m v^2 over atoms 0..n-1 (V (3, N)) in Engine.sample's order (NumPy's pairwise sum);
        KS: scratch of n."""
        for a in range(n):
            KS[a] = _th_mv2(M[a], V[0, a], V[1, a], V[2, a])
        return 0.0 + _th_pairwise(KS, 0, n)

    @inline
    def _take_stats(stat, out, k0):
        """A sample's reflect statistics since the last one (take_stats): each face's (count,
        impulse) of one case's stat (K, 2) into out[k0 + k]; the sums start again from zero."""
        for k in range(stat.shape[0]):
            out[k0 + k, 0] = stat[k, 0]
            out[k0 + k, 1] = stat[k, 1]
            stat[k, 0] = 0.0
            stat[k, 1] = 0.0

    @inline
    def _group_low(CAND, groups, g, u0, u1):
        """fix dt/reset: the smallest candidate dt over the group g's atoms u0..u1-1, NaN if any of
        them is NaN (engine.Engine.reset_dt's minimum)."""
        low = np.inf
        nnan = 0
        for i in range(u0, u1):
            ci = CAND[i] if groups[g, i] != 0 else np.inf
            nnan += ci != ci
            low = ci if ci < low else low
        return np.nan if nnan else low

    @inline
    def _fix_post_force(u0, u1, V, F, groups, fxp):
        """Engine.step's post_force fixes (Ensemble.post_force) on atoms u0..u1-1: the Langevin
        force G1 v + FR (kept in FL for the tally), then enforce2d (z force and velocity zeroed)."""
        fx_meta, G1, FR, FL = fxp
        for k in range(fx_meta.shape[0]):  # rows and selects (every atom written): the loops vectorise
            if fx_meta[k, 0] == FIX_LANGEVIN:  # each langevin fix adds its force, in fix order (s.f += force)
                mask, l = groups[fx_meta[k, 1]], fx_meta[k, 4]
                g1 = G1[l]
                for d in range(3):
                    vd, fd, rd, ld = V[d], F[d], FR[3 * l + d], FL[3 * l + d]
                    for i in range(u0, u1):
                        fl = g1[i] * vd[i] + rd[i] if mask[i] != 0 else 0.0
                        ld[i] = fl
                        fd[i] = fd[i] + fl
        for k in range(fx_meta.shape[0]):
            if fx_meta[k, 0] == FIX_ENFORCE2D:
                mask, fz, vz = groups[fx_meta[k, 1]], F[2], V[2]
                for i in range(u0, u1):
                    on = mask[i] != 0
                    fz[i] = 0.0 if on else fz[i]
                    vz[i] = 0.0 if on else vz[i]

    @jit_inner
    def _group_temperature(V, M, groups, g, dof, mvv2e, boltz, KB):
        """thermostats.temperature of one case's group g: sum m v^2 (NumPy's pairwise order)."""
        n = V.shape[1]
        if dof <= 0:
            return 0.0
        mask, v0, v1, v2 = groups[g], V[0], V[1], V[2]  # rows: the loop vectorises
        for i in range(n):
            e = _th_mv2(M[i], v0[i], v1[i], v2[i])
            KB[i] = e if mask[i] != 0 else 0.0
        return (0.0 + _th_pairwise(KB, 0, n)) * (mvv2e / (dof * boltz))

    @jit_inner
    def _scale_group(V, groups, g, factor):
        """thermostats.scale_group for one case: v *= factor on the group atoms."""
        mask = groups[g]
        for d in range(3):  # every atom times factor or 1.0 (x * 1.0 is x, bit for bit): the loop vectorises
            row = V[d]
            for i in range(row.shape[0]):
                row[i] = row[i] * (factor if mask[i] != 0 else 1.0)

    @inline
    def _ramp_frac(stepn, dtc, at, ats, fx_int, fx_f):
        """The fraction of the run done at the case's step stepn (BatchState.context's
        ramp_fraction, the thermostats' ramp): its time / the run time in a run to a time (fx_f[3];
        NaN in a run of steps), the time atime + (stepn - atimestep) dt from the case's clock (at,
        ats; the same arithmetic), else stepn / the run's end step (fx_int[1])."""
        if fx_f[3] == fx_f[3]:
            return (at + (stepn - ats) * dtc) / fx_f[3]
        return float(stepn) / fx_int[1] if fx_int[1] > 0 else 0.0

    @jit_inner
    def _fix_pre(c, stepn, dtc, at, ats, V, M, groups, fx, rngs, SQM, FR, KB):
        """Before the step's atoms move: fix nvt's first chain half step and velocity scaling
        (Ensemble.initial_integrate), and each langevin fix's random forces of the step (the
        case's generator of that fix, rngs[l], drawn as rng.random((n_group, 3)) in
        Ensemble.post_force)."""
        fx_meta, fx_val, fx_acc, eta, ed, edd, Q, tc, tt, tf, drag, fx_int, fx_f, _fo = fx
        n = V.shape[1]
        frac = _ramp_frac(stepn, dtc, at, ats, fx_int, fx_f)
        boltz = fx_f[0]
        for k in range(fx_meta.shape[0]):
            kind = fx_meta[k, 0]
            g = fx_meta[k, 1]
            target = _th_ramped(fx_val[c, k, 0], fx_val[c, k, 1], frac)
            if kind == FIX_NVT:
                j, o, m = fx_meta[k, 4], fx_meta[k, 5], fx_meta[k, 6]
                tt[c, j] = target
                total, tc[c, j] = _th_nh(eta[c, o:o + m], ed[c, o + j:o + j + m + 1], edd[c, o:o + m], Q[c, o:o + m],
                                         tc[c, j], target, tf[c, j], fx_val[c, k, 5], boltz, fx_meta[k, 7], drag[c, j],
                                         dtc)
                _scale_group(V, groups, g, total)
            elif kind == FIX_LANGEVIN:
                m0, m1, m2, count = _langevin_draws(c, k, target, dtc, boltz, fx_meta, fx_val, fx_f, rngs, SQM, FR,
                                                    groups, 0, n)
                if fx_meta[k, 3] & 1 and count > 0:  # zero yes: the group's random forces sum to zero
                    l = fx_meta[k, 4]
                    f0, f1, f2 = FR[3 * l], FR[3 * l + 1], FR[3 * l + 2]
                    m0 /= count
                    m1 /= count
                    m2 /= count
                    for i in range(n):
                        f0[i] = f0[i] - m0
                        f1[i] = f1[i] - m1
                        f2[i] = f2[i] - m2
        return 0

    @inline
    def _langevin_draws(c, k, target, dtc, boltz, fx_meta, fx_val, fx_f, rngs, SQM, FR, groups, a_lo, a_hi):
        """Langevin fix k's random forces of the atoms a_lo .. a_hi - 1 into its rows of FR: three
        uniforms from its generator rngs[l] per atom of its group, atom after atom (thermostats'
        langevin random force at temperature `target`; 0.5, no draw, for the others). Returns their
        sums over the group's atoms, in atom order, and the count of those atoms."""
        l, g = fx_meta[k, 4], fx_meta[k, 1]
        rng = rngs[l]
        f0, f1, f2 = FR[3 * l], FR[3 * l + 1], FR[3 * l + 2]
        amp = _th_amp(fx_val[c, k, 2], dtc, fx_f[1], fx_f[2], boltz)
        st = np.sqrt(target)
        m0 = 0.0
        m1 = 0.0
        m2 = 0.0
        count = 0
        for i in range(a_lo, a_hi):
            if groups[g, i] != 0:
                r0 = _th_random(SQM[i], amp, st, rng.random())
                r1 = _th_random(SQM[i], amp, st, rng.random())
                r2 = _th_random(SQM[i], amp, st, rng.random())
                count += 1
            else:
                r0 = _th_random(SQM[i], amp, st, 0.5)
                r1 = _th_random(SQM[i], amp, st, 0.5)
                r2 = _th_random(SQM[i], amp, st, 0.5)
            f0[i] = r0
            f1[i] = r1
            f2[i] = r2
            if groups[g, i] != 0:
                m0 += r0
                m1 += r1
                m2 += r2
            else:
                m0 += 0.0
                m1 += 0.0
                m2 += 0.0
        return m0, m1, m2, count

    @inline
    def _fix_draws(c, stepn, dtc, at, ats, groups, fx, rngs, SQM, FR, a_lo, a_hi):
        """The langevin fixes' random forces of step stepn for the atoms a_lo .. a_hi - 1 only, each
        fix's from rngs[l] (`_fix_pre`'s draws, for one thread's run of atoms: its generators
        stand where the one-thread stream reaches atom a_lo). For fixes without zero yes and no
        fix nvt (`_fix_pre` does nothing else then)."""
        fx_meta, fx_val, fx_acc, eta, ed, edd, Q, tc, tt, tf, drag, fx_int, fx_f, _fo = fx
        frac = _ramp_frac(stepn, dtc, at, ats, fx_int, fx_f)
        boltz = fx_f[0]
        for k in range(fx_meta.shape[0]):
            if fx_meta[k, 0] == FIX_LANGEVIN:
                target = _th_ramped(fx_val[c, k, 0], fx_val[c, k, 1], frac)
                _langevin_draws(c, k, target, dtc, boltz, fx_meta, fx_val, fx_f, rngs, SQM, FR, groups, a_lo, a_hi)
        return 0

    @inline
    def _langevin_setup(c, M, fx, ftm2v, SQM, G1):
        """Case c's per-atom factors of its langevin fixes: sqrt(m) for the random force and each
        fix's drag row G1[l] (thermostats.langevin_drag of its damp)."""
        for a in range(M.shape[0]):
            SQM[a] = np.sqrt(M[a])
        for k in range(fx[0].shape[0]):
            if fx[0][k, 0] == FIX_LANGEVIN:
                g1, damp = G1[fx[0][k, 4]], fx[1][c, k, 2]
                for a in range(M.shape[0]):
                    g1[a] = _th_drag(M[a], damp, ftm2v)

    @inline
    def _sample_fixes(c, fx, acc, chain):
        """Case c's fix state at a sample (what Ensemble.ecouple reads): each fix's accumulators
        into acc (K, 4) and each fix nvt's chain, in fix order, eta, eta_dot, eta_mass and
        t_target into chain (3 m + 2 each)."""
        fx_meta = fx[0]
        p = 0
        for k in range(fx_meta.shape[0]):
            for i in range(4):
                acc[k, i] = fx[2][c, k, i]
            if fx_meta[k, 0] == FIX_NVT:
                j, o, m = fx_meta[k, 4], fx_meta[k, 5], fx_meta[k, 6]
                for i in range(m):
                    chain[p] = fx[3][c, o + i]
                    p += 1
                for i in range(m + 1):
                    chain[p] = fx[4][c, o + j + i]
                    p += 1
                for i in range(m):
                    chain[p] = fx[6][c, o + i]
                    p += 1
                chain[p] = fx[8][c, j]
                p += 1

    @jit_inner
    def _fix_end(c, stepn, dtc, at, ats, V, M, groups, fx, KB, FL):
        """After the step's final kick: fix nvt's second half step (Ensemble.final_integrate), then
        Ensemble.end_of_step: temp/berendsen, temp/rescale (every N), the Langevin tally. Returns 6
        when a rescaling fix meets a zero temperature (the NumPy loop reports it)."""
        fx_meta, fx_val, fx_acc, eta, ed, edd, Q, tc, tt, tf, drag, fx_int, fx_f, _fo = fx
        n = V.shape[1]
        frac = _ramp_frac(stepn, dtc, at, ats, fx_int, fx_f)
        boltz, mvv2e = fx_f[0], fx_f[2]
        for k in range(fx_meta.shape[0]):
            if fx_meta[k, 0] == FIX_NVT:
                g, j, o, m = fx_meta[k, 1], fx_meta[k, 4], fx_meta[k, 5], fx_meta[k, 6]
                target = _th_ramped(fx_val[c, k, 0], fx_val[c, k, 1], frac)
                tc[c, j] = _group_temperature(V, M, groups, g, fx_val[c, k, 5], mvv2e, boltz, KB)
                tt[c, j] = target
                total, tc[c, j] = _th_nh(eta[c, o:o + m], ed[c, o + j:o + j + m + 1], edd[c, o:o + m], Q[c, o:o + m],
                                         tc[c, j], target, tf[c, j], fx_val[c, k, 5], boltz, fx_meta[k, 7], drag[c, j],
                                         dtc)
                _scale_group(V, groups, g, total)
        for k in range(fx_meta.shape[0]):
            kind = fx_meta[k, 0]
            if kind != FIX_BERENDSEN and kind != FIX_RESCALE:
                continue
            if kind == FIX_RESCALE and stepn % fx_meta[k, 2] != 0:
                continue
            g = fx_meta[k, 1]
            dof = fx_val[c, k, 5]
            t_now = _group_temperature(V, M, groups, g, dof, mvv2e, boltz, KB)
            if dof < 1:
                continue
            if t_now == 0.0:
                return 6
            target = _th_ramped(fx_val[c, k, 0], fx_val[c, k, 1], frac)
            if kind == FIX_BERENDSEN:
                factor, removed = _th_berendsen(t_now, target, dtc, fx_val[c, k, 2], dof, boltz)
            else:
                factor, removed = _th_rescale(t_now, target, fx_val[c, k, 3], fx_val[c, k, 4], dof, boltz)
            _scale_group(V, groups, g, factor)
            fx_acc[c, k, 0] = fx_acc[c, k, 0] + removed
        for k in range(fx_meta.shape[0]):
            if fx_meta[k, 0] == FIX_LANGEVIN and fx_meta[k, 3] & 2:
                l = fx_meta[k, 4]
                for i in range(n):
                    KB[i] = _th_dot3(FL[3 * l, i], FL[3 * l + 1, i], FL[3 * l + 2, i], V[0, i], V[1, i], V[2, i])
                power = 0.0 + _th_pairwise(KB, 0, n)
                fx_acc[c, k, 3] = dtc
                fx_acc[c, k, 2] = power
                fx_acc[c, k, 1] = fx_acc[c, k, 1] + power * dtc
        return 0

    @inline
    def _reflect_face(d, side, wall, g, coord, vwall, stats, row, k, X, V, M, groups, rstat, ftm2v, u0, u1):
        """One wall/reflect face over atoms u0..u1-1 (walls.ReflectKernel.apply): an atom of group g
        past coord (side < 0: below it; else above) gets x -> 2 coord - x and v -> -v (`wall`,
        frame wall: v -> 2 vwall - v). Without statistics one branch-free pass (selects: the same
        values, every atom written), which the compiler vectorises; with them the reflected atoms
        add their count and impulse M (v_before - v_after) / ftm2v to rstat[row, k] in atom
        order, as np.bincount sums them."""
        sgn = 1.0 if side < 0 else -1.0  # past: sgn x < sgn coord (x < coord, or -x < -coord: x > coord), exactly
        lim = sgn * coord
        two = 2.0 * coord
        if stats:
            for i in range(u0, u1):
                pos = X[d, i]
                if sgn * pos < lim and groups[g, i] != 0:
                    X[d, i] = two - pos
                    vb = V[d, i]
                    va = 2.0 * vwall - vb if wall else -vb
                    V[d, i] = va
                    rstat[row, k, 0] += 1.0
                    rstat[row, k, 1] += M[i] * (vb - va) / ftm2v
        elif wall:
            vw2 = 2.0 * vwall
            for i in range(u0, u1):
                pos = X[d, i]
                vb = V[d, i]
                past = (sgn * pos < lim) & (groups[g, i] != 0)
                X[d, i] = two - pos if past else pos
                V[d, i] = vw2 - vb if past else vb
        else:
            for i in range(u0, u1):
                pos = X[d, i]
                vb = V[d, i]
                past = (sgn * pos < lim) & (groups[g, i] != 0)
                X[d, i] = two - pos if past else pos
                V[d, i] = -vb if past else vb

    @inline
    def _block_step(c, u0, u1, si, row, dtc, due, X, V, F, M, RAD, DTFM, CAND, groups, box,
                    sf_meta, sf_val, rf_meta, rf_val, vw, rstat, stats, ftm2v, mvv2e, dtr_group, dtr_par, rg, fxp,
                    tbst):
        """One velocity-Verlet step (engine.Engine.step) of atoms u0..u1-1 of case c, as simple
        passes over the structure-of-arrays buffers: kick-drift (with the force clear and, when
        nothing in between moves a periodic coordinate, the periodic wrap), reflect faces (wall velocities
        vw[row], statistics into rstat[row]), the periodic wrap if not done before, soft faces, lost test,
        kick; with `due`, fix dt/reset's candidates. Returns (status, smallest candidate over
        the dt/reset group, NaN if any is NaN); status 0, 1 (an atom on/behind a soft wall) or
        2 (an atom left through a fixed boundary). box rows: lo, hi, periodic (1.0) per dimension;
        dtr_par[c]: xmax, emax, tmin, tmax; tbst = (tb, st, lp, mv): the wall/table faces' tables
        (`_table_faces`), the wall/reflect/stochastic faces (`_stochastic_faces`), the
        parameter rows (C, faces, P) of wall/lepton faces with more than 3 parameters and the
        integrated atoms' mask (nonzero: integrated; read with _K_FROZEN only), one argument
        (a call of more than 30 arguments is compiled by CPython as f(*args), which numba cannot
        inline)."""
        tb, st, lp, mv = tbst
        # the periodic wrap joins the drift unless something between them reads or moves a
        # periodic coordinate (a wall/reflect face on a periodic dimension, wall/reflect/stochastic);
        # the force clear joins it too (nothing reads F before the clear): the same values, fewer passes
        early = not (_K_STOCHASTIC and st[0].shape[0])
        if _K_REFLECT:
            for k in range(rf_meta.shape[0]):
                early = early and box[2, rf_meta[k, 0]] == 0.0
        for d in range(2 if _K_2D else 3):  # initial_integrate: v += dtfm f; x += dt v (then wrap, f = 0)
            if early and box[2, d] != 0.0:
                lod = box[0, d]
                hid = box[1, d]
                length = hid - lod
                for i in range(u0, u1):
                    vi = V[d, i] + DTFM[i] * F[d, i]
                    xi = X[d, i] + dtc * vi
                    if _K_FROZEN:  # atoms no integrator moves keep v and x (selects: the loop still vectorises)
                        vi = vi if mv[i] != 0 else V[d, i]
                        xi = xi if mv[i] != 0 else X[d, i]
                    V[d, i] = vi
                    xi = xi - length if xi >= hid else xi
                    X[d, i] = xi + length if xi < lod else xi
                    F[d, i] = 0.0
            else:
                for i in range(u0, u1):
                    vi = V[d, i] + DTFM[i] * F[d, i]
                    xi = X[d, i] + dtc * vi
                    if _K_FROZEN:
                        vi = vi if mv[i] != 0 else V[d, i]
                        xi = xi if mv[i] != 0 else X[d, i]
                    V[d, i] = vi
                    X[d, i] = xi
                    F[d, i] = 0.0
        if _K_REFLECT:
            for k in range(rf_meta.shape[0]):  # wall/reflect (post_integrate)
                _reflect_face(rf_meta[k, 0], rf_meta[k, 1], rf_meta[k, 2] == 1, rf_meta[k, 3], rf_val[c, si, k],
                              vw[row, k], stats, row, k, X, V, M, groups, rstat, ftm2v, u0, u1)
        if _K_STOCHASTIC and st[0].shape[0]:  # wall/reflect/stochastic (post_integrate, after the wall/reflect fixes: `eligible`)
            _stochastic_faces(c, u0, u1, X, V, M, groups, st, ftm2v, mvv2e)
        for d in range(2 if _K_2D else 3):  # periodic wrap (when not done with the drift)
            if box[2, d] != 0.0 and not early:
                lod = box[0, d]
                hid = box[1, d]
                length = hid - lod
                for i in range(u0, u1):
                    xi = X[d, i]
                    xi = xi - length if xi >= hid else xi
                    X[d, i] = xi + length if xi < lod else xi
        nbad = 0
        for k in range(sf_meta.shape[0]):  # soft walls (post_force), one loop per style
            style = sf_meta[k, 0]
            g, d, side = sf_meta[k, 3], sf_meta[k, 1], sf_meta[k, 2]
            coord, cut, ron = sf_val[c, si, k, 0], sf_val[c, si, k, 4], sf_val[c, si, k, 5]
            p0, p1, p2 = sf_val[c, si, k, 1], sf_val[c, si, k, 2], sf_val[c, si, k, 3]
            if _K_TABLES and style == TABLE_STYLE:  # wall/table: the face's table from tb (data, not code)
                nbad += _table_faces(tb, k, X, F, groups, g, d, side, coord, cut, u0, u1)
            elif _K_VECTOR and style < TABLE_STYLE:  # wall/lepton, parameters as an array: this case's row of lp
                nbad += _vector_faces(-2 - style, X, F, RAD, groups, g, d, side, coord, lp[c, k], cut, u0, u1)
            else:
                nbad += _soft_face(style, sf_meta[k, 4], X, F, RAD, groups, g, d, side, coord, p0, p1, p2, cut,
                                   ron, u0, u1)
        if _K_REGION and rg[0].shape[0]:  # wall/region fixes (post_force, after the flat walls as in compute_forces)
            nbad += _region_walls(c, u0, u1, X, F, RAD, groups, rg[0], rg[1], rg[2], rg[3])
        if nbad:
            return 1, 0.0
        if _K_FIXES and fxp[0].shape[0]:  # post_force fixes: langevin, enforce2d (Ensemble.post_force)
            _fix_post_force(u0, u1, V, F, groups, fxp)
        nlost = 0
        for d in range(3):  # lost atoms
            if box[2, d] == 0.0:
                lod = box[0, d]
                hid = box[1, d]
                for i in range(u0, u1):
                    nlost += (X[d, i] < lod) | (X[d, i] > hid)
        if nlost:
            return 2, 0.0
        xmax = emax = tmax = 0.0
        if _K_DTR and due:  # (dtr_par is None in a kernel without dt/reset: `SceneKernel`)
            xmax, emax, tmax = dtr_par[c, 0], dtr_par[c, 1], dtr_par[c, 3]
        if not _K_DTR or not due or tmax != tmax:
            for d in range(2 if _K_2D else 3):  # final_integrate: v += dtfm f (2-D: z stays 0)
                for i in range(u0, u1):
                    vi = V[d, i] + DTFM[i] * F[d, i]
                    if _K_FROZEN:
                        vi = vi if mv[i] != 0 else V[d, i]
                    V[d, i] = vi
            if not _K_DTR or not due:
                return 0, np.inf
        else:
            # final_integrate fused with a test: each atom's dt is >= min(dtv, dtf, dte) / 2 (the
            # displacement cut at most halves it). If products alone show min(...) >= 2.0001 tmax for
            # every group atom of the block, none gives less than tmax, which the result is clamped
            # to: the exact values are not needed. (Non-finite v or f fail the test.)
            big = 2.0001 * tmax
            big2 = big * big
            vlim = xmax * xmax
            flim = (2.0 * xmax) * (2.0 * xmax)
            fk = (ftm2v * big2) * (ftm2v * big2)
            ek = ftm2v * mvv2e * big2
            elim = emax * emax
            nexact = 0
            for i in range(u0, u1):
                f0, f1, f2 = F[0, i], F[1, i], F[2, i]
                v0 = V[0, i] + DTFM[i] * f0
                v1 = V[1, i] + DTFM[i] * f1
                v2 = V[2, i] + DTFM[i] * f2
                if _K_FROZEN and mv[i] == 0:
                    v0, v1, v2 = V[0, i], V[1, i], V[2, i]
                V[0, i] = v0
                V[1, i] = v1
                V[2, i] = v2
                vsq = v0 * v0 + v1 * v1 + v2 * v2
                fsq = f0 * f0 + f1 * f1 + f2 * f2
                ok = (vsq * big2 <= vlim) & (fsq * fk <= flim * (M[i] * M[i])) & ((emax <= 0) | (fsq * vsq * ek <= elim))
                nexact += (groups[dtr_group, i] != 0) & (not ok)
            if nexact == 0:
                return 0, np.inf
        for i in range(u0, u1):  # fix dt/reset: each atom's largest dt
            CAND[i] = _dt_candidate(V[0, i], V[1, i], V[2, i], F[0, i], F[1, i], F[2, i], M[i], ftm2v, mvv2e,
                                    xmax, emax)
        return 0, _group_low(CAND, groups, dtr_group, u0, u1)

    @inline
    def _late_dt_low(natom, V, F, M, CAND, groups, g, ftm2v, mvv2e, par):
        """fix dt/reset at the end of a step whose thermostats scaled v after the block pass: the
        smallest candidate (`_dt_candidate`) of the group g's atoms from their final v and f
        (engine.Engine.reset_dt after Ensemble.end_of_step); par: xmax, emax, tmin, tmax."""
        for i in range(natom):
            CAND[i] = _dt_candidate(V[0, i], V[1, i], V[2, i], F[0, i], F[1, i], F[2, i], M[i], ftm2v, mvv2e,
                                    par[0], par[1])
        return _group_low(CAND, groups, g, 0, natom)

    @inline
    def _clamp(low, natom, par):
        """engine.Engine.reset_dt after the per-atom minimum: BIG, tmin, tmax (par[2], par[3])."""
        new = _nmin(low, BIG) if natom > 0 else BIG
        if par[2] == par[2]:
            new = _nmax(new, par[2])
        if par[3] == par[3]:
            new = _nmin(new, par[3])
        return new

    def _flow_step(X, V, M, fl_int, fl_f, walls, grp, phys, pend, prev, cross, rng, CI, DIR):
        """fix wall/flow's end_of_step (flow.FlowKernel.end_of_step) for the one case of the chunk,
        on its buffers: crossings (flow_compiled.crossing per atom), then the draws from the case's
        generator in the NumPy order (u1, u2, g (n, 2)) and the redraws (flow_compiled.redraw).
        fl_int: on, axis, exact; fl_f: lo, length, vflow, kT. Compiled by `kernel_for` for scenes
        with a flow wall (`flow_compiled` is linked then)."""
        ax = fl_int[1]
        lo, length = fl_f[0], fl_f[1]
        n = 0
        for i in range(X.shape[1]):
            xi = X[ax, i]
            sg, d, pe = flow_compiled.crossing(xi, V[ax, i], prev[i], lo, length, walls, phys[i], pend[i], grp[i] != 0)
            pend[i] = pe
            if d != 0.0:
                CI[n] = i
                DIR[n] = d
                n += 1
            phys[i] = sg
            prev[i] = xi
        if n == 0:
            return
        u1 = rng.random(n)
        u2 = rng.random(n)
        g = rng.standard_normal((n, 2))
        kT, vflow = fl_f[3], fl_f[2]
        for k in range(n):
            i = CI[k]
            gamma = 1.0 / math.sqrt(2.0 * kT / M[i])
            v_axis, V[(ax + 1) % 3, i], V[(ax + 2) % 3, i] = flow_compiled.redraw(u1[k], u2[k], g[k, 0], g[k, 1],
                                                                                  gamma, vflow)
            V[ax, i] = v_axis
            pend[i] = -DIR[k] if fl_int[2] != 0 and v_axis * DIR[k] < 0.0 else 0
        cross[0] += n

    def _make_run_chunk(fingerprint: int) -> Any:
        """The chunk kernel's Python function (compiled by `kernel_for`); `fingerprint` (see
        _fingerprint) joins its on-disk cache key."""

        def _run_chunk(nsteps, time_mode, target, tol, x, v, f, mass, radius, dt, atime, atimestep,
                       step, lo, hi, periodic, sf_meta, sf_val, groups, rf_meta, rf_val, rf_prev, rf_stat,
                       stats, dtr_every, dtr_group, dtr_par, ftm2v, mvv2e, xo, vo, fo, rg_meta, rg_geo, rg_val,
                       fl_int, fl_f, fl_walls, fl_grp, fl_phys, fl_pend, fl_prev, fl_cross, fl_rng, fx, fx_rng,
                       tb_meta, tb_par, tb_data, st_meta, st_val, st_stat, st_flag, st_rng, lp_val, mrow, sm):
            """Advance every case by nsteps steps (or, with time_mode, to the time `target` as
            Engine.advance_to_time does), reading x, v, f and writing xo, vo, fo. Returns 0, or the
            nonzero status of the first trouble met (1: an atom on/behind a soft wall, 2: a lost atom,
            3: a non-finite value, 4: a case with nothing to do); the caller then falls back to NumPy.

            Per case, the atoms are copied into structure-of-arrays buffers (X, V, F: (3, N)), and
            steps run in windows: every step of the window on one block of BLOCK atoms (it stays in
            L1 cache), then the next block. Without dt/reset a window is the whole chunk. With dt/reset
            a window of WINDOW steps runs at the current dt and keeps each step's smallest candidate;
            if one of them would change dt, the window is undone and run step by step (all blocks per
            step) up to that step, then windows resume. Time-based runs go step by step.

            Sampled chunks (sm[0], the sample steps counted from the chunk's start, not empty; step-
            based runs): windows end at sample steps, and after each sample step the outputs of
            every case go into the sm arrays (`_sample_faces`; sum m v^2 in NumPy's pairwise order;
            step, dt, atime, atimestep; reflect statistics and flow redraws since the last sample;
            the fixes' accumulators and chain), as Engine.sample would record them."""
            # (each return releases every live array: a few returns only, for a shorter compile)
            # (the arguments of what the kernel leaves out are None: `SceneKernel`; their code is under
            # the feature's flag, so numba drops it before typing)
            ncase, natom = x.shape[0], x.shape[1]
            nrf = rf_meta.shape[0] if _K_REFLECT else 0
            hf = 0.5 * ftm2v
            vary = 1 if (sf_val.shape[1] > 1 or (_K_REFLECT and rf_val.shape[1] > 1)) else 0
            # wall/reflect/stochastic draws for the atoms of a face in atom order: one block of all atoms
            blk = (natom if natom > 1 else 1) if _K_STOCHASTIC and st_meta.shape[0] else BLOCK
            nblock = (natom + blk - 1) // blk
            box = np.empty((3, 3))
            for d in range(3):
                box[0, d] = lo[d]
                box[1, d] = hi[d]
                box[2, d] = 1.0 if periodic[d] != 0 else 0.0
            X = np.empty((3, natom))
            V = np.empty((3, natom))
            F = np.empty((3, natom))
            M = np.empty(natom)
            RAD = np.empty(natom)
            DTFM = np.empty(natom)
            CAND = np.empty(natom)
            speculate = _K_DTR and dtr_every > 0 and not time_mode
            if _K_DTR:
                XS = np.empty((3, natom if speculate else 0))  # window start, to undo a window
                VS = np.empty((3, natom if speculate else 0))
                FS = np.empty((3, natom if speculate else 0))
            # (plain conditionals for min/max and np.empty for np.zeros: each overload is a compile)
            nrow = nsteps if dtr_every == 0 else (WINDOW if WINDOW < nsteps else nsteps)
            nrow = nrow if nrow > 1 else 1
            vw = np.empty((nrow, nrf))  # wall velocities (frame wall) per step of a window (set per window)
            rstat = np.empty((nrow, nrf, 2))  # reflections and impulse per step and face (set per window)
            low = np.empty(nrow)  # smallest dt/reset candidate per step of a window
            # wall/region: one argument (a call of more than 30 arguments is compiled by CPython as
            # f(*args), which numba cannot inline); RB holds a block's contacts (_region_contacts)
            rg = (rg_meta, rg_geo, rg_val, np.empty((6, 5, blk)) if _K_REGION else None)
            # wall/flow (fl_int[0] != 0; the chunk then holds one case): step by step over all blocks
            flowing = False
            if _K_FLOW:
                flowing = fl_int[0] != 0
                CI = np.empty(natom if fl_int[0] != 0 else 0, np.int64)
                DIR = np.empty(natom if fl_int[0] != 0 else 0)
            # fixes (fx: see _fix_pre; fx[0] = fx_meta): thermostats couple the atoms every step, so
            # a chunk with one goes step by step over all blocks; enforce2d alone keeps the windows
            thermo = False
            late = False
            nlang = 0  # langevin fixes
            rescale_only = True  # temp/rescale alone: windows up to its next due step
            if _K_FIXES:
                fx_meta = fx[0]
                for k in range(fx_meta.shape[0]):
                    thermo = thermo or fx_meta[k, 0] != FIX_ENFORCE2D
                    if fx_meta[k, 0] == FIX_LANGEVIN:
                        nlang += 1
                    if fx_meta[k, 0] != FIX_ENFORCE2D and fx_meta[k, 0] != FIX_RESCALE:
                        rescale_only = False
                nfx = natom if fx_meta.shape[0] else 0
                # with fix dt/reset, the atoms' candidates once the thermostats have scaled v at the
                # step's end (Engine.step's order), step by step over all atoms (`_late_dt_low`)
                late = _K_DTR and thermo and dtr_every != 0
                SQM = np.empty(nfx)  # sqrt(m): the Langevin random force's per-atom factor
                G1 = np.empty((nlang, nfx))  # each langevin fix's drag per atom
                FR = np.empty((3 * nlang, nfx))  # this step's Langevin random forces (x, y, z of each fix)
                FL = np.empty((3 * nlang, nfx))  # this step's Langevin forces (the tally's)
                for d in range(3 * nlang):
                    for a in range(nfx):
                        FR[d, a] = 0.0
                        FL[d, a] = 0.0
                KB = np.empty(nfx)  # per-atom terms of a sum over atoms
                fxp = (fx_meta, G1, FR, FL)
            else:
                fxp = None
            nsm = 0
            if _K_SAMPLES:
                sm_at, sm_mv2, sm_clock, sm_face, sm_rstat, sm_fx, sm_chain, sm_cross, sm_reg = sm
                nsm = sm_at.shape[0]
                KS = np.empty(natom if nsm else 0)  # m v^2 per atom at a sample
                if _K_REGION:
                    RBS = np.empty((6, 5, natom if nsm and rg_meta.shape[0] else 0))  # a case's region contacts
            if _K_TABLES:  # wall/table faces (`_table_faces`) and their scratch bytes
                tb = (tb_meta, tb_par, tb_data, np.zeros(((blk + 63) // 64) * 64 if tb_meta.shape[0] else 0, np.uint8))
            else:
                tb = (tb_meta, tb_par, tb_data, None)
            if _K_STOCHASTIC:  # the stochastic faces and their scratch
                nst = natom if st_meta.shape[0] else 0
                sto = (st_meta, st_val, st_stat, st_flag, st_rng, np.empty(nst, np.int64), np.empty((4, nst)))
            else:
                sto = (st_meta, st_val, st_stat, st_flag, st_rng, None, None)
            # wall/reflect/stochastic, lepton parameter rows, the integrated atoms (groups row mrow; -1: all)
            tbst = (tb, sto, lp_val, groups[mrow] if mrow >= 0 else groups[0])
            for c in range(ncase):
                for a in range(natom):
                    for d in range(3):
                        X[d, a] = x[c, a, d]
                        V[d, a] = v[c, a, d]
                        F[d, a] = f[c, a, d]
                    M[a] = mass[c, a]
                    RAD[a] = radius[c, a]
                if _K_FIXES and nlang:
                    _langevin_setup(c, M, fx, ftm2v, SQM, G1)
                done = 0  # steps done for this case
                ism = 0  # the case's next sample
                stepwise = 0  # steps to run one at a time before the next window
                backoff = 0
                while True:
                    base = 0.0
                    sdt = 0.0
                    landing = False
                    if _K_TIME and time_mode:
                        now = atime[c] + (step[c] - atimestep[c]) * dt[c]
                        if not now < target - tol:
                            if done == 0:
                                return 4
                            break
                    elif done == nsteps:
                        break
                    # a window of nwin steps at one dt, block by block; or one step (time-based runs, and
                    # dt/reset while dt changes), which is a window of one step followed by its dt update
                    window = (not time_mode and (dtr_every == 0 or stepwise == 0) and not flowing
                              and (rescale_only or not thermo) and not late)
                    nwin = 1
                    if window:
                        nwin = nsteps - done
                        if dtr_every != 0 and WINDOW < nwin:
                            nwin = WINDOW
                        if _K_FIXES and thermo:  # temp/rescale only (its atoms are coupled on due steps only)
                            for k in range(fx_meta.shape[0]):
                                if fx_meta[k, 0] == FIX_RESCALE:
                                    every = fx_meta[k, 2]
                                    due_in = every - step[c] % every
                                    nwin = due_in if due_in < nwin else nwin
                        if _K_SAMPLES and ism < nsm:  # a window ends at a sample step
                            to_sample = sm_at[ism] - done
                            nwin = to_sample if to_sample < nwin else nwin
                    if _K_TIME and time_mode:
                        base = dt[c]
                        rem = target - now
                        sdt = _nmin(base, rem)
                        landing = base >= rem - tol
                        if sdt != dt[c]:
                            atime[c] = now
                            atimestep[c] = step[c]
                            dt[c] = sdt
                    dtc = dt[c]
                    hdt = hf * dtc
                    for a in range(natom):
                        DTFM[a] = hdt / M[a]
                    if _K_DTR and window and speculate:
                        _copy3(XS, X)
                        _copy3(VS, V)
                        _copy3(FS, F)
                    for s in range(nwin):
                        low[s] = np.inf
                        if _K_REFLECT:
                            for k in range(nrf):
                                prev = rf_prev[c, k] if s == 0 else rf_val[c, (done + s - 1) * vary, k]
                                vw[s, k] = (rf_val[c, (done + s) * vary, k] - prev) / dtc if dtc > 0 else 0.0
                                rstat[s, k, 0] = 0.0
                                rstat[s, k, 1] = 0.0
                    if _K_FIXES and thermo:  # fix nvt's first half step, the Langevin random forces
                        _fix_pre(c, step[c] + 1, dtc, atime[c], atimestep[c], V, M, groups, fx, fx_rng, SQM, FR, KB)
                    for b in range(nblock):
                        u0 = np.uint64(b * blk)  # unsigned: no negative-index wraparound, loops vectorise
                        u1 = np.uint64(b * blk + blk if b * blk + blk < natom else natom)
                        for s in range(nwin):
                            due = _K_DTR and dtr_every > 0 and (step[c] + s + 1) % dtr_every == 0 and not late
                            st, m = _block_step(c, u0, u1, (done + s) * vary, s, dtc, due, X, V, F, M, RAD, DTFM,
                                                CAND, groups, box, sf_meta, sf_val, rf_meta, rf_val,
                                                vw, rstat, stats, ftm2v, mvv2e, dtr_group, dtr_par, rg, fxp, tbst)
                            if st != 0:
                                return st
                            if _K_DTR and due:
                                low[s] = _nmin(low[s], m)
                    if _K_FIXES and thermo:  # fix nvt's second half step, temp/berendsen, temp/rescale, the tally
                        st = _fix_end(c, step[c] + nwin, dtc, atime[c], atimestep[c], V, M, groups, fx, KB, FL)
                        if st != 0:
                            return st
                    if _K_FLOW and fl_int[0] != 0:  # fix wall/flow (end_of_step)
                        _flow_step(X, V, M, fl_int, fl_f, fl_walls, fl_grp, fl_phys, fl_pend, fl_prev, fl_cross,
                                   fl_rng, CI, DIR)
                    if _K_DTR and window and speculate:
                        first = -1
                        for s in range(nwin):
                            if (step[c] + s + 1) % dtr_every == 0 and _clamp(low[s], natom, dtr_par[c]) != dtc:
                                first = s
                                break
                        if first >= 0:  # dt changes after step `first`: undo, go step by step up to there
                            _copy3(X, XS)
                            _copy3(V, VS)
                            _copy3(F, FS)
                            stepwise = first + 1 + backoff
                            backoff = 2 * backoff + 8 if 2 * backoff + 8 < 4096 else 4096
                            continue
                        backoff = 0
                    step[c] += nwin
                    if _K_REFLECT:
                        for s in range(nwin):
                            for k in range(nrf):
                                rf_stat[c, k, 0] += rstat[s, k, 0]
                                rf_stat[c, k, 1] += rstat[s, k, 1]
                        for k in range(nrf):
                            rf_prev[c, k] = rf_val[c, (done + nwin - 1) * vary, k]
                    done += nwin
                    if not window:
                        if _K_DTR and dtr_every > 0 and step[c] % dtr_every == 0:  # fix dt/reset (end_of_step)
                            if late:
                                low[0] = _late_dt_low(natom, V, F, M, CAND, groups, dtr_group, ftm2v, mvv2e, dtr_par[c])
                            new = _clamp(low[0], natom, dtr_par[c])
                            if new != dt[c]:
                                atime[c] = atime[c] + (step[c] - atimestep[c]) * dt[c]
                                atimestep[c] = step[c]
                                dt[c] = new
                        if stepwise > 0:
                            stepwise -= 1
                        if _K_TIME and time_mode:
                            new_base = dt[c] if dt[c] != sdt else base
                            if landing or new_base != dt[c]:  # at a fixed dt: time = atime + n dt (no sum)
                                now = atime[c] + (step[c] - atimestep[c]) * dt[c]
                                atime[c] = target if landing else now
                                atimestep[c] = step[c]
                            dt[c] = new_base
                            if landing:
                                break
                    if _K_SAMPLES and ism < nsm and done == sm_at[ism]:  # a sample step: the outputs of Engine.sample
                        _sample_faces(c, (done - 1) * vary, X, RAD, groups, sf_meta, sf_val, tb, lp_val, sm_face[c, ism])
                        if _K_REGION and rg_meta.shape[0]:
                            _sample_regions(c, X, RAD, groups, rg_meta, rg_geo, rg_val, RBS, sm_reg[c, ism])
                        sm_mv2[c, ism] = _mv2_sum(M, V, KS, natom)
                        sm_clock[c, ism, 0] = step[c]
                        sm_clock[c, ism, 1] = dt[c]
                        sm_clock[c, ism, 2] = atime[c]
                        sm_clock[c, ism, 3] = atimestep[c]
                        if _K_REFLECT:  # reflect statistics since the last sample
                            _take_stats(rf_stat[c], sm_rstat[c, ism], 0)
                        if _K_STOCHASTIC and st_flag[0] != 0:  # wall/reflect/stochastic's, after them
                            _take_stats(st_stat[c], sm_rstat[c, ism], nrf)
                        if _K_FIXES:
                            _sample_fixes(c, fx, sm_fx[c, ism], sm_chain[c, ism])
                        sm_cross[c, ism] = fl_cross[0] if _K_FLOW else 0.0  # flow redraws since the last sample
                        if _K_FLOW:  # (take_crossings)
                            fl_cross[0] = 0.0
                        ism += 1
                finite = math.isfinite(dt[c])
                for a in range(natom):
                    for d in range(3):
                        finite = finite & math.isfinite(X[d, a]) & math.isfinite(V[d, a])
                        xo[c, a, d] = X[d, a]
                        vo[c, a, d] = V[d, a]
                        fo[c, a, d] = F[d, a]
                if not finite:
                    return 3
                if _K_FIXES and nlang:
                    for a in range(natom):
                        for d in range(3 * nlang):
                            fx[13][c, a, d] = FL[d, a]
            return 5 if nsteps == -fingerprint else 0  # never 5: ties the on-disk cache to the styles (_fingerprint)
        return _run_chunk

    @jit
    def _no_region_walls(c, u0, u1, X, F, RAD, groups, rg_meta, rg_geo, rg_val, RB):
        """`_region_walls` of a scene without wall/region fixes: nothing."""
        return 0

    @jit
    def _no_sample_regions(c, X, RAD, groups, rg_meta, rg_geo, rg_val, RB, out):
        """`_sample_regions` of a scene without wall/region fixes: nothing."""
        return

    @jit
    def _no_flow_step(X, V, M, fl_int, fl_f, walls, grp, phys, pend, prev, cross, rng, CI, DIR):
        """`_flow_step` of a scene without wall/flow fixes: nothing."""
        return

    # stubs linked into the kernel of a scene without `fixes:` or without fix dt/reset (`kernel_for`):
    # the chunk never calls them then (no fix rows; dtr_every == 0), and leaving the thermostat and
    # dt/reset code out makes the first compile of such a scene's kernel several seconds shorter
    @jit
    def _no_fix_pre(c, stepn, dtc, at, ats, V, M, groups, fx, rng, SQM, FR, KB):
        """`_fix_pre` of a scene without fixes: nothing."""
        return 0

    @jit
    def _no_fix_end(c, stepn, dtc, at, ats, V, M, groups, fx, KB, FL):
        """`_fix_end` of a scene without fixes: nothing."""
        return 0

    @inline
    def _no_fix_post_force(u0, u1, V, F, groups, fxp):
        """`_fix_post_force` of a scene without fixes: nothing."""
        return

    @inline
    def _no_dt_candidate(vx, vy, vz, fx, fy, fz, m, ftm2v, mvv2e, xmax, emax):
        """`_dt_candidate` of a scene without fix dt/reset: never called."""
        return np.inf

    @inline
    def _copy3(dst, src):
        """dst[:] = src for (3, N) buffers, as a plain loop (no broadcasting checks to compile)."""
        for d in range(3):
            for i in range(src.shape[1]):
                dst[d, i] = src[d, i]

    def _relink(fn: Any, name: str | None = None, filename: str | None = None, **replace: Any) -> Any:
        """The Python function `fn` (or a jitted dispatcher's) with some of its globals replaced
        (the same code, closure and defaults), ready to be jitted again. `name` sets its
        __qualname__, which names numba's on-disk cache files (one index per scene kernel);
        `filename`: the file the code is attributed to, so that numba's on-disk cache of the result
        lives with (and is keyed by) that file instead of this one (numba keys a cached function by
        its file, name, code and closure, not by its globals)."""
        fn = getattr(fn, "py_func", fn)
        namespace = dict(fn.__globals__)
        namespace.update(replace)
        code = fn.__code__ if filename is None else fn.__code__.replace(co_filename=filename)
        out = types.FunctionType(code, namespace, fn.__name__, fn.__defaults__, fn.__closure__)
        out.__kwdefaults__ = fn.__kwdefaults__
        if name is not None:
            out.__qualname__ = name
        return out

    @dataclass(frozen=True)
    class ScenePieces:
        """The compiled pieces of one kind of scene (`pieces_for`): the soft-face dispatch, the
        region walls, the flow step and the block step linked to them, the generated `source`
        they come from, the file a kernel built on them is attributed to (the generated module
        of wall/lepton and wall/table forces, else None: this file) and a `fingerprint` of it all."""

        soft_face: Any
        region_walls: Any
        flow_step: Any
        block_step: Any
        source: str
        filename: str | None
        fingerprint: int
        sample_faces: Any = None  # the soft faces' outputs at a sample step (sampled chunks)
        sample_regions: Any = None  # and the wall/region fixes'
        vector_faces: Any = None  # wall/lepton faces with their parameters as an array (`_vector_faces`)

    def _scene_args(soft: Any, region: Any, flow: Any, extra: Any, tables: Any = False, stochastic: Any = False
                    ) -> tuple:
        return (tuple(sorted(set(soft))), tuple(sorted(set(region))), bool(flow), tuple(extra), bool(tables),
                bool(stochastic))

    def pieces_for(soft: tuple[tuple[int, int], ...], region: tuple[tuple[int, int], ...] = (), flow: bool = False,
                   extra: tuple[str, ...] = (), tables: bool = False, stochastic: bool = False) -> ScenePieces:
        """The compiled pieces of one kind of scene (`_pieces_for`), one per specialisation and
        process: what `kernel_for` and the fused pair chunks (engine/pair_compiled.py) link in."""
        return _pieces_for(*_scene_args(soft, region, flow, extra, tables, stochastic))

    @functools.lru_cache(maxsize=64)
    def _pieces_for(soft: tuple[tuple[int, int], ...], region: tuple[tuple[int, int], ...], flow: bool,
                    extra: tuple[str, ...], tables: bool = False, stochastic: bool = False) -> ScenePieces:
        """The face dispatch, region walls, flow step and block step of one kind of scene,
        specialised to what it has: the (style number, cut-off mode) pairs of its flat soft faces
        (`soft`) and of its wall/region fixes (`region`, none: no region code), a wall/flow fix
        (`flow`), generated forces (`extra`: wall/lepton, the source of
        force(r, p0, p1, p2, rc, radius) from WallStyle.generated_force, mode shift, styles
        len(COMPILED_STYLES) + j), wall/table faces (`tables`: one table loop, the tables are
        the kernel's data, style TABLE_STYLE) and a wall/reflect/stochastic fix (`stochastic`). Only
        those branches are generated and compiled. With `extra`
        the forces and the dispatch are written to a module file (styles.lepton.generated_module,
        `_chunk_module_source`) that a kernel built on them is attributed to, so numba caches it
        on disk. The pieces are this module's functions re-linked (the same code objects, new
        globals) to the scene's generated dispatch."""
        pairs = tuple(sorted(set(soft) | set(region)))
        # the name of each piece compiled on its own (`_renamed`): the scene's specialisation
        tag = hashlib.sha256(repr((soft, region, flow, extra, tables, stochastic)).encode()).hexdigest()[:15]
        base: dict[str, Any] = {"_face": _face, "_rface": _rface, "_eface": _eface, "_nan": math.nan,
                                **{f"_FORCE_{i}_{m}": _K_MODE_FORCES[(i, m)] for i, m in pairs},
                                **{f"_ENERGY_{i}_{m}": _K_MODE_ENERGIES[(i, m)] for i, m in soft
                                   if (i, m) in _K_MODE_ENERGIES}}
        filename = None
        if extra:
            source = _chunk_module_source(soft, extra)
            module = generated_module(source, "lepton_chunk")
            namespace = vars(module)
            namespace.update(base)
            inline_jit = njit(nogil=True, error_model="numpy", inline="always")
            for j in range(len(extra)):
                force = inline_jit(namespace[f"_LEPTON_{j}"])
                energy = namespace.get(f"_LEPTON_E_{j}")  # E(r) unshifted (samples in the kernel), if generated
                if energy is not None:
                    energy = inline_jit(energy)
                if extra[j].startswith(VECTOR_MARK):  # the registry's signature, the parameter array as p0
                    namespace[f"_VEXTRA_{j}"] = inline_jit(_vector_args(force))
                    if energy is not None:
                        namespace[f"_VEENERGY_{j}"] = inline_jit(_vector_args(energy))
                else:
                    namespace[f"_EXTRA_{j}"] = njit(**_SCENE)(
                        _renamed(cutoff_functions(force, force, SHIFT, _switch)[0], f"_extra_{j}_{tag}"))
                    if energy is not None:
                        namespace[f"_EEXTRA_{j}"] = njit(**_SCENE)(
                            _renamed(cutoff_functions(force, energy, SHIFT, _switch)[1], f"_eextra_{j}_{tag}"))
            filename = module.__file__
        else:
            namespace = base
            source = _dispatch_source(soft)
            exec(compile(source, "<wallbatch soft-face dispatch>", "exec"), namespace)  # noqa: S102 - generated here
        soft_face = njit(nogil=True, error_model="numpy", inline="always")(namespace["_soft_face"])
        vector = any(src.startswith(VECTOR_MARK) for src in extra)
        # the outputs of generated forces with a generated energy (wall/lepton; `_generated_force`)
        sampled_extra = tuple(j for j, src in enumerate(extra)
                              if not src.startswith(VECTOR_MARK) and "\ndef energy(" in src)
        osource = _outputs_source(soft, "face", sampled_extra)
        if vector:
            osource += _vector_outputs_source(extra)
        source += osource
        exec(compile(osource, "<wallbatch soft-face outputs dispatch>", "exec"), namespace)  # noqa: S102 - generated here
        face_out = njit(nogil=True, error_model="numpy", inline="always")(namespace["_face_out"])
        vector_out = _no_vector_out
        if vector:
            vector_out = njit(nogil=True, error_model="numpy", inline="always")(namespace["_vector_out"])
        sample_faces = njit(**_SCENE)(
            _relink(_sample_faces, name=f"_sample_faces_{tag}", _face_out=face_out, _vector_out=vector_out,
                    _K_VECTOR=vector, _table_out=_table_out if tables else _no_table_out))
        region_walls = _no_region_walls
        sample_regions = _no_sample_regions
        if region:
            namespace.update({f"_ENERGY_{i}_{m}": _K_MODE_ENERGIES[(i, m)] for i, m in region
                              if (i, m) in _K_MODE_ENERGIES})
            namespace["_rout"] = _rout
            rsource = _region_dispatch_source(region) + _outputs_source(region, "region")
            source += rsource
            exec(compile(rsource, "<wallbatch region dispatch>", "exec"), namespace)  # noqa: S102 - generated here
            region_force = njit(nogil=True, error_model="numpy", inline="always")(namespace["_region_force"])
            region_walls = njit(**_SCENE)(_relink(_region_walls, name=f"_region_walls_{tag}", _region_force=region_force))
            region_out = njit(nogil=True, error_model="numpy", inline="always")(namespace["_region_out"])
            sample_regions = njit(**_SCENE)(_relink(_sample_regions, name=f"_sample_regions_{tag}",
                                                    _region_out=region_out))
        flow_step = _no_flow_step
        if flow:
            from wallbatch.engine import flow_compiled  # lazy: scipy.special, only for flow walls

            flow_step = njit(**_SCENE)(_relink(_flow_step, flow_compiled=flow_compiled))
        vector_faces = _no_vector_faces
        if vector:
            vector_faces = njit(nogil=True, error_model="numpy", inline="always")(namespace["_vector_faces"])
        table_faces = _no_table_faces
        if tables:
            table_faces = _table_faces
            source += _TABLE_SOURCE
        stochastic_faces = _no_stochastic_faces
        if stochastic:
            stochastic_faces = _stochastic_faces
            source += "# wall/reflect/stochastic\n" + inspect.getsource(_st)
        block_step = njit(nogil=True, error_model="numpy", inline="always")(
            _relink(_block_step, _soft_face=soft_face, _region_walls=region_walls, _table_faces=table_faces,
                    _stochastic_faces=stochastic_faces, _vector_faces=vector_faces))
        return ScenePieces(soft_face, region_walls, flow_step, block_step, source, filename,
                           _fingerprint(pairs, flow, False, source), sample_faces, sample_regions, vector_faces)

    def kernel_for(soft: tuple[tuple[int, int], ...], region: tuple[tuple[int, int], ...] = (), flow: bool = False,
                   extra: tuple[str, ...] = (), parallel: bool = False, fixes: bool = True, dtr: bool = True,
                   tables: bool = False, stochastic: bool = False, reflect: bool = True, time: bool = True,
                   sampled: bool = True, two_d: bool = False, frozen: bool = False) -> Any:
        """The chunk kernel of one kind of scene (`_kernel_for`), one per specialisation and process;
        False leaves that code out: `fixes` (`fixes:`), `dtr` (fix dt/reset), `reflect`
        (wall/reflect), `time` (time-based runs, `FastPath.advance_to_time`), `sampled` (samples
        recorded in the kernel, `FastPath.advance_sampled`); `two_d`: the step integrates x and y
        only (`two_d_eligible`); `frozen`: some atoms are not integrated (`_K_FROZEN`)."""
        return _kernel_for(*_scene_args(soft, region, flow, extra, tables, stochastic), bool(parallel), bool(fixes),
                           bool(dtr), bool(reflect), bool(time), bool(sampled), bool(two_d), bool(frozen))

    @functools.lru_cache(maxsize=64)
    def _kernel_for(soft: tuple[tuple[int, int], ...], region: tuple[tuple[int, int], ...], flow: bool,
                    extra: tuple[str, ...], tables: bool, stochastic: bool, parallel: bool, fixes: bool = True,
                    dtr: bool = True, reflect: bool = True, time: bool = True, sampled: bool = True,
                    two_d: bool = False, frozen: bool = False) -> Any:
        """The chunk kernel of one kind of scene (`pieces_for`; `parallel`: compiled with numba
        parallel=True, reserved for a two-thread variant, not used by the engine yet): this
        module's chunk kernel re-linked to the scene's block and flow steps and to its
        KERNEL_FLAGS (what it leaves out), named `_run_chunk_<fingerprint>` so numba caches it on
        disk in its own index file (beside this file, or with `extra` beside the generated module
        it is attributed to: compiled once, loaded by later processes)."""
        p = _pieces_for(soft, region, flow, extra, tables, stochastic)
        flags = {"_K_REFLECT": reflect, "_K_STOCHASTIC": stochastic, "_K_TABLES": tables,
                 "_K_VECTOR": any(src.startswith(VECTOR_MARK) for src in extra), "_K_REGION": bool(region),
                 "_K_FIXES": fixes, "_K_DTR": dtr, "_K_FLOW": flow, "_K_TIME": time, "_K_SAMPLES": sampled,
                 "_K_2D": two_d, "_K_FROZEN": frozen}
        fp = _fingerprint(tuple(sorted(set(soft) | set(region))), flow, parallel,
                          p.source + "\n# " + ", ".join(f"{k} {v}" for k, v in flags.items()))
        gone: dict[str, Any] = {}
        links: dict[str, Any] = {}
        if not fixes:
            gone["_fix_post_force"] = _no_fix_post_force
            links = {"_fix_pre": _no_fix_pre, "_fix_end": _no_fix_end}
        if not dtr:
            gone["_dt_candidate"] = _no_dt_candidate
        block_step = njit(nogil=True, error_model="numpy", inline="always")(_relink(p.block_step, **gone, **flags))
        fn = _relink(_make_run_chunk(fp), name=f"_run_chunk_{fp:015x}", filename=p.filename,
                     _block_step=block_step, _flow_step=p.flow_step, _sample_faces=p.sample_faces,
                     _sample_regions=p.sample_regions, **links, **flags)
        dispatcher = njit(cache=True, nogil=True, error_model="numpy", parallel=parallel, no_cfunc_wrapper=True)(fn)
        return SceneKernel(dispatcher, frozenset(a for k, on in flags.items() if not on for a in FLAG_ARGS.get(k, ())))

    class SceneKernel:
        """A scene's chunk kernel (`kernel_for`): its numba dispatcher, called with the chunk
        kernel's full argument list (engine/threads.py splits that list by name: `py_func`) but
        with None in place of the arguments of the features the kernel leaves out (FLAG_ARGS), so
        its compiled entry point does not convert them. Every other attribute is the dispatcher's."""

        def __init__(self, dispatcher: Any, dropped: frozenset[str]):
            self.dispatcher = dispatcher
            self.dropped = dropped
            self._keep = tuple(name not in dropped for name in inspect.signature(dispatcher.py_func).parameters)

        def __call__(self, *args: Any) -> int:
            return self.dispatcher(*self._trim(args))

        def _trim(self, args: tuple) -> list:
            if len(args) != len(self._keep):
                raise TypeError(f"the chunk kernel takes {len(self._keep)} arguments, {len(args)} given")
            return [a if keep else None for keep, a in zip(self._keep, args)]

        def resolved(self, args: tuple) -> Callable[..., int]:
            """`backend.resolved` of this kernel (which asks this method): for many calls with
            arguments of the types of `args` (the full list), the compiled entry point of their
            overload (numba types ~60 arguments per call otherwise, ~1.5 ms), called as this kernel
            is; this kernel itself if it has none yet."""
            entry = backend.resolved(self.dispatcher, tuple(self._trim(args)))
            if entry is self.dispatcher:
                return self
            return lambda *a: entry(*self._trim(a))

        def __getattr__(self, name: str) -> Any:
            if name in ("dispatcher", "dropped", "_keep"):  # not set yet (copy, pickle)
                raise AttributeError(name)
            return getattr(self.dispatcher, name)


# ----------------------------------------------------------------------------- the Python side


def _chunk_module_source(soft: tuple[tuple[int, int], ...], extra: tuple[str, ...]) -> str:
    """The generated module of a scene kernel with generated forces (`pieces_for`): the forces
    `_LEPTON_j` (wall/lepton, wall/table) and the scene's soft-face dispatch with one more branch
    per force (calling `_EXTRA_j`, its cut-off wrapper). Its header names a digest of this file and
    the lepton helpers and the fingerprint of the scene's styles, so the file (named by a hash of
    its source) and numba's cache beside it change when any of them does."""
    forces = "".join(f"\n\n{src.replace('def kernel(', f'def _LEPTON_{j}(', 1).replace('def energy(', f'def _LEPTON_E_{j}(', 1)}"
                     for j, src in enumerate(extra))
    positional = tuple(j for j, src in enumerate(extra) if not src.startswith(VECTOR_MARK))
    body = HELPERS_IMPORT + forces + "\n\n" + _dispatch_source(soft, positional)
    if len(positional) < len(extra):
        body += "\n\n" + _vector_dispatch_source(extra)
    header = ('"""wall/lepton chunk kernel dispatch, generated by wallbatch.engine.compiled: do not edit."""\n'
              f"# key: compiled.py {_SOURCE_DIGEST}, styles {_fingerprint(soft, False, False, body):015x}\n")
    return header + body


# the wall/flow arguments of a chunk without flow walls (same types: one compiled signature)
_NO_FLOW = (np.zeros(3, np.int64), np.zeros(4), np.zeros(0), np.zeros(0, np.uint8), np.zeros(0, np.int64),
            np.zeros(0, np.int64), np.zeros(0), np.zeros(1), np.random.default_rng(0))
# fix langevin's generators (one per fix) of a chunk without one (the type of a chunk with one)
_NO_RNGS = (_NO_FLOW[-1],)


@dataclass
class ChunkPlan:
    """What the compiled path runs, built by the engine for each chunk (Engine.compiled_plan).

    * ``state``: the batch (positions, velocities, forces, masses, radii, steps, time, variables);
    * ``soft``: flat soft wall kernels, each with its registry entry (``kernel.style``), group
      and per-face values (``kernel.faces``: coord and parameters, (C,) arrays or variable names);
    * ``reflect``: wall/reflect kernels (faces, frame, previous positions, statistics);
    * ``dt_reset`` and ``dt_reset_params`` (C, 4): xmax, emax, tmin, tmax (NaN: no bound);
    * ``region``: wall/region kernels (and wall/region/ees ones, which `eligible` refuses);
    * ``flow``: the wall/flow kernels (`eligible` takes at most one, without dt/reset);
    * ``others``: what else the scene has (pair, ellipsoids): the compiled path runs only
      plans where this is empty;
    * ``ensemble``: the `fixes:` of the batch (engine.ensemble.Ensemble) or None; `fixes_eligible`
      says which the kernel runs (nve on every atom, nvt and langevin fixes, temp/berendsen,
      temp/rescale, enforce2d; thermostats not with dt/reset, wall/flow or runs to a time);
    * ``compute_outputs()``: the NumPy forces and outputs at the current positions,
      ``finish_step(out, sample)``: drop failed cases and sample, ``advance_numpy(n, sample)``: the
      NumPy loop (for the rest of a split chunk).
    """

    state: BatchState
    soft: tuple[SoftWallKernel, ...]
    reflect: tuple[ReflectKernel, ...]
    dt_reset: DtResetSpec | None
    dt_reset_params: np.ndarray | None
    others: tuple[str, ...]
    compute_outputs: Callable[[], dict]
    finish_step: Callable[[dict, bool], None]
    advance_numpy: Callable[[int, bool], None]
    region: tuple[RegionWallKernel, ...] = ()
    flow: tuple = ()  # flow.FlowKernel: at most one, without dt/reset (`eligible`)
    ensemble: Any = None  # ensemble.Ensemble (fixes: nve on all, thermostats, enforce2d) or None
    # Engine.record's arguments -> the samples of a sampled chunk appended (Engine.record_block);
    # None: the engine takes samples one at a time only
    record_samples: Callable[..., None] | None = None
    outputs: tuple[str, ...] = ()  # the thermo outputs (press needs the virial)
    samples: Callable[[], int] | None = None  # the run's samples after step 0 (None: not known)


def _face_styles(w: SoftWallKernel) -> list[WallStyle]:
    """The style of each face of a soft kernel (wall/lepton and wall/table: one per face)."""
    return list(w.face_styles) if isinstance(w, CustomWallKernel) else [w.style] * len(w.faces)


def _generated_force(style: WallStyle) -> str | None:
    """The generated source of a face's force: wall/lepton with at most 3 parameters
    (WallStyle.generated_force), or with more, its parameters as an array
    (WallStyle.generated_vector_force, marked by a first line VECTOR_MARK); else None. Followed by
    the source of its unshifted energy `energy(...)` in the same form (WallStyle.generated_energy)
    when the style has one: sampled chunks report E(r) - E(rc) from it."""
    src = style.generated_force()
    if src is None:
        vec = style.generated_vector_force()
        src = None if vec is None else VECTOR_MARK + vec
    energy = style.generated_energy() if src is not None else None
    if energy is not None:
        src += "\n\n" + energy
    return src


def face_style_id(style: WallStyle, extra: tuple[str, ...]) -> int:
    """A soft face's style number in a kernel's sf_meta: the registry's compiled style's, TABLE_STYLE
    (wall/table), len(COMPILED_STYLES) + j for generated force j of `extra` (`_lepton_extra`), or
    -2 - j for one that takes its parameters as an array."""
    if STYLE_IDS.get(style.name) is not None and COMPILED_STYLES[STYLE_IDS[style.name]] == style:
        return STYLE_IDS[style.name]
    if _is_table(style):
        return TABLE_STYLE
    src = _generated_force(style)
    if src.startswith(VECTOR_MARK):  # parameters as an array: style -2 - j
        return -2 - extra.index(src)
    return len(COMPILED_STYLES) + extra.index(src)


def _lepton_rows(soft_faces: list, C: int) -> np.ndarray:
    """lp_val (C, faces, P): the parameter values of each wall/lepton face whose force takes them
    as an array, in the style's order (rows of other faces: zeros; P >= 1)."""
    P = max([1] + [len(st.args_names) for _, st, _ in soft_faces if st.generated_vector_force() is not None])
    out = np.zeros((C, len(soft_faces), P))
    for k, (_, st, face) in enumerate(soft_faces):
        if st.generated_vector_force() is not None:
            for j, key in enumerate(st.args_names):
                out[:, k, j] = np.broadcast_to(np.asarray(face.params[key], float), (C,))
    return out


def _plain_reflect(plan: ChunkPlan) -> list[ReflectKernel]:
    """The plan's wall/reflect fixes (its `reflect` list without wall/reflect/stochastic)."""
    return [w for w in plan.reflect if type(w) is ReflectKernel]


def _reflect_arrays(plan: ChunkPlan, group: Callable[[np.ndarray, bool], int]
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, bool]:
    """The kernel's arrays of the plan's wall/reflect faces (`_plain_reflect`): rf_meta (K, 4) =
    dim, side, frame wall (1) or box (0), group row; rf_prev (C, K): each face's coord at the last
    step (its velocity is the change over a step); rf_stat (C, K, 2): reflections and impulse so
    far (with reflect statistics, else zeros); and whether statistics are kept."""
    reflect = _plain_reflect(plan)
    C = plan.state.ncases
    meta = np.array([[face.dim, face.side, 1 if w.frame == "wall" else 0, group(w.group, w.all_atoms)]
                     for w in reflect for face in w.faces], np.int64).reshape(-1, 4)
    stats = bool(reflect) and reflect[0].stats
    prev = np.ascontiguousarray(np.stack([p for w in reflect for p in w.previous], axis=1),
                                dtype=float) if reflect else np.zeros((C, 0))
    prev = np.broadcast_to(prev, (C, prev.shape[1])).copy()
    if stats:
        stat = np.stack([np.stack([w.count[:, k], w.impulse[:, k]], axis=1)
                         for w in reflect for k in range(len(w.faces))], axis=1)
    else:
        stat = np.zeros((C, meta.shape[0], 2))
    return meta, prev, np.ascontiguousarray(stat), stats


def _reflect_store(plan: ChunkPlan, rf_prev: np.ndarray, rf_stat: np.ndarray, st_stat: np.ndarray) -> None:
    """Write a successful chunk's wall/reflect state back to the fixes (`_reflect_arrays`' rows),
    and wall/reflect/stochastic's counters (`_stochastic_arrays`' st_stat)."""
    k0 = 0
    for sk in _stochastic_kernels(plan):  # each fix's faces, in fix order
        K = len(sk.faces)
        if sk.stats:
            sk.count[...] = st_stat[:, k0:k0 + K, 0]
            sk.impulse[...] = st_stat[:, k0:k0 + K, 1]
        k0 += K
    reflect = _plain_reflect(plan)
    stats = bool(reflect) and reflect[0].stats
    k = 0
    for w in reflect:
        for j, face in enumerate(w.faces):
            # as ReflectKernel.apply: a constant wall keeps its coord array, a variable one a copy
            w.previous[j] = face.coord if isinstance(face.coord, np.ndarray) else rf_prev[:, k].copy()
            if stats:
                w.count[:, j] = rf_stat[:, k, 0]
                w.impulse[:, j] = rf_stat[:, k, 1]
            k += 1


def _stochastic_kernel(plan: ChunkPlan) -> StochasticKernel | None:
    """The plan's first wall/reflect/stochastic fix, None without one (`eligible`: they come
    after the wall/reflect ones)."""
    return next((w for w in plan.reflect if isinstance(w, StochasticKernel)), None)


def _stochastic_kernels(plan: ChunkPlan) -> list[StochasticKernel]:
    """The plan's wall/reflect/stochastic fixes, in fix order."""
    return [w for w in plan.reflect if isinstance(w, StochasticKernel)]


def _stochastic_rngs(plan: ChunkPlan, c: int) -> tuple:
    """Case c's generators of the wall/reflect/stochastic fixes, in fix order (the kernel's
    st_rng; a placeholder of the same type without one)."""
    return tuple(w.rngs[c] for w in _stochastic_kernels(plan)) or _NO_RNGS


def _chunk_generators(plan: ChunkPlan, fx_rngs: list[tuple]) -> list[Any]:
    """Every generator a chunk's kernel draws from (fix langevin's per case and fix, wall/flow's,
    wall/reflect/stochastic's per case and fix), so that a chunk handed back to NumPy can rewind
    them; empty: the kernel draws nothing."""
    flow = list(plan.flow[0].rngs) if plan.flow else []
    return [r for rs in fx_rngs for r in rs] + flow + [r for w in _stochastic_kernels(plan) for r in w.rngs]


def _stochastic_eligible(plan: ChunkPlan) -> bool:
    """wall/reflect/stochastic in the kernel: such fixes after every wall/reflect fix (the
    kernel reflects in that order), constant face values, no dt/reset (its windows may be
    undone, the draws cannot)."""
    kinds = [isinstance(w, StochasticKernel) for w in plan.reflect]
    if not any(kinds):
        return True
    first = kinds.index(True)
    if not all(kinds[first:]) or plan.dt_reset is not None:
        return False
    fixes = _stochastic_kernels(plan)
    return all(w.rstyle in RSTYLES and all(isinstance(v, np.ndarray) for face in w.faces
                                           for v in (face.coord, *face.params.values())) for w in fixes)


def _stochastic_arrays(plan: ChunkPlan, group: Callable[[np.ndarray, bool], int]) -> tuple:
    """The kernel's wall/reflect/stochastic arguments (see `_stochastic_faces`): st_meta, st_val,
    st_stat (a copy of the counters), st_flag; empty without such a fix."""
    s = plan.state
    fixes = _stochastic_kernels(plan)
    if not fixes:
        return np.zeros((0, 5), np.int64), np.zeros((s.ncases, 0, 9)), np.zeros((s.ncases, 0, 2)), np.zeros(1, np.int64)
    faces = [(q, w, f) for q, w in enumerate(fixes) for f in w.faces]  # fix after fix
    K = len(faces)
    meta = np.array([[f.dim, f.side, group(w.group, w.all_atoms), RSTYLES.index(w.rstyle), q] for q, w, f in faces],
                    np.int64).reshape(K, 5)
    val = np.zeros((s.ncases, K, 9))
    for k, (_, _, f) in enumerate(faces):
        val[:, k, 0] = f.coord
        for j, key in enumerate(("temp", "vx", "vy", "vz", "ax", "ay", "az")):
            val[:, k, 1 + j] = f.params[key]
        val[:, k, 8] = s.units.boltz
    stats = fixes[0].stats  # (the batch's outputs set it for every reflect fix: walls.build_kernels)
    stat = (np.concatenate([np.stack([w.count, w.impulse], axis=2) for w in fixes], axis=1).astype(float) if stats
            else np.zeros((s.ncases, K, 2)))
    return meta, val, np.ascontiguousarray(stat), np.array([1 if stats else 0], np.int64)


def _is_table(style: WallStyle) -> bool:
    """A wall/table face: the kernel runs its table as data (style TABLE_STYLE), no compile of its own."""
    return isinstance(style, TableWallStyle) and style.table is not None


def _tables(soft_faces: list) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The kernel's tb arrays for the soft faces [(kernel, style, face), ...] in sf_meta order:
    tb_meta (K, 3) int = offset into tb_data, N, linear (1) or spline (0); tb_par (K, 3) = lo,
    1/delta, delta^2/6; tb_data: the rows (WallTable.kernel_rows) of each table once. Rows of
    other faces are zeros."""
    meta = np.zeros((len(soft_faces), 3), np.int64)
    par = np.zeros((len(soft_faces), 3))
    chunks: list[np.ndarray] = []
    where: dict[int, int] = {}
    size = 0
    for k, (_, st, _) in enumerate(soft_faces):
        if not _is_table(st):
            continue
        t = st.table
        if id(t) not in where:
            where[id(t)] = size
            chunks.append(t.kernel_rows().reshape(-1))
            size += chunks[-1].size
        meta[k] = (where[id(t)], len(t.r), 1 if t.tabstyle == "linear" else 0)
        par[k] = (t.lo, t.invdelta, t.deltasq6)
    return meta, par, (np.concatenate(chunks) if chunks else np.zeros(0))


# wall/table faces run in the built-in scene kernel (their tables are its data): always eligible.
# wall/lepton faces run in the scene's chunk kernel with the batch's expressions (`kernel_for`):
# compiled once (~20-30 s), then cached on disk and loaded by later processes (~0.5 s, like the
# built-in kernel). WALLBATCH_LEPTON_COMPILED=always|never|auto; auto (the default) runs the batch
# compiled when that is expected to take less time in this run than the NumPy path
# (`lepton_seconds`: a cost model from the batch's steps, atoms and samples, measured on a 2-core
# machine with benchmarks/lepton_cost.py): NumPy LEPTON_NUMPY_STEP_S per step plus
# LEPTON_NUMPY_ATOM_STEP_S per atom-step, and per sample LEPTON_NUMPY_SAMPLE_S plus
# LEPTON_NUMPY_SAMPLE_ATOM_S per atom; compiled LEPTON_COMPILED_ATOM_STEP_S per atom-step (samples
# recorded in the kernel: next to nothing) plus nothing when this process has run the kernel
# already, LEPTON_LOAD_S when it is on disk, or LEPTON_COMPILE_S when it must be compiled first.
LEPTON_NUMPY_STEP_S = 0.09e-3
LEPTON_NUMPY_ATOM_STEP_S = 14e-9
LEPTON_NUMPY_SAMPLE_S = 0.22e-3
LEPTON_NUMPY_SAMPLE_ATOM_S = 3e-9
LEPTON_COMPILED_ATOM_STEP_S = 6e-9
LEPTON_LOAD_S = 0.5
LEPTON_COMPILE_S = 30.0
# With pair lj/cut (the fused pair chunk of engine/pair_compiled.py, its own kernel: `kind` "pair")
# both paths run the same compiled pair forces, so the model counts what differs: the per-step
# path's NumPy walls and integration less the fused chunk's, LEPTON_PAIR_NUMPY_STEP_S per step plus
# LEPTON_PAIR_NUMPY_ATOM_STEP_S per atom-step (`benchmarks/lepton_cost.py --pair`, AVX-512 host:
# 0.134 ms + 24 ns; the fused chunk 2.2x faster a step at N = 1000, 1.2x at N = 16000); its first
# compile took 8 s there (LEPTON_PAIR_COMPILE_S errs long, for slower hosts).
LEPTON_PAIR_NUMPY_STEP_S = 0.13e-3
LEPTON_PAIR_NUMPY_ATOM_STEP_S = 24e-9
LEPTON_PAIR_COMPILED_ATOM_STEP_S = 0.0
LEPTON_PAIR_COMPILE_S = 15.0
_LEPTON_RUN: set[tuple[str, tuple[str, ...]]] = set()  # the generated kernels (kind, `extra`) this process has run


def _lepton_extra(plan: ChunkPlan) -> tuple[str, ...]:
    """The generated forces of the plan's wall/lepton faces, each once, in face order (the
    numbering of `kernel_for`'s `extra`)."""
    out: dict[str, None] = {}
    for w in plan.soft:
        for st in _face_styles(w):
            if not (STYLE_IDS.get(st.name) is not None and COMPILED_STYLES[STYLE_IDS[st.name]] == st):
                src = _generated_force(st)
                if src is not None:
                    out.setdefault(src)
    return tuple(out)


def _compiled_marker(extra: tuple[str, ...], kind: str = "chunk") -> Path:
    """A file beside the generated module, written once its chunk kernel (`kind` "chunk"; "pair":
    the fused pair chunk's) has been compiled (and so cached on disk by numba)."""
    forces = "".join(extra)
    path = generated_path(f"# compiled.py {_SOURCE_DIGEST}\n{forces}", "lepton_chunk")
    return path.with_suffix(".compiled" if kind == "chunk" else f".{kind}-compiled")


@functools.lru_cache(maxsize=64)
def _mark_compiled(extra: tuple[str, ...], kind: str = "chunk") -> None:
    _LEPTON_RUN.add((kind, extra))
    marker = _compiled_marker(extra, kind)
    if not marker.exists():
        marker.write_text("")


def lepton_seconds(steps: float, atoms: float, samples: float, kernel: str, kind: str = "chunk"
                   ) -> tuple[float, float]:
    """(NumPy, compiled) seconds expected for a batch of `atoms` atoms over all its cases run
    `steps` steps with `samples` samples, the compiled path's kernel being "run" (already run in
    this process), "cached" (on disk) or "new" (compiled first): the cost model above (`kind`
    "pair": with pair lj/cut, what differs between the paths)."""
    if kind == "pair":
        step_s, atom_s, compiled_atom_s, compile_s = (LEPTON_PAIR_NUMPY_STEP_S, LEPTON_PAIR_NUMPY_ATOM_STEP_S,
                                                      LEPTON_PAIR_COMPILED_ATOM_STEP_S, LEPTON_PAIR_COMPILE_S)
    else:
        step_s, atom_s, compiled_atom_s, compile_s = (LEPTON_NUMPY_STEP_S, LEPTON_NUMPY_ATOM_STEP_S,
                                                      LEPTON_COMPILED_ATOM_STEP_S, LEPTON_COMPILE_S)
    numpy_s = (steps * (step_s + atom_s * atoms)
               + samples * (LEPTON_NUMPY_SAMPLE_S + LEPTON_NUMPY_SAMPLE_ATOM_S * atoms))
    start = {"run": 0.0, "cached": LEPTON_LOAD_S, "new": compile_s}[kernel]
    return numpy_s, start + steps * atoms * compiled_atom_s


def lepton_compiled_wanted(state: BatchState, extra: tuple[str, ...] = (), samples: Callable[[], int] | None = None,
                           kind: str = "chunk") -> bool:
    """Whether wall/lepton faces (generated forces `extra`) run on the compiled path for this batch
    (see above; `kind` "pair": in the fused pair chunk): decided once per batch from its whole run
    (`samples()`: its samples after step 0; None: counted as none) and kept on the state, so every
    chunk of the run gets the same answer."""
    mode = os.environ.get("WALLBATCH_LEPTON_COMPILED", "auto").strip().lower()
    if mode in ("always", "1", "yes"):
        return True
    if mode in ("never", "0", "no"):
        return False
    chosen = state.__dict__.setdefault("_lepton_compiled", {})
    if (kind, extra) not in chosen:
        # the batch's whole run, not what is left of it: the choice must not flip to NumPy halfway
        steps = float(np.max(np.maximum(state.end_step, 0)))
        kernel = "run" if (kind, extra) in _LEPTON_RUN else "cached" if _compiled_marker(extra, kind).exists() \
            else "new"
        numpy_s, compiled_s = lepton_seconds(steps, float(state.x.shape[0] * state.x.shape[1]),
                                             float(samples()) if samples is not None else 0.0, kernel, kind)
        chosen[(kind, extra)] = compiled_s < numpy_s
    return chosen[(kind, extra)]


def _compiled_face(w: SoftWallKernel, style: WallStyle) -> bool:
    if STYLE_IDS.get(style.name) is not None and COMPILED_STYLES[STYLE_IDS[style.name]] == style:
        return w.cutoff.mode_id in _modes(style)
    if _is_table(style):
        return w.cutoff.mode_id == SHIFT
    return _generated_force(style) is not None and w.cutoff.mode_id == SHIFT


def eligible(plan: ChunkPlan, kind: str = "chunk") -> bool:
    """Whitelist: flat soft walls of compiled styles, wall/reflect (lab or wall frame), wall/region
    with compiled styles and constant parameters, one wall/flow (not with dt/reset), dt/reset,
    variables; nothing else in the scene (`fixes_eligible`; `kind`: the kernel
    whose wall/lepton policy applies, `lepton_compiled_wanted`)."""
    if plan.others:
        return False
    if any(type(w) not in (SoftWallKernel, CustomWallKernel) or
           not all(_compiled_face(w, st) for st in _face_styles(w)) for w in plan.soft):
        return False
    extra = _lepton_extra(plan)
    if extra and not lepton_compiled_wanted(plan.state, extra, plan.samples, kind):
        return False
    if any(not region_eligible(w) for w in plan.region):
        return False
    if len(plan.flow) > 1 or (plan.flow and plan.dt_reset is not None):
        return False
    if not fixes_eligible(plan):
        return False
    if not _stochastic_eligible(plan):
        return False
    return all(w.frame in ("lab", "wall") for w in _plain_reflect(plan))


def _thermostats(ensemble: Any) -> bool:
    """True when the batch has a fix that couples its atoms every step (not only enforce2d)."""
    return ensemble is not None and any(f.style in FIX_KINDS and f.style != "enforce2d" for f in ensemble.fixes)


def two_d_eligible(plan: ChunkPlan) -> bool:
    """Whether the chunk's kernel may integrate x and y only (`_K_2D`) and give the bits of the
    three-dimensional step: a 2-D scene with fix enforce2d on every atom (it zeroes f_z and v_z
    after the forces, every step), nothing that draws z velocities (wall/flow,
    wall/reflect/stochastic) or reflects along z, and now v_z = f_z = +0.0 for every atom (as
    enforce2d's setup leaves them), no z = -0.0 and z inside a periodic box: the step's updates
    of z are then the identity, bit for bit."""
    ens = plan.ensemble
    if ens is None or ens.dimension != 2 or not any(f.all for f in ens.enforce2d):
        return False
    if plan.flow or _stochastic_kernel(plan) is not None:
        return False
    if any(face.dim == 2 for w in _plain_reflect(plan) for face in w.faces):
        return False
    s = plan.state
    xz = s.x[..., 2]
    # +0.0 is the one double whose bits are all 0; -0.0 the one with only the sign bit
    if np.any(s.v[..., 2].view(np.int64)) or np.any(s.f[..., 2].view(np.int64)):
        return False
    if np.any(xz.view(np.int64) == np.iinfo(np.int64).min):
        return False
    if 2 in s.periodic and (np.any(xz < s.box_lo[2]) or np.any(xz >= s.box_hi[2])):
        return False
    return True


def fixes_eligible(plan: ChunkPlan) -> bool:
    """The batch's `fixes:` the kernel runs: nve or nvt on every atom or on some (the others stay
    where they are: frozen atoms, fx_int[2], `_K_FROZEN`), any number of nvt and langevin fixes,
    temp/berendsen, temp/rescale, enforce2d; with dt/reset or wall/flow too (Engine.step's
    end_of_step order: the thermostats, the flow walls, dt/reset)."""
    ens = plan.ensemble
    if ens is None:
        return True
    styles = [f.style for f in ens.fixes]
    if any(st not in FIX_KINDS and st != "nve" for st in styles):
        return False
    return True


def _fix_arrays(plan: ChunkPlan, group: Callable[[np.ndarray, bool], int]) -> tuple[tuple, list[Any], list[Any]]:
    """The kernel's `fx` tuple for the batch's fixes (see _fix_pre), the fixes in its rows, and
    each case's tuple of generators, one per langevin fix in fix order ([] without one). The chain
    arrays are copies: the caller keeps them only when the chunk succeeds."""
    s = plan.state
    C, N = s.ncases, s.x.shape[1]
    ens = plan.ensemble
    fixes = [f for f in ens.fixes if f.style in FIX_KINDS] if ens is not None else []
    K = len(fixes)
    meta = np.zeros((K, 8), np.int64)
    val = np.zeros((C, K, 6))
    acc = np.zeros((C, K, 4))
    langevin = [f for f in fixes if f.style == "langevin"]
    nvt = [f for f in fixes if f.style == "nvt"]
    offsets = np.cumsum([0] + [f.chain.eta.shape[1] for f in nvt])  # each chain's first column
    for k, f in enumerate(fixes):
        j = langevin.index(f) if f.style == "langevin" else nvt.index(f) if f.style == "nvt" else -1
        chain_at = (offsets[j], f.chain.eta.shape[1], f.chain.tloop) if f.style == "nvt" else (0, 0, 1)
        meta[k] = (FIX_KINDS[f.style], group(f.group, f.all), f.every, (1 if f.zero else 0) | (2 if f.tally else 0),
                   j, *chain_at)
        for j, name in enumerate(("t_start", "t_stop", "damp", "window", "fraction")):
            val[:, k, j] = getattr(f, name)
        val[:, k, 5] = float(f.dof)
        acc[:, k, 0], acc[:, k, 1], acc[:, k, 2], acc[:, k, 3] = f.removed, f.work, f.power, f.last_dt
    rngs = [tuple(f.rngs[c] for f in langevin) for c in range(C)] if langevin else []
    if nvt:  # the chains side by side (copies), their per-case values a column each
        chains = [f.chain for f in nvt]
        chain = tuple(np.concatenate([np.asarray(getattr(ch, name), float) for ch in chains], axis=1)
                      for name in ("eta", "eta_dot", "eta_dotdot", "eta_mass"))
        per_case = tuple(np.stack([np.broadcast_to(np.asarray(getattr(ch, name), float), (C,)) for ch in chains],
                                  axis=1) for name in ("t_current", "t_target", "t_freq", "drag"))
    else:
        chain = (np.zeros((C, 1)), np.zeros((C, 2)), np.zeros((C, 1)), np.zeros((C, 1)))
        per_case = tuple(np.zeros((C, 1)) for _ in range(4))
    u = s.units
    run_time = np.nan if s.run_time is None else float(s.run_time)  # (a run to a time: the ramp follows the time)
    # the integrated atoms' group row (Ensemble.moving; -1: every atom): the frozen atoms' mask
    moving = -1 if ens is None or ens.moving is None else group(ens.moving, False)
    # fx_int: 0 (the pair chunks' sample step on threads sets 1 in its copy: its tail on all atoms ends the
    # fixes' step too), the run's end step, the moving row
    fx = (meta, val, acc, *chain, *per_case, np.array([0, s.end_step, moving], np.int64),
          np.array([float(u.boltz), float(u.ftm2v), float(u.mvv2e), run_time]), np.zeros((C, N, 3 * len(langevin))))
    return fx, fixes, rngs


def _fix_slice(fx: tuple, c: slice) -> tuple:
    """The `fx` arrays of cases c (views; meta, fx_int and fx_f are shared)."""
    return tuple(a if j in (0, 11, 12) else a[c] for j, a in enumerate(fx))


def _fix_store(fx: tuple, fixes: list[Any], plan: ChunkPlan) -> None:
    """Write a successful chunk's fix state back to the Ensemble (ecouple's terms, the chain)."""
    acc = fx[2]
    for k, f in enumerate(fixes):
        f.removed, f.work, f.power, f.last_dt = (acc[:, k, j].copy() for j in range(4))
        if f.style == "nvt":  # its columns of the chains (see _fix_arrays)
            ch, (j, o, m) = f.chain, (int(v) for v in fx[0][k, 4:7])
            ch.eta, ch.eta_dotdot, ch.eta_mass = (fx[i][:, o:o + m].copy() for i in (3, 5, 6))
            ch.eta_dot = fx[4][:, o + j:o + j + m + 1].copy()
            ch.t_current, ch.t_target = fx[7][:, j].copy(), fx[8][:, j].copy()
        if f.style == "langevin":  # its columns of the last step's Langevin forces (C, N, 3 L)
            l = int(fx[0][k, 4])
            f.force = np.ascontiguousarray(fx[13][:, :, 3 * l:3 * l + 3])


def region_eligible(w: Any) -> bool:
    """A wall/region fix the kernel runs: a compiled soft style (not wall/region/ees), a region
    of REGION_KINDS, constant parameters."""
    if type(w) is not RegionWallKernel or w.style is None or STYLE_IDS.get(w.style.name) is None:
        return False
    if COMPILED_STYLES[STYLE_IDS[w.style.name]] != w.style or w.cutoff.mode_id not in _modes(w.style):
        return False
    if (w.geom.style, w.geom.side) not in REGION_KINDS or any(isinstance(v, str) for v in w.params.values()):
        return False
    return True


_ANNOUNCED: set[str] = set()


def _cached_on_disk(kernel: Any) -> bool:
    """Whether numba's on-disk cache holds a fresh build of `kernel` (its index file exists, for
    this numba and this version of the source). False when that cannot be told."""
    try:
        return bool(kernel._cache._cache_file._load_index())
    except Exception:  # noqa: BLE001 - numba internals: unknown means "say it compiles"
        return False


def cache_dir(kernel: Any = None) -> str:
    """Where numba keeps the compiled kernels: NUMBA_CACHE_DIR if set, else beside this file (or a
    user cache directory when that is not writable)."""
    try:
        return str(kernel._cache._cache_path)
    except Exception:  # noqa: BLE001
        return os.environ.get("NUMBA_CACHE_DIR") or os.path.join(os.path.dirname(__file__), "__pycache__")


def announce_compile(kernel: Any, seconds: float = COMPILE_SECONDS) -> None:
    """Say on stderr, once per process and kernel, that a scene kernel is being compiled (it is
    not in the on-disk cache yet): the run is silent for a few seconds otherwise."""
    import sys

    name = kernel.py_func.__qualname__
    if name in _ANNOUNCED or (kernel._cache.__class__.__name__ != "NullCache" and _cached_on_disk(kernel)):
        return
    _ANNOUNCED.add(name)
    where = f", cached in {cache_dir(kernel)}" if kernel._cache.__class__.__name__ != "NullCache" else ""
    print(f"wallbatch: compiling kernels for this scene, once, ~{seconds:g} s{where}", file=sys.stderr,
          flush=True)


class KernelPath:
    """What the compiled paths of an Engine share (FastPath, pair_compiled.PairChunks,
    asphere_compiled.AspherePath): the length of one kernel call, and the steps run before a
    run of samples recorded in the kernel."""

    step_cost = 1  # one atom-step of this path's kernel, in flat-wall atom-steps (CALL_WORK)
    least_steps = FLAT_MIN_CALL_STEPS  # the fewest steps of a call (a call's set-up copies every atom)
    plan_source: Callable[[], ChunkPlan]

    def call_steps(self) -> int:
        """The most steps one kernel call runs (`call_steps` of the current plan)."""
        return call_steps(self.plan_source(), self.step_cost, self.least_steps)

    def in_calls(self, chunk: Callable[[int, bool], bool], nsteps: int, sample: bool) -> bool:
        """`chunk(nsteps, sample)` (a kernel call of this path), or, for more than `call_steps`
        steps, several of them (`split_steps`)."""
        most = self.call_steps()
        if nsteps > most:
            return split_steps(chunk, self.plan_source(), nsteps, sample, most)
        return chunk(nsteps, sample)

    def one_call(self, at: np.ndarray) -> np.ndarray:
        """The samples `at` (steps from now, increasing) that one kernel call records: those
        within `call_steps` steps, the first one at least."""
        return at[at <= max(int(at[0]), self.call_steps())]

    def samples_in_kernel(self, at: np.ndarray) -> bool:
        raise NotImplementedError

    def lead_steps(self, at: np.ndarray) -> int:
        """Steps Engine.run runs first, without a sample (Engine.advance: calls of at most
        `call_steps` steps), before the samples `at` (steps from now, increasing) go to
        `advance_sampled`: the first sample's steps beyond one call, so that a far sample (a run
        sampled at its end only) is not one long call. The bits are those of one call."""
        at = np.asarray(at, np.int64)
        if at.size == 0 or not self.samples_in_kernel(at):
            return 0
        return max(0, int(at[0]) - self.call_steps())


class FastPath(KernelPath):
    """The compiled path of one Engine (see module docstring): `plan_source()` gives the plan of
    the next chunk."""

    def __init__(self, plan_source: Callable[[], ChunkPlan]):
        self.plan_source = plan_source
        self.compiled_chunks = 0  # chunks run compiled (tests and benchmarks read these)
        self.sampled_calls = 0  # kernel calls that recorded samples themselves (advance_sampled)
        self.kernel: Any = None  # the scene kernel of the last chunk (kernel_for)
        self.kernel_names: set[str] = set()  # every scene kernel this path ran (each is a compile)
        self.fallbacks = 0  # chunks handed back to NumPy
        self._spare: tuple[np.ndarray, ...] = ()  # output buffers for x, v, f (swapped with the state's)
        self._sampled_refused = False  # the scene's samples are not recorded in the kernel (sampled_eligible)
        self._sampled_count = 0  # samples of the last sampled chunk
        self._sampled_progress = 0  # after trouble in a sampled chunk: the samples completed before it
        self._numpy_next = False  # the next chunk has the trouble a sampled chunk met: straight to NumPy
        self._sampled_trouble = False  # the last sampled chunk met trouble in the kernel

    # -- packing ---------------------------------------------------------------------------

    @staticmethod
    def _values(plan: ChunkPlan, nsteps: int, varying: bool) -> tuple[np.ndarray, np.ndarray] | None:
        """Per-step wall values: soft (C, S', F, 6) = coord, p0, p1, p2, cutoff, switch_on and reflect
        coords (C, S', R); S' = nsteps when a value varies with time, else 1. None: fall back."""
        s = plan.state
        C = s.ncases
        nval = nsteps if varying else 1
        cache: dict[str, np.ndarray] = {}
        ctx = None

        def var(name: str) -> np.ndarray:
            nonlocal ctx
            if name not in cache:
                if ctx is None:
                    ctx = s.context(s.step[None, :] + np.arange(1, nval + 1, dtype=np.int64)[:, None])
                cache[name] = np.broadcast_to(np.asarray(s.variables.evaluate(name, ctx), float), (nval, C))
            return cache[name]

        def value(v: Any) -> np.ndarray:
            return np.broadcast_to(v, (nval, C)) if isinstance(v, np.ndarray) else var(v)

        soft_faces = [(st, face) for w in plan.soft for st, face in zip(_face_styles(w), w.faces)]
        sf = np.zeros((C, nval, len(soft_faces), 6))
        rf = np.zeros((C, nval, sum(len(w.faces) for w in _plain_reflect(plan))))
        with np.errstate(all="ignore"):
            try:
                for k, (style, face) in enumerate(soft_faces):
                    coord = face.coord if isinstance(face.coord, np.ndarray) else var(face.coord) * face.scale
                    sf[:, :, k, 0] = np.broadcast_to(coord, (nval, C)).T
                    for j, key in enumerate(style.args_names[:3]):  # more (wall/lepton): `_lepton_rows`
                        if key in face.params:
                            val = value(face.params[key])
                            low = style.param(key).min
                            if isinstance(face.params[key], str) and low is not None and np.any(val < low):
                                return None  # the NumPy path fails these cases with its message
                            sf[:, :, k, 1 + j] = val.T
                    sf[:, :, k, 4] = value(face.params["cutoff"]).T
                    if "switch_on" in face.params:  # cutoff_mode smooth
                        sf[:, :, k, 5] = value(face.params["switch_on"]).T
                k = 0
                for w in _plain_reflect(plan):
                    for face in w.faces:
                        coord = face.coord if isinstance(face.coord, np.ndarray) else var(face.coord) * face.scale
                        rf[:, :, k] = np.broadcast_to(coord, (nval, C)).T
                        k += 1
            except VariableError:
                return None
        return sf, rf

    @staticmethod
    def value_steps(plan: ChunkPlan) -> int:
        """The most steps of per-step wall values (`_values`: 6 doubles per soft or reflect face,
        step and case) a chunk holds within VALUE_BUDGET; longer chunks are split."""
        per_step = 6 * max(1, sum(len(w.faces) for w in plan.soft + plan.reflect)) * max(1, plan.state.ncases)
        return max(1, VALUE_BUDGET // per_step)

    @staticmethod
    def sample_steps(plan: ChunkPlan, extra: int = 0) -> int:
        """The most samples a sampled chunk records within SAMPLE_BUDGET doubles (its sample arrays,
        (C, S, ...): sum m v^2, clock and flow redraws, each region's and soft face's outputs, each
        reflect face's statistics, the fixes' state; `extra`: more per sample, e.g. a pair's energy
        and virial); longer runs of samples take several calls."""
        nfix = len(plan.ensemble.fixes) if plan.ensemble is not None else 0
        width = (6 + extra + 5 * len(plan.region) + 3 * sum(len(w.faces) for w in plan.soft)
                 + 2 * sum(len(w.faces) for w in plan.reflect) + 4 * nfix + (3 * MAX_CHAIN + 2 if nfix else 0))
        return max(1, SAMPLE_BUDGET // (width * max(1, plan.state.ncases)))

    @staticmethod
    def _uses_time(plan: ChunkPlan) -> bool:
        names = [v for w in list(plan.soft) + list(plan.reflect) for face in w.faces
                 for v in [face.coord, *face.params.values()] if isinstance(v, str)]
        return any(plan.state.variables.depends_on_time(n) for n in names)

    @staticmethod
    def _regions(plan: ChunkPlan, group: Callable[[np.ndarray, bool], int]
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The wall/region fixes for the kernel: rg_meta (K, 5) int = kind (REGION_KINDS), axis,
        style number, group row, cut-off mode; rg_geo (K, 10) = lo xyz, hi xyz, radius, centre;
        rg_val (C, K, 5) = p0, p1, p2, cutoff, switch_on (constants: `eligible` refuses variables)."""
        C = plan.state.ncases
        K = len(plan.region)
        meta = np.zeros((K, 5), np.int64)
        geo = np.zeros((K, 10))
        val = np.zeros((C, K, 5))
        for k, w in enumerate(plan.region):
            g = w.geom
            meta[k] = (REGION_KINDS[(g.style, g.side)], g.axis or 0, STYLE_IDS[w.style.name],
                       group(np.isin(np.arange(plan.state.x.shape[1]), w.atoms), w.atoms.size == plan.state.x.shape[1]),
                       w.cutoff.mode_id)
            if g.style == "block":
                geo[k, 0:3], geo[k, 3:6] = g.lo, g.hi
            elif g.style == "sphere":
                geo[k, 6], geo[k, 7:10] = g.radius, g.center
            else:
                geo[k, 0], geo[k, 3], geo[k, 6], geo[k, 7:9] = g.lo, g.hi, g.radius, g.center
            for j, key in enumerate(w.style.args_names):
                if key in w.params:
                    val[:, k, j] = np.broadcast_to(np.asarray(w.params[key], float), (C,))
            val[:, k, 3] = np.broadcast_to(np.asarray(w.params.get("cutoff", np.inf), float), (C,))
            val[:, k, 4] = np.broadcast_to(np.asarray(w.params.get("switch_on", 0.0), float), (C,))
        return meta, geo, val

    # -- the chunk -------------------------------------------------------------------------

    def advance(self, nsteps: int, sample: bool) -> bool:
        """Run nsteps steps (and the sample of the last one); False: let the NumPy loop do it (also
        right after a sampled chunk met trouble in these steps)."""
        if self._numpy_next:
            self._numpy_next = False
            return False
        return self._chunk(nsteps, sample, None)

    def advance_to_time(self, target: float) -> bool:
        """Engine.advance_to_time compiled; False: let the NumPy loop do it."""
        return self._chunk(0, True, target)

    def samples_in_kernel(self, at: np.ndarray) -> bool:
        """Whether `advance_sampled` records the samples `at` (steps from now, increasing) in the
        kernel; False: the caller goes one instant at a time (`advance`). Decided by the steps per
        sample, not by a chunk's length, so a run keeps to one way (batch/runner.py warms it)."""
        at = np.asarray(at, np.int64)
        if self._sampled_refused or at.size == 0 or at[0] <= 0 or np.any(np.diff(at) <= 0):
            return False
        plan = self.plan_source()
        if not (enabled() and eligible(plan) and sampled_eligible(plan)):
            self._sampled_refused = True  # not asked again
            return False
        # one case with enough work between two samples for threads over its atoms
        # (threads.plan_split), and enough steps between them to earn each sample's NumPy pass:
        # one instant at a time
        per = max(1, int(at[-1]) // at.size)
        return per < SPLIT_SAMPLE_STEPS or not _splits_atoms(plan, per)

    def advance_sampled(self, at: np.ndarray) -> int:
        """Run to the sample steps `at` (counted from now, increasing), recording every sample
        inside the kernel (plan.record_samples); returns how many of them were run (the first ones;
        0: nothing done, let the caller go sample by sample: `samples_in_kernel`)."""
        if not self.samples_in_kernel(at):
            return 0
        at = np.asarray(at, np.int64)
        plan = self.plan_source()
        at = at[:self.sample_steps(plan)]  # the sample arrays within SAMPLE_BUDGET: fewer samples per call
        at = self.one_call(at)  # and the call within CALL_WORK
        trouble = False
        while True:
            self._sampled_count = at.size
            self._sampled_progress = 0
            self._sampled_trouble = False
            if self._chunk(int(at[-1]), True, None, at):
                self._numpy_next = trouble  # the next stretch holds the trouble: NumPy runs it, reports it
                return self._sampled_count
            trouble = trouble or self._sampled_trouble
            if self._sampled_progress <= 0:
                self._numpy_next = trouble
                return 0
            # trouble after some samples (of the case that met it; the cases before it ran them all):
            # run to the last sample before it in the kernel, the step with trouble then in NumPy
            at = at[:self._sampled_progress]

    def _step_chunk(self, nsteps: int, sample: bool) -> bool:
        return self._chunk(nsteps, sample, None)

    def _chunk(self, nsteps: int, sample: bool, target: float | None, at: np.ndarray | None = None) -> bool:
        plan = self.plan_source()
        s = plan.state
        if s.ncases == 0 or s.failed or not enabled() or not eligible(plan):
            return False
        if at is not None and not sampled_eligible(plan):
            return False
        if any(w.style.needs_radius and not w._radius_checked for w in plan.region):
            return False  # colloid's radius check (the NumPy setup step makes it) reports in NumPy
        time_mode = target is not None
        if time_mode and plan.flow:
            return False
        if not time_mode and nsteps <= 0:
            return False
        if not time_mode and at is None and nsteps > self.call_steps():  # within CALL_WORK per call
            return self.in_calls(self._step_chunk, nsteps, sample)
        varying = self._uses_time(plan)
        if varying and (plan.dt_reset is not None or time_mode):
            return False  # per-step values depend on a dt that changes inside the chunk
        if varying and not time_mode:
            most = self.value_steps(plan)
            if at is not None and nsteps > most:  # a sampled chunk: the samples within `most` steps
                at = at[at <= most]
                if at.size == 0:
                    return False
                nsteps = int(at[-1])
                self._sampled_count = at.size
            if nsteps > most:  # split a long chunk: the values of fewer steps at a time
                return split_steps(self._step_chunk, plan, nsteps, sample, most)
        values = self._values(plan, nsteps if varying else 1, varying)
        if values is None:
            self.fallbacks += 1
            return False
        sf_val, rf_val = values
        for name in ("x", "v", "f", "mass", "radius"):
            if not getattr(s, name).flags.c_contiguous:
                setattr(s, name, np.ascontiguousarray(getattr(s, name)))

        soft_faces = [(w, st, face) for w in plan.soft for st, face in zip(_face_styles(w), w.faces)]
        extra = _lepton_extra(plan)  # generated forces (wall/lepton), numbered after the registry's styles
        groups: list[np.ndarray] = [np.ones(s.x.shape[1], np.uint8)]

        def group(kernel_group: np.ndarray, all_atoms: bool) -> int:
            """Row of `groups` (uint8 (G, N) masks) for a fix's group; row 0 is "all"."""
            if all_atoms:
                return 0
            groups.append(kernel_group.astype(np.uint8))
            return len(groups) - 1

        sf_meta = np.array([[face_style_id(st, extra), face.dim, face.side, group(w.group, w.all_atoms),
                             w.cutoff.mode_id] for w, st, face in soft_faces], np.int64).reshape(-1, 5)
        rf_meta, rf_prev, rf_stat, stats = _reflect_arrays(plan, group)
        C = s.ncases
        dtr = plan.dt_reset
        if dtr is not None:
            dtr_group = group(dtr.group, bool(dtr.group.all()))
            dtr_par = np.ascontiguousarray(plan.dt_reset_params, dtype=float)
        else:
            dtr_group, dtr_par = 0, np.zeros((C, 4))
        rg = self._regions(plan, group)
        fx, fx_fixes, fx_rngs = _fix_arrays(plan, group)
        mrow = int(fx[11][2])  # the integrated atoms' group row (-1: every atom)
        sk = _stochastic_kernel(plan)
        sto = _stochastic_arrays(plan, group)
        groups_arr = np.stack(groups)
        periodic = np.zeros(3, np.int64)
        periodic[s.periodic] = 1

        if not self._spare or self._spare[0].shape != s.x.shape:
            self._spare = tuple(np.empty_like(s.x) for _ in range(3))
        xo, vo, fo = self._spare
        backup = {k: getattr(s, k).copy() for k in ("dt", "atime", "atimestep", "step")}
        fk = plan.flow[0] if plan.flow else None
        n = len(COMPILED_STYLES)
        tb = _tables(soft_faces)
        lp_val = _lepton_rows(soft_faces, C)
        kernel = kernel_for(tuple(sorted({(int(r[0]), int(r[4])) for r in sf_meta if 0 <= r[0] < n})),
                            tuple(sorted({(int(r[2]), int(r[4])) for r in rg[0]})), fk is not None, tuple(extra),
                            fixes=bool(fx[0].shape[0]), dtr=dtr is not None,
                            tables=bool(np.any(sf_meta[:, 0] == TABLE_STYLE)), stochastic=sk is not None,
                            reflect=bool(rf_meta.shape[0]), time=time_mode,
                            # one kernel for both ways of sampling (a second would be a second compile)
                            sampled=sampled_eligible(plan), two_d=two_d_eligible(plan), frozen=mrow >= 0)
        self.kernel = kernel  # the last chunk's kernel (tests read its cache statistics)
        self.kernel_names.add(kernel.py_func.__qualname__)
        if not kernel.signatures:
            announce_compile(kernel, 30 if extra else COMPILE_SECONDS_FIXES if fx[0].shape[0] or dtr is not None
                             else COMPILE_SECONDS)  # generated forces: ~30 s
        sf_val, rf_val, rf_stat = (np.ascontiguousarray(a) for a in (sf_val, rf_val, rf_stat))
        lo, hi = np.asarray(s.box_lo, float), np.asarray(s.box_hi, float)
        args = (int(nsteps), time_mode, float(target if time_mode else 0.0),
                float(landing_tol(target)) if time_mode else 0.0)
        consts = (stats, int(dtr.every if dtr is not None else 0), dtr_group)
        units = (float(s.units.ftm2v), float(s.units.mvv2e))
        sm = _sample_arrays(at, C, sf_meta.shape[0], rf_meta.shape[0] + sto[0].shape[0], fx, rg[0].shape[0])

        def case_args(c: slice, fl: tuple, fx_rng: tuple = _NO_RNGS, st_rng: tuple = _NO_RNGS) -> tuple:
            """The kernel's arguments for cases c (a slice: views, so the kernel writes through)."""
            return (*args, s.x[c], s.v[c], s.f[c], s.mass[c], s.radius[c], s.dt[c], s.atime[c],
                    s.atimestep[c], s.step[c], lo, hi, periodic, sf_meta, sf_val[c], groups_arr, rf_meta,
                    rf_val[c], rf_prev[c], rf_stat[c], *consts, dtr_par[c], *units, xo[c], vo[c], fo[c],
                    rg[0], rg[1], rg[2][c], *fl, _fix_slice(fx, c), fx_rng, *tb, sto[0], sto[1][c],
                    sto[2][c], sto[3], st_rng, lp_val[c], mrow,
                    (sm[0],) + tuple(a[c] for a in sm[1:]))

        # generators drawn from in the kernel (fix langevin, wall/flow, wall/reflect/stochastic):
        # then one case per call, each with its own generators
        generators = _chunk_generators(plan, fx_rngs)
        rng_states = [r.bit_generator.state for r in generators]
        if fk is not None:
            phys, pend = fk.phys.astype(np.int64), fk.pend.astype(np.int64)
            # redraws since the last sample: the pending count, then the chunk's (a sampled chunk
            # reports and zeroes it at each sample)
            prev = np.ascontiguousarray(fk.prev, dtype=float).copy()
            cross = np.array(fk.crossings, dtype=float).reshape(C, 1)
        def run_cases(c0: int, c1: int) -> int:
            """Cases c0 .. c1 - 1: in one call, or, with generators, one call per case (in order,
            up to the first trouble)."""
            if not generators:  # in threads over cases or atoms where they do not interact
                return threads.run_kernel(kernel, case_args(slice(c0, c1), _NO_FLOW))
            # every case's call has arguments of the same types: typed once (`backend.Repeated`)
            call = backend.Repeated(kernel, lambda *one: threads.run_kernel(kernel, one))
            for c in range(c0, c1):
                fl = _NO_FLOW
                if fk is not None:
                    fl_int = np.array([1, fk.axis[c], int(fk.exact[c])], np.int64)
                    fl_f = np.array([fk.lo[c], fk.length[c], fk.vflow[c], fk.kT[c]])
                    walls = np.ascontiguousarray(fk.walls[c][np.isfinite(fk.walls[c])])
                    fl = (fl_int, fl_f, walls, fk.group[c].astype(np.uint8), phys[c], pend[c], prev[c], cross[c],
                          fk.rngs[c])
                status = call(*case_args(slice(c, c + 1), fl, fx_rngs[c] if fx_rngs else _NO_RNGS,
                                         _stochastic_rngs(plan, c)))
                if status != 0:
                    return status
            return 0

        # `fixes:` (per-fix layout, `_fix_slice`) or generators: threads.run_kernel does not split
        # these calls, so runs of cases go to threads here, each case's calls those of one thread
        how = None
        if generators or fx_fixes:
            how = threads.split_edges(C, s.x.shape[1], threads.TIME_MODE_STEPS if time_mode else int(nsteps),
                                      threads.count(), atoms=False)
        if how is None:
            status = run_cases(0, C)
        else:
            status = threads.call_parts(run_cases, ("c0", "c1"), [{"c0": p.start, "c1": p.stop} for p in how[1]],
                                        "cases")
        s.ctx = None
        s.var_step = {}
        if extra:  # compiled (and cached on disk by numba) by now: later processes load it
            _mark_compiled(extra)
        if status != 0:
            if at is not None:  # samples the case with trouble completed (cases run in order)
                self._sampled_trouble = True
                done = np.count_nonzero(sm[2][:, :, 0], axis=1)
                short = np.nonzero(done < sm[0].size)[0]
                self._sampled_progress = int(done[short[0]]) if short.size else 0
            for k, arr in backup.items():
                getattr(s, k)[...] = arr
            for r, state in zip(generators, rng_states):  # the NumPy loop re-runs the chunk with the same draws
                r.bit_generator.state = state
            self.fallbacks += 1
            return False
        # a sampled chunk counts once per sample (each the chunk it replaces: the steps up to a sample)
        self.compiled_chunks += 1 if at is None else int(at.size)
        self.sampled_calls += at is not None
        if fx_fixes:
            _fix_store(fx, fx_fixes, plan)
        if fk is not None:
            fk.phys, fk.pend, fk.prev = phys.astype(np.intp), pend.astype(np.int8), prev
            fk.crossings = cross[:, 0].copy()
        self._spare = (s.x, s.v, s.f)
        s.x, s.v, s.f = xo, vo, fo
        _reflect_store(plan, rf_prev, rf_stat, sto[2])
        if at is not None:
            s.ctx = None
            s.var_step = {}
            plan.record_samples(**_sample_record(plan, sm, fx_fixes))
            return True
        finish_chunk(plan, s, sample, scratch={"f": self._spare[2]})  # the forces before the chunk: free now
        return True


def _sample_arrays(at: np.ndarray | None, C: int, nface: int, nrf: int, fx: tuple, nreg: int
                   ) -> tuple[np.ndarray, ...]:
    """The kernel's `sm` tuple: sample steps (S,) (none: a chunk without samples inside), sum m v^2
    (C, S), clock (C, S, 4): step, dt, atime, atimestep; soft faces (C, S, faces, 3): energy,
    force on the wall, virial; reflect statistics (C, S, reflect faces, 2), wall/reflect/stochastic's faces last; the fixes'
    accumulators (C, S, K, 4); the nvt fixes' chains (C, S, 3 M + 2 each); flow redraws
    (C, S); wall/region fixes (C, S, fixes, 5): energy, force on the wall x y z, virial."""
    at = np.zeros(0, np.int64) if at is None else np.ascontiguousarray(at, np.int64)
    S = at.size
    K = fx[0].shape[0]
    nvt = int(np.count_nonzero(fx[0][:, 0] == FIX_NVT)) if K else 0
    width = 3 * fx[3].shape[1] + 2 * nvt if nvt else 0  # 3 m + 2 per nvt fix
    return (at, np.zeros((C, S)), np.zeros((C, S, 4)), np.zeros((C, S, nface, 3)), np.zeros((C, S, nrf, 2)),
            np.zeros((C, S, K, 4)), np.zeros((C, S, width)), np.zeros((C, S)), np.zeros((C, S, nreg, 5)))


def _sample_record(plan: ChunkPlan, sm: tuple, fixes: list[Any], virial: np.ndarray | None = None
                   ) -> dict[str, Any]:
    """The arguments of Engine.record (plan.record_samples) from a sampled chunk's `sm` arrays:
    the fix outputs summed as compute_forces sums them (face by face from zero; the virial from
    `virial`, the pair's, else zero), the clock, the reflect statistics, the flow redraws and the
    thermostats' ecouple (Ensemble.ecouple on the samples' accumulators and chains, all samples at once)."""
    _, mv2, clock, face, rstat, acc, chain, cross, reg = sm
    C, S = mv2.shape
    out: dict[str, tuple[np.ndarray, ...]] = {}
    k = 0
    virial = np.zeros((C, S)) if virial is None else virial.copy()
    for w in plan.soft:
        energy = np.zeros((C, S))
        vector = np.zeros((C, S, len(w.faces)))
        last_virial = np.zeros((C, S))
        for j in range(len(w.faces)):
            energy += face[:, :, k, 0]
            vector[:, :, j] = face[:, :, k, 1]
            last_virial += face[:, :, k, 2]
            k += 1
        out[w.fix_id] = (energy, vector)
        if w.virial:
            virial += last_virial
    for k, w in enumerate(plan.region):
        out[w.fix_id] = (reg[:, :, k, 0], reg[:, :, k, 1:4])
        if w.virial:
            virial += reg[:, :, k, 4]
    step, dt, atime, atimestep = (clock[:, :, j] for j in range(4))
    args: dict[str, Any] = {"step": step.astype(np.int64), "time": atime + (step - atimestep) * dt, "dt": dt,
                            "mv2": mv2, "out": out, "virial": virial if "press" in plan.outputs else None}
    if plan.reflect and plan.reflect[0].stats:
        args["reflect"] = (rstat[:, :, :, 0], rstat[:, :, :, 1])
    if plan.flow:
        args["crossings"] = cross
    if plan.ensemble is not None:
        args["ecouple"] = _ecouple_samples(plan.ensemble, fixes, acc, chain)
    return args


def _ecouple_samples(ensemble: Any, fixes: list[Any], acc: np.ndarray, chain: np.ndarray) -> np.ndarray:
    """Ensemble.ecouple (C, S) of S samples: each fix's accumulators (and fix nvt's chain) set to
    the samples' values flattened to C*S rows for the call, then put back."""
    C, S = acc.shape[:2]
    saved = []
    p = 0
    try:
        for k, f in enumerate(fixes):
            saved.append((f, {name: getattr(f, name) for name in ("removed", "work", "power", "last_dt")}))
            f.removed, f.work, f.power, f.last_dt = (acc[:, :, k, j].reshape(-1) for j in range(4))
            if f.style == "nvt":  # its block of the chains' samples (3 M + 2 columns, fix order)
                ch = f.chain
                M = ch.eta.shape[1]
                saved.append((ch, {name: getattr(ch, name) for name in ("eta", "eta_dot", "eta_mass", "t_target")}))
                flat = chain.reshape(C * S, -1)[:, p:p + 3 * M + 2]
                p += 3 * M + 2
                ch.eta, ch.eta_dot, ch.eta_mass = flat[:, :M], flat[:, M:2 * M + 1], flat[:, 2 * M + 1:3 * M + 1]
                ch.t_target = flat[:, 3 * M + 1]
        return ensemble.ecouple(C * S).reshape(C, S)
    finally:
        for obj, attrs in saved:
            for name, value in attrs.items():
                setattr(obj, name, value)


# A case split over atoms takes its samples one instant at a time, each sample's outputs from a
# NumPy pass over all atoms after the threads' steps (~45 ns an atom: ~12 one-thread steps of a
# flat-wall kernel; the split's calls cost a few steps' worth more). Below this many steps between
# samples, two threads lost to one thread recording the samples in the kernel (N = 1e5 and 1e6,
# 2 cores: sampled every 10 steps, 1.6-1.7x slower; every 25, even; every 50, 1.2-1.6x faster).
SPLIT_SAMPLE_STEPS = 32


def _splits_atoms(plan: ChunkPlan, nsteps: int) -> bool:
    """Whether threads.run_kernel would split a chunk of nsteps steps of this plan over atoms (one
    case, nothing coupling its atoms, enough work for two threads): a sampled chunk, whose sums
    run over all atoms, is not split, so such chunks keep sampling one instant at a time."""
    s = plan.state
    natom = s.x.shape[1]
    if s.ncases != 1 or threads.count() < 2 or natom <= threads.ALIGN or plan.dt_reset is not None or plan.flow:
        return False
    if _thermostats(plan.ensemble) or _stochastic_kernel(plan) is not None:
        return False
    if plan.ensemble is not None and any(f.style in FIX_KINDS for f in plan.ensemble.fixes):
        return False  # `fixes:` (enforce2d too): the per-fix layout is never split
    if plan.reflect and plan.reflect[0].stats:
        return False
    return natom * max(1, nsteps) // threads.MIN_WORK >= 2


def sampled_eligible(plan: ChunkPlan) -> bool:
    """Scenes whose samples the kernel records itself (sampled chunks): `eligible` ones with
    flat soft faces of registry styles whose energy it computes (`energy_compiled`), of
    wall/table (`_table_out`) or of wall/lepton with a generated energy (`_generated_force`),
    wall/region fixes of such styles, and an engine that takes the records
    (wall/reflect/stochastic's counters are recorded after the wall/reflect ones, in
    Engine.reflect's order)."""
    if plan.record_samples is None:
        return False
    return all((type(w) is SoftWallKernel and energy_compiled(w.style)) or
               (type(w) is CustomWallKernel and all(_is_table(st) or _generated_energy(st) for st in w.face_styles))
               for w in plan.soft) and all(energy_compiled(w.style) for w in plan.region)


def _generated_energy(style: WallStyle) -> bool:
    """A face whose generated force comes with its generated energy (`_generated_force`)."""
    src = _generated_force(style)
    return src is not None and "\ndef energy(" in src


def call_steps(plan: ChunkPlan, cost: int = 1, least: int = 1) -> int:
    """The most steps one kernel call runs: CALL_WORK atom-steps over the batch's cases, each
    atom-step counted `cost` times (PAIR_STEP_COST, ASPHERE_STEP_COST), but `least` at least."""
    return max(1, least, CALL_WORK // max(1, cost * plan.state.ncases * plan.state.x.shape[1]))


def split_steps(chunk: Callable[[int, bool], bool], plan: ChunkPlan, nsteps: int, sample: bool, most: int) -> bool:
    """nsteps steps as kernel calls `chunk(n, sample)` of at most `most` steps each (the sample, if
    asked, after the last), so a Ctrl-C is seen between them; a call handed back to NumPy: the
    rest in NumPy (plan.advance_numpy). False (nothing done) if the first one was. The calls
    leave their whole state to the next, so the bits are those of one call."""
    done = 0
    while done < nsteps:
        n = min(most, nsteps - done)
        if not chunk(n, sample and done + n == nsteps):
            if done == 0:
                return False
            plan.advance_numpy(nsteps - done, sample)  # the rest in NumPy
            return True
        done += n
    return True


def finish_chunk(plan: ChunkPlan, s: BatchState, sample: bool, keep: tuple[str, ...] = ("f",),
                 scratch: dict[str, np.ndarray] | None = None) -> None:
    """End a compiled chunk as the NumPy loop ends its last step. On a sample step the outputs
    (energies, wall forces, virial) come from the NumPy code itself, at these very positions (the
    final half-kick moves only v, and L for ellipsoids); the compiled arrays named in `keep`
    (forces, torques) are kept, not the NumPy pass's. `scratch`: arrays of their shapes the NumPy
    pass may overwrite (the kernel's spare buffers): the kept arrays are then set aside as they
    are, not copied (at N = 1e6 a copy of f there and back is ~7 ms)."""
    out: dict = {}
    if sample:
        scratch = scratch or {}
        kept = {name: getattr(s, name) if name in scratch else getattr(s, name).copy() for name in keep}
        try:
            for name in kept:
                if name in scratch:
                    setattr(s, name, scratch[name])
            out = plan.compute_outputs()
        finally:
            for name, values in kept.items():
                if name in scratch:
                    setattr(s, name, values)
                else:
                    getattr(s, name)[...] = values
        s.ctx = None
        s.var_step = {}
    plan.finish_step(out, sample)


def attach_fast_path(plan_source: Callable[[], ChunkPlan]) -> FastPath | None:
    """The compiled path for the engine whose plans `plan_source` gives, or None (NumPy path)."""
    if not enabled() or not eligible(plan_source()):
        return None
    return FastPath(plan_source)
