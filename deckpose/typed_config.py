"""One typed config loader: YAML text into frozen dataclasses, by their annotations.

Every config of deckpose (render jobs, deck layouts, synthetic detector datasets,
motion jobs) is read by :func:`load_yaml` and built by :func:`from_mapping`, so
they all reject the same mistakes with the same one-line messages:

* a file that cannot be read, is not text, is not valid YAML (line and column
  named) or repeats a key (YAML takes the last silently; we refuse);
* unknown keys, listed with the valid ones;
* a value of the wrong type, checked exactly against the field's annotation: a
  ``bool`` field takes ``true``/``false`` only (the string ``"no"`` is truthy), an
  ``int`` field an integer only (``12.5`` is not silently 12, ``true`` is not 1), a
  ``float`` field a number but not a quoted one or a boolean, an enum field one of
  its values; ``X | None``, ``tuple[X, ...]``, fixed-length tuples, nested
  dataclasses and ``Any`` are understood.

Ranges and cross-field rules stay with each config (they are what the fields
mean); this module only makes sure each value is the type it claims to be.
"""

from __future__ import annotations

import dataclasses
import difflib
import enum
import math
import os
import re
import types
import typing
from collections.abc import Callable, Iterable, Mapping
from pathlib import Path
from typing import Any, TypeVar

import yaml

from deckpose.errors import ConfigError, short_repr

T = TypeVar("T")


class _UniqueKeyLoader(yaml.SafeLoader):
    """A safe YAML loader that refuses a key repeated in one mapping."""


def _mapping_without_duplicates(loader: yaml.SafeLoader, node: yaml.MappingNode, deep: bool = False) -> Any:
    seen: dict[Any, yaml.Node] = {}
    for key_node, _value in node.value:
        key = loader.construct_object(key_node, deep=deep)  # type: ignore[arg-type]
        try:
            first = seen.get(key)
        except TypeError:  # an unhashable key: PyYAML's own error follows
            break
        if first is not None:
            raise yaml.constructor.ConstructorError(
                None, None,
                f"key {key!r} appears twice (lines {first.start_mark.line + 1} and "
                f"{key_node.start_mark.line + 1}); keep one",
                None,
            )
        seen[key] = key_node
    return loader.construct_mapping(node, deep=deep)


_UniqueKeyLoader.add_constructor(
    yaml.resolver.BaseResolver.DEFAULT_MAPPING_TAG, _mapping_without_duplicates
)
# YAML 1.1 (PyYAML) reads ``1e-5`` as a string: its floats need a dot (``1.0e-5``). YAML 1.2
# and every other reader take it as a number, and so does a config author, so exponent
# floats without a dot are floats here too. The resolver lists are copied first: PyYAML's
# add_implicit_resolver would append to the lists it shares with SafeLoader.
_UniqueKeyLoader.yaml_implicit_resolvers = {
    k: list(v) for k, v in yaml.SafeLoader.yaml_implicit_resolvers.items()
}
_UniqueKeyLoader.add_implicit_resolver(
    "tag:yaml.org,2002:float",
    re.compile(r"^[-+]?[0-9][0-9_]*(?:\.[0-9_]*)?[eE][-+]?[0-9]+$"),
    list("-+0123456789"),
)


def yaml_error_line(exc: yaml.YAMLError) -> str:
    """One line for a YAML error: what is wrong and where (line, column), without a dump."""
    mark = getattr(exc, "problem_mark", None)
    problem = getattr(exc, "problem", None) or str(exc).splitlines()[0]
    where = f" at line {mark.line + 1}, column {mark.column + 1}" if mark is not None else ""
    context = getattr(exc, "context", None)
    return f"{problem}{where}" + (f" ({context})" if context else "")


def parse_yaml(text: str, source: str, error: type[Exception] = ConfigError) -> Any:
    """Parse YAML text, refusing duplicate keys; errors are one line naming ``source``."""
    try:
        return yaml.load(text, Loader=_UniqueKeyLoader)
    except yaml.YAMLError as exc:
        raise error(f"{source}: not valid YAML: {yaml_error_line(exc)}") from None


