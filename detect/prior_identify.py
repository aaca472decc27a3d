"""Identification from a prior pose: when no ring (or no bow) can be identified in the frame alone.

A frame whose bow beacons are out of view, or that shows too little of either ring
for its ellipse, cannot be identified by :func:`~deckpose.detect.identify.identify_beacons`.
With a prior relative pose ``T_cam_from_deck`` (the previous frame's estimate, carried
to this frame with the camera attitude the IMU gives now) every beacon of the layout is
projected and the detections are matched to the projections by a minimum-cost assignment
(:func:`scipy.optimize.linear_sum_assignment`) inside a gate.

The gate is a fraction (``gate_frac < 0.5``) of the smallest spacing between the
predicted beacons in view, so a detection lies within the gate of at most one
prediction. A prediction with two detections inside its gate (a glint beside a beacon)
is ambiguous: neither takes its id. The identification is ok with at least
``min_beacons`` matches. It is only as good as the prior: a prior off by more than the
gate leaves beacons unmatched (and the frame not ok), never matched to a neighbour;
the driver must pass a recent prior (see :func:`deckpose.sequence_estimate.estimate_sequence`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from deckpose.detect.identification import Identification
from numpy.typing import NDArray
from scipy.optimize import linear_sum_assignment

from deckpose.camera import CameraModel
from deckpose.errors import ConfigError, check_shape
from deckpose.layout import DeckLayout
from deckpose.records import UNASSIGNED

__all__ = ["PriorIdentifyOptions", "identify_with_prior", "predicted_beacons_px"]

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class PriorIdentifyOptions:
    """Options of :func:`identify_with_prior`.

    Attributes
    ----------
    gate_frac : float
        The gate, as a fraction of the smallest spacing between predicted beacons in
        view; below 0.5 so no detection can be in two gates.
    min_beacons : int
        Fewest matched beacons for an ok identification (PnP needs 4).
    """

    gate_frac: float = 0.3
    min_beacons: int = 4

    def __post_init__(self) -> None:
        if not 0.0 < self.gate_frac < 0.5:
            raise ConfigError(f"gate_frac must be in (0, 0.5) so a detection lies in at most one gate, "
                              f"got {self.gate_frac}")
        if int(self.min_beacons) < 4:
            raise ConfigError(f"min_beacons must be >= 4 (PnP's minimum), got {self.min_beacons}")


def predicted_beacons_px(
    layout: DeckLayout, camera: CameraModel, R_cam_from_deck: FloatArray, t_cam_from_deck: FloatArray
) -> tuple[FloatArray, NDArray[np.bool_]]:
    """Every beacon of the layout projected with a relative pose.

    Parameters
    ----------
    layout : DeckLayout
    camera : CameraModel
    R_cam_from_deck : (3, 3) array of float
    t_cam_from_deck : (3,) array of float, metres
        Deck centre in the camera frame.

    Returns
    -------
    points_px : (n_beacons, 2) array of float
        Distorted pixels (NaN behind the camera).
    in_view : (n_beacons,) array of bool
        In front of the camera and inside the image.
    """
    R = np.asarray(R_cam_from_deck, dtype=float)
    t = np.asarray(t_cam_from_deck, dtype=float).reshape(-1)
    check_shape("R_cam_from_deck", R, (3, 3))
    check_shape("t_cam_from_deck", t, (3,))
    P = layout.positions_deck_m() @ R.T + t
    front = P[:, 2] > 1e-9
    pts = np.full((P.shape[0], 2), np.nan)
    if np.any(front):
        pts[front] = camera.project(P[front])
    in_view = front & np.isfinite(pts).all(axis=1) & camera.in_image(np.nan_to_num(pts, nan=-1.0))
    return pts, in_view


def identify_with_prior(
    points_px: FloatArray,
    layout: DeckLayout,
    camera: CameraModel,
    R_cam_from_deck: FloatArray,
    t_cam_from_deck: FloatArray,
    *,
    options: PriorIdentifyOptions = PriorIdentifyOptions(),
) -> Identification:
    """Assign layout ids to detections by matching them to the beacons a prior pose predicts.

    Parameters
    ----------
    points_px : (N, 2) array of float
        Detected centres, distorted pixels.
    layout : DeckLayout
    camera : CameraModel
    R_cam_from_deck : (3, 3) array of float
        Prior relative attitude (deck to camera).
    t_cam_from_deck : (3,) array of float, metres
        Prior deck centre in the camera frame.
    options : PriorIdentifyOptions, keyword-only

    Returns
    -------
    Identification
        Falsy with a reason when fewer than ``options.min_beacons`` detections match.
    """
    pts = np.asarray(points_px, dtype=float)
    check_shape("points_px", pts, (None, 2))
    N = pts.shape[0]
    ids = np.full(N, UNASSIGNED, np.int64)
    pred, in_view = predicted_beacons_px(layout, camera, R_cam_from_deck, t_cam_from_deck)
    cand = np.flatnonzero(in_view)
    if cand.size < options.min_beacons:
        return Identification(ids, False, f"the prior pose puts only {cand.size} beacons in view; "
                                          f"need >= {options.min_beacons}")
    P = pred[cand]
    gaps = np.linalg.norm(P[:, None] - P[None], axis=2)
    spacing = float(np.min(gaps[~np.eye(cand.size, dtype=bool)]))
    gate = options.gate_frac * spacing
    usable = np.asarray(np.isfinite(pts).all(axis=1), dtype=bool)
    d = np.linalg.norm(np.where(usable.reshape(-1, 1), pts, np.inf)[:, None, :] - P[None], axis=2)
    inside: NDArray[np.bool_] = np.asarray(d < gate, dtype=bool)
    # two detections in one prediction's gate: which is the beacon is not known, so neither
    crowded = inside.sum(axis=0) > 1
    inside[:, crowded] = False
    if N and np.any(inside):
        cost = np.where(inside, d, gate * 1e3)
        rows, cols = linear_sum_assignment(cost)
        take = inside[rows, cols]
        ids[rows[take]] = cand[cols[take]]
    n_match = int(np.count_nonzero(ids >= 0))
    if n_match < options.min_beacons:
        extra = f" ({int(crowded.sum())} ambiguous: two blobs in one gate)" if crowded.any() else ""
        return Identification(ids, False, (
            f"only {n_match} blobs match the beacons the prior pose predicts within {gate:.1f} px{extra}; "
            f"need >= {options.min_beacons}"))
    return Identification(ids, True, "")
