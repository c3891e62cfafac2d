"""The results of a run as plain NumPy arrays with names, dimensions and attributes: what the
results file holds, built without xarray (its import costs a small run a third of its time).

`Results` keeps its variables in the order xarray's Dataset would (data variables of the
constructor, then coordinates, then variables added later) and `to_xarray` gives the very
Dataset that `xarray.open_dataset` reads back from the file written by `io.netcdf.write_netcdf`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import sys

import numpy as np

if TYPE_CHECKING:
    import xarray as xr


@dataclass
class Var:
    """One variable: dimension names, data (shape matching the dims) and attributes."""

    dims: tuple[str, ...]
    data: np.ndarray
    attrs: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        self.dims = (self.dims,) if isinstance(self.dims, str) else tuple(self.dims)
        self.data = np.asarray(self.data)

    @property
    def values(self) -> np.ndarray:
        return self.data


class Results:
    """Named variables (data and coordinates) and global attributes; see the module docstring."""

    def __init__(self, data_vars: dict[str, Var], coords: dict[str, Var]):
        self.variables: dict[str, Var] = {**data_vars, **coords}
        self.coord_names: set[str] = set(coords)
        self.attrs: dict[str, Any] = {}
        self._constructed = len(data_vars)  # variables given to the constructor as data

    @property
    def dims(self) -> dict[str, int]:
        """Dimension sizes, in order of first appearance over the variables."""
        out: dict[str, int] = {}
        for v in self.variables.values():
            for d, n in zip(v.dims, v.data.shape):
                out.setdefault(d, n)
        return out

    @property
    def coords(self) -> set[str]:
        return self.coord_names

    @property
    def data_vars(self) -> list[str]:
        return [k for k in self.variables if k not in self.coord_names]

    def __getitem__(self, name: str) -> Var:
        return self.variables[name]

    def __setitem__(self, name: str, var: Var) -> None:
        self.variables[name] = var

    def __contains__(self, name: object) -> bool:
        return name in self.variables

    def to_xarray(self) -> xr.Dataset:
        """The same results as an xarray.Dataset (imports xarray)."""
        import xarray as xr

        _defer_dask_import()

        def xvar(v: Var) -> xr.Variable:
            return xr.Variable(v.dims, v.data, attrs=dict(v.attrs))

        items = list(self.variables.items())
        first = items[:self._constructed]
        coords = {k: xvar(v) for k, v in items if k in self.coord_names}
        ds = xr.Dataset({k: xvar(v) for k, v in first}, coords=coords)
        # the variables added after construction in one update, in order (one merge, not one each)
        ds.update({k: xvar(v) for k, v in items[self._constructed:] if k not in self.coord_names})
        ds.attrs.update(self.attrs)
        return ds


class _DaskOnDemand:
    """Stands in xarray's cache of duck-array modules for "dask" until dask is imported.

    xarray imports dask (0.5-1.5 s) the first time it builds any Variable, only to test
    `isinstance(data, dask.array.Array)`. No dask array can exist before dask.array is imported,
    so until then the answer is "not a dask array"; from then on the real entry is used."""

    def _real(self) -> Any:
        from xarray.namedarray import pycompat

        real = pycompat.DuckArrayModule("dask")
        pycompat._cached_duck_array_modules["dask"] = real
        return real

    def __getattr__(self, name: str) -> Any:
        if "dask" not in sys.modules and name == "type":
            return ()
        return getattr(self._real(), name)


def _defer_dask_import() -> None:
    """Keep xarray from importing dask and distributed for runs that never use them (half a
    small run's start-up): its "is this a dask array / which dask scheduler is active?" tests
    answer no while dask is not imported, which is exact, since no dask object or scheduler can
    exist before. Once dask is imported, xarray's own functions answer."""
    try:
        from xarray.backends import locks, writers
        from xarray.namedarray import pycompat
        from xarray.namedarray import utils as nutils

        cache = pycompat._cached_duck_array_modules
        targets = [(nutils, "is_dask_collection", False), (locks, "get_dask_scheduler", None),
                   (writers, "get_dask_scheduler", None)]
        originals = [getattr(mod, name) for mod, name, _ in targets]
    except (ImportError, AttributeError):  # another xarray layout: nothing to do
        return
    if isinstance(cache, dict) and "dask" not in cache and "dask" not in sys.modules:
        cache["dask"] = _DaskOnDemand()
    for (mod, name, without), original in zip(targets, originals):
        if getattr(original, "_wallbatch_lazy", False):
            continue

        def lazy(*args: Any, _original: Any = original, _without: Any = without, **kwargs: Any) -> Any:
            return _original(*args, **kwargs) if "dask" in sys.modules else _without

        lazy._wallbatch_lazy = True  # type: ignore[attr-defined]
        setattr(mod, name, lazy)
