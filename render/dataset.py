"""A rendered dataset on disk, generated in batch: local processes or a Dask cluster.

Layout (the dataset contract)::

    DATASET/manifest.json            format, resolved config, seed, versions, layout, cameras
    DATASET/cameras/<name>.yaml      ROS camera_info per camera
    DATASET/images/<frame_id>.png    lossless 8- or 16-bit PNG (BGR on disk)
    DATASET/previews/<frame_id>.png  the log's 8-bit preview (long side deckpose.preview.PREVIEW_PX)
    DATASET/frames.parquet           one row per frame
    DATASET/beacons.parquet          one row per frame x beacon
    DATASET/.parts/<frame_id>.json   per-frame ground truth, written after the image

Every file is written atomically (temporary name, then rename). A frame is done
when its part file exists, and the part is written only after its image, so a run
killed at any moment loses at most the frames in flight; ``resume=True`` renders
the rest and rebuilds the tables. Each frame's noise comes from its own seed, so
the output does not depend on the number of workers or where they run.
"""

from __future__ import annotations

import errno
import json
import logging
import os
import platform
import shutil
import threading
from collections.abc import Iterable
from concurrent.futures import ProcessPoolExecutor, as_completed
from importlib import metadata
from multiprocessing import get_context
from pathlib import Path
from typing import Any

import cv2
import pandas as pd
from deckpose.render.config import RenderConfig, config_to_dict, load_config
from deckpose.render.plan import FrameSpec, plan_frames

from deckpose.atomic_io import atomic_open, atomic_path, remove_stale_temps
from deckpose.camera_info import write_camera_info
from deckpose.errors import ConfigError
from deckpose.layout import layout_to_dict
from deckpose.output_folder import LOCK_NAME
from deckpose.preview import PREVIEW_PX, make_preview
from deckpose.run_folder import (
    DATASET_FORMAT,
    RunPaths,
    image_relpath,
    manifest_cameras,
    preview_relpath,
)
from deckpose.tables import write_table

log = logging.getLogger(__name__)

#: PNG settings: the SUB filter at the default zlib level (lossless; same size as OpenCV's
#: default, about 1.5x faster to encode on noisy frames here).
PNG_PARAMS: list[int] = [cv2.IMWRITE_PNG_FILTER, cv2.IMWRITE_PNG_FILTER_SUB]
_PACKAGES = ("deckpose", "numpy", "opencv-contrib-python-headless", "scikit-robot-pyrender", "PyOpenGL",
             "trimesh", "pandas", "pyarrow", "dask", "distributed")

# Per-process renderer cache: created lazily in the process that renders (a worker).
_RENDERERS: dict[tuple[Any, ...], Any] = {}
_LOCK = threading.Lock()


def _versions() -> dict[str, str]:
    out = {"python": platform.python_version()}
    for p in _PACKAGES:
        try:
            out[p] = metadata.version(p)
        except metadata.PackageNotFoundError:
            pass
    return out


def _part_path(out_dir: Path, frame_id: int) -> Path:
    return out_dir / ".parts" / f"{frame_id:06d}.json"


def render_one(cfg: RenderConfig, spec: FrameSpec, out_dir: str) -> int:
    """Render one frame and write its image then its ground-truth part (worker entry point)."""
    from deckpose.render.frame import beacon_rows, frame_row, render_frame
    from deckpose.render.scene import DeckRenderer

    out = Path(out_dir)
    key = (cfg.layout, cfg.scene, cfg.deck_half_size_m(), cfg.backend)
    with _LOCK:  # one GL context per process; Dask may run several threads per worker
        if key not in _RENDERERS:
            _RENDERERS[key] = DeckRenderer(cfg.layout, cfg.scene, cfg.deck_half_size_m(), cfg.backend)
        camera = cfg.cameras_by_name()[spec.camera_name]
        rf = render_frame(cfg, spec, camera, _RENDERERS[key])
    rel = image_relpath(spec.frame_id)
    img = rf.frame.image
    with atomic_path(out / rel) as tmp:
        if not cv2.imwrite(str(tmp), img if img.ndim == 2 else img[..., ::-1], PNG_PARAMS):
            # OpenCV says only that it failed: a full disk is the usual reason, so say so
            if shutil.disk_usage(tmp.parent).free < img.nbytes:
                raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(out / rel))
            raise OSError(f"OpenCV could not write {tmp}")
    # the log's preview, made from the frame in memory (the log would decode the PNG again)
    preview = make_preview(img if img.ndim == 2 else img[..., ::-1], PREVIEW_PX)
    with atomic_path(out / preview_relpath(spec.frame_id)) as tmp:
        if not cv2.imwrite(str(tmp), preview):
            raise OSError(f"OpenCV could not write {tmp}")
    part = {"frame": frame_row(rf, rel), "beacons": beacon_rows(rf)}
    with atomic_open(_part_path(out, spec.frame_id), "w") as fh:
        json.dump(part, fh)
    return spec.frame_id


