"""Tabulated walls (LAMMPS ``fix wall/table linear|spline N face coord file keyword cutoff``).

A table file holds one or more sections, each started by a keyword line and a parameter line
``N n [FP fplo fphi]``, then n lines ``index r e f``: distance from the wall r [length],
energy e [energy] and force f = -de/dr [force] (> 0 repulsive), r strictly increasing. Lines
starting with ``#`` and blank lines are ignored.

Interpolation follows LAMMPS (pinned by running LAMMPS):

1. the file's n points are resampled onto N equally spaced points from r_1 to r_n with cubic
   splines through the file values (end slopes: -f for the energy, FP fplo/fphi for the force,
   or the one-sided differences of the first and last two forces when FP is absent);
2. ``linear``: E and F are interpolated linearly between the two neighbouring grid points;
   ``spline``: cubic splines through the grid values (same end conditions) are evaluated;
3. the wall energy is E(r) - E_lin(rc): the offset at the cut-off is always a *linear* lookup,
   also for spline tables.

A distance outside [r_1, r_n] is an error (the table does not cover it).
"""

from __future__ import annotations

import functools
import math
import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from dataclasses import dataclass, field

import numpy as np

from wallbatch.styles.base import Param, WallStyle, cutoff_param
from wallbatch.styles.flat import STYLES
from wallbatch.styles.lepton import LeptonError, compile_expression, derivative, evaluate, simplify

__all__ = [
    "TableWallStyle",
    "TableEntry",
    "TABLE",
    "FaceError",
    "table_style",
    "TableError",
    "TableData",
    "read_table",
    "write_table",
    "WallTable",
    "spline_coefficients",
    "spline_eval",
    "linear_lookup",
    "spline_lookup",
    "tabulate",
    "table_source",
    "write_source_table",
]


MAX_TABLE_POINTS = 10_000_000  # points of a table (a written one, or the N it is resampled onto): memory


class TableError(ValueError):
    """A missing or malformed table file or section, or a distance outside the table. ``key``
    names the face key at fault (``file``, or ``keyword`` for a section the file lacks)."""

    def __init__(self, message: str, key: str = "file") -> None:
        super().__init__(message)
        self.key = key


@dataclass(frozen=True)
class TableData:
    """One keyword section of a table file (the file's own points)."""

    keyword: str
    r: np.ndarray  # (n,) [length], increasing
    e: np.ndarray  # (n,) [energy]
    f: np.ndarray  # (n,) [force]
    fplo: float | None  # dF/dr at r[0] and r[-1] from ``FP``, else None
    fphi: float | None
    path: str = ""
    line: int = 0  # 1-based line of the keyword


def _where(path: str, line: int) -> str:
    return f"{path}:{line}"


def read_table(path: str | os.PathLike, keyword: str) -> TableData:
    """Read section ``keyword`` of a LAMMPS wall/bond-style table file. Raises TableError
    naming ``file:line`` for a missing section, a bad parameter line or a bad data line."""
    path = os.fspath(path)
    try:
        with open(path, encoding="utf-8") as fh:
            lines = fh.read().splitlines()
    except OSError as exc:
        raise TableError(f"{path}: cannot read table file: {exc.strerror or exc}") from None
    i = 0
    while i < len(lines):
        words = lines[i].split("#", 1)[0].split()
        if not words:
            i += 1
            continue
        if words[0] != keyword:
            i += 1
            continue
        start = i + 1
        i += 1
        # parameter line
        while i < len(lines) and not lines[i].split("#", 1)[0].split():
            i += 1
        if i >= len(lines):
            raise TableError(f"{_where(path, start)}: section {keyword!r} has no 'N n' line")
        params = lines[i].split("#", 1)[0].split()
        pline = i + 1
        n, fplo, fphi = None, None, None
        k = 0
        try:
            while k < len(params):
                if params[k] == "N":
                    n = int(params[k + 1])
                    k += 2
                elif params[k] == "FP":
                    fplo, fphi = float(params[k + 1]), float(params[k + 2])
                    k += 3
                else:
                    raise TableError(
                        f"{_where(path, pline)}: unknown table parameter {params[k]!r} "
                        "(expected 'N n [FP fplo fphi]')"
                    )
        except TableError:
            raise
        except (IndexError, ValueError):
            raise TableError(
                f"{_where(path, pline)}: bad table parameter line {lines[i].strip()!r} "
                "(expected 'N n [FP fplo fphi]')"
            ) from None
        if n is None or n < 2:
            raise TableError(f"{_where(path, pline)}: section {keyword!r} needs 'N n' with n >= 2")
        i += 1
        rows: list[tuple[float, float, float]] = []
        while len(rows) < n:
            if i >= len(lines):
                raise TableError(
                    f"{_where(path, start)}: section {keyword!r} ends after {len(rows)} of {n} lines"
                )
            words = lines[i].split("#", 1)[0].split()
            i += 1
            if not words:
                continue
            try:
                if len(words) < 4:
                    raise ValueError
                rows.append((float(words[1]), float(words[2]), float(words[3])))
            except ValueError:
                raise TableError(
                    f"{_where(path, i)}: bad table line {lines[i - 1].strip()!r} "
                    "(expected 'index r e f')"
                ) from None
        a = np.array(rows, dtype=np.float64)
        r, e, f = a[:, 0].copy(), a[:, 1].copy(), a[:, 2].copy()
        if not np.all(np.diff(r) > 0):
            raise TableError(f"{_where(path, start)}: section {keyword!r}: r must increase")
        if r[0] <= 0.0:
            raise TableError(f"{_where(path, start)}: section {keyword!r}: r must be > 0")
        return TableData(keyword, r, e, f, fplo, fphi, path, start)
    raise TableError(f"{path}: no table section {keyword!r}: {_sections(lines)}", "keyword")


