"""estimate --run -> evaluate -> MCAP -> report on a synthetic run with known answers."""

import json

import numpy as np
import pandas as pd
import pytest
from deckpose.evaluate.errors import frame_errors
from deckpose.evaluate.run import compute_errors
from mcap.decoder import DecoderFactory as McapDecoderFactory
from mcap.reader import make_reader
from mcap_protobuf.decoder import DecoderFactory

from deckpose.cli import main
from deckpose.errors import InputDataError
from deckpose.run_folder import run_paths
from tests.evaluate.fake_run import make_fake_run


class JsonDecoderFactory(McapDecoderFactory):
    def decoder_for(self, message_encoding, schema):
        return json.loads if message_encoding == "json" else None


@pytest.fixture
def run(tmp_path):
    root = make_fake_run(tmp_path / "run")
    assert main(["estimate", "--run", str(root), "--detector", "fake", "--method", "thesis"]) == 0
    return root


def test_errors_against_truth(run):
    errs = pd.read_parquet(run / "estimates" / "fake--thesis.parquet")
    assert errs.ok.all()
    e = compute_errors(run_paths(run))
    assert set(e.detector) == {"fake"} and set(e.method) == {"thesis"}
    # 0.3 px noise on beacons 80-200 px from the centre: well under a degree
    assert np.abs(e[["roll_err_deg", "pitch_err_deg"]]).max().max() < 1.0
    # centroid errors equal the injected noise: RMS of |N(0, 0.3 I)| is 0.3*sqrt(2)
    assert e.centroid_rms_px.mean() == pytest.approx(0.3 * np.sqrt(2), rel=0.2)
    assert (e.recall == 1.0).all()
    assert e.surge_err_m.isna().all()  # the thesis method gives no surge
    # the per-frame bound: finite, positive, and (for an efficient-ish estimator) of the
    # same order as the observed errors
    assert (e.crb_roll_deg > 0).all() and (e.crb_height_m > 0).all()
    ratio = np.sqrt(np.mean(e.roll_err_deg**2)) / np.sqrt(np.mean(e.crb_roll_deg**2))
    assert 0.2 < ratio < 5.0


def test_variants_of_a_method_are_kept_apart(run):
    """``thesis`` and ``thesis+mean`` in one run: two estimate files, two methods in the errors."""
    assert main(["estimate", "--run", str(run), "--detector", "fake", "--method", "thesis",
                 "--posterior-mean"]) == 0
    assert (run / "estimates" / "fake--thesis.parquet").exists()
    mean = pd.read_parquet(run / "estimates" / "fake--thesis+mean.parquet")
    assert mean.ok.all() and (mean.method == "thesis+mean").all() and (mean.posterior_mean == 1).all()
    e = compute_errors(run_paths(run))
    assert set(e.method) == {"thesis", "thesis+mean"} and len(e) == 2 * len(mean)
    assert e[e.method == "thesis+mean"].surge_err_m.notna().all()  # refined: 6 DoF


def test_frame_errors_wrap_yaw_and_use_true_height():
    frames = pd.DataFrame({"frame_id": [0], "camera": ["c"], "camera_height_m": [30.0], "roll_deg": [0.0], "pitch_deg": [0.0],
                               "yaw_deg": [179.0], "heave_m": [2.0], "surge_m": [1.0], "sway_m": [0.0],
                               "cam_x_m": [0.0], "cam_y_m": [0.0], "cam_z_m": [30.0]})
    est = pd.DataFrame({"frame_id": [0], "method": ["m"], "ok": [True], "reason": [""], "roll_deg": [0.1], "pitch_deg": [0.0],
                            "yaw_deg": [-179.0], "surge_m": [1.5], "sway_m": [0.0], "height_m": [28.5]})
    e = frame_errors(frames, est).iloc[0]
    assert e.yaw_err_deg == pytest.approx(2.0)
    assert e.height_err_m == pytest.approx(0.5)  # true height = 30 - 2
    assert e.surge_err_m == pytest.approx(0.5)