def _manifest(cfg: RenderConfig, plan: list[FrameSpec], complete: bool) -> dict[str, Any]:
    cams = cfg.cameras_by_name()
    return {
        "format": DATASET_FORMAT,
        "name": cfg.name,
        "complete": complete,
        "n_frames": len(plan),
        "seed": cfg.seed,
        "config": config_to_dict(cfg),
        "versions": _versions(),
        "layout": layout_to_dict(cfg.layout),
        "sensor": sensor_block(cfg),
        "sensor_channels": 1 if cfg.sensor.color == "mono" else 3,
        "cameras": manifest_cameras(cams),
        "preview_px": PREVIEW_PX,
    }


def sensor_block(cfg: RenderConfig) -> dict[str, Any]:
    """The manifest's ``sensor`` block: the per-channel noise model behind every frame.

    ``gain_dn_per_e`` (DN per electron, ``(2**bit_depth - 1) / full_well_e``),
    ``read_noise_e``, ``full_well_e``, ``bit_depth``, ``offset_dn`` (black level, 0) and
    ``background_e``: 0, because the rendered scene is the background; the level under
    each beacon is ``spot_background_e`` in ``beacons.parquet`` (summed over channels).
    """
    s = cfg.sensor
    return {"gain_dn_per_e": (2 ** s.bit_depth - 1) / s.full_well_e, "read_noise_e": s.read_noise_e,
            "full_well_e": s.full_well_e, "bit_depth": s.bit_depth, "offset_dn": 0.0,
            "background_e": 0.0, "noise": s.noise}


def _write_json(path: Path, doc: dict[str, Any]) -> None:
    with atomic_open(path, "w") as fh:
        json.dump(doc, fh, indent=2, sort_keys=False)


def _prepare(cfg: RenderConfig, plan: list[FrameSpec], out: Path, resume: bool) -> None:
    run = RunPaths(out)
    manifest = run.manifest
    if manifest.exists():
        try:
            old = json.loads(manifest.read_text())
        except (OSError, ValueError) as exc:
            raise ConfigError(f"{manifest} is unreadable ({exc}); render into a new folder") from exc
        if not resume:
            raise ConfigError(f"{out} already holds a dataset; pass --resume to finish it or pick a new folder")
        if old.get("config") != json.loads(json.dumps(config_to_dict(cfg))):
            raise ConfigError(f"{out} was rendered from another config; resume needs the same config and seed")
    elif out.exists() and any(p.name != LOCK_NAME for p in out.iterdir()) and not resume:
        raise ConfigError(f"output folder {out} is not empty; choose a new or empty folder")
    out.mkdir(parents=True, exist_ok=True)
    remove_stale_temps(out)
    for name, cam in cfg.cameras_by_name().items():
        write_camera_info(cam, run.camera_file(name))
    run.images_dir.mkdir(exist_ok=True)
    run.previews_dir.mkdir(exist_ok=True)
    (out / ".parts").mkdir(exist_ok=True)
    _write_json(manifest, _manifest(cfg, plan, complete=False))