def load_yaml(
    path: str | os.PathLike[str], what: str, error: type[Exception] = ConfigError
) -> Any:
    """Read and parse a YAML file; every failure is one ``error`` naming the file.

    Parameters
    ----------
    path : path-like
    what : str
        What the file is, for the messages ("render config", "layout file").
    error : exception type
        Raised on failure (a :class:`~deckpose.errors.DeckposeError` subclass).
    """
    p = Path(path)
    try:
        raw = p.read_bytes()
    except IsADirectoryError:
        raise error(f"cannot read {what} {p}: it is a folder; give a YAML file") from None
    except OSError as exc:
        raise error(f"cannot read {what} {p}: {exc.strerror}") from None
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise error(
            f"{p}: not a text file (byte {exc.start} is not UTF-8); a {what} is YAML text"
        ) from None
    if "\x00" in text:
        raise error(f"{p}: not a text file (it holds NUL bytes); a {what} is YAML text")
    return parse_yaml(text, str(p), error)


def _describe(value: object) -> str:
    if isinstance(value, str):
        return f"{value!r} (a string; numbers and true/false go without quotes)"
    if isinstance(value, bool):
        return f"{str(value).lower()} (a boolean)"
    if isinstance(value, (dict, list)):
        return f"a {'mapping' if isinstance(value, dict) else 'list'} ({short_repr(value)})"
    return short_repr(value)


def coerce(hint: Any, value: object, where: str) -> Any:
    """``value`` as the type ``hint`` describes, exactly; :class:`ConfigError` otherwise.

    Parameters
    ----------
    hint : type annotation (resolved)
    value : object
        A parsed YAML value.
    where : str
        The key's dotted path, for the message.
    """
    origin = typing.get_origin(hint)
    if hint is Any:
        return value
    if origin in (typing.Union, types.UnionType):
        args = typing.get_args(hint)
        if value is None and type(None) in args:
            return None
        others = [a for a in args if a is not type(None)]
        if len(others) == 1:
            return coerce(others[0], value, where)
        errors = []
        for a in others:
            try:
                return coerce(a, value, where)
            except ConfigError as exc:
                errors.append(str(exc))
        raise ConfigError(errors[0])
    if value is None:
        raise ConfigError(f"{where}: a value is needed here (got null)")
    if hint is bool:
        if isinstance(value, bool):
            return value
        raise ConfigError(f"{where}: expected true or false, got {_describe(value)}")
    if hint is int:
        if isinstance(value, int) and not isinstance(value, bool):
            return value
        raise ConfigError(f"{where}: expected an integer, got {_describe(value)}")
    if hint is float:
        if isinstance(value, (int, float)) and not isinstance(value, bool):
            v = float(value)
            if not math.isfinite(v):
                raise ConfigError(f"{where}: expected a finite number, got {value!r}")
            return v
        raise ConfigError(f"{where}: expected a number, got {_describe(value)}")
    if hint is str:
        if isinstance(value, str):
            return value
        raise ConfigError(f"{where}: expected a string, got {_describe(value)}")
    if isinstance(hint, type) and issubclass(hint, enum.Enum):
        if isinstance(value, hint):
            return value
        valid = [e.value for e in hint]
        if isinstance(value, str):
            try:
                return hint(value.lower())
            except ValueError:
                pass
        raise ConfigError(f"{where}: {short_repr(value)} is not one of {valid}")
    if origin is tuple:
        args = typing.get_args(hint)
        if not isinstance(value, (list, tuple)):
            raise ConfigError(f"{where}: expected a list, got {_describe(value)}")
        if len(args) == 2 and args[1] is Ellipsis:
            return tuple(coerce(args[0], v, f"{where}[{i}]") for i, v in enumerate(value))
        if len(value) != len(args):
            raise ConfigError(f"{where}: expected a list of {len(args)} values, got {len(value)}")
        return tuple(coerce(a, v, f"{where}[{i}]") for i, (a, v) in enumerate(zip(args, value)))
    if dataclasses.is_dataclass(hint) and isinstance(hint, type):
        return from_mapping(hint, value, where)
    raise TypeError(f"typed_config: no rule for the annotation {hint!r} of {where}")


