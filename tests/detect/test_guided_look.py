"""The guided second look (:mod:`deckpose.detect.guided_look`) on frames we did not render.

Frames come from ``benchmarks/independent_spots.py`` (erf-integrated Gaussian spots,
Poisson + read noise, rounding to 8 bits), at 960x540 so the tests stay fast; noise
windows are drawn here from the same physics. The tolerances come from the
statistic's distribution (a standard normal on noise alone) and binomial counts.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from deckpose.detect import guided_look as gl
from deckpose.detect import registry
from deckpose.detect.colour import blob_rgb_flux
from deckpose.detect.frame_detection import detect_frame
from deckpose.detect.identify import identify_beacons
from deckpose.detect.registry import DetectorOptions
from scipy.special import ndtr

from deckpose.camera import CameraModel
from deckpose.layout import DeckLayout
from deckpose.records import Frame
from tests.detect.independent_generator import load_independent_generator

gen = load_independent_generator()
LAYOUT = DeckLayout()
#: The benchmark's rgb8_uneven frames at a quarter of the pixels: 8-bit RGB, 6,000 e full
#: scale (23.5 e per DN), uneven brightness; ring 100-180 px in radius.
RGB8 = gen.SpotFrameSpec(width_px=960, height_px=540, focal_px=625.0, bits=8,
                         full_well_e=6000.0, uneven=(0.4, 1.0))
GAIN = 255.0 / 6000.0  # DN per electron of RGB8 (no spot reaches full scale at these fluxes)


def _red_snr(sigma_px: float, flux_e: float, spec) -> float:
    """Integrated SNR of the bow in the red channel: sqrt(Fisher information of its flux).

    ``sum_p (F_r P_p)^2 / var_p`` over the pixels, in DN: the red share ``RED[0]`` of the
    flux, the pixel-integrated profile ``P``, and per pixel Poisson (background + spot)
    and read noise times the gain squared plus 1/12 DN^2 of rounding.
    """
    f_r = flux_e * gen.RED[0]
    x = np.arange(-20, 21, dtype=float)
    P = np.outer(gen.spot_profile(0.3, sigma_px, x), gen.spot_profile(-0.2, sigma_px, x))
    var = (spec.background_e + f_r * P + spec.read_noise_e**2) * GAIN**2 + 1.0 / 12.0
    return float(np.sqrt(np.sum((f_r * GAIN * P) ** 2 / var)))


def _bow_at_snr(seed: int, snr: float, spec=RGB8):
    """A frame of ``spec`` whose bow's red-channel SNR is ``snr`` (flux solved by bisection).

    The frame is drawn twice from the same seed: the first draw gives the bow's sigma
    (drawn before the flux), the second overrides the bow's flux.
    """
    sigma = gen.make_frame(spec, np.random.default_rng(seed)).sigma_px[0]
    lo, hi = 10.0, 30_000.0
    for _ in range(50):
        mid = math.sqrt(lo * hi)
        lo, hi = (mid, hi) if _red_snr(sigma, mid, spec) < snr else (lo, mid)
    return gen.make_frame(replace(spec, flux_override=((0, lo),)), np.random.default_rng(seed))


def _frame(t) -> Frame:
    return Frame(t.image, CameraModel(t.image.shape[1], t.image.shape[0], t.K), 0)


def _full_search_alone(frame: Frame, detector: str):
    """The detector's blobs and their identification without the second look."""
    blobs = registry.get(detector)(frame, DetectorOptions())
    rgb = blob_rgb_flux(frame.image, blobs.points_px, np.maximum(2.0, 2.0 * blobs.size_px))
    return blobs, identify_beacons(blobs.points_px, LAYOUT, frame.camera, rgb_flux=rgb)


@pytest.mark.parametrize("detector", ["gauss", "cog"])
def test_a_dim_red_bow_at_snr_8_to_12_is_found_and_identified(detector):
    # 10 frames, the bow's red-channel SNR spread over 8-12. The second look's statistic
    # at the bow is about SNR x the filter's efficiency (>= 0.79 for the ring's median
    # sigma against the bow's, both in 0.8-2.5 px) >= 6.3, against a threshold of 4.1-4.6:
    # a miss has probability <= Q(1.7) = 4.5 % per frame (an identification also needs
    # the red share measured; it errs far less at this SNR). Allowed: 2 misses of 10
    # (probability of more than 2 at 4.5 % each: 1.0 %).
    ok = before = 0
    for seed, snr in zip(range(100, 110), np.linspace(8.0, 12.0, 10)):
        t = _bow_at_snr(seed, float(snr))
        frame = _frame(t)
        res = detect_frame(frame, detector, LAYOUT)
        idx, _ = gen.match(res.detections.points_px, t)
        right = all(idx[i] >= 0 and res.detections.beacon_ids[idx[i]] == t.beacon_id[i]
                    for i in range(t.beacon_id.size))
        ok += bool(res.ok and right)
        if detector == "gauss":  # the search before the second look is the same for both
            before += bool(_full_search_alone(frame, detector)[1].ok)
    assert ok >= 8, f"{ok} of 10 frames identified with the second look"
    # the full-frame search alone often misses such a bow (its channel-sum statistic is the
    # red one / sqrt(3) or less, about the threshold here: it found 4 of 10 once 8-bit block
    # sums were exact, 0-2 before): the second look must add frames, or the test would not
    # tell it from nothing
    if detector == "gauss":
        assert ok > before, f"the second look added nothing: {before} of 10 identified without it"


