"""The base of every config model: YAML's `true` / `false` is not a number.

Pydantic's lax mode reads a bool as the integer or float 1 / 0, so `steps: true` would run one
step. A bool written for a key whose type admits neither a bool nor text is passed on as its
YAML spelling (`'true'`), which that key's own check then refuses at its place ("Input should be
a valid integer", "expected a number").
"""

from __future__ import annotations

from typing import Any, Literal, get_args, get_origin

from pydantic import BaseModel, model_validator


def admits_bool_or_text(tp: Any) -> bool:
    """A type (with its unions, Annotated, Literal and container arguments) admits a bool or a str."""
    if tp is bool or tp is str or tp is Any:
        return True
    if get_origin(tp) is Literal:
        return any(isinstance(a, (bool, str)) for a in get_args(tp))
    return any(admits_bool_or_text(a) for a in get_args(tp) if a is not Ellipsis)


def _spelled(v: Any) -> Any:
    """A bool as YAML writes it, inside lists too."""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (list, tuple)):
        return [_spelled(e) for e in v]
    return v


def _has_bool(v: Any) -> bool:
    return isinstance(v, bool) or (isinstance(v, (list, tuple)) and any(isinstance(e, bool) for e in v))


class NoBoolNumbers(BaseModel):
    """Config model base: a bool given for a number is refused at its key, not read as 1 or 0."""

    @model_validator(mode="before")
    @classmethod
    def _bools_are_not_numbers(cls, data: Any) -> Any:
        if not isinstance(data, dict):
            return data
        fields = cls.model_fields
        spell = [k for k, v in data.items()
                 if _has_bool(v) and k in fields and not admits_bool_or_text(fields[k].annotation)]
        return {**data, **{k: _spelled(data[k]) for k in spell}} if spell else data
