"""The `wallbatch` command line: run, check, show, plot, schema, table, export-lammps, validate.

Every foreseeable problem ends in one `error: ...` message with its place (file:line:col, the
sweep file's line or the `--set` argument) and exit code 2; a failed case gives exit code 1; an
interrupted run exit code 130. Anything unexpected is one line asking for a report; `--debug`
shows its traceback."""

from __future__ import annotations

import gc
import os
import sys
from pathlib import Path
from typing import Any

# One OpenBLAS thread for the command line's process unless the user says otherwise: NumPy's
# OpenBLAS starts a thread per core when NumPy is imported (~0.07 s of every command's start-up,
# ~0.1 s of CPU), and wallbatch multiplies no matrices big enough for BLAS threads (its compiled
# chunks use numba's own threads, WALLBATCH_THREADS). Set before anything imports NumPy.
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
# No Pydantic plugins in the command line's process unless the user names some: none is meant for
# wallbatch's config models, and looking for them reads the entry points of every installed
# package at the first model's build (~5 ms with 160 packages, more in a large environment).
os.environ.setdefault("PYDANTIC_DISABLE_PLUGINS", "__all__")

# The imports below (typer, NumPy, the config and scene layers) allocate ~80k long-lived objects
# and free almost none: the collector is paused while they run, as for a command's start-up (see
# _start_up_done), and restored at once after them, so a program importing this module keeps its
# collector as it was.
_gc_was_enabled = gc.isenabled()
gc.disable()
try:
    import typer  # noqa: E402

    from wallbatch.config.source import ConfigError  # noqa: E402
    from wallbatch.scene.case import CaseError  # noqa: E402
    from wallbatch.version import __version__  # noqa: E402
finally:
    if _gc_was_enabled:
        gc.enable()


_gc_paused = False  # the garbage collector is paused for a command's start-up (_start_up_done)


def _start_up_done() -> None:
    """End of a command's start-up: the objects built so far (modules, the config models'
    validators, the plan) move to the collector's permanent generation (gc.freeze: never scanned
    again) and collection resumes. The start-up runs with collection paused (_GuardedTyper): its
    imports and validation allocate about a million long-lived objects and free almost none, and
    the collector's passes over them cost ~0.1 s, a sixth of a small run."""
    global _gc_paused
    if _gc_paused:
        _gc_paused = False
        gc.freeze()
        gc.enable()


class _GuardedTyper(typer.Typer):
    """The app as the console script calls it: an unexpected exception is one line plus a request
    to report it, unless `--debug` asks for the traceback; Ctrl-C outside a run exits 130. The
    garbage collector is paused until the command's start-up is done (_start_up_done), and every
    object left is frozen when the command returns: Python's exit runs full collections over
    every tracked object (numba's ~300k) before freeing them, ~0.2 s of a `wallbatch run`."""

    def __call__(self, *args: Any, **kwargs: Any) -> Any:
        global _gc_paused
        debug = "--debug" in sys.argv[1:]
        if gc.isenabled():
            gc.disable()
            _gc_paused = True
        try:
            return super().__call__(*args, **kwargs)
        except KeyboardInterrupt:
            sys.stderr.write("interrupted\n")
            sys.exit(130)
        except Exception as exc:  # noqa: BLE001 - the top-level guard
            if debug:
                raise
            text = " ".join(str(exc).split())
            text = text if len(text) <= 200 else text[:197] + "..."
            sys.stderr.write(f"error: unexpected {type(exc).__name__}: {text}\n  this is a wallbatch bug: please "
                             f"report it to the wallbatch developers with the config and the command; rerun with "
                             f"--debug for the traceback\n")
            sys.exit(3)
        finally:
            _start_up_done()
            gc.freeze()  # the process exits next: its finalizer's collections skip what is alive (~0.2 s with numba)


app = _GuardedTyper(add_completion=False, no_args_is_help=True, pretty_exceptions_enable=False,
                    help="Batches of wall-bounded particle simulations (LAMMPS wall fixes) to labelled NetCDF.")


def _version(value: bool) -> None:
    if value:
        typer.echo(f"wallbatch {__version__}")
        raise typer.Exit()


