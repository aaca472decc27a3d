"""Astronomy's centroiders as detectors: ``sep`` and ``photutils`` (optional peers).

Baselines that ``deckpose bench-detectors`` puts beside ours, each used the way
its documentation shows, on the channel-sum image (where the photons are), with
no help from our candidate search:

* ``sep`` (Source Extractor as a library): ``sep.Background`` (64 px boxes),
  ``sep.extract`` at 3 background sigmas (``minarea`` 5), then ``sep.winpos``,
  the windowed (Gaussian-weighted) centroid, with ``sig = 2 / 2.35 * r_half``
  from ``sep.flux_radius`` (as sep's documentation advises);
* ``photutils``: ``Background2D`` (64 px boxes, median), ``DAOStarFinder``
  (FWHM 3 px, 5 background sigmas, sharpness and roundness limits off), then
  ``centroid_sources`` with ``centroid_2dg`` (a 2-D Gaussian fit) in an 11 px box,
  weighted by the background error.

Both need the optional extra: ``pip install 'deckpose[peers]'``. They register
only when their package imports (:data:`PEER_PACKAGES` says which package each
needs, so asking for a missing one says how to install it).
"""

from __future__ import annotations

import importlib.util
import inspect
import math
import warnings

import numpy as np
from deckpose.detect.background import mono
from deckpose.detect.registry import OPTIONAL_DETECTORS as PEER_PACKAGES
from deckpose.detect.registry import Blobs, DetectorOptions, register

from deckpose.records import Frame


def available(name: str) -> bool:
    """Whether peer detector ``name``'s package is installed."""
    return importlib.util.find_spec(PEER_PACKAGES[name]) is not None


def _channel_sum(frame: Frame) -> np.ndarray:
    return np.ascontiguousarray(mono(frame.image))


def _rows(
    frame: Frame, x: np.ndarray, y: np.ndarray, cov: np.ndarray, flux: np.ndarray,
    size: np.ndarray, score: np.ndarray,
) -> Blobs:
    """The peers' sources as Blobs, without non-finite or out-of-image centres."""
    H, W = frame.image.shape[:2]
    ok = np.isfinite(x) & np.isfinite(y) & np.isfinite(cov).all(axis=(1, 2))
    ok &= (x > -0.5) & (x < W - 0.5) & (y > -0.5) & (y < H - 0.5)
    if not ok.any():
        return Blobs.empty("no source found")
    return Blobs(np.column_stack([x[ok], y[ok]]), cov[ok], flux[ok], size[ok], score[ok])


def detect_sep(frame: Frame, options: DetectorOptions) -> Blobs:
    """``sep.extract`` sources, centred by ``sep.winpos`` (see the module docstring)."""
    import sep

    data = _channel_sum(frame)
    bkg = sep.Background(data, bw=64, bh=64)
    sub = data - bkg.back()
    rms = float(bkg.globalrms)
    sep.set_extract_pixstack(max(300_000, data.size // 10))
    try:
        objs = sep.extract(sub, 3.0, err=rms, minarea=5)
    except Exception as exc:  # noqa: BLE001 - sep raises a bare Exception (pixel stack full)
        return Blobs.empty(f"sep.extract failed: {exc}")
    if len(objs) == 0:
        return Blobs.empty("sep found no source")
    if len(objs) > options.max_blobs:
        return Blobs.empty(f"sep found {len(objs)} sources, over max_blobs={options.max_blobs}")
    r_half, _ = sep.flux_radius(sub, objs["x"], objs["y"], 6.0 * objs["a"], 0.5, subpix=5)
    sig = np.maximum(2.0 / 2.35 * np.asarray(r_half, float), 0.5)
    x, y, _flag = sep.winpos(sub, objs["x"], objs["y"], sig)
    cov = np.stack(
        [np.stack([objs["errx2"], objs["errxy"]], -1), np.stack([objs["errxy"], objs["erry2"]], -1)],
        axis=1,
    ).astype(float)
    cov = np.where(np.isfinite(cov), cov, 1.0)
    flux = np.asarray(objs["flux"], float)
    score = flux / (rms * np.sqrt(np.maximum(np.asarray(objs["npix"], float), 1.0)))
    return _rows(frame, np.asarray(x, float), np.asarray(y, float), cov, flux, sig, score)


def detect_photutils(frame: Frame, options: DetectorOptions) -> Blobs:
    """``DAOStarFinder`` sources, centred by ``centroid_2dg`` (see the module docstring)."""
    with warnings.catch_warnings():  # astropy's deprecation and fit warnings
        warnings.simplefilter("ignore")
        return _photutils(frame, options)


def _photutils(frame: Frame, options: DetectorOptions) -> Blobs:
    from photutils.background import Background2D, MedianBackground
    from photutils.centroids import centroid_2dg, centroid_sources
    from photutils.detection import DAOStarFinder

    data = _channel_sum(frame)
    box = min(64, max(8, min(data.shape) // 4))
    bkg = Background2D(data, box, filter_size=3, bkg_estimator=MedianBackground())
    sub = data - bkg.background
    rms = float(np.median(bkg.background_rms))
    params = inspect.signature(DAOStarFinder).parameters
    limits: dict[str, object] = (
        {"sharpness_range": None, "roundness_range": None}
        if "sharpness_range" in params  # photutils >= 3
        else {"sharplo": -math.inf, "sharphi": math.inf, "roundlo": -math.inf, "roundhi": math.inf}
    )
    finder = DAOStarFinder(fwhm=3.0, threshold=5.0 * rms, **limits)  # type: ignore[arg-type]
    src = finder(sub)
    if src is None or len(src) == 0:
        return Blobs.empty("DAOStarFinder found no source")
    if len(src) > options.max_blobs:
        return Blobs.empty(
            f"DAOStarFinder found {len(src)} sources, over max_blobs={options.max_blobs}"
        )
    x0 = np.asarray(src["x_centroid"] if "x_centroid" in src.colnames else src["xcentroid"], float)
    y0 = np.asarray(src["y_centroid"] if "y_centroid" in src.colnames else src["ycentroid"], float)
    err = np.sqrt(bkg.background_rms**2 + np.maximum(sub, 0.0))
    with warnings.catch_warnings():  # "the fit may not have converged": its centre stays
        warnings.simplefilter("ignore")
        x, y = centroid_sources(sub, x0, y0, box_size=11, centroid_func=centroid_2dg, error=err)
    flux = np.asarray(src["flux"], float)
    n = x0.size
    # photutils gives no centroid covariance: that of a 1.5 px Gaussian spot's centroid
    var = (1.5**2 + 1.0 / 12.0) / np.maximum(flux, 1.0) * (1.0 + 4 * math.pi * 1.5**2 * rms**2
                                                             / np.maximum(flux, 1.0))
    cov = var[:, None, None] * np.eye(2)[None]
    score = flux / (rms * math.sqrt(4 * math.pi * 1.5**2))
    return _rows(frame, np.asarray(x, float), np.asarray(y, float), cov, flux, np.full(n, 1.5),
                 score)


if available("sep"):
    register("sep")(detect_sep)
if available("photutils"):
    register("photutils")(detect_photutils)
