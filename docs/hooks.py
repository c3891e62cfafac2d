"""MkDocs hook: fill the generated parts of the pages at build time.

A page line ``<!-- generated: NAME -->`` is replaced by the output of ``gen_reference.GENERATORS[NAME]``
(config keys from the Pydantic models, unit table, wall styles, the CLI from the Typer app). A
config key without a description, or a description of a key that no longer exists, is a build
warning, so ``mkdocs build --strict`` fails on drift.
"""

from __future__ import annotations

import logging
import posixpath
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


_FENCE = re.compile(r"^```.*?^```", re.M | re.S)
_PHYSICS = re.compile(r"(?<![\[#])\bPhysics §(\d+(?:\.\d+)?[a-z]?)(?![\]\w])")
_BARE = re.compile(r"(?<![\[\w§])(?<!Physics )§(\d+(?:\.\d+)?[a-z]?)(?![\]\w])")
_QUIRK = re.compile(r"(?<![\[#\w])quirk #(\d+)\b(?!\])")


def _autolink(text: str, page_uri: str) -> str:
    """Plain "Physics §4.6" and "quirk #12" mentions become links (not inside code or links)."""
    here = posixpath.dirname(page_uri)
    physics = posixpath.relpath("physics.md", here or ".")
    deviations = posixpath.relpath("deviations.md", here or ".")

    def prose(chunk: str) -> str:
        parts = chunk.split("`")
        for i in range(0, len(parts), 2):  # outside inline code
            p = _PHYSICS.sub(lambda m: f"[Physics §{m.group(1)}]({physics}#s{m.group(1).replace('.', '-')})",
                             parts[i])
            if page_uri == "physics.md":  # the page's own bare "§5.1" references
                p = _BARE.sub(lambda m: f"[§{m.group(1)}](#s{m.group(1).replace('.', '-')})", p)
            if page_uri != "deviations.md":
                p = _QUIRK.sub(lambda m: f"[quirk #{m.group(1)}]({deviations}#quirk-by-quirk)", p)
            parts[i] = p
        return "`".join(parts)

    out, last = [], 0
    for m in _FENCE.finditer(text):
        out += [prose(text[last:m.start()]), m.group(0)]
        last = m.end()
    out.append(prose(text[last:]))
    return "".join(out)


def on_page_markdown(markdown: str, page, config, files, **kwargs) -> str:  # noqa: ARG001
    return _autolink(_MARK.sub(_generate, markdown), page.file.src_uri)
