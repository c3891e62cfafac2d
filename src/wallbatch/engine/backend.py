"""Which path runs the steps: compiled chunks (numba) or the NumPy engine alone.

The compiled path pays a fixed price in every process that runs cases: importing numba (~0.3 s)
and loading the scene's kernel from numba's disk cache (~0.3 s). A run too small to earn that
back runs in NumPy and never imports numba. The choice is made once per plan (a `wallbatch run`,
`wallbatch.run`, `runner.run_plan`) from the whole plan's size, known before anything runs:

    work = sum over ALL cases of steps x (atoms + STEP_ATOMS)

(a NumPy step costs about 65 us plus 14 ns per atom on a 2-core x86 machine: STEP_ATOMS = 4000
atoms' worth per step; a scene with pair forces or ellipsoids costs NumPy far more, ~1 ms per step
at 1000 atoms: its atoms count HEAVY_ATOM times and its steps HEAVY_STEP times); below SMALL_RUN
(NumPy's time about equal to numba's start-up and kernel load, ~0.35 s) the plan runs in NumPy,
otherwise compiled. It does not depend on how the cases are batched, resumed or spread over
`--jobs` workers, so a plan is all one path and its results are the same however it is run.
`WALLBATCH_NUMBA=0` (or numba missing) forces NumPy, `WALLBATCH_NUMBA=1` forces the compiled path,
for any plan.

Flat walls, wall/reflect, wall/region, dt/reset and `fixes:` give the same bits on both paths;
morse, pair lj/cut, wall/flow redraws and ellipsoids agree to ~1e-14 relative.

numba's own set-up in a process that runs compiled (`prepare_numba`, once, before its first
kernel is loaded). numba's cache load first loads all of numba's typing and target registries
(its NumPy implementations, ~0.2 s of imports and templates), which only its compiler uses: a
kernel found in the cache is loaded with numba's runtime (NRT) set up and nothing else, and the
registries load only when a kernel is compiled. When they do, `numba.np.arraymath` probes at
import whether BLAS is available by importing `scipy.linalg.cython_blas`: all of scipy.linalg and,
through scipy's array API layer, numpy.f2py (~0.3 s). wallbatch's kernels use no BLAS (no np.dot,
np.linalg, np.correlate or np.convolve in jitted code), so the probe is skipped: the registries
load with the probe answering "no BLAS" and the probe function is restored right after, so a
later BLAS use in the same process (np.dot in a user's own @njit function) still finds scipy's
BLAS. The only thing the answer selects is the inner product np.correlate and np.convolve use in
compiled code (a plain loop instead of BLAS's dot). A numba without these names, or already set
up, is left as it is. A compile's IR inlining copies each inlined function's variable table once
per copy instead of once per block, and a Loc's cached source lines not at all
(`_cheap_ir_copies`: same code, ~1 s less per kernel), and the messages numba formats for the
overloads it tries and rejects come without colour (`_plain_error_text`: ~0.1 s less per kernel).
"""

from __future__ import annotations

import contextlib
import os
import sys
import threading
from collections.abc import Callable, Iterator
from typing import Any

import numpy as np

from wallbatch.config.models import Config
from wallbatch.config.sweep import SweepPlan
from wallbatch.scene.build import atom_count
from wallbatch.units import UNIT_SYSTEMS

SMALL_RUN = 25_000_000  # work (atom-steps + STEP_ATOMS per step): below it a plan runs in NumPy
STEP_ATOMS = 4_000  # a NumPy step's fixed cost (~65 us) in atoms (~14 ns per atom-step)
HEAVY_ATOM, HEAVY_STEP = 50, 15  # pair lj/cut or ellipsoids: NumPy's cost per atom and per step, relative
_OFF = ("0", "false", "no", "off")
_ON = ("1", "true", "yes", "on")

_plan_choice: bool | None = None  # set while a plan runs (inherited by forked workers)
_numba_prepared = False  # prepare_numba has run in this process (forked workers inherit it)


def env_choice() -> bool | None:
    """WALLBATCH_NUMBA: True (1/true/yes/on), False (0/false/no/off), None (unset or empty)."""
    value = os.environ.get("WALLBATCH_NUMBA", "").strip().lower()
    if value in _OFF:
        return False
    if value in _ON:
        return True
    return None


