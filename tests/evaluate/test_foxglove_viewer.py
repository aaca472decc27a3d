"""The log and its shipped layout, opened in a real Foxglove viewer, show what a person should see.

``tools/foxglove_viewer`` runs Foxglove Studio 1.48.0 (``@foxglove/studio-base``'s browser bundle)
under headless Chromium on the log and layout and saves a screenshot, the page's text and each
panel's place. Optional: needs ``node``, a Chromium (``apt-get install chromium-headless-shell``,
or ``$CHROMIUM``) and the harness's packages (``npm ci --prefix tools/foxglove_viewer``).
"""

import json
import os
import shutil
import subprocess
from pathlib import Path

import cv2
import numpy as np
import pytest
from deckpose.evaluate.foxglove_layout import IMAGE_PANEL, PLOT_PANEL, SCENE_PANEL, TRACK_PLOT_PANEL

from deckpose.capture_time import DEFAULT_CAPTURE_EPOCH_NS

TOOL = Path(__file__).resolve().parents[2] / "tools" / "foxglove_viewer"
NODE = shutil.which("node")
#: The browser view.mjs would use: $CHROMIUM, else the first of these on PATH.
CHROMIUM = next((p for p in (os.environ.get("CHROMIUM"), *map(shutil.which, ("chromium-headless-shell", "chromium",
                                                                          "chromium-browser")))
                 if p and Path(p).is_file()), None)
BUNDLE = TOOL / "node_modules" / "@foxglove" / "studio-base" / "assets" / "index.js"

pytestmark = pytest.mark.skipif(
    NODE is None or CHROMIUM is None or not BUNDLE.is_file(),
    reason="needs node, Chromium and the viewer's packages; enable with: apt-get install chromium-headless-shell "
           "&& npm ci --prefix tools/foxglove_viewer",
)


def _view(run: Path, out: Path):
    env = {**os.environ, "CHROMIUM": str(CHROMIUM)}
    r = subprocess.run([str(NODE), str(TOOL / "view.mjs"), str(run / "log.mcap"),
                        str(run / "foxglove_layout.json"), str(out), "--timeout-s", "150"],
                       capture_output=True, text=True, timeout=300, check=False, env=env)
    assert r.returncode == 0, r.stdout + r.stderr
    report = json.loads((out / "report.json").read_text())
    shot = cv2.imread(str(out / "screenshot.png"), cv2.IMREAD_COLOR)
    assert shot is not None
    return report, shot


@pytest.fixture(scope="module")
def viewed(evaluated_run, tmp_path_factory):
    """The harness's report (dict) and screenshot (BGR array) for the evaluated fake run."""
    return _view(evaluated_run, tmp_path_factory.mktemp("viewer"))


def _panel(report, panel_id):
    found = [p for p in report["panels"] if p["id"] == panel_id]
    assert len(found) == 1, f"panel {panel_id} not on the page: {[p['id'] for p in report['panels']]}"
    return found[0]


def _body_pixels(shot, panel):
    x, y, w, h = (round(v) for v in panel["body"])
    return shot[y:y + h, x:x + w].reshape(-1, 3).astype(int)  # BGR


def _series_pixels(shot, panel) -> int:
    """Coloured pixels in the right third of a plot's body: series lines (the legend sits on the left half)."""
    x, y, w, h = (round(v) for v in panel["body"])
    px = shot[y:y + h, x + 2 * w // 3:x + w].reshape(-1, 3).astype(int)
    return int(((px.max(axis=1) - px.min(axis=1)) > 100).sum())


def _count(px, lo_rgb, hi_rgb):
    lo, hi = np.array(lo_rgb[::-1]), np.array(hi_rgb[::-1])
    return int(((px >= lo) & (px <= hi)).all(axis=1).sum())


def test_the_log_opens_with_the_layout_and_no_problem(viewed):
    report, _ = viewed
    assert report["loaded"] and report["errors"] == []
    assert "Unknown panel type" not in report["text"]
    assert report["problems"]["tab"] and report["problems"]["count"] == 0 and report["problems"]["items"] == []
    assert "No problems found" in report["problems"]["text"]
    assert {p["id"] for p in report["panels"]} == {IMAGE_PANEL, SCENE_PANEL, PLOT_PANEL}
    # log times on the capture epoch: the viewer shows a 2024 date, not 1970
    assert "2024-01-01" in report["text"] and "1970" not in report["text"]


def test_the_image_panel_draws_the_frame_with_truth_and_detections(viewed):
    report, shot = viewed
    panel = _panel(report, IMAGE_PANEL)
    assert panel["title"] == "/camera/image"
    # the panel prints the drawn image's stamp (only once it has an image): the first frame's
    assert f"{DEFAULT_CAPTURE_EPOCH_NS // 1_000_000_000}.000000000" in panel["text"]
    px = _body_pixels(shot, panel)
    # the fake frames are black with white spots; the panel's own background is not pure black
    assert _count(px, (0, 0, 0), (0, 0, 0)) > 0.2 * len(px)
    assert _count(px, (0, 200, 20), (80, 255, 90)) > 500   # truth, green (TRUTH_RGBA)
    assert _count(px, (220, 50, 0), (255, 110, 60)) > 500  # detections, orange (DETECTION_RGBA)


def test_the_3d_panel_shows_the_deck_beacons_and_camera(viewed):
    report, shot = viewed
    px = _body_pixels(shot, _panel(report, SCENE_PANEL))
    assert _count(px, (150, 0, 0), (255, 70, 70)) > 10        # the bow beacon, red
    assert _count(px, (180, 180, 170), (255, 255, 255)) > 20  # the other beacons, white
    assert _count(px, (200, 160, 0), (255, 230, 90)) > 50     # the ring, yellow
    assert _count(px, (30, 150, 200), (130, 230, 255)) > 200  # the camera frustum, cyan
    grey = (np.abs(px - px.mean(axis=1, keepdims=True)) < 8).all(axis=1) & (px.mean(axis=1) > 90)
    assert grey.sum() > 0.02 * len(px)                        # the deck plate, grey


def test_the_plot_panel_plots_the_error_series(viewed):
    report, shot = viewed
    panel = _panel(report, PLOT_PANEL)
    for q in ("roll_err_deg", "pitch_err_deg", "yaw_err_deg", "height_err_m"):
        assert f"fake+thesis {q}" in panel["text"]
    # series lines in the plot's colours (blue, orange, yellow, green), not only axes and legend
    assert _series_pixels(shot, panel) > 50


def test_a_tracked_run_plots_roll_true_per_frame_filtered_and_predicted(tracked_run, tmp_path):
    report, shot = _view(tracked_run, tmp_path)
    assert report["loaded"] and report["errors"] == [] and report["problems"]["count"] == 0
    assert {p["id"] for p in report["panels"]} == {IMAGE_PANEL, SCENE_PANEL, PLOT_PANEL, TRACK_PLOT_PANEL}
    panel = _panel(report, TRACK_PLOT_PANEL)
    for label in ("true roll_deg", "fake+thesis per frame", "wave-bank filtered", "wave-bank predicted 0.1 s ahead",
                  "wave-bank predicted 0.2 s ahead"):
        assert label in panel["text"]
    assert _series_pixels(shot, panel) > 50   # series drawn, not only axes and legend
