"""Expression walls (LAMMPS ``fix wall/lepton``): E(r) written as a Lepton expression of ``r``.

The text is parsed with Lepton's grammar into the expression tree of :mod:`wallbatch.expr`
(``Num``, ``VarRef`` for ``r`` and parameter names, ``Unary``, ``Binary``, ``Call``); Python
``eval`` is never used. Lepton differs from LAMMPS equal-style variables, and LAMMPS's wall/lepton
follows Lepton (checked by running LAMMPS):

* ``^`` is right-associative (``2^3^2`` = 512) and binds tighter than unary minus
  (``-r^2`` = -(r^2)); ``+ - * /`` are left-associative; ``log`` is the natural logarithm;
* there are no comparison or logical operators; ``step(x)`` = 1 if x >= 0 else 0,
  ``delta(x)`` = 1 if x == 0 else 0, ``select(x, a, b)`` = a if x != 0 else b;
* ``expr; k=100.0; rc=4.0`` appends definitions; a definition sees only the definitions that
  follow it (Lepton reads them last to first). wallbatch refuses a definition that uses an earlier
  one (LAMMPS silently evaluates such a name as 0).

The force F = -dE/dr [force] is the symbolic derivative of the tree (:func:`derivative`, then
:func:`simplify`), never a finite difference. The wall energy is E(r) - E(rc) [energy], zero at
the cut-off like LAMMPS. F > 0 pushes the atom away from the wall (wallbatch's convention for all
styles).

Integer powers ``x^n`` (n a literal integer, |n| <= 64) are computed by binary exponentiation
(square-and-multiply, then 1/x for n < 0), as Lepton does; every other function and ``^`` is
evaluated with the C library's routines (numba-compiled ufuncs), so the NumPy evaluation
(:func:`evaluate`) and the generated numba kernel (:func:`numba_kernel`) agree bit for bit. Note:
NumPy's own exp/log/tanh use SIMD code that differs from the C library by an ulp.
"""

from __future__ import annotations

import functools
import hashlib
import importlib.util
import math
import os
import re
import sys
import tempfile
from pathlib import Path
from types import ModuleType
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass

import numpy as np

from wallbatch.expr import Binary, Call, Node, Num, Unary, VarRef, VariableError
from wallbatch.styles.base import Param, WallStyle, cutoff_param

__all__ = [
    "LeptonError",
    "LEPTON_FUNCTIONS",
    "LeptonExpression",
    "parse_lepton",
    "compile_expression",
    "derivative",
    "simplify",
    "evaluate",
    "to_lepton",
    "free_names",
    "numba_kernel",
    "kernel_source",
    "lepton_style",
    "LeptonWallStyle",
    "LeptonEntry",
    "LEPTON",
    "positional_kernels",
    "force_source",
    "vector_force_source",
    "energy_source",
    "kernel_cache_dir",
    "generated_module",
    "generated_path",
]


class LeptonError(VariableError):
    """An invalid wall/lepton expression (syntax, unknown name, misplaced definition, ...)."""


#: Lepton function name -> number of arguments.
LEPTON_FUNCTIONS: dict[str, int] = {
    "sqrt": 1, "exp": 1, "log": 1, "sin": 1, "cos": 1, "sec": 1, "csc": 1, "tan": 1, "cot": 1,
    "asin": 1, "acos": 1, "atan": 1, "atan2": 2, "sinh": 1, "cosh": 1, "tanh": 1, "erf": 1,
    "erfc": 1, "step": 1, "delta": 1, "square": 1, "cube": 1, "recip": 1, "min": 2, "max": 2,
    "abs": 1, "floor": 1, "ceil": 1, "select": 3,
}  # fmt: skip

R = "r"  # the distance variable [length]
_MAX_INT_POWER = 64

# ---------------------------------------------------------------------------------------------
# Parsing

_TOKEN_RE = re.compile(
    r"(?P<ws>\s+)|(?P<num>(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?)|(?P<name>[A-Za-z_][A-Za-z0-9_]*)"
    r"|(?P<op>[-+*/^(),])"
)
_BP = {"+": (1, 2), "-": (1, 2), "*": (3, 4), "/": (3, 4), "^": (7, 6)}  # (left, right) power
_UNARY_BP = 5  # -x^2 = -(x^2), -a*b = (-a)*b


class _Parser:
    def __init__(self, text: str, where: str) -> None:
        self.text, self.where = text, where
        self.tokens: list[tuple[str, str, int]] = []
        pos = 0
        while pos < len(text):
            m = _TOKEN_RE.match(text, pos)
            if m is None:
                raise self.error(pos, f"unexpected character {text[pos]!r}")
            if m.lastgroup != "ws":
                self.tokens.append((m.lastgroup or "", m.group(), pos))
            pos = m.end()
        self.tokens.append(("end", "", len(text)))
        self.i = 0

    def error(self, pos: int, msg: str) -> LeptonError:
        return LeptonError(f"syntax error at position {pos} in {self.where}{self.text!r}: {msg}")

    def peek(self) -> tuple[str, str, int]:
        return self.tokens[self.i]

    def take(self) -> tuple[str, str, int]:
        tok = self.tokens[self.i]
        self.i += 1
        return tok

    def expect(self, op: str) -> None:
        kind, text, pos = self.take()
        if kind != "op" or text != op:
            raise self.error(pos, f"expected {op!r}, found {text or 'the end'!r}")

    def expression(self, min_bp: int = 0) -> Node:
        left = self.prefix()
        while True:
            kind, op, _ = self.peek()
            if kind != "op" or op not in _BP or _BP[op][0] < min_bp:
                return left
            self.take()
            left = Binary(op, left, self.expression(_BP[op][1]))

    def prefix(self) -> Node:
        kind, text, pos = self.take()
        if kind == "num":
            return Num(float(text))
        if kind == "op" and text == "-":
            return Unary("-", self.expression(_UNARY_BP))
        if kind == "op" and text == "(":
            node = self.expression()
            self.expect(")")
            return node
        if kind == "name":
            if self.peek()[:2] == ("op", "("):
                if text not in LEPTON_FUNCTIONS:
                    known = ", ".join(sorted(LEPTON_FUNCTIONS))
                    raise LeptonError(
                        f"unknown function {text!r} at position {pos} in {self.where}"
                        f"{self.text!r} (known: {known})"
                    )
                self.take()
                args: list[Node] = []
                if self.peek()[:2] != ("op", ")"):
                    args.append(self.expression())
                    while self.peek()[:2] == ("op", ","):
                        self.take()
                        args.append(self.expression())
                self.expect(")")
                if len(args) != LEPTON_FUNCTIONS[text]:
                    raise LeptonError(
                        f"function {text!r} takes {LEPTON_FUNCTIONS[text]} argument(s), got "
                        f"{len(args)}, at position {pos} in {self.where}{self.text!r}"
                    )
                return Call(text, tuple(args))
            return VarRef(text)
        raise self.error(pos, f"expected a value, found {text or 'the end'!r}")

    def parse(self) -> Node:
        node = self.expression()
        kind, text, pos = self.peek()
        if kind != "end":
            raise self.error(pos, f"unexpected {text!r} after the expression")
        return node


