"""The one reader of LAMMPS log files: thermo tables and minimization statistics.

A thermo table starts at a header line whose first word is `Step` (the column names of
`thermo_style custom`, e.g. `Step PotEng f_w`) and ends at the `Loop time of ...` line of its run;
its rows are the lines of exactly as many numbers (lines of other lengths or with words, such as a
`WARNING`, are skipped). With `thermo_modify format float %.17g` every value round-trips to the
double LAMMPS held. A `minimize` command adds a table of its own and, after it, a
`Minimization stats:` block of `key = value` lines (stopping criterion, energies with 15
significant digits, force norms with `%g`, iteration and force-evaluation counts).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = [
    "MinimizeStats",
    "ThermoTable",
    "last_thermo",
    "minimize_stats",
    "printed",
    "thermo_tables",
]


@dataclass(frozen=True)
class ThermoTable:
    """One run's thermo table: LAMMPS's column names (`Step`, `PotEng`, `f_w[1]`, ...) and the rows,
    shape (samples, columns), in thermo units (`norm no`: extensive totals)."""

    header: tuple[str, ...]
    rows: np.ndarray

    def columns(self, names: list[str] | tuple[str, ...] | None = None) -> dict[str, np.ndarray]:
        """Each column as an array, keyed by `names` (e.g. the `thermo_style custom` keywords, in
        order) or by the header's names."""
        names = list(self.header if names is None else names)
        if len(names) != len(self.header):
            raise ValueError(f"{len(names)} names for a table of {len(self.header)} columns {self.header}")
        return {name: self.rows[:, j].copy() for j, name in enumerate(names)}


def thermo_tables(log_text: str) -> list[ThermoTable]:
    """Every thermo table of a log, in order (one per `run`/`minimize`)."""
    tables: list[ThermoTable] = []
    header: tuple[str, ...] | None = None
    rows: list[list[float]] = []

    def close() -> None:
        if header is not None:
            tables.append(ThermoTable(header, np.array(rows, dtype=float).reshape(-1, len(header))))

    for line in log_text.splitlines():
        words = line.split()
        if words[:1] == ["Step"]:
            close()
            header, rows = tuple(words), []
            continue
        if header is None:
            continue
        if line.startswith("Loop time of"):
            close()
            header = None
            continue
        if len(words) == len(header):
            try:
                rows.append([float(w) for w in words])
            except ValueError:
                continue  # e.g. a WARNING line of as many words inside the table
    close()  # a run stopped by an error has no "Loop time" line
    return tables


def last_thermo(log_text: str, ncols: int | None = None) -> np.ndarray:
    """Rows of the last thermo table (of `ncols` columns, if given): the final run's, also when a
    minimization before it printed a table of its own. An empty (0, ncols) array if there is none."""
    tables = [t for t in thermo_tables(log_text) if ncols is None or len(t.header) == ncols]
    if not tables:
        return np.zeros((0, ncols or 0))
    return tables[-1].rows


@dataclass(frozen=True)
class MinimizeStats:
    """One `Minimization stats:` block. Energies (initial, next-to-last, final) carry 15
    significant digits, the force norms (initial, final) only `%g`'s 6."""

    stop_reason: str
    iterations: int
    evaluations: int
    energy: tuple[float, float, float]
    fnorm2: tuple[float, float]  # force two-norm
    fnorm_inf: tuple[float, float]  # force max component
    fields: dict[str, str]  # every `key = value` line of the block, as text


_MIN_KEYS = ("Stopping criterion", "Energy initial, next-to-last, final", "Force two-norm initial, final",
             "Force max component initial, final", "Iterations, force evaluations")


def minimize_stats(log_text: str) -> list[MinimizeStats]:
    """Every `Minimization stats:` block of a log, in order; a block missing one of its lines
    raises ValueError naming it."""
    lines = log_text.splitlines()
    blocks: list[dict[str, str]] = []
    inside = False  # a block runs from its title to the first blank line
    for k, line in enumerate(lines):
        if line.strip() == "Minimization stats:":
            blocks.append({})
            inside = True
            continue
        if not line.strip():
            inside = False
        if not inside or "=" not in line:
            continue
        key, _, value = line.partition("=")
        key, value = key.strip(), value.strip()
        if not value and k + 1 < len(lines):  # LAMMPS puts the three energies on the next line
            value = lines[k + 1].strip()
        blocks[-1].setdefault(key, value)
    out = []
    for fields in blocks:
        missing = [key for key in _MIN_KEYS if key not in fields]
        if missing:
            raise ValueError(f"a Minimization stats block without {', '.join(missing)}")
        energy = tuple(float(w) for w in fields[_MIN_KEYS[1]].split()[:3])
        f2 = tuple(float(w) for w in fields[_MIN_KEYS[2]].split()[:2])
        finf = tuple(float(w) for w in fields[_MIN_KEYS[3]].split()[:2])
        it, ev = (int(w) for w in fields[_MIN_KEYS[4]].split()[:2])
        out.append(MinimizeStats(fields[_MIN_KEYS[0]], it, ev, energy, f2, finf, fields))  # type: ignore[arg-type]
    return out


def printed(log_text: str, tag: str) -> list[list[str]]:
    """The words after `tag` on every line a `print "TAG ..."` command wrote (the echoed command
    itself, and lines whose `$(...)` was not expanded, are left out)."""
    return [line.split()[1:] for line in log_text.splitlines()
            if line.startswith(tag + " ") and "$(" not in line]