def _sections(lines: list[str]) -> str:
    """The section keywords of a table file (a word whose next non-blank line is 'N n ...'), said
    as what to write instead."""
    found, last = [], None
    for line in lines:
        words = line.split("#", 1)[0].split()
        if not words:
            continue
        if words[0] == "N" and last is not None and len(last) == 1:
            found.append(last[0])
        last = words
    return f"give one of {', '.join(found)}" if found else "the file has no section ('KEYWORD' then 'N n')"


def write_table(
    path: str | os.PathLike,
    keyword: str,
    r: Sequence[float],
    e: Sequence[float],
    f: Sequence[float],
    fp: tuple[float, float] | None = None,
    comment: str = "",
    append: bool = False,
) -> None:
    """Write one section in LAMMPS table format (values with 17 significant digits)."""
    with open(path, "a" if append else "w", encoding="utf-8") as fh:
        if comment:
            for c in comment.splitlines():
                fh.write(f"# {c}\n")
        fh.write(f"\n{keyword}\nN {len(r)}")
        if fp is not None:
            fh.write(f" FP {fp[0]!r} {fp[1]!r}")
        fh.write("\n\n")
        for k, (ri, ei, fi) in enumerate(zip(r, e, f, strict=True), start=1):
            fh.write(f"{k} {float(ri)!r} {float(ei)!r} {float(fi)!r}\n")


# ---------------------------------------------------------------------------------------------
# Cubic splines (clamped: given end slopes), the classic tridiagonal construction


def spline_coefficients(x: np.ndarray, y: np.ndarray, yp1: float, ypn: float) -> np.ndarray:
    """Second derivatives y2 of the cubic spline through (x, y) with end slopes yp1, ypn
    (a natural end where the slope is > 0.99e30). Sequential by nature (a tridiagonal solve)."""
    n = len(x)
    y2 = np.zeros(n)
    u = np.zeros(n)
    if yp1 > 0.99e30:
        y2[0] = u[0] = 0.0
    else:
        y2[0] = -0.5
        u[0] = (3.0 / (x[1] - x[0])) * ((y[1] - y[0]) / (x[1] - x[0]) - yp1)
    xl, yl = x.tolist(), y.tolist()
    y2l, ul = y2.tolist(), u.tolist()
    for i in range(1, n - 1):
        sig = (xl[i] - xl[i - 1]) / (xl[i + 1] - xl[i - 1])
        p = sig * y2l[i - 1] + 2.0
        y2l[i] = (sig - 1.0) / p
        ul[i] = (yl[i + 1] - yl[i]) / (xl[i + 1] - xl[i]) - (yl[i] - yl[i - 1]) / (xl[i] - xl[i - 1])
        ul[i] = (6.0 * ul[i] / (xl[i + 1] - xl[i - 1]) - sig * ul[i - 1]) / p
    if ypn > 0.99e30:
        qn = un = 0.0
    else:
        qn = 0.5
        un = (3.0 / (xl[n - 1] - xl[n - 2])) * (ypn - (yl[n - 1] - yl[n - 2]) / (xl[n - 1] - xl[n - 2]))
    y2l[n - 1] = (un - qn * ul[n - 2]) / (qn * y2l[n - 2] + 1.0)
    for k in range(n - 2, -1, -1):
        y2l[k] = y2l[k] * y2l[k + 1] + ul[k]
    return np.array(y2l)