def _parse_one(text: str, where: str = "") -> Node:
    return _Parser(text, where).parse()


def _substitute(node: Node, defs: Mapping[str, Node]) -> Node:
    if isinstance(node, VarRef):
        return defs.get(node.name, node)
    if isinstance(node, Unary):
        return Unary(node.op, _substitute(node.operand, defs))
    if isinstance(node, Binary):
        return Binary(node.op, _substitute(node.left, defs), _substitute(node.right, defs))
    if isinstance(node, Call):
        return Call(node.func, tuple(_substitute(a, defs) for a in node.args))
    return node


def free_names(node: Node) -> list[str]:
    """Names (``VarRef``) used by the tree, in order of first appearance (``r`` included)."""
    out: dict[str, None] = {}

    def walk(n: Node) -> None:
        if isinstance(n, VarRef):
            out.setdefault(n.name)
        elif isinstance(n, Unary):
            walk(n.operand)
        elif isinstance(n, Binary):
            walk(n.left)
            walk(n.right)
        elif isinstance(n, Call):
            for a in n.args:
                walk(a)

    walk(node)
    return list(out)


def parse_lepton(text: str) -> tuple[Node, dict[str, float]]:
    """Parse ``"expr; name=value; ..."`` into (energy tree, numeric definitions).

    Definitions whose value is a number (or a constant expression) are returned as parameters
    (so they can be swept); the others are substituted into the tree. A definition sees only the
    definitions after it, as in Lepton.
    """
    if not isinstance(text, str) or not text.strip():
        raise LeptonError("the expression is empty")
    parts = text.split(";")
    main, defs_text = parts[0], parts[1:]
    entries: list[tuple[str, str]] = []
    for part in defs_text:
        if not part.strip():
            continue
        name, eq, value = part.partition("=")
        name = name.strip()
        if not eq or not re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*", name):
            raise LeptonError(f"definition {part.strip()!r} must be 'name=value' in {text!r}")
        if name == R:
            raise LeptonError(f"'r' is the distance to the wall and cannot be defined in {text!r}")
        if name in LEPTON_FUNCTIONS:
            raise LeptonError(f"definition name {name!r} is a function name in {text!r}")
        if any(name == n for n, _ in entries):
            raise LeptonError(f"{name!r} is defined twice in {text!r}")
        entries.append((name, value))
    numbers: dict[str, float] = {}
    exprs: dict[str, Node] = {}
    names = [n for n, _ in entries]
    for k in range(len(entries) - 1, -1, -1):  # Lepton: last to first
        name, value = entries[k]
        node = _parse_one(value, f"definition {name!r} of ")
        for used in free_names(node):
            if used in names[:k] or used == name:
                raise LeptonError(
                    f"definition {name!r} uses {used!r}, which is defined before it in {text!r}: "
                    "a definition can only use the definitions that follow it"
                )
        node = simplify(_substitute(node, exprs))
        if isinstance(node, Num):
            numbers[name] = node.value
        elif free_names(node) and all(n in numbers for n in free_names(node)):
            numbers[name] = float(evaluate(node, 0.0, numbers))
        else:
            exprs[name] = node
    tree = _substitute(_parse_one(main), exprs)
    return tree, {n: numbers[n] for n in names if n in numbers}


# ---------------------------------------------------------------------------------------------
# Simplification and derivative


def _num(node: Node, value: float) -> bool:
    return isinstance(node, Num) and node.value == value


def _const(node: Node) -> bool:
    return isinstance(node, Num)


def _int_exponent(node: Node) -> int | None:
    # (the bound first: an exponent of inf or nan, say 1e400, has no integer value)
    if isinstance(node, Num) and abs(node.value) <= _MAX_INT_POWER and node.value == int(node.value):
        return int(node.value)
    return None


