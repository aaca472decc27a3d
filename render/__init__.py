"""Rendering stage: synthetic camera frames of the lit deck with exact ground truth."""

from typing import TYPE_CHECKING

__all__ = [
    "RenderConfig",
    "config_from_dict",
    "default_config",
    "load_config",
    "render_dataset",
]

#: Where each name of the stage API lives.
_API: dict[str, str] = {
    "RenderConfig": "deckpose.render.config",
    "load_config": "deckpose.render.config",
    "config_from_dict": "deckpose.render.config",
    "default_config": "deckpose.render.config",
    "render_dataset": "deckpose.render.dataset",
}

if TYPE_CHECKING:  # the same names for type checkers (at run time __getattr__ imports them)
    from deckpose.render.config import RenderConfig, config_from_dict, default_config, load_config
    from deckpose.render.dataset import render_dataset


def __getattr__(name: str) -> object:
    """The stage API, imported on first use (so that ``import deckpose.render`` stays cheap)."""
    import importlib

    try:
        module = _API[name]
    except KeyError:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}") from None
    return getattr(importlib.import_module(module), name)


def __dir__() -> list[str]:
    return sorted(__all__)