def _noise_image(rng: np.random.Generator, shape=(1000, 1000)) -> np.ndarray:
    """8-bit RGB noise of RGB8's sensor: Poisson(30 e) + N(0, 5 e), x gain, rounded."""
    e = rng.poisson(RGB8.background_e, (*shape, 3)) + rng.normal(0.0, RGB8.read_noise_e, (*shape, 3))
    return np.clip(np.rint(e * GAIN), 0, 255).astype(np.uint8)


def _grid(image: np.ndarray, spacing: int) -> np.ndarray:
    H, W = image.shape[:2]
    g = np.arange(spacing, min(H, W) - spacing, spacing, dtype=float)
    uu, vv = np.meshgrid(g + 0.3, g - 0.2)
    return np.column_stack([uu.ravel(), vv.ravel()])


def test_the_rounding_noise_is_in_the_channel_noise():
    # Regression: on 8-bit frames the noise is mostly rounding. The per-channel pixel noise
    # is sqrt((background + read^2) gain^2 + 1/12) DN = 0.43 DN here, independently of
    # detect; the estimate (10,000 pixel differences, clipped at 4 sigma, which removes
    # ~1e-3 of a Gaussian's variance) has a relative sampling error of ~0.7 %: 3 % allowed
    # (4 standard errors and the clip's bias).
    # Before, an unsigned channel's differences wrapped around (70 DN).
    img = _noise_image(np.random.default_rng(1), (1080, 1920))
    expected = math.sqrt((RGB8.background_e + RGB8.read_noise_e**2) * GAIN**2 + 1.0 / 12.0)
    bg, noise = gl.channel_noise(img)
    assert np.allclose(noise, expected, rtol=0.03), (noise, expected)
    assert np.allclose(bg, round(RGB8.background_e * GAIN), atol=0.5)
    # a flat integer frame still has its rounding: the floor sqrt(1/12) DN, not 0
    flat = np.full((200, 300, 3), 7, np.uint8)
    assert np.allclose(gl.channel_noise(flat)[1], math.sqrt(1.0 / 12.0))


def test_on_noise_the_statistic_is_standard_normal_and_false_alarms_stay_in_the_bound():
    rng = np.random.default_rng(7)
    imgs = [_noise_image(rng, (1200, 1200))]
    radius, sigma = 3.0, 1.5
    templates = np.array([[1 / 3, 1 / 3, 1 / 3], [0.87, 0.09, 0.04]])
    # (1) the statistic at one position, over independent windows (34 px apart, wider than
    # a window): mean 0 and sd 1 within 3 standard errors (1 / sqrt(N), 1 / sqrt(2N)).
    # A threshold of -inf returns each window's highest T; radius 0 searches one pixel.
    z = []
    n_win = 0
    for img in imgs:
        pos = _grid(img, 34)
        n_win += pos.shape[0]
        _bg, noise = gl.channel_noise(img)
        z += [s.z for s in gl.search_windows(img, np.rint(pos), 0.0, sigma, templates, noise, -np.inf)]
    z_a = np.array(z)
    assert z_a.size == 2 * n_win
    assert abs(z_a.mean()) < 3 / math.sqrt(z_a.size), z_a.mean()
    assert abs(z_a.std() - 1.0) < 3 / math.sqrt(2 * z_a.size), z_a.std()
    # (2) windows of the search radius: the union bound puts the chance that a window has
    # a T above t at most n Q(t) (n = positions x templates). At t for n Q(t) = 0.05 the
    # count over N windows is at most binomial(N, 0.05): allowed its mean + 3 sd.
    n = gl.search_positions(radius) * 2
    t = gl.guided_threshold(n, 0.05)
    hits = 0
    for img in imgs:
        _bg, noise = gl.channel_noise(img)
        found = gl.search_windows(img, _grid(img, 34), radius, sigma, templates, noise, t)
        hits += len({s.slot for s in found})
    assert hits <= n_win * 0.05 + 3 * math.sqrt(n_win * 0.05 * 0.95), (hits, n_win)
    # (3) at the frame's threshold (4 empty slots, both templates: 1e-3 per frame), the
    # windows make n_win / 4 frames: expected false alarms <= n_win / 4 x 1e-3 (0.4 here);
    # more than 3 has probability < 1e-3.
    t_frame = gl.guided_threshold(4 * n)
    phantoms = 0
    for img in imgs:
        _bg, noise = gl.channel_noise(img)
        phantoms += len(gl.search_windows(img, _grid(img, 34), radius, sigma, templates, noise,
                                          t_frame))
    assert phantoms <= 3, phantoms