def simplify(node: Node) -> Node:
    """Fold constants and drop neutral terms (x+0, x*1, x*0, x^1, x^0, --x, ...), bottom up."""
    if isinstance(node, Unary):
        a = simplify(node.operand)
        if isinstance(a, Num):
            return Num(-a.value)
        if isinstance(a, Unary) and a.op == "-":
            return a.operand
        return Unary("-", a)
    if isinstance(node, Binary):
        a, b, op = simplify(node.left), simplify(node.right), node.op
        if _const(a) and _const(b):
            v = _fold(op, a.value, b.value)  # type: ignore[union-attr]
            if v is not None:
                return Num(v)
        if op == "+":
            if _num(a, 0.0):
                return b
            if _num(b, 0.0):
                return a
            if isinstance(b, Unary):
                return simplify(Binary("-", a, b.operand))
        elif op == "-":
            if _num(b, 0.0):
                return a
            if _num(a, 0.0):
                return simplify(Unary("-", b))
            if isinstance(b, Unary):
                return simplify(Binary("+", a, b.operand))
        elif op == "*":
            if _num(a, 0.0) or _num(b, 0.0):
                return Num(0.0)
            if _num(a, 1.0):
                return b
            if _num(b, 1.0):
                return a
            if _num(a, -1.0):
                return simplify(Unary("-", b))
            if _num(b, -1.0):
                return simplify(Unary("-", a))
            if isinstance(a, Unary) and isinstance(b, Unary):
                return simplify(Binary("*", a.operand, b.operand))
            if isinstance(a, Unary) or isinstance(b, Unary):  # pull the sign out: -(x*y)
                x = a.operand if isinstance(a, Unary) else a
                y = b.operand if isinstance(b, Unary) else b
                return simplify(Unary("-", Binary("*", x, y)))
        elif op == "/":
            if _num(a, 0.0):
                return Num(0.0)
            if _num(b, 1.0):
                return a
            if isinstance(a, Unary) and isinstance(b, Unary):
                return simplify(Binary("/", a.operand, b.operand))
            if isinstance(a, Unary):
                return simplify(Unary("-", Binary("/", a.operand, b)))
        elif op == "^":
            if _num(b, 1.0):
                return a
            if _num(b, 0.0):
                return Num(1.0)
        return Binary(op, a, b)
    if isinstance(node, Call):
        args = tuple(simplify(x) for x in node.args)
        if node.func == "select" and args[1] == args[2]:
            return args[1]
        if node.func == "select" and _const(args[0]):
            return args[1] if args[0].value != 0 else args[2]  # type: ignore[union-attr]
        if all(_const(x) for x in args):
            with np.errstate(all="ignore"):
                v = float(_FUNC_EVAL[node.func](*(np.float64(x.value) for x in args)))  # type: ignore[union-attr]
            if math.isfinite(v):
                return Num(v)
        return Call(node.func, args)
    return node


def _fold(op: str, a: float, b: float) -> float | None:
    with np.errstate(all="ignore"):
        if op == "^":
            n = _int_exponent(Num(b))
            v = float(_ipow(np.float64(a), n)) if n is not None else float(_pow()(a, b))
        else:
            v = float(_ARITH[op](np.float64(a), np.float64(b)))
    return v if math.isfinite(v) else None


def _neg(x: Node) -> Node:
    return Unary("-", x)


def _mul(*xs: Node) -> Node:
    out = xs[0]
    for x in xs[1:]:
        out = Binary("*", out, x)
    return out


def derivative(node: Node, var: str = R) -> Node:
    """d(node)/d(var) as a new tree (not simplified; see :func:`simplify`)."""
    d = functools.partial(derivative, var=var)
    if isinstance(node, Num):
        return Num(0.0)
    if isinstance(node, VarRef):
        return Num(1.0 if node.name == var else 0.0)
    if isinstance(node, Unary):
        return _neg(d(node.operand))
    if isinstance(node, Binary):
        u, v, op = node.left, node.right, node.op
        if op in ("+", "-"):
            return Binary(op, d(u), d(v))
        if op == "*":
            return Binary("+", _mul(d(u), v), _mul(u, d(v)))
        if op == "/":  # u'/v - u v'/v^2
            return Binary("-", Binary("/", d(u), v), Binary("/", _mul(u, d(v)), _mul(v, v)))
        # ^
        if var not in free_names(v):  # n u^(n-1) u'
            n_minus_1 = simplify(Binary("-", v, Num(1.0)))
            return _mul(v, Binary("^", u, n_minus_1), d(u))
        if var not in free_names(u):  # ln(u) u^v v'
            return _mul(Call("log", (u,)), node, d(v))
        return _mul(node, Binary("+", _mul(d(v), Call("log", (u,))), Binary("/", _mul(v, d(u)), u)))
    assert isinstance(node, Call)
    f, args = node.func, node.args
    if f == "select":
        return Call("select", (args[0], d(args[1]), d(args[2])))
    if f in ("min", "max"):  # Lepton: the derivative of the argument min/max picks
        a, b = args
        first, second = (d(b), d(a)) if f == "min" else (d(a), d(b))
        return Call("select", (Call("step", (Binary("-", a, b),)), first, second))
    if f == "atan2":  # atan2(y, x)' = (x y' - y x') / (x^2 + y^2)
        y, x = args
        return Binary(
            "/", Binary("-", _mul(x, d(y)), _mul(y, d(x))),
            Binary("+", _mul(x, x), _mul(y, y)),
        )  # fmt: skip
    u = args[0]
    du = d(u)
    outer = _outer_derivative(f, u, node)
    return _mul(outer, du)


def _outer_derivative(f: str, u: Node, node: Node) -> Node:
    """f'(u) for a one-argument function."""
    one = Num(1.0)
    if f == "sqrt":
        return Binary("/", Num(0.5), node)
    if f == "exp":
        return node
    if f == "log":
        return Binary("/", one, u)
    if f == "sin":
        return Call("cos", (u,))
    if f == "cos":
        return _neg(Call("sin", (u,)))
    if f == "sec":
        return _mul(node, Call("tan", (u,)))
    if f == "csc":
        return _neg(_mul(node, Call("cot", (u,))))
    if f == "tan":
        return Call("square", (Call("sec", (u,)),))
    if f == "cot":
        return _neg(Call("square", (Call("csc", (u,)),)))
    if f == "asin":
        return Binary("/", one, Call("sqrt", (Binary("-", one, Call("square", (u,))),)))
    if f == "acos":
        return _neg(Binary("/", one, Call("sqrt", (Binary("-", one, Call("square", (u,))),))))
    if f == "atan":
        return Binary("/", one, Binary("+", one, Call("square", (u,))))
    if f == "sinh":
        return Call("cosh", (u,))
    if f == "cosh":
        return Call("sinh", (u,))
    if f == "tanh":
        return Binary("-", one, Call("square", (node,)))
    if f in ("erf", "erfc"):
        g = _mul(Num(2.0 / math.sqrt(math.pi)), Call("exp", (_neg(Call("square", (u,))),)))
        return g if f == "erf" else _neg(g)
    if f == "square":
        return _mul(Num(2.0), u)
    if f == "cube":
        return _mul(Num(3.0), Call("square", (u,)))
    if f == "recip":
        return _neg(Binary("/", one, Call("square", (u,))))
    if f == "abs":
        return Binary("-", _mul(Num(2.0), Call("step", (u,))), one)
    if f in ("step", "delta", "floor", "ceil"):
        return Num(0.0)
    raise LeptonError(f"no derivative for function {f!r}")  # pragma: no cover - table complete


