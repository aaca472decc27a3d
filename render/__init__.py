"""Rendering stage: synthetic camera frames of the lit deck with exact ground truth."""

from typing import TYPE_CHECKING

from deckpose.lazy_api import lazy_api

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

__getattr__, __dir__ = lazy_api(__name__, _API)
