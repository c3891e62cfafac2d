"""Unions of Pydantic models tagged by a key (`style:`), validated on demand: each value is
validated by the model its tag names, built when first used, instead of a union whose every
model is built when the config models are (start-up of every run, issue 15).

The errors are those of `Annotated[Union[...], Field(discriminator=key)]` (the same messages, the
tag after the key in their places) and so is the JSON schema, which builds every model.
"""

from __future__ import annotations

import functools
from typing import Annotated, Any, Callable, Union

from pydantic import BaseModel, Field, GetCoreSchemaHandler, GetJsonSchemaHandler, TypeAdapter
from pydantic_core import CoreSchema, PydanticKnownError, core_schema


def tagged_on_demand(tags: tuple[str, ...], model_of: Callable[[str], type[BaseModel]], key: str = "style") -> type:
    """A field type for the union of `model_of(tag)` over `tags` (in this order), tagged by `key`."""

    @functools.cache
    def tagged(tag: str) -> TypeAdapter:
        # {tag: value} through a mapping: the errors' places name the tag, as the union's do
        model = model_of(tag)
        model.model_rebuild()  # its own validator and serializer too (dumping a config serializes it)
        return TypeAdapter(dict[str, model])  # type: ignore[valid-type]

    def validate(value: Any) -> Any:
        if isinstance(value, dict):
            if key not in value:
                raise PydanticKnownError("union_tag_not_found", {"discriminator": f"'{key}'"})
            tag = value[key]
        elif isinstance(value, BaseModel) and hasattr(value, key):
            tag = getattr(value, key)
        else:
            raise PydanticKnownError("model_attributes_type")
        if not (isinstance(tag, str) and tag in tags):
            raise PydanticKnownError("union_tag_invalid", {
                "discriminator": f"'{key}'", "tag": str(tag), "expected_tags": ", ".join(f"'{t}'" for t in tags)})
        return tagged(tag).validate_python({tag: value})[tag]

    def union() -> Any:
        return Annotated[Union[tuple(model_of(t) for t in tags)], Field(discriminator=key)]  # type: ignore[misc]

    class OnDemand:
        """Validated by the model its tag names (built on first use); JSON schema: the union."""

        @classmethod
        def __get_pydantic_core_schema__(cls, source: Any, handler: GetCoreSchemaHandler) -> CoreSchema:
            return core_schema.no_info_plain_validator_function(validate)

        @classmethod
        def __get_pydantic_json_schema__(cls, schema: CoreSchema, handler: GetJsonSchemaHandler) -> Any:
            return handler(TypeAdapter(union()).core_schema)

        @classmethod
        def full_annotation(cls) -> Any:
            """The annotation this type stands for (for tools that read the models' annotations,
            like the docs' reference generator): the tagged union of every model."""
            return union()

    return OnDemand
