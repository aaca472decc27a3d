"""Hot pixels at night: the detectors drop them by shape and colour and keep every beacon.

Frames come from a generator written here (not ``render/`` nor ``benchmarks/``):
erf-integrated Gaussian spots, Poisson + read noise, hot photosites with a fixed
excess, quantised to 12 bits; mono, or an RGGB mosaic demosaiced by OpenCV. The
beacons are projected here by a nadir pinhole camera.
"""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest
from deckpose.detect.defects import LEAST_SHARE, SIGMA_MIN_PX, min_neighbour_ratio, point_defects
from deckpose.detect.frame_detection import detect_frame
from deckpose.detect.registry import DetectorOptions
from scipy.special import erf

from deckpose.camera import CameraModel
from deckpose.layout import DeckLayout
from deckpose.records import Frame

W, H = 1280, 960
FOCAL_PX = 1200.0
READ_E = 5.0
BACKGROUND_E = 10.0
FULL_SCALE_DN = 4095
#: 400 hot pixels on an 8 MP (3840x2160) sensor, scaled to this frame's area: 59.
N_HOT = round(400 * W * H / (3840 * 2160))
#: OpenCV names a Bayer pattern by its second row and column: an RGGB sensor is "BG".
RGGB_CODES = (cv2.COLOR_BayerBG2RGB, cv2.COLOR_BayerBG2RGB_EA)


def _profile(centre: float, sigma: float, n: int) -> np.ndarray:
    """Fraction of a 1-D Gaussian in each unit pixel ``0 .. n-1`` (pixel centres at integers)."""
    x = np.arange(n + 1) - 0.5
    return np.diff(0.5 * (1.0 + erf((x - centre) / (sigma * math.sqrt(2.0)))))


def _spot(u: float, v: float, sigma: float, flux: float, h: int = H, w: int = W) -> np.ndarray:
    return flux * np.outer(_profile(v, sigma, h), _profile(u, sigma, w))


def _beacons_px(yaw_rad: float, height_m: float) -> np.ndarray:
    """Pixels of the 12 ring beacons (id i at 2 pi i / 12 from the bow toward port, 10 m) and the
    centre (id 12), seen by a nadir camera ``height_m`` above the deck centre, image up = bow."""
    a = 2 * np.pi * np.arange(12) / 12 + yaw_rad
    x = np.append(10.0 * np.cos(a), 0.0)  # toward the bow
    y = np.append(10.0 * np.sin(a), 0.0)  # toward port
    return np.column_stack([(W - 1) / 2 - FOCAL_PX * y / height_m, (H - 1) / 2 - FOCAL_PX * x / height_m])