@app.callback()
def _main(ctx: typer.Context,
          version: bool = typer.Option(False, "--version", callback=_version, is_eager=True,
                                       help="print the version and exit"),
          debug: bool = typer.Option(False, "--debug", help="show the Python traceback of an unexpected error "
                                                            "(for a bug report)")) -> None:
    """Batches of wall-bounded particle simulations (LAMMPS wall fixes) to labelled NetCDF."""
    _warnings_as_lines()
    if ctx.invoked_subcommand != "run":  # run: once its modules are imported and its plan loaded
        _start_up_done()


def _warnings_as_lines() -> None:
    """wallbatch's own warnings (minimize with a wall whose energy is left out, ...) as one line
    each on stderr, `warning: TEXT`, each text once per process (every case of a sweep would repeat
    it); other packages' warnings as Python shows them."""
    import warnings

    shown = warnings.showwarning
    if getattr(shown, "wallbatch", False):  # already installed (the app called again in this process)
        return

    def show(message: Any, category: type, filename: str, lineno: int, file: Any = None, line: Any = None) -> None:
        if category.__module__.startswith("wallbatch."):
            sys.stderr.write(f"warning: {message}\n")
        else:
            shown(message, category, filename, lineno, file, line)

    show.wallbatch = True  # type: ignore[attr-defined]
    warnings.showwarning = show
    warnings.filterwarnings("once", category=UserWarning, module=r"wallbatch\.")


def _fail(message: str, code: int = 2) -> typer.Exit:
    typer.echo(f"error: {message}", err=True)
    return typer.Exit(code)


def _plan(config: Path, sets: list[str] | None):
    """The validated plan of CONFIG (what `wallbatch.load` does for a path), or exit 2 with the
    problems. Only the config modules are needed: a bad config fails before the runner, the engine
    and netCDF4 are imported."""
    from wallbatch.config.sweep import load_plan

    try:
        return load_plan(Path(config), list(sets or []))
    except ConfigError as exc:
        typer.echo(f"error: invalid config\n{exc}", err=True)
        raise typer.Exit(2) from None


def _failures(ds) -> list[str]:
    """Failed cases grouped by message, each group with its sweep coordinates."""
    import numpy as np

    status = ds["status"].values
    errors = ds["error"].values
    dims = list(ds["status"].dims)
    groups: dict[str, list[str]] = {}
    for idx in np.ndindex(*status.shape):
        if str(status[idx]) != "failed":
            continue
        coords = ", ".join(f"{d}={ds[d].values[i] if d in ds.coords else i}" for d, i in zip(dims, idx))
        groups.setdefault(str(errors[idx]) or "(no message)", []).append(coords)
    lines = []
    for msg, where in sorted(groups.items(), key=lambda kv: -len(kv[1])):
        if where == [""]:
            lines.append(f"failed: {msg}")
            continue
        shown = "; ".join(where[:4]) + (f"; and {len(where) - 4} more" if len(where) > 4 else "")
        lines.append(f"failed ({len(where)} case{'s' if len(where) > 1 else ''}: {shown}): {msg}")
    return lines


