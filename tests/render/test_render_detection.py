"""Detection at render time (``deckpose render --detect``, ``--no-images``).

The reference is the two-step path users have today: render the frames to disk, then
``deckpose detect`` decodes and detects them. Detecting at render time works on the same
array the lossless file holds, so its tables must be equal, value for value, but for the
timing columns.
"""

from __future__ import annotations

import json
from pathlib import Path

import pandas as pd
import pytest
from deckpose.detect.run import detect_run
from deckpose.render.config import config_from_dict
from deckpose.render.dataset import render_dataset
from deckpose.render.render_detection import RenderDetection

from deckpose.cli import main
from deckpose.errors import ConfigError, InputDataError

from .conftest import tiny_doc

TIMING = ["seconds", "cpu_seconds"]


@pytest.fixture(scope="module")
def rendered_then_detected(tmp_path_factory: pytest.TempPathFactory, egl_renderer_factory) -> Path:
    egl_renderer_factory(config_from_dict(tiny_doc()))
    out = render_dataset(config_from_dict(tiny_doc()), tmp_path_factory.mktemp("two_step") / "ds", workers=0,
                         progress=False)
    for det in ("cog", "gauss"):
        detect_run(out, det)
    return out


@pytest.fixture(scope="module")
def detected_at_render(tmp_path_factory: pytest.TempPathFactory, egl_renderer_factory) -> Path:
    egl_renderer_factory(config_from_dict(tiny_doc()))
    return render_dataset(config_from_dict(tiny_doc()), tmp_path_factory.mktemp("fused") / "ds", workers=0,
                          progress=False, detection=RenderDetection(("cog", "gauss")))


@pytest.mark.parametrize("det", ["cog", "gauss"])
def test_detections_at_render_equal_those_of_the_detect_stage(rendered_then_detected: Path,
                                                              detected_at_render: Path, det: str) -> None:
    a, b = rendered_then_detected / "detections", detected_at_render / "detections"
    da, db = pd.read_parquet(a / f"{det}.parquet"), pd.read_parquet(b / f"{det}.parquet")
    assert len(da) > 0
    pd.testing.assert_frame_equal(da, db)
    fa, fb = pd.read_parquet(a / f"{det}.frames.parquet"), pd.read_parquet(b / f"{det}.frames.parquet")
    pd.testing.assert_frame_equal(fa.drop(columns=TIMING), fb.drop(columns=TIMING))
    ra, rb = (json.loads((p / f"{det}.run.json").read_text()) for p in (a, b))
    assert (ra["detected_at_render"], rb["detected_at_render"]) == (False, True)
    assert ra["detector_options"] == rb["detector_options"]  # the sensor's gain in both
    # the frames and ground truth are those of a run without detection
    for t in ("frames.parquet", "beacons.parquet"):
        pd.testing.assert_frame_equal(pd.read_parquet(rendered_then_detected / t),
                                      pd.read_parquet(detected_at_render / t))


def test_no_images_keeps_previews_tables_and_detections(tmp_path: Path, egl_renderer_factory,
                                                        rendered_then_detected: Path) -> None:
    egl_renderer_factory(config_from_dict(tiny_doc()))
    out = render_dataset(config_from_dict(tiny_doc()), tmp_path / "ds", workers=0, progress=False,
                         detection=RenderDetection(("cog",), keep_images=False))
    man = json.loads((out / "manifest.json").read_text())
    assert man["images_kept"] is False and man["detect_at_render"]["detectors"] == ["cog"]
    assert not (out / "images").exists()  # no frame kept: no images folder
    assert len(list((out / "previews").glob("*.png"))) == man["n_frames"]
    frames = pd.read_parquet(out / "frames.parquet")
    assert (frames["image"] == "").all()
    dets = pd.read_parquet(out / "detections" / "cog.parquet")
    ref = pd.read_parquet(rendered_then_detected / "detections" / "cog.parquet")
    pd.testing.assert_frame_equal(dets, ref)
    ff = pd.read_parquet(out / "detections" / "cog.frames.parquet")
    assert (ff["image"] == "").all()
    # no frame to detect in: one clear error naming the detections that are there
    with pytest.raises(InputDataError, match="keeps no frames.*--no-images"):
        detect_run(out, "gauss")
    # resuming with another choice is refused before anything is written
    with pytest.raises(ConfigError, match="--detect cog --no-images.*no --detect"):
        render_dataset(config_from_dict(tiny_doc()), out, workers=0, progress=False, resume=True)


def test_bad_choices_fail_before_anything_is_written(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="--no-images keeps no frame.*--detect"):
        render_dataset(config_from_dict(tiny_doc()), tmp_path / "a", progress=False,
                       detection=RenderDetection((), keep_images=False))
    with pytest.raises(ConfigError, match="unknown detector 'nope'"):
        render_dataset(config_from_dict(tiny_doc()), tmp_path / "b", progress=False,
                       detection=RenderDetection(("nope",)))
    assert not (tmp_path / "a").exists() and not (tmp_path / "b").exists()


def test_pipeline_detects_at_render_and_reports_from_previews(tmp_path: Path,
                                                               capsys: pytest.CaptureFixture[str]) -> None:
    import yaml

    doc = tiny_doc(heights_m=[30.0], lighting=["night"])
    cfg = tmp_path / "tiny.yaml"
    cfg.write_text(yaml.safe_dump(doc))
    run = tmp_path / "run"
    argv = ["pipeline", str(cfg), str(run), "--method", "pnp", "--workers", "0", "--no-progress",
            "--no-mcap", "--detect-at-render", "--no-images"]
    assert main(argv) == 0
    out = capsys.readouterr().out
    assert "done at render time" in out
    assert not (run / "images").exists()
    errors = pd.read_parquet(run / "evaluation" / "errors.parquet")
    assert len(errors) == 2 and errors.ok.all()
    record = json.loads((run / "pipeline.json").read_text())
    assert record["detect_at_render"] is True and record["images_kept"] is False
    assert "--detect-at-render" in record["command"] and "--no-images" in record["command"]
    assert list((run / "report" / "figures").glob("example_*.png"))  # drawn on the preview
    # later stages again, without repeating the flags: the detect stage finds the detections there
    assert main(["pipeline", str(cfg), str(run), "--method", "pnp", "--no-progress", "--no-mcap",
                 "--from-stage", "detect"]) == 0
    assert "done at render time" in capsys.readouterr().out
    assert main(["detect", str(run), "--detector", "cog"]) == 2
    assert "estimate from them" in capsys.readouterr().err  # not "render it again"
    assert main(["render", str(cfg), str(tmp_path / "r3"), "--detect", ""]) == 2
    assert "--detect needs detector names" in capsys.readouterr().err
    # exports need the frames: one line saying why
    assert main(["export", str(run), "--format", "coco", "-o", str(tmp_path / "coco")]) == 2
    assert "keeps no frames" in capsys.readouterr().err
    # --no-images alone has nothing to detect in
    assert main(["pipeline", str(cfg), str(tmp_path / "r2"), "--no-images", "--no-progress"]) == 2
    assert "--detect-at-render" in capsys.readouterr().err
