"""MkDocs hook: fill the generated parts of the pages at build time.

A page line ``<!-- generated: NAME -->`` is replaced by the output of ``gen_reference.GENERATORS[NAME]``
(config keys from the Pydantic models, unit table, wall styles, the CLI from the Typer app). A
config key without a description, or a description of a key that no longer exists, is a build
warning, so ``mkdocs build --strict`` fails on drift.
"""

from __future__ import annotations

import logging
import re
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import gen_reference  # noqa: E402

log = logging.getLogger("mkdocs.hooks.wallbatch")
_MARK = re.compile(r"^<!-- generated: ([a-z-]+) -->$", re.M)
_cache: dict[str, str] = {}


def on_pre_build(config, **kwargs) -> None:  # noqa: ARG001
    _cache.clear()
    for name in gen_reference.undocumented():
        log.warning("config key %s has no description: add Field(description=...) to its model or an entry "
                    "to KEYS in docs/gen_reference.py", name)
    for name in gen_reference.stale():
        log.warning("docs/gen_reference.py KEYS describes %s, which is not a config key", name)


def _generate(match: re.Match) -> str:
    name = match.group(1)
    if name not in gen_reference.GENERATORS:
        log.warning("unknown generated block %r", name)
        return match.group(0)
    if name not in _cache:
        _cache[name] = gen_reference.GENERATORS[name]()
    return _cache[name]


def on_page_markdown(markdown: str, page, config, files, **kwargs) -> str:  # noqa: ARG001
    return _MARK.sub(_generate, markdown)
