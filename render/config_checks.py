"""Small validators shared by the render config sections (unknown keys, enum values)."""

from __future__ import annotations

import enum
from dataclasses import fields
from typing import Any

from deckpose.errors import ConfigError


def check_keys(doc: object, cls: type, where: str) -> dict[str, Any]:
    if doc is None:
        return {}
    if not isinstance(doc, dict):
        raise ConfigError(f"{where}: expected a mapping, got {type(doc).__name__}")
    valid = {f.name for f in fields(cls)}
    unknown = set(doc) - valid
    if unknown:
        raise ConfigError(f"{where}: unknown key(s) {sorted(unknown)}; valid keys are {sorted(valid)}")
    return dict(doc)


def parse_enum(cls: type[enum.Enum], value: object, where: str) -> Any:
    if isinstance(value, cls):
        return value
    try:
        return cls(str(value).lower())
    except ValueError:
        raise ConfigError(f"{where}: {value!r} is not one of {[e.value for e in cls]}") from None
