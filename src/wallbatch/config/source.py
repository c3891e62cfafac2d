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
OTHER_WALLS = ("reflect", "flow", "region", "region/ees", "reflect/stochastic")
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
        # a message never carries more than a few hundred characters of user text
        self.problems = [p if len(p) <= 2000 else p[:1997] + "..." for p in problems]
        super().__init__("\n".join(self.problems))


# pydantic's names of a union's members in an error's location: a type, a constrained type, a model
# (CamelCase with a lower-case letter; keys such as D0 or N have none)
_UNION_MEMBER = re.compile(r"float|int|str|bool|none|bytes|constrained-\w+|[A-Z][A-Za-z0-9]*[a-z]\w*")


def _a_key(part: str) -> bool:
    """Whether a loc part a pydantic error names could be a config key (not a union's tag)."""
    return part not in WALL_TAGS and not any(c in part for c in "[]()") and not _UNION_MEMBER.fullmatch(part)


def tuple_length_errors(errors: list[dict]) -> list[dict]:
    """Pydantic errors with a fixed-length list of the wrong length said plainly: the `missing`
    errors pydantic gives per absent item of a too-short tuple become one error at the list
    ("expects 3 values, got 2"), and its "Tuple should have at most ..." of a too-long one too."""
    out: list[dict] = []
    short: dict[tuple, dict] = {}  # the list's loc -> its one error
    for err in errors:
        loc, given = tuple(err["loc"]), err.get("input")
        if err["type"] == "missing" and loc and isinstance(loc[-1], int) and isinstance(given, (list, tuple)) \
                and loc[-1] >= len(given):
            need = loc[-1] + 1
            if loc[:-1] in short:
                short[loc[:-1]]["need"] = max(short[loc[:-1]]["need"], need)
                continue
            short[loc[:-1]] = new = {**err, "loc": loc[:-1], "need": need, "got": len(given)}
            out.append(new)
        elif err["type"] == "too_long" and (err.get("ctx") or {}).get("field_type") == "Tuple":
            ctx = err["ctx"]
            out.append({**err, "msg": f"expects {ctx['max_length']} values, got {ctx['actual_length']}"})
        else:
            out.append(err)
    for err in short.values():
        err["msg"] = f"expects {err.pop('need')} values, got {err.pop('got')}"
    return out


def model_type_errors(errors: list[dict]) -> list[dict]:
    """Pydantic's "Input should be a valid dictionary or instance of Run" (a scalar or a list where
    a section of keys belongs) said without the class name: "expected a mapping of keys, got 5"."""
    out = []
    for err in errors:
        loc, given = tuple(err["loc"]), err.get("input")
        if err["type"] == "model_type" and loc and loc[-1] == (err.get("ctx") or {}).get("class_name") \
                and isinstance(given, (int, float)) and not isinstance(given, bool) \
                and any(tuple(e["loc"][:-1]) == loc[:-1] and e is not err for e in errors):
            continue  # a number given to a union of a number and a section: the number's error says it
        if err["type"] == "model_type":
            kind = {list: "a list", str: "text", bool: "true/false", type(None): "nothing (null)"}.get(
                type(given), "a number" if isinstance(given, (int, float)) else type(given).__name__)
            shown = "" if given is None else f" {shorten(repr(given) if isinstance(given, str) else given, 80)}"
            face = str((err.get("ctx") or {}).get("class_name", "")).endswith("Face")
            also = " or the positional list of the LAMMPS command (coord epsilon sigma cutoff ...)" if face else ""
            err = {**err, "msg": f"expected a mapping of keys (key: value){also}, got {kind}{shown}"}
        out.append(err)
    return out


KEY = "<key>"  # last part of a path that means the mapping key itself (a problem of a name: shown at the key)


class SourceMap:
    """Where each value of a YAML document stands: dotted path -> (line, column), 1-based."""

    def __init__(self, filename: str, marks: dict[tuple, tuple[int, int]], data: Any):
        self.filename = filename
        self.marks = marks
        self.data = data

    def locate(self, loc: tuple) -> tuple[tuple, tuple[int, int] | None]:
        """Resolve a Pydantic error location against the data: drop union tags and other loc
        parts that index nothing, and return (path to show, nearest known mark)."""
        shown, path, _ = self.walk(loc)
        mark = None
        for n in range(len(path), -1, -1):
            mark = self.marks.get(tuple(path[:n]))
            if mark:
                break
        return shown, mark

    def walk(self, loc: tuple) -> tuple[tuple, list, bool]:
        """`locate`'s walk of the data: (path to show, path indexing the marks, whether a key of
        loc is missing from the data). Loc parts that are no key (union tags: a wall style,
        pydantic's names of a union's members such as `float`, `constrained-int` or a model's
        name) are left out."""
        path: list = []  # indexes the marks: mapping keys as written (text), list indices
        shown: list = []  # what the user reads: field names, also for positional faces
        node, missing = self.data, False
        for i, part in enumerate(loc):
            if isinstance(node, dict) and part in WALL_TAGS and node.get("style") == part and i + 1 < len(loc):
                continue  # the union tag of this wall (`region` is also a key of a region wall)
            if part == KEY:  # the key written for the path so far (its own mark), not a value inside it
                path.append(KEY)
                break
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
            elif isinstance(node, dict) and isinstance(part, str) and (part in FACES or _a_key(part)):
                shown.append(part)  # a missing key: name it, point at its parent
                node, missing = None, True
            elif isinstance(node, str) and isinstance(part, str) and _a_key(part):
                shown.append(part)  # a field of a wall written as a fix line: name it, point at the line
        return tuple(shown), path, missing

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


