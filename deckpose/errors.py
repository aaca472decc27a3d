"""The one exception hierarchy of deckpose.

Every error we raise on bad input derives from :class:`DeckposeError` and from the
matching builtin (``ValueError``, ``FileNotFoundError``...), so callers can catch
either. Messages say what was wrong *and* how to fix it.
"""

from __future__ import annotations


class DeckposeError(Exception):
    """Root of all deckpose errors."""


class ShapeError(DeckposeError, ValueError):
    """An array does not have the shape a function or record expects."""


class ConfigError(DeckposeError, ValueError):
    """A configuration file or option is invalid."""


class CameraFileError(DeckposeError, ValueError):
    """A camera_info YAML file cannot be parsed or is inconsistent."""


class InputDataError(DeckposeError, ValueError):
    """A table of detections, motion or ground truth is malformed."""


def short_repr(value: object, limit: int = 60) -> str:
    """``repr(value)`` cut to ``limit`` characters, for messages (a 5-million-character
    cell must not become a 5 MB error)."""
    item = getattr(value, "item", None)
    if callable(item) and getattr(value, "shape", None) == ():
        value = item()  # a numpy scalar as the Python value it holds: nan, not np.float64(nan)
    s = repr(value)
    return s if len(s) <= limit else s[: limit - 3] + "..."


def check_shape(name: str, array: object, shape: tuple[int | None, ...]) -> None:
    """Raise :class:`ShapeError` unless ``array`` has ``shape`` (``None`` = any size).

    Parameters
    ----------
    name : str
        Name of the argument, used in the message.
    array : array_like
        The array to check (must expose ``.shape``).
    shape : tuple of int or None
        Expected shape; ``None`` entries match any length.
    """
    actual = getattr(array, "shape", None)
    ok = actual is not None and len(actual) == len(shape) and all(
        e is None or e == a for e, a in zip(shape, actual)
    )
    if not ok:
        want = "(" + ", ".join("N" if e is None else str(e) for e in shape) + ")"
        raise ShapeError(f"{name}: expected shape {want}, got {actual}")
