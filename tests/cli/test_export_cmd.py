"""``deckpose export``: both formats from the command line, on a rendered run too, and its errors."""

from __future__ import annotations

import contextlib
import io
import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml

from deckpose.camera import CameraModel, preset
from deckpose.camera_info import write_camera_info
from deckpose.cli import main
from tests.evaluate.bop_format_check import project_bop, read_bop_dataset
from tests.evaluate.fake_run import make_fake_run
from tests.tolerances import PROJECTION_PX, ROUNDOFF


@pytest.fixture(scope="module")
def fake_run(tmp_path_factory) -> Path:
    return make_fake_run(tmp_path_factory.mktemp("export_cli") / "run", n_per_cell=1)


def _one_line_error(capsys: pytest.CaptureFixture[str], *words: str) -> str:
    err = capsys.readouterr().err
    assert "Traceback" not in err and err.count("\n") == 1, err
    assert err.startswith("deckpose export: error: ")
    for w in words:
        assert w in err, err
    return err


def test_help_explains_formats_and_conventions(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit):
        main(["export", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    for phrase in ("scene_gt.json", "cam_t_m2c in mm", "models_info.json", "deck_keypoints.json",
                   "x = u + 0.5", "distortion", "--copy-images", "skeleton"):
        assert phrase in text, phrase


def test_both_formats_from_the_command_line(fake_run: Path, tmp_path: Path,
                                            capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["export", str(fake_run), "--format", "bop", "-o", str(tmp_path / "bop"),
                 "--no-progress"]) == 0
    assert "BOP dataset of 4 images" in capsys.readouterr().out
    read_bop_dataset(tmp_path / "bop")
    assert main(["export", str(fake_run), "--format", "coco", "-o", str(tmp_path / "coco"),
                 "--copy-images", "--no-progress"]) == 0
    assert "COCO keypoints of 4 images (4 annotations)" in capsys.readouterr().out
    assert not any(p.is_symlink() for p in (tmp_path / "coco" / "images").iterdir())


def test_not_a_run_folder(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["export", str(tmp_path / "nosuch"), "--format", "bop", "-o", str(tmp_path / "o")]) == 2
    _one_line_error(capsys, "does not exist", "deckpose render")
    assert not (tmp_path / "o").exists()
    (tmp_path / "empty").mkdir()
    assert main(["export", str(tmp_path / "empty"), "--format", "coco", "-o", str(tmp_path / "o")]) == 2
    _one_line_error(capsys, "manifest.json is missing")


def test_unknown_format(fake_run: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exc:
        main(["export", str(fake_run), "--format", "yolo", "-o", str(tmp_path / "o")])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert "invalid choice: 'yolo'" in err and "Traceback" not in err


def test_missing_images(fake_run: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    run = tmp_path / "run"
    shutil.copytree(fake_run, run)
    shutil.rmtree(run / "images")
    assert main(["export", str(run), "--format", "coco", "-o", str(tmp_path / "o")]) == 2
    _one_line_error(capsys, "4 of 4 images are missing")


def test_bop_refuses_a_distorted_camera(fake_run: Path, tmp_path: Path,
                                        capsys: pytest.CaptureFixture[str]) -> None:
    run = tmp_path / "run"
    shutil.copytree(fake_run, run)
    cam = preset("8mp").with_size(960, 540)
    write_camera_info(CameraModel(cam.width_px, cam.height_px, cam.K, np.array([0.05, 0, 0, 0, 0]), cam.name),
                      run / "cameras" / "8mp-small.yaml")
    assert main(["export", str(run), "--format", "bop", "-o", str(tmp_path / "o")]) == 2
    _one_line_error(capsys, "8mp-small", "lens distortion", "--format coco")
    assert main(["export", str(run), "--format", "coco", "-o", str(tmp_path / "c"), "--no-progress"]) == 0


def test_output_inside_the_runs_images_is_refused(fake_run: Path, tmp_path: Path,
                                                  capsys: pytest.CaptureFixture[str]) -> None:
    run = tmp_path / "run"
    shutil.copytree(fake_run, run)
    before = (run / "images" / "000000.png").read_bytes()
    assert main(["export", str(run), "--format", "coco", "-o", str(run)]) == 2
    _one_line_error(capsys, "holds files no deckpose coco export wrote")
    for fmt in ("coco", "bop"):  # the run's own images, either way
        assert main(["export", str(run), "--format", fmt, "-o", str(run / "images")]) == 2
        _one_line_error(capsys, f"holds files no deckpose {fmt} export wrote")
    assert (run / "images" / "000000.png").read_bytes() == before


@pytest.mark.slow
def test_a_rendered_run_exports_exactly(tmp_path: Path) -> None:
    # 12 m above a radius-10 ring with a 75-degree lens: the ring's sides leave the image
    doc = {"name": "export", "cameras": [{"preset": "4mp", "size": [160, 120]}], "heights_m": [12, 30],
           "lighting": ["night"], "motion": {"source": "fixed", "attitudes_deg": [[3, -2, 20]]},
           "scene": {"texture_px": 128, "deck_half_size_m": 12.5}}
    cfg = tmp_path / "cfg.yaml"
    cfg.write_text(yaml.safe_dump(doc))
    run = tmp_path / "run"
    # --workers 1: rendering happens in a spawned worker, so this process needs no GL context
    assert main(["render", str(cfg), str(run), "--workers", "1", "--no-progress"]) == 0
    assert main(["export", str(run), "--format", "bop", "-o", str(tmp_path / "bop"), "--no-progress"]) == 0
    assert main(["export", str(run), "--format", "coco", "-o", str(tmp_path / "coco"), "--no-progress"]) == 0
    beacons = pd.read_parquet(run / "beacons.parquet").sort_values(["frame_id", "beacon_id"])
    assert not beacons.in_image.all()  # the test needs beacons outside the image
    ds = read_bop_dataset(tmp_path / "bop")
    assert ds.models_info[1]["size_x"] == pytest.approx(25_000.0)  # the config's plate, mm
    (scene,) = ds.scenes.values()
    pts = ds.models[1].pts_mm[:13]
    for im_id, (inst,) in scene.gt.items():
        uv = project_bop(pts, scene.camera[im_id]["cam_K"], inst["R"], inst["t_mm"])
        truth = beacons[beacons.frame_id == im_id][["u_px", "v_px"]].to_numpy()
        assert np.abs(uv - truth).max() < PROJECTION_PX
    pytest.importorskip("pycocotools")
    from pycocotools.coco import COCO

    with contextlib.redirect_stdout(io.StringIO()):
        coco = COCO(str(tmp_path / "coco" / "deck_keypoints.json"))
    for ann in coco.loadAnns(coco.getAnnIds()):
        kp = np.array(ann["keypoints"], float).reshape(-1, 3)
        b = beacons[beacons.frame_id == ann["image_id"]]
        np.testing.assert_array_equal(kp[:, 2] > 0, b.in_image.to_numpy())
        on = kp[:, 2] > 0
        np.testing.assert_allclose(kp[on, :2] - 0.5, b[["u_px", "v_px"]].to_numpy()[on], atol=ROUNDOFF * 1e3)


def test_a_folder_of_other_files_is_refused_and_an_earlier_export_replaced(
        fake_run: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # --copy-images wrote over a user's own images/000000.png in a folder no export had made
    out = tmp_path / "mine"
    (out / "images").mkdir(parents=True)
    (out / "images" / "000000.png").write_text("mine")
    assert main(["export", str(fake_run), "--format", "coco", "-o", str(out), "--copy-images",
                 "--no-progress"]) == 2
    _one_line_error(capsys, "holds files no deckpose coco export wrote", "new or empty folder")
    assert (out / "images" / "000000.png").read_text() == "mine"
    # an earlier export of the same format is replaced; one of the other format is not
    coco = tmp_path / "coco"
    for _ in range(2):
        assert main(["export", str(fake_run), "--format", "coco", "-o", str(coco), "--no-progress"]) == 0
    assert main(["export", str(fake_run), "--format", "bop", "-o", str(coco), "--no-progress"]) == 2
    _one_line_error(capsys, "holds files no deckpose bop export wrote")
    bop = tmp_path / "bop"
    for _ in range(2):
        assert main(["export", str(fake_run), "--format", "bop", "-o", str(bop), "--no-progress"]) == 0
    # a BOP dataset of others (its standard files, none of our notes) is not ours to write over
    other = tmp_path / "their_bop"
    (other / "test").mkdir(parents=True)
    (other / "test_targets_bop19.json").write_text("[]")
    assert main(["export", str(fake_run), "--format", "bop", "-o", str(other), "--no-progress"]) == 2
    _one_line_error(capsys, "holds files no deckpose bop export wrote")
