"""Detections turned into what the estimators fit: normalised, undistorted, whitened observations.

Every estimator in this package works in *normalised* camera coordinates
(distortion removed, ``K`` inverted), so non-square pixels, skew, any principal
point and lens distortion are handled once, here. Each observation carries the
square root of its information matrix in those coordinates, mapped from the
detection's pixel covariance through the local Jacobian of the camera model, so
a whitened residual ``L @ (predicted - observed)`` is distributed as N(0, I)
to first order.

Batch-first: :func:`group_observations` selects the usable detections of many frames,
undistorts every point with one OpenCV call and whitens them together; frames whose
usable detections carry the same beacon ids in the same order form a group
(:class:`Observations`) that the solvers handle together. With every beacon
identified a run is one group; a lone frame is a batch of one (:func:`observe_frame`).
"""

from __future__ import annotations

import functools
from collections.abc import Sequence
from dataclasses import dataclass
from functools import cached_property

import numpy as np
from deckpose.estimate.pose_model import TRANSLATION_SIGN
from numpy.typing import NDArray

from deckpose.camera import CameraModel
from deckpose.layout import DeckLayout
from deckpose.records import Detections

FloatArray = NDArray[np.float64]

#: Step of the central differences of the distortion model, normalised units.
_DIFF_STEP = 1e-6


@dataclass(frozen=True)
class Observations:
    """Identified beacons of ``F`` frames that share one beacon set, ready for fitting.

    Internal to the estimators; one frame is a batch of one (``F = 1``).

    Attributes
    ----------
    ids : (M,) array of int
        Layout id of each observation, the same for every frame.
    points_deck_m : (M, 3) array of float
        Layout position of each observation's beacon, deck frame, metres.
    xy : (F, M, 2) array of float
        Undistorted normalised image coordinates.
    sqrt_info : (F, M, 2, 2) or (F, 1, 2, 2) array of float
        ``L`` with ``L.T @ L`` the inverse covariance of ``xy`` (one per frame
        when it is the same for all points).
    px_from_norm : (F, M, 2, 2) or (F, 1, 2, 2) array of float
        Local Jacobian d(pixel)/d(normalised).
    R_world_from_cam : (F, 3, 3) array of float
        Camera attitude of each frame.
    """

    ids: NDArray[np.int64]
    points_deck_m: FloatArray
    xy: FloatArray
    sqrt_info: FloatArray
    px_from_norm: FloatArray
    R_world_from_cam: FloatArray

    def __len__(self) -> int:
        return int(self.xy.shape[0])

    @property
    def n_points(self) -> int:
        """Observations per frame, ``M``."""
        return int(self.ids.shape[0])

    @cached_property
    def R_cam_from_world(self) -> FloatArray:
        """``R_world_from_cam`` transposed, (F, 3, 3) (computed once: every iteration needs it)."""
        return self.R_world_from_cam.swapaxes(1, 2)

    @cached_property
    def translation_jacobian(self) -> FloatArray:
        """d(camera-frame point)/d(surge, sway, height), (F, 1, 3, 3): the same for every point."""
        return (self.R_cam_from_world * TRANSLATION_SIGN)[:, None]

    def take(self, rows: NDArray[np.int64]) -> Observations:
        """The frames ``rows`` (index array)."""
        return Observations(self.ids, self.points_deck_m, self.xy[rows], self.sqrt_info[rows],
                            self.px_from_norm[rows], self.R_world_from_cam[rows])

    def points(self, keep: NDArray[np.bool_] | NDArray[np.int64]) -> Observations:
        """The observations ``keep`` (a mask or index array over the ``M`` points) of every frame."""
        M = self.ids.shape[0]
        # (F, 1, 2, 2): one matrix serves every point and stays as it is
        return Observations(self.ids[keep], self.points_deck_m[keep], self.xy[:, keep],
                            self.sqrt_info if self.sqrt_info.shape[1] != M else self.sqrt_info[:, keep],
                            self.px_from_norm if self.px_from_norm.shape[1] != M else self.px_from_norm[:, keep],
                            self.R_world_from_cam)


def stack_frames(parts: Sequence[Observations]) -> Observations:
    """Observations of the same beacon set, frame after frame, as one batch.

    Parameters
    ----------
    parts : sequence of Observations
        Each of any number of frames; all with the same ``ids``.

    Returns
    -------
    Observations
        Their frames in order (``parts[0]`` itself when there is one). Where the parts
        differ in whether one whitening matrix serves every point, each is repeated per point.
    """
    if len(parts) == 1:
        return parts[0]
    first = parts[0]
    M = first.ids.shape[0]

    def cat(name: str) -> FloatArray:
        arrays = [getattr(p, name) for p in parts]
        if len({a.shape[1] for a in arrays}) > 1:
            arrays = [np.broadcast_to(a, (a.shape[0], M, 2, 2)) for a in arrays]
        return np.concatenate(arrays)

    return Observations(first.ids, first.points_deck_m, np.concatenate([p.xy for p in parts]), cat("sqrt_info"),
                        cat("px_from_norm"), np.concatenate([p.R_world_from_cam for p in parts]))