@app.command()
def run(config: Path = typer.Argument(..., help="scene or sweep YAML file"),
        output: str = typer.Option(None, "-o", "--output",
                                   help="results file (default: CONFIG's name with .nc, in the current directory)"),
        set_: list[str] = typer.Option(None, "--set", help="override a value: path=value (repeatable)"),
        jobs: int = typer.Option(os.cpu_count() or 1, "--jobs", "-j",
                                 help="local worker processes (at most the cores and the tasks)"),
        executor: str = typer.Option("local", help="local | dask"),
        scheduler: str = typer.Option(None, help="dask scheduler address (with --executor dask)"),
        resume: bool = typer.Option(False, help="reuse the cases finished by an interrupted run (kept in OUT.nc.parts)"),
        fresh: bool = typer.Option(False, help="discard the cases left by an interrupted run and start over"),
        force: bool = typer.Option(False, "--force", help="overwrite an existing results file"),
        verbose: bool = typer.Option(False, "--verbose", "-v", help="say which engine runs the plan (NumPy or "
                                     "compiled) and why, and after the run which path its steps took"),
        ) -> None:
    """Run the scene (and its sweep) of CONFIG and write the results as NetCDF.

    Ctrl-C (or SIGTERM) stops the run within seconds and keeps every finished case: rerun with
    --resume to compute only the rest."""
    if executor not in ("local", "dask"):
        raise _fail(f"--executor must be local or dask, not {executor!r}")
    if executor == "dask" and not scheduler:
        raise _fail("--executor dask needs --scheduler ADDRESS (e.g. tcp://127.0.0.1:8786)")
    if jobs < 1:
        raise _fail(f"--jobs {jobs}: give at least 1")
    if resume and fresh:
        raise _fail("--resume and --fresh contradict each other: give one")
    if output is not None and output.endswith(("/", os.sep)):  # (a Path drops the slash: a file would be written)
        raise _fail(f"-o {output}: the results are one file, not a folder: give its name, e.g. "
                    f"{Path(output) / (config.stem + '.nc')}")
    plan = _plan(config, set_)  # a bad config fails here, before the runner and the engine are imported
    from wallbatch.batch.runner import Interrupted, RunError, run_plan

    _start_up_done()
    out = Path(output) if output else Path(config.stem + ".nc")
    steps: list[tuple[int, int]] = []  # per case run: (compiled steps, NumPy steps), for -v
    if verbose:
        from wallbatch.engine import backend

        typer.echo(backend.describe(plan), err=True)
    try:
        # the plain results (xarray is not imported: a third of a small run's start-up)
        ds = run_plan(plan, out, jobs=jobs, executor=executor, scheduler=scheduler, resume=resume, fresh=fresh,
                      overwrite=force, log=lambda msg: typer.echo(msg, err=True), as_xarray=False,
                      summary=True,  # the file is written block by block: only status and errors come back
                      on_result=(lambda i, res: steps.append((res.compiled_steps, res.numpy_steps))) if verbose
                      else None)
    except Interrupted as exc:
        typer.echo(str(exc), err=True)
        raise typer.Exit(130) from None
    except RunError as exc:
        raise _fail(str(exc)) from None
    except CaseError as exc:
        raise _fail(f"{config}: {exc}") from None
    if verbose and (steps or not resume):  # (cases reused by --resume ran before: their path is not known)
        typer.echo(backend.ran(steps), err=True)
    failed = int((ds["status"].values == "failed").sum())
    total = int(ds["status"].values.size)
    typer.echo(f"{total - failed} of {total} case(s) ok -> {out}")
    lines = _failures(ds)
    for line in lines[:10]:
        typer.echo(line, err=True)
    if len(lines) > 10:
        typer.echo(f"... and {len(lines) - 10} other message(s): wallbatch show {out}", err=True)
    if failed:
        raise typer.Exit(1)


@app.command()
def check(config: Path = typer.Argument(..., help="scene or sweep YAML file"),
          set_: list[str] = typer.Option(None, "--set", help="override a value: path=value (repeatable)"),
          jobs: int = typer.Option(os.cpu_count() or 1, "--jobs", "-j", help="as for run: how tasks are split"),
          ) -> None:
    """Validate CONFIG (every case of its sweep) and print the plan, without running anything."""
    from wallbatch import api

    plan = _plan(config, set_)
    try:
        report = api.check(plan, jobs=jobs)
    except CaseError as exc:
        typer.echo(f"error: {config}: {exc}", err=True)
        raise typer.Exit(2) from None
    lines = report.lines(str(config))
    typer.echo(lines[0])
    for line in lines[1:1 + len(plan.dims)]:
        typer.echo(line)
    groups: dict[str, list[str]] = {}
    for i, msg in report.errors.items():
        groups.setdefault(msg, []).append(plan.cases[i].label)
    for msg, labels in groups.items():
        shown = "; ".join(labels[:4]) + (f"; and {len(labels) - 4} more" if len(labels) > 4 else "")
        which = "the case" if labels == ["(single case)"] else f"{len(labels)} case(s) ({shown})"
        typer.echo(f"  {which} cannot be built: {msg}", err=True)
    for line in lines[1 + len(plan.dims):]:
        typer.echo(line)
    if not report.ok:
        raise typer.Exit(1)