def test_evaluate_writes_tables_and_mcap_with_every_topic(run):
    assert main(["evaluate", str(run), "--preview-px", "256"]) == 0
    tables = pd.read_csv(run / "evaluation" / "resolution_tables.csv")
    assert set(tables.camera) == {"4mp-small", "8mp-small"} and set(tables.table_height_m) == {20, 40}
    assert (tables.n_frames == 3).all()
    topics, count = {}, 0
    with open(run / "log.mcap", "rb") as fh:
        reader = make_reader(fh, decoder_factories=[DecoderFactory(), JsonDecoderFactory()])
        summary = reader.get_summary()
        assert summary is not None
        for schema, channel, message, decoded in reader.iter_decoded_messages():
            topics.setdefault(channel.topic, []).append((schema.name, message, decoded))
            count += 1
    expected = {"/camera/image": "foxglove.CompressedImage", "/camera/calibration": "foxglove.CameraCalibration",
                "/annotations/truth": "foxglove.ImageAnnotations", "/annotations/fake": "foxglove.ImageAnnotations",
                "/tf": "foxglove.FrameTransforms", "/scene": "foxglove.SceneUpdate",
                "/errors/fake--thesis": "deckpose.FrameErrors", "/estimates/fake--thesis": "deckpose.FrameEstimate",
                "/truth/deck": "deckpose.DeckTruth"}
    assert set(topics) == set(expected)
    for t, name in expected.items():
        assert len(topics[t]) == 12 and all(s == name for s, _, _ in topics[t])
    # previews respect the size limit, and the calibration matches the preview
    cal = topics["/camera/calibration"][0][2]
    assert max(cal.width, cal.height) <= 256
    img = topics["/camera/image"][0][2]
    assert img.format == "png" and len(img.data) > 0
    # explicit, monotone log times; publish time equals log time
    times = [m.log_time for _, m, _ in topics["/tf"]]
    assert times == sorted(times) and len(set(times)) == len(times)
    assert all(m.publish_time == m.log_time for _, m, _ in topics["/tf"])
    frames = {tf.child_frame_id for _, _, d in topics["/tf"] for tf in d.transforms}
    assert frames == {"deck", "camera", "deck_est/fake--thesis"}
    err = topics["/errors/fake--thesis"][0][2]
    assert "roll_err_deg" in err and "t_s" in err
    layout = json.loads((run / "foxglove_layout.json").read_text())
    assert layout["configById"]["ImageViewPanel!deckpose"]["cameraTopic"] == "/camera/image"


def test_report(run):
    assert main(["evaluate", str(run), "--no-mcap"]) == 0
    assert main(["report", str(run)]) == 0
    md = (run / "report" / "report.md").read_text()
    # the first figure answers "which resolution?"
    assert md.index("error_vs_resolution.png") < md.index("error_vs_height.png")
    for fig in ("error_vs_resolution.png", "error_vs_height.png", "error_distributions.png",
                "centroid_vs_size.png", "example_4mp-small.png"):
        assert f"figures/{fig}" in md
        assert (run / "report" / "figures" / fig).stat().st_size > 1000
    # the fake run's cameras are 578x434 and 960x540: named 4mp/8mp, but not the thesis's
    # 4 MP and 8 MP cameras, so nothing is set beside the thesis's rows (it used to be)
    assert "## Beside the thesis" in md and "| fake+thesis | 4mp |" not in md
    assert "No cell of this run has a thesis resolution" in md and "4mp-small 578x434" in md


def test_thesis_comparison_needs_the_thesis_resolution():
    from deckpose.evaluate.report import thesis_comparison

    row = {"detector": "cog", "method": "pnp", "table_height_m": 20.0, "max_roll": 0.1, "max_pitch": 0.1,
               "max_yaw": 0.1, "max_height": 0.01, "centroid_rms_mean_px": 0.05}
    table = pd.DataFrame([dict(row, camera="4mp-thesis"), dict(row, camera="4mp-640x480")])
    lines = thesis_comparison(table, {"4mp-thesis": (2312, 1734), "4mp-640x480": (640, 480)})
    rows = [ln for ln in lines if ln.startswith("| cog+pnp")]
    assert len(rows) == 1 and rows[0].startswith("| cog+pnp | 4mp | 20 |")
    # no thesis cell: the run's cameras are listed once each (a camera named by its size, once)
    none = thesis_comparison(table.assign(camera=["640x480", "cam2"]), {"640x480": (640, 480), "cam2": (960, 540)})
    assert len(none) == 1 and "(this run's cameras: 640x480, cam2 960x540)" in none[0]


def test_missing_stage_names_the_command(tmp_path, capsys):
    root = make_fake_run(tmp_path / "r2")
    assert main(["evaluate", str(root)]) == 2
    assert "deckpose estimate --run" in capsys.readouterr().err
    assert main(["report", str(root)]) == 2
    assert f"deckpose evaluate {root}" in capsys.readouterr().err
    assert main(["evaluate", str(tmp_path / "nope")]) == 2
    err = capsys.readouterr().err
    # the hint is a command render accepts (CONFIG then the output folder; it has no -o)
    assert f"make it with: deckpose render CONFIG.yaml {tmp_path / 'nope'}" in err
    with pytest.raises(SystemExit):
        main(["render", "--help"])
    assert "-o DIR, --output DIR" in capsys.readouterr().out


