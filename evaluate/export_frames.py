"""A run's frames with their exact truth, as the dataset exporters (BOP, COCO) read them.

One record for the whole run, batch-first: the frames in ``frame_id`` order, where each
image is, which camera took it, the deck pose relative to the camera
(``T_cam_from_deck``, from the frames table's ship and camera poses) and every beacon's
projected centre with the flags ``beacons.parquet`` gives it. Everything is read through
:mod:`deckpose.run_folder`; a run whose tables disagree, or whose images are missing, is
one :class:`~deckpose.errors.InputDataError`.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from deckpose import run_folder as rl
from deckpose.camera import CameraModel
from deckpose.errors import InputDataError, check_shape
from deckpose.layout import DeckLayout
from deckpose.pose import T_cam_from_deck
from deckpose.shell_command import deckpose_command

__all__ = ["ExportFrames", "deck_half_size_m", "read_export_frames"]


def _ro(a: np.ndarray) -> np.ndarray:
    out = np.array(a)
    out.setflags(write=False)
    return out


@dataclass(frozen=True)
class ExportFrames:
    """The frames of a run and their truth.

    Attributes
    ----------
    frame_id : (F,) array of int
        Frame ids, ascending.
    camera : tuple of F str
        Camera name of each frame (a key of ``cameras``).
    image_path : tuple of F Path
        Each frame's image file (inside the run folder).
    image_relpath : tuple of F str
        The same, relative to the run folder (``images/000042.png``).
    T_cam_from_deck : (F, 4, 4) array of float, metres
        Deck pose relative to the (OpenCV) camera at the frame's mid-exposure.
    points_px : (F, N, 2) array of float, pixels
        Each beacon's projected centre (lens distortion included), ``(u, v)``, OpenCV's
        pixel convention (pixel centres at integers); NaN where behind the camera.
    in_image : (F, N) array of bool
        The centre lies in the image (``beacons.parquet``'s ``in_image``).
    facing : (F, N) array of bool
        The camera sees the beacon's lit side (``facing``).
    cameras : dict of str to CameraModel
    layout : DeckLayout
        ``N = layout.n_beacons``; beacon id ``i`` is column ``i``.
    manifest : dict
        The run's manifest as read.
    """

    frame_id: NDArray[np.int64]
    camera: tuple[str, ...]
    image_path: tuple[Path, ...]
    image_relpath: tuple[str, ...]
    T_cam_from_deck: NDArray[np.float64]
    points_px: NDArray[np.float64]
    in_image: NDArray[np.bool_]
    facing: NDArray[np.bool_]
    cameras: dict[str, CameraModel]
    layout: DeckLayout
    manifest: dict[str, Any]

    def __post_init__(self) -> None:
        f, n = len(self.frame_id), self.layout.n_beacons
        check_shape("frame_id", np.asarray(self.frame_id), (f,))
        check_shape("T_cam_from_deck", np.asarray(self.T_cam_from_deck), (f, 4, 4))
        check_shape("points_px", np.asarray(self.points_px), (f, n, 2))
        check_shape("in_image", np.asarray(self.in_image), (f, n))
        check_shape("facing", np.asarray(self.facing), (f, n))
        for name in ("camera", "image_path", "image_relpath"):
            if len(getattr(self, name)) != f:
                raise InputDataError(f"ExportFrames.{name} needs {f} entries, got {len(getattr(self, name))}")
        for name in ("frame_id", "T_cam_from_deck", "points_px", "in_image", "facing"):
            object.__setattr__(self, name, _ro(getattr(self, name)))

    @property
    def n_frames(self) -> int:
        return len(self.frame_id)

    @property
    def visible(self) -> NDArray[np.bool_]:
        """In the image and facing the camera, (F, N)."""
        return self.in_image & self.facing


def read_export_frames(run: rl.RunPaths) -> ExportFrames:
    """Read a run's frames, poses, beacon truth, cameras and layout for an export.

    Raises
    ------
    InputDataError
        When ``run`` is not a run folder, its beacons table does not have one row per
        frame and beacon, a frame names a camera with no camera file, or an image is missing.
    """
    manifest = rl.read_manifest(run)
    layout = rl.read_layout(run)
    frames = rl.read_frames(run).sort_values("frame_id", kind="stable").reset_index(drop=True)
    beacons = rl.read_beacons(run)
    if frames.empty:
        raise InputDataError(f"{run.frames} has no frames; nothing to export")
    ids = frames["frame_id"].to_numpy(np.int64)
    if len(np.unique(ids)) != len(ids):
        raise InputDataError(f"{run.frames} repeats frame ids; remake the run with deckpose render")
    cameras = rl.read_cameras(run, sorted(set(frames["camera"].astype(str))))
    n = layout.n_beacons
    b = beacons[beacons["frame_id"].isin(ids)]
    if len(b) != len(ids) * n or set(b["beacon_id"].astype(int)) - set(range(n)):
        raise InputDataError(
            f"{run.beacons} should have one row per frame and beacon id 0..{n - 1} "
            f"({len(ids)} x {n} rows), found {len(b)}; remake the run with deckpose render")
    b = b.sort_values(["frame_id", "beacon_id"], kind="stable")
    if not np.array_equal(b["frame_id"].to_numpy(np.int64).reshape(-1, n)[:, 0], ids) or \
            not np.array_equal(b["beacon_id"].to_numpy(np.int64).reshape(-1, n),
                               np.tile(np.arange(n), (len(ids), 1))):
        raise InputDataError(f"{run.beacons}: each frame needs beacon ids 0..{n - 1} once each")
    points = b[["u_px", "v_px"]].to_numpy(float).reshape(-1, n, 2)
    in_image = b["in_image"].to_numpy(bool).reshape(-1, n)
    facing = b["facing"].to_numpy(bool).reshape(-1, n)
    T = np.stack([T_cam_from_deck(*rl.frame_poses(row)) for _, row in frames.iterrows()])
    rel = tuple(str(r) for r in frames["image"])
    if not all(rel):
        raise InputDataError(
            f"{run.root} keeps no frames (rendered with --no-images: detections and previews only), so "
            f"it cannot be exported; render it again without --no-images: deckpose render CONFIG.yaml DIR")
    paths = tuple(run.root / r for r in rel)
    missing = [str(p) for p in paths if not p.is_file()]
    if missing:
        raise InputDataError(
            f"{len(missing)} of {len(paths)} images are missing (e.g. {missing[0]}); "
            f"render them again with: {deckpose_command('render', 'CONFIG.yaml', run.root)}")
    return ExportFrames(ids, tuple(str(c) for c in frames["camera"]), paths, rel, T, points,
                        in_image, facing, cameras, layout, manifest)


def deck_half_size_m(manifest: dict[str, Any], layout: DeckLayout) -> float:
    """Half the side of the square deck plate the run was rendered with, metres.

    The render config's rule (:meth:`deckpose.render.RenderConfig.deck_half_size_m`,
    1.4 x the ring radius unless the config sets it), applied to the config recorded in
    the manifest; a run without one (a synthetic dataset) gets the default.
    """
    from deckpose.render import RenderConfig, config_from_dict

    config = manifest.get("config")
    cfg = (config_from_dict(config, "manifest config") if isinstance(config, dict)
           else RenderConfig(cameras=(), heights_m=(), layout=layout))
    return cfg.deck_half_size_m()