def did_you_mean(unknown: Iterable[object], valid: Iterable[str]) -> str:
    """`` (did you mean 'heights_m'?)`` for unknown keys close to a valid one, else ``""``.

    Closeness is :func:`difflib.get_close_matches`' ratio (at least 0.75), so a
    typo or a singular/plural slip is named and an unrelated key is not.
    """
    names = list(valid)
    pairs = []
    for key in unknown:
        near = difflib.get_close_matches(str(key), names, n=1, cutoff=0.75)
        if near:
            pairs.append(f"{near[0]!r} instead of {str(key)!r}")
    return f" (did you mean {', '.join(pairs)}?)" if pairs else ""


def from_mapping(
    cls: type[T],
    doc: object,
    where: str,
    *,
    convert: Mapping[str, Callable[[object, str], Any]] | None = None,
) -> T:
    """An instance of the dataclass ``cls`` from a parsed YAML mapping (``None``: defaults).

    Each key is checked against its field's annotation (:func:`coerce`); keys in
    ``convert`` are built by their own function ``(value, where) -> field value``
    instead (a shape the annotation does not say, such as a mapping stored as pairs).
    Missing keys take the field's default. ``where`` names the mapping in messages
    (``sensor``, ``cameras[0]``); one ending in ``:`` (``"job.yaml:"``) is a file's top
    level, whose keys are named after it (``job.yaml: seed``).
    """
    if doc is None:
        doc = {}
    here = where.rstrip(":")  # "job.yaml:" names a file's top level; its messages read "job.yaml: ..."
    if not isinstance(doc, dict):
        raise ConfigError(f"{here}: expected a mapping of keys, got {_describe(doc)}")
    fields = {f.name: f for f in dataclasses.fields(cls)}  # type: ignore[arg-type]
    unknown = [k for k in doc if k not in fields]
    if unknown:
        raise ConfigError(
            f"{here}: unknown key(s) {sorted(map(str, unknown))}{did_you_mean(unknown, fields)}; "
            f"valid keys are {sorted(fields)}"
        )
    hints = typing.get_type_hints(cls)
    kwargs: dict[str, Any] = {}
    for key, value in doc.items():
        # "file.yaml:" names a file's top level: its keys follow after a space
        sub = f"{where} {key}" if where.endswith(":") else f"{where}.{key}"
        if convert and key in convert:
            kwargs[key] = convert[key](value, sub)
        else:
            kwargs[key] = coerce(hints[key], value, sub)
    missing = [
        n for n, f in fields.items()
        if n not in kwargs and f.default is dataclasses.MISSING
        and f.default_factory is dataclasses.MISSING  # type: ignore[misc]
    ]
    if missing:
        raise ConfigError(f"{here}: required key(s) {missing} missing")
    try:
        return cls(**kwargs)
    except ConfigError as exc:  # a check of the record itself: say where it came from
        if str(exc).startswith(where.rstrip(":")):
            raise
        raise ConfigError(f"{where.rstrip(':')}: {exc}") from None


def check_range(
    value: float, where: str, *, low: float | None = None, high: float | None = None,
    low_open: bool = False, high_open: bool = False,
) -> float:
    """``value`` if it lies in the range, else a :class:`ConfigError` stating the range."""
    bad = (low is not None and (value < low or (low_open and value == low))) or (
        high is not None and (value > high or (high_open and value == high))
    )
    if bad:
        lo = "" if low is None else f"{'>' if low_open else '>='} {low:g}"
        hi = "" if high is None else f"{'<' if high_open else '<='} {high:g}"
        raise ConfigError(f"{where}: must be {' and '.join(s for s in (lo, hi) if s)}, got {value:g}")
    return value