def test_the_threshold_follows_the_union_bound():
    # n Q(t) = p, with Q the normal tail (scipy's ndtr, not the code's ndtri)
    for n, p in ((1, 0.01), (232, 1e-3), (2000, 1e-4)):
        t = gl.guided_threshold(n, p)
        assert math.isclose(n * (1.0 - ndtr(t)), p, rel_tol=1e-9)


def test_empty_slots_get_no_phantom():
    # Frames with 2 ring beacons and the centre missing, the bow bright: the second look
    # searches 3 empty positions each and must add nothing (no beacon is there). Over 8
    # frames at 1e-3 per frame the expected count is 0.008: any phantom fails.
    spec = replace(RGB8, missing_ring=2, drop_centre=True, flux_override=((0, 20_000.0),))
    rng = np.random.default_rng(11)
    for _ in range(8):
        t = gen.make_frame(spec, rng)
        res = detect_frame(_frame(t), "gauss", LAYOUT)
        idx, _ = gen.match(res.detections.points_px, t)
        assert res.ok, res.reason
        assert len(res.detections.points_px) == int(np.count_nonzero(idx >= 0))
        present = set(t.beacon_id.tolist())
        assert set(res.detections.beacon_ids.tolist()) <= present


def _paint_red(image: np.ndarray, points_px: np.ndarray, flux_e: float, sigma_px: float,
               rng: np.random.Generator) -> np.ndarray:
    """``image`` with red spots (the generator's profile and colour, Poisson) added, 8-bit."""
    out = image.astype(np.float64)
    for u, v in points_px:
        r = math.ceil(6 * sigma_px) + 2
        u0, v0 = int(u) - r, int(v) - r
        xs, ys = np.arange(u0, u0 + 2 * r + 1, dtype=float), np.arange(v0, v0 + 2 * r + 1, dtype=float)
        P = np.outer(gen.spot_profile(v, sigma_px, ys), gen.spot_profile(u, sigma_px, xs))
        mu = flux_e * P[..., None] * np.asarray(gen.RED)[None, None, :]
        out[v0 : v0 + 2 * r + 1, u0 : u0 + 2 * r + 1] += rng.poisson(mu) * GAIN
    return np.clip(np.rint(out), 0, 255).astype(np.uint8)


def test_one_red_spot_in_an_empty_slot_is_the_bow_and_two_are_not():
    # A frame without its bow and with one ring beacon missing; red spots (650 e, sigma
    # 1.5 px: red-channel SNR 9.6, a channel-sum statistic of about 9.6 / sqrt(3) = 5.5,
    # under the full-frame search's threshold of 5 sigmas raised for the counts' skew; 800 e,
    # SNR 11.5, was found by it once 8-bit block sums were exact) painted into its empty
    # slots, found where the ring's homography puts them.
    spec = replace(RGB8, drop_bow=True, missing_ring=1)
    t = gen.make_frame(spec, np.random.default_rng(3))
    frame = _frame(t)
    assert not detect_frame(frame, "gauss", LAYOUT).ok  # no bow: no identification
    blobs, ident = _full_search_alone(frame, "gauss")
    empty, slots, _resid = gl.slot_predictions(ident, LAYOUT, frame.camera, blobs.points_px)
    ring = empty[slots >= 0]
    assert ring.shape[0] == 2  # the bow's slot and the missing beacon's
    rng = np.random.default_rng(4)
    assert 9 < _red_snr(1.5, 650.0, RGB8) < 10
    for k in range(2):
        one = Frame(_paint_red(t.image, ring[k : k + 1], 650.0, 1.5, rng), frame.camera, 0)
        alone, _ = _full_search_alone(one, "gauss")
        assert np.linalg.norm(alone.points_px - ring[k], axis=1).min() > 3.0
        res = detect_frame(one, "gauss", LAYOUT)
        assert res.ok, res.reason
        d = np.linalg.norm(res.detections.points_px - ring[k], axis=1)
        assert res.detections.beacon_ids[int(np.argmin(d))] == LAYOUT.bow_id and d.min() < 1.5
    both = Frame(_paint_red(t.image, ring, 650.0, 1.5, rng), frame.camera, 0)
    res = detect_frame(both, "gauss", LAYOUT)
    assert not res.ok
    assert "2 red spots in empty ring slots" in res.reason
