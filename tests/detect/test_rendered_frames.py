"""Detection on rendered frames (configs/smoke.yaml): night and day, both cameras.

Unlike the analytic spots of the other tests, rendered beacons have saturated
cores, a glow, a dark housing, and sit on a lit, textured deck with white and
yellow markings (day) or faint markings and edges (night). Every frame must be
fully identified and the centres must match the renderer's projected beacon
centres (beacons.parquet) to well under half a pixel.
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pandas as pd
import pytest
from deckpose.detect.frame_detection import detect_frame
from deckpose.detect.registry import DetectorOptions
from deckpose.detect.sources import load_frame, open_dataset

REPO = Path(__file__).resolve().parents[2]

#: Centroid RMS bound, pixels. Measured on this set: cog ~0.02 (night) / ~0.06 (day),
#: binary and opencv-blob ~0.08-0.14; 0.5 px is the identification-grade bound of the issue.
MAX_RMS_PX = 0.5
#: Largest single centroid error, pixels.
MAX_ERR_PX = 1.0


@pytest.fixture(scope="module")
def smoke_dataset(tmp_path_factory: pytest.TempPathFactory) -> Path:
    from deckpose.render.config import load_config
    from deckpose.render.dataset import render_dataset

    # One fresh worker process: this process may already hold another GL backend.
    return render_dataset(
        load_config(REPO / "configs" / "smoke.yaml"),
        tmp_path_factory.mktemp("smoke") / "ds",
        workers=1,
        progress=False,
    )


def _score(
    root: Path, detector: str, every: int = 1, options: DetectorOptions = DetectorOptions()
) -> tuple[list[str], np.ndarray, set[str]]:
    fs = open_dataset(root)
    frames = pd.read_parquet(root / "frames.parquet").set_index("frame_id")
    gt = pd.read_parquet(root / "beacons.parquet")
    fails, errs, lights = [], [], set()
    for src in fs.sources[::every]:
        frame = load_frame(src, fs.cameras[src.camera_name])
        assert not isinstance(frame, str), frame
        lights.add(str(frames.loc[src.frame_id, "lighting"]))
        fd = detect_frame(frame, detector, fs.layout, options=options)
        if not fd.ok:
            fails.append(f"frame {src.frame_id}: {fd.reason}")
            continue
        t = gt[(gt.frame_id == src.frame_id) & gt.visible].set_index("beacon_id")
        d = fd.detections
        ided = d.beacon_ids >= 0
        found = {int(i) for i in d.beacon_ids[ided]}
        if found != set(t.index):
            fails.append(f"frame {src.frame_id}: ids {sorted(found)} != {sorted(t.index)}")
        for (u, v), i in zip(d.points_px[ided], d.beacon_ids[ided]):
            if int(i) in t.index:
                errs.append(np.hypot(u - t.u_px[int(i)], v - t.v_px[int(i)]))
    return fails, np.asarray(errs), lights


def test_cog_identifies_every_smoke_frame(smoke_dataset: Path) -> None:
    fails, err, lights = _score(smoke_dataset, "cog")
    assert not fails, fails
    assert lights == {"night", "day"}
    assert err.size == 24 * 13
    assert np.sqrt(np.mean(err**2)) < MAX_RMS_PX and err.max() < MAX_ERR_PX


@pytest.mark.parametrize("detector", ["binary", "gauss", "log", "opencv-blob"])
def test_other_detectors_on_rendered_frames(smoke_dataset: Path, detector: str) -> None:
    fails, err, lights = _score(smoke_dataset, detector, every=5)
    assert not fails, fails
    assert lights == {"night", "day"}
    assert np.sqrt(np.mean(err**2)) < MAX_RMS_PX and err.max() < MAX_ERR_PX


def test_spot_search_can_be_switched_off(smoke_dataset: Path) -> None:
    # The old threshold (background + k sigma) finds the deck markings of a day frame:
    # the bright-spot search is what makes rendered day frames work.
    fs = open_dataset(smoke_dataset)
    frames = pd.read_parquet(smoke_dataset / "frames.parquet")
    fid = int(frames[frames.lighting == "day"].frame_id.iloc[0])
    src = next(s for s in fs.sources if s.frame_id == fid)
    frame = load_frame(src, fs.cameras[src.camera_name])
    assert not isinstance(frame, str)
    old = detect_frame(frame, "cog", fs.layout, options=DetectorOptions(spot_level=0.0))
    new = detect_frame(frame, "cog", fs.layout)
    assert new.ok and not old.ok


def test_opening_background_never_raises(smoke_dataset: Path) -> None:
    # --background-kernel-px 15 used to raise a broadcasting ValueError in cog (frame 2):
    # the detector itself, not only the pipeline's guard, must return a value.
    from deckpose.detect import registry

    fs = open_dataset(smoke_dataset)
    opts = DetectorOptions(background_kernel_px=15)
    for src in fs.sources:
        frame = load_frame(src, fs.cameras[src.camera_name])
        assert not isinstance(frame, str)
        blobs = registry.get("cog")(frame, opts)
        assert blobs.ok or blobs.reason


@pytest.mark.parametrize("kernel_px", [15, 25])
def test_opening_mode_identifies_day_and_night_frames(smoke_dataset: Path, kernel_px: int) -> None:
    # --background-kernel-px: the bright-spot search on the frame minus its grey opening.
    # It used to take every bit of lit deck texture for a candidate and fail day frames.
    # The kernel must be wider than a beacon with its glow (here up to 3.4 px radius at 30 m,
    # 960x540 with square pixels): a 9 px opening keeps part of such a beacon and cuts its
    # centre off by up to 4 px, as the option's help says it would.
    opts = DetectorOptions(background_kernel_px=kernel_px)
    fails, err, lights = _score(smoke_dataset, "cog", options=opts)
    assert not fails, fails
    assert lights == {"night", "day"} and err.size == 24 * 13
    assert np.sqrt(np.mean(err**2)) < MAX_RMS_PX and err.max() < MAX_ERR_PX


def _hide_and_glint(
    image: np.ndarray, truth: pd.DataFrame, hide_id: int, rng: np.random.Generator
) -> tuple[np.ndarray, np.ndarray]:
    """The frame with beacon ``hide_id`` painted out and one glint added; and the glint (u, v).

    The beacon's core, housing and glow are inpainted from their surroundings (OpenCV
    Telea); the glint is a saturated white Gaussian spot as large as the beacons,
    at least 40 px from every beacon.
    """
    img = image.copy()
    row = truth.loc[hide_id]
    mask = np.zeros(img.shape[:2], np.uint8)
    r_px = int(np.ceil(10.0 * row.apparent_radius_px + 10))  # core, housing and glow
    cv2.circle(mask, (round(row.u_px), round(row.v_px)), r_px, 1, -1)
    img = cv2.inpaint(img, mask, 3, cv2.INPAINT_TELEA)
    H, W = img.shape[:2]
    beacons = truth[["u_px", "v_px"]].to_numpy(float)
    while True:
        g = rng.uniform([20.0, 20.0], [W - 20.0, H - 20.0])
        if np.min(np.linalg.norm(beacons - g, axis=1)) > 40.0:
            break
    sigma = max(1.0, float(truth.apparent_radius_px.median()) / 2.0)
    vv, uu = np.mgrid[0:H, 0:W]
    spot = 5.0 * 255.0 * np.exp(-((uu - g[0]) ** 2 + (vv - g[1]) ** 2) / (2 * sigma**2))
    img = np.clip(img.astype(float) + spot[..., None], 0, 255).astype(np.uint8)
    return img, g


@pytest.mark.parametrize("detector", ["cog", "gauss"])
def test_identification_with_one_hidden_beacon_and_one_glint(smoke_dataset: Path, detector: str):
    # The case on rendered frames (night and day, both cameras): a ring beacon
    # painted out and a saturated glint added; the rest keep their ids, the glint gets none.
    from deckpose.records import Frame

    fs = open_dataset(smoke_dataset)
    gt = pd.read_parquet(smoke_dataset / "beacons.parquet")
    rng = np.random.default_rng(17)
    for src in fs.sources[::2]:
        frame = load_frame(src, fs.cameras[src.camera_name])
        assert not isinstance(frame, str)
        truth = gt[(gt.frame_id == src.frame_id) & gt.visible].set_index("beacon_id")
        hide = int(rng.choice([i for i in truth.index if i != fs.layout.bow_id]))
        img, glint = _hide_and_glint(frame.image, truth, hide, rng)
        fd = detect_frame(Frame(img, frame.camera, frame.frame_id), detector, fs.layout)
        assert fd.ok, (src.frame_id, fd.reason)
        d = fd.detections
        ids = {int(i) for i in d.beacon_ids if i >= 0}
        assert ids == set(truth.index) - {hide}, (src.frame_id, hide, sorted(ids))
        for (u, v), i in zip(d.points_px, d.beacon_ids):
            if i >= 0:  # every id sits on its own beacon
                assert np.hypot(u - truth.u_px[int(i)], v - truth.v_px[int(i)]) < 1.0
        near_glint = np.linalg.norm(d.points_px - glint, axis=1) < 3.0
        assert near_glint.sum() == 1  # the glint is detected (a beacon-like spot) ...
        assert d.beacon_ids[near_glint][0] < 0  # ... and left unassigned
