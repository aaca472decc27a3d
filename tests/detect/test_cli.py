"""``deckpose detect`` and ``deckpose bench-detectors`` end to end on a tiny synthetic dataset."""

import json
import shutil

import numpy as np
import pandas as pd
import pytest
from deckpose.detect.tables import DETECTION_COLUMNS, FRAME_COLUMNS, read_detections

from deckpose.cli import main


@pytest.mark.parametrize("detector", ["binary", "cog", "gauss", "log", "opencv-blob"])
def test_detect_dataset_writes_tables_with_ids(tiny_dataset, tmp_path, detector):
    out = tmp_path / detector
    assert (
        main(
            [
                "detect",
                str(tiny_dataset),
                "--detector",
                detector,
                "--out",
                str(out),
                "--no-progress",
            ]
        )
        == 0
    )
    dets = pd.read_parquet(out / "detections.parquet")
    frames = pd.read_parquet(out / "detect_frames.parquet")
    assert list(dets.columns) == list(DETECTION_COLUMNS)
    assert set(FRAME_COLUMNS) <= set(frames.columns)
    assert frames.ok.all(), list(frames.reason)
    truth = pd.read_parquet(tiny_dataset / "beacons.parquet")
    for fid, g in dets.groupby("frame_id"):
        t = truth[(truth.frame_id == fid) & truth.visible].set_index("beacon_id")
        ided = g[g.beacon_id >= 0].set_index("beacon_id")
        assert set(ided.index) == set(
            t.index
        )  # every visible beacon found and named; glint left -1
        err = np.hypot(ided.u_px - t.u_px.loc[ided.index], ided.v_px - t.v_px.loc[ided.index])
        assert err.max() < 0.5
        assert (g.beacon_id == -1).sum() == 1  # the glint
    run = json.loads((out / "detect_run.json").read_text())
    assert run["detector"] == detector and (out / "cameras").is_dir()
    per_frame = read_detections(out / "detections.parquet")
    assert sorted(per_frame) == sorted(frames.frame_id)


def test_detect_folder_of_images_with_camera_info(tiny_dataset, tmp_path, capsys):
    folder = tmp_path / "mine"
    shutil.copytree(tiny_dataset / "images", folder)
    (folder / "notes.txt").write_text("ignored")
    cam = next((tiny_dataset / "cameras").iterdir())
    out = tmp_path / "out"
    assert (
        main(["detect", str(folder), "--camera-info", str(cam), "--out", str(out), "--no-progress"])
        == 0
    )
    frames = pd.read_parquet(out / "detect_frames.parquet")
    assert len(frames) == 4 and frames.ok.all()
    # the spelling every other command uses: --camera and -o
    out2 = tmp_path / "out2"
    assert main(["detect", str(folder), "--camera", str(cam), "-o", str(out2), "--no-progress"]) == 0
    pd.testing.assert_frame_equal(pd.read_parquet(out2 / "detections.parquet"),
                                  pd.read_parquet(out / "detections.parquet"))


def test_detect_folder_without_camera_info_is_a_clear_error(tmp_path, capsys):
    assert main(["detect", str(tmp_path), "--no-progress"]) == 2
    assert "--camera CAMERA.yaml" in capsys.readouterr().err


def test_unknown_detector_lists_the_known_ones(tiny_dataset, capsys):
    assert main(["detect", str(tiny_dataset), "--detector", "nope"]) == 2
    assert "cog" in capsys.readouterr().err


def test_a_list_of_detectors_is_told_one_per_call(tiny_dataset, capsys):
    assert main(["detect", str(tiny_dataset), "--detector", "cog,gauss"]) == 2
    err = capsys.readouterr().err
    assert "one detector per call" in err and "bench-detectors" in err and "Traceback" not in err
    assert len(err.strip().splitlines()) == 1


def test_plugin_detector_appears_in_the_cli(tmp_path, monkeypatch, capsys):
    (tmp_path / "my_detector_plugin.py").write_text(
        "from deckpose.detect import registry\n"
        "from deckpose.detect.cog import detect_cog\n"
        "registry.register('my-cog')(detect_cog)\n"
    )
    monkeypatch.syspath_prepend(str(tmp_path))
    try:
        assert main(["detect", ".", "--plugin", "my_detector_plugin", "--list"]) == 0
        assert "my-cog" in capsys.readouterr().out.split()
    finally:
        from deckpose.detect import registry

        registry.unregister("my-cog")


def test_detect_list_needs_no_dataset(capsys):
    # the README's command: `deckpose detect --list`
    assert main(["detect", "--list"]) == 0
    assert {"binary", "cog", "gauss"} <= set(capsys.readouterr().out.split())
    assert main(["detect"]) == 2
    assert "no DATASET" in capsys.readouterr().err


