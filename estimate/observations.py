"""Detections turned into what the estimators fit: normalised, undistorted, whitened observations.

Every estimator in this package works in *normalised* camera coordinates
(distortion removed, ``K`` inverted), so non-square pixels, skew, any principal
point and lens distortion are handled once, here. Each observation carries the
square root of its information matrix in those coordinates, mapped from the
detection's pixel covariance through the local Jacobian of the camera model, so
a whitened residual ``L @ (predicted - observed)`` is distributed as N(0, I)
to first order.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from deckpose.camera import CameraModel
from deckpose.layout import DeckLayout
from deckpose.records import Detections

FloatArray = NDArray[np.float64]

#: Step of the central differences of the distortion model, normalised units.
_DIFF_STEP = 1e-6


@dataclass(frozen=True)
class Observations:
    """Identified beacons ready for fitting (internal to the estimators).

    Attributes
    ----------
    ids : (N,) array of int
        Layout id of each observation.
    index : (N,) array of int
        Row of each observation in the source :class:`~deckpose.records.Detections`.
    points_deck_m : (N, 3) array of float
        Layout position of each observation's beacon, deck frame, metres.
    xy : (N, 2) array of float
        Undistorted normalised image coordinates.
    sqrt_info : (N, 2, 2) array of float
        ``L`` with ``L.T @ L`` the inverse covariance of ``xy``.
    px_from_norm : (N, 2, 2) array of float
        Local Jacobian d(pixel)/d(normalised), to express residuals in pixels.
    n_ignored : int
        Detections not used: unassigned, unknown id, non-finite point or covariance.
    """

    ids: NDArray[np.int64]
    index: NDArray[np.int64]
    points_deck_m: FloatArray
    xy: FloatArray
    sqrt_info: FloatArray
    px_from_norm: FloatArray
    n_ignored: int = 0

    def __len__(self) -> int:
        return int(self.ids.shape[0])

    def subset(self, keep: NDArray[np.bool_] | NDArray[np.int64]) -> Observations:
        """The observations selected by a boolean mask or an index array."""
        return Observations(
            self.ids[keep], self.index[keep], self.points_deck_m[keep], self.xy[keep],
            self.sqrt_info[keep], self.px_from_norm[keep], self.n_ignored,
        )


def pixel_covariances(detections: Detections, sigma_px: float, use_detection_covariance: bool) -> FloatArray:
    """The pixel covariance of each detection, px^2, shape (N, 2, 2).

    The detector's own covariances are used when ``use_detection_covariance`` and
    they are not all the identity (the :class:`~deckpose.records.Detections`
    default that means "unknown"); otherwise ``sigma_px**2 * I``.
    """
    cov = np.asarray(detections.covariance_px2, dtype=float)
    n = cov.shape[0]
    if use_detection_covariance and n and not np.all(cov == np.eye(2)):
        return cov
    return np.broadcast_to(np.eye(2) * sigma_px**2, (n, 2, 2))


def _common_isotropic_sigma(cov: np.ndarray) -> float | None:
    """``s`` when every covariance is ``s**2 * I`` with the same ``s > 0``, else None."""
    if cov.shape[0] == 0:
        return None
    c0 = cov[0]
    if not (c0[0, 1] == 0.0 and c0[1, 0] == 0.0 and c0[0, 0] == c0[1, 1] and c0[0, 0] > 0
            and np.isfinite(c0[0, 0]) and np.all(cov == c0)):
        return None
    return float(np.sqrt(c0[0, 0]))


@functools.lru_cache(maxsize=64)
def layout_positions_m(layout: DeckLayout) -> FloatArray:
    """The layout's beacon positions, deck frame, metres, (n_beacons, 3) (cached per layout)."""
    return layout.positions_deck_m()


