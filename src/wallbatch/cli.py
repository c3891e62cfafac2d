"""The `wallbatch` command line: `run` a config to NetCDF, `check` a config without running."""

from __future__ import annotations

from pathlib import Path

import typer

from .config import ConfigError, load_config
from .scene import CaseError

app = typer.Typer(add_completion=False, no_args_is_help=True,
                  help="Batches of wall-bounded particle simulations (LAMMPS wall fixes) to labelled NetCDF.")


def _load(config: Path):
    try:
        return load_config(config)
    except ConfigError as exc:
        typer.echo(f"error: invalid config\n{exc}", err=True)
        raise typer.Exit(2) from None


def _plan(config: Path, sets: list[str] | None):
    from .sweep import load_plan

    try:
        return load_plan(config, sets or [])
    except ConfigError as exc:
        typer.echo(f"error: invalid config\n{exc}", err=True)
        raise typer.Exit(2) from None


@app.command()
def run(config: Path = typer.Argument(..., help="scene or sweep YAML file"),
        output: Path = typer.Option(None, "-o", "--output", help="results file (default: CONFIG with .nc)"),
        set_: list[str] = typer.Option(None, "--set", help="override a value: path=value (repeatable)")) -> None:
    """Run the scene (and its sweep) of CONFIG and write the results as NetCDF."""
    from .runner import run_plan

    plan = _plan(config, set_)
    out = output or config.with_suffix(".nc")
    try:
        ds = run_plan(plan, out)
    except CaseError as exc:
        typer.echo(f"error: {config}: {exc}", err=True)
        raise typer.Exit(2) from None
    failed = int((ds["status"] == "failed").sum())
    total = int(ds["status"].size)
    typer.echo(f"{total - failed} of {total} case(s) ok -> {out}")
    for err in set(ds["error"].values.ravel().tolist()) - {""}:
        typer.echo(f"failed: {err}", err=True)
    if failed:
        raise typer.Exit(1)


@app.command()
def check(config: Path = typer.Argument(..., help="scene YAML file")) -> None:
    """Validate CONFIG and print what a run would do, without running it."""
    from .engine import sample_steps
    from .scene import build_case

    cfg = _load(config)
    try:
        case = build_case(cfg)
    except CaseError as exc:
        typer.echo(f"error: {config}: {exc}", err=True)
        raise typer.Exit(2) from None
    kernels = ["nve"] + [f"wall/reflect {w.fix_id}" for w in case.reflect_walls] + \
        [f"wall/{w.style.name} {w.fix_id}" for w in case.soft_walls] + (["dt/reset"] if case.dt_reset else [])
    typer.echo(f"{config}: valid")
    typer.echo(f"  atoms: {case.natoms}   units: {case.units.name}   dt: {case.dt}")
    typer.echo(f"  kernels: {', '.join(kernels)}")
    if case.steps is not None:
        typer.echo(f"  steps: {case.steps}   samples: {len(sample_steps(case.steps, int(case.thermo)))}"
                   f"   atom-steps: {case.steps * case.natoms}")
    else:
        typer.echo(f"  run time: {case.run_time}")


if __name__ == "__main__":  # pragma: no cover
    app()
