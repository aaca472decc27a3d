"""A rendered dataset on disk, generated in batch: local processes or a Dask cluster.

Layout (the dataset contract)::

    DATASET/manifest.json            format, resolved config, seed, versions, layout, cameras
    DATASET/cameras/<name>.yaml      ROS camera_info per camera
    DATASET/cameras/<name>_hot_pixels.parquet  the camera's hot pixels (only with sensor.hot_pixel_fraction > 0)
    DATASET/images/<frame_id>.png    lossless 8- or 16-bit PNG (BGR on disk)
    DATASET/previews/<frame_id>.png  the log's 8-bit preview (long side deckpose.preview.PREVIEW_PX)
    DATASET/frames.parquet           one row per frame
    DATASET/beacons.parquet          one row per frame x beacon
    DATASET/lights.parquet           one row per frame x non-beacon light (navigation, floodlights, glints)
    DATASET/.parts/<frame_id>.json   per-frame ground truth, written after the image
    DATASET/detections/<detector>.*  with ``detection``: detected at render time
                                     (:mod:`deckpose.render.render_detection`)

With a :class:`~deckpose.render.render_detection.RenderDetection` (``deckpose render
--detect``), each frame is also detected in the worker that rendered it, from memory, and
with ``keep_images=False`` (``--no-images``) its image file is not written.

Every file is written atomically (temporary name, then rename). A frame is done
when its part file exists, and the part is written only after its image, so a run
killed at any moment loses at most the frames in flight; ``resume=True`` renders
the rest and rebuilds the tables. Each frame's noise comes from its own seed, so
the output does not depend on the number of workers or where they run.

Local worker processes render and write their frames themselves (:func:`render_one`);
Dask workers only render and encode (:func:`encode_frame`) and this process writes
what they return (:func:`write_frame`), so a cluster needs no shared file system.
"""

from __future__ import annotations

import contextlib
import json
import logging
import os
import platform
import shutil
import threading
from collections.abc import Generator
from concurrent.futures import as_completed
from dataclasses import dataclass
from importlib import metadata
from pathlib import Path
from typing import TYPE_CHECKING, Any, cast

import pandas as pd
from deckpose.render.config import RenderConfig, config_to_dict, load_config
from deckpose.render.fixed_pattern import hot_pixel_table
from deckpose.render.plan import FrameSpec, plan_frames
from deckpose.render.render_detection import (
    RenderDetection,
    detect_rendered,
    manifest_fields,
    resolve_detection,
    write_rendered_detections,
)
from deckpose.render.sensor_config import BayerPattern
from deckpose.render.video_pass import video_pass

from deckpose.atomic_io import atomic_open, remove_stale_temps, write_bytes
from deckpose.camera_info import write_camera_info
from deckpose.errors import ConfigError
from deckpose.image_store import ImageFormat, encode_image
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
from deckpose.table_schemas import (
    HOT_PIXEL_COLUMNS,
    LIGHT_COLUMNS,
    PAINTED_RING_COLUMNS,
    typed_frame,
)
from deckpose.tables import write_table
from deckpose.worker_pool import connect_scheduler, worker_pool

if TYPE_CHECKING:
    from deckpose.render.scene import DeckRenderer
    from distributed import Client

log = logging.getLogger(__name__)

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


@dataclass(frozen=True)
class EncodedFrame:
    """One rendered frame as the bytes of its files: what a worker hands back to be written.

    ``image`` is the file ``part["frame"]["image"]`` names (``images/<frame_id>.png``, BGR
    on disk, or ``.zst``: :mod:`deckpose.image_store`; empty, and no file, when the frames
    are not kept), ``preview_png`` is
    ``previews/<frame_id>.png`` and ``part`` is the ``.parts/<frame_id>.json`` document
    (the frame's ``frames.parquet`` row and ``beacons.parquet`` rows).
    """

    frame_id: int
    image: bytes
    preview_png: bytes
    part: dict[str, Any]


