"""The MCAP log (times, scene, metadata, attachments) and layout follow what the Foxglove app reads.

tools/foxglove_check checks the same with the app's readers; tests/evaluate/test_foxglove_viewer.py draws them.
"""

import json
import re
from datetime import datetime, timezone

import numpy as np
import pandas as pd
import pytest
from deckpose.evaluate.foxglove_layout import (
    IMAGE_PANEL,
    PLOT_PANEL,
    SCENE_PANEL,
    foxglove_layout,
    plot_path,
)
from deckpose.evaluate.mcap_log import annotations_msg, write_run_log
from deckpose.evaluate.mcap_scene import camera_entity
from foxglove_schemas_protobuf.SceneEntityDeletion_pb2 import SceneEntityDeletion
from mcap.reader import make_reader
from mcap_protobuf.decoder import DecoderFactory

from deckpose import run_folder as rl
from deckpose.camera import preset
from deckpose.capture_time import DEFAULT_CAPTURE_EPOCH_NS, capture_epoch, log_stamps
from deckpose.errors import InputDataError
from deckpose.layout import DeckLayout
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
    three_d = layout["configById"][SCENE_PANEL]
    # global frame-axis settings live in scene.transforms; `transforms` is keyed "frame:<id>"
    assert three_d["scene"]["transforms"] == {"showLabel": True, "axisScale": 3}
    assert all(k.startswith("frame:") for k in three_d.get("transforms", {}))
    # the 3D panel hides a SceneUpdate topic unless the layout makes it visible
    assert three_d["topics"] == {"/scene": {"visible": True}}
    # Studio 1.48's image panel and its keys (the newer app migrates them to imageMode)
    assert IMAGE_PANEL.startswith("ImageViewPanel!")
    image = layout["configById"][IMAGE_PANEL]
    assert image["cameraTopic"] == "/camera/image" and "imageMode" not in image
    assert image["enabledMarkerTopics"] == ["/annotations/truth", "/annotations/fake"]
    with open(evaluated_run / "log.mcap", "rb") as fh:
        topics = {c.topic for c in make_reader(fh).get_summary().channels.values()}
    plot_topics = {p["value"].rsplit(".", 1)[0] for p in layout["configById"][PLOT_PANEL]["paths"]}
    assert plot_topics == {"/errors/fake--thesis"} <= topics
    assert {image["cameraTopic"], *image["enabledMarkerTopics"], *three_d["topics"]} <= topics


def _decoded(run, topic):
    with open(run / "log.mcap", "rb") as fh:
        reader = make_reader(fh, decoder_factories=[DecoderFactory()])
        return [(m, d) for _, _, m, d in reader.iter_decoded_messages(topics=[topic])]


def test_log_times_are_on_a_capture_epoch_and_keep_stamp_ns(evaluated_run):
    # the fake run's stamps are motion time from 0, replayed per camera and height: the log
    # lays the replays end to end from the default capture epoch (2024-01-01T00:00:00Z)
    frames = pd.read_parquet(evaluated_run / "frames.parquet")
    assert frames["stamp_ns"].min() == 0
    expected = log_stamps(frames, DEFAULT_CAPTURE_EPOCH_NS)
    times = [m.log_time for m, _ in _decoded(evaluated_run, "/camera/image")]
    assert times == sorted(expected.tolist()) and times[0] == DEFAULT_CAPTURE_EPOCH_NS
    assert datetime.fromtimestamp(times[0] / 1e9, tz=timezone.utc) == datetime(2024, 1, 1, tzinfo=timezone.utc)
    with open(evaluated_run / "log.mcap", "rb") as fh:
        errs = [json.loads(m.data) for _, _, m in make_reader(fh).iter_messages(topics=["/errors/fake--thesis"])]
    by_frame = frames.set_index("frame_id")["stamp_ns"]
    assert all(e["stamp_ns"] == by_frame[e["frame_id"]] for e in errs)


