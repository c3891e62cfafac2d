"""wallbatch: batches of particle simulations bounded by LAMMPS-style walls.

The public API (documented in the docs' API page) is three functions, imported on first use so
that ``import wallbatch`` stays cheap:

* ``wallbatch.load(path, sets=...)`` -> a validated plan (every case of the sweep);
* ``wallbatch.run(config_or_path, output=None, jobs=1, ...)`` -> ``xarray.Dataset``;
* ``wallbatch.check(config_or_path, sets=..., jobs=1)`` -> a :class:`wallbatch.api.CheckReport`.
"""

from __future__ import annotations

from typing import Any

from wallbatch.version import __version__

__all__ = ["__version__", "load", "run", "check"]


def __getattr__(name: str) -> Any:
    if name in ("load", "run", "check"):
        from wallbatch import api

        return getattr(api, name)
    raise AttributeError(f"module 'wallbatch' has no attribute {name!r}")
