"""Shared fixtures of the render tests: tiny configs and one in-process renderer."""

from __future__ import annotations

import os
from typing import Any

import pytest
from deckpose.render.config import RenderConfig, config_from_dict


def tiny_doc(**over: Any) -> dict[str, Any]:
    """A small config (320x240) as YAML data; keyword arguments replace top-level keys."""
    doc: dict[str, Any] = {
        "name": "tiny",
        "seed": 3,
        "backend": "egl",
        "cameras": [{"preset": "4mp", "size": [320, 240]}],
        "heights_m": [25.0, 40.0],
        "lighting": ["night", "day"],
        "motion": {"source": "fixed", "attitudes_deg": [[0, 0, 0], [4.0, -3.0, 20.0, 0.5, 0.3, -0.2]]},
        "sensor": {"bit_depth": 8, "read_noise_e": 5},
        "scene": {"shading": "flat", "texture_px": 256},
    }
    doc.update(over)
    return doc


def tiny_config(**over: Any) -> RenderConfig:
    return config_from_dict(tiny_doc(**over))


@pytest.fixture(scope="session")
def egl_renderer_factory():
    """Renderers for this (pytest) process; EGL only - OSMesa is tested in a worker process."""
    from deckpose.render.config import Backend
    from deckpose.render.scene import DeckRenderer, use_backend

    if os.environ.get("PYOPENGL_PLATFORM", "egl") != "egl":
        pytest.skip("this process already uses another GL platform")
    use_backend(Backend.EGL)
    made: dict[Any, DeckRenderer] = {}

    def make(cfg: RenderConfig) -> DeckRenderer:
        key = (cfg.layout, cfg.scene, cfg.deck_half_size_m())
        if key not in made:
            made[key] = DeckRenderer(cfg.layout, cfg.scene, cfg.deck_half_size_m(), cfg.backend)
        return made[key]

    yield make
    for r in made.values():
        r.close()