def _night_frame(rng: np.random.Generator, *, bayer: int | None, n_hot: int,
                 sigma_px: tuple[float, float] = (0.6, 1.5)) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A night frame: (image, beacon pixels (13, 2), hot pixels (n_hot, 2) as (u, v)).

    Beacons: white (1/3 of the flux per channel), the bow red (1, 0.1, 0.05); flux
    3,000-20,000 e (channel sum), sigma uniform in ``sigma_px``; gain 1 DN/e. Hot pixels:
    excess log-uniform (the top ones clip), on photosites away from the beacons: 100-5,000 e
    on mono frames (17-850 noise sigmas), 1,000-5,000 e on Bayer frames (the colour test
    needs ~150 sigmas, see test_demosaiced_hot_pixel_is_dropped; the ladder's real camera
    has 1,500 e).
    """
    uv = _beacons_px(rng.uniform(-np.pi, np.pi), rng.uniform(38.0, 42.0))
    uv += rng.uniform(-0.5, 0.5, uv.shape)
    mean = np.full((H, W, 3), BACKGROUND_E / 3)
    for i, (u, v) in enumerate(uv):
        rgb = np.array([1.0, 0.1, 0.05]) if i == 0 else np.ones(3)
        s = _spot(u, v, rng.uniform(*sigma_px), rng.uniform(3000.0, 20000.0))
        mean += s[:, :, None] * (rgb / rgb.sum())[None, None, :]
    hot = []
    while len(hot) < n_hot:
        p = rng.integers([0, 0], [W, H])
        if np.hypot(*(uv - p).T).min() > 8 and all(abs(p - q).max() > 2 for q in hot):
            hot.append(p)
    hot_uv = np.array(hot, float).reshape(-1, 2)
    lo = 100.0 if bayer is None else 1000.0
    excess = np.exp(rng.uniform(math.log(lo), math.log(5000.0), len(hot)))
    if bayer is None:
        e = mean.sum(axis=2)
        dn = rng.poisson(e) + rng.normal(0.0, READ_E, e.shape)
        dn[hot_uv[:, 1].astype(int), hot_uv[:, 0].astype(int)] += excess
        img = np.clip(np.rint(dn), 0, FULL_SCALE_DN).astype(np.uint16)
    else:
        chan = np.array([[0, 1], [1, 2]])[np.arange(H)[:, None] % 2, np.arange(W)[None, :] % 2]
        e = np.take_along_axis(mean, chan[:, :, None], axis=2)[:, :, 0] * 3  # the pixel's filter
        dn = rng.poisson(e) + rng.normal(0.0, READ_E, e.shape)
        dn[hot_uv[:, 1].astype(int), hot_uv[:, 0].astype(int)] += excess
        img = cv2.cvtColor(np.clip(np.rint(dn), 0, FULL_SCALE_DN).astype(np.uint16), bayer)
    return img, uv, hot_uv


def _check_frame(img: np.ndarray, uv: np.ndarray, hot_uv: np.ndarray, detector: str) -> None:
    cam = CameraModel(W, H, np.array([[FOCAL_PX, 0, (W - 1) / 2], [0, FOCAL_PX, (H - 1) / 2], [0, 0, 1]]))
    # a mono frame cannot tell the bow (by its colour): its beacons are found, not identified
    rgb = img.ndim == 3
    res = detect_frame(Frame(img, cam, 0), detector, DeckLayout(), options=DetectorOptions(gain_dn_per_e=1.0),
                       identify=rgb)
    assert res.ok, res.reason
    pts = res.detections.points_px
    ids = res.detections.beacon_ids
    # every beacon found within 1 px (an SNR >= ~20 spot's centroid error is far below) with its id
    for i, p in enumerate(uv):
        d = np.hypot(*(pts - p).T)
        assert d.min() < 1.0, f"beacon {i} at {p} not found (nearest {d.min():.1f} px)"
        assert not rgb or ids[d.argmin()] == i, f"beacon {i} identified as {ids[d.argmin()]}"
    # no detection on a hot pixel
    d_hot = np.hypot(pts[:, None, 0] - hot_uv[None, :, 0], pts[:, None, 1] - hot_uv[None, :, 1])
    assert not (d_hot < 2.0).any(), f"{int((d_hot < 2.0).any(axis=1).sum())} hot pixels reported as spots"


@pytest.mark.parametrize("bayer", [None, *RGGB_CODES], ids=["mono", "bayer-bilinear", "bayer-ea"])
@pytest.mark.parametrize("n_hot", [N_HOT, 300], ids=["8mp-density", "above-max-blobs"])
def test_night_frame_with_hot_pixels(bayer: int | None, n_hot: int) -> None:
    """Every beacon found and identified, no hot pixel a spot: at 8 MP density (59 hot pixels
    here) and beyond max_blobs (300 > 200), which failed every frame before."""
    rng = np.random.default_rng(2313 + n_hot + (bayer or 0))
    img, uv, hot_uv = _night_frame(rng, bayer=bayer, n_hot=n_hot)
    _check_frame(img, uv, hot_uv, "cog")


def test_gauss_on_bayer_night_frame() -> None:
    rng = np.random.default_rng(7)
    img, uv, hot_uv = _night_frame(rng, bayer=RGGB_CODES[0], n_hot=N_HOT)
    _check_frame(img, uv, hot_uv, "gauss")


def test_min_neighbour_ratio_is_the_centred_spot() -> None:
    """The sharpest pixel-integrated Gaussian is centred on a pixel: compare with that case in
    closed form, and with a brute-force search over offsets on a grid finer than the function's."""
    for sigma in (0.5, 0.6, 1.0):
        p0 = erf(0.5 / (sigma * math.sqrt(2)))
        p1 = 0.5 * (erf(1.5 / (sigma * math.sqrt(2))) - p0)
        closed = ((p0 + 2 * p1) ** 2 - p0**2) / p0**2
        assert min_neighbour_ratio(sigma) == pytest.approx(closed, rel=1e-12)
        blocks = [np.outer(_profile(1 + dv, sigma, 3), _profile(1 + du, sigma, 3))
                  for du in np.linspace(-0.5, 0.5, 41) for dv in np.linspace(-0.5, 0.5, 41)]
        brute = min((b.sum() - b[1, 1]) / b[1, 1] for b in blocks)
        assert brute >= closed - 1e-12
    assert min_neighbour_ratio(SIGMA_MIN_PX) == pytest.approx(1.7518, abs=1e-4)