def distortion_jacobian(camera: CameraModel, xy: FloatArray) -> FloatArray:
    """d(pixel)/d(normalised) at normalised points, (N, 2, 2), by central differences."""
    n = xy.shape[0]
    h = _DIFF_STEP
    offs = np.array([[h, 0.0], [-h, 0.0], [0.0, h], [0.0, -h]])
    pts = (xy[None, :, :] + offs[:, None, :]).reshape(-1, 2)
    px = camera.project(np.column_stack([pts, np.ones(len(pts))])).reshape(4, n, 2)
    D = np.empty((n, 2, 2))
    D[:, :, 0] = (px[0] - px[1]) / (2 * h)
    D[:, :, 1] = (px[2] - px[3]) / (2 * h)
    return D


def build_observations(
    detections: Detections,
    camera: CameraModel,
    layout: DeckLayout,
    *,
    sigma_px: float,
    use_detection_covariance: bool = True,
) -> Observations:
    """Select the identified detections and express them in normalised, whitened form.

    Parameters
    ----------
    detections : Detections
        Distorted pixel positions with ids and covariances.
    camera : CameraModel
    layout : DeckLayout
    sigma_px : float, keyword-only
        Pixel noise assumed when the detections carry no covariance.
    use_detection_covariance : bool, keyword-only

    Returns
    -------
    Observations
        Possibly empty; never raises for bad values in ``detections``.
    """
    ids_all = np.asarray(detections.beacon_ids, dtype=np.int64)
    pts_all = np.asarray(detections.points_px, dtype=float)
    cov_all = pixel_covariances(detections, sigma_px, use_detection_covariance)
    sigma_iso = _common_isotropic_sigma(cov_all)
    with np.errstate(invalid="ignore"):
        keep = (ids_all >= 0) & (ids_all < layout.n_beacons) & np.isfinite(pts_all).all(axis=1)
        if sigma_iso is None:
            a, b, c = cov_all[:, 0, 0], cov_all[:, 0, 1], cov_all[:, 1, 1]
            keep &= np.isfinite(cov_all).all(axis=(1, 2)) & (a > 0) & (a * c - b * b > 0) & (
                np.abs(cov_all[:, 1, 0] - b) <= 1e-9 * (np.abs(b) + a + c))
    index = np.flatnonzero(keep)
    ids = ids_all[index]
    P = layout_positions_m(layout)[ids]
    K = camera.K
    Kinv = np.linalg.inv(K)
    und = camera.undistort(pts_all[index]) if camera.has_distortion else pts_all[index]
    xy = und @ Kinv[:2, :2].T + Kinv[:2, 2]
    n = len(index)
    if not camera.has_distortion and sigma_iso is not None:
        # Fast path: linear camera, one isotropic noise level: one whitening matrix for all.
        D = np.broadcast_to(K[:2, :2], (n, 2, 2))
        L = np.broadcast_to(K[:2, :2] / sigma_iso, (n, 2, 2))
        return Observations(ids, index, P, xy, L, D, int(len(ids_all) - n))
    if camera.has_distortion and n:
        D = distortion_jacobian(camera, xy)
    else:
        D = np.broadcast_to(K[:2, :2], (n, 2, 2))
    A = np.linalg.inv(D) if len(index) else np.zeros((0, 2, 2))
    cov_n = A @ cov_all[index] @ np.swapaxes(A, 1, 2)
    # L = C^-1 with cov_n = C C^T (lower Cholesky) gives L^T L = cov_n^-1.
    ok = np.isfinite(cov_n).all(axis=(1, 2)) & np.isfinite(xy).all(axis=1)
    if not ok.all():
        index, ids, P, xy, cov_n, D = index[ok], ids[ok], P[ok], xy[ok], cov_n[ok], D[ok]
    if len(index):
        L = np.asarray(np.linalg.inv(np.linalg.cholesky(cov_n)), dtype=np.float64)
    else:
        L = np.zeros((0, 2, 2))
    return Observations(ids, index, P, xy, L, np.array(D), int(len(ids_all) - len(index)))
