"""YAML with line marks: loading (safe, duplicate keys refused) and `file:line:col: path: message`
errors through `ConfigError` and `SourceMap`.
"""

from __future__ import annotations

import re
from typing import Any

import yaml

from wallbatch.styles import STYLES

FACES = ("xlo", "xhi", "ylo", "yhi", "zlo", "zhi")
# wall styles without per-face potential parameters (their models live in config.models)
OTHER_WALLS = ("reflect", "flow", "region", "region/ees", "reflect/stochastic", "lepton", "table")
WALL_TAGS = tuple(STYLES) + OTHER_WALLS  # the `style:` values (the discriminator tags of the wall models)


def positional_index(field: str, length: int) -> int | None:
    """Where `field` stands in a face written positionally with `length` values (any registered
    style's `[coord, ...]` order of that length), or None."""
    for style in STYLES.values():
        if len(style.positional) == length and field in style.positional:
            return style.positional.index(field)
    return None


# ----------------------------------------------------------------------------- errors


class ConfigError(ValueError):
    """Invalid config: one line per problem, `file:line:col: path: message`."""

    def __init__(self, problems: list[str]):
        self.problems = problems
        super().__init__("\n".join(problems))


class SourceMap:
    """Where each value of a YAML document stands: dotted path -> (line, column), 1-based."""

    def __init__(self, filename: str, marks: dict[tuple, tuple[int, int]], data: Any):
        self.filename = filename
        self.marks = marks
        self.data = data

    def locate(self, loc: tuple) -> tuple[tuple, tuple[int, int] | None]:
        """Resolve a Pydantic error location against the data: drop union tags and other loc
        parts that index nothing, and return (path to show, nearest known mark)."""
        path: list = []  # indexes the marks: mapping keys as written (text), list indices
        shown: list = []  # what the user reads: field names, also for positional faces
        node = self.data
        for part in loc:
            if isinstance(node, dict) and isinstance(part, str) and part not in node and part.lstrip("-").isdigit() \
                    and int(part) in node:
                part = int(part)  # a fix-ID like `1:` that YAML read as a number
            if isinstance(node, dict) and part in node:
                node = node[part]
                path.append(str(part))
                shown.append(part)
            elif isinstance(node, list) and isinstance(part, int) and 0 <= part < len(node):
                node = node[part]
                path.append(part)
                shown.append(part)
            elif isinstance(node, list) and isinstance(part, str) and positional_index(part, len(node)) is not None:
                i = positional_index(part, len(node))  # a field of a face written positionally
                node = node[i]
                path.append(i)
                shown.append(part)
            elif isinstance(node, dict) and isinstance(part, str) and (part in FACES or (
                    part not in WALL_TAGS and not any(c in part for c in "[]()"))):
                shown.append(part)  # a missing key: name it, point at its parent
                node = None
            elif isinstance(node, str) and isinstance(part, str) and part not in WALL_TAGS \
                    and not any(c in part for c in "[]()"):
                shown.append(part)  # a field of a wall written as a fix line: name it, point at the line
        mark = None
        for n in range(len(path), -1, -1):
            mark = self.marks.get(tuple(path[:n]))
            if mark:
                break
        return tuple(shown), mark

    def format(self, loc: tuple, message: str) -> str:
        path, mark = self.locate(loc)
        where = f"{self.filename}:{mark[0]}:{mark[1]}" if mark else self.filename
        dotted = ".".join(str(p) for p in path) or "(top level)"
        return f"{where}: {dotted}: {message}"


class _Loader(yaml.SafeLoader):
    """SafeLoader that reads `1e-5` as a number (YAML 1.1 wants `1.0e-5`) and refuses
    duplicate keys."""


_Loader.add_implicit_resolver(
    "tag:yaml.org,2002:float",
    re.compile(r"^[-+]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)[eE][-+]?[0-9]+$"),
    list("-+0123456789."),
)


def load_yaml(text: str, filename: str = "<config>") -> tuple[Any, SourceMap]:
    """Parse YAML (safe) and keep the line/column of every value."""
    try:
        loader = _Loader(text)
        try:
            node = loader.get_single_node()
        finally:
            loader.dispose()
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f"{filename}:{mark.line + 1}:{mark.column + 1}" if mark else filename
        raise ConfigError([f"{where}: YAML syntax error: {getattr(exc, 'problem', exc)}"]) from None
    if node is None:
        raise ConfigError([f"{filename}: the file is empty"])
    marks: dict[tuple, tuple[int, int]] = {}
    problems: list[str] = []

    def walk(n: yaml.Node, path: tuple) -> None:
        marks[path] = (n.start_mark.line + 1, n.start_mark.column + 1)
        if isinstance(n, yaml.MappingNode):
            seen: dict[str, int] = {}
            for k, v in n.value:
                key = k.value
                if key in seen:
                    dotted = ".".join(str(p) for p in path + (key,))
                    problems.append(
                        f"{filename}:{k.start_mark.line + 1}:{k.start_mark.column + 1}: {dotted}: "
                        f"defined twice (first at line {seen[key]}); keep one"
                    )
                seen[key] = k.start_mark.line + 1
                walk(v, path + (key,))
        elif isinstance(n, yaml.SequenceNode):
            for i, v in enumerate(n.value):
                walk(v, path + (i,))

    walk(node, ())
    if problems:
        raise ConfigError(problems)
    data = _Loader(text).get_single_data()
    return data, SourceMap(filename, marks, data)