def numba_allowed() -> bool:
    """May this process use compiled kernels now: WALLBATCH_NUMBA if set, else the running
    plan's choice, else yes. A question only: numba must also import (`use_numba`)."""
    env = env_choice()
    return env if env is not None else (True if _plan_choice is None else _plan_choice)


def use_numba() -> bool:
    """For a compiled module that imported numba, before it loads a kernel: `numba_allowed()`, and
    if so numba set up for this process (`prepare_numba`, once)."""
    allowed = numba_allowed()
    if allowed and "numba" in sys.modules:
        prepare_numba()
    return allowed


def call_kernel(kernel: Callable[..., Any], *args: Any) -> Any:
    """`kernel(*args)`, a Ctrl-C seen during the call raised as KeyboardInterrupt. A compiled call
    does not return to Python before its end, so the signal waits; a kernel that returns a tuple
    holding an array then runs numba's Python helper as it boxes the array
    (`numba.core.serialize._numba_unpickle`), which raises the pending KeyboardInterrupt, and numba
    reports that as a SystemError caused by it (the pair chunks' kernel: a Ctrl-C failed the case
    as an internal error instead of interrupting the run)."""
    try:
        return kernel(*args)
    except SystemError as err:
        if isinstance(err.__cause__, KeyboardInterrupt):
            raise KeyboardInterrupt from None
        raise


def resolved(kernel: Callable[..., Any], args: tuple) -> Callable[..., Any]:
    """The compiled entry point of the numba dispatcher `kernel` for the types of `args`, for many
    calls with arguments of those types: a dispatcher types every call's arguments anew, in Python
    for tuples (~2 ms for the ~40 arrays in the pair chunk kernel's tuples; its CPython entry
    point unboxes them in ~0.01 ms). The dispatcher itself if that overload is not compiled yet
    (its first call compiles it) or `kernel` is no dispatcher. The entry point releases the GIL as
    the dispatcher's call does (nogil) and computes the same bits (the same machine code). A
    wrapper whose class has a `resolved(args)` method (compiled.SceneKernel) resolves its own way."""
    own = getattr(type(kernel), "resolved", None)
    if own is not None:
        return own(kernel, args)
    overloads = getattr(kernel, "overloads", None)
    if not overloads:
        return kernel
    try:
        from numba import typeof  # noqa: PLC0415 - only with compiled kernels

        return overloads[tuple(typeof(a) for a in args)].entry_point
    except Exception:  # noqa: BLE001 - an argument numba cannot type here, or no such overload: the dispatcher
        return kernel


_ENTRIES: dict[tuple[int, Any], tuple[Any, Callable[..., Any]]] = {}  # (id(kernel), argument kinds): (kernel, entry)
_INT64 = (-(1 << 63), 1 << 63)


def argument_kinds(args: tuple) -> Any:
    """What numba's typing reads from `args` (`Repeated`'s key of a resolved entry point): per
    array its class, dtype, dimensions, layout (C, F or neither), whether it is writeable and
    aligned; per tuple its items' kinds; per Python int whether it fits int64; per NumPy scalar
    its dtype; per other scalar or generator its class. None for anything else (no key: typed by
    numba each time)."""
    out = []
    for a in args:
        t = type(a)
        if t is np.ndarray:
            fl = a.flags
            out.append((a.dtype, a.ndim, fl.c_contiguous, fl.f_contiguous, fl.writeable, fl.aligned))
        elif t is tuple:
            k = argument_kinds(a)
            if k is None:
                return None
            out.append(("t", k))
        elif t is int:
            out.append((int, _INT64[0] <= a < _INT64[1]))
        elif isinstance(a, np.generic):  # (numba types it by its dtype: a record's fields too)
            out.append(("g", a.dtype))
        elif t in _SCALARS or isinstance(a, np.random.Generator):
            out.append(t)
        else:
            return None
    return tuple(out)


_SCALARS = (float, bool, complex, type(None))


