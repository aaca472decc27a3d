"""``write_coco``: a run as COCO keypoints, read back with pycocotools."""

from __future__ import annotations

import contextlib
import io
import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from deckpose.evaluate.export_coco import coco_keypoints, keypoint_names, skeleton, write_coco

from deckpose.layout import DeckLayout, thesis_layout
from deckpose.run_folder import run_paths
from tests.evaluate.fake_run import make_fake_run
from tests.tolerances import ROUNDOFF

pytest.importorskip("pycocotools")
from pycocotools.coco import COCO
from pycocotools.cocoeval import COCOeval


@pytest.fixture(scope="module")
def run_with_hidden_beacons(tmp_path_factory) -> Path:
    """A fake run whose frame 1 has beacon 3 outside the image and beacon 5 seen from below,
    and whose frame 2 has no beacon in the image."""
    root = make_fake_run(tmp_path_factory.mktemp("coco") / "run", n_per_cell=2)
    b = pd.read_parquet(root / "beacons.parquet")
    out = (b.frame_id == 1) & (b.beacon_id == 3)
    below = (b.frame_id == 1) & (b.beacon_id == 5)
    b.loc[out, ["in_image", "visible"]] = False
    b.loc[below, ["facing", "visible"]] = False
    b.loc[b.frame_id == 2, ["in_image", "visible"]] = False
    b.to_parquet(root / "beacons.parquet", index=False)
    return root


def _load(path: Path) -> COCO:
    with contextlib.redirect_stdout(io.StringIO()):  # pycocotools prints its progress
        return COCO(str(path))


def test_pycocotools_reads_the_export(run_with_hidden_beacons: Path, tmp_path: Path) -> None:
    res = write_coco(run_paths(run_with_hidden_beacons), tmp_path / "coco")
    coco = _load(res.annotations)
    frames = pd.read_parquet(run_with_hidden_beacons / "frames.parquet")
    cat_ids = coco.getCatIds(catNms=["deck"])
    assert cat_ids == [1]
    (cat,) = coco.loadCats(cat_ids)
    assert cat["keypoints"] == ["bow", *(f"ring_{i}" for i in range(1, 12)), "centre"]
    assert len(cat["skeleton"]) == 24 and min(min(e) for e in cat["skeleton"]) == 1
    assert sorted(coco.getImgIds()) == sorted(frames.frame_id)
    for img in coco.loadImgs(coco.getImgIds()):
        path = tmp_path / "coco" / img["file_name"]
        assert path.is_file() and img["file_name"].startswith("images/")
    assert res.n_annotations == len(frames) - 1  # frame 2 has nothing labelled
    assert coco.getAnnIds(imgIds=[2]) == []


def test_keypoints_are_the_truth_shifted_half_a_pixel(run_with_hidden_beacons: Path,
                                                      tmp_path: Path) -> None:
    res = write_coco(run_paths(run_with_hidden_beacons), tmp_path / "coco")
    coco = _load(res.annotations)
    beacons = pd.read_parquet(run_with_hidden_beacons / "beacons.parquet")
    for ann in coco.loadAnns(coco.getAnnIds()):
        kp = np.array(ann["keypoints"], float).reshape(-1, 3)
        b = beacons[beacons.frame_id == ann["image_id"]].sort_values("beacon_id")
        v = np.where(b.in_image, np.where(b.facing, 2, 1), 0)
        np.testing.assert_array_equal(kp[:, 2], v)
        on = v > 0
        np.testing.assert_allclose(kp[on, :2], b[["u_px", "v_px"]].to_numpy()[on] + 0.5, atol=ROUNDOFF)
        assert np.all(kp[~on, :2] == 0)
        assert ann["num_keypoints"] == int(on.sum())
        x, y, w, h = ann["bbox"]
        xy = kp[on, :2]
        assert (x, y) == pytest.approx(tuple(xy.min(0))) and w == pytest.approx(np.ptp(xy[:, 0]))
        assert ann["area"] == pytest.approx(w * h) and ann["iscrowd"] == 0
        assert ann["id"] == ann["image_id"] + 1
    (a1,) = coco.loadAnns(coco.getAnnIds(imgIds=[1]))
    assert a1["keypoints"][3 * 3 + 2] == 0 and a1["keypoints"][5 * 3 + 2] == 1


def test_cocoeval_scores_the_truth_perfectly(run_with_hidden_beacons: Path, tmp_path: Path) -> None:
    res = write_coco(run_paths(run_with_hidden_beacons), tmp_path / "coco")
    gt = _load(res.annotations)
    dets = [{"image_id": a["image_id"], "category_id": 1, "keypoints": a["keypoints"], "score": 1.0}
            for a in gt.loadAnns(gt.getAnnIds())]
    with contextlib.redirect_stdout(io.StringIO()):
        dt = gt.loadRes(dets)
        ev = COCOeval(gt, dt, "keypoints")
        ev.params.kpt_oks_sigmas = np.full(13, 0.05)
        ev.evaluate()
        ev.accumulate()
        ev.summarize()
    assert ev.stats[0] == pytest.approx(1.0)  # AP at OKS .50:.95


def test_keypoint_names_and_skeleton_follow_the_layout() -> None:
    lay = thesis_layout()  # 12 ring beacons, no centre
    assert keypoint_names(lay)[:2] == ["bow", "ring_1"] and len(keypoint_names(lay)) == 12
    assert skeleton(lay) == [[i + 1, (i + 1) % 12 + 1] for i in range(12)]
    sk = skeleton(DeckLayout())
    assert [13, 1] in sk and [12, 1] in sk and max(max(e) for e in sk) == 13


def test_coco_keypoints_of_a_batch() -> None:
    pts = np.array([[[10.0, 20.0], [np.nan, np.nan], [3.0, 4.0], [-5.0, 1.0]]])
    kp = coco_keypoints(pts, np.array([[True, True, True, False]]), np.array([[True, True, False, True]]))
    np.testing.assert_array_equal(kp[0], [[10.5, 20.5, 2], [0, 0, 0], [3.5, 4.5, 1], [0, 0, 0]])


def test_a_run_with_missing_images_is_refused(run_with_hidden_beacons: Path, tmp_path: Path) -> None:
    from deckpose.errors import InputDataError

    run = tmp_path / "run"
    shutil.copytree(run_with_hidden_beacons, run)
    (run / "images" / "000000.png").unlink()
    with pytest.raises(InputDataError, match="images are missing"):
        write_coco(run_paths(run), tmp_path / "coco")
