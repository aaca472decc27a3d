"""The Foxglove layout shipped beside a run's MCAP log (``RUN/foxglove_layout.json``).

Three panels: the camera image with the truth and detection annotations, a 3D view of the
scene (deck, beacons, camera frustum, the estimators' decks) and a plot of the per-frame
errors. The image panel is ``ImageViewPanel``, the id Foxglove Studio 1.48 (the last
open-source release, whose ``Image`` panel is behind a flag) knows, with its config keys
(``cameraTopic``, ``enabledMarkerTopics``); later versions and the Lichtblick fork migrate
it to their ``Image`` panel on import (``imageTopic`` and ``annotations`` from those keys).
``tools/foxglove_viewer`` opens the log with this layout in 1.48 under headless Chromium;
``tools/foxglove_check`` checks the keys against the newer app's panel configs.
"""

from __future__ import annotations

import re
from typing import Any

from deckpose import run_folder as rl

__all__ = ["IMAGE_PANEL", "PLOT_PANEL", "SCENE_PANEL", "foxglove_layout", "plot_path"]

IMAGE_PANEL = "ImageViewPanel!deckpose"
SCENE_PANEL = "3D!deckpose"
PLOT_PANEL = "Plot!errors"
#: The 3D view's camera: orbiting the world origin, looking down at the deck from 55 deg off vertical.
_CAMERA_STATE = {"distance": 75.0, "perspective": True, "phi": 55.0, "thetaOffset": 35.0,
                 "target": [0.0, 0.0, 0.0], "targetOffset": [0.0, 0.0, 8.0],
                 "targetOrientation": [0.0, 0.0, 0.0, 1.0], "fovy": 45.0, "near": 0.5, "far": 5000.0}


def plot_path(topic: str, field: str) -> str:
    """A Foxglove message path ``<topic>.<field>``; topics outside ``/[A-Za-z0-9_-]`` are quoted.

    The app's message-path grammar reads an unquoted topic as slash-separated ids
    of ``[A-Za-z0-9_-]``, so a topic with any other character (a dot, a space) must
    be written as a double-quoted string, backslashes and double quotes escaped.
    """
    if re.fullmatch(r"(/[A-Za-z0-9_-]*)+", topic):
        return f"{topic}.{field}"
    quoted = topic.replace("\\", "\\\\").replace('"', '\\"')
    return f'"{quoted}".{field}'


def foxglove_layout(detectors: list[str], pairs: list[tuple[str, str]]) -> dict[str, Any]:
    """A Foxglove layout: image with annotations, 3D view of the scene, error plots.

    Keys follow the app's panel configs: ``cameraTopic`` and ``enabledMarkerTopics``
    for the image panel (``ImageViewPanel``); ``followTf``, ``cameraState``, ``topics``
    (``/scene`` made visible: the 3D panel hides scene topics by default) and
    ``scene.transforms`` (axis and label settings) for the 3D panel; ``paths`` of message
    paths for the Plot panel; and ``playbackConfig``, which the app reads.
    """
    markers = ["/annotations/truth", *(f"/annotations/{d}" for d in detectors)]
    paths = []
    for d, m in pairs:
        for q in ("roll_err_deg", "pitch_err_deg", "yaw_err_deg", "height_err_m"):
            paths.append({"value": plot_path(f"/errors/{d}{rl.SEPARATOR}{m}", q), "enabled": True,
                          "timestampMethod": "receiveTime", "label": f"{d}+{m} {q}"})
    return {
        "configById": {
            IMAGE_PANEL: {"cameraTopic": "/camera/image", "enabledMarkerTopics": markers,
                          "synchronize": False, "transformMarkers": False, "mode": "fit"},
            SCENE_PANEL: {"followTf": "world", "cameraState": dict(_CAMERA_STATE),
                          "topics": {"/scene": {"visible": True}},
                          "scene": {"transforms": {"showLabel": True, "axisScale": 3}}},
            PLOT_PANEL: {"paths": paths, "showLegend": True, "xAxisVal": "timestamp"},
        },
        "globalVariables": {},
        "userNodes": {},
        "playbackConfig": {"speed": 1.0},
        "layout": {"direction": "row", "first": IMAGE_PANEL,
                   "second": {"direction": "column", "first": SCENE_PANEL, "second": PLOT_PANEL,
                              "splitPercentage": 50},
                   "splitPercentage": 55},
    }
