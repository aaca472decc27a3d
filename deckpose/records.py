"""The records the pipeline stages exchange: render -> detect -> estimate -> evaluate.

Every record is a frozen dataclass whose arrays are shape-checked and made
read-only on construction. Ground truth is kept apart from what a detector or
estimator sees (:class:`Frame`, :class:`Detections`), so no stage can peek at it.
"""

from __future__ import annotations

import copy
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType

import numpy as np
from numpy.typing import NDArray

from deckpose.camera import CameraModel
from deckpose.errors import ShapeError, check_shape
from deckpose.pose import CameraPose, ShipPose

FloatArray = NDArray[np.float64]

#: Beacon id of a detection that has not been identified.
UNASSIGNED = -1


def _freeze(a: object, dtype: type | None = None) -> np.ndarray:
    arr = np.array(a, dtype=dtype)
    arr.setflags(write=False)
    return arr


def _read_only(state: dict[str, object]) -> dict[str, object]:
    """A record's pickled fields with its arrays read-only (unpickled arrays are writable)."""
    for v in state.values():
        if isinstance(v, np.ndarray):
            v.setflags(write=False)
    return state


@dataclass(frozen=True)
class Frame:
    """One camera image, as a detector sees it (render -> detect).

    Attributes
    ----------
    image : (H, W) or (H, W, 3) array of uint8 or uint16
        Pixel values; colour images are RGB.
    camera : CameraModel
    frame_id : int
    stamp_ns : int
        Capture time, integer nanoseconds on the motion time base.
    """

    image: np.ndarray
    camera: CameraModel
    frame_id: int = 0
    stamp_ns: int = 0

    def __post_init__(self) -> None:
        img = np.asarray(self.image)
        if img.ndim not in (2, 3) or (img.ndim == 3 and img.shape[2] != 3):
            raise ShapeError(f"image: expected (H, W) or (H, W, 3), got {img.shape}")
        if img.shape[:2] != (self.camera.height_px, self.camera.width_px):
            raise ShapeError(
                f"image is {img.shape[1]}x{img.shape[0]} but the camera is "
                f"{self.camera.width_px}x{self.camera.height_px}"
            )
        if not img.flags.writeable:
            object.__setattr__(self, "image", img)
        else:
            object.__setattr__(self, "image", _freeze(img))


@dataclass(frozen=True)
class GroundTruth:
    """Exact truth of one frame (render -> evaluate only).

    Attributes
    ----------
    ship : ShipPose
    camera_pose : CameraPose
    points_px : (N, 2) array of float
        Projected (distortion-aware) beacon centres, row = beacon id.
    visible : (N,) array of bool
    apparent_radius_px : (N,) array of float
    frame_id : int
    stamp_ns : int
    seed : int
    """

    ship: ShipPose
    camera_pose: CameraPose
    points_px: FloatArray
    visible: NDArray[np.bool_]
    apparent_radius_px: FloatArray
    frame_id: int = 0
    stamp_ns: int = 0
    seed: int = 0

    def __post_init__(self) -> None:
        pts = _freeze(self.points_px, float)
        n = pts.shape[0] if pts.ndim == 2 else -1
        check_shape("points_px", pts, (None, 2))
        check_shape("visible", np.asarray(self.visible), (n,))
        check_shape("apparent_radius_px", np.asarray(self.apparent_radius_px), (n,))
        object.__setattr__(self, "points_px", pts)
        object.__setattr__(self, "visible", _freeze(self.visible, bool))
        object.__setattr__(self, "apparent_radius_px", _freeze(self.apparent_radius_px, float))


@dataclass(frozen=True, init=False)
class Detections:
    """Beacon detections in one frame (detect -> estimate).

    Attributes
    ----------
    points_px : (N, 2) array of float
        Detected centres, distorted pixels as measured in the image.
    beacon_ids : (N,) array of int
        Layout id of each detection, :data:`UNASSIGNED` (-1) if not identified.
    covariance_px2 : (N, 2, 2) array of float
        Per-point covariance, px^2 (identity * sigma^2 when unknown).
    score : (N,) array of float
        Detector confidence or flux (larger = better).
    frame_id : int

    ``covariance_px2`` and ``score`` may be given as None (the defaults above); the
    record always holds arrays, hence its own ``__init__``.
    """

    points_px: FloatArray
    beacon_ids: NDArray[np.int64]
    covariance_px2: FloatArray
    score: FloatArray
    frame_id: int = 0

    def __init__(
        self,
        points_px: FloatArray,
        beacon_ids: NDArray[np.int64],
        covariance_px2: FloatArray | None = None,
        score: FloatArray | None = None,
        frame_id: int = 0,
    ) -> None:
        pts = _freeze(points_px, float)
        check_shape("points_px", pts, (None, 2))
        n = pts.shape[0]
        ids = _freeze(beacon_ids, np.int64)
        check_shape("beacon_ids", ids, (n,))
        cov = np.broadcast_to(np.eye(2), (n, 2, 2)) if covariance_px2 is None else covariance_px2
        cov = _freeze(cov, float)
        check_shape("covariance_px2", cov, (n, 2, 2))
        score = np.ones(n) if score is None else score
        score = _freeze(score, float)
        check_shape("score", score, (n,))
        object.__setattr__(self, "points_px", pts)
        object.__setattr__(self, "beacon_ids", ids)
        object.__setattr__(self, "covariance_px2", cov)
        object.__setattr__(self, "score", score)
        object.__setattr__(self, "frame_id", frame_id)

    def __len__(self) -> int:
        return int(self.points_px.shape[0])

    def __setstate__(self, state: dict[str, object]) -> None:
        """Unpickled (in a worker process) with its arrays read-only again."""
        self.__dict__.update(_read_only(state))


