"""The Foxglove layout shipped beside a run's MCAP log (``RUN/foxglove_layout.json``).

Three panels: the camera image with the truth and detection annotations, a 3D view of the
scene (deck, beacons, camera frustum, the estimators' decks) and a plot of the per-frame
errors; a run with tracks gets a fourth, its roll against time (true, per frame, filtered,
predicted). The image panel is ``ImageViewPanel``, the id Foxglove Studio 1.48 (the last
open-source release, whose ``Image`` panel is behind a flag) knows, with its config keys
(``cameraTopic``, ``enabledMarkerTopics``); later versions and the Lichtblick fork migrate
it to their ``Image`` panel on import (``imageTopic`` and ``annotations`` from those keys).
``tools/foxglove_viewer`` opens the log with this layout in 1.48 under headless Chromium;
``tools/foxglove_check`` checks the keys against the newer app's panel configs.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from typing import Any

from deckpose.evaluate.log_topics import (
    TRUTH_DECK_TOPIC,
    errors_topic,
    estimates_topic,
    prediction_topic,
    track_stem,
    track_topic,
)

__all__ = ["IMAGE_PANEL", "PLOT_PANEL", "SCENE_PANEL", "TRACK_PLOT_PANEL", "foxglove_layout", "plot_path"]

IMAGE_PANEL = "ImageViewPanel!deckpose"
SCENE_PANEL = "3D!deckpose"
PLOT_PANEL = "Plot!errors"
#: With tracks: roll against time, true, per-frame, filtered and predicted at each horizon.
TRACK_PLOT_PANEL = "Plot!tracks"
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


def foxglove_layout(detectors: list[str], pairs: list[tuple[str, str]],
                    tracks: Sequence[tuple[str, str, str, Sequence[float]]] = ()) -> dict[str, Any]:
    """A Foxglove layout: image with annotations, 3D view of the scene, error plots.

    Keys follow the app's panel configs: ``cameraTopic`` and ``enabledMarkerTopics``
    for the image panel (``ImageViewPanel``); ``followTf``, ``cameraState``, ``topics``
    (``/scene`` made visible: the 3D panel hides scene topics by default) and
    ``scene.transforms`` (axis and label settings) for the 3D panel; ``paths`` of message
    paths for the Plot panel; and ``playbackConfig``, which the app reads.

    ``tracks`` (``(detector, method, tracker, horizons_s)`` of each track the log holds)
    adds a second plot: the deck's roll against time, true, per frame, filtered and
    predicted one horizon earlier.
    """
    markers = ["/annotations/truth", *(f"/annotations/{d}" for d in detectors)]
    paths = []
    for d, m in pairs:
        for q in ("roll_err_deg", "pitch_err_deg", "yaw_err_deg", "height_err_m"):
            paths.append({"value": plot_path(errors_topic(d, m), q), "enabled": True,
                          "timestampMethod": "receiveTime", "label": f"{d}+{m} {q}"})
    config: dict[str, Any] = {
        IMAGE_PANEL: {"cameraTopic": "/camera/image", "enabledMarkerTopics": markers,
                      "synchronize": False, "transformMarkers": False, "mode": "fit"},
        SCENE_PANEL: {"followTf": "world", "cameraState": dict(_CAMERA_STATE),
                      "topics": {"/scene": {"visible": True}},
                      "scene": {"transforms": {"showLabel": True, "axisScale": 3}}},
        PLOT_PANEL: {"paths": paths, "showLegend": True, "xAxisVal": "timestamp"},
    }
    right: Any = {"direction": "column", "first": SCENE_PANEL, "second": PLOT_PANEL, "splitPercentage": 50}
    if tracks:
        def line(topic: str, label: str) -> dict[str, Any]:
            return {"value": plot_path(topic, "roll_deg"), "enabled": True, "timestampMethod": "receiveTime",
                    "label": label}

        track_paths = [line(TRUTH_DECK_TOPIC, "true roll_deg")]
        for d, m, t, horizons in tracks:
            stem = track_stem(d, m, t)
            track_paths.append(line(estimates_topic(d, m), f"{d}+{m} per frame"))
            track_paths.append(line(track_topic(stem), f"{t} filtered"))
            track_paths.extend(line(prediction_topic(stem, h), f"{t} predicted {h:g} s ahead") for h in horizons)
        config[TRACK_PLOT_PANEL] = {"paths": track_paths, "showLegend": True, "xAxisVal": "timestamp"}
        right = {"direction": "column", "first": SCENE_PANEL,
                 "second": {"direction": "column", "first": PLOT_PANEL, "second": TRACK_PLOT_PANEL,
                            "splitPercentage": 50},
                 "splitPercentage": 40}
    return {
        "configById": config,
        "globalVariables": {},
        "userNodes": {},
        "playbackConfig": {"speed": 1.0},
        "layout": {"direction": "row", "first": IMAGE_PANEL, "second": right, "splitPercentage": 55},
    }