def spline_eval(x: np.ndarray, y: np.ndarray, y2: np.ndarray, xv: np.ndarray) -> np.ndarray:
    """The spline (x, y, y2) at points xv (bisection for the interval, as for any grid)."""
    xv = np.asarray(xv, dtype=np.float64)
    klo = np.clip(np.searchsorted(x, xv, side="right") - 1, 0, len(x) - 2)
    khi = klo + 1
    h = x[khi] - x[klo]
    a = (x[khi] - xv) / h
    b = (xv - x[klo]) / h
    return a * y[klo] + b * y[khi] + ((a * a * a - a) * y2[klo] + (b * b * b - b) * y2[khi]) * (h * h) / 6.0


# ---------------------------------------------------------------------------------------------
# The resampled table and its lookups


def linear_lookup(r, i, grid, y, dy, invdelta):
    """y(r) by linear interpolation on the grid's interval i (grid[i] <= r), dy[i] = y[i+1] - y[i],
    invdelta = 1 / grid spacing. Plain arithmetic: NumPy arrays (r, i) or scalars in numba."""
    fraction = (r - grid[i]) * invdelta
    return y[i] + fraction * dy[i]


def spline_lookup(r, i, grid, y, y2, invdelta, deltasq6):
    """y(r) by the cubic spline (grid values y, second derivatives y2) on interval i;
    deltasq6 = spacing^2 / 6. Plain arithmetic, as :func:`linear_lookup`."""
    b = (r - grid[i]) * invdelta
    a = 1.0 - b
    ca = a * a * a - a
    cb = b * b * b - b
    return a * y[i] + b * y[i + 1] + (ca * y2[i] + cb * y2[i + 1]) * deltasq6