def _open(results: Path):
    """A wallbatch results file, or a clear error (missing, not NetCDF, another program's NetCDF)."""
    import xarray as xr

    if not results.is_file():
        raise _fail(f"{results}: no such file" if not results.exists() else f"{results}: not a file")
    try:
        ds = xr.open_dataset(results)
    except Exception as exc:  # noqa: BLE001 - any reader failure: not a readable NetCDF file
        hint = (f"; this looks like a config: `wallbatch check {results}` checks it, `wallbatch run {results} -o "
                f"{results.with_suffix('.nc').name}` writes a results file" if results.suffix in (".yaml", ".yml") else
                "; give the results file `wallbatch run -o` wrote")
        raise _fail(f"cannot open {results}: not a NetCDF file, or a damaged one ({type(exc).__name__}){hint}") \
            from None
    if "wallbatch_version" not in ds.attrs or "status" not in ds:
        raise _fail(f"{results} is a NetCDF file but not a wallbatch results file (no wallbatch_version "
                    f"attribute or status variable)")
    return ds


@app.command()
def show(results: Path = typer.Argument(..., help="results NetCDF written by wallbatch run")) -> None:
    """Print a readable summary of a results file: dimensions, status counts, value ranges, slowest cases."""
    from wallbatch.io.report import summary

    typer.echo(summary(_open(results)))


@app.command()
def plot(results: Path = typer.Argument(..., help="results NetCDF written by wallbatch run"),
         var: str = typer.Argument(..., help="variable to plot, e.g. wall_force"),
         output: Path = typer.Option(..., "-o", "--output", help="PNG file to write"),
         x: str = typer.Option(None, "--x", help="x axis: sample (time series, default) or a sweep dimension"),
         hue: str = typer.Option(None, "--hue", help="sweep dimension that colours the lines"),
         sel: list[str] = typer.Option(None, "--sel", help="dim=value selection (repeatable)"),
         kind: str = typer.Option("auto", help="line | heatmap | auto")) -> None:
    """A quick matplotlib look at one variable: time series per case, or a summary over sweep dims."""
    try:
        import matplotlib  # noqa: F401 - only to give a one-line message when it is missing
    except ImportError:
        raise _fail("plot needs matplotlib: pip install matplotlib (the extra 'plot')") from None
    from wallbatch.io.report import plot as make_plot

    _check_image_path(output, var)
    selection = {}
    for item in sel or []:
        key, eq, value = item.partition("=")
        if not eq:
            typer.echo(f"error: --sel {item}: write dim=value", err=True)
            raise typer.Exit(2)
        if key.strip() in selection:  # the later one silently replaced the earlier one
            typer.echo(f"error: --sel {item}: {key.strip()} is already selected ({key.strip()}="
                       f"{selection[key.strip()]}); give one value per dimension", err=True)
            raise typer.Exit(2)
        selection[key.strip()] = value.strip()
    try:
        path = make_plot(_open(results), var, output, x=x, hue=hue, sel=selection, kind=kind, cli=True)
    except ValueError as exc:
        typer.echo(f"error: {exc}", err=True)
        raise typer.Exit(2) from None
    typer.echo(f"wrote {path}")


def _check_image_path(output: Path, var: str) -> None:
    """Exit 2 naming `-o` unless it is a file name whose extension is an image format matplotlib
    writes (matplotlib would append .png to a name without one, or fail late on an unknown one)."""
    from matplotlib.backend_bases import FigureCanvasBase

    formats = sorted(FigureCanvasBase.get_supported_filetypes())
    safe = "".join(c if c.isalnum() or c in "-_." else "_" for c in var) or "plot"
    if output.is_dir():
        raise _fail(f"-o {output} is a directory: give a file name, e.g. {output / (safe + '.png')}")
    suffix = output.suffix.lower().lstrip(".")
    if not suffix:
        raise _fail(f"-o {output}: give the image format as the file's extension, e.g. {output}.png")
    if suffix not in formats:
        raise _fail(f"-o {output}: .{suffix} is not an image format matplotlib writes: use one of "
                    f"{', '.join(formats)}")


@app.command()
def schema() -> None:
    """Print the JSON schema of configs and sweep files (for editor completion of YAML files:
    save it and start a YAML file with `# yaml-language-server: $schema=wallbatch.schema.json`)."""
    import json

    from wallbatch.config.schema import json_schema

    typer.echo(json.dumps(json_schema(), indent=2))


