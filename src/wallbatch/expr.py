"""LAMMPS equal-style variable expressions: a safe parser and a vectorised evaluator.

The grammar and semantics follow LAMMPS's ``variable`` command (config.md "Variables",
physics.md section 10): ``^`` is left-associative, unary ``-`` and ``!`` bind tighter than ``^``,
``%`` is C's fmod, ``log`` is base 10, ``round(x)`` is floor(x + 0.5).  Expressions are parsed
by a hand-written tokenizer and a precedence-climbing parser into a tree of frozen dataclasses
and evaluated with numpy over the case axis; Python ``eval`` is never used.

Like LAMMPS, every operand and function argument is evaluated (no short circuit), so an error
such as a division by zero in an unselected ``ternary`` branch is still an error.
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

import numpy as np

__all__ = [
    "VariableError",
    "EvalContext",
    "Variables",
    "parse",
    "to_lammps",
    "Node",
    "Num",
    "Keyword",
    "VarRef",
    "Unary",
    "Binary",
    "Call",
    "FUNCTIONS",
    "KEYWORDS",
    "TIME_NAMES",
]


class VariableError(ValueError):
    """An invalid variable expression, reference, cycle or evaluation (e.g. divide by zero).
    `variable` names the variable it belongs to, where known."""

    def __init__(self, message: str, variable: str | None = None) -> None:
        super().__init__(message)
        self.variable = variable


class _NamedError(VariableError):
    """An evaluation error already prefixed with the variable it occurred in."""


# ---------------------------------------------------------------------------------------------
# AST


@dataclass(frozen=True)
class Num:
    """A number literal (``PI`` parses to ``Num(math.pi)``)."""

    value: float


@dataclass(frozen=True)
class Keyword:
    """A thermo keyword such as ``step`` or ``lx``."""

    name: str


@dataclass(frozen=True)
class VarRef:
    """A reference ``v_name`` to another variable (``name`` without the ``v_`` prefix)."""

    name: str


@dataclass(frozen=True)
class Unary:
    """``-x`` or ``!x``."""

    op: str
    operand: Node


@dataclass(frozen=True)
class Binary:
    """``left op right`` for an arithmetic, comparison or logical operator."""

    op: str
    left: Node
    right: Node


@dataclass(frozen=True)
class Call:
    """A function call ``func(args...)``."""

    func: str
    args: tuple[Node, ...]


Node = Num | Keyword | VarRef | Unary | Binary | Call

#: Function name -> number of arguments.
FUNCTIONS: dict[str, int] = {
    "sqrt": 1, "exp": 1, "ln": 1, "log": 1, "abs": 1,
    "sin": 1, "cos": 1, "tan": 1, "asin": 1, "acos": 1, "atan": 1, "atan2": 2,
    "floor": 1, "ceil": 1, "round": 1, "ternary": 3, "min": 2, "max": 2,
    "ramp": 2, "vdisplace": 2, "swiggle": 3, "cwiggle": 3,
}  # fmt: skip

#: Thermo keywords usable in expressions.
KEYWORDS: frozenset[str] = frozenset(
    "step elapsed elaplong dt time xlo xhi ylo yhi zlo zhi lx ly lz vol atoms".split()
)

#: Keywords and functions whose value can change during a run.
TIME_NAMES: frozenset[str] = frozenset(
    "step elapsed elaplong dt time ramp vdisplace swiggle cwiggle".split()
)

# Binary operator -> binding power (higher binds tighter); all are left-associative.
_BINARY_BP: dict[str, int] = {
    "||": 1, "|^": 1,
    "&&": 2,
    "==": 3, "!=": 3,
    "<": 4, "<=": 4, ">": 4, ">=": 4,
    "+": 5, "-": 5,
    "*": 6, "/": 6, "%": 6,
    "^": 7,
}  # fmt: skip
_UNARY_BP = 8

# ---------------------------------------------------------------------------------------------
# Tokenizer and parser

_TOKEN_RE = re.compile(
    r"""
    (?P<ws>\s+)
  | (?P<num>(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?)
  | (?P<name>[A-Za-z_][A-Za-z0-9_]*)
  | (?P<op>\|\||\|\^|&&|==|!=|<=|>=|[-+*/^%<>!(),])
    """,
    re.VERBOSE,
)


@dataclass(frozen=True)
class _Token:
    kind: str  # "num" | "name" | "op" | "end"
    text: str
    pos: int


def _tokenize(text: str) -> list[_Token]:
    tokens: list[_Token] = []
    pos = 0
    while pos < len(text):
        m = _TOKEN_RE.match(text, pos)
        if m is None:
            raise VariableError(
                f"syntax error at position {pos} in {text!r}: unexpected character {text[pos]!r}"
            )
        if m.lastgroup != "ws":
            tokens.append(_Token(m.lastgroup or "", m.group(), pos))
        pos = m.end()
    tokens.append(_Token("end", "", len(text)))
    return tokens


class _Parser:
    def __init__(self, text: str) -> None:
        self.text = text
        self.tokens = _tokenize(text)
        self.i = 0

    def error(self, tok: _Token, msg: str) -> VariableError:
        where = "end of expression" if tok.kind == "end" else f"{tok.text!r}"
        return VariableError(
            f"syntax error at position {tok.pos} in {self.text!r}: {msg} (at {where})"
        )

    def peek(self) -> _Token:
        return self.tokens[self.i]

    def next(self) -> _Token:
        tok = self.tokens[self.i]
        self.i += 1
        return tok

    def expect(self, text: str) -> _Token:
        tok = self.next()
        if tok.text != text or tok.kind != "op":
            raise self.error(tok, f"expected {text!r}")
        return tok

    def expression(self, min_bp: int = 0) -> Node:
        left = self.prefix()
        while True:
            tok = self.peek()
            bp = _BINARY_BP.get(tok.text) if tok.kind == "op" else None
            if bp is None or bp < min_bp:
                return left
            self.next()
            left = Binary(tok.text, left, self.expression(bp + 1))

    def prefix(self) -> Node:
        tok = self.next()
        if tok.kind == "num":
            return Num(float(tok.text))
        if tok.kind == "op" and tok.text in ("-", "!"):
            return Unary(tok.text, self.expression(_UNARY_BP))
        if tok.kind == "op" and tok.text == "(":
            node = self.expression()
            self.expect(")")
            return node
        if tok.kind == "name":
            return self.name(tok)
        raise self.error(tok, "expected a value")

    def name(self, tok: _Token) -> Node:
        word = tok.text
        if self.peek().kind == "op" and self.peek().text == "(":
            if word not in FUNCTIONS:
                raise VariableError(
                    f"unknown function {word!r} at position {tok.pos} in {self.text!r}"
                )
            self.next()
            args: list[Node] = []
            if not (self.peek().kind == "op" and self.peek().text == ")"):
                args.append(self.expression())
                while self.peek().kind == "op" and self.peek().text == ",":
                    self.next()
                    args.append(self.expression())
            self.expect(")")
            n = FUNCTIONS[word]
            if len(args) != n:
                plural = "argument" if n == 1 else "arguments"
                raise VariableError(
                    f"Invalid {word} function in variable formula: must have {n} {plural} "
                    f"(got {len(args)}, at position {tok.pos} in {self.text!r})"
                )
            return Call(word, tuple(args))
        if word.startswith("v_"):
            if len(word) == 2:
                raise self.error(tok, "empty variable name after 'v_'")
            return VarRef(word[2:])
        if word == "PI":
            return Num(math.pi)
        if word in KEYWORDS:
            return Keyword(word)
        if word in FUNCTIONS:
            raise VariableError(
                f"function {word!r} needs arguments, at position {tok.pos} in {self.text!r}"
            )
        raise VariableError(
            f"unknown keyword {word!r} at position {tok.pos} in {self.text!r}"
        )


def parse(text: str) -> Node:
    """Parse an equal-style expression into an AST; raises VariableError on invalid text."""
    if not isinstance(text, str):
        raise VariableError(f"expression must be a string, not {type(text).__name__}")
    parser = _Parser(text)
    node = parser.expression()
    tok = parser.peek()
    if tok.kind != "end":
        raise parser.error(tok, "unexpected text after the expression")
    return node


def _walk(node: Node):
    """Yield every node of the tree."""
    yield node
    if isinstance(node, Unary):
        yield from _walk(node.operand)
    elif isinstance(node, Binary):
        yield from _walk(node.left)
        yield from _walk(node.right)
    elif isinstance(node, Call):
        for arg in node.args:
            yield from _walk(arg)


def to_lammps(node: Node) -> str:
    """Write an AST back as LAMMPS text (fully parenthesised; ``min``/``max`` as ``ternary``)."""
    if isinstance(node, Num):
        return repr(float(node.value))
    if isinstance(node, Keyword):
        return node.name
    if isinstance(node, VarRef):
        return f"v_{node.name}"
    if isinstance(node, Unary):
        return f"({node.op}({to_lammps(node.operand)}))"
    if isinstance(node, Binary):
        return f"({to_lammps(node.left)}{node.op}{to_lammps(node.right)})"
    a = [to_lammps(arg) for arg in node.args]
    if node.func == "min":
        return f"ternary(({a[0]})<=({a[1]}),{a[0]},{a[1]})"
    if node.func == "max":
        return f"ternary(({a[0]})>=({a[1]}),{a[0]},{a[1]})"
    return f"{node.func}({','.join(a)})"


# ---------------------------------------------------------------------------------------------
# Evaluation


@dataclass(frozen=True)
class EvalContext:
    """Values the thermo keywords and time functions see, vectorised over the case axis (C,).

    Any field may be a scalar or a per-case array of shape (C,) (box components and atoms too).
    """

    step: np.ndarray | int  # current step n
    begin_step: int  # b: the run's first step
    end_step: int  # e: the run's last step
    dt: np.ndarray | float  # current timestep
    time: np.ndarray | float  # accumulated simulated time
    elapsed_time: np.ndarray | float  # (n-b)*dt, or elapsed simulated time under dt/reset
    ramp_fraction: np.ndarray | float  # f of ramp(x,y) = x + f*(y-x)
    box_lo: tuple[float, float, float]
    box_hi: tuple[float, float, float]
    atoms: int
    values: Mapping[str, np.ndarray] = field(default_factory=dict)  # per-case values that replace
    # the expressions of these variables (numeric constants swept over a batch)


Array = np.ndarray
_F = np.float64


def _check(bad: Array, msg: str) -> None:
    if np.any(bad):
        raise VariableError(msg)


def _div(a: Array, b: Array) -> Array:
    _check(b == 0, "Divide by 0 in variable formula")
    return a / b


def _mod(a: Array, b: Array) -> Array:
    _check(b == 0, "Modulo 0 in variable formula")
    return np.fmod(a, b)


def _pow(a: Array, b: Array) -> Array:
    _check((a == 0) & (b < 0), "Invalid power expression in variable formula (0 to a negative power)")
    return np.power(a, b)


def _truth(x: Array) -> Array:
    return x != 0


_BINARY_FUNCS: dict[str, Callable[[Array, Array], Array]] = {
    "+": np.add,
    "-": np.subtract,
    "*": np.multiply,
    "/": _div,
    "%": _mod,
    "^": _pow,
    "<": lambda a, b: (a < b).astype(_F),
    "<=": lambda a, b: (a <= b).astype(_F),
    ">": lambda a, b: (a > b).astype(_F),
    ">=": lambda a, b: (a >= b).astype(_F),
    "==": lambda a, b: (a == b).astype(_F),
    "!=": lambda a, b: (a != b).astype(_F),
    "&&": lambda a, b: (_truth(a) & _truth(b)).astype(_F),
    "||": lambda a, b: (_truth(a) | _truth(b)).astype(_F),
    "|^": lambda a, b: (_truth(a) ^ _truth(b)).astype(_F),
}


def _sqrt(x: Array) -> Array:
    _check(x < 0, "Sqrt of negative value in variable formula")
    return np.sqrt(x)


def _ln(x: Array) -> Array:
    _check(x <= 0, "Log of zero/negative value in variable formula")
    return np.log(x)


def _log(x: Array) -> Array:
    _check(x <= 0, "Log of zero/negative value in variable formula")
    return np.log10(x)


def _asin(x: Array) -> Array:
    _check(np.abs(x) > 1, "Arcsin of invalid value in variable formula")
    return np.arcsin(x)


def _acos(x: Array) -> Array:
    _check(np.abs(x) > 1, "Arccos of invalid value in variable formula")
    return np.arccos(x)


_MATH_FUNCS: dict[str, Callable[..., Array]] = {
    "sqrt": _sqrt,
    "exp": np.exp,
    "ln": _ln,
    "log": _log,
    "abs": np.abs,
    "sin": np.sin,
    "cos": np.cos,
    "tan": np.tan,
    "asin": _asin,
    "acos": _acos,
    "atan": np.arctan,
    "atan2": np.arctan2,
    "floor": np.floor,
    "ceil": np.ceil,
    "round": lambda x: np.floor(x + 0.5),
    "ternary": lambda c, a, b: np.where(c != 0, a, b),
    "min": np.minimum,
    "max": np.maximum,
}


def _omega(func: str, z: Array) -> Array:
    _check(z == 0, f"Invalid {func}(x,y,z) function in variable formula: z must be > 0")
    return 2.0 * np.pi / z


def _keyword(word: str, ctx: EvalContext) -> Array:
    f = lambda v: np.asarray(v, dtype=_F)  # noqa: E731
    if word == "step":
        return f(ctx.step)
    if word in ("elapsed", "elaplong"):
        return f(ctx.step) - ctx.begin_step
    if word == "dt":
        return f(ctx.dt)
    if word == "time":
        return f(ctx.time)
    if word == "atoms":
        return f(ctx.atoms)
    lo = [f(ctx.box_lo[i]) for i in range(3)]
    hi = [f(ctx.box_hi[i]) for i in range(3)]
    if word[0] in "xyz" and word[1:] in ("lo", "hi"):
        i = "xyz".index(word[0])
        return lo[i] if word[1:] == "lo" else hi[i]
    length = [hi[i] - lo[i] for i in range(3)]
    if word == "vol":
        return length[0] * length[1] * length[2]
    return length["xyz".index(word[1])]  # lx ly lz


def _case_shape(ctx: EvalContext) -> tuple[int, ...]:
    fields = [ctx.step, ctx.dt, ctx.time, ctx.elapsed_time, ctx.ramp_fraction, ctx.atoms]
    fields += [ctx.box_lo[i] for i in range(3)] + [ctx.box_hi[i] for i in range(3)]
    try:
        return np.broadcast_shapes(*(np.shape(v) for v in fields))
    except ValueError as exc:
        raise VariableError(f"EvalContext fields have inconsistent case shapes: {exc}") from None


class Variables:
    """A set of named equal-style variables, parsed and checked on construction."""

    def __init__(self, exprs: Mapping[str, str | int | float]) -> None:
        self._ast: dict[str, Node] = {}
        for name, text in exprs.items():
            if not isinstance(name, str) or not re.fullmatch(r"[A-Za-z0-9_]+", name):
                raise VariableError(
                    f"invalid variable name {name!r}: use letters, digits and underscores", name
                )
            if isinstance(text, (int, float)) and not isinstance(text, bool):
                self._ast[name] = Num(float(text))
                continue
            try:
                self._ast[name] = parse(text)
            except VariableError as exc:
                raise VariableError(f"variable {name!r}: {exc}", name) from None
        self._refs: dict[str, tuple[str, ...]] = {}
        for name, node in self._ast.items():
            refs = tuple(dict.fromkeys(n.name for n in _walk(node) if isinstance(n, VarRef)))
            for ref in refs:
                if ref not in self._ast:
                    raise VariableError(
                        f"variable {name!r} references unknown variable 'v_{ref}'", name
                    )
            self._refs[name] = refs
        self._check_cycles()
        self._uses: dict[str, frozenset[str]] = {}
        for name in self._ast:
            self._collect_uses(name)

    def _check_cycles(self) -> None:
        done: set[str] = set()
        for name in self._ast:
            self._visit(name, [], done)

    def _visit(self, name: str, path: list[str], done: set[str]) -> None:
        """Depth-first walk of the references from `name` (a method, not a nested function: a
        recursive closure is a reference cycle, and one per case was garbage left to the
        collector's full passes)."""
        if name in path:
            cycle = path[path.index(name):] + [name]
            raise VariableError(f"cycle between variables: {' -> '.join(cycle)}", name)
        if name in done:
            return
        path.append(name)
        for ref in self._refs[name]:
            self._visit(ref, path, done)
        path.pop()
        done.add(name)

    def _collect_uses(self, name: str) -> frozenset[str]:
        if name not in self._uses:
            own = {
                n.func if isinstance(n, Call) else n.name
                for n in _walk(self._ast[name])
                if isinstance(n, (Call, Keyword))
            }
            for ref in self._refs[name]:
                own |= self._collect_uses(ref)
            self._uses[name] = frozenset(own)
        return self._uses[name]

    def _get(self, name: str) -> Node:
        if name not in self._ast:
            raise VariableError(f"unknown variable {name!r}")
        return self._ast[name]

    def names(self) -> list[str]:
        """Variable names in definition order."""
        return list(self._ast)

    def ast(self, name: str) -> Node:
        """The parsed expression of a variable."""
        return self._get(name)

    def uses(self, name: str) -> frozenset[str]:
        """Function names and thermo keywords used by the variable, transitively."""
        self._get(name)
        return self._uses[name]

    def depends_on_time(self, name: str) -> bool:
        """True if the value can change during a run (step, dt, time, ramp, ... transitively)."""
        return bool(self.uses(name) & TIME_NAMES)

    def constant_value(self, name: str) -> float | None:
        """The value if it uses no thermo keyword or time function, else None."""
        if self.uses(name) & (KEYWORDS | TIME_NAMES):
            return None
        return float(self._evaluate(name, None, {}, ()))

    def evaluate(self, name: str, ctx: EvalContext) -> np.ndarray:
        """The value as a float64 array of the case shape (C,) (or () if ctx is all scalars)."""
        self._get(name)
        shape = _case_shape(ctx)
        memo = {k: np.asarray(v, dtype=_F) for k, v in ctx.values.items()} if ctx is not None else {}
        value = self._evaluate(name, ctx, memo, ())
        return np.array(np.broadcast_to(value, shape), dtype=_F)

    def _evaluate(
        self, name: str, ctx: EvalContext | None, memo: dict[str, Array], chain: tuple[str, ...]
    ) -> Array:
        if name in memo:
            return memo[name]
        chain = chain + (name,)
        try:
            with np.errstate(all="ignore"):
                value = self._eval_node(self._ast[name], ctx, memo, chain)
        except _NamedError:
            raise
        except VariableError as exc:
            via = f" (via {' -> '.join(chain)})" if len(chain) > 1 else ""
            raise _NamedError(f"variable {name!r}{via}: {exc}") from None
        memo[name] = value
        return value

    def _eval_node(
        self, node: Node, ctx: EvalContext | None, memo: dict[str, Array], chain: tuple[str, ...]
    ) -> Array:
        ev = lambda n: self._eval_node(n, ctx, memo, chain)  # noqa: E731
        if isinstance(node, Num):
            return np.asarray(node.value, dtype=_F)
        if isinstance(node, VarRef):
            return self._evaluate(node.name, ctx, memo, chain)
        if isinstance(node, Keyword):
            if ctx is None:
                raise VariableError(f"thermo keyword {node.name!r} needs an evaluation context")
            return _keyword(node.name, ctx)
        if isinstance(node, Unary):
            x = ev(node.operand)
            return -x if node.op == "-" else (x == 0).astype(_F)
        if isinstance(node, Binary):
            return _BINARY_FUNCS[node.op](ev(node.left), ev(node.right))
        args = [ev(a) for a in node.args]
        if node.func in _MATH_FUNCS:
            return np.asarray(_MATH_FUNCS[node.func](*args), dtype=_F)
        if ctx is None:
            raise VariableError(f"function {node.func!r} needs an evaluation context")
        elapsed = np.asarray(ctx.elapsed_time, dtype=_F)
        if node.func == "ramp":
            x, y = args
            return x + np.asarray(ctx.ramp_fraction, dtype=_F) * (y - x)
        if node.func == "vdisplace":
            x, y = args
            return x + y * elapsed
        x, y, z = args
        omega = _omega(node.func, z)
        if node.func == "swiggle":
            return x + y * np.sin(omega * elapsed)
        return x + y * (1.0 - np.cos(omega * elapsed))  # cwiggle