def _noise(rng: np.random.Generator, mean_e: np.ndarray) -> np.ndarray:
    return rng.poisson(mean_e) + rng.normal(0.0, READ_E, mean_e.shape)


def test_sigma_06_spot_at_snr_10_is_kept() -> None:
    """A sigma-0.6 px spot of integrated (matched-filter) SNR 10, at random sub-pixel offsets, is
    almost never a defect, mono or a white spot demosaiced.

    Its 8 neighbours hold >= 1.75 x its peak pixel's light; the shape test asks them to fall
    short of half that by 2 noise sigmas of the difference. At SNR 10 (137 e over 10 e of
    background and 5 e of read noise) the peak holds ~49 e, the neighbours ~85 e: a call
    needs their sum ~4 sigmas low (3,000 draws: 0 mono, 1 Bayer). Allowed: 1 % of 400
    draws; the test without its noise margin dropped 1.3 % (mono), a threshold at the spot's
    own ratio about half."""
    rng = np.random.default_rng(10)
    n = 32
    var_bg = BACKGROUND_E + READ_E**2
    unit = _spot(16.0, 16.0, SIGMA_MIN_PX, 1.0, n, n)
    flux = 10.0 / math.sqrt(float(np.sum(unit**2 / var_bg)))  # matched-filter SNR 10 (background-limited)
    dropped = {"mono": 0, "bayer": 0}
    for _ in range(400):
        u, v = 16 + rng.uniform(-0.5, 0.5, 2)
        s = _spot(u, v, SIGMA_MIN_PX, flux, n, n)
        mono = np.clip(np.rint(_noise(rng, s + BACKGROUND_E) + 100), 0, FULL_SCALE_DN).astype(np.uint16)
        dropped["mono"] += int(point_defects(mono, np.array([[u, v]]))[0])
        mos = np.clip(np.rint(_noise(rng, s + BACKGROUND_E) + 100), 0, FULL_SCALE_DN).astype(np.uint16)
        rgb = cv2.cvtColor(mos, RGGB_CODES[0])
        dropped["bayer"] += int(point_defects(rgb, np.array([[u, v]]))[0])
    assert dropped["mono"] <= 4 and dropped["bayer"] <= 4, dropped


def test_red_bow_demosaiced_is_kept() -> None:
    """The default layout's red bow (1, 0.1, 0.05), sigma 0.6-1 px, 20,000 e, on a Bayer frame:
    its green and blue keep it, wherever it falls on the mosaic.

    Its least share of green and blue beside red, computed here from the noise-free
    demosaiced spot over a grid of positions, is the one LEAST_SHARE states for red."""
    assert DeckLayout().bow_rgb == (1.0, 0.1, 0.05)
    rng = np.random.default_rng(11)
    n = 32
    chan = np.array([[0, 1], [1, 2]])[np.arange(n)[:, None] % 2, np.arange(n)[None, :] % 2]
    scale = np.array([1.0, 0.1, 0.05])[chan]
    kept = 0
    for k in range(100):
        u, v = 16 + k % 10 * 0.2, 16 + k // 10 * 0.2
        s = _spot(u, v, rng.uniform(0.6, 1.0), 20000.0, n, n) * scale
        mos = np.clip(np.rint(_noise(rng, s + BACKGROUND_E) + 100), 0, FULL_SCALE_DN).astype(np.uint16)
        kept += int(not point_defects(cv2.cvtColor(mos, RGGB_CODES[0]), np.array([[u, v]]))[0])
    assert kept == 100
    least = math.inf
    for du in np.linspace(0.0, 2.0, 9):
        for dv in np.linspace(0.0, 2.0, 9):
            s = _spot(16 + du, 16 + dv, SIGMA_MIN_PX, 1e5, n, n) * scale
            rgb = cv2.cvtColor(np.rint(s).astype(np.uint16), RGGB_CODES[0]).astype(float)
            r, c = np.unravel_index(rgb.sum(axis=2).argmax(), (n, n))
            box = rgb[r - 2 : r + 3, c - 2 : c + 3].reshape(-1, 3)
            dev = box - box.mean(axis=0)
            amp = dev[:, 0] @ dev / (dev[:, 0] @ dev[:, 0])  # least-squares slope on the red profile
            least = min(least, amp[1] + amp[2])
    assert least == pytest.approx(LEAST_SHARE[0], abs=0.002)