@app.command()
def table(source: str = typer.Argument(..., help="a wall style (lj93, lj126, lj1043, harmonic, morse) or a "
                                                 "wall/lepton expression of r, e.g. 'k*(r-rc)^2'"),
          output: Path = typer.Option(..., "-o", "--output", help="table file to write"),
          param: list[str] = typer.Option(None, "--param", "-p", help="a parameter: name=value (repeatable)"),
          lo: float = typer.Option(..., help="first distance r [length], > 0"),
          hi: float = typer.Option(..., help="last distance r [length] (at least the wall's cut-off)"),
          n: int = typer.Option(1000, "-n", help="number of points"),
          keyword: str = typer.Option("WALL", "--keyword", "-k", help="section keyword"),
          append: bool = typer.Option(False, help="add the section to an existing file"),
          force: bool = typer.Option(False, "--force", help="replace an existing table file"),
          ) -> None:
    """Write a wall potential (a style or an expression) as a LAMMPS table for wall/table."""
    from wallbatch.styles.table import TableError, write_source_table

    params: dict[str, float] = {}
    for item in param or []:
        name, eq, value = item.partition("=")
        try:
            params[name.strip()] = float(value)
        except ValueError:
            eq = ""
        if not eq or not name.strip():
            typer.echo(f"error: --param {item!r}: write name=number", err=True)
            raise typer.Exit(2)
    if output.exists() and not (append or force):
        typer.echo(f"error: -o {output}: the file exists; add --append to add section {keyword} to it, or --force "
                   "to replace it", err=True)
        raise typer.Exit(2)
    try:
        write_source_table(output, source, params, lo, hi, n, keyword, append=append)
    except TableError as exc:
        typer.echo(f"error: {exc}", err=True)
        raise typer.Exit(2) from None
    typer.echo(f"wrote section {keyword} ({n} points, r in [{lo:g}, {hi:g}]) to {output}")


@app.command("export-lammps")
def export_lammps(config: Path = typer.Argument(..., help="scene or sweep YAML file"),
                  output: Path = typer.Option(..., "-o", "--output", help="folder for in.NAME and data.NAME"),
                  case: str = typer.Option(None, "--case", help="one case of a sweep: index (0, 1, ...; -1: the last) "
                                           "or coordinates name=value,name=value (a list value as [a, b])"),
                  steps: int = typer.Option(None, "--steps", help="run length in steps (default: the config's)"),
                  set_: list[str] = typer.Option(None, "--set", help="override a value: path=value (repeatable)"),
                  ) -> None:
    """Write one case as a LAMMPS input script and data file that reproduce it exactly."""
    from wallbatch.lammps.export import ExportError, export_selected, write_export

    if output.exists() and not output.is_dir():
        raise _fail(f"-o {output} is a file: give a folder for in.NAME and data.NAME (made if missing)")
    plan = _plan(config, set_)
    try:
        exp = export_selected(plan, case, steps)
    except (ExportError, CaseError, ConfigError) as exc:
        typer.echo(f"error: {config}: {exc}", err=True)
        raise typer.Exit(2) from None
    script, data = write_export(exp, output)
    typer.echo(f"wrote {script} and {data} ({exp.steps} steps; run: cd {output} && lmp -in {exp.script_name})")
    for name in exp.files:
        typer.echo(f"wrote {Path(output) / name} (read by the script's fix wall/table)")
    if exp.decisions:
        typer.echo(f"{len(exp.decisions)} place(s) where wallbatch decides differently from LAMMPS: see the "
                   f"comment block of {exp.script_name}")