def encode_frame(cfg: RenderConfig, spec: FrameSpec, detection: RenderDetection | None = None) -> EncodedFrame:
    """Render one frame and encode its image, preview and ground truth; writes nothing.

    The Dask workers' task: what it returns is written by the process that owns the
    output folder (:func:`write_frame`), so the workers need no access to it. With
    ``detection``, the frame is also detected here, from memory (the part's
    ``"detections"``), and its image is encoded only if ``detection.keep_images``.
    """
    from deckpose.render.frame import (
        beacon_rows,
        frame_row,
        light_rows,
        painted_ring_rows,
        render_frame,
    )
    with _LOCK:  # one GL context per process; Dask may run several threads per worker
        camera = cfg.cameras_by_name()[spec.camera_name]
        rf = render_frame(cfg, spec, camera, _renderer(cfg))
    img = rf.frame.image
    bgr = img if img.ndim == 2 else img[..., ::-1]
    keep = detection is None or detection.keep_images
    image = encode_image(bgr, cfg.image_format) if keep else b""
    # the log's preview, made from the frame in memory (the log would decode the PNG again)
    preview_png = encode_image(make_preview(bgr, PREVIEW_PX), ImageFormat.PNG)
    rel = image_relpath(spec.frame_id, cfg.image_format.suffix) if keep else ""
    part: dict[str, Any] = {"frame": frame_row(rf, rel), "beacons": beacon_rows(rf), "lights": light_rows(rf)}
    if cfg.painted_ring is not None:  # the key only with a ring (default parts unchanged)
        part["painted_ring"] = painted_ring_rows(rf)
    if detection is not None and detection.detectors:
        part["detections"] = detect_rendered(rf.frame, spec.camera_name, rel, cfg.layout, detection)
    return EncodedFrame(spec.frame_id, image, preview_png, part)


def _renderer(cfg: RenderConfig) -> DeckRenderer:
    """This process's renderer of the config's scene (made on first use; call with ``_LOCK`` held)."""
    from deckpose.render.scene import DeckRenderer

    key = (cfg.layout, cfg.scene, cfg.deck_half_size_m(), cfg.backend)
    if key not in _RENDERERS:
        _RENDERERS[key] = DeckRenderer(cfg.layout, cfg.scene, cfg.deck_half_size_m(), cfg.backend)
    return cast("DeckRenderer", _RENDERERS[key])


def write_frame(out_dir: Path, frame: EncodedFrame) -> int:
    """Write a frame's image, then its preview, then its part (the commit marker); atomically.

    Returns the frame id. A frame is done when its part exists, so a writer killed at
    any moment leaves whole files and, at worst, a frame that ``resume`` renders again.
    """
    if frame.part["frame"]["image"]:  # "" when the frames are not kept
        write_bytes(out_dir / frame.part["frame"]["image"], frame.image)
    write_bytes(out_dir / preview_relpath(frame.frame_id), frame.preview_png)
    with atomic_open(_part_path(out_dir, frame.frame_id), "w") as fh:
        json.dump(frame.part, fh)
    return frame.frame_id


def render_one(cfg: RenderConfig, spec: FrameSpec, out_dir: str, detection: RenderDetection | None = None) -> int:
    """Render one frame and write it into ``out_dir`` (the local workers' entry point)."""
    return write_frame(Path(out_dir), encode_frame(cfg, spec, detection))


def _manifest(cfg: RenderConfig, plan: list[FrameSpec], complete: bool,
              detection: RenderDetection | None = None) -> dict[str, Any]:
    # with the frame's modules (scipy, OpenCV), not when the CLI imports this one
    from deckpose.render.optics import optics_block

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
        **manifest_fields(detection),
        **({"optics": optics_block(cfg.optics, cams)} if cfg.optics.enabled() else {}),
    }