# ---------------------------------------------------------------------------------------------
# Evaluation (NumPy, with C-library transcendental functions)


def _ipow(x, n: int):
    """x^n for an integer n by square-and-multiply (Lepton's integer powers); 1/x^|n| if n < 0."""
    m = abs(n)
    result = None
    base = x
    while m:
        if m & 1:
            result = base if result is None else result * base
        m >>= 1
        if m:
            base = base * base
    if result is None:
        return x * 0.0 + 1.0
    return 1.0 / result if n < 0 else result


_LIBM_SOURCES: dict[str, tuple[int, Callable]] = {
    "exp": (1, lambda x: math.exp(x)),
    "log": (1, lambda x: math.log(x) if x > 0 else (-math.inf if x == 0 else math.nan)),
    "sin": (1, lambda x: math.sin(x)),
    "cos": (1, lambda x: math.cos(x)),
    "tan": (1, lambda x: math.tan(x)),
    "asin": (1, lambda x: math.asin(x) if abs(x) <= 1.0 else math.nan),
    "acos": (1, lambda x: math.acos(x) if abs(x) <= 1.0 else math.nan),
    "atan": (1, lambda x: math.atan(x)),
    "sinh": (1, lambda x: math.sinh(x)),
    "cosh": (1, lambda x: math.cosh(x)),
    "tanh": (1, lambda x: math.tanh(x)),
    "erf": (1, lambda x: math.erf(x)),
    "erfc": (1, lambda x: math.erfc(x)),
    "atan2": (2, lambda y, x: math.atan2(y, x)),
    "pow": (2, lambda x, y: x**y),
}


@functools.cache
def _ufunc(name: str) -> Callable:
    """The C-library function ``name`` as a NumPy ufunc (numba.vectorize), compiled on first use."""
    from numba import vectorize  # noqa: PLC0415 - heavy optional import, compiled on first use only

    nargs, fn = _LIBM_SOURCES[name]
    return vectorize(["float64(float64)" if nargs == 1 else "float64(float64, float64)"])(fn)


def _pow() -> Callable:
    return _ufunc("pow")


def _lib(name: str) -> Callable:
    return lambda *a: _ufunc(name)(*a)


_ARITH: dict[str, Callable] = {
    "+": np.add,
    "-": np.subtract,
    "*": np.multiply,
    "/": np.divide,
}

_FUNC_EVAL: dict[str, Callable] = {
    "sqrt": np.sqrt,
    "exp": _lib("exp"),
    "log": _lib("log"),
    "sin": _lib("sin"),
    "cos": _lib("cos"),
    "sec": lambda x: 1.0 / _ufunc("cos")(x),
    "csc": lambda x: 1.0 / _ufunc("sin")(x),
    "tan": _lib("tan"),
    "cot": lambda x: 1.0 / _ufunc("tan")(x),
    "asin": _lib("asin"),
    "acos": _lib("acos"),
    "atan": _lib("atan"),
    "atan2": _lib("atan2"),
    "sinh": _lib("sinh"),
    "cosh": _lib("cosh"),
    "tanh": _lib("tanh"),
    "erf": _lib("erf"),
    "erfc": _lib("erfc"),
    "step": lambda x: np.where(x >= 0.0, 1.0, 0.0),
    "delta": lambda x: np.where(x == 0.0, 1.0, 0.0),
    "square": lambda x: x * x,
    "cube": lambda x: x * x * x,
    "recip": lambda x: 1.0 / x,
    "min": lambda a, b: np.where(a <= b, a, b),
    "max": lambda a, b: np.where(a >= b, a, b),
    "abs": np.abs,
    "floor": np.floor,
    "ceil": np.ceil,
    "select": lambda c, a, b: np.where(c != 0.0, a, b),
}


def evaluate(node: Node, r, params: Mapping[str, np.ndarray | float]) -> np.ndarray:
    """Value of the tree at distance ``r`` [length] with named parameters; broadcasts like NumPy.

    Non-finite results (division by zero, log of a negative number) are returned as inf/nan,
    not raised: the checks and the engine decide what is an error.
    """
    r = np.asarray(r, dtype=np.float64)
    with np.errstate(all="ignore"):
        out = np.asarray(_eval(node, r, params), dtype=np.float64)
    if out.shape != r.shape:  # a tree without r (a constant force): one value per r all the same
        out = np.array(np.broadcast_to(out, np.broadcast_shapes(out.shape, r.shape)))
    return out


def _eval(node: Node, r: np.ndarray, params: Mapping[str, np.ndarray | float]):
    if isinstance(node, Num):
        return np.float64(node.value)
    if isinstance(node, VarRef):
        if node.name == R:
            return r
        if node.name not in params:
            raise LeptonError(f"parameter {node.name!r} has no value")
        return np.asarray(params[node.name], dtype=np.float64)
    if isinstance(node, Unary):
        return -_eval(node.operand, r, params)
    if isinstance(node, Binary):
        a = _eval(node.left, r, params)
        if node.op == "^":
            n = _int_exponent(node.right)
            if n is not None:
                return _ipow(a, n)
            return _pow()(a, _eval(node.right, r, params))
        return _ARITH[node.op](a, _eval(node.right, r, params))
    args = [_eval(a, r, params) for a in node.args]  # type: ignore[union-attr]
    return _FUNC_EVAL[node.func](*args)  # type: ignore[union-attr]