@app.command()
def validate(config: Path = typer.Argument(..., help="scene or sweep YAML file"),
             case: str = typer.Option(None, "--case", help="one case of a sweep: index (0, 1, ...; -1: the last) "
                                      "or coordinates name=value,name=value (a list value as [a, b])"),
             steps: int = typer.Option(None, "--steps", help="run length in steps (default: the config's)"),
             rtol: float = typer.Option(1e-9, "--rtol", help="relative tolerance of every output"),
             set_: list[str] = typer.Option(None, "--set", help="override a value: path=value (repeatable)"),
             ) -> None:
    """Run one case in wallbatch and in LAMMPS (Python module) and compare every shared output.
    Exit 0 if all agree within --rtol, 1 if not, 2 if it cannot run (no LAMMPS, cannot export)."""
    import math

    from wallbatch.lammps.export import ExportError, select_case
    from wallbatch.lammps.validate import LammpsMissing, validate_case

    if not (math.isfinite(rtol) and rtol >= 0):
        raise _fail(f"--rtol {rtol:g}: give a relative tolerance >= 0, e.g. --rtol 1e-9")
    plan = _plan(config, set_)
    try:
        report = validate_case(select_case(plan, case), steps=steps, rtol=rtol)
    except LammpsMissing as exc:
        typer.echo(f"error: {exc}", err=True)
        raise typer.Exit(2) from None
    except (ExportError, CaseError, ConfigError) as exc:
        typer.echo(f"error: {config}: {exc}", err=True)
        raise typer.Exit(2) from None
    typer.echo(f"{config}: {report.text()}")
    if not report.ok:
        raise typer.Exit(1)


@app.command("import-lammps")
def import_lammps(script: Path = typer.Argument(..., help="LAMMPS input script (in.NAME)"),
                  output: Path = typer.Option(None, "-o", "--output", help="config YAML to write (default: print it)"),
                  var: list[str] = typer.Option(None, "--var", help="name=value: an index variable, as lmp -var "
                                                "(repeatable)"),
                  strict: bool = typer.Option(False, "--strict", help="exit 1 if any command could not be imported"),
                  exact: bool = typer.Option(False, "--exact", help="run the setup in LAMMPS and start from its state "
                                             "(a data file beside the config): LAMMPS's random numbers"),
                  force: bool = typer.Option(False, "--force", help="overwrite an existing -o file"),
                  ) -> None:
    """Turn a LAMMPS input script into an equivalent wallbatch config, commented with the original
    lines; what cannot be imported is listed at its end (exit 1 under --strict)."""
    from wallbatch.lammps.importer import LammpsImportError, import_lammps as do_import
    from wallbatch.lammps.validate import LammpsMissing

    variables = {}
    for item in var or []:
        key, eq, value = item.partition("=")
        if not eq or not key.strip():
            typer.echo(f"error: --var {item}: write name=value", err=True)
            raise typer.Exit(2)
        variables[key.strip()] = value.strip()
    if output is not None:
        if output.is_dir():
            raise _fail(f"-o {output} is a folder: give the config's file name, e.g. {output / 'config.yaml'}")
        if output.exists() and output.resolve() == script.resolve():
            raise _fail(f"-o {output} is the script itself: choose another name, e.g. "
                        f"{output.with_suffix('.yaml').name if output.suffix != '.yaml' else 'config.yaml'}")
        if output.exists() and not force:
            raise _fail(f"{output} exists: add --force to overwrite it, or choose another -o")
        output.parent.mkdir(parents=True, exist_ok=True)
    try:
        result = do_import(script, output, variables, exact=exact)
    except (LammpsImportError, LammpsMissing) as exc:
        typer.echo(f"error: {exc}", err=True)
        raise typer.Exit(2) from None
    if output is None:
        typer.echo(result.text, nl=False)
    else:
        output.write_text(result.text)
        typer.echo(f"wrote {output}" + "".join(f" and {p}" for p in result.written), err=True)
    for issue in result.unsupported:
        typer.echo(f"not imported: {script}:{issue.line}: {issue.text} -> {issue.reason}", err=True)
    for problem in result.problems:
        typer.echo(f"invalid: {problem}", err=True)
    if not result.complete:
        typer.echo(f"{len(result.unsupported) + len(result.problems)} problem(s): the config differs from the "
                   f"script (listed at its end)", err=True)
        if strict:
            raise typer.Exit(1)


def _floats(text: str | None, option: str) -> list[float] | None:
    if not text:
        return None
    try:
        return [float(v) for v in text.replace(" ", "").split(",") if v]
    except ValueError:
        typer.echo(f"error: {option} {text}: write numbers separated by commas, e.g. {option} 0.01,0.005,0.0025",
                   err=True)
        raise typer.Exit(2) from None


