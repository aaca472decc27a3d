"""The lens after the pinhole raster: which raster a camera needs, and the warp into its image.

The deck and the sea are rasterised through a pinhole (OpenGL draws straight lines
straight); the lens comes after, as a ``cv2.remap``: every pixel of the distorted image
takes the raster at its own ray, found by :meth:`CameraModel.undistort
<deckpose.camera.CameraModel.undistort>`. So every model the camera knows (OpenCV's
standard model, its fisheye) warps the same way, and the raster agrees with
:meth:`~deckpose.camera.CameraModel.project`, which places the beacons and the ground truth.

The raster must hold every image pixel's ray. A barrel or fisheye lens sees further than
a pinhole with the same ``K`` and size, so :func:`raster_camera` grows the raster's canvas
around the rays at the camera's focal length, and lowers the focal length (coarser
background at the centre, never the beacons, which are drawn in the image itself) only
where the canvas would pass :data:`MAX_RASTER_AREA` times the image or the renderer's
:data:`MAX_SIDE_PX`. A ray 90 degrees or more off the axis has
no pinhole image at all, and one near it needs an unbounded canvas: a camera whose pixels
see rays beyond :data:`MAX_RAY_ANGLE_DEG` is refused.
"""

from __future__ import annotations

import math

import cv2
import numpy as np
from numpy.typing import NDArray

from deckpose.camera import CameraModel
from deckpose.errors import ConfigError, ShapeError

__all__ = ["MAX_RASTER_AREA", "MAX_RAY_ANGLE_DEG", "MAX_SIDE_PX", "distort", "distortion_maps",
           "raster_camera"]

#: Longest raster side the renderer takes, pixels: OpenGL's framebuffer limit on Mesa
#: (``GL_MAX_RENDERBUFFER_SIZE``; llvmpipe and most GPUs give 16384). The renderer draws
#: a frame in horizontal tiles, so the width must fit and tall frames get more tiles.
MAX_SIDE_PX = 16384
#: Widest ray off the optical axis a camera's pixels may see, degrees (a pinhole raster
#: holding a ray at angle a is tan(a) focal lengths wide: 5.7 at 80 degrees).
MAX_RAY_ANGLE_DEG = 80.0
#: Largest raster, as a multiple of the image's pixel count; past it the focal length drops.
MAX_RASTER_AREA = 4.0
#: Raster pixels kept beyond the outermost ray (bilinear interpolation reads one more).
_MARGIN_PX = 2
#: Image pixels undistorted at a time while the warp is built (bounded memory at 64 MP).
_CHUNK_PX = 2 ** 20

_RASTER_CACHE: dict[tuple[object, ...], CameraModel] = {}
_MAP_CACHE: dict[tuple[object, ...], tuple[np.ndarray, np.ndarray]] = {}


def _key(camera: CameraModel) -> tuple[object, ...]:
    return (camera.width_px, camera.height_px, camera.K.tobytes(), camera.dist_coeffs.tobytes(),
            camera.distortion_model)


def _rays(camera: CameraModel, points_px: NDArray[np.float64]) -> NDArray[np.float64]:
    """Normalised undistorted rays ``(x/z, y/z)`` of image pixels, (N, 2) (NaN where none)."""
    und = camera.undistort(points_px)
    y = (und[:, 1] - camera.cy) / camera.fy  # K^-1, written out (a (N,2)@(2,2) matmul is slow)
    x = (und[:, 0] - camera.cx - camera.K[0, 1] * y) / camera.fx
    return np.column_stack([x, y])


def _edge_px(width_px: int, height_px: int) -> NDArray[np.float64]:
    """Every pixel centre on the image's edge, (M, 2): the rays' extremes lie there."""
    u, v = np.arange(width_px, dtype=float), np.arange(height_px, dtype=float)
    W, H = width_px - 1.0, height_px - 1.0
    return np.concatenate([np.c_[u, np.zeros_like(u)], np.c_[u, np.full_like(u, H)],
                           np.c_[np.zeros_like(v), v], np.c_[np.full_like(v, W), v]])