def to_lepton(node: Node) -> str:
    """Write a tree back as Lepton text (parenthesised where needed; round-trips exactly)."""
    if isinstance(node, Num):
        v = node.value
        return repr(v) if v >= 0 else f"({v!r})"
    if isinstance(node, VarRef):
        return node.name
    if isinstance(node, Unary):
        return f"(-{to_lepton(node.operand)})"
    if isinstance(node, Binary):
        return f"({to_lepton(node.left)}{node.op}{to_lepton(node.right)})"
    return f"{node.func}({','.join(to_lepton(a) for a in node.args)})"  # type: ignore[union-attr]


# ---------------------------------------------------------------------------------------------
# A compiled expression wall


@dataclass(frozen=True)
class LeptonExpression:
    """A parsed expression wall: energy and force trees of ``r`` and the parameters.

    ``params`` is the ordered tuple of parameter names (every free name but ``r``);
    ``defaults`` holds the values given by ``;`` definitions in the text.
    """

    text: str
    energy: Node
    force: Node  # F = -dE/dr, simplified
    params: tuple[str, ...]
    defaults: Mapping[str, float]

    def energy_force(self, r, params: Mapping[str, np.ndarray | float]) -> tuple[np.ndarray, np.ndarray]:
        """Unshifted E(r) [energy] and F = -dE/dr [force] (F > 0 repulsive)."""
        p = {**self.defaults, **params}
        return evaluate(self.energy, r, p), evaluate(self.force, r, p)

    def shifted_energy(self, r, params: Mapping[str, np.ndarray | float], cutoff) -> np.ndarray:
        """E(r) - E(rc) [energy], as LAMMPS's wall/lepton reports it."""
        p = {**self.defaults, **params}
        with np.errstate(all="ignore"):
            return evaluate(self.energy, r, p) - evaluate(self.energy, cutoff, p)

    def lammps_text(self, values: Mapping[str, float] | None = None) -> str:
        """The expression with its parameters as Lepton ``;`` definitions (for a LAMMPS fix line)."""
        p = {**self.defaults, **(values or {})}
        defs = "".join(f"; {n}={float(p[n])!r}" for n in self.params)
        return f"{to_lepton(self.energy)}{defs}"

    def check(self, cutoff: float, params: Mapping[str, float], samples: int = 4096) -> None:
        """Refuse an expression that is not finite at the cut-off, or whose energy or force
        divides by zero for some r in (0, rc]: a denominator that is 0 at, or changes sign
        between, two of the points r = rc k/samples, k = 1..samples (the pole is then located by
        bisection)."""
        p = {**self.defaults, **params}
        missing = [n for n in self.params if n not in p]
        if missing:
            raise LeptonError(f"parameter(s) {', '.join(map(repr, missing))} have no value")
        rs = cutoff * np.arange(1, samples + 1, dtype=np.float64) / samples
        e, f = self.energy_force(np.float64(cutoff), p)
        if not (np.isfinite(e) and np.isfinite(f)):
            raise LeptonError(f"the expression is not finite at the cut-off r = {cutoff!r} (E = {e}, F = {f})")
        for tree, what in ((self.energy, "energy"), (self.force, "force")):
            bad = _division_by_zero(tree, rs, p)
            if bad is not None:
                raise LeptonError(f"division by zero in the {what} at r = {bad!r}")


def _denominators(node: Node) -> list[Node]:
    """Subtrees that are divided by: right of /, base of a negative integer power, recip's
    argument, and cos/sin/tan for sec/csc/cot."""
    out: list[Node] = []

    def walk(n: Node) -> None:
        if isinstance(n, Binary):
            walk(n.left)
            walk(n.right)
            if n.op == "/":
                out.append(n.right)
            elif n.op == "^" and (_int_exponent(n.right) or 0) < 0:
                out.append(n.left)
        elif isinstance(n, Unary):
            walk(n.operand)
        elif isinstance(n, Call):
            for a in n.args:
                walk(a)
            if n.func == "recip":
                out.append(n.args[0])
            elif n.func in ("sec", "csc", "cot"):
                out.append(Call({"sec": "cos", "csc": "sin", "cot": "tan"}[n.func], n.args))

    walk(node)
    return out


def _division_by_zero(node: Node, rs: np.ndarray, params: Mapping[str, float]) -> float | None:
    """The smallest r of the grid ``rs`` where a denominator of the tree is 0, or the root
    (bisected, 12 digits) of one that changes sign between neighbouring points; None if none."""
    found: list[float] = []
    for den in _denominators(node):
        v = np.broadcast_to(evaluate(den, rs, params), rs.shape)
        zero = np.flatnonzero(v == 0.0)
        if zero.size:
            found.append(float(rs[zero[0]]))
            continue
        ok = np.isfinite(v[:-1]) & np.isfinite(v[1:])
        change = np.flatnonzero(ok & (np.sign(v[:-1]) != np.sign(v[1:])))
        if change.size:
            a, b = float(rs[change[0]]), float(rs[change[0] + 1])
            va = float(evaluate(den, a, params))
            for _ in range(80):
                m = 0.5 * (a + b)
                vm = float(evaluate(den, m, params))
                if vm == 0.0 or m in (a, b):
                    break
                if np.sign(vm) == np.sign(va):
                    a, va = m, vm
                else:
                    b = m
            found.append(float(f"{0.5 * (a + b):.12g}"))
    return min(found) if found else None


def compile_expression(text: str, params: Iterable[str] = ()) -> LeptonExpression:
    """Parse a wall/lepton expression and derive its force (cached per text and parameter set).

    ``params`` are the parameter names the config supplies; every free name of the expression
    other than ``r`` must be one of them or a ``;`` definition. Raises LeptonError.
    """
    return _compile(text, tuple(sorted(set(params))))