def test_frames_that_do_not_match_are_rejected(run):
    d = pd.read_parquet(run / "detections" / "fake.parquet")
    d.loc[0, "frame_id"] = 999
    d.to_parquet(run / "detections" / "fake.parquet", index=False)
    with pytest.raises(InputDataError, match="frame ids the dataset does not have"):
        compute_errors(run_paths(run))


def test_distribution_plot_of_a_run_whose_every_estimate_failed(tmp_path):
    """Failed estimates carry NaN errors: the figure is still written (no legend of nothing,
    which matplotlib warns about and this suite turns into an error)."""
    import pandas as pd
    from deckpose.evaluate.report import plot_distributions

    nan = float("nan")
    errors = pd.DataFrame({"detector": ["cog"] * 3, "method": ["pnp"] * 3, "roll_err_deg": [nan] * 3,
                           "pitch_err_deg": [nan] * 3, "yaw_err_deg": [nan] * 3, "height_err_m": [nan] * 3})
    plot_distributions(errors, tmp_path / "d.png")
    assert (tmp_path / "d.png").stat().st_size > 1000


def test_example_frame_hands_matplotlib_at_most_max_px(run, tmp_path, monkeypatch):
    # `deckpose report` peaked at 4.6 GiB on 64 MP frames: example_frame handed the whole
    # image to matplotlib and ignored max_px. A 4000x3000 frame must reach imshow as at most
    # max_px on its long side, with the axes still in full-resolution pixels.
    import cv2
    import matplotlib.axes
    from deckpose.evaluate.report import example_frame

    from deckpose import run_folder as rl

    paths = rl.run_paths(run)
    frames = pd.read_parquet(paths.frames)
    beacons = pd.read_parquet(paths.beacons)
    row = frames.iloc[0].copy()
    big = np.zeros((3000, 4000, 3), np.uint16)
    big[1500, 2000] = 65535
    cv2.imwrite(str(tmp_path / "big.png"), big)
    row["image"] = str(tmp_path / "big.png")  # an absolute path joins to itself
    seen = []
    real = matplotlib.axes.Axes.imshow

    def spy(self, X, *a, **k):
        seen.append((np.shape(X), k.get("extent")))
        return real(self, X, *a, **k)

    monkeypatch.setattr(matplotlib.axes.Axes, "imshow", spy)
    example_frame(paths, row, beacons, {}, tmp_path / "ex.png", max_px=800)
    shape, extent = seen[0]  # the frame (then the zoomed inset, a few native pixels)
    assert max(shape[:2]) == 800 and all(max(s[:2]) <= 800 for s, _ in seen)
    assert extent == (-0.5, 3999.5, 2999.5, -0.5)
    assert (tmp_path / "ex.png").stat().st_size > 1000


def test_listings_ignore_a_killed_writers_temp_files(run):
    # a detect killed between its two writes left .cog.parquet.XXXX.tmp.parquet, which the
    # listing returned as a detector and evaluate then failed to read
    from deckpose import run_folder as rl

    paths = rl.run_paths(run)
    before_d, before_e = paths.detectors(), paths.estimate_pairs()
    (run / "detections" / ".fake.parquet.abc123.tmp.parquet").write_bytes(b"partial")
    (run / "estimates" / ".fake--thesis.parquet.x.tmp.parquet").write_bytes(b"partial")
    try:
        assert paths.detectors() == before_d and paths.estimate_pairs() == before_e
    finally:
        (run / "detections" / ".fake.parquet.abc123.tmp.parquet").unlink()
        (run / "estimates" / ".fake--thesis.parquet.x.tmp.parquet").unlink()


def test_report_warns_of_estimates_the_evaluation_has_not_seen(evaluated_run, tmp_path, capsys):
    """A new estimator's table added after 'evaluate': the report says it is left out, and how to fix it."""
    import shutil

    from deckpose import run_folder as rl
    from deckpose.cli import main

    root = tmp_path / "run"
    shutil.copytree(evaluated_run, root)
    run = rl.run_paths(root)
    assert main(["report", str(root)]) == 0
    assert "newer than the evaluation" not in capsys.readouterr().err
    assert main(["estimate", "--run", str(root), "--detector", "fake", "--method", "pnp"]) == 0
    capsys.readouterr()
    assert main(["report", str(root)]) == 0
    err = capsys.readouterr().err
    assert f"{run.estimates('fake', 'pnp')} is newer than the evaluation" in err
    assert "leaves it out" in err and f"deckpose evaluate {root}" in err