def test_stamps_on_a_real_epoch_are_the_log_times():
    stamps = 1_750_000_000_000_000_000 + np.arange(4) * 50_000_000
    frames = pd.DataFrame({"frame_id": np.arange(4), "camera": ["a", "a", "b", "b"],
                           "camera_height_m": 30.0, "stamp_ns": stamps})
    assert log_stamps(frames).tolist() == stamps.tolist()


def test_capture_epoch_comes_from_the_manifest_when_it_has_one():
    assert capture_epoch({}) == (DEFAULT_CAPTURE_EPOCH_NS, "default")
    assert capture_epoch({"capture_epoch_ns": 1_750_000_000_000_000_000}) == (1_750_000_000_000_000_000, "manifest")
    with pytest.raises(InputDataError, match="capture_epoch_ns"):
        capture_epoch({"capture_epoch_ns": 12})


def test_scene_has_deck_beacons_camera_and_estimated_decks(evaluated_run):
    updates = _decoded(evaluated_run, "/scene")
    tfs = {m.log_time: {t.child_frame_id for t in d.transforms} for m, d in _decoded(evaluated_run, "/tf")}
    assert len(updates) == 12
    layout = DeckLayout()
    for message, update in updates:
        assert [x.type for x in update.deletions] == [SceneEntityDeletion.Type.ALL]
        entities = {e.id: e for e in update.entities}
        # every entity is drawn in a frame that /tf gives at the same instant
        assert {e.frame_id for e in update.entities} <= tfs[message.log_time]
        deck = entities["deck"]
        assert deck.frame_id == "deck" and len(deck.cubes) == 1 and len(deck.lines) == 1
        assert len(deck.spheres) == layout.n_beacons
        bow = deck.spheres[layout.bow_id].color
        assert (bow.r, bow.g, bow.b) == pytest.approx(layout.bow_rgb)
        assert deck.spheres[layout.bow_id].pose.position.x == pytest.approx(layout.radius_m)
        assert entities["camera"].frame_id == "camera" and len(entities["camera"].lines[0].points) == 16
        for e in update.entities:
            assert e.timestamp.seconds * 1_000_000_000 + e.timestamp.nanos == message.log_time
    solved = [u for _, u in updates if "deck_est/fake--thesis" in {e.id for e in u.entities}]
    assert solved, "no frame shows the thesis estimator's deck"
    disc = next(e for e in solved[0].entities if e.id == "deck_est/fake--thesis")
    assert disc.frame_id == "deck_est/fake--thesis" and 0 < disc.cylinders[0].color.a < 1


def test_camera_frustum_reaches_the_image_corners():
    cam = preset("4mp").with_size(400, 300)
    pts = camera_entity(cam, 10.0, 0).lines[0].points
    corners = np.array([[p.x, p.y, p.z] for p in pts[1::4]])
    assert (corners[:, 2] == 10.0).all()
    uv = corners[:, :2] / corners[:, 2:] @ cam.K[:2, :2].T + cam.K[:2, 2]
    assert uv == pytest.approx(np.array([[-0.5, -0.5], [399.5, -0.5], [399.5, 299.5], [-0.5, 299.5]]), abs=1e-9)


def test_log_has_metadata_and_attachments(evaluated_run):
    with open(evaluated_run / "log.mcap", "rb") as fh:
        reader = make_reader(fh)
        metadata = {m.name: m.metadata for m in reader.iter_metadata()}
        attachments = {a.name: a for a in reader.iter_attachments()}
    assert set(metadata) == {"deckpose.run", "deckpose.config", "deckpose.versions", "deckpose.time"}
    assert metadata["deckpose.run"]["seed"] == "0"
    assert json.loads(metadata["deckpose.run"]["command"]) == ["deckpose", "evaluate", str(evaluated_run),
                                                              "--preview-px", "256"]
    assert json.loads(metadata["deckpose.config"]["layout"])["n_ring"] == 12
    assert metadata["deckpose.versions"]["deckpose (log)"]
    assert metadata["deckpose.time"]["capture_epoch_ns"] == str(DEFAULT_CAPTURE_EPOCH_NS)
    assert metadata["deckpose.time"]["capture_epoch_source"] == "default"
    for name in ("4mp-small", "8mp-small"):
        a = attachments[f"cameras/{name}.yaml"]
        assert a.media_type == "application/yaml"
        assert a.data == (evaluated_run / "cameras" / f"{name}.yaml").read_bytes()
        assert a.log_time == DEFAULT_CAPTURE_EPOCH_NS
    assert json.loads(attachments["manifest.json"].data)["seed"] == 0
    assert "report/report.md" not in attachments  # the fixture evaluates before any report exists


