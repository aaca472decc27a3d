"""Enum values of render config fields (the rest is :mod:`deckpose.typed_config`)."""

from __future__ import annotations

import enum
from typing import Any

from deckpose.errors import ConfigError


def parse_enum(cls: type[enum.Enum], value: object, where: str) -> Any:
    if isinstance(value, cls):
        return value
    try:
        return cls(str(value).lower())
    except ValueError:
        raise ConfigError(f"{where}: {value!r} is not one of {[e.value for e in cls]}") from None