@dataclass(frozen=True)
class WallTable:
    """A table resampled onto N equally spaced points, ready for linear or spline lookups.

    ``lookup(r)`` returns (E, F) [energy], [force] unshifted; ``offset(rc)`` the energy LAMMPS
    subtracts (a linear lookup at rc).
    """

    tabstyle: str  # "linear" | "spline"
    lo: float
    hi: float
    delta: float
    invdelta: float
    r: np.ndarray  # (N,) grid
    e: np.ndarray
    f: np.ndarray
    de: np.ndarray  # (N-1,) e[i+1] - e[i]
    df: np.ndarray
    e2: np.ndarray  # (N,) spline second derivatives on the grid
    f2: np.ndarray
    deltasq6: float

    @classmethod
    def build(cls, data: TableData, tabstyle: str, n: int) -> WallTable:
        """Resample ``data`` onto n points (LAMMPS's N) for ``tabstyle`` linear or spline."""
        if tabstyle not in ("linear", "spline"):
            raise TableError(f"tabstyle must be 'linear' or 'spline', not {tabstyle!r}")
        if n < 2:
            raise TableError(f"N must be >= 2, not {n}")
        rf, ef, ff = data.r, data.e, data.f
        if data.fplo is None:
            fplo = (ff[1] - ff[0]) / (rf[1] - rf[0])
            fphi = (ff[-1] - ff[-2]) / (rf[-1] - rf[-2])
        else:
            fplo, fphi = data.fplo, data.fphi
        e2file = spline_coefficients(rf, ef, -ff[0], -ff[-1])
        f2file = spline_coefficients(rf, ff, fplo, fphi)
        lo, hi = float(rf[0]), float(rf[-1])
        delta = (hi - lo) / (n - 1)
        invdelta = 1.0 / delta
        grid = lo + np.arange(n) * delta
        e = spline_eval(rf, ef, e2file, grid)
        f = spline_eval(rf, ff, f2file, grid)
        de = e[1:] - e[:-1]
        df = f[1:] - f[:-1]
        e2 = spline_coefficients(grid, e, -f[0], -f[-1])
        f2 = spline_coefficients(grid, f, fplo, fphi)
        return cls(tabstyle, lo, hi, delta, invdelta, grid, e, f, de, df, e2, f2, delta * delta / 6.0)

    def below(self, r) -> np.ndarray | bool:
        """True where r [length] is too near for the table: (r - lo)/delta <= -1. As LAMMPS, the
        first interval reaches one interval below lo (the index int((r - lo)/delta) truncates
        toward 0 there, and the lookup extrapolates that interval)."""
        return (r - self.lo) * self.invdelta <= -1.0

    def inner(self) -> float:
        """The largest distance :meth:`below` refuses [length] (about lo - delta): r <= inner()
        exactly where below(r), as the lookup's arithmetic is monotone in r."""
        t = self.lo - self.delta
        while not self.below(t):
            t = np.nextafter(t, -np.inf)
        while self.below(np.nextafter(t, np.inf)):
            t = np.nextafter(t, np.inf)
        return float(t)

    def lookup(self, r, tabstyle: str | None = None) -> tuple[np.ndarray, np.ndarray]:
        """(E, F) at distances r [length] (any shape), unshifted. Raises TableError below the
        table's reach (:meth:`below`) or beyond its last distance hi."""
        style = tabstyle or self.tabstyle
        r = np.asarray(r, dtype=np.float64)
        out = self.below(r) | (r > self.hi)
        if np.any(out):
            raise TableError(
                f"distance {r[out].flat[0]!r} from the wall is outside the table [{self.lo!r}, {self.hi!r}] "
                f"and its first interval's extension down to {self.lo - self.delta!r}"
            )
        n = len(self.r)
        i = np.minimum(((r - self.lo) * self.invdelta).astype(np.int64), n - 2)  # as int() in the kernel
        if style == "linear":
            return (linear_lookup(r, i, self.r, self.e, self.de, self.invdelta),
                    linear_lookup(r, i, self.r, self.f, self.df, self.invdelta))
        return (spline_lookup(r, i, self.r, self.e, self.e2, self.invdelta, self.deltasq6),
                spline_lookup(r, i, self.r, self.f, self.f2, self.invdelta, self.deltasq6))

    def kernel_rows(self) -> np.ndarray:
        """The table as data for the compiled path: rows (6, N) = grid r, force F, and per
        tabstyle the force differences dF (linear; padded with a 0 to N) or the spline's second
        derivatives F2 (spline); energy E, dE or E2 likewise; and dE again (the offset at the
        cut-off is a linear lookup for either tabstyle). The compiled chunk kernel takes every
        face's rows concatenated and looks them up with the same :func:`linear_lookup` /
        :func:`spline_lookup` as :meth:`lookup` (jitted), so the two agree bit for bit and no
        table needs its own compile."""
        spline = self.tabstyle != "linear"
        de = np.append(self.de, 0.0)
        d = self.f2 if spline else np.append(self.df, 0.0)
        return np.ascontiguousarray(np.stack([self.r, self.f, d, self.e, self.e2 if spline else de, de]))

    def offset(self, cutoff: float) -> float:
        """E_lin(rc): the energy subtracted so the wall energy is 0 at the cut-off [energy]."""
        return float(self.lookup(np.float64(cutoff), "linear")[0])

    def shifted_energy_force(self, r, cutoff: float) -> tuple[np.ndarray, np.ndarray]:
        """(E(r) - E_lin(rc), F(r)) as LAMMPS's wall/table."""
        e, f = self.lookup(r)
        return e - self.offset(cutoff), f


