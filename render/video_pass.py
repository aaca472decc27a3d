"""The video pass of a rendered dataset: each time sequence through a video codec, in place.

After every frame of a run is rendered and stored, :func:`video_pass` compresses each
time sequence (camera, height, lighting, in time order, at its frame rate) as one video
stream (:mod:`deckpose.render.video_codec`) and stores the decoded frames and their
previews over the rendered ones. The truth tables are not touched: the codec changes the
pixels, not where the beacons are.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
from deckpose.render.config import RenderConfig
from deckpose.render.plan import FrameSpec
from deckpose.render.sensor_config import VideoSpec

from deckpose.atomic_io import atomic_open, write_bytes
from deckpose.image_store import ImageFormat, decode_image, encode_image
from deckpose.preview import PREVIEW_PX, make_preview
from deckpose.run_folder import image_relpath, preview_relpath


def video_pass(cfg: RenderConfig, video: VideoSpec, plan: list[FrameSpec], out: Path, progress: bool) -> None:
    """Compress each time sequence's stored frames as a video stream and store the decoded frames.

    Two-phase, so an interrupted pass resumes without compressing a frame twice: a
    sequence's decoded frames and previews are written under ``.video/`` and then
    ``.video/<k>.staged``; only then are they moved over ``images/`` and ``previews/``
    (each move atomic), and ``.video/<k>.applied`` marks the sequence done. A sequence
    with no marker still has every frame as rendered.
    """
    from deckpose.render.exposure_control import time_sequences
    from tqdm import tqdm

    stage = out / ".video"
    stage.mkdir(exist_ok=True)
    sequences = time_sequences(plan)
    bar = tqdm(total=len(plan), unit="frame", disable=None if progress else True, desc=f"video {cfg.name}")
    try:
        for k, idx in enumerate(sequences):
            applied, staged = stage / f"{k:04d}.applied", stage / f"{k:04d}.staged"
            if not applied.exists():
                specs = [plan[i] for i in idx]
                if not staged.exists():
                    _stage_sequence(cfg, video, specs, out, stage)
                    with atomic_open(staged, "w") as fh:
                        json.dump([s.frame_id for s in specs], fh)
                for spec in specs:
                    for rel in (image_relpath(spec.frame_id, cfg.image_format.suffix), preview_relpath(spec.frame_id)):
                        if (stage / rel).exists():  # (moved already when a pass was cut here)
                            os.replace(stage / rel, out / rel)
                with atomic_open(applied, "w") as fh:
                    json.dump([s.frame_id for s in specs], fh)
                staged.unlink()
            bar.update(len(idx))
    finally:
        bar.close()


def _stage_sequence(cfg: RenderConfig, video: VideoSpec, specs: list[FrameSpec], out: Path, stage: Path) -> None:
    """Write one sequence's frames after the video round trip, and their previews, under ``stage``."""
    from deckpose.render.video_codec import video_round_trip

    rels = [image_relpath(s.frame_id, cfg.image_format.suffix) for s in specs]
    frames = []
    for rel in rels:
        img = decode_image((out / rel).read_bytes(), rel)
        frames.append(img if img.ndim == 2 else img[..., ::-1])  # BGR on disk
    t = np.array([s.t_s for s in specs], float)
    steps = np.diff(t)
    dt = float(np.median(steps)) if steps.size and np.median(steps) > 0 else cfg.motion.dt_s
    decoded = video_round_trip(frames, 1.0 / dt, video)
    for spec, rel, img in zip(specs, rels, decoded):
        bgr = img if img.ndim == 2 else np.ascontiguousarray(img[..., ::-1])
        for path in (stage / rel, stage / preview_relpath(spec.frame_id)):
            path.parent.mkdir(parents=True, exist_ok=True)
        write_bytes(stage / rel, encode_image(bgr, cfg.image_format))
        write_bytes(stage / preview_relpath(spec.frame_id), encode_image(make_preview(bgr, PREVIEW_PX),
                                                                          ImageFormat.PNG))