def sensor_block(cfg: RenderConfig) -> dict[str, Any]:
    """The manifest's ``sensor`` block: the per-channel noise model behind every frame.

    ``gain_dn_per_e`` (DN per electron, ``(2**bit_depth - 1) / full_well_e``),
    ``read_noise_e``, ``full_well_e``, ``bit_depth``, ``offset_dn`` (black level, 0) and
    ``background_e``: 0, because the rendered scene is the background; the level under
    each beacon is ``spot_background_e`` in ``beacons.parquet`` (summed over channels).
    """
    s = cfg.sensor
    block: dict[str, Any] = {
        "gain_dn_per_e": (2 ** s.bit_depth - 1) / s.full_well_e, "read_noise_e": s.read_noise_e,
        "full_well_e": s.full_well_e, "bit_depth": s.bit_depth, "offset_dn": 0.0,
        "background_e": 0.0, "noise": s.noise}
    # sensor effects (issue 23 item 4), named only when on: a default manifest is unchanged
    if s.bayer is not BayerPattern.NONE:
        block["bayer"] = s.bayer.value  # each pixel measured one channel; RGB is bilinear demosaicing
    if s.jpeg_quality is not None:
        block["jpeg_quality"] = s.jpeg_quality
    if s.prnu or s.dsnu_e or s.hot_pixel_fraction:
        block["fixed_pattern"] = {"prnu": s.prnu, "dsnu_e": s.dsnu_e, "hot_pixel_fraction": s.hot_pixel_fraction,
                                  "hot_pixel_e": s.hot_pixel_e, "hot_pixels": "cameras/<name>_hot_pixels.parquet"}
    ae = s.auto_exposure
    if ae is not None and ae.controlled:
        block["exposure"] = {
            "control": "per time sequence (camera, height, lighting) in time order: frame k's exposure from the "
                       "meterings of the frames before it (render/exposure_control.py); nothing drawn at random",
            "time_constant_s": ae.time_constant_s, "max_step_stops": ae.max_step_stops,
            "metering_scale": ae.metering_scale,
            "columns": "frames.parquet exposure (used), metered_exposure (the frame's own metering)"}
    elif ae is not None:
        block["exposure"] = "per frame: frames.parquet exposure (auto-exposure)"
    if s.video is not None:
        from deckpose.render.video_codec import encoder_description

        block["video"] = {
            "codec": s.video.codec.value, "bitrate_kbps": s.video.bitrate_kbps, "gop_frames": s.video.gop_frames,
            "encoder": encoder_description(s.video.codec),
            "order": "one stream per time sequence (camera, height, lighting) in time order, at its frame rate; "
                     "the decoded frames are stored (render/video_codec.py)"}
    return block


def _write_json(path: Path, doc: dict[str, Any]) -> None:
    with atomic_open(path, "w") as fh:
        json.dump(doc, fh, indent=2, sort_keys=False)


def _config_mismatch(out: Path, old: object, new: dict[str, Any]) -> str:
    """Why a dataset cannot be resumed with ``new``: another config, or one an older deckpose wrote."""
    if not isinstance(old, dict):
        return f"{out} was rendered from another config; resume needs the same config and seed"
    if _is_older_form(old, new):
        return (f"{out} was rendered by an older deckpose (its config has no "
                f"{', '.join(sorted(_missing_keys(old, new)))}); its frames cannot be mixed with this "
                "version's: render into a new folder")
    changed = sorted(k for k in set(old) | set(new) if old.get(k) != new.get(k))
    return (f"{out} was rendered from another config (differs in {', '.join(changed)}); "
            "resume needs the same config and seed")


def _is_older_form(old: object, new: object) -> bool:
    """Whether ``old`` is ``new`` with some keys left out, at any depth (and not ``new`` itself)."""
    def within(a: object, b: object) -> bool:
        if isinstance(a, dict) and isinstance(b, dict):
            return set(a) <= set(b) and all(within(a[k], b[k]) for k in a)
        if isinstance(a, list) and isinstance(b, list):
            return len(a) == len(b) and all(within(x, y) for x, y in zip(a, b))
        return a == b

    return old != new and within(old, new)