@pytest.mark.parametrize("how", ["module in the current folder", "file path"])
def test_plugin_from_the_current_folder_or_a_file(tmp_path, monkeypatch, capsys, how):
    (tmp_path / "mypeak_plugin.py").write_text(
        "from deckpose.detect import registry\n"
        "from deckpose.detect.cog import detect_cog\n"
        "registry.register('my-peak')(detect_cog)\n"
    )
    monkeypatch.chdir(tmp_path)  # no PYTHONPATH, as a user types it
    arg = "mypeak_plugin" if how.startswith("module") else "./mypeak_plugin.py"
    try:
        assert main(["detect", "--plugin", arg, "--list"]) == 0
        assert "my-peak" in capsys.readouterr().out.split()
    finally:
        from deckpose.detect import registry

        registry.unregister("my-peak")
        import sys

        sys.modules.pop("mypeak_plugin", None)


def test_a_broken_plugin_is_one_line_not_a_traceback(tmp_path, monkeypatch, capsys):
    (tmp_path / "broken.py").write_text("raise RuntimeError('boom')\n")
    monkeypatch.chdir(tmp_path)
    for arg in ("./broken.py", "broken", "./missing.py"):
        assert main(["detect", "--plugin", arg, "--list"]) == 2
        err = capsys.readouterr().err
        assert "cannot import detector plugin" in err and "Traceback" not in err


def test_bench_detectors_report(tiny_dataset, tmp_path, capsys):
    out = tmp_path / "bench"
    assert (
        main(
            [
                "bench-detectors",
                str(tiny_dataset),
                "--detectors",
                "binary,cog,gauss",
                "--out",
                str(out),
                "--no-progress",
            ]
        )
        == 0
    )
    table = pd.read_csv(out / "bench_detectors.csv")
    assert set(table.detector) == {"binary", "cog", "gauss"}
    assert len(table) == 3 * 2  # detectors x heights (one camera)
    assert (table.recall == 1.0).all() and (table.id_accuracy == 1.0).all()
    assert np.allclose(table.precision, 12 / 13)  # one glint per frame among 12 visible beacons
    assert table.crb_px.notna().all()
    cog = table[table.detector == "cog"]
    binary = table[table.detector == "binary"]
    assert (cog.rms_over_crb < 1.6).all()  # ~50 spots per row: loose statistical margin
    assert (binary.rms_px.to_numpy() > 2 * cog.rms_px.to_numpy()).all()
    for f in ("bench_detectors.md", "error_vs_height.png", "error_vs_size.png"):
        assert (out / f).stat().st_size > 0


def test_detect_dataset_default_output_is_the_run_layout(tiny_dataset, tmp_path):
    ds = tmp_path / "run"
    shutil.copytree(tiny_dataset, ds)
    assert main(["detect", str(ds), "--detector", "cog", "--no-progress"]) == 0
    dets = pd.read_parquet(ds / "detections" / "cog.parquet")
    frames = pd.read_parquet(ds / "detections" / "cog.frames.parquet")
    assert len(frames) == 4 and frames.ok.all()
    assert {"frame_id", "beacon_id", "u_px", "v_px", "cov_uu", "cov_uv", "cov_vv"} <= set(
        dets.columns
    )
    # ids are unique per frame (estimators reject duplicates), -1 apart
    ided = dets[dets.beacon_id >= 0]
    assert not ided.duplicated(["frame_id", "beacon_id"]).any()
    meta = json.loads((ds / "detections" / "cog.run.json").read_text())
    assert meta["detections"] == "cog.parquet"
    assert (ds / "detections" / meta["cameras"]["640x360"]).resolve().is_file()


def test_bench_detectors_on_a_dataset_without_spot_model(tiny_dataset, tmp_path, capsys):
    """A dataset rendered before the spot model was recorded: the CRB stays empty, with a note."""
    ds = tmp_path / "old"
    shutil.copytree(tiny_dataset, ds)
    beacons = pd.read_parquet(ds / "beacons.parquet")
    beacons.drop(columns=["spot_sigma_px", "spot_flux_e"]).to_parquet(ds / "beacons.parquet")
    out = tmp_path / "bench"
    argv = ["bench-detectors", str(ds), "--detectors", "cog", "--out", str(out), "--no-progress"]
    assert main(argv) == 0
    table = pd.read_csv(out / "bench_detectors.csv")
    assert table.crb_px.isna().all() and (table.recall == 1.0).all()
    md = (out / "bench_detectors.md").read_text()
    assert "CRB left empty: beacons.parquet lacks spot_sigma_px, spot_flux_e" in md
    assert "cpu_ms_per_frame" in table.columns and (table.cpu_ms_per_frame > 0).all()


def test_declared_gain_comes_from_the_manifest_sensor_block():
    from deckpose.detect.sources import declared_gain

    assert declared_gain({"sensor": {"gain_dn_per_e": 0.273, "read_noise_e": 4}}) == 0.273
    assert declared_gain({"sensor": {"gain_dn_per_e": 0.273, "noise": False}}) is None
    assert declared_gain({"sensor": {"read_noise_e": 4}}) is None
    assert declared_gain({}) is None  # an image folder or an old dataset: estimated per frame


