"""The detector benchmark's counts on hand-made tables whose answers are known by construction.

One camera, one height, two frames; the detections are placed by hand: each beacon found
or not, a detection on a recorded ship light, one on nothing, an occluded beacon found.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from deckpose.detect.benchmark import (
    LIGHT_GATE_PX,
    false_detections,
    findable,
    match_run,
    summarise,
)


def _tables() -> tuple[pd.DataFrame, pd.DataFrame, pd.DataFrame, pd.DataFrame, pd.DataFrame]:
    beacons = pd.DataFrame({
        "frame_id": [0, 0, 0, 0, 1, 1, 1, 1],
        "beacon_id": [0, 1, 2, 3, 0, 1, 2, 3],
        "u_px": [100.0, 200.0, 300.0, 400.0, 100.0, 200.0, 300.0, 400.0],
        "v_px": [50.0] * 8,
        "visible": [True, True, True, False, True, True, True, True],
        "apparent_radius_px": [2.0] * 8,
        # frame 1: beacon 1 cut in part, beacon 3 wholly hidden
        "occluded_fraction": [0.0, 0.0, 0.0, 0.0, 0.0, 0.4, 0.0, 1.0],
    })
    frames = pd.DataFrame({"frame_id": [0, 1], "camera": ["c", "c"], "camera_height_m": [30.0, 30.0]})
    det = pd.DataFrame({
        "frame_id": [0, 0, 0, 0, 1, 1, 1],
        "beacon_id": [0, 1, -1, -1, 0, 1, -1],
        # frame 0: beacons 0 and 1 (0.3 px off in u), beacon 2 missed, one on a light, one on nothing
        "u_px": [100.3, 200.3, 612.0 + 0.5 * LIGHT_GATE_PX, 900.0, 100.0, 201.0, 300.1],
        "v_px": [50.0, 50.0, 80.0, 900.0, 50.0, 50.0, 50.0],
        "size_px": [1.0] * 7,
    })
    fout = pd.DataFrame({"frame_id": [0, 1], "ok": [True, True], "seconds": [0.01, 0.02],
                         "cpu_seconds": [0.01, 0.02]})
    lights = pd.DataFrame({"frame_id": [0, 0, 1], "light_id": [0, 1, 0], "kind": ["port", "glint", "port"],
                           "u_px": [612.0, 5000.0, 700.0], "v_px": [80.0, 80.0, 80.0],
                           "in_image": [True, False, True], "flux_e": [1e4, 0.0, 1e4]})
    return beacons, frames, det, fout, lights


def test_findable_drops_invisible_and_wholly_hidden() -> None:
    beacons = _tables()[0]
    assert findable(beacons).tolist() == [True, True, True, False, True, True, True, False]


def test_counts_false_detections_and_lights_hit() -> None:
    beacons, frames, det, fout, lights = _tables()
    m = match_run(det, fout, beacons, frames)
    false = false_detections(det, m, lights, [0, 1])
    assert false.to_dict("records") == [
        {"frame_id": 0, "n_false": 2, "n_lights": 1, "n_lights_found": 1},
        {"frame_id": 1, "n_false": 0, "n_lights": 1, "n_lights_found": 0},
    ]
    m["crb_var_px2"] = np.nan
    row = summarise("x", m, det, fout, frames, false).iloc[0]
    assert row["beacons"] == 6  # 3 visible in frame 0; 3 findable in frame 1
    assert row["recall"] == 5 / 6 and row["precision"] == 5 / 7
    assert row["recall_occluded"] == 1.0  # the cut beacon was found ...
    # ... but stays out of the centroid error: 0.3, 0.3 (frame 0), 0, 0.1 (frame 1) in u, 0 in v
    assert row["rms_px"] == pytest.approx(np.sqrt(np.mean(np.array([0.3, 0.3, 0.0, 0.1]) ** 2 / 2)), rel=1e-12)
    assert row["false_per_frame"] == 1.0 and row["lights_found"] == 0.5


def test_without_lights_or_occlusion_columns() -> None:
    """Datasets of earlier versions: no lights table, no occlusion column."""
    beacons, frames, det, fout, _ = _tables()
    beacons = beacons.drop(columns="occluded_fraction")
    m = match_run(det, fout, beacons, frames)
    assert not m["occluded"].any()
    false = false_detections(det, m, None, [0, 1])
    assert false["n_lights"].sum() == 0
    row = summarise("x", m.assign(crb_var_px2=np.nan), det, fout, frames, false).iloc[0]
    assert np.isnan(row["lights_found"]) and np.isnan(row["recall_occluded"])
    assert row["beacons"] == 7
