"""The documentation of a config field, kept on the field: its description, unit and example.

Config dataclasses annotate a field ``Annotated[type, field_doc("...", unit="m")]``;
pydantic carries the text into the JSON schema (``description``, ``examples`` and the
extra key ``unit``), from which ``docs/gen_scene_reference.py`` writes the scene
reference page. Constraints (``ge``, ``max_length``, ...) go in the same call.

Examples:
    >>> import pydantic
    >>> from typing import Annotated
    >>> schema = pydantic.TypeAdapter(
    ...     Annotated[float, field_doc("Height of the top.", unit="m", gt=0)]
    ... ).json_schema()
    >>> schema["description"], schema["unit"], schema["exclusiveMinimum"]
    ('Height of the top.', 'm', 0)
"""

from __future__ import annotations

from typing import Any

import pydantic
from pydantic.fields import FieldInfo

__all__ = ["field_doc"]


def field_doc(
    description: str, unit: str = "", example: Any = None, **constraints: Any
) -> FieldInfo:
    """A ``pydantic.Field`` with ``description``, the ``unit`` (``""``: none) and, when
    given, one ``example`` value, plus any ``constraints``."""
    return pydantic.Field(
        description=description,
        examples=None if example is None else [example],
        json_schema_extra={"unit": unit},
        **constraints,
    )