def test_bench_detectors_splits_centroid_error_by_lighting(two_lighting_dataset, tmp_path):
    """With night and dusk frames the report adds a per-lighting table whose rows add up to
    the pooled summary: beacon counts sum, and the pooled RMS^2 is their count-weighted mean."""
    ds = two_lighting_dataset
    out = tmp_path / "bench"
    argv = ["bench-detectors", str(ds), "--detectors", "cog", "--out", str(out), "--no-progress"]
    assert main(argv) == 0
    md = (out / "bench_detectors.md").read_text()
    assert "## Centroid error by lighting" in md
    pooled = pd.read_csv(out / "bench_detectors.csv")
    by = pd.read_csv(out / "bench_detectors_by_lighting.csv")
    assert set(by.lighting) == {"night", "dusk"}
    for h, g in by.groupby("height_m"):
        p = pooled[pooled.height_m == h].iloc[0]
        assert g.beacons.sum() == p.beacons * p.recall
        pooled_rms = np.sqrt((g.beacons * g.rms_px**2).sum() / g.beacons.sum())
        assert pooled_rms == pytest.approx(p.rms_px, rel=1e-5)  # CSVs keep 6 digits


def test_detect_exit_status_when_no_frame_succeeds(tmp_path, tiny_dataset, capsys):
    # detect used to exit 0 with 0 of 12 frames ok; now 3 (none ok), and --strict gives 4
    # when some failed
    import cv2

    from deckpose.camera import preset
    from deckpose.camera_info import write_camera_info

    imgs = tmp_path / "imgs"
    imgs.mkdir()
    for k in range(3):
        cv2.imwrite(str(imgs / f"{k:03d}.png"), np.zeros((36, 64), np.uint8))
    write_camera_info(preset("8mp").with_size(64, 36), tmp_path / "cam.yaml")
    argv = ["detect", str(imgs), "--camera-info", str(tmp_path / "cam.yaml"), "--out",
            str(tmp_path / "out"), "--no-progress"]
    assert main(argv) == 3
    assert "0 ok" in capsys.readouterr().out
    ok = ["detect", str(tiny_dataset), "--out", str(tmp_path / "ok"), "--no-progress"]
    assert main(ok) == 0
    assert main([*ok, "--strict"]) == 0  # every tiny frame identifies


def _damaged_copy(tiny_dataset, tmp_path, name):
    run = tmp_path / name
    shutil.copytree(tiny_dataset, run)
    return run


def test_bench_detectors_leaves_out_an_unreadable_frame_with_a_warning(tiny_dataset, tmp_path, capsys):
    """A damaged image is no detector's miss: the frame is named on stderr and left out of every table."""
    run = _damaged_copy(tiny_dataset, tmp_path, "damaged")
    first = min((run / "images").iterdir())
    first.write_bytes(b"not an image")
    assert main(["bench-detectors", str(run), "--detectors", "cog", "-o", str(tmp_path / "b"), "--no-progress"]) == 0
    out = capsys.readouterr()
    assert "frame 0 left out of the benchmark: cannot decode image" in out.err
    assert f"report -> {tmp_path / 'b' / 'bench_detectors.md'}" in out.out
    table = pd.read_csv(tmp_path / "b" / "bench_detectors.csv")
    assert (table.recall == 1.0).all()  # the other frames' beacons are all found


@pytest.mark.parametrize("damage", ["no_beacons", "all_unreadable", "no_images"])
def test_bench_detectors_refuses_a_dataset_it_cannot_score_in_one_line(tiny_dataset, tmp_path, capsys, damage):
    run = _damaged_copy(tiny_dataset, tmp_path, damage)
    if damage == "no_beacons":
        (run / "beacons.parquet").unlink()
        want = "beacons.parquet is missing; make it with: deckpose render"
    elif damage == "all_unreadable":
        for p in (run / "images").iterdir():
            p.write_bytes(b"")
        want = "none of its"
    else:  # as a --no-images render records it
        manifest = json.loads((run / "manifest.json").read_text())
        (run / "manifest.json").write_text(json.dumps({**manifest, "images_kept": False}))
        want = "keeps no frames (rendered with --no-images)"
    assert main(["bench-detectors", str(run), "--detectors", "cog", "-o", str(tmp_path / "b"), "--no-progress"]) == 2
    err = capsys.readouterr().err.strip()
    assert want in err and "\n" not in err and "Traceback" not in err


def test_detect_names_a_missing_frames_table_and_how_to_remake_it(tiny_dataset, tmp_path, capsys):
    run = _damaged_copy(tiny_dataset, tmp_path, "noframes")
    (run / "frames.parquet").unlink()
    assert main(["detect", str(run), "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert "frames.parquet is missing; make it again with: deckpose render CONFIG.yaml" in err and "--resume" in err