#: Order of the 6 pose parameters in :attr:`PoseEstimate.covariance`.
POSE_PARAMS = ("roll_rad", "pitch_rad", "yaw_rad", "surge_m", "sway_m", "height_m")


@dataclass(frozen=True)
class PoseEstimate:
    """The output of an estimator for one frame (estimate -> evaluate).

    A failed estimate is falsy and carries a ``reason``; its numbers are NaN.

    Attributes
    ----------
    method : str
    ok : bool
    reason : str
        Empty when ``ok``; otherwise why the estimate must not be trusted.
    roll_rad, pitch_rad, yaw_rad : float
        ZYX attitude of the deck in the world frame (NaN if unknown).
    height_m : float
        Height of the camera above the deck centre along world z (NaN if unknown).
    surge_m, sway_m : float
        Deck-centre displacement along world x, y (NaN when the method does not give them).
    covariance : (6, 6) array of float or None
        Covariance of :data:`POSE_PARAMS`.
    inliers : tuple of int
        Beacon ids used.
    extras : mapping of str to float
        Method-specific values (e.g. the thesis's own angles, ``thesis_roll_deg``).
    frame_id : int
        The frame estimated (its detections' ``frame_id``; set by the estimate stage).
    """

    method: str
    ok: bool
    reason: str = ""
    roll_rad: float = math.nan
    pitch_rad: float = math.nan
    yaw_rad: float = math.nan
    height_m: float = math.nan
    surge_m: float = math.nan
    sway_m: float = math.nan
    covariance: FloatArray | None = None
    inliers: tuple[int, ...] = ()
    extras: Mapping[str, float] = field(default_factory=dict)
    frame_id: int = 0

    def __post_init__(self) -> None:
        if self.ok and self.reason:
            raise ValueError("an ok PoseEstimate cannot carry a failure reason")
        if not self.ok and not self.reason:
            raise ValueError("a failed PoseEstimate needs a reason")
        if self.covariance is not None:
            cov = _freeze(self.covariance, float)
            check_shape("covariance", cov, (6, 6))
            object.__setattr__(self, "covariance", cov)
        object.__setattr__(self, "inliers", tuple(map(int, self.inliers)))
        object.__setattr__(self, "extras", MappingProxyType(dict(self.extras)))

    def __bool__(self) -> bool:
        return self.ok

    def __getstate__(self) -> dict[str, object]:
        """Pickled (to or from a worker process) with ``extras`` as a dict (a mapping proxy does not pickle)."""
        return {**self.__dict__, "extras": dict(self.extras)}

    def __setstate__(self, state: dict[str, object]) -> None:
        """Unpickled with ``extras`` read-only and its covariance read-only again."""
        self.__dict__.update(_read_only(state), extras=MappingProxyType(dict(state["extras"])))  # type: ignore[arg-type]

    @classmethod
    def failed(cls, method: str, reason: str, **extras: float) -> PoseEstimate:
        """A failed estimate with a reason."""
        return cls(method=method, ok=False, reason=reason, extras=extras)

    def for_frame(self, frame_id: int) -> PoseEstimate:
        """This estimate as that of frame ``frame_id``: a new record sharing the frozen fields.

        (A shallow copy: :func:`dataclasses.replace` would validate and freeze every
        field again, several times the cost of a batched estimate.)
        """
        if self.frame_id == frame_id:
            return self
        out = copy.copy(self)
        object.__setattr__(out, "frame_id", int(frame_id))
        return out

    def relabelled(self, method: str, extras: Mapping[str, float]) -> PoseEstimate:
        """This estimate under ``method`` with ``extras`` instead: a new record sharing the frozen fields.

        (A shallow copy, as :meth:`for_frame`: the refinement relabels every refined
        record with its estimator's name and extras, and :func:`dataclasses.replace`
        would validate and freeze every other field again.)
        """
        out = copy.copy(self)
        object.__setattr__(out, "method", str(method))
        object.__setattr__(out, "extras", MappingProxyType(dict(extras)))
        return out
