"""The thesis's estimator (Algorithm 2), faithfully, vectorised over frames.

This is the port of the published implementation as specified in
``docs/THESIS_IMPLEMENTATION.md`` ("The estimator, step by step"),
including its quirks (the 90-degree turn of the orthographic projection, the
mixing of distorted and undistorted quantities in the minor-axis point, and
the quaternion formulas exactly as printed). Where the original produces NaN,
complex numbers or a silently wrong answer, this port returns ``ok = False``
with a reason code instead (see :data:`REASONS`).

Inputs are centred image coordinates ``X' = u - cx`` (right) and
``Y' = cy - v`` (up), pixels, with the bow beacon in column 0.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass

import numpy as np
from deckpose.estimate.conic_fit import fit_conic, ray_ellipse_distances
from numpy.typing import NDArray

from deckpose.errors import ShapeError

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

#: Round-off allowance before an acos/asin argument outside [-1, 1] counts as a failure.
_ARG_TOL = 1e-12


class Failure(enum.IntEnum):
    """Why the thesis estimator could not give a trustworthy answer for a frame."""

    OK = 0
    TOO_FEW_BEACONS = 1
    NO_BOW_BEACON = 2
    LEVEL_DECK = 3
    NOT_AN_ELLIPSE = 4
    CENTRE_OUTSIDE_ELLIPSE = 5
    MINOR_AXIS_ABOVE_RADIUS = 6
    ACOS_OUT_OF_RANGE = 7
    NON_FINITE = 8


#: Human-readable reason per :class:`Failure` code.
REASONS: dict[Failure, str] = {
    Failure.OK: "",
    Failure.TOO_FEW_BEACONS: "fewer than 5 beacons: the conic fit needs at least 5",
    Failure.NO_BOW_BEACON: "bow beacon not visible: the thesis method would take another beacon "
    "as the bow and get yaw wrong by a multiple of the beacon spacing",
    Failure.LEVEL_DECK: "level deck: the beacon conic is a circle, so its tilt (and the "
    "thesis's yaw/roll split) is undefined",
    Failure.NOT_AN_ELLIPSE: "the fitted conic is not a real ellipse",
    Failure.CENTRE_OUTSIDE_ELLIPSE: "the image centre is not inside the fitted ellipse: "
    "a beacon ray does not cross it twice",
    Failure.MINOR_AXIS_ABOVE_RADIUS: "acos of a value above 1: the undistorted minor "
    "semi-axis exceeds the ring radius",
    Failure.ACOS_OUT_OF_RANGE: "acos argument outside [-1, 1] in the bow-beacon angle",
    Failure.NON_FINITE: "non-finite intermediate result",
}


@dataclass(frozen=True)
class ThesisResult:
    """Output of :func:`thesis_algorithm`; all arrays have shape (F,).

    Attributes
    ----------
    ok : array of bool
    failure : array of int
        :class:`Failure` code per frame (0 when ok).
    roll_deg, pitch_deg, yaw_deg : array of float
        The thesis's angles (``R = Rx(roll) Ry(pitch) Rz(yaw)``), degrees; NaN if not ok.
    height : array of float
        Camera height above the deck centre, ring units; NaN if not ok.
    yz2 : array of float
        ``Y''_z``, whose sign picks the direction of beta (Table 4.14).
    alpha_deg, beta_deg, gamma_deg : array of float
        The ZXZ angles of step 5.
    """

    ok: BoolArray
    failure: NDArray[np.int64]
    roll_deg: FloatArray
    pitch_deg: FloatArray
    yaw_deg: FloatArray
    height: FloatArray
    yz2: FloatArray
    alpha_deg: FloatArray
    beta_deg: FloatArray
    gamma_deg: FloatArray

    def reason(self, i: int) -> str:
        """The failure reason of frame ``i`` ("" when ok)."""
        return REASONS[Failure(int(self.failure[i]))]


def _set_failure(failure: NDArray[np.int64], cond: BoolArray, code: Failure) -> None:
    failure[(failure == 0) & cond] = int(code)


def thesis_algorithm(
    points_c: FloatArray, mask: BoolArray, fx: float, fy: float, radius: float
) -> ThesisResult:
    """Run the thesis's Algorithm 2 on many frames at once.

    Parameters
    ----------
    points_c : (F, N, 2) array of float
        Centred image coordinates ``(X', Y')`` per frame and beacon, pixels;
        column 0 is the bow beacon. Entries where ``mask`` is False are ignored.
    mask : (F, N) array of bool
        Which beacons are visible.
    fx, fy : float
        Focal lengths, pixels.
    radius : float
        Ring radius r (sets the unit of the height).

    Returns
    -------
    ThesisResult
    """
    P = np.asarray(points_c, dtype=float)
    m = np.asarray(mask, dtype=bool)
    if P.ndim != 3 or P.shape[2] != 2 or m.shape != P.shape[:2]:
        raise ShapeError(f"points_c must be (F, N, 2) and mask (F, N); got {P.shape} and {m.shape}")
    F = P.shape[0]
    r = float(radius)
    m = m & np.logical_and.reduce(np.isfinite(P), axis=2)
    X = np.where(m, P[..., 0], 0.0)
    Y = np.where(m, P[..., 1], 0.0)
    failure = np.zeros(F, dtype=np.int64)
    _set_failure(failure, m.sum(axis=1) < 5, Failure.TOO_FEW_BEACONS)
    _set_failure(failure, ~m[:, 0], Failure.NO_BOW_BEACON)

    with np.errstate(all="ignore"):
        # Step 1: distorted conic.
        c1 = fit_conic(X, Y, m)
        _set_failure(failure, c1.circle, Failure.LEVEL_DECK)
        _set_failure(failure, ~c1.ok, Failure.NOT_AN_ELLIPSE)
        k, h = c1.k[:, None], c1.h[:, None]
        Ma, Mi = c1.major[:, None], c1.minor[:, None]

        # Step 2: per-beacon 3-D reconstruction.
        norm = np.hypot(X, Y)
        Vx, Vy = X / norm, Y / norm
        L1, L2 = ray_ellipse_distances(Vx, Vy, k, h, c1.tilt_rad[:, None], Ma, Mi)
        miss = m & ~(np.isfinite(L1) & np.isfinite(L2) & (L1 > 0) & (L2 < 0))
        _set_failure(failure, miss.any(axis=1), Failure.CENTRE_OUTSIDE_ELLIPSE)
        d = L1 - L2
        Xb = -2.0 * Vy * L1 * L2 / (fy * d)
        Yb = 2.0 * Vx * L1 * L2 / (fx * d)
        Zb = -(L1 + L2) / d
        nb = np.sqrt(Xb * Xb + Yb * Yb + Zb * Zb)
        heights = r / nb
        P3 = r * np.stack([Xb, Yb, Zb], axis=-1) / nb[..., None]
        n_vis = np.maximum(m.sum(axis=1), 1)
        height = np.where(m, heights, 0.0).sum(axis=1) / n_vis

        # Step 3: undistorted conic of the orthographic projection, turned by 90 deg.
        c2 = fit_conic(np.where(m, -P3[..., 1], 0.0), np.where(m, P3[..., 0], 0.0), m)
        _set_failure(failure, c2.circle, Failure.LEVEL_DECK)
        _set_failure(failure, ~c2.ok, Failure.NOT_AN_ELLIPSE)
        Mi_u = c2.minor
        tu = c2.tilt_rad

        # Step 4: minor-axis point (distorted Mi', k, h with the undistorted tilt).
        wx = c1.minor * np.sin(tu) + c1.k
        wy = c1.minor * np.cos(tu) + c1.h
        wn = np.hypot(wx, wy)
        M1, M2 = ray_ellipse_distances(wx / wn, wy / wn, c1.k, c1.h, tu, c1.major, c1.minor)
        _set_failure(failure, ~(np.isfinite(M1) & np.isfinite(M2)), Failure.CENTRE_OUTSIDE_ELLIPSE)
        yz2 = np.sign(tu) * (-(M1 + M2) / (M1 - M2))

        # Step 5: ZXZ angles.
        phi = np.sign(tu) * (np.pi / 2.0 - np.abs(tu))
        Pma = np.stack([r * np.cos(phi), r * np.sin(phi), np.zeros(F)], axis=-1)
        Pbow = P3[:, 0, :]
        cos_beta = Mi_u / r
        _set_failure(failure, ~(cos_beta <= 1.0), Failure.MINOR_AXIS_ABOVE_RADIUS)
        beta = np.sign(yz2) * np.arccos(np.clip(cos_beta, -1.0, 1.0))
        dist2 = np.sum((Pma - Pbow) ** 2, axis=-1)
        cos_g = 1.0 - dist2 / (2.0 * r * r)
        _set_failure(failure, ~(np.abs(cos_g) <= 1.0 + _ARG_TOL), Failure.ACOS_OUT_OF_RANGE)
        gamma = -np.sign(yz2) * np.sign(Pbow[:, 2]) * np.arccos(np.clip(cos_g, -1.0, 1.0))
        alpha = phi

        # Step 6: quaternion (exactly as printed) -> thesis roll, pitch, yaw.
        A2, B2, G2 = alpha / 2.0, beta / 2.0, gamma / 2.0
        cA, sA, cB, sB, cG, sG = np.cos(A2), np.sin(A2), np.cos(B2), np.sin(B2), np.cos(G2), np.sin(G2)
        q0 = cG * cB * cA - sG * cB * sA
        q1 = cG * sB * cA + sG * sB * sA
        q2 = sG * sB * cA - cG * sB * sA
        q3 = cG * cB * sA + sG * cB * cA
        roll = np.arctan2(2.0 * (q0 * q1 + q2 * q3), 1.0 - 2.0 * (q1 * q1 + q2 * q2))
        pitch = -np.arcsin(np.clip(2.0 * (q0 * q2 - q3 * q1), -1.0, 1.0))
        yaw = np.arctan2(2.0 * (q0 * q3 + q1 * q2), 1.0 - 2.0 * (q2 * q2 + q3 * q3))

    out = np.stack([roll, pitch, yaw, height], axis=1)
    _set_failure(failure, ~np.logical_and.reduce(np.isfinite(out), axis=1), Failure.NON_FINITE)
    ok = failure == 0
    nan = np.nan

    def _mask(a: FloatArray) -> FloatArray:
        return np.where(ok, a, nan)

    return ThesisResult(
        ok=ok,
        failure=failure,
        roll_deg=_mask(np.degrees(roll)),
        pitch_deg=_mask(np.degrees(pitch)),
        yaw_deg=_mask(np.degrees(yaw)),
        height=_mask(height),
        yz2=_mask(yz2),
        alpha_deg=_mask(np.degrees(alpha)),
        beta_deg=_mask(np.degrees(beta)),
        gamma_deg=_mask(np.degrees(gamma)),
    )