@app.command()
def convergence(config: Path = typer.Argument(..., help="scene or sweep YAML file"),
                case: str = typer.Option(None, "--case", help="one case of a sweep: index or name=value,..."),
                dt: str = typer.Option(None, "--dt", help="timesteps, comma-separated (default: the scene's "
                                       "timestep x 2, 1, 1/2, 1/4, 1/8); the smallest is the reference"),
                xmax: str = typer.Option(None, "--xmax", help="dt/reset xmax values (scenes with dt_reset)"),
                rtol: float = typer.Option(None, "--rtol", help="print the cheapest timestep whose error is "
                                           "at most this (relative RMS against the finest run)"),
                output_var: list[str] = typer.Option(None, "--var", help="outputs --rtol applies to "
                                                     "(repeatable; default: all)"),
                set_: list[str] = typer.Option(None, "--set", help="override a value: path=value (repeatable)"),
                output: Path = typer.Option(None, "-o", "--output", help="write the runs as NetCDF with a dt "
                                            "(or xmax) dimension"),
                plot_to: Path = typer.Option(None, "--plot", help="write a PNG of error and drift against cost"),
                force: bool = typer.Option(False, "--force", help="overwrite an existing -o file"),
                ) -> None:
    """Run one case at a ladder of timesteps over the same simulated time and print, per output,
    the error against the finest run, the observed order, the energy drift and the cost."""
    import math

    from wallbatch.batch.runner import RunError, check_output
    from wallbatch.convergence import ConvergenceError, UnknownOutput
    from wallbatch.convergence import convergence as run_ladder
    from wallbatch.convergence import plot as plot_ladder
    from wallbatch.lammps.export import ExportError

    if rtol is not None and not (math.isfinite(rtol) and rtol > 0):  # before the ladder runs
        raise _fail(f"--rtol {rtol:g}: give a positive relative error, e.g. --rtol 1e-4")
    plan = _plan(config, set_)
    if output is not None:
        try:
            check_output(output, plan.inputs, overwrite=force)
        except RunError as exc:
            raise _fail(str(exc)) from None
    try:
        report = run_ladder(plan, case=case, dts=_floats(dt, "--dt"), xmaxs=_floats(xmax, "--xmax"),
                            outputs=output_var or None)
    except UnknownOutput as exc:  # (checked after the first run, before the ladder)
        raise _fail(f"--var {' --var '.join(output_var)}: {exc}") from None
    except (ConvergenceError, ExportError, CaseError, ConfigError) as exc:
        typer.echo(f"error: {config}: {exc}", err=True)
        raise typer.Exit(2) from None
    typer.echo(report.table())
    if output is not None:
        output.parent.mkdir(parents=True, exist_ok=True)  # as `run -o` does
        report.dataset.to_netcdf(output)
        typer.echo(f"-> {output}")
    if plot_to is not None:
        typer.echo(f"-> {plot_ladder(report, plot_to)}")
    if rtol is not None:
        try:
            best = report.recommend(rtol, output_var or None)
        except ConvergenceError as exc:
            typer.echo(f"error: {exc}", err=True)
            raise typer.Exit(2) from None
        if best is None:
            typer.echo(f"no {report.dim} of the ladder meets rtol {rtol:g}: try smaller values", err=True)
            raise typer.Exit(1)
        typer.echo(f"cheapest {report.dim} with every error <= {rtol:g}: {best.h:g} "
                   f"({best.seconds:.3f} s, {best.atom_steps_per_s:.3g} atom-steps/s)")


def main() -> None:
    """The console script (and `python -m wallbatch.cli`): the app, then the process ends at once
    with the command's exit code, once its output is flushed. Every command has closed its files
    by then; what Python's own exit would add is tearing down modules and freeing every object,
    with numba and NetCDF loaded ~0.01-0.04 s of a `wallbatch run`. (`app()` itself, as a program
    that imports wallbatch calls it, exits through SystemExit as usual; so does `main()` under a
    profiler or a tracer such as coverage, which write their results at Python's exit.)"""
    if sys.getprofile() is not None or sys.gettrace() is not None:
        app()
        return
    try:
        app()
        code: Any = 0
    except SystemExit as exc:
        code = exc.code
    if code is None:
        code = 0
    elif not isinstance(code, int):  # sys.exit("message"): printed, status 1, as Python does
        sys.stderr.write(f"{code}\n")
        code = 1
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):  # a closed pipe: nothing more can be said
            pass
    os._exit(code & 0xFF if code >= 0 else 1)


if __name__ == "__main__":  # pragma: no cover
    main()
