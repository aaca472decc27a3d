"""The capture time base: rendered stamps on an epoch, replays end to end, the log's times equal to them."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from deckpose.render.config import config_from_dict
from deckpose.render.plan import plan_frames

from deckpose.capture_time import (
    DEFAULT_CAPTURE_EPOCH_NS,
    REPLAY_GAP_NS,
    epoch_ns,
    log_stamps,
    replay_starts_ns,
)
from deckpose.errors import ConfigError


def _doc(**extra):
    return {"cameras": [{"preset": "4mp-square", "size": [64, 48], "name": "a"},
                        {"preset": "4mp-square", "size": [96, 72], "name": "b"}],
            "heights_m": [20.0, 30.0], "lighting": ["night", "day"],
            "motion": {"source": "thesis", "max_samples": 4, "every": 7}, **extra}


def test_epoch_parsing_against_the_calendar():
    # 2024-01-01T00:00:00Z is 19723 days after 1970-01-01 (54 years, 13 leap days)
    assert epoch_ns("2024-01-01T00:00:00Z") == 19723 * 86_400 * 10**9 == DEFAULT_CAPTURE_EPOCH_NS
    assert epoch_ns("2024-01-01T02:00:00+02:00") == DEFAULT_CAPTURE_EPOCH_NS
    assert epoch_ns("2024-01-01T00:00:00.000001Z") == DEFAULT_CAPTURE_EPOCH_NS + 1000
    for bad, says in (("2024-01-01T00:00:00", "no time zone"), ("yesterday", "not an ISO 8601"),
                      ("1990-01-01T00:00:00Z", "before 2000")):
        with pytest.raises(ConfigError, match=says):
            epoch_ns(bad)


def test_replays_are_laid_end_to_end_one_gap_apart():
    first = np.array([0, 5, 0], np.int64)
    last = np.array([10, 7, 3], np.int64)
    got = replay_starts_ns(first, last, 100)
    assert got.tolist() == [100, 100 + 10 + REPLAY_GAP_NS, 100 + 10 + REPLAY_GAP_NS + 2 + REPLAY_GAP_NS]


def test_rendered_stamps_are_distinct_increasing_capture_times():
    cfg = config_from_dict(_doc(capture_epoch="2025-06-01T12:00:00Z"))
    plan = plan_frames(cfg)
    stamps = np.array([f.stamp_ns for f in plan])
    assert stamps[0] == epoch_ns("2025-06-01T12:00:00Z")
    assert np.all(np.diff(stamps) > 0)  # frame-id order is capture order: distinct, increasing
    # within a replay (camera x height x lighting) the spacing is the motion series' own
    t = np.array([f.t_s for f in plan]).reshape(-1, 4)
    np.testing.assert_array_equal(np.diff(stamps.reshape(-1, 4), axis=1), np.round(np.diff(t, axis=1) * 1e9))
    # and a replay starts one gap after the previous one's last frame
    s = stamps.reshape(-1, 4)
    assert np.all(s[1:, 0] - s[:-1, -1] == REPLAY_GAP_NS)


def test_the_default_epoch_and_a_bad_one_in_a_config():
    plan = plan_frames(config_from_dict(_doc()))
    assert plan[0].stamp_ns == DEFAULT_CAPTURE_EPOCH_NS
    with pytest.raises(ConfigError, match="capture_epoch"):
        config_from_dict(_doc(capture_epoch="2024-13-01T00:00:00Z"))


def test_the_log_times_are_the_rendered_stamps():
    plan = plan_frames(config_from_dict(_doc()))
    frames = pd.DataFrame({"frame_id": [f.frame_id for f in plan], "camera": [f.camera_name for f in plan],
                           "camera_height_m": [f.height_m for f in plan], "stamp_ns": [f.stamp_ns for f in plan]})
    assert log_stamps(frames).tolist() == frames["stamp_ns"].tolist()
    # a dataset whose stamps are motion time gets the same layout from the log (one rule)
    motion = frames.assign(stamp_ns=[round(f.t_s * 1e9) for f in plan])
    assert log_stamps(motion).tolist() == frames["stamp_ns"].tolist()