#: The 2x2 identity: the covariance a detection without its own carries ("unknown").
_EYE2 = np.eye(2)
_EYE2.setflags(write=False)


def pixel_covariances(covariance_px2: FloatArray, sigma_px: float, use_detection_covariance: bool
                      ) -> tuple[FloatArray, bool]:
    """One frame's pixel covariance of each detection, px^2: the one home of this rule.

    The detector's own covariances are used when ``use_detection_covariance`` and
    they are not all the identity (the :class:`~deckpose.records.Detections`
    default that means "unknown"); otherwise ``sigma_px**2 * I``.

    Parameters
    ----------
    covariance_px2 : (N, 2, 2) array of float
        The frame's detections' own covariances.
    sigma_px : float
    use_detection_covariance : bool

    Returns
    -------
    cov : (N, 2, 2) array of float
    own : bool
        Whether ``cov`` is the detections' own.
    """
    own = bool(use_detection_covariance and covariance_px2.shape[0] and not (covariance_px2 == _EYE2).all())
    if own:
        return covariance_px2, True
    return np.broadcast_to(_EYE2 * sigma_px**2, covariance_px2.shape), False


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


@dataclass(frozen=True)
class ObservationGroup:
    """Frames with one beacon set, and where they sit in the input.

    Attributes
    ----------
    frames : (F,) array of int
        Position of each frame in the input sequence.
    observations : Observations
    n_ignored : (F,) array of int
        Detections of each frame not used (unassigned, unknown id, non-finite).
    detection_rows : (F, M) array of int
        Row of each observation in its frame's :class:`~deckpose.records.Detections`.
    """

    frames: NDArray[np.int64]
    observations: Observations
    n_ignored: NDArray[np.int64]
    detection_rows: NDArray[np.int64]


@dataclass(frozen=True)
class StackedDetections:
    """All frames' detections concatenated (internal).

    Attributes
    ----------
    counts : (F,) array of int
        Detections per frame.
    starts : (F,) array of int
        Row of each frame's first detection.
    points_px : (T, 2) array of float
    beacon_ids : (T,) array of int
    covariance_px2 : (T, 2, 2) array of float
        As given (identity = unknown).
    """

    counts: NDArray[np.int64]
    starts: NDArray[np.int64]
    points_px: FloatArray
    beacon_ids: NDArray[np.int64]
    covariance_px2: FloatArray

    @property
    def frame_of(self) -> NDArray[np.int64]:
        """Frame of each detection, (T,)."""
        return np.repeat(np.arange(self.counts.size), self.counts)


def stack_detections(detections: Sequence[Detections]) -> StackedDetections:
    """Concatenate the frames' detections (no copies of the records' own arrays are kept)."""
    if len(detections) == 1:  # a lone frame: its arrays are the stack
        d = detections[0]
        return StackedDetections(np.array([len(d)], dtype=np.int64), np.zeros(1, dtype=np.int64),
                                 d.points_px, d.beacon_ids, d.covariance_px2)
    counts = np.fromiter((len(d) for d in detections), dtype=np.int64, count=len(detections))
    starts = np.zeros_like(counts)
    np.cumsum(counts[:-1], out=starts[1:])
    if counts.size == 0 or counts.sum() == 0:
        return StackedDetections(counts, starts, np.zeros((0, 2)), np.zeros(0, dtype=np.int64),
                                 np.zeros((0, 2, 2)))
    pts = np.concatenate([d.points_px for d in detections])
    ids = np.concatenate([d.beacon_ids for d in detections])
    cov = np.concatenate([d.covariance_px2 for d in detections])
    return StackedDetections(counts, starts, pts, ids, cov)


@functools.lru_cache(maxsize=16)
def _normalising_map(K_bytes: bytes) -> tuple[FloatArray, FloatArray]:
    """``(A, b)`` with ``xy = px @ A + b`` the normalised coordinates of pixels, for ``K`` as bytes (cached)."""
    Kinv = np.asarray(np.linalg.inv(np.frombuffer(K_bytes, dtype=np.float64).reshape(3, 3)), dtype=np.float64)
    A, b = Kinv[:2, :2].T.copy(), Kinv[:2, 2].copy()
    A.setflags(write=False)
    b.setflags(write=False)
    return A, b


def _per_frame_all(flags: NDArray[np.bool_], frame_of: NDArray[np.int64], n_frames: int) -> NDArray[np.bool_]:
    """Per frame: every flag of the frame's detections is True (True for a frame without any)."""
    bad = np.bincount(frame_of, weights=~flags, minlength=n_frames)
    return bad == 0


