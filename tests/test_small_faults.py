"""The reliability issue's smaller findings, each from its own input."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest
from deckpose.detect import registry
from deckpose.detect.registry import DetectorOptions

from deckpose.camera import CameraModel
from deckpose.camera_info import write_camera_info
from deckpose.cli import main
from deckpose.records import Frame


def _camera(w: int, h: int) -> CameraModel:
    return CameraModel(w, h, np.array([[100.0, 0, w / 2], [0, 100.0, h / 2], [0, 0, 1]]))


def test_a_one_pixel_frame_says_it_is_too_small():
    # log gave "no blob above nan DN (noise nan DN)"
    for name in ("log", "cog", "gauss"):
        b = registry.get(name)(Frame(np.zeros((1, 1), np.uint8), _camera(1, 1)), DetectorOptions())
        assert len(b) == 0 and "1x1 px: too small" in b.reason and "nan" not in b.reason


def test_a_dark_frame_names_its_brightest_pixel_not_a_sample():
    img = np.zeros((64, 64), np.uint8)
    img[33, 35] = 3  # off the strided sample grid
    b = registry.get("cog")(Frame(img, _camera(64, 64)), DetectorOptions(spot_level=0,
                                                                         threshold_sigma=50))
    assert len(b) == 0 and "brightest pixel 3 DN" in b.reason, b.reason


@pytest.mark.parametrize("argv", [["detect"], ["estimate", "--run"], ["evaluate"], ["report"], ["track"]])
def test_a_stage_on_an_unfinished_dataset_says_so(tmp_path, capsys, argv):
    # estimate, evaluate and report had said "frames.parquet is missing; make it with: deckpose
    # render CONFIG.yaml RUN", which a render into the same folder refuses
    root = tmp_path / "ds"
    (root / ".parts").mkdir(parents=True)
    (root / ".parts" / "000000.json").write_text("{}")
    (root / "manifest.json").write_text(json.dumps(
        {"format": "deckpose-dataset/1", "complete": False, "n_frames": 12}))
    assert main([*argv, str(root), "--no-progress"] if argv[0] in ("detect", "estimate")
                else [*argv, str(root)]) == 2
    err = capsys.readouterr().err
    assert "unfinished dataset (1 of 12 frames rendered)" in err and "--resume" in err, err
    assert err.count("\n") == 1


@pytest.mark.parametrize("command", ["evaluate", "report", "track"])
def test_a_file_given_as_the_run_folder_is_called_a_file(tmp_path, capsys, command):
    log = tmp_path / "foreign.mcap"
    log.write_bytes(b"\x89MCAP0\r\n")
    assert main([command, str(log)]) == 2
    err = capsys.readouterr().err
    assert f"{log} is a file, not a run folder" in err and "does not exist" not in err, err


def test_a_huge_cell_gives_a_short_message(tmp_path, capsys):
    cam = tmp_path / "cam.yaml"
    write_camera_info(_camera(640, 480), cam)
    det = tmp_path / "d.csv"
    pd.DataFrame({"frame_id": [0, 0], "beacon_id": [0, 1], "u_px": [1.0, 2.0],
                  "v_px": ["x" * 5_000_000, "3"]}).to_csv(det, index=False)
    code = main(["estimate", str(det), "--camera", str(cam), "-o", str(tmp_path / "o.csv")])
    err = capsys.readouterr().err
    assert code == 2 and "v_px" in err and len(err) < 1200 and err.count("\n") == 1


def test_a_detect_output_folder_given_as_a_table_names_the_table_in_it(tmp_path):
    # `deckpose detect FOLDER -o x.parquet` makes a folder; reading it as a table says where the table is
    import pandas as pd
    import pytest

    from deckpose.errors import InputDataError
    from deckpose.tables import read_table

    out = tmp_path / "x.parquet"
    out.mkdir()
    pd.DataFrame({"a": [1]}).to_parquet(out / "detect_frames.parquet")
    pd.DataFrame({"a": [1]}).to_parquet(out / "detections.parquet")
    with pytest.raises(InputDataError, match=r"is a folder, not a detections file; read .*x\.parquet/detections\.parquet$"):
        read_table(out, "detections")


def test_a_numpy_value_in_a_message_reads_as_its_value():
    # "non-numeric v_px (np.float64(nan))" leaked numpy's repr into a user's message
    import numpy as np

    from deckpose.errors import short_repr

    assert short_repr(np.float64(np.nan)) == "nan" and short_repr(np.int64(7)) == "7"
    assert short_repr("x" * 100, limit=10) == "'xxxxxx..."


def test_a_run_that_keeps_no_frame_has_no_images_folder(tmp_path):
    from deckpose.render.config import DEFAULT_CONFIG, config_from_dict
    from deckpose.render.dataset import render_dataset
    from deckpose.render.render_detection import RenderDetection

    doc = {**DEFAULT_CONFIG, "cameras": [{"preset": "4mp-square", "size": [320, 240]}], "heights_m": [30.0],
           "lighting": ["night"], "motion": {"source": "fixed", "attitudes_deg": [[0, 0, 0]]}}
    out = tmp_path / "ds"
    render_dataset(config_from_dict(doc), out, workers=0, progress=False,
                   detection=RenderDetection(detectors=("cog",), keep_images=False))
    assert not (out / "images").exists() and (out / "detections" / "cog.parquet").exists()


@pytest.mark.parametrize("text", [
    "frame_id, beacon_id, u_px, v_px\n0, 0, 960.25, 190.5\n0, 1, 785.0, 237.75\n",  # spaces after commas
    "frame_id;beacon_id;u_px;v_px\n0;0;960,25;190,5\n0;1;785;237,75\n",  # a comma-decimal spreadsheet's (785: a whole number)
    "frame_id;beacon_id;u_px;v_px\n0;0;960.25;190.5\n0;1;785.0;237.75\n",  # ";" with decimal points
    "frame_id;beacon_id;u_px;v_px\n0;0;960,25;190,5\n0;1;785;237,75\n\n",  # a blank last line
    "frame_id; beacon_id; u_px; v_px\n0; 0; 960,25; 190,5\n0; 1; 785; 237,75\n",
])
def test_spreadsheet_csv_forms_read_as_the_plain_one(tmp_path, text):
    from deckpose.tables import read_table

    path = tmp_path / "d.csv"
    path.write_text(text)
    df = read_table(path, "detections")
    assert df.columns.tolist() == ["frame_id", "beacon_id", "u_px", "v_px"]
    assert df["frame_id"].tolist() == [0, 0] and df["beacon_id"].tolist() == [0, 1]
    assert df["u_px"].tolist() == [960.25, 785.0] and df["v_px"].tolist() == [190.5, 237.75]