def test_the_report_is_attached_when_it_exists(evaluated_run, tmp_path):
    run = rl.run_paths(evaluated_run)
    report = run.report_dir / "report.md"
    report.parent.mkdir(exist_ok=True)
    report.write_text("# a report\n")
    try:
        out = write_run_log(run, tmp_path / "log.mcap", preview_px=64)
    finally:
        report.unlink()
    with open(out, "rb") as fh:
        attachments = {a.name: a for a in make_reader(fh).iter_attachments()}
    assert attachments["report/report.md"].data == b"# a report\n"
    assert attachments["report/report.md"].media_type == "text/markdown"


def test_layout_leaves_match_panel_configs():
    layout = foxglove_layout(["cog"], [("cog", "pnp")])
    assert set(layout["configById"]) == {IMAGE_PANEL, SCENE_PANEL, PLOT_PANEL}

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


def test_the_log_uses_the_render_stages_previews_and_decodes_no_frame(tmp_path, monkeypatch):
    """With previews of the log's size stored at render time, no frame is decoded again and
    the log's images are those previews; at another size each is made from the frame."""
    import cv2
    import numpy as np
    from deckpose.evaluate import mcap_log, mcap_messages

    from deckpose.preview import make_preview
    from deckpose.run_folder import RunPaths
    from tests.evaluate.fake_run import make_fake_run

    root = make_fake_run(tmp_path / "run", heights=(20.0,), n_per_cell=1)
    run = RunPaths(root)
    frames = pd.read_parquet(root / "frames.parquet")
    run.previews_dir.mkdir()
    for row in frames.itertuples():
        full = cv2.imread(str(root / row.image), cv2.IMREAD_UNCHANGED)
        assert cv2.imwrite(str(run.preview(int(row.frame_id))), make_preview(full, 256))
    man = json.loads(run.manifest.read_text())
    run.manifest.write_text(json.dumps({**man, "preview_px": 256}))
    decoded = []
    real_decode = mcap_messages.decode_image
    monkeypatch.setattr(mcap_messages, "decode_image", lambda *a, **k: decoded.append(a[1]) or real_decode(*a, **k))
    mcap_log.write_run_log(run, preview_px=256)
    assert decoded == []
    stored = [msg.data for _, msg in _decoded(root, "/camera/image")]
    want = {run.preview(int(r.frame_id)).read_bytes() for r in frames.itertuples()}
    assert len(stored) == len(frames) and set(stored) == want
    mcap_log.write_run_log(run, preview_px=200)  # another size: made from the frames, by the same rule
    assert len(decoded) == len(frames)
    for _, msg in _decoded(root, "/camera/image"):
        got = cv2.imdecode(np.frombuffer(msg.data, np.uint8), cv2.IMREAD_UNCHANGED)
        assert max(got.shape[:2]) == 200


def test_a_fisheye_calibration_uses_foxgloves_model_name():
    import numpy as np
    from deckpose.evaluate.mcap_log import calibration_msg

    from deckpose.camera import CameraModel

    K = np.array([[300.0, 0, 160], [0, 300.0, 120], [0, 0, 1]])
    fish = CameraModel(320, 240, K, np.array([0.01, -0.002, 0.0, 0.0]), "fish", distortion_model="equidistant")
    msg = calibration_msg(fish, 0, 160, 120)
    assert msg.distortion_model == "kannala_brandt" and list(msg.D) == [0.01, -0.002, 0.0, 0.0]
    plain = CameraModel(320, 240, K, np.zeros(5), "plain")
    assert calibration_msg(plain, 0, 160, 120).distortion_model == "plumb_bob"