def _run_local(cfg: RenderConfig, todo: list[FrameSpec], out: Path, workers: int) -> Iterable[int]:
    if workers == 0:
        for spec in todo:
            yield render_one(cfg, spec, str(out))
        return
    with ProcessPoolExecutor(max_workers=workers, mp_context=get_context("spawn")) as pool:
        futures = [pool.submit(render_one, cfg, spec, str(out)) for spec in todo]
        try:
            for fut in as_completed(futures):
                yield fut.result()
        except BaseException:
            for f in futures:
                f.cancel()
            raise


def _run_dask(cfg: RenderConfig, todo: list[FrameSpec], out: Path, address: str) -> Iterable[int]:
    try:
        from distributed import Client
        from distributed import as_completed as dask_completed
    except ImportError:
        raise ConfigError("--scheduler needs dask.distributed: pip install 'deckpose[cluster]'") from None
    with Client(address) as client:
        cfg_f = client.scatter(cfg, broadcast=True)
        futures = client.map(render_one, [cfg_f] * len(todo), todo, [str(out)] * len(todo), pure=False)
        for fut in dask_completed(futures):
            yield fut.result()


def collect_tables(out: Path, plan: list[FrameSpec]) -> tuple[pd.DataFrame, pd.DataFrame]:
    """Build the frames and beacons tables from the part files, sorted by frame id."""
    frames, beacons = [], []
    for spec in plan:
        doc = json.loads(_part_path(out, spec.frame_id).read_text())
        frames.append(doc["frame"])
        beacons.extend(doc["beacons"])
    fdf = pd.DataFrame(frames).sort_values("frame_id", kind="stable").reset_index(drop=True)
    bdf = pd.DataFrame(beacons).sort_values(["frame_id", "beacon_id"], kind="stable").reset_index(drop=True)
    for c in ("frame_id", "stamp_ns", "seed", "n_visible"):
        fdf[c] = fdf[c].astype("int64")
    for c in ("frame_id", "beacon_id"):
        bdf[c] = bdf[c].astype("int64")
    return fdf, bdf


def render_dataset(config: RenderConfig | str | os.PathLike[str], out_dir: str | os.PathLike[str], *,
                   workers: int = 1, resume: bool = False, scheduler: str | None = None,
                   progress: bool = True) -> Path:
    """Render every frame of a config into a dataset folder.

    Parameters
    ----------
    config : RenderConfig or path-like
        A validated config or a YAML file.
    out_dir : path-like
        Dataset folder (created; must be new or empty unless ``resume``).
    workers : int
        Local worker processes (spawned; each creates its GL context lazily).
        0 renders in this process.
    resume : bool
        Finish an interrupted run of the same config: render only missing frames.
    scheduler : str, optional
        Address of a Dask scheduler (``tcp://host:8786``); overrides ``workers``.
    progress : bool
        Show a progress bar.

    Returns
    -------
    Path
        The dataset folder.
    """
    cfg = config if isinstance(config, RenderConfig) else load_config(config)
    if workers < 0:
        raise ConfigError(f"workers must be >= 0, got {workers}")
    plan = plan_frames(cfg)  # every config error surfaces here, before any frame
    out = Path(out_dir)
    _prepare(cfg, plan, out, resume)
    todo = [s for s in plan if not _part_path(out, s.frame_id).exists()]
    log.info("%d of %d frames to render into %s (%s)", len(todo), len(plan), out,
             f"scheduler {scheduler}" if scheduler else f"{workers} worker processes")
    from tqdm import tqdm

    bar = tqdm(total=len(plan), initial=len(plan) - len(todo), unit="frame", disable=None if progress else True,
               desc=f"render {cfg.name}")
    runner = _run_dask(cfg, todo, out, scheduler) if scheduler else _run_local(cfg, todo, out, workers)
    for _ in runner:
        bar.update(1)
    bar.close()
    fdf, bdf = collect_tables(out, plan)
    write_table(fdf, RunPaths(out).frames, "frames")
    write_table(bdf, RunPaths(out).beacons, "beacons")
    _write_json(RunPaths(out).manifest, _manifest(cfg, plan, complete=True))
    log.info("dataset %s complete: %d frames", out, len(plan))
    return out
