"""Cramér–Rao bound on the six pose parameters for a layout, camera, pose and pixel noise.

With Gaussian detection noise of covariance ``Sigma_i`` on each visible beacon's
pixel position, the Fisher information of the pose parameters
(:data:`deckpose.records.POSE_PARAMS`) is ``J^T Sigma^-1 J``, with ``J`` the
Jacobian of the (distorted) pixel positions; its inverse bounds the covariance
of every unbiased estimator. Computed with the same whitened model as the
estimators (exact: the distortion Jacobian cancels between ``J`` and ``Sigma``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from deckpose.estimate.least_squares import evaluate_fit
from deckpose.estimate.observations import observe_frame
from deckpose.estimate.pose_model import params_from_relative
from deckpose.estimate.registry import SIGMA_PX_RANGE
from numpy.typing import NDArray

from deckpose.camera import CameraModel
from deckpose.errors import ConfigError
from deckpose.layout import DeckLayout
from deckpose.pose import CameraPose, ShipPose, T_cam_from_deck
from deckpose.projection import project_layout
from deckpose.records import POSE_PARAMS, Detections

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class CramerRaoBound:
    """The bound for one configuration.

    Attributes
    ----------
    covariance : (6, 6) array of float
        Inverse Fisher information, order :data:`~deckpose.records.POSE_PARAMS`
        (radians, metres). NaN if the visible beacons do not determine the pose.
    visible_ids : tuple of int
        Beacons that entered the bound.
    sigma_px : float
        Isotropic pixel noise assumed (NaN when per-point covariances were given).
    """

    covariance: FloatArray
    visible_ids: tuple[int, ...]
    sigma_px: float

    @property
    def sigma(self) -> dict[str, float]:
        """Lower bound on the standard deviation of each parameter (rad or m)."""
        return {n: float(np.sqrt(v)) for n, v in zip(POSE_PARAMS, np.diag(self.covariance))}

    @property
    def ok(self) -> bool:
        return bool(np.all(np.isfinite(self.covariance)))


def cramer_rao_bound(
    layout: DeckLayout,
    camera: CameraModel,
    ship: ShipPose,
    camera_pose: CameraPose,
    sigma_px: float,
    *,
    covariance_px2: FloatArray | None = None,
    visible_only: bool = True,
) -> CramerRaoBound:
    """Cramér–Rao bound of the pose parameters.

    Parameters
    ----------
    layout : DeckLayout
    camera : CameraModel
    ship : ShipPose
        True deck pose.
    camera_pose : CameraPose
        True camera pose; its attitude is taken as known (as the estimators do).
    sigma_px : float
        Isotropic pixel noise standard deviation, pixels.
    covariance_px2 : (n_beacons, 2, 2) array of float, keyword-only, optional
        Per-beacon pixel covariance instead of ``sigma_px``.
    visible_only : bool, keyword-only
        Use only beacons inside the image and facing the camera.

    Returns
    -------
    CramerRaoBound
    """
    lo, hi = SIGMA_PX_RANGE
    if not lo <= sigma_px <= hi:
        raise ConfigError(f"sigma_px must be a pixel noise between {lo:g} and {hi:g} px, got {sigma_px}")
    proj = project_layout(layout, ship, camera_pose, camera)
    use = proj.visible if visible_only else np.isfinite(proj.points_px).all(axis=1)
    ids = np.flatnonzero(use)
    if covariance_px2 is None:
        cov = np.broadcast_to(np.eye(2) * sigma_px**2, (len(ids), 2, 2))
    else:
        cov_all = np.asarray(covariance_px2, dtype=float)
        if cov_all.shape != (layout.n_beacons, 2, 2):
            raise ConfigError(
                f"covariance_px2 must have shape ({layout.n_beacons}, 2, 2), got {cov_all.shape}")
        cov = cov_all[ids]
    det = Detections(proj.points_px[ids], ids, cov)
    R_wc = camera_pose.R_world_from_cam
    obs = observe_frame(det, camera, layout, R_wc, sigma_px=sigma_px, use_detection_covariance=True).observations
    T = T_cam_from_deck(ship, camera_pose)
    params = params_from_relative(T[:3, :3], T[:3, 3], R_wc)
    cov, ok = evaluate_fit(params[None], obs).covariance()
    out = cov[0] if ok[0] and obs.n_points >= 3 else np.full((6, 6), np.nan)
    return CramerRaoBound(out, tuple(int(i) for i in obs.ids),
                          float(sigma_px) if covariance_px2 is None else float("nan"))