@functools.lru_cache(maxsize=256)
def _compile(text: str, supplied: tuple[str, ...]) -> LeptonExpression:
    tree, defaults = parse_lepton(text)
    names = [n for n in free_names(tree) if n != R]
    unknown = [n for n in names if n not in defaults and n not in supplied]
    if unknown:
        raise LeptonError(
            f"unknown name(s) {', '.join(map(repr, unknown))} in {text!r}: the expression may use "
            "r, its ';' definitions and the wall's params"
        )
    unused = [n for n in supplied if n not in names]
    if unused:
        raise LeptonError(
            f"parameter(s) {', '.join(map(repr, unused))} are not used by the expression {text!r}"
        )
    energy = simplify(tree)
    force = simplify(_neg(derivative(energy)))
    order = tuple(n for n in names)
    return LeptonExpression(text, energy, force, order, dict(defaults))


# ---------------------------------------------------------------------------------------------
# Code generation: a numba-jittable scalar kernel from the trees


def _codegen(trees: Iterable[Node], params: tuple[str, ...], positional: bool = False) -> str:
    """:func:`_generate`, cached per trees, parameters and form (the compiled path asks for a
    face's sources at every chunk)."""
    return _generate(tuple(trees), tuple(params), positional)


@functools.lru_cache(maxsize=512)
def _generate(trees: tuple[Node, ...], params: tuple[str, ...], positional: bool = False) -> str:
    """Python source of ``kernel(r, p) -> (E, F)`` for scalar r and a parameter array p (or, with
    ``positional``, ``kernel(r, p0, p1, p2, rc, radius)`` returning the one tree's value, the
    signature of a compiled wall-style force); one statement per node, in the evaluation order of
    :func:`evaluate`."""
    lines: list[str] = []
    index = {n: i for i, n in enumerate(params)}
    counter = [0]

    def tmp(expr: str) -> str:
        name = f"t{counter[0]}"
        counter[0] += 1
        lines.append(f"    {name} = {expr}")
        return name

    def gen(n: Node) -> str:
        if isinstance(n, Num):
            return tmp(f"{n.value!r}") if math.isfinite(n.value) else tmp(f"float({str(n.value)!r})")
        if isinstance(n, VarRef):
            if n.name == R:
                return "r"
            return f"p{index[n.name]}" if positional else tmp(f"p[{index[n.name]}]")
        if isinstance(n, Unary):
            return tmp(f"-{gen(n.operand)}")
        if isinstance(n, Binary):
            a = gen(n.left)
            if n.op == "^":
                k = _int_exponent(n.right)
                if k is not None:
                    return _gen_ipow(a, k, tmp)
                return tmp(f"_pow({a}, {gen(n.right)})")
            b = gen(n.right)
            if n.op == "/":
                return tmp(f"_div({a}, {b})")
            return tmp(f"{a} {n.op} {b}")
        args = [gen(a) for a in n.args]  # type: ignore[union-attr]
        return tmp(_CALL_SRC[n.func].format(*args))  # type: ignore[union-attr]

    outs = [gen(t) for t in trees]
    body = "\n".join(lines) or "    pass"
    if positional:
        extra = ", ".join(f"p{i}" for i in range(len(params), POSITIONAL_PARAMS))
        head = "def kernel(r, " + ", ".join([f"p{i}" for i in range(len(params))] + ([extra] if extra else [])
                                         + ["rc", "radius"]) + "):"
        return f"{head}\n{body}\n    return {outs[0]}\n"
    return f"def kernel(r, p):\n{body}\n    return {', '.join(outs)}\n"


def _gen_ipow(a: str, n: int, tmp: Callable[[str], str]) -> str:
    m, result, base = abs(n), None, a
    while m:
        if m & 1:
            result = base if result is None else tmp(f"{result} * {base}")
        m >>= 1
        if m:
            base = tmp(f"{base} * {base}")
    if result is None:
        return tmp(f"{a} * 0.0 + 1.0")
    return tmp(f"_div(1.0, {result})") if n < 0 else result


_CALL_SRC: dict[str, str] = {
    "sqrt": "_sqrt({0})",
    "exp": "math.exp({0})",
    "log": "_log({0})",
    "sin": "math.sin({0})",
    "cos": "math.cos({0})",
    "sec": "_div(1.0, math.cos({0}))",
    "csc": "_div(1.0, math.sin({0}))",
    "tan": "math.tan({0})",
    "cot": "_div(1.0, math.tan({0}))",
    "asin": "(math.asin({0}) if abs({0}) <= 1.0 else math.nan)",
    "acos": "(math.acos({0}) if abs({0}) <= 1.0 else math.nan)",
    "atan": "math.atan({0})",
    "atan2": "math.atan2({0}, {1})",
    "sinh": "math.sinh({0})",
    "cosh": "math.cosh({0})",
    "tanh": "math.tanh({0})",
    "erf": "math.erf({0})",
    "erfc": "math.erfc({0})",
    "step": "(1.0 if {0} >= 0.0 else 0.0)",
    "delta": "(1.0 if {0} == 0.0 else 0.0)",
    "square": "{0} * {0}",
    "cube": "{0} * {0} * {0}",
    "recip": "_div(1.0, {0})",
    "min": "({0} if {0} <= {1} else {1})",
    "max": "({0} if {0} >= {1} else {1})",
    "abs": "abs({0})",
    "floor": "np.floor({0})",
    "ceil": "np.ceil({0})",
    "select": "({1} if {0} != 0.0 else {2})",
}


@functools.lru_cache(maxsize=1)
def _helpers() -> dict[str, Callable]:
    from numba import njit  # noqa: PLC0415 - compiled on first use only

    jit = njit(inline="always", error_model="numpy")

    @jit
    def _div(a, b):
        return a / b  # IEEE: x/0 = +-inf, 0/0 = nan (error_model="numpy")

    @jit
    def _sqrt(x):
        return math.sqrt(x) if x >= 0.0 else math.nan

    @jit
    def _log(x):
        if x > 0.0:
            return math.log(x)
        return -math.inf if x == 0.0 else math.nan

    @jit
    def _pow(x, y):
        return x**y

    return {"_div": _div, "_sqrt": _sqrt, "_log": _log, "_pow": _pow, "math": math, "np": np}


POSITIONAL_PARAMS = 3  # parameters a compiled wall-style force takes (p0, p1, p2)