def raster_camera(camera: CameraModel) -> CameraModel:
    """The pinhole camera to rasterise through so that every pixel of ``camera`` finds its ray.

    Parameters
    ----------
    camera : CameraModel

    Returns
    -------
    CameraModel
        ``camera`` itself without distortion; otherwise a distortion-free camera: ``camera.K``
        at the image size when that holds every ray, else a larger canvas (focal length kept
        up to :data:`MAX_RASTER_AREA`, lowered beyond), zero skew.

    Raises
    ------
    ConfigError
        If a pixel sees no ray in front of the camera, or one beyond :data:`MAX_RAY_ANGLE_DEG`.
    """
    if not camera.has_distortion:
        return camera
    key = _key(camera)
    if key in _RASTER_CACHE:
        return _RASTER_CACHE[key]
    W, H = camera.width_px, camera.height_px
    where = f"camera {camera.name}" if camera.name else f"the {W}x{H} {camera.distortion_model} camera"
    edge = _edge_px(W, H)
    xy = _rays(camera, edge)
    if not np.isfinite(xy).all():
        raise ConfigError(f"{where}: some of its edge pixels see no ray in front of the camera (90 "
                          f"deg or more off the optical axis, or past the range of its "
                          f"{camera.distortion_model} coefficients); a pinhole raster holds less than "
                          f"90 deg and deckpose renders up to {MAX_RAY_ANGLE_DEG:g} deg: use a smaller "
                          f"image or a longer focal length")
    angle_deg = math.degrees(math.atan(float(np.hypot(xy[:, 0], xy[:, 1]).max())))
    if angle_deg > MAX_RAY_ANGLE_DEG:
        raise ConfigError(f"{where}: its edge pixels see rays {angle_deg:.1f} deg off the optical "
                          f"axis; a pinhole raster holds less than 90 deg and deckpose renders up "
                          f"to {MAX_RAY_ANGLE_DEG:g} deg: use a smaller image or a longer focal length")
    ideal = xy @ camera.K[:2, :2].T + camera.K[:2, 2]
    name = f"{camera.name}-raster" if camera.name else "raster"
    if (ideal >= -0.5).all() and (ideal[:, 0] <= W - 0.5).all() and (ideal[:, 1] <= H - 0.5).all():
        out = CameraModel(W, H, camera.K, np.zeros(0), name)  # its own pinhole holds every ray
    else:
        lo, span = xy.min(axis=0), np.ptp(xy, axis=0)
        f = np.array([camera.fx, camera.fy])
        extent = f * span + 2 * _MARGIN_PX + 1  # raster pixels at the camera's focal length
        scale = min(1.0, math.sqrt(MAX_RASTER_AREA * W * H / float(np.prod(extent))),
                    (MAX_SIDE_PX - 2 * _MARGIN_PX - 1) / float(f[0] * span[0]))
        f_r = scale * f
        w_r, h_r = (math.ceil(float(x)) for x in f_r * span + 2 * _MARGIN_PX + 1)
        c_r = _MARGIN_PX - f_r * lo
        K_r = np.array([[f_r[0], 0.0, c_r[0]], [0.0, f_r[1], c_r[1]], [0.0, 0.0, 1.0]])
        out = CameraModel(w_r, h_r, K_r, np.zeros(0), name)
    if len(_RASTER_CACHE) > 16:
        _RASTER_CACHE.clear()
    _RASTER_CACHE[key] = out
    return out


def distortion_maps(camera: CameraModel) -> tuple[np.ndarray, np.ndarray]:
    """Maps for ``cv2.remap`` from the :func:`raster_camera` raster to the image (cached per camera).

    Every image pixel maps to the raster pixel of its ray, ``K_raster @ (x/z, y/z, 1)`` with
    ``(x/z, y/z)`` from :meth:`~deckpose.camera.CameraModel.undistort`; the maps are OpenCV's
    fixed-point form (1/32 px).
    """
    key = _key(camera)
    if key not in _MAP_CACHE:
        _MAP_CACHE.clear()
        pin = raster_camera(camera)
        W, H = camera.width_px, camera.height_px
        mx, my = np.empty((H, W), np.float32), np.empty((H, W), np.float32)
        rows = max(1, _CHUNK_PX // W)
        u = np.arange(W, dtype=float)
        for r0 in range(0, H, rows):
            r1 = min(H, r0 + rows)
            vv, uu = np.meshgrid(np.arange(r0, r1, dtype=float), u, indexing="ij")
            ray = _rays(camera, np.column_stack([uu.ravel(), vv.ravel()]))
            src = np.column_stack([pin.fx * ray[:, 0] + pin.cx, pin.fy * ray[:, 1] + pin.cy])  # no skew
            src = np.nan_to_num(src, nan=-1.0)  # no ray: the raster's border
            mx[r0:r1] = src[:, 0].reshape(r1 - r0, W)
            my[r0:r1] = src[:, 1].reshape(r1 - r0, W)
        m1, m2 = cv2.convertMaps(mx, my, cv2.CV_16SC2)
        _MAP_CACHE[key] = (m1, m2)
    return _MAP_CACHE[key]


def distort(raster: NDArray[np.uint8], camera: CameraModel) -> NDArray[np.uint8]:
    """Warp a raster drawn through :func:`raster_camera` into the camera's image.

    Parameters
    ----------
    raster : (h, w, 3) array of uint8
        Drawn through ``raster_camera(camera)`` (``camera`` itself when it has no distortion).
    camera : CameraModel

    Returns
    -------
    (H, W, 3) array of uint8
        ``raster`` itself without distortion.
    """
    if not camera.has_distortion:
        return raster
    pin = raster_camera(camera)
    if raster.shape[:2] != (pin.height_px, pin.width_px):
        raise ShapeError(f"raster is {raster.shape[1]}x{raster.shape[0]} px but the camera's raster "
                         f"is {pin.width_px}x{pin.height_px}: draw it through raster_camera(camera)")
    m1, m2 = distortion_maps(camera)
    return np.asarray(cv2.remap(raster, m1, m2, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE),
                      dtype=np.uint8)