def _missing_keys(old: dict[str, Any], new: dict[str, Any], prefix: str = "") -> list[str]:
    """Keys (dotted) that ``new`` has and ``old`` lacks, at any depth of nested mappings."""
    out = []
    for k, v in new.items():
        if k not in old:
            out.append(prefix + k)
        elif isinstance(v, dict) and isinstance(old[k], dict):
            out += _missing_keys(old[k], v, f"{prefix}{k}.")
        elif isinstance(v, list) and isinstance(old[k], list) and len(v) == len(old[k]):
            for i, (a, b) in enumerate(zip(old[k], v)):
                if isinstance(a, dict) and isinstance(b, dict):
                    out += _missing_keys(a, b, f"{prefix}{k}[{i}].")
    return out


def _detection_mismatch(out: Path, old: dict[str, Any], detection: RenderDetection | None) -> str:
    """Why a dataset cannot be resumed with another choice of detection at render time ("" if it can)."""
    new = json.loads(json.dumps(manifest_fields(detection)))
    was = {k: old[k] for k in ("images_kept", "detect_at_render") if k in old}
    if was == new:
        return ""

    def say(fields: dict[str, Any]) -> str:
        names = ",".join(fields.get("detect_at_render", {}).get("detectors", []))
        kept = fields.get("images_kept", True)
        return (f"--detect {names}" if names else "no --detect") + ("" if kept else " --no-images")

    return (f"{out} was rendered with {say(was)}, this run asks for {say(new)}; resume with the "
            "same choice, or render into a new folder")


def _prepare(cfg: RenderConfig, plan: list[FrameSpec], out: Path, resume: bool,
             detection: RenderDetection | None = None) -> None:
    run = RunPaths(out)
    manifest = run.manifest
    if manifest.exists():
        try:
            old = json.loads(manifest.read_text())
        except (OSError, ValueError) as exc:
            raise ConfigError(f"{manifest} is unreadable ({exc}); render into a new folder") from exc
        if not resume:
            raise ConfigError(f"{out} already holds a dataset; pass --resume to finish it or pick a new folder")
        new = json.loads(json.dumps(config_to_dict(cfg)))
        if old.get("config") != new:
            raise ConfigError(_config_mismatch(out, old.get("config"), new))
        why = _detection_mismatch(out, old, detection)
        if why:
            raise ConfigError(why)
    elif out.exists() and any(p.name != LOCK_NAME for p in out.iterdir()) and not resume:
        raise ConfigError(f"output folder {out} is not empty; choose a new or empty folder")
    out.mkdir(parents=True, exist_ok=True)
    remove_stale_temps(out)
    for name, cam in cfg.cameras_by_name().items():
        write_camera_info(cam, run.camera_file(name))
        if cfg.sensor.hot_pixel_fraction > 0:  # the fixed pattern's hot pixels, for false-detection counts
            hot = hot_pixel_table(cfg.sensor, cfg.seed, name, cam.height_px, cam.width_px)
            write_table(typed_frame([], HOT_PIXEL_COLUMNS) if not hot["u_px"].size else pd.DataFrame(hot),
                        run.hot_pixels_file(name), "hot pixels")
    if detection is None or detection.keep_images:  # a run that keeps no frame has no images folder
        run.images_dir.mkdir(exist_ok=True)
    run.previews_dir.mkdir(exist_ok=True)
    (out / ".parts").mkdir(exist_ok=True)
    _write_json(manifest, _manifest(cfg, plan, complete=False, detection=detection))


def _run_local(cfg: RenderConfig, todo: list[FrameSpec], out: Path, workers: int,
               detection: RenderDetection | None = None) -> Generator[int, None, None]:
    if workers == 0:
        for spec in todo:
            yield render_one(cfg, spec, str(out), detection)
        return
    # workers ignore Ctrl-C; on it (or any error) the frames not started are cancelled and the
    # workers stopped within seconds (deckpose.worker_pool)
    with worker_pool(workers) as pool:
        futures = [pool.submit(render_one, cfg, spec, str(out), detection) for spec in todo]
        for fut in as_completed(futures):
            yield fut.result()