@pytest.mark.parametrize("excess_sigma", [20.0, 30.0, 100.0, 1000.0, 1e5])
def test_mono_hot_pixel_is_dropped_at_any_amplitude(excess_sigma: float) -> None:
    """From near what the significance search can see (a lone pixel of ~13 noise sigmas makes
    a 5-sigma smoothed peak) to a clipped pixel. The 8 neighbours hold only noise; the test
    asks their deficit below 0.88 x the excess to exceed 2 of its noise sigmas (2 x 2.96
    pixel sigmas): at 20 sigmas the margin is 11.6 pixel sigmas against ~3.4 of noise (with
    the hot pixel's own shot noise), a miss every ~3,000 draws (at 15 sigmas, one in ~80)."""
    rng = np.random.default_rng(int(excess_sigma))
    sigma = math.sqrt(BACKGROUND_E + READ_E**2)
    for _ in range(50):
        dn = _noise(rng, np.full((24, 24), BACKGROUND_E)) + 100
        dn[12, 12] += excess_sigma * sigma
        img = np.clip(np.rint(dn), 0, FULL_SCALE_DN).astype(np.uint16)
        assert point_defects(img, np.array([[12.0, 12.0]]))[0]


@pytest.mark.parametrize("code", RGGB_CODES, ids=["bilinear", "ea"])
@pytest.mark.parametrize("excess_sigma", [150.0, 1000.0, 1e5])
def test_demosaiced_hot_pixel_is_dropped(code: int, excess_sigma: float) -> None:
    """A hot photosite of each Bayer phase, demosaiced: light in one channel only.

    The colour test's noise is about one pixel's noise over the excess per channel, and a red
    one must lie 2.5 of those below the bow's share (0.05): tested from 150 sigmas (a real
    hot pixel, 1,500 e over ~5 e of noise, is ~300) to clipped."""
    rng = np.random.default_rng(int(excess_sigma) + code)
    sigma = math.sqrt(BACKGROUND_E + READ_E**2)
    for phase in range(4):
        r, c = 12 + phase // 2, 12 + phase % 2
        for _ in range(20):
            dn = _noise(rng, np.full((28, 28), BACKGROUND_E)) + 100
            dn[r, c] += excess_sigma * sigma
            img = cv2.cvtColor(np.clip(np.rint(dn), 0, FULL_SCALE_DN).astype(np.uint16), code)
            assert point_defects(img, np.array([[c + 0.7, r - 0.6]]))[0], (phase, excess_sigma)


def _with_extra_spots(rng: np.random.Generator, n_extra: int, sigma_px: float = 1.2,
                      flux_e: float = 1500.0) -> tuple[np.ndarray, np.ndarray]:
    """A Bayer night frame (no hot pixels) plus ``n_extra`` genuine white spots (by default
    sigma 1.2 px, 1,500 e: dimmer than every beacon), away from the beacons; (image, beacon
    pixels). The beacons: sigma 1 px, 15,000 e."""
    uv = _beacons_px(rng.uniform(-np.pi, np.pi), 40.0)
    e = np.full((H, W), BACKGROUND_E)
    chan = np.array([[0, 1], [1, 2]])[np.arange(H)[:, None] % 2, np.arange(W)[None, :] % 2]
    for i, (u, v) in enumerate(uv):
        rgb = np.array([1.0, 0.1, 0.05]) if i == 0 else np.ones(3)
        e += _spot(u, v, 1.0, 15000.0) * (rgb / rgb.sum() * 3)[chan]
    placed = 0
    while placed < n_extra:
        p = rng.uniform([20, 20], [W - 20, H - 20])
        if np.hypot(*(uv - p).T).min() > 15:
            e += _spot(p[0], p[1], sigma_px, flux_e)
            placed += 1
    dn = rng.poisson(e) + rng.normal(0.0, READ_E, e.shape)
    return cv2.cvtColor(np.clip(np.rint(dn), 0, FULL_SCALE_DN).astype(np.uint16), RGGB_CODES[0]), uv