def positional_kernels(expr: LeptonExpression) -> tuple[Callable, Callable] | None:
    """numba-jitted ``force(r, p0, p1, p2, rc, radius)`` and ``energy(...)`` (unshifted) of an
    expression with at most 3 parameters (in ``expr.params`` order), the signature of a compiled
    wall style; None with more parameters. Bit-identical to :meth:`LeptonExpression.energy_force`;
    cached per generated source."""
    if len(expr.params) > POSITIONAL_PARAMS:
        return None
    return tuple(_jit_positional(_codegen((tree,), expr.params, positional=True))  # type: ignore[return-value]
                 for tree in (expr.force, expr.energy))


@functools.lru_cache(maxsize=256)
def _jit_positional(source: str) -> Callable:
    from numba import njit  # noqa: PLC0415 - heavy optional import, compiled on first use only

    namespace = dict(_helpers())
    exec(compile(source, "<wall/lepton kernel>", "exec"), namespace)  # noqa: S102 - our own codegen
    return njit(nogil=True, error_model="numpy", inline="always")(namespace["kernel"])


def force_source(expr: LeptonExpression, name: str = "kernel") -> str | None:
    """Python source of ``name(r, p0, p1, p2, rc, radius)``, the force F = -dE/dr [force] of an
    expression with at most 3 parameters (None with more): the function :func:`positional_kernels`
    jits, for a generated module (:func:`generated_module`). It calls ``_div``, ``_sqrt``,
    ``_log``, ``_pow``, ``math`` and ``np``: a module imports them with ``HELPERS_IMPORT``."""
    if len(expr.params) > POSITIONAL_PARAMS:
        return None
    return _codegen((expr.force,), expr.params, positional=True).replace("def kernel(", f"def {name}(", 1)


def vector_force_source(expr: LeptonExpression, name: str = "kernel") -> str | None:
    """Python source of ``name(r, p)``, the force F = -dE/dr [force] of an expression with more
    than 3 parameters (None with fewer: :func:`force_source`), the parameters as one array p in
    ``expr.params`` order: the compiled path passes each face's values as a row of an array. The
    same generated statements as :func:`numba_kernel`'s force, so bit-identical to NumPy."""
    if len(expr.params) <= POSITIONAL_PARAMS:
        return None
    return _codegen((expr.force,), expr.params).replace("def kernel(", f"def {name}(", 1)


def energy_source(expr: LeptonExpression, name: str = "energy") -> str:
    """Python source of ``name(r, p0, p1, p2, rc, radius)`` (at most 3 parameters, as
    :func:`force_source`) or ``name(r, p)`` (more, the parameters as one array, as
    :func:`vector_force_source`): the unshifted energy E(r) [energy], the same generated
    statements as :func:`numba_kernel`'s energy, so bit-identical to :func:`evaluate`. The
    compiled path reports E(r) - E(rc) from it, as :func:`lepton_style`'s shifted energy does."""
    positional = len(expr.params) <= POSITIONAL_PARAMS
    return _codegen((expr.energy,), expr.params, positional=positional).replace("def kernel(", f"def {name}(", 1)


# the first lines of a generated module that calls the helpers of the generated kernels
HELPERS_IMPORT = ("from wallbatch.styles.lepton import _helpers as _lepton_helpers\n"
                  "globals().update(_lepton_helpers())\n")


def kernel_cache_dir() -> Path:
    """Where generated kernel modules are written (and numba caches their compiled code, in the
    ``__pycache__`` beside them): ``$WALLBATCH_CACHE_DIR``, else ``$XDG_CACHE_HOME/wallbatch``,
    else ``~/.cache/wallbatch``; a fresh temporary directory when that is not writable (then
    nothing outlives the process)."""
    env = os.environ.get("WALLBATCH_CACHE_DIR")
    base = Path(env) if env else Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "wallbatch"
    path = base / "kernels"
    try:
        path.mkdir(parents=True, exist_ok=True)
        probe = path / f".probe-{os.getpid()}"
        probe.write_text("")
        probe.unlink()
    except OSError:
        path = _temporary_dir()
    return path


@functools.lru_cache(maxsize=1)
def _temporary_dir() -> Path:
    return Path(tempfile.mkdtemp(prefix="wallbatch-kernels-"))


def generated_module(source: str, prefix: str = "wb") -> ModuleType:
    """Import generated Python ``source`` as a real module file, so that numba's ``cache=True``
    can cache what is compiled from it across processes (numba caches only functions with a
    source file). The file is ``kernel_cache_dir()/PREFIX_HASH.py``, HASH a digest of the
    source and the numba version, written once (atomically); the same source gives the same
    file, hence the same numba cache entries. Cached per process."""
    return _generated_module(source, prefix, str(kernel_cache_dir()))


def generated_path(source: str, prefix: str = "wb") -> Path:
    """The file :func:`generated_module` writes ``source`` to (whether or not it exists yet)."""
    import numba  # noqa: PLC0415 - heavy optional import, only where kernels are generated

    digest = hashlib.sha256(f"numba {numba.__version__}\n{source}".encode()).hexdigest()[:24]
    return kernel_cache_dir() / f"{prefix}_{digest}.py"


@functools.lru_cache(maxsize=64)
def _generated_module(source: str, prefix: str, directory: str) -> ModuleType:
    path = generated_path(source, prefix)
    digest = path.stem.rpartition("_")[2]
    if not path.exists() or path.read_text(encoding="utf-8") != source:
        tmp = path.with_suffix(f".{os.getpid()}.tmp")
        tmp.write_text(source, encoding="utf-8")
        os.replace(tmp, path)  # atomic: another process sees the whole file or none
    spec = importlib.util.spec_from_file_location(f"wallbatch_generated_{prefix}_{digest}", path)
    module = importlib.util.module_from_spec(spec)  # type: ignore[arg-type]
    sys.modules[spec.name] = module  # type: ignore[union-attr]  # numba finds a cached function's module by name
    spec.loader.exec_module(module)  # type: ignore[union-attr]
    return module