# limits on what a config file may hold: checked while reading, before anything is built from it
MAX_CONFIG_BYTES = 20_000_000  # size of one YAML file
MAX_DEPTH = 64  # nesting of mappings and lists
MAX_NODES = 2_000_000  # values after alias expansion (a 1 kB alias bomb expands to billions)
SAFE_TAGS = frozenset(f"tag:yaml.org,2002:{t}" for t in ("str", "int", "float", "bool", "null", "map", "seq", "merge",
                                                          "timestamp"))


def shorten(text: str, limit: int = 200) -> str:
    """User text quoted in a message: at most `limit` characters, one line."""
    text = str(text).replace("\n", "\\n")
    return text if len(text) <= limit else text[: limit - 3] + "..."


def read_config_text(path) -> str:
    """The text of a config file: a regular file of UTF-8 text within MAX_CONFIG_BYTES."""
    import os
    import stat

    try:
        st = os.stat(path)
    except OSError as exc:
        raise ConfigError([f"{path}: cannot read the config: {exc.strerror}"]) from None
    if not stat.S_ISREG(st.st_mode):
        kind = "a directory" if stat.S_ISDIR(st.st_mode) else "not a regular file (a pipe or a device)"
        raise ConfigError([f"{path}: cannot read the config: it is {kind}"])
    if st.st_size > MAX_CONFIG_BYTES:
        raise ConfigError([f"{path}: the config is {st.st_size:,} bytes, more than the limit of "
                           f"{MAX_CONFIG_BYTES:,}: put large data in an atoms file"])
    try:
        with open(path, "rb") as fh:
            raw = fh.read(MAX_CONFIG_BYTES + 1)
    except OSError as exc:
        raise ConfigError([f"{path}: cannot read the config: {exc.strerror}"]) from None
    try:
        return raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        line = raw[: exc.start].count(b"\n") + 1
        col = exc.start - (raw.rfind(b"\n", 0, exc.start) + 1) + 1
        hint = " (it looks like UTF-16: save it as UTF-8)" if raw[:2] in (b"\xff\xfe", b"\xfe\xff") else ""
        raise ConfigError([f"{path}:{line}:{col}: the config is not UTF-8 text (byte 0x{raw[exc.start]:02x})"
                           f"{hint}"]) from None


def _reader_error(exc: Any, text: str, filename: str) -> str:
    pos = int(getattr(exc, "position", 0) or 0)
    line = text.count("\n", 0, pos) + 1
    col = pos - (text.rfind("\n", 0, pos) + 1) + 1
    char = getattr(exc, "character", "")
    if isinstance(char, str) and len(char) == 1:
        char = ord(char)
    code = f"U+{char:04X}" if isinstance(char, int) else repr(char)
    return f"{filename}:{line}:{col}: the character {code} is not allowed in YAML (a control character?)"


def _syntax_hint(problem: str) -> str:
    """What to do about the YAML syntax errors people make most."""
    if "'\\t'" in problem:
        return ": indent with spaces (YAML does not allow tabs there)"
    if "mapping values are not allowed" in problem:
        return ": a 'key: value' inside a value? quote the value, or start a new line for the key"
    return ""


