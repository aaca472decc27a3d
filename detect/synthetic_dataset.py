"""A dataset of analytic-spot frames in the ``deckpose-dataset/1`` contract.

Not a rendering: each visible beacon is a pixel-integrated Gaussian
(:mod:`deckpose.detect.synthetic`) whose sigma matches the second moment of the
beacon's blurred disc (:func:`~deckpose.detect.synthetic.disc_spot_sigma_px`),
at the exact projected centre (:func:`deckpose.projection.project_layout`).
That makes the truth exact and the centroid Cramér–Rao bound computable, so the
detection stage can be tested and benchmarked without the renderer. Besides the
contract's columns, ``beacons.parquet`` carries ``spot_sigma_px`` and
``spot_flux_e`` (electrons in the sum of the colour channels) and the manifest a
``sensor`` block, which the benchmark uses for the bound.
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pandas as pd
from deckpose.detect.synthetic import SensorModel, disc_spot_sigma_px, render_spots

from deckpose.atomic_io import atomic_open, atomic_path
from deckpose.camera import CameraModel, preset
from deckpose.camera_info import write_camera_info
from deckpose.errors import ConfigError
from deckpose.layout import DeckLayout, layout_from_dict, layout_to_dict
from deckpose.pose import CameraPose, ShipPose
from deckpose.projection import project_layout
from deckpose.run_folder import (
    DATASET_FORMAT,
    RunPaths,
    frame_truth_row,
    image_relpath,
    manifest_cameras,
)
from deckpose.tables import write_table
from deckpose.typed_config import from_mapping, load_yaml


@dataclass(frozen=True)
class SyntheticDatasetConfig:
    """What :func:`write_synthetic_dataset` makes.

    Attributes
    ----------
    cameras : tuple of str
        Camera presets (:func:`deckpose.camera.preset`), or ``"WxH"`` for a
        small camera with the thesis focal angle.
    heights_m : tuple of float
        Camera heights above the deck.
    frames_per_config : int
        Frames per camera x height.
    max_tilt_deg : float
        Roll and pitch drawn uniformly in ``[-max, max]``; yaw in ``[-180, 180)``.
    psf_sigma_px : float
        Optical blur, pixels.
    radiance_e_per_px : float
        Electrons per pixel (per colour channel at weight 1) inside a beacon's disc.
    colour : bool
        RGB frames (bow beacon red) or mono.
    glint_probability, hide_probability : float
        Chance per frame of one spurious glint, and of one hidden (non-bow) beacon.
    sensor : SensorModel
    layout : DeckLayout
    seed : int
    """

    cameras: tuple[str, ...] = ("4mp", "8mp")
    heights_m: tuple[float, ...] = (30.0, 60.0, 120.0, 200.0)
    frames_per_config: int = 3
    max_tilt_deg: float = 5.0
    psf_sigma_px: float = 0.7
    radiance_e_per_px: float = 3000.0
    colour: bool = True
    glint_probability: float = 0.0
    hide_probability: float = 0.0
    sensor: SensorModel = field(default_factory=SensorModel)
    layout: DeckLayout = field(default_factory=DeckLayout)
    seed: int = 0

    def __post_init__(self) -> None:
        if not self.cameras or not self.heights_m or self.frames_per_config < 1:
            raise ConfigError("need at least one camera, one height and frames_per_config >= 1")
        if any(not h > 0 for h in self.heights_m):
            raise ConfigError(f"heights_m must be positive, got {self.heights_m}")
        for p in (self.glint_probability, self.hide_probability):
            if not 0.0 <= p <= 1.0:
                raise ConfigError(f"probabilities must be in [0, 1], got {p}")
        if not (self.psf_sigma_px > 0 and self.radiance_e_per_px > 0):
            raise ConfigError("psf_sigma_px and radiance_e_per_px must be positive")


def config_from_dict(doc: object, source: str = "config") -> SyntheticDatasetConfig:
    """Parse a mapping (e.g. YAML) into a validated config, typed exactly; unknown keys are errors."""
    return from_mapping(SyntheticDatasetConfig, doc, f"{source}:",
                        convert={"layout": layout_from_dict})


def read_config(path: str | os.PathLike[str]) -> SyntheticDatasetConfig:
    """Read a synthetic-dataset YAML config."""
    return config_from_dict(load_yaml(path, "synthetic-dataset config"), str(path))


def _camera(name: str) -> CameraModel:
    if "x" in name and name.replace("x", "").isdigit():
        w, h = (int(s) for s in name.split("x"))
        return preset("8mp").with_size(w, h)
    return preset(name)


def summed_channels_sensor(sensor: SensorModel, n_channels: int) -> SensorModel:
    """Equivalent sensor of the sum of ``n_channels`` independent channels (for the CRB)."""
    if n_channels == 1:
        return sensor
    q = 1.0 / (12.0 * sensor.gain_dn_per_e**2)
    read = math.sqrt(n_channels * sensor.read_noise_e**2 + (n_channels - 1) * q)
    return dataclasses.replace(
        sensor, read_noise_e=read, background_e=n_channels * sensor.background_e
    )


def write_synthetic_dataset(
    config: SyntheticDatasetConfig, out_dir: str | os.PathLike[str]
) -> Path:
    """Write the dataset; returns its folder. Deterministic for a given config (seed)."""
    out = Path(out_dir)
    rng = np.random.default_rng(config.seed)
    lay = config.layout
    n = lay.n_beacons
    frame_rows, beacon_rows, cams = [], [], {}
    rgb_all = np.array(lay.beacon_rgb_all())
    fid = 0
    for cam_name in config.cameras:
        cam = _camera(cam_name)
        cam_key = cam_name.replace("/", "_")
        cams[cam_key] = cam
        write_camera_info(
            dataclasses.replace(cam, name=cam_key), RunPaths(out).camera_file(cam_key)
        )
        for h in config.heights_m:
            for _ in range(config.frames_per_config):
                roll, pitch = np.radians(rng.uniform(-config.max_tilt_deg, config.max_tilt_deg, 2))
                yaw = np.radians(rng.uniform(-180.0, 180.0))
                ship = ShipPose(roll, pitch, yaw, heave_m=float(rng.uniform(-1, 1)))
                cpose = CameraPose.nadir(h)
                pr = project_layout(lay, ship, cpose, cam)
                visible = pr.visible.copy()
                if rng.random() < config.hide_probability:
                    cand = [i for i in np.flatnonzero(visible) if i != lay.bow_id]
                    if cand:
                        visible[rng.choice(cand)] = False
                sig = disc_spot_sigma_px(
                    np.nan_to_num(pr.apparent_radius_px, nan=1.0), config.psf_sigma_px
                )
                flux = (
                    config.radiance_e_per_px * math.pi * np.nan_to_num(pr.apparent_radius_px) ** 2
                )
                pts, sg, fl, col = (
                    pr.points_px[visible],
                    sig[visible],
                    flux[visible],
                    rgb_all[visible],
                )
                if rng.random() < config.glint_probability:
                    g = _glint_position(cam, pr.points_px[pr.in_image], rng)
                    pts = np.vstack([pts, g])
                    glint_e = (
                        float(np.median(fl)) if fl.size else config.radiance_e_per_px * math.pi
                    )
                    sg, fl = np.append(sg, 1.0), np.append(fl, glint_e)
                    col = np.vstack([col, [1.0, 1.0, 1.0]])
                seed = int(rng.integers(2**31))
                frng = np.random.default_rng(seed)
                shape = (cam.height_px, cam.width_px)
                img = render_spots(
                    shape, pts, sg, fl, config.sensor, frng, rgb=col if config.colour else None
                )
                rel = image_relpath(fid)
                with atomic_path(out / rel) as tmp:
                    bgr = cv2.cvtColor(img, cv2.COLOR_RGB2BGR) if img.ndim == 3 else img
                    if not cv2.imwrite(str(tmp.with_suffix(".png")), bgr):
                        raise OSError(f"cannot write {out / rel}")
                    os.replace(tmp.with_suffix(".png"), tmp)
                frame_rows.append(
                    _frame_row(fid, rel, cam_key, h, ship, cpose, int(visible.sum()), seed)
                )
                chan_w = rgb_all.sum(axis=1) if config.colour else np.ones(n)
                for b in range(n):
                    beacon_rows.append(
                        {
                            "frame_id": fid,
                            "beacon_id": b,
                            "u_px": pr.points_px[b, 0],
                            "v_px": pr.points_px[b, 1],
                            "visible": bool(visible[b]),
                            "in_image": bool(pr.in_image[b]),
                            "facing": bool(pr.facing[b]),
                            "apparent_radius_px": float(pr.apparent_radius_px[b]),
                            "spot_sigma_px": float(sig[b]),
                            "spot_flux_e": float(flux[b] * chan_w[b]),
                        }
                    )
                fid += 1
    run = RunPaths(out)
    write_table(pd.DataFrame(frame_rows), run.frames, "frames")
    write_table(pd.DataFrame(beacon_rows), run.beacons, "beacons")
    manifest = {
        "format": DATASET_FORMAT,
        "generator": "deckpose.detect.synthetic_dataset (analytic Gaussian spots, NOT rendered)",
        "config": _config_dict(config),
        "seed": config.seed,
        "layout": layout_to_dict(lay),
        "cameras": manifest_cameras({k: dataclasses.replace(c, name=k) for k, c in sorted(cams.items())}),
        "sensor": dataclasses.asdict(config.sensor),
        "sensor_channels": 3 if config.colour else 1,
        "versions": {"numpy": np.__version__, "opencv": cv2.__version__},
    }
    with atomic_open(run.manifest, "w") as fh:
        json.dump(manifest, fh, indent=2)
    return out


def _config_dict(config: SyntheticDatasetConfig) -> dict[str, Any]:
    d = dataclasses.asdict(config)
    d["layout"] = layout_to_dict(config.layout)
    d["cameras"], d["heights_m"] = list(config.cameras), list(config.heights_m)
    return d


def _glint_position(
    cam: CameraModel, beacon_px: np.ndarray, rng: np.random.Generator
) -> np.ndarray:
    """A random in-image point at least 40 px from every beacon."""
    for _ in range(1000):
        p = rng.uniform([20, 20], [cam.width_px - 20, cam.height_px - 20])
        if beacon_px.size == 0 or np.min(np.linalg.norm(beacon_px - p, axis=1)) > 40:
            return p
    return np.array([20.0, 20.0])


def _frame_row(
    fid: int,
    rel: str,
    cam: str,
    h: float,
    ship: ShipPose,
    cpose: CameraPose,
    n_visible: int,
    seed: int,
) -> dict[str, Any]:
    return frame_truth_row(fid, rel, cam, fid * 100_000_000, fid * 0.1, h, ship, cpose, "synthetic-analytic",
                           seed, n_visible)
