"""Shared test setup: helper modules on sys.path, scene factories and the LAMMPS oracle as
fixtures, and the `lammps` / `slow` markers applied where they belong.

Layout: tests/ mirrors src/wallbatch (styles/, geometry/, config/, engine/, io/, batch/, lammps/;
the leaves units/expr and api, cli, layers at the top). Helper modules, importable from any test:
`factories` (scene dicts, config/Case/run from a dict, YAML text, path or Config) and
`lammps_oracle` (LAMMPS through its Python API; its log read by `wallbatch.lammps.log`).

Markers, so that `pytest -m "not slow and not lammps"` is the fast subset:
- `lammps`: added to every test that carries `lammps_oracle.requires_lammps` or takes a LAMMPS
  fixture below; a test marked `lammps` by hand is skipped when LAMMPS is not usable.
- `slow`: every test over about 5 s, and a few of 1-3 s (long convergence and statistics runs) so
  that the fast subset stays under a minute on two busy cores. Mark the test, or list a slow
  (module-scoped) fixture in the module's `SLOW_FIXTURES` tuple: every test that takes it is marked.
"""

import os
import sys

import pytest

# Make helper modules in tests/ (e.g. lammps_oracle) importable from any test.
_TESTS_DIR = os.path.dirname(os.path.abspath(__file__))
if _TESTS_DIR not in sys.path:
    sys.path.insert(0, _TESTS_DIR)

import factories
import lammps_oracle

from wallbatch.lammps import log as lammps_log_module

LAMMPS_FIXTURES = frozenset({"lammps_module", "lammps_script", "lammps_run_log"})


# ----------------------------------------------------------------------------- markers


def _needs_lammps(item: pytest.Item) -> bool:
    if LAMMPS_FIXTURES & set(getattr(item, "fixturenames", ())):
        return True
    return any(m.name == "skipif" and m.kwargs.get("reason") == lammps_oracle.SKIP_REASON
               for m in item.iter_markers())


@pytest.hookimpl(tryfirst=True)  # before `-m` deselects by marker
def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    for item in items:
        if _needs_lammps(item) and item.get_closest_marker("lammps") is None:
            item.add_marker(pytest.mark.lammps)
        if item.get_closest_marker("lammps") is not None and not lammps_oracle.lammps_available():
            item.add_marker(pytest.mark.skip(reason=lammps_oracle.SKIP_REASON))
        module = getattr(item, "module", None)
        slow = set(getattr(module, "SLOW_FIXTURES", ()))
        if slow & set(getattr(item, "fixturenames", ())) and item.get_closest_marker("slow") is None:
            item.add_marker(pytest.mark.slow)


# ----------------------------------------------------------------------------- scene factories


@pytest.fixture
def config_of():
    """scene (dict | YAML text | path | Config) -> validated Config."""
    return factories.config_of


@pytest.fixture
def case_of():
    """scene -> Case (optional seed_key)."""
    return factories.case_of


@pytest.fixture
def run_one():
    """scene -> the engine's CaseResult of the single case."""
    return factories.run_one


@pytest.fixture
def run_ok():
    """scene -> CaseResult, asserting status ok."""
    return factories.run_ok


@pytest.fixture
def run_dataset():
    """scene -> the results Dataset (runner.run_config)."""
    return factories.run_dataset


@pytest.fixture
def box_scene():
    """atom groups and walls in a box -> config dict (see factories.box_scene)."""
    return factories.box_scene


@pytest.fixture
def slab_gas():
    """ideal gas between walls -> config dict (see factories.slab_gas)."""
    return factories.slab_gas


# ----------------------------------------------------------------------------- LAMMPS oracle


@pytest.fixture(scope="session")
def lammps_module():
    """LAMMPS's Python module with MPI loaded globally (skips the test if it is not usable)."""
    return lammps_oracle.load_lammps()


@pytest.fixture
def lammps_script(lammps_module):
    """(commands, columns=None) -> the last thermo table of a fresh LAMMPS run, column -> array."""
    return lammps_oracle.run_script


@pytest.fixture
def lammps_run_log(lammps_module):
    """commands -> the log text of a fresh LAMMPS run."""
    return lammps_oracle.lammps_log


@pytest.fixture
def lammps_log_reader():
    """wallbatch.lammps.log: thermo_tables, last_thermo, minimize_stats, printed."""
    return lammps_log_module