def _run_dask(client: Client, cfg: RenderConfig, todo: list[FrameSpec], out: Path,
              detection: RenderDetection | None = None) -> Generator[int, None, None]:
    """Render on the cluster's workers and write here, as the frames come back.

    The workers write nothing (:func:`encode_frame`), so they need no shared disk and
    their working folder does not matter. At most two frames per worker thread are
    submitted and not yet written, and each result is released once written: the
    cluster holds at most that many encoded frames, this process one.
    """
    from distributed import as_completed as dask_completed

    specs = iter(todo)
    running = dask_completed()

    def submit_up_to_window() -> None:
        threads = cast("dict[str, int]", client.nthreads())  # a dict (a coroutine in async clients)
        window = 2 * max(1, sum(threads.values()))  # asked each time: workers come and go
        while running.count() < window:
            spec = next(specs, None)
            if spec is None:
                return
            running.add(client.submit(encode_frame, cfg, spec, detection, pure=False))

    submit_up_to_window()
    for fut in running:
        frame: EncodedFrame = fut.result()
        fut.release()
        submit_up_to_window()
        yield write_frame(out, frame)
        del frame


def read_parts(out: Path, plan: list[FrameSpec]) -> list[dict[str, Any]]:
    """The part documents of every planned frame, in plan order."""
    return [json.loads(_part_path(out, spec.frame_id).read_text()) for spec in plan]


def collect_tables(out: Path, plan: list[FrameSpec], parts: list[dict[str, Any]] | None = None
                   ) -> tuple[pd.DataFrame, pd.DataFrame, pd.DataFrame]:
    """Build the frames, beacons and lights tables from the part files, sorted by frame id."""
    frames, beacons, lights = [], [], []
    for doc in parts if parts is not None else read_parts(out, plan):
        frames.append(doc["frame"])
        beacons.extend(doc["beacons"])
        lights.extend(doc.get("lights", []))
    fdf = pd.DataFrame(frames).sort_values("frame_id", kind="stable").reset_index(drop=True)
    bdf = pd.DataFrame(beacons).sort_values(["frame_id", "beacon_id"], kind="stable").reset_index(drop=True)
    ldf = typed_frame(lights, LIGHT_COLUMNS).sort_values(["frame_id", "light_id"], kind="stable").reset_index(drop=True)
    for c in ("frame_id", "stamp_ns", "seed", "n_visible"):
        fdf[c] = fdf[c].astype("int64")
    for c in ("frame_id", "beacon_id"):
        bdf[c] = bdf[c].astype("int64")
    return fdf, bdf, ldf


def _render_todo(cfg: RenderConfig, plan: list[FrameSpec], out: Path, workers: int, scheduler: str | None,
                 client: Any, progress: bool, detection: RenderDetection | None) -> None:
    """Render the frames of ``plan`` that have no finished part yet, with a progress bar."""
    todo = [s for s in plan if not _part_path(out, s.frame_id).exists()]
    log.info("%d of %d frames to render into %s (%s)", len(todo), len(plan), out,
             f"scheduler {scheduler}" if scheduler else f"{workers} worker processes")
    from tqdm import tqdm

    bar = tqdm(total=len(plan), initial=len(plan) - len(todo), unit="frame",
               disable=None if progress else True, desc=f"render {cfg.name}")
    runner = (_run_dask(client, cfg, todo, out, detection) if client is not None
              else _run_local(cfg, todo, out, workers, detection))
    try:
        for _ in runner:
            bar.update(1)
    finally:
        bar.close()
        runner.close()  # on an interrupt here, the workers are stopped now, not when collected


