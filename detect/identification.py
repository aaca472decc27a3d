"""The record and options of beacon identification, shared by its one-ring, two-ring and prior-pose forms."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from deckpose.errors import ConfigError, check_shape
from deckpose.records import UNASSIGNED

__all__ = ["Identification", "IdentifyOptions", "failed_identification"]


@dataclass(frozen=True)
class IdentifyOptions:
    """Options of :func:`~deckpose.detect.identify.identify_beacons`.

    Attributes
    ----------
    inlier_tol_px : float
        Floor of the ring-ellipse inlier distance, pixels.
    inlier_tol_frac : float
        Inlier distance as a fraction of the ellipse's mean semi-axis (the larger wins).
    assign_tol_frac : float
        A blob takes a predicted beacon position when closer than this fraction
        of the predicted spacing between neighbouring ring beacons.
    min_ring : int or None
        Fewest ring beacons to accept (None: ``max(5, n_ring - n_ring // 3)``).
    min_red_margin : float
        The bow's red share must exceed the median of the other ring blobs by this.
    max_ransac : int
        Most RANSAC samples (adaptive stopping usually needs far fewer; up to 100
        5-subsets are tried exhaustively).
    seed : int
        Seed of the RANSAC sampler (identification is deterministic per frame).
    max_axis_ratio : float or None
        RANSAC rejects ring ellipses more elongated than this (major over minor
        semi-axis); None: no limit. :func:`~deckpose.detect.two_ring_identify.identify_two_rings` sets it (see
        :data:`~deckpose.detect.two_ring_identify.TWO_RING_MAX_AXIS_RATIO`), where a thin ellipse through half of the
        outer ring, the inner ring and the centre can outnumber the outer ring.
    """

    inlier_tol_px: float = 2.0
    inlier_tol_frac: float = 0.005
    assign_tol_frac: float = 0.15
    min_ring: int | None = None
    min_red_margin: float = 0.15
    max_ransac: int = 1000
    seed: int = 0
    max_axis_ratio: float | None = None

    def __post_init__(self) -> None:
        if not (
            self.inlier_tol_px > 0 and self.inlier_tol_frac >= 0 and 0 < self.assign_tol_frac < 0.5
        ):
            raise ConfigError(
                "inlier_tol_px > 0, inlier_tol_frac >= 0 and 0 < assign_tol_frac < 0.5"
            )
        if self.max_axis_ratio is not None and not self.max_axis_ratio > 1:
            raise ConfigError(f"max_axis_ratio must be > 1 (or None: no limit), got {self.max_axis_ratio}")
        if self.min_ring is not None and self.min_ring < 5:
            raise ConfigError(
                f"min_ring must be >= 5 (a conic needs 5 points), got {self.min_ring}"
            )


@dataclass(frozen=True)
class Identification:
    """Beacon ids of a frame's detections; falsy with a ``reason`` if incomplete.

    Attributes
    ----------
    beacon_ids : (N,) array of int64
        Layout id per detection, ``UNASSIGNED`` (-1) for spurious or unidentified blobs.
    ok : bool
    reason : str
    ring_homography : (3, 3) array of float or None
        One-ring identification that got as far as the ring's homography: the map from
        the ring's deck plane (unit circle, slot ``k`` at angle ``2 pi k / n``) to
        undistorted pixels, so that the empty slots can be predicted
        (:mod:`~deckpose.detect.guided_look`); ``None`` otherwise.
    ring_slot : (N,) array of int64 or None
        With ``ring_homography``: each detection's slot on that unit circle
        (``UNASSIGNED``: off the ring), numbered from the blob the fit started at, not
        from the bow (which may be missing); the slots no detection holds are the
        ring's empty ones.
    """

    beacon_ids: NDArray[np.int64]
    ok: bool
    reason: str = ""
    ring_homography: NDArray[np.float64] | None = None
    ring_slot: NDArray[np.int64] | None = None

    def __post_init__(self) -> None:
        ids = np.array(self.beacon_ids, dtype=np.int64).reshape(-1)
        ids.setflags(write=False)
        object.__setattr__(self, "beacon_ids", ids)
        if (self.ring_homography is None) != (self.ring_slot is None):
            raise ValueError("Identification: ring_homography and ring_slot come together")
        if self.ring_homography is not None and self.ring_slot is not None:
            H = np.array(self.ring_homography, dtype=float)
            check_shape("ring_homography", H, (3, 3))
            slot = np.array(self.ring_slot, dtype=np.int64).reshape(-1)
            check_shape("ring_slot", slot, (ids.size,))
            H.setflags(write=False)
            slot.setflags(write=False)
            object.__setattr__(self, "ring_homography", H)
            object.__setattr__(self, "ring_slot", slot)

    def __bool__(self) -> bool:
        return self.ok


def failed_identification(n: int, reason: str, ids: NDArray[np.int64] | None = None) -> Identification:
    """A failed identification of ``n`` detections, saying why.

    Parameters
    ----------
    n : int
        Detections in the frame.
    reason : str
    ids : (n,) array of int64, optional
        The ids found so far (default: all ``UNASSIGNED``).
    """
    return Identification(np.full(n, UNASSIGNED) if ids is None else ids, False, reason)