class Repeated:
    """Calls of one compiled kernel with arguments of the same types, one after another (a chunk's
    call per case, per thread's part and step): the first through `first` (default: the kernel,
    by `call_kernel`), the others to the entry point `resolved` finds for that first call's
    arguments (numba's typing once, not per call). Without `first`, the entry point is also kept
    for the process under the arguments' kinds (`argument_kinds`): a later Repeated of the same
    kernel with arguments of the same kinds (the next chunk's) skips numba's typing altogether
    (~1-2 ms per typing of the pair chunk kernel's ~50 arguments). Threads may share one: a race
    only makes two first calls."""

    def __init__(self, kernel: Callable[..., Any], first: Callable[..., Any] | None = None):
        self.kernel = kernel
        self.first = first
        self.entry: Callable[..., Any] | None = None

    def __call__(self, *args: Any) -> Any:
        if self.entry is not None:
            return call_kernel(self.entry, *args)
        kinds = argument_kinds(args) if self.first is None else None
        key = None if kinds is None else (id(self.kernel), kinds)
        kept = _ENTRIES.get(key) if key is not None else None
        if kept is not None and kept[0] is self.kernel:
            self.entry = kept[1]
            return call_kernel(self.entry, *args)
        out = self.first(*args) if self.first is not None else call_kernel(self.kernel, *args)
        self.entry = resolved(self.kernel, args)  # (compiled by the first call if it was new)
        if key is not None and self.entry is not self.kernel:
            _ENTRIES[key] = (self.kernel, self.entry)
        return out


def numba_prepared() -> bool:
    """Has `prepare_numba` run in this process (or the process it was forked from)."""
    return _numba_prepared


def _no_blas() -> None:
    raise ImportError("wallbatch: numba's BLAS probe skipped at set-up (no BLAS in wallbatch's kernels)")


def prepare_numba() -> None:
    """Set numba up for this process, once: loading a kernel from the disk cache initialises only
    numba's runtime (`_light_cache_load`), and numba's registries load when something is compiled,
    with the BLAS probe skipped (`load_registries`). A no-op if numba is set up already or its
    names differ from numba 0.5x-0.6x's (numba then sets itself up as usual). Its compiles inline
    functions without copying a whole variable table per block (`_cheap_ir_copies`), and format
    the messages of the overloads they reject without colour (`_plain_error_text`)."""
    global _numba_prepared
    if _numba_prepared:
        return
    _numba_prepared = True
    _cheap_ir_copies()  # a compile's IR inlining without its quadratic copies
    _plain_error_text()  # nor colorama set up again for every overload it rejects
    if "numba.np.arraymath" in sys.modules:  # set up already (the probe has run): nothing to skip
        return
    if not _light_cache_load():
        load_registries()


def load_registries() -> None:
    """Load numba's CPU typing and target registries (what its first compile does) with the BLAS
    probe of `numba.np.arraymath` answering "no BLAS" instead of importing scipy.linalg (~0.3 s;
    see the module docstring); the probe is restored afterwards. Once per process."""
    if "numba.np.arraymath" in sys.modules:  # loaded already (the probe has run)
        return
    try:
        from numba.core.registry import cpu_target
        from numba.np import linalg
    except Exception:  # noqa: BLE001 - no numba, or another layout: numba sets itself up as usual
        return
    real = getattr(linalg, "ensure_blas", None)
    if not callable(real):
        return
    linalg.ensure_blas = _no_blas  # arraymath binds it by `from numba.np.linalg import ensure_blas`
    try:
        cpu_target.typing_context.refresh()  # the typing registries, then the target's (arraymath among
        cpu_target.target_context.refresh()  # them), in numba's order
    except Exception:  # noqa: BLE001 - the first compile loads them again and reports any real problem
        pass
    finally:
        linalg.ensure_blas = real
        arraymath = sys.modules.get("numba.np.arraymath")
        if arraymath is not None and getattr(arraymath, "ensure_blas", None) is _no_blas:
            arraymath.ensure_blas = real


