"""Pinhole camera with OpenCV distortion (standard or fisheye), and the thesis's camera presets.

Pixels follow OpenCV: ``u`` right, ``v`` down, pixel centres at integer
coordinates, ``(u, v) = K @ (x_d, y_d, 1)`` with ``(x_d, y_d)`` the distorted
normalised point of ``(x/z, y/z)``. The camera frame is OpenCV's: x right, y down,
z along the optical axis.

Distortion models (ROS names):

* ``plumb_bob`` and ``rational_polynomial``: OpenCV's standard model
  (:func:`cv2.projectPoints`), k1, k2, p1, p2[, k3[, k4, k5, k6]];
* ``equidistant``: OpenCV's fisheye model (:mod:`cv2.fisheye`, Kannala-Brandt with
  four coefficients): ``theta = atan(r)``, ``r = |(x/z, y/z)|``,
  ``theta_d = theta (1 + k1 theta^2 + k2 theta^4 + k3 theta^6 + k4 theta^8)`` and
  ``(x_d, y_d) = (theta_d / r) (x/z, y/z)``. It is never pinhole, even with k1..k4 = 0.
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass, field

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray

from deckpose.errors import ConfigError, check_shape

FloatArray = NDArray[np.float64]

#: Number of coefficients per distortion model name (ROS spelling), as camera files carry them.
DISTORTION_MODELS: dict[str, tuple[int, ...]] = {
    "plumb_bob": (5,),
    "rational_polynomial": (8,),
    "equidistant": (4,),
    "none": (0,),
}

#: The coefficient counts :class:`CameraModel` takes per model: the files' counts and OpenCV's
#: shorter forms (plumb_bob's k1, k2, p1, p2; none for no distortion). ``opencv`` is OpenCV's
#: standard model with thin-prism (12) or tilt (14) terms, which ROS does not name.
MODEL_COUNTS: dict[str, tuple[int, ...]] = {
    "plumb_bob": (5, 4, 0),
    "rational_polynomial": (8, 0),
    "equidistant": (4,),
    "opencv": (12, 14),
}

#: Model of a coefficient count when none is named; a fisheye must be named (``equidistant``).
_MODEL_OF_COUNT = {0: "plumb_bob", 4: "plumb_bob", 5: "plumb_bob", 8: "rational_polynomial",
                   12: "opencv", 14: "opencv"}

#: Newton iterations of the undistortion: enough for 1e-12 in normalised units.
_UNDISTORT_CRITERIA = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-14)
#: A fisheye undistortion is kept when re-projecting it lands this close to the pixel, pixels.
_FISHEYE_BACK_PX = 1e-6

#: The thesis's camera resolutions, (width_px, height_px).
THESIS_RESOLUTIONS: dict[str, tuple[int, int]] = {
    "4mp": (2312, 1734),
    "8mp": (3840, 2160),
    "16mp": (4624, 3468),
    "64mp": (9248, 6936),
}

#: The thesis's focal angle, degrees (eq. 1.8/1.9 and chapter 4).
THESIS_FOCAL_ANGLE_DEG = 75.0


class PixelForm(enum.Enum):
    """How a focal angle turns into focal lengths."""

    #: Thesis eq. 1.8/1.9: the angle applies to both axes, fx != fy (non-square pixels).
    THESIS = "thesis"
    #: Square pixels, the angle is the horizontal field of view.
    SQUARE = "square"


def _readonly(a: ArrayLike) -> FloatArray:
    out = np.array(a, dtype=float)
    out.setflags(write=False)
    return out


@dataclass(frozen=True)
class CameraModel:
    """Intrinsics of a camera with optional OpenCV lens distortion (standard or fisheye model).

    Attributes
    ----------
    width_px, height_px : int
        Image size in pixels.
    K : (3, 3) array of float
        Camera matrix ``[[fx, s, cx], [0, fy, cy], [0, 0, 1]]``, pixels.
    dist_coeffs : (D,) array of float
        OpenCV distortion coefficients: D = 0 (none), 4 or 5 (plumb_bob), 8
        (rational_polynomial), 12 or 14 (OpenCV's thin-prism and tilt terms), or 4
        (equidistant: k1..k4 of :mod:`cv2.fisheye`).
    name : str
        Free-form label (e.g. ``"8mp-thesis"``).
    distortion_model : str
        ROS name of the model: ``plumb_bob``, ``rational_polynomial``, ``equidistant``
        or ``none`` (stored as ``plumb_bob`` without coefficients); empty (the default)
        for the standard model the count implies (a fisheye must be named).
    """

    width_px: int
    height_px: int
    K: FloatArray
    dist_coeffs: FloatArray = field(default_factory=lambda: np.zeros(0))
    name: str = ""
    distortion_model: str = ""

    def __post_init__(self) -> None:
        if int(self.width_px) <= 0 or int(self.height_px) <= 0:
            raise ConfigError(
                f"camera size must be positive, got {self.width_px}x{self.height_px}"
            )
        K = _readonly(self.K)
        check_shape("K", K, (3, 3))
        if not np.isfinite(K).all() or K[0, 0] <= 0 or K[1, 1] <= 0:
            raise ConfigError(f"camera matrix needs finite, positive fx and fy, got\n{K}")
        if not np.allclose(K[2], [0.0, 0.0, 1.0]) or K[1, 0] != 0.0:
            raise ConfigError(f"camera matrix must be upper triangular with K[2] = [0,0,1], got\n{K}")
        d = _readonly(np.ravel(self.dist_coeffs))
        if not np.isfinite(d).all():
            raise ConfigError("distortion coefficients must be finite")
        model = str(self.distortion_model).strip().lower()
        if model == "none":
            if (d != 0.0).any():
                raise ConfigError(f"distortion model none takes no (or only zero) coefficients, got {d.size} "
                                  "with non-zero ones")
            model, d = "plumb_bob", _readonly(np.zeros(0))
        if not model:
            if d.size not in _MODEL_OF_COUNT:
                raise ConfigError(
                    f"distortion needs 0, 4, 5, 8, 12 or 14 coefficients (OpenCV), got {d.size}"
                )
            model = _MODEL_OF_COUNT[d.size]
        if model not in MODEL_COUNTS:
            raise ConfigError(
                f"unknown distortion model {model!r}; use one of {', '.join([*DISTORTION_MODELS])}"
            )
        if d.size not in MODEL_COUNTS[model]:
            counts = " or ".join(map(str, sorted(MODEL_COUNTS[model])))
            raise ConfigError(f"distortion model {model} takes {counts} coefficients, got {d.size}")
        object.__setattr__(self, "width_px", int(self.width_px))
        object.__setattr__(self, "height_px", int(self.height_px))
        object.__setattr__(self, "K", K)
        object.__setattr__(self, "dist_coeffs", d)
        object.__setattr__(self, "distortion_model", model)

    @property
    def fx(self) -> float:
        return float(self.K[0, 0])

    @property
    def fy(self) -> float:
        return float(self.K[1, 1])

    @property
    def cx(self) -> float:
        return float(self.K[0, 2])

    @property
    def cy(self) -> float:
        return float(self.K[1, 2])

    @property
    def is_fisheye(self) -> bool:
        """The equidistant (:mod:`cv2.fisheye`) model."""
        return self.distortion_model == "equidistant"

    @property
    def has_distortion(self) -> bool:
        """Pixels are not ``K @ (x/z, y/z, 1)``: non-zero coefficients, or a fisheye (always)."""
        return self.is_fisheye or bool((self.dist_coeffs != 0.0).any())

    def project(self, points_cam: ArrayLike) -> FloatArray:
        """Project camera-frame points to pixels, with distortion.

        Parameters
        ----------
        points_cam : (N, 3) array of float
            Points in the camera frame; z must be positive for a meaningful result.

        Returns
        -------
        (N, 2) array of float, pixels
        """
        P = np.asarray(points_cam, dtype=float)
        check_shape("points_cam", P, (None, 3))
        if P.shape[0] == 0:
            return np.zeros((0, 2))
        if not self.has_distortion:
            xy = P[:, :2] / P[:, 2:3]
            return xy @ self.K[:2, :2].T + self.K[:2, 2]
        if self.is_fisheye:
            # cv2.fisheye reads fx, fy, cx, cy from K and the skew from alpha = K[0,1] / fx
            uv, _ = cv2.fisheye.projectPoints(
                P.reshape(-1, 1, 3), np.zeros(3), np.zeros(3), self.K, self.dist_coeffs,
                alpha=self.K[0, 1] / self.K[0, 0],
            )
            return uv.reshape(-1, 2).astype(float)
        uv, _ = cv2.projectPoints(
            P.reshape(-1, 1, 3), np.zeros(3), np.zeros(3), self.K, self.dist_coeffs
        )
        return uv.reshape(-1, 2).astype(float)

    def undistort(self, points_px: ArrayLike) -> FloatArray:
        """Remove lens distortion: pixels in, ideal (undistorted) pixels out through the same K.

        Parameters
        ----------
        points_px : (N, 2) array of float

        Returns
        -------
        (N, 2) array of float, pixels
            NaN where no ray in front of the camera reaches the pixel (a fisheye pixel
            beyond the model's range, or one whose ray is 90 degrees or more off axis).
        """
        p = np.asarray(points_px, dtype=float)
        check_shape("points_px", p, (None, 2))
        if not self.has_distortion or p.shape[0] == 0:
            return p.copy()
        if self.is_fisheye:
            return self._undistort_fisheye(p)
        criteria = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-12)
        src = p.reshape(-1, 1, 2)
        undistort_iter = getattr(cv2, "undistortPointsIter", None)
        if undistort_iter is not None:  # OpenCV 4.x
            out = undistort_iter(src, self.K, self.dist_coeffs, None, self.K, criteria)
        else:  # OpenCV 5 folded the iterative variant into undistortPoints
            out = cv2.undistortPoints(src, self.K, self.dist_coeffs, R=None, P=self.K, criteria=criteria)
        return out.reshape(-1, 2).astype(float)

    def _undistort_fisheye(self, p: FloatArray) -> FloatArray:
        # K is removed here (cv2.fisheye.undistortPoints ignores the skew K[0,1]); its Newton
        # solve of theta_d(theta) is checked by projecting back, which also rejects a theta
        # past 90 degrees (tan changes sign) and pixels beyond a turning point of theta_d.
        Kinv = np.linalg.inv(self.K)
        xy_d = p @ Kinv[:2, :2].T + Kinv[:2, 2]
        eye = np.eye(3)
        xy = cv2.fisheye.undistortPoints(xy_d.reshape(-1, 1, 2), eye, self.dist_coeffs, R=eye, P=eye,
                                         criteria=_UNDISTORT_CRITERIA).reshape(-1, 2).astype(float)
        out = xy @ self.K[:2, :2].T + self.K[:2, 2]
        with np.errstate(invalid="ignore", over="ignore"):
            finite = np.isfinite(xy).all(axis=1) & (np.abs(xy) < 1e12).all(axis=1)
            back = np.full_like(p, np.nan)
            if finite.any():
                back[finite] = self.project(np.column_stack([xy[finite], np.ones(int(finite.sum()))]))
            good = finite & (np.abs(back - p) <= _FISHEYE_BACK_PX).all(axis=1)
        out[~good] = np.nan
        return out

    def in_image(self, points_px: ArrayLike) -> NDArray[np.bool_]:
        """Whether pixels lie inside the image, ``0 <= u <= W`` and ``0 <= v <= H``."""
        p = np.asarray(points_px, dtype=float)
        return (
            (p[..., 0] >= 0.0)
            & (p[..., 0] <= self.width_px)
            & (p[..., 1] >= 0.0)
            & (p[..., 1] <= self.height_px)
        )

    def pinhole(self) -> CameraModel:
        """The same ``K`` and size without lens distortion: the camera of undistorted pixels."""
        return CameraModel(self.width_px, self.height_px, self.K, np.zeros(0), self.name)

    def with_size(self, width_px: int, height_px: int) -> CameraModel:
        """The same field of view at another resolution (K scaled per axis)."""
        sx, sy = width_px / self.width_px, height_px / self.height_px
        K = self.K.copy()
        K[0] *= sx
        K[1] *= sy
        return CameraModel(width_px, height_px, K, self.dist_coeffs, self.name, self.distortion_model)


def from_focal_angle(
    width_px: int,
    height_px: int,
    focal_angle_deg: float = THESIS_FOCAL_ANGLE_DEG,
    *,
    form: PixelForm = PixelForm.THESIS,
    name: str = "",
) -> CameraModel:
    """A distortion-free camera from a focal angle, centred principal point.

    ``form=THESIS`` applies eq. 1.8/1.9 of the thesis: ``fx = (W/2)/tan(FA/2)``,
    ``fy = (H/2)/tan(FA/2)``. ``form=SQUARE`` uses ``fx = fy = (W/2)/tan(FA/2)``.
    """
    if not 0.0 < focal_angle_deg < 180.0:
        raise ConfigError(f"focal angle must be in (0, 180) degrees, got {focal_angle_deg}")
    t = math.tan(math.radians(focal_angle_deg) / 2.0)
    cx, cy = width_px / 2.0, height_px / 2.0
    fx = cx / t
    fy = cy / t if form is PixelForm.THESIS else fx
    K = np.array([[fx, 0.0, cx], [0.0, fy, cy], [0.0, 0.0, 1.0]])
    return CameraModel(width_px, height_px, K, np.zeros(0), name)


def preset(name: str) -> CameraModel:
    """A named camera preset.

    Names are ``"<res>"`` or ``"<res>-thesis"`` (non-square thesis form) and
    ``"<res>-square"`` with ``<res>`` one of ``4mp, 8mp, 16mp, 64mp``, plus
    ``"published"``: the 3840x2160, ``fx = fy = 1920/tan(50 deg)`` camera
    hard-coded in the thesis's published files.
    """
    key = name.strip().lower()
    if key == "published":
        f = 1920.0 / math.tan(math.radians(50.0))
        K = np.array([[f, 0.0, 1920.0], [0.0, f, 1080.0], [0.0, 0.0, 1.0]])
        return CameraModel(3840, 2160, K, np.zeros(0), "published")
    res, _, form = key.partition("-")
    if res not in THESIS_RESOLUTIONS or form not in ("", "thesis", "square"):
        raise ConfigError(
            f"unknown camera preset {name!r}; use one of {', '.join(preset_names())}"
        )
    w, h = THESIS_RESOLUTIONS[res]
    pform = PixelForm.SQUARE if form == "square" else PixelForm.THESIS
    return from_focal_angle(w, h, form=pform, name=f"{res}-{pform.value}")


def preset_names() -> list[str]:
    """All names :func:`preset` accepts (canonical spellings)."""
    names = [f"{r}-{f}" for r in THESIS_RESOLUTIONS for f in ("thesis", "square")]
    return names + ["published"]
