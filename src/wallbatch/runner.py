"""From a validated config to a results file: build the case(s), run them, write NetCDF."""

from __future__ import annotations

from pathlib import Path

import xarray as xr

from .config import Config
from .engine import run_cases
from .output import build_dataset, write_netcdf
from .scene import build_case


def run_config(cfg: Config, config_text: str = "", output: str | Path | None = None) -> xr.Dataset:
    """Run one scene; write `output` if given; return the results Dataset."""
    case = build_case(cfg)
    results = run_cases([case])
    ds = build_dataset(results, [case], config_text=config_text)
    if output is not None:
        write_netcdf(ds, output)
    return ds