def tabulate(energy_force, lo: float, hi: float, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Sample ``energy_force(r) -> (E, F)`` at n equally spaced r in [lo, hi] for a table file."""
    if not (0.0 < lo < hi) or n < 2 or not math.isfinite(hi):
        raise TableError(f"need 0 < lo < hi and n >= 2 (got lo={lo}, hi={hi}, n={n})")
    if n > MAX_TABLE_POINTS:
        raise TableError(f"n = {n:,}: a table has at most {MAX_TABLE_POINTS:,} points")
    r = lo + np.arange(n) * ((hi - lo) / (n - 1))
    r[-1] = hi
    e, f = energy_force(r)
    return r, np.asarray(e, dtype=np.float64), np.asarray(f, dtype=np.float64)


@dataclass(frozen=True)
class TableWallStyle(WallStyle):
    """A face's table as a wall style; an atom at one table interval or more below the table's
    first r is refused (LAMMPS extrapolates the first interval down to there)."""

    lo: float = 0.0
    delta: float = 0.0
    inner: float = 0.0  # WallTable.inner(): r <= inner is refused
    table: WallTable | None = field(default=None, compare=False)  # arrays: not part of ==, hash

    def too_close(self, p) -> float:
        return self.inner

    def too_close_message(self) -> str | None:
        return (f"nearer than {self.lo - self.delta:g}, one table interval below the table's first distance "
                f"{self.lo:g} (LAMMPS: Particle / wall distance < table inner cutoff)")


def table_style(table: WallTable) -> TableWallStyle:
    """One face's resampled table as a wall style (its one parameter: the cut-off): E(r) -
    E_lin(rc) and F(r) by the table's interpolation; functions of ``(r, p0, p1, p2, rc, radius)``."""

    def force(r, *a):
        return table.lookup(r)[1]

    def energy(r, *a):
        return table.lookup(r)[0]

    def shifted(r, *a):
        return table.lookup(r)[0] - table.lookup(a[-2], "linear")[0]

    return TableWallStyle("table", (cutoff_param(),), force=force, energy=energy, shifted_fn=shifted,
                          region=False, compiled=False, doc="wall/table", lo=table.lo, delta=table.delta,
                          inner=table.inner(), table=table)


def table_source(source: str, params: dict[str, float]):
    """(energy_force(r) -> (E, F), dF/dr(r) or None) for a built-in flat style name (lj93, lj126,
    lj1043, harmonic, morse; its LAMMPS parameters in ``params``) or a wall/lepton expression of r
    (its parameters in ``params``; dF/dr is the symbolic second derivative)."""
    if source in STYLES:
        style = STYLES[source]
        if style.needs_radius:
            raise TableError(f"style {source} depends on the particle radius: it cannot be one table")
        need = [k for k in style.params if k not in params and style.param(k).required]
        if need:
            raise TableError(f"style {source} needs {', '.join(need)} (give --param name=value)")
        unknown = sorted(set(params) - set(style.params))
        if unknown:
            raise TableError(f"style {source} takes {', '.join(style.params)}, not {', '.join(unknown)}")
        p = {k: float(v) for k, v in params.items()}
        return (lambda r: style.energy_force(r, p)), None
    try:
        expr = compile_expression(source, tuple(params))
    except LeptonError as exc:
        raise TableError(f"{source!r} is neither a wall style ({', '.join(sorted(STYLES))}) nor a valid expression: "
                         f"{exc}") from None
    p = {k: float(v) for k, v in params.items()}
    dfdr = simplify(derivative(expr.force))
    return (lambda r: expr.energy_force(r, p)), (lambda r: evaluate(dfdr, r, {**expr.defaults, **p}))


def _section_line(path, keyword: str) -> int | None:
    """The line (1-based) of the first section ``keyword`` of the table file at ``path``, found as
    :func:`read_table` (and LAMMPS) find it: the first line whose first word is the keyword; None
    if there is none or no such file."""
    try:
        with open(path, encoding="utf-8") as fh:
            for k, line in enumerate(fh, start=1):
                words = line.split("#", 1)[0].split()
                if words and words[0] == keyword:
                    return k
    except (OSError, UnicodeDecodeError):
        return None
    return None


def write_source_table(path, source: str, params: dict[str, float], lo: float, hi: float, n: int,
                       keyword: str, append: bool = False) -> None:
    """Tabulate a style or expression on n equally spaced points of [lo, hi] into a LAMMPS table
    section (with FP from the exact dF/dr for an expression)."""
    if not keyword or len(keyword.split()) != 1 or keyword.startswith("#"):
        raise TableError(f"keyword {keyword!r}: a section keyword is one word (LAMMPS reads the line's first word)")
    if append:
        taken = _section_line(path, keyword)
        if taken is not None:
            raise TableError(f"{_where(os.fspath(path), taken)}: the file already has a section {keyword!r}; LAMMPS "
                             f"(and wallbatch) read the first section of a keyword, so the appended one would never "
                             f"be read: choose another keyword (-k), or write a new file")
    cutoff = params.get("cutoff")
    if source in STYLES and cutoff is not None and hi < cutoff:
        raise TableError(f"hi = {hi:g} is below the wall's cut-off {cutoff:g}: wall/table needs the table to reach "
                         f"the cut-off (LAMMPS: wall cutoff is larger than table outer cutoff); give --hi {cutoff:g} "
                         "or more")
    energy_force, dfdr = table_source(source, params)
    with np.errstate(all="ignore"):  # (overflow near r = 0: refused just below, without NumPy's warning)
        r, e, f = tabulate(energy_force, lo, hi, n)
    if not (np.all(np.isfinite(e)) and np.all(np.isfinite(f))):
        bad = float(r[~(np.isfinite(e) & np.isfinite(f))][0])
        raise TableError(f"{source!r} is not finite at r = {bad:g}: choose a larger lo")
    fp = None if dfdr is None else (float(dfdr(np.float64(lo))), float(dfdr(np.float64(hi))))
    text = ", ".join(f"{k}={v!r}" for k, v in params.items())
    write_table(path, keyword, r, e, f, fp=fp, append=append,
                comment=f"wallbatch table: {source}{' with ' + text if text else ''}, {n} points on [{lo!r}, {hi!r}]")


# ---------------------------------------------------------------------------------------------
# The registry entry


class FaceError(ValueError):
    """A face that cannot be built: ``key`` names its config key."""

    def __init__(self, key: str, message: str) -> None:
        super().__init__(message)
        self.key = key


@functools.lru_cache(maxsize=64)
def _table(path: str, keyword: str, tabstyle: str, n: int) -> WallTable:
    return WallTable.build(read_table(path, keyword), tabstyle, n)


def _file(face: Mapping, base_dir: str) -> Path:
    path = Path(face["file"])
    return (path if path.is_absolute() else Path(base_dir) / path).resolve()


@dataclass(frozen=True)
class TableEntry(WallStyle):
    """The registry entry of wall/table: each face's style is its table file's section, resampled
    (:class:`WallTable`) for the wall's tabstyle and N; files are relative to the config."""

    def face_style(self, face: Mapping, wall: Mapping, base_dir: str) -> tuple[WallStyle, dict, object]:
        path = str(_file(face, base_dir))
        try:
            table = _table(path, face["keyword"], wall["tabstyle"], int(wall["N"]))
        except TableError as exc:
            raise FaceError(exc.key, str(exc)) from None
        return table_style(table), {"cutoff": float(face["cutoff"])}, (path, face["keyword"], wall["tabstyle"],
                                                                        int(wall["N"]))

    def check_face(self, face: Mapping, wall: Mapping, base_dir: str) -> list[tuple[str, str]]:
        """The file and its section read, and the cut-off lies inside the table."""
        try:
            data = read_table(_file(face, base_dir), face["keyword"])
        except TableError as exc:
            return [(exc.key, str(exc))]
        if face["cutoff"] > data.r[-1]:
            return [("cutoff", f"cutoff {face['cutoff']:g} is beyond the table's last distance {data.r[-1]:g} "
                               "(LAMMPS: Fix wall/table wall cutoff is larger than table outer cutoff): give a "
                               f"cutoff <= {data.r[-1]:g}, or a table that reaches further")]
        return []

    def lammps_face(self, face: Mapping, params: Mapping[str, float], signature: object) -> dict:
        """The table file by its absolute path."""
        path, keyword = signature[0], signature[1]  # type: ignore[index]
        return {"coord": face["coord"], "file": path, "keyword": keyword, "cutoff": float(params["cutoff"])}

    def example(self, directory: str) -> tuple[dict, dict]:
        path = Path(directory) / "example.table"
        lj93 = compile_expression("eps*(2/15*(sig/r)^9-(sig/r)^3); eps=1.3; sig=0.9")
        r, e, f = tabulate(lambda r: lj93.energy_force(r, {}), 0.05, 3.0, 600)
        write_table(path, "LJ93", r, e, f)
        return {"tabstyle": "linear", "N": 1000}, {"file": str(path), "keyword": "LJ93", "cutoff": 2.5}


TABLE = TableEntry(
    "table",
    (Param("file", "", variable=False, kind="word", doc="a LAMMPS table file (relative to the config)"),
     Param("keyword", "", variable=False, kind="word", doc="the keyword of the file's section"),
     cutoff_param()),
    wall_parameters=(Param("tabstyle", "", variable=False, kind="choice", choices=("linear", "spline"),
                           doc="interpolation: linear or spline (as LAMMPS)"),
                     Param("N", "", variable=False, kind="integer", min=2, max=MAX_TABLE_POINTS,
                           doc="the number of points the table is resampled onto (as LAMMPS)")),
    region=False, compiled=False, per_face=True, doc="a tabulated wall")