def _controlled_exposures(cfg: RenderConfig, plan: list[FrameSpec], progress: bool) -> list[FrameSpec]:
    """The plan with the auto-exposure controller's exposures (the plan itself without the controller).

    The metering pre-pass (:mod:`deckpose.render.exposure_control`) rasterises every
    frame's scene at ``metering_scale`` in this process, in plan order, and runs the
    controller over each time sequence; a resumed run meters again and gets the same
    exposures (nothing is drawn at random).
    """
    ae = cfg.sensor.auto_exposure
    if ae is None or not ae.controlled:
        return plan
    from deckpose.render.exposure_control import metering_exposure, with_exposures
    from tqdm import tqdm

    cams = cfg.cameras_by_name()
    metered = []
    with _LOCK:
        renderer = _renderer(cfg)
        for spec in tqdm(plan, unit="frame", disable=None if progress else True, desc=f"meter {cfg.name}"):
            metered.append(metering_exposure(spec, cams[spec.camera_name], renderer, cfg.sensor,
                                             cfg.scene.shading, ae))
    return with_exposures(plan, metered, ae)


def _remove_unfinished(out: Path) -> None:
    """Remove what :func:`_prepare` wrote into ``out`` (all but another job's lock file)."""
    for p in out.iterdir():
        if p.name == LOCK_NAME:
            continue
        if p.is_dir():
            shutil.rmtree(p)
        else:
            p.unlink()


def render_dataset(config: RenderConfig | str | os.PathLike[str], out_dir: str | os.PathLike[str], *,
                   workers: int = 1, resume: bool = False, scheduler: str | None = None,
                   progress: bool = True, detection: RenderDetection | None = None) -> Path:
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
    detection : RenderDetection, optional
        Detect each frame at render time, from memory, and optionally keep no frames
        (:mod:`deckpose.render.render_detection`). ``options.gain_dn_per_e = None`` takes
        the sensor's gain, as ``deckpose detect`` does from the manifest.

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
    if detection is not None:  # checked before anything is written
        if cfg.sensor.video is not None:
            raise ConfigError("sensor.video compresses the frames after they are rendered, so --detect would "
                              "detect frames the video changes afterwards: detect the run with deckpose detect, "
                              "or set sensor.video: null")
        detection = resolve_detection(detection, sensor_block(cfg))
    fresh = not RunPaths(out).manifest.exists()
    with connect_scheduler(scheduler) if scheduler else contextlib.nullcontext() as client:  # before writing
        _prepare(cfg, plan, out, resume, detection)
        plan = _controlled_exposures(cfg, plan, progress)
        try:
            _render_todo(cfg, plan, out, workers, scheduler, client, progress, detection)
        except ConfigError as exc:
            # A config fault only a frame can show (a rolling shutter whose rows do not
            # converge): a new dataset that has no finished frame is removed, so the same
            # folder can be used again once the config is fixed.
            if fresh and not any((out / ".parts").glob("*.json")):
                _remove_unfinished(out)
                raise ConfigError(f"{exc} (nothing was kept in {out})") from None
            raise
    if cfg.sensor.video is not None:
        video_pass(cfg, cfg.sensor.video, plan, out, progress)
    parts = read_parts(out, plan)

    fdf, bdf, ldf = collect_tables(out, plan, parts)
    write_table(fdf, RunPaths(out).frames, "frames")
    write_table(bdf, RunPaths(out).beacons, "beacons")
    write_table(ldf, RunPaths(out).lights, "lights")
    if cfg.painted_ring is not None:
        rings = [row for doc in parts for row in doc.get("painted_ring", [])]
        rdf = typed_frame(rings, PAINTED_RING_COLUMNS).sort_values(["frame_id", "edge"], kind="stable")
        write_table(rdf.reset_index(drop=True), RunPaths(out).painted_ring, "painted ring")
    _write_json(RunPaths(out).manifest, _manifest(cfg, plan, complete=True, detection=detection))
    if detection is not None:
        for path in write_rendered_detections(out, parts, detection):
            log.info("detections at render time: %s", path)
    log.info("dataset %s complete: %d frames", out, len(plan))
    return out