def load_yaml(text: str, filename: str = "<config>") -> tuple[Any, SourceMap]:
    """Parse YAML (safe: plain data only) and keep the line/column of every value.

    Refused with a location: syntax errors, tags other than plain data (`!!python/...`, `!foo`),
    keys that are not plain text, duplicate keys, nesting deeper than MAX_DEPTH, aliases that refer
    to themselves or expand to more than MAX_NODES values."""
    if len(text) > MAX_CONFIG_BYTES:
        raise ConfigError([f"{filename}: the config is {len(text):,} characters, more than the limit of "
                           f"{MAX_CONFIG_BYTES:,}"])
    try:
        loader = _Loader(text)
    except yaml.reader.ReaderError as exc:  # a control character: YAML reads printable text only
        raise ConfigError([_reader_error(exc, text, filename)]) from None
    try:
        try:
            node = loader.get_single_node()
        except yaml.reader.ReaderError as exc:
            raise ConfigError([_reader_error(exc, text, filename)]) from None
        except yaml.YAMLError as exc:
            mark = getattr(exc, "problem_mark", None)
            where = f"{filename}:{mark.line + 1}:{mark.column + 1}" if mark else filename
            problem = str(getattr(exc, "problem", None) or exc)
            raise ConfigError([f"{where}: YAML syntax error: {shorten(problem)}{_syntax_hint(problem)}"]) \
                from None
        except RecursionError:
            raise ConfigError([f"{filename}: the YAML is nested too deeply (limit {MAX_DEPTH} levels)"]) from None
        if node is None:
            raise ConfigError([f"{filename}: the file is empty"])
        marks: dict[tuple, tuple[int, int]] = {}
        problems: list[str] = []
        count = [0]

        def at(n: yaml.Node) -> str:
            return f"{filename}:{n.start_mark.line + 1}:{n.start_mark.column + 1}"

        def walk(n: yaml.Node, path: tuple, active: set[int]) -> None:
            count[0] += 1
            if count[0] > MAX_NODES:
                raise ConfigError([f"{at(n)}: the YAML expands to more than {MAX_NODES:,} values (aliases "
                                   f"repeated inside aliases?): write the data out or shorten it"])
            marks.setdefault(path, (n.start_mark.line + 1, n.start_mark.column + 1))
            dotted = ".".join(str(p) for p in path) or "(top level)"
            if n.tag not in SAFE_TAGS:
                raise ConfigError([f"{at(n)}: {shorten(dotted)}: YAML tag {shorten(n.tag.replace('tag:yaml.org,2002:', '!!'), 60)} is not allowed "
                                   f"(configs hold plain data: text, numbers, lists, mappings)"])
            if not isinstance(n, (yaml.MappingNode, yaml.SequenceNode)):
                return
            if id(n) in active:
                raise ConfigError([f"{at(n)}: {shorten(dotted)}: an alias refers to the value that contains it"])
            if len(path) >= MAX_DEPTH:
                raise ConfigError([f"{at(n)}: {shorten(dotted)}: nested more than {MAX_DEPTH} levels deep"])
            active.add(id(n))
            if isinstance(n, yaml.MappingNode):
                seen: dict[Any, tuple[int, str]] = {}
                for k, v in n.value:
                    if not isinstance(k, yaml.ScalarNode) or k.tag not in SAFE_TAGS:
                        raise ConfigError([f"{at(k)}: {shorten(dotted)}: a key must be plain text or a number"])
                    key = k.value
                    if "\n" in key or "\r" in key:
                        raise ConfigError([f"{at(k)}: {shorten(dotted)}: a key may not contain a line break"])
                    if k.tag.endswith(":merge"):
                        walk(v, path + (key,), active)
                        continue
                    try:  # the key as YAML reads it: `1`, `0x1` and `+1` are one key; `~` is null
                        value = loader.construct_object(k)
                        same = str(value) if isinstance(value, (str, int, float)) and not isinstance(
                            value, bool) else key  # `1:` and `'1':` name one fix too
                    except (yaml.YAMLError, TypeError, ValueError, OverflowError):
                        value, same = key, key
                    if value is None:
                        raise ConfigError([f"{at(k)}: {shorten(dotted)}: the key {shorten(key or '(empty)', 40)} "
                                           f"reads as null: write a name"])
                    if same in seen:
                        line, first = seen[same]
                        alias = "" if first == key else f" as {shorten(first, 40)}; YAML reads both as {same}"
                        problems.append(f"{at(k)}: {shorten('.'.join(str(p) for p in path + (key,)))}: "
                                        f"defined twice (first at line {line}{alias}); keep one")
                    else:
                        seen[same] = (k.start_mark.line + 1, key)
                    marks.setdefault(path + (key, KEY), (k.start_mark.line + 1, k.start_mark.column + 1))
                    walk(v, path + (key,), active)
            else:
                for i, v in enumerate(n.value):
                    walk(v, path + (i,), active)
            active.discard(id(n))

        walk(node, (), set())
        if problems:
            raise ConfigError(problems)
        try:
            data = loader.construct_document(node)
        except yaml.YAMLError as exc:
            mark = getattr(exc, "problem_mark", None)
            where = f"{filename}:{mark.line + 1}:{mark.column + 1}" if mark else filename
            raise ConfigError([f"{where}: {shorten(getattr(exc, 'problem', None) or exc)}"]) from None
        except (TypeError, ValueError, OverflowError) as exc:  # e.g. a timestamp out of range
            raise ConfigError([f"{filename}: cannot read a value: {shorten(exc)}"]) from None
    finally:
        loader.dispose()
    return data, SourceMap(filename, marks, data)