def _light_cache_load() -> bool:
    """Make numba's disk-cache load initialise only what loaded machine code calls: numba's runtime
    (NRT: allocation and reference counts). numba's own load first refreshes its whole typing and
    target registries (~0.2 s of imports and templates), which only a compile uses; a load that
    finds nothing calls `load_registries` before numba compiles (numba's compiler refreshes them
    itself as well). False if numba's cache has another layout (nothing changed)."""
    try:
        from numba.core import caching
        from numba.core.runtime import rtsys
    except Exception:  # noqa: BLE001 - no numba, or another layout
        return False
    real = getattr(caching.Cache, "load_overload", None)
    if getattr(real, "wallbatch_light", False):
        return True
    if not (callable(real) and hasattr(caching.Cache, "_load_overload")
            and hasattr(caching.Cache, "_guard_against_spurious_io_errors") and hasattr(rtsys, "initialize")):
        return False

    def load_overload(self, sig, target_context):  # noqa: ANN001, ANN202 - numba's own signature
        rtsys.initialize(target_context)
        found = None
        with self._guard_against_spurious_io_errors():
            found = self._load_overload(sig, target_context)
        if found is None:  # not in the cache: numba compiles next
            load_registries()
        return found

    load_overload.wallbatch_light = True
    caching.Cache.load_overload = load_overload
    return True


def _cheap_ir_copies() -> bool:
    """Make numba's IR inliner copy what it copies once, not once per block or per Loc.

    Inlining a function (`inline="always"`, how the kernels put their pieces into one loop) copies
    the callee's IR twice with `copy.deepcopy`, one block at a time, and copies two things in vain:
    - Every variable of every block refers to the function's one Scope, which holds all its
      variables, so each block's deepcopy copies the whole Scope again: an inline costs blocks x
      variables. During one `InlineWorker.inline_ir`, the blocks copied from one Scope now share one
      copy of it, as the original blocks share the original; numba then renames the callee's
      variables from that copy and moves the blocks into the caller's scope, as before.
    - A Loc (a source position) caches its file's lines once it has printed itself (numba's IR
      warnings do), and deepcopy copied that list (thousands of strings) with every Loc: a copied
      Loc now shares it (a read-only cache).
    Same IR, same machine code; ~1 s less of a flat-wall kernel's compile. True if installed (or
    already); False, nothing changed, if numba's inliner has another layout."""
    try:
        import copy

        from numba.core import inline_closurecall as icc
        from numba.core import ir
    except Exception:  # noqa: BLE001 - no numba, or another layout
        return False
    worker = getattr(icc, "InlineWorker", None)
    real = getattr(worker, "inline_ir", None)
    if getattr(real, "wallbatch_cheap_copies", False):
        return True
    loc = getattr(ir, "Loc", None)
    if not (callable(real) and getattr(icc, "copy", None) is copy and isinstance(getattr(ir, "Block", None), type)
            and isinstance(loc, type) and "__deepcopy__" not in vars(loc)):
        return False
    state = threading.local()  # the Scope copies of the inline_ir call running in this thread

    class _Copy:
        """The `copy` module as inline_closurecall sees it: deepcopy of a Block inside inline_ir
        starts from the Scope copy shared by that call; everything else is copy's own."""

        def __getattr__(self, name: str) -> Any:
            return getattr(copy, name)

        @staticmethod
        def deepcopy(x: Any, memo: dict | None = None) -> Any:
            scopes = getattr(state, "scopes", None)
            if memo is None and scopes is not None and isinstance(x, ir.Block):
                scope = x.scope
                pair = scopes.get(id(scope))
                if pair is None:  # (the Scope itself kept too: its id stays its own)
                    pair = scopes[id(scope)] = (scope, copy.deepcopy(scope))
                memo = {id(scope): pair[1]}
            return copy.deepcopy(x, memo)

    def inline_ir(self, *args: Any, **kwargs: Any) -> Any:  # noqa: ANN001 - numba's own signature
        outer = getattr(state, "scopes", None)
        state.scopes = {}
        try:
            return real(self, *args, **kwargs)
        finally:
            state.scopes = outer

    def loc_deepcopy(self, memo):  # noqa: ANN001, ANN202 - copy's protocol
        new = copy.copy(self)  # file, line, column, and the lines cache shared
        memo[id(self)] = new
        return new

    inline_ir.wallbatch_cheap_copies = True
    inline_ir.__wrapped__ = real
    icc.copy = _Copy()
    worker.inline_ir = inline_ir
    loc.__deepcopy__ = loc_deepcopy
    return True