def test_more_spots_than_max_blobs_keeps_the_most_significant() -> None:
    """40 genuine extra spots with max_blobs=30: the frame used to fail ("more than 30
    significant spots"); now the 30 most significant are kept, the 13 beacons (brighter) among
    them, and identification decides."""
    rng = np.random.default_rng(23)
    img, uv = _with_extra_spots(rng, 40)
    cam = CameraModel(W, H, np.array([[FOCAL_PX, 0, (W - 1) / 2], [0, FOCAL_PX, (H - 1) / 2], [0, 0, 1]]))
    res = detect_frame(Frame(img, cam, 0), "cog", DeckLayout(),
                       options=DetectorOptions(gain_dn_per_e=1.0, max_blobs=30))
    assert len(res.detections.points_px) <= 30
    assert res.ok, res.reason
    pts, ids = res.detections.points_px, res.detections.beacon_ids
    for i, p in enumerate(uv):
        d = np.hypot(*(pts - p).T)
        assert d.min() < 1.0 and ids[d.argmin()] == i


def test_a_failure_after_a_cut_says_so() -> None:
    """When the cut leaves beacons out and identification fails, the reason says so: 40 broad
    bright patches (sigma 4 px, 100,000 e: more significant than the beacons, yet below the
    bright-spot level) with max_blobs=20."""
    rng = np.random.default_rng(24)
    img, _uv = _with_extra_spots(rng, 40, sigma_px=4.0, flux_e=100000.0)
    cam = CameraModel(W, H, np.array([[FOCAL_PX, 0, (W - 1) / 2], [0, FOCAL_PX, (H - 1) / 2], [0, 0, 1]]))
    res = detect_frame(Frame(img, cam, 0), "cog", DeckLayout(),
                       options=DetectorOptions(gain_dn_per_e=1.0, max_blobs=20))
    assert not res.ok
    assert "max_blobs=20: kept the 20 most significant" in res.reason, res.reason



def test_a_faint_spot_on_a_quantised_background_is_no_defect():
    # An 8-bit frame whose dark background is 2 DN with under half a DN of noise: most border
    # pixels hold the same value, so their MAD (the noise estimate) was 0, and a faint, broad
    # beacon's noisy profile looked sharp or one-coloured (the independent generator's 8-bit
    # frames lost 3 beacons of 1,900-3,700 e that way; here 10 of 20 draws were called
    # defects). The noise is now at least the thresholds' floor (1 DN per channel on an
    # integer image); a real hot pixel beside it still is one, in every draw.
    H, W = 64, 96
    vv, uu = np.mgrid[0:H, 0:W]
    spot = 0.8 * np.exp(-((uu - 30.3) ** 2 + (vv - 31.6) ** 2) / (2 * 2.0**2))  # peak 0.8 DN, sigma 2 px
    called = []
    for seed in range(20):
        rng = np.random.default_rng(seed)
        img = np.empty((H, W, 3))
        for ch, level in enumerate((1.0, 1.0, 0.9)):  # a white ring beacon's colour
            img[..., ch] = 2.0 + level * spot + rng.normal(0.0, 0.3, (H, W))
        img = np.clip(np.round(img), 0, 255).astype(np.uint8)
        # a hot green photosite at (70, 30), bilinearly demosaiced: its 3x3 in one channel only
        img[29:32, 69:72, 1] = np.array([[40, 80, 40], [80, 160, 80], [40, 80, 40]], np.uint8)
        called.append(point_defects(img, np.array([[30.0, 32.0], [70.0, 30.0]])).tolist())
    assert all(c == [False, True] for c in called), called


def test_a_clipped_plateau_is_a_spot_and_judging_it_warns_of_nothing() -> None:
    """A beacon clipped flat in every channel (16-bit RGB) leaves the colour test a flat template
    (no profile at all): it is no defect, and no overflow warning may reach the user's terminal
    (pytest turns warnings into errors here)."""
    img = np.full((64, 64, 3), 800, np.uint16)
    yy, xx = np.mgrid[:64, :64]
    spot = 60000.0 * np.exp(-((xx - 32.2) ** 2 + (yy - 31.7) ** 2) / (2 * 3.0**2))
    img += np.clip(spot, 0, 65535 - 800).astype(np.uint16)[..., None]
    img[28:36, 28:36] = 65535  # the clipped core, flat in all three channels
    assert not point_defects(img, np.array([[32.0, 32.0]]), search_px=2).any()