def group_observations(
    stacked: StackedDetections,
    camera: CameraModel,
    layout: DeckLayout,
    R_world_from_cam: FloatArray,
    *,
    sigma_px: float,
    use_detection_covariance: bool,
) -> list[ObservationGroup]:
    """Usable detections of every frame, whitened, grouped by beacon set.

    Frame by frame: a frame's detector covariances are used when ``use_detection_covariance``
    and not all of them are the identity, else ``sigma_px**2 * I``; detections
    with an unknown id, a non-finite point or (for non-isotropic frames) an
    invalid covariance are ignored.

    Parameters
    ----------
    stacked : StackedDetections
    camera : CameraModel
    layout : DeckLayout
    R_world_from_cam : (F, 3, 3) array of float
    sigma_px : float, keyword-only
    use_detection_covariance : bool, keyword-only

    Returns
    -------
    list of ObservationGroup
        Every frame in exactly one group (a frame without usable detections is
        in a group with ``M = 0``).
    """
    F = stacked.counts.size
    ids_all = stacked.beacon_ids
    pts_all = stacked.points_px
    raw = stacked.covariance_px2
    distorted = camera.has_distortion
    if F == 1:  # a lone frame: its own covariances or not, isotropic or not, without per-frame reductions
        frame_of = np.zeros(ids_all.size, dtype=np.int64)
        cov, own1 = pixel_covariances(raw, sigma_px, use_detection_covariance)
        c0 = cov[0] if ids_all.size else _EYE2
        iso1 = bool(ids_all.size and c0[0, 1] == 0.0 and c0[1, 0] == 0.0 and c0[0, 0] == c0[1, 1]
                    and 0.0 < c0[0, 0] < np.inf and (not own1 or (cov == c0).all()))
        iso = np.array([iso1])
        sigma_iso = np.array([np.sqrt(c0[0, 0]) if iso1 else np.nan])
    else:
        frame_of = stacked.frame_of
        own = use_detection_covariance & ~_per_frame_all((raw == _EYE2).all(axis=(1, 2)), frame_of, F)
        has_any = stacked.counts > 0
        own &= has_any
        any_own = bool(own.any())
        cov = raw if own.all() else np.where(own[frame_of, None, None], raw, _EYE2 * sigma_px**2)
        # One isotropic sigma for the whole frame (one whitening matrix for all its points).
        iso = np.zeros(F, dtype=bool)
        sigma_iso = np.full(F, np.nan)
        has = np.flatnonzero(has_any)
        if has.size and not any_own and 0.0 < sigma_px**2 < np.inf:  # every frame at sigma_px**2 * I
            iso[has] = True
            sigma_iso[has] = np.sqrt(sigma_px**2)
        elif has.size:
            c0 = cov[stacked.starts[has]]
            with np.errstate(invalid="ignore"):
                first_iso = ((c0[:, 0, 1] == 0.0) & (c0[:, 1, 0] == 0.0) & (c0[:, 0, 0] == c0[:, 1, 1])
                             & (c0[:, 0, 0] > 0) & np.isfinite(c0[:, 0, 0]))
            c0_full = np.zeros((F, 2, 2))
            c0_full[has] = c0
            same = _per_frame_all((cov == c0_full[frame_of]).all(axis=(1, 2)), frame_of, F)
            iso[has] = first_iso & same[has]
            sigma_iso[iso] = np.sqrt(c0_full[iso, 0, 0])
    keep = (ids_all >= 0) & (ids_all < layout.n_beacons) & np.isfinite(pts_all).all(axis=1)
    iso_point = iso[frame_of]
    if not iso_point.all():  # a frame with its own covariances: each must be a valid one
        with np.errstate(invalid="ignore"):
            a, b, c = cov[:, 0, 0], cov[:, 0, 1], cov[:, 1, 1]
            cov_ok = np.isfinite(cov).all(axis=(1, 2)) & (a > 0) & (a * c - b * b > 0) & (
                np.abs(cov[:, 1, 0] - b) <= 1e-9 * (np.abs(b) + a + c))
        keep &= iso_point | cov_ok
    index = np.flatnonzero(keep)
    fidx = frame_of[index]
    K = camera.K
    A_norm, b_norm = _normalising_map(np.ascontiguousarray(K, dtype=np.float64).tobytes())
    und = camera.undistort(pts_all[index]) if distorted else pts_all[index]
    xy = und @ A_norm + b_norm
    n = index.size
    K22 = K[:2, :2]
    if distorted and n:
        D = distortion_jacobian(camera, xy)
    else:
        D = np.broadcast_to(K22, (n, 2, 2))
    general = ~iso[fidx] | distorted
    if not general.any():  # one whitening matrix per frame
        L = K22[None] / sigma_iso[fidx, None, None]
    else:
        L = np.empty((n, 2, 2))
        fast = ~general
        L[fast] = K22[None] / sigma_iso[fidx[fast], None, None]
    if general.any():
        gi = np.flatnonzero(general)
        # 2x2 inverses where they exist: a point far outside the image (-8e170 px) makes a
        # distortion Jacobian singular, and one LinAlgError ended every frame of a batch
        Dg = np.asarray(D)[gi]
        det = Dg[:, 0, 0] * Dg[:, 1, 1] - Dg[:, 0, 1] * Dg[:, 1, 0]
        scale = np.abs(Dg).reshape(-1, 4).max(axis=1)
        with np.errstate(all="ignore"):
            invertible = np.isfinite(det) & (np.abs(det) > 1e-12 * scale**2)
            A = np.zeros_like(Dg)
            A[:, 0, 0], A[:, 1, 1] = Dg[:, 1, 1], Dg[:, 0, 0]
            A[:, 0, 1], A[:, 1, 0] = -Dg[:, 0, 1], -Dg[:, 1, 0]
            A /= np.where(invertible, det, 1.0)[:, None, None]
            cov_n = A @ cov[index[gi]] @ A.swapaxes(1, 2)
            cn_det = cov_n[:, 0, 0] * cov_n[:, 1, 1] - cov_n[:, 0, 1] * cov_n[:, 1, 0]
        ok = (invertible & np.isfinite(cov_n).all(axis=(1, 2)) & np.isfinite(xy[gi]).all(axis=1)
              & (cov_n[:, 0, 0] > 0) & (cn_det > 0))
        drop = gi[~ok]
        gi, cov_n = gi[ok], cov_n[ok]
        if gi.size:
            L[gi] = np.linalg.inv(np.linalg.cholesky(cov_n))
        if drop.size:
            sel = np.ones(n, dtype=bool)
            sel[drop] = False
            index, fidx, xy, D, L = index[sel], fidx[sel], xy[sel], np.asarray(D)[sel], L[sel]
            general = general[sel]
            n = index.size
    ids = ids_all[index]
    pos = layout_positions_m(layout)
    D = np.ascontiguousarray(D)
    if F == 1:  # a lone frame is its own group: no grouping, its arrays are the stack
        if ids.size and not general[0]:
            Lg, Dg = L[None, :1], D[None, :1]
        else:
            Lg, Dg = L[None], D[None]
        obs = Observations(ids, pos[ids], xy[None], Lg, Dg, R_world_from_cam)
        return [ObservationGroup(np.zeros(1, dtype=np.int64), obs, stacked.counts - ids.size, index[None])]
    used = np.bincount(fidx, minlength=F)
    first = np.zeros_like(used)
    np.cumsum(used[:-1], out=first[1:])
    groups: dict[bytes, list[int]] = {}
    for f in range(F):
        key = ids[first[f]:first[f] + used[f]].tobytes()
        groups.setdefault(key, []).append(f)
    out = []
    for key, members in groups.items():
        fr = np.array(members, dtype=np.int64)
        g_ids = np.frombuffer(key, dtype=np.int64).copy()
        M = g_ids.size
        rows = first[fr, None] + np.arange(M)[None, :]
        if M and not general[rows].any():
            # Linear camera, one isotropic sigma per frame: one whitening matrix per frame.
            Lg, Dg = L[rows[:, :1]], D[rows[:, :1]]
        else:
            Lg, Dg = L[rows], D[rows]
        obs = Observations(g_ids, pos[g_ids], xy[rows], Lg, Dg, R_world_from_cam[fr])
        out.append(ObservationGroup(fr, obs, stacked.counts[fr] - used[fr], index[rows] - stacked.starts[fr, None]))
    return out


def observe_frame(
    detections: Detections,
    camera: CameraModel,
    layout: DeckLayout,
    R_world_from_cam: FloatArray,
    *,
    sigma_px: float,
    use_detection_covariance: bool,
) -> ObservationGroup:
    """One frame's usable detections, whitened: :func:`group_observations` of a batch of one.

    Parameters
    ----------
    detections : Detections
    camera : CameraModel
    layout : DeckLayout
    R_world_from_cam : (3, 3) array of float
    sigma_px : float, keyword-only
    use_detection_covariance : bool, keyword-only

    Returns
    -------
    ObservationGroup
        ``F = 1``; possibly with no observation (``M = 0``). Never raises for bad
        values in ``detections``.
    """
    return group_observations(stack_detections([detections]), camera, layout,
                              np.asarray(R_world_from_cam, dtype=float)[None], sigma_px=sigma_px,
                              use_detection_covariance=use_detection_covariance)[0]