def kernel_source(expr: LeptonExpression) -> str:
    """The generated source of the scalar kernel (E, F) = kernel(r, p)."""
    return _codegen((expr.energy, expr.force), expr.params)


@functools.lru_cache(maxsize=128)
def _jit_kernel(source: str) -> Callable:
    from numba import njit  # noqa: PLC0415

    namespace = dict(_helpers())
    exec(compile(source, "<wall/lepton kernel>", "exec"), namespace)  # noqa: S102 - our own codegen
    return njit(inline="always", error_model="numpy")(namespace["kernel"])


def numba_kernel(expr: LeptonExpression) -> Callable:
    """A numba-jitted ``kernel(r, p) -> (E, F)`` for scalar r [length] and the parameter values
    p (float64 array in ``expr.params`` order); cached per generated source. Bit-identical to
    :meth:`LeptonExpression.energy_force`. Callable from other jitted code (inlined)."""
    return _jit_kernel(kernel_source(expr))


# ---------------------------------------------------------------------------------------------
# As a flat-wall style


def lepton_style(expr: LeptonExpression) -> WallStyle:
    """One face's expression as a wall style: the parameters are the expression's names (numbers)
    and the cut-off; force/energy take ``(r, *params, rc, radius)`` (the registry's positional
    form); the energy is shifted by E(rc) as LAMMPS does. Not a registry entry: an expression wall
    makes one per face (see wallbatch.engine.compiled for its compiled kernel)."""
    names = expr.params

    def values(a: tuple) -> dict:
        return {**expr.defaults, **dict(zip(names, a))}

    def force(r, *a):
        return evaluate(expr.force, r, values(a))

    def energy(r, *a):
        return evaluate(expr.energy, r, values(a))

    def shifted(r, *a):
        p = values(a)
        with np.errstate(all="ignore"):
            return evaluate(expr.energy, r, p) - evaluate(expr.energy, np.asarray(a[-2], dtype=np.float64), p)

    parameters = tuple(Param(n, "", variable=False, doc="a parameter of the expression") for n in names)
    return LeptonWallStyle("lepton", parameters + (cutoff_param(),), force=force, energy=energy,
                           shifted_fn=shifted, region=False, compiled=False, doc=f"wall/lepton {expr.text}",
                           expression=expr)


@dataclass(frozen=True)
class LeptonWallStyle(WallStyle):
    """A face's expression as a wall style; ``expression`` gives the compiled path its generated
    kernel (:func:`positional_kernels`)."""

    expression: LeptonExpression | None = None

    def generated_force(self) -> str | None:
        """The generated force source (:func:`force_source`; None with more than 3 parameters)."""
        return None if self.expression is None else force_source(self.expression)

    def generated_vector_force(self) -> str | None:
        """The generated force source with the parameters as an array (:func:`vector_force_source`;
        None with at most 3 parameters)."""
        return None if self.expression is None else vector_force_source(self.expression)

    def generated_energy(self) -> str | None:
        """The generated unshifted energy source E(r) (:func:`energy_source`), in the same form
        as the face's generated force (positional or an array of parameters)."""
        return None if self.expression is None else energy_source(self.expression)


# ---------------------------------------------------------------------------------------------
# The registry entry


@dataclass(frozen=True)
class LeptonEntry(WallStyle):
    """The registry entry of wall/lepton: each face's style is built from its expression
    (:func:`lepton_style`); the face's ``params`` are folded into the expression as Lepton ``;``
    definitions in a fix line."""

    def face_style(self, face: Mapping, wall: Mapping, base_dir: str) -> tuple[WallStyle, dict, object]:
        params = dict(face.get("params") or {})
        expr = compile_expression(face["expression"], tuple(params))
        values = {"cutoff": float(face["cutoff"]),
                  **{n: float(params.get(n, expr.defaults.get(n, 0.0))) for n in expr.params}}
        return lepton_style(expr), values, face["expression"]

    def check_face(self, face: Mapping, wall: Mapping, base_dir: str) -> list[tuple[str, str]]:
        """The expression parses, uses only r, its definitions and its params, is finite at the
        cut-off and divides by zero nowhere in (0, rc]."""
        params = dict(face.get("params") or {})
        if "cutoff" in params:
            return [("params.cutoff", "'cutoff' is the face's cut-off, not a parameter name")]
        try:
            compile_expression(face["expression"], tuple(params)).check(face["cutoff"], params)
        except LeptonError as exc:
            return [("expression", str(exc))]
        return []

    def fix_face(self, face: Mapping) -> dict:
        text = str(face.get("expression", ""))
        text += "".join(f"; {k}={float(v)!r}" for k, v in (face.get("params") or {}).items())
        return {"coord": face.get("coord"), "expression": text, "cutoff": face.get("cutoff")}

    def lammps_face(self, face: Mapping, params: Mapping[str, float], signature: object) -> dict:
        """The expression with this case's parameter values as ``;`` definitions."""
        expr = compile_expression(str(signature), tuple(face.get("params") or {}))
        values = {k: float(v) for k, v in params.items() if k != "cutoff"}
        return {"coord": face["coord"], "expression": expr.lammps_text(values), "cutoff": float(params["cutoff"])}

    def example(self, directory: str) -> tuple[dict, dict]:
        return {}, {"expression": "eps*(2/15*(sig/r)^9-(sig/r)^3); eps=1.3; sig=0.9", "cutoff": 2.5}


LEPTON = LeptonEntry(
    "lepton",
    (Param("expression", "energy", variable=False, kind="word", quoted=True,
           doc="the wall energy E(r) as a Lepton expression of r, the distance to the wall; `;` definitions "
               "allowed (F = -dE/dr is derived exactly; E is shifted to 0 at the cut-off)"),
     Param("params", "", variable=False, required=False, kind="mapping",
           doc="named numbers used by the expression (sweepable; written as `; name=value` definitions in "
               "the LAMMPS fix line); `cutoff` is reserved"),
     cutoff_param()),
    region=False, compiled=False, per_face=True, lammps_force_sign=-1.0,
    doc="E(r) from an expression, F = -dE/dr exactly")
