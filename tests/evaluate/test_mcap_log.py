"""The MCAP log and layout follow what the Foxglove app reads (tools/foxglove_check checks the same)."""

import json
import re

import numpy as np
import pandas as pd
import pytest
from deckpose.evaluate.mcap_log import annotations_msg, foxglove_layout, log_stamps, plot_path
from mcap.reader import make_reader

from tests.tolerances import ROUNDOFF


def test_log_stamps_are_distinct_when_lighting_replays_the_series():
    # The render plan nests cameras x heights x lighting x motion samples: the night and day
    # replays of one camera and height repeat the same motion stamps.
    rows = []
    for cam in ("a", "b"):
        for light in ("night", "day"):
            for k in range(3):
                rows.append({"camera": cam, "camera_height_m": 30.0, "lighting": light,
                             "stamp_ns": k * 100_000_000})
    frames = pd.DataFrame(rows)
    frames.insert(0, "frame_id", np.arange(len(frames)))
    t = log_stamps(frames)
    assert t.is_unique
    # four replays of three frames each, in frame-id order, each keeping its 0.1 s spacing
    per_replay = t.to_numpy().reshape(4, 3)
    assert (np.diff(per_replay, axis=1) == 100_000_000).all()
    assert (per_replay[1:, 0] > per_replay[:-1, -1]).all()


def test_annotation_points_use_foxglove_corner_origin():
    # Foxglove: origin at the top-left corner of the top-left pixel. The centre of
    # full-resolution pixel (10, 20) (OpenCV: pixel centres at integers) is at (10.5, 20.5).
    ann = annotations_msg(np.array([[10.0, 20.0]]), np.array([3]), 1.0, 1.0, 0, (1, 0, 0, 1), "")
    p = ann.points[0].points[0]
    assert (p.x, p.y) == pytest.approx((10.5, 20.5), abs=ROUNDOFF)
    # At a quarter scale, the 4x4 block of full-resolution pixels 0..3 makes preview pixel 0;
    # the block's centre (full-res u = v = 1.5) is the centre of preview pixel 0: (0.5, 0.5).
    ann = annotations_msg(np.array([[1.5, 1.5]]), np.array([-1]), 0.25, 0.25, 0, (1, 0, 0, 1), "")
    p = ann.points[0].points[0]
    assert (p.x, p.y) == pytest.approx((0.5, 0.5), abs=ROUNDOFF)
    assert ann.texts[0].text == "?"


def test_error_channels_carry_a_typed_json_schema(evaluated_run):
    # The app's JSON Schema parser iterates `properties` and accepts only these types.
    accepted = {"number", "integer", "boolean", "string"}
    with open(evaluated_run / "log.mcap", "rb") as fh:
        reader = make_reader(fh)
        seen = 0
        for schema, channel, message in reader.iter_messages(topics=["/errors/fake--thesis"]):
            assert schema.encoding == "jsonschema" and channel.message_encoding == "json"
            js = json.loads(schema.data)
            assert js["type"] == "object"
            props = js["properties"]
            assert {p["type"] for p in props.values()} <= accepted
            obj = json.loads(message.data)
            assert set(obj) <= set(props)
            for key, value in obj.items():
                kind = props[key]["type"]
                if value is None:
                    assert kind == "number"  # NaN is written as null
                elif isinstance(value, bool):
                    assert kind == "boolean"
                elif isinstance(value, int):
                    assert kind in ("integer", "number")
                elif isinstance(value, float):
                    assert kind == "number"
                else:
                    assert kind == "string"
            seen += 1
    assert seen == 12
    for q in ("roll_err_deg", "pitch_err_deg", "yaw_err_deg", "height_err_m"):
        assert props[q]["type"] == "number"


def test_layout_uses_the_app_config_keys(evaluated_run):
    layout = json.loads((evaluated_run / "foxglove_layout.json").read_text())
    assert layout["playbackConfig"] == {"speed": 1.0}
    three_d = layout["configById"]["3D!deckpose"]
    # global frame-axis settings live in scene.transforms; `transforms` is keyed "frame:<id>"
    assert three_d["scene"]["transforms"] == {"showLabel": True, "axisScale": 3}
    assert all(k.startswith("frame:") for k in three_d.get("transforms", {}))
    image = layout["configById"]["Image!deckpose"]["imageMode"]
    assert image["annotations"] == {"/annotations/truth": {"visible": True}, "/annotations/fake": {"visible": True}}
    with open(evaluated_run / "log.mcap", "rb") as fh:
        topics = {c.topic for c in make_reader(fh).get_summary().channels.values()}
    plot_topics = {p["value"].rsplit(".", 1)[0] for p in layout["configById"]["Plot!errors"]["paths"]}
    assert plot_topics == {"/errors/fake--thesis"} <= topics
    assert {image["imageTopic"], image["calibrationTopic"], *image["annotations"]} <= topics


def test_layout_leaves_match_panel_configs():
    layout = foxglove_layout(["cog"], [("cog", "pnp")])

    def leaves(node):
        return [node] if isinstance(node, str) else leaves(node["first"]) + leaves(node["second"])

    assert sorted(leaves(layout["layout"])) == sorted(layout["configById"])


def _topic_of(path: str) -> str:
    # The app's message-path grammar: an unquoted topic is (/[A-Za-z0-9_-]*)+, or a quoted string.
    m = re.match(r'^"((?:[^"\\]|\\\\|\\")*)"\.', path)
    if m:
        return re.sub(r'\\(["\\])', r"\1", m.group(1))
    m = re.match(r"^(?:/[A-Za-z0-9_-]*)+", path)
    assert m is not None
    return m.group(0)


@pytest.mark.parametrize("topic",
                         ["/errors/cog--pnp", "/errors/my.det--pnp", '/errors/we"ird\\name--pnp'])
def test_plot_path_reads_back_as_its_topic(topic):
    path = plot_path(topic, "roll_err_deg")
    assert path.endswith(".roll_err_deg")
    assert _topic_of(path) == topic
    plain = not any(c in topic for c in '."\\')
    assert (path == f"{topic}.roll_err_deg") == plain