def _plain_error_text() -> bool:
    """Typing a kernel, numba tries overloads and formats a message for each one it rejects
    (~4,700 for the flat-wall kernel), and with colorama installed its colour scheme wraps stdout
    and stderr anew for every piece of such a message (colorama's init and deinit: ~0.1 s of a
    kernel's compile). Unless the user chose a scheme (NUMBA_COLOR_SCHEME), numba's scheme now
    returns the text as it is: its messages read the same, without colour or bold. True if set
    (or already); False, nothing changed, where numba's scheme has another layout."""
    if os.environ.get("NUMBA_COLOR_SCHEME"):
        return False
    try:
        from numba.core import errors
    except Exception:  # noqa: BLE001 - no numba
        return False
    scheme = errors.termcolor()  # the one instance numba's modules hold
    if getattr(scheme, "_markup", None) is None:
        return False
    if getattr(scheme._markup, "wallbatch_plain", False):
        return True

    def plain(msg: str, color: Any = None, style: Any = None) -> str:
        return msg

    plain.wallbatch_plain = True
    scheme._markup = plain
    return True


@contextlib.contextmanager
def plan_path(compiled: bool | None) -> Iterator[None]:
    """Run the body with the plan's choice (None: leave it as it is); restored afterwards."""
    global _plan_choice
    saved = _plan_choice
    if compiled is not None:
        _plan_choice = compiled
    try:
        yield
    finally:
        _plan_choice = saved


def case_work(cfg: Config) -> int:
    """steps x (atoms + STEP_ATOMS) of one case (a run to a simulated time: time / initial dt),
    atoms and steps weighted HEAVY_ATOM and HEAVY_STEP for pair forces or ellipsoids."""
    if cfg.run.steps is not None:
        steps = cfg.run.steps
    else:
        dt = cfg.timestep if cfg.timestep is not None else UNIT_SYSTEMS[cfg.units].dt
        steps = int(cfg.run.time / dt) + 1 if dt > 0 else 0
    heavy = cfg.pair is not None or any(g.shape is not None for g in cfg.atoms)
    if heavy:
        return steps * (HEAVY_ATOM * atom_count(cfg) + HEAVY_STEP * STEP_ATOMS)
    return steps * (atom_count(cfg) + STEP_ATOMS)


def plan_work(plan: SweepPlan) -> int:
    """The whole plan's work: every case, however the cases are batched or resumed."""
    return sum(case_work(sc.config) for sc in plan.cases)


def choose(plan: SweepPlan) -> bool:
    """True: the plan runs compiled chunks; False: NumPy only (see the module docstring)."""
    env = env_choice()
    if env is not None:
        return env
    return plan_work(plan) >= SMALL_RUN


WHERE_IT_CAN = "where the scene allows (the NumPy path runs the rest)"


def describe(plan: SweepPlan) -> str:
    """One line, before the run: the path the plan is to run on and why (`ran`: after it, the
    path its steps took)."""
    env = env_choice()
    if env is not None:
        return (f"engine: {'compiled (numba) ' + WHERE_IT_CAN if env else 'NumPy'}, as "
                f"WALLBATCH_NUMBA={os.environ['WALLBATCH_NUMBA']} asks")
    work = plan_work(plan)
    if work >= SMALL_RUN:
        return f"engine: compiled (numba) {WHERE_IT_CAN}: work {work:.3g} atom-steps, at least {SMALL_RUN:.3g}"
    return (f"engine: NumPy: work {work:.3g} atom-steps, below {SMALL_RUN:.3g} (numba's start-up would cost "
            f"more; WALLBATCH_NUMBA=1 forces it)")


def ran(steps: list[tuple[int, int]]) -> str:
    """One line, after a run: the path the cases' steps took, from each case's (compiled steps,
    NumPy steps) (engine.CaseResult: those of its batch). A scene the compiled kernels do not take
    (or a chunk they hand back) runs on the NumPy path even when the plan chose compiled."""
    compiled = [c for c, n in steps if c and not n]
    mixed = [(c, n) for c, n in steps if c and n]
    numpy = [n for c, n in steps if n and not c]
    if not (compiled or mixed or numpy):
        return "engine: no step was run"
    parts = []
    if compiled:
        parts.append(f"compiled (numba) for {len(compiled)} case(s)")
    if mixed:
        n, total = sum(n for _, n in mixed), sum(c + n for c, n in mixed)
        parts.append(f"partly compiled for {len(mixed)} case(s) ({n} of their {total} steps on the NumPy path)")
    if numpy:
        parts.append(f"on the NumPy path for {len(numpy)} case(s)")
    return "engine: ran " + "; ".join(parts)
