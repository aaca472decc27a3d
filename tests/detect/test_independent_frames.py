"""Detection on frames from a generator independent of ``render/`` and ``detect/``.

``benchmarks/independent_spots.py`` draws erf-integrated Gaussian spots with
Poisson + read noise and rounding, and computes its own per-axis centroid
Cramér–Rao bound (CRB) of the channel-sum image. The frames here are 1920x1080
(the benchmark's are 8 MP) so the suite stays fast; the spots are the issue's:
sigma 0.8-2.5 px, 3,000-30,000 e, background 30 e, read noise 5 e.

Accuracy tolerances come from the bound and the sampling error of an RMS: over
``m`` normalised per-axis errors, the sample RMS has a relative standard error of
about ``1 / sqrt(2 m)``; a test allows the target plus three of those.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from deckpose.detect import registry
from deckpose.detect.frame_detection import detect_frame

from deckpose.camera import CameraModel
from deckpose.errors import ConfigError
from deckpose.layout import DeckLayout
from deckpose.records import Frame
from tests.detect.independent_generator import load_independent_generator

gen = load_independent_generator()

#: 1920x1080 with the ring 210-360 px in radius (35-60 m at 1250 px focal length).
SMALL = gen.SpotFrameSpec(width_px=1920, height_px=1080, focal_px=1250.0)
LAYOUT = DeckLayout()


def _frames(spec, n: int, seed: int):
    rng = np.random.default_rng(seed)
    return [gen.make_frame(spec, rng) for _ in range(n)]


def _run(detector: str, truth) -> tuple[object, np.ndarray]:
    cam = CameraModel(truth.image.shape[1], truth.image.shape[0], truth.K)
    res = detect_frame(Frame(truth.image, cam, 0), detector, LAYOUT)
    idx, _ = gen.match(res.detections.points_px, truth)
    return res, idx


def _errors(detector: str, frames, *, min_flux_e: float = 0.0) -> np.ndarray:
    """Normalised errors (error / CRB per axis) of every found, unclipped beacon, (m, 2).

    ``min_flux_e``: only the beacons brighter than this (channel sum, electrons).
    """
    out = []
    for t in frames:
        res, idx = _run(detector, t)
        for i in np.flatnonzero((idx >= 0) & ~t.saturated & (t.flux_e > min_flux_e)):
            out.append((res.detections.points_px[idx[i]] - t.centre_px[i]) / t.crb_px[i])
    return np.array(out)


def _own_sigma_errors(detector: str, frames) -> np.ndarray:
    """Errors over the detector's own sigma per axis of every found, unclipped beacon, (m, 2)."""
    out = []
    for t in frames:
        res, idx = _run(detector, t)
        for i in np.flatnonzero((idx >= 0) & ~t.saturated):
            err = res.detections.points_px[idx[i]] - t.centre_px[i]
            out.append(err / np.sqrt(np.diag(res.detections.covariance_px2[idx[i]])))
    return np.array(out)


def _allowance(target: float, n_axes: int) -> float:
    return target * (1.0 + 3.0 / math.sqrt(2.0 * n_axes))


@pytest.fixture(scope="module")
def uneven_frames():
    # the failure: each beacon's flux times U(0.4, 1.0)
    return _frames(replace(SMALL, uneven=(0.4, 1.0)), 14, seed=5)


@pytest.mark.parametrize("detector", ["cog", "gauss"])
def test_uneven_beacons_are_all_found_and_identified(detector, uneven_frames):
    # Before the significance search, 4 of 10 such frames failed ("only 5 blobs detected")
    # and 55 % of the beacons were identified.
    for t in uneven_frames:
        res, idx = _run(detector, t)
        assert res.ok, res.reason
        assert np.all(idx >= 0), "a beacon was missed"
        assert len(res.detections.points_px) == t.beacon_id.size, "a false detection"
        ids = res.detections.beacon_ids[idx]
        np.testing.assert_array_equal(ids, t.beacon_id)


@pytest.mark.parametrize(("detector", "target"), [("gauss", 1.05), ("cog", 1.20)])
def test_centroids_reach_the_bound_on_independent_frames(detector, target, uneven_frames):
    e = _errors(detector, uneven_frames)
    ratio = float(np.sqrt(np.mean(e**2)))
    assert e.shape[0] == 13 * len(uneven_frames)
    # 364 per-axis errors: the RMS's standard error is 3.7 %
    assert 0.85 < ratio < _allowance(target, e.size), ratio
    # no bias beyond noise on either axis
    assert np.all(np.abs(e.mean(axis=0)) < 3.0 / math.sqrt(e.shape[0]) * ratio + 0.02)


def test_cog_covariance_is_honest_on_unclipped_rgb_spots(uneven_frames):
    """cog's own sigmas against its errors on the independent frames' unclipped RGB spots.

    An unclipped RGB spot is measured on the channel sum; its covariance took the peak
    channel's (smaller) noise, which understated it: RMS error / own sigma 1.42-1.48 on these
    frames. With the channel sum's own noise it is 1.11-1.12. An honest covariance gives 1
    within 3 / sqrt(2 m) (0.11 here); cog's model keeps a smaller understatement of its own
    (about 1.1 on mono frames too, `benchmarks/independent_covariance.py`), so the test
    allows 1.25: a covariance off by a quarter at most.
    """
    z = _own_sigma_errors("cog", uneven_frames)
    rms = float(np.sqrt(np.mean(np.square(z))))
    assert len(z) > 100
    assert 0.8 < rms < 1.25, rms


#: 8-bit RGB at the generator's default full well (0.01275 DN/e): the 30 e background is 0.38 DN a
#: channel and rounds to 0 DN almost everywhere (the frame's median pixel is 0 DN).
DARK_8BIT = replace(SMALL, bits=8)


@pytest.fixture(scope="module")
def dark_frames():
    return _frames(DARK_8BIT, 8, seed=11)


def test_dark_8bit_frames_find_and_identify_every_beacon(dark_frames):
    """A frame whose background rounds to 0 DN gets the significance search too.

    Without it (until session 22) only the brightest 3-5 of 13 beacons were found on such
    frames and none was identified. A beacon may still be missed on an odd frame (a dim red
    bow carries its light in one channel), so the test asks for 95 % of the beacons, every
    beacon found given its right id, 7 of 8 frames identified and no false detection.
    """
    found = total = frames_ok = 0
    for t in dark_frames:
        res, idx = _run("cog", t)
        found += int((idx >= 0).sum())
        total += idx.size
        frames_ok += bool(res.ok)
        assert len(res.detections.points_px) == int((idx >= 0).sum()), "a false detection"
        if res.ok:
            np.testing.assert_array_equal(res.detections.beacon_ids[idx[idx >= 0]], t.beacon_id[idx >= 0])
    assert found >= 0.95 * total, (found, total)
    assert frames_ok >= 7, frames_ok


def test_cog_reaches_the_bound_on_the_bright_spots_of_dark_8bit_frames(dark_frames):
    """cog on the dark 8-bit frames' beacons of 12,000-30,000 e (issue 15: 1.20x the bound at most).

    There a beacon's wings are below the noise and rounding (0.1 DN of noise a channel cannot
    dither a 1 DN step), and the 3-sigma disc weighed them by their offset: 1.64x the bound
    on these 41 beacons (1.32x on all 103). Weighed by each pixel's noise
    (:func:`deckpose.detect.centroid.noise_weight`) they read 1.18x (1.00x on all). The
    tolerance is the target plus three standard errors of an RMS over ``m`` axes.
    """
    e = _errors("cog", dark_frames, min_flux_e=12_000.0)
    ratio = float(np.sqrt(np.mean(e**2)))
    assert e.shape[0] > 30, e.shape
    assert ratio < _allowance(1.20, e.size), (ratio, _allowance(1.20, e.size))


def test_cog_covariance_is_not_understated_on_dark_8bit_frames(dark_frames):
    """cog's sigmas on a dark 8-bit frame's spots: the channel sum's own noise, not the thresholds'.

    A spot the significance search finds took the thresholds' noise, floored at 1 DN a channel:
    about 3x these frames' noise, RMS error / own sigma 0.34. With the channel sum's noise as it
    is it reads 0.86-0.92 (`benchmarks/independent_covariance.py`): not understated (below
    1 + 3 / sqrt(2 m)), and overstated by no more than the rounding, which noise of 0.1 DN does not
    dither, explains (the disc's wings are a fixed rounding there, counted as noise: 0.7).
    With the bright spots' pixels weighed by their noise it reads 0.80 on these frames: the
    frame's estimated gain (:func:`~deckpose.detect.gain.estimate_gain`, 0.038 DN/e against the
    generator's 0.0128) overstates the shot noise; with the true gain it reads 1.00.
    """
    z = _own_sigma_errors("cog", dark_frames)
    m = 2 * len(z)
    rms = float(np.sqrt(np.mean(np.square(z))))
    assert m > 150, m
    assert 0.7 < rms < 1.0 + 3.0 / math.sqrt(2.0 * m), rms


def test_mono_frames_keep_the_dim_red_bow():
    # On a mono sensor the red bow gives 0.43x the grey of a white beacon: the bright-spot
    # search alone (0.8 of the brightest) dropped it in every frame (recall 0.926).
    spec = replace(SMALL, rgb=False, bits=16, flux_e=(15_000.0, 20_000.0))
    for t in _frames(spec, 4, seed=8):
        res, idx = _run("cog", t)
        assert np.all(idx >= 0), t.flux_e[idx < 0]
        assert len(res.detections.points_px) == t.beacon_id.size
        # no colour in mono: only the centre beacon can be named; the frame says so
        assert not res.ok and "mono" in res.reason


def test_a_beacon_twenty_times_dimmer_than_the_brightest_is_found():
    # 30,000 e beside 1,300 e at sigma 1 px: integrated SNR of the dim one about 20
    spec = replace(SMALL, sigma_px=(1.0, 1.0), flux_e=(30_000.0, 30_000.0),
                   flux_override=((3, 1_300.0), (7, 1_500.0)))
    for t in _frames(spec, 3, seed=9):
        for det in ("cog", "gauss"):
            res, idx = _run(det, t)
            assert res.ok, res.reason
            assert np.all(idx >= 0)


@pytest.mark.parametrize("detector", ["cog", "gauss"])
def test_identification_with_missing_beacons_and_other_lights(detector):
    # centre beacon and 3 ring beacons missing, 5 other lights (red and green sidelights,
    # floodlights, a glint) off the ring: every beacon keeps its id, no light gets one
    spec = replace(SMALL, uneven=(0.4, 1.0), missing_ring=3, drop_centre=True, other_lights=5)
    for t in _frames(spec, 4, seed=10):
        res, idx = _run(detector, t)
        assert res.ok, res.reason
        assert np.all(idx >= 0)
        np.testing.assert_array_equal(res.detections.beacon_ids[idx], t.beacon_id)
        others = np.setdiff1d(np.arange(len(res.detections.points_px)), idx)
        assert np.all(res.detections.beacon_ids[others] < 0)
        assert len(others) <= len(t.lights_px)


def test_a_frame_without_its_bow_is_not_ok():
    spec = replace(SMALL, drop_bow=True)
    for t in _frames(spec, 2, seed=11):
        res, idx = _run("cog", t)
        assert np.all(idx >= 0)
        assert not res.ok and "bow" in res.reason
        assert np.all(res.detections.beacon_ids[idx[t.beacon_id < gen.N_RING]] < 0)


def test_saturated_cores_are_found_and_identified():
    spec = replace(SMALL, saturate=True, full_well_e=1_000.0, uneven=(0.4, 1.0))
    frames = _frames(spec, 3, seed=12)
    assert any(t.saturated.any() for t in frames)
    for t in frames:
        res, idx = _run("gauss", t)
        assert res.ok, res.reason
        np.testing.assert_array_equal(res.detections.beacon_ids[idx], t.beacon_id)


def test_the_generator_bound_matches_the_textbook_limit():
    # Independent check of the generator's CRB: a bright spot with no background and no
    # read noise has the photon-limited centroid bound sigma_total / sqrt(N) per axis,
    # sigma_total^2 = sigma^2 + 1/12 (the pixel's own width), within a few per cent.
    spec = replace(SMALL, background_e=1e-9, read_noise_e=1e-9, bits=16,
                   sigma_px=(2.0, 2.0), flux_e=(1e5, 1e5))
    t = _frames(spec, 1, seed=13)[0]
    expect = math.sqrt(2.0**2 + 1.0 / 12.0) / math.sqrt(1e5)
    np.testing.assert_allclose(t.crb_px, expect, rtol=0.05)


@pytest.mark.parametrize("peer", ["sep", "photutils"])
def test_peers_run_beside_ours(peer, uneven_frames):
    pytest.importorskip(peer)
    assert peer in registry.names()
    frames = uneven_frames[:4]
    e_peer = _errors(peer, frames)
    e_ours = _errors("gauss", frames)
    assert e_peer.shape[0] >= 0.9 * 13 * len(frames)
    # both near the bound: ours no worse than the peer beyond the sampling error
    r_peer = float(np.sqrt(np.mean(e_peer**2)))
    r_ours = float(np.sqrt(np.mean(e_ours**2)))
    assert r_ours < r_peer * (1.0 + 3.0 / math.sqrt(2.0 * e_ours.size)), (r_ours, r_peer)


def test_a_missing_peer_package_says_how_to_install_it(monkeypatch):
    monkeypatch.delitem(registry._REGISTRY, "sep", raising=False)
    with pytest.raises(ConfigError, match=r"deckpose\[peers\]"):
        registry.get("sep")


def test_dim_beacons_on_dark_8bit_frames_are_all_found_without_false_ones():
    """Uneven beacons (x U(0.4, 1)) on the dark 8-bit frames: every one found, nothing else.

    The significance search took the noise as at least 1 DN a channel, 3.2x these frames' (0.54
    DN on the channel sum, mostly the rounding), which dropped the dimmest beacons (1,600 e, a
    red bow at 3,600 e: 6 of 156 on the 8 MP benchmark). Their integrated SNR against the
    measured noise is 4-11 on a linear matched filter, and far more on the stored DN, whose
    rounding lifts a pixel 0.1 DN above the background to 1 DN: they are there to be found.
    Chance clusters of 1-DN pixels are counts, not Gaussian noise; the threshold keeps the
    Gaussian tail probability (skew_threshold), so no false detection is allowed.
    """
    for t in _frames(replace(DARK_8BIT, uneven=(0.4, 1.0)), 6, seed=23):
        res, idx = _run("cog", t)
        assert np.all(idx >= 0), (t.flux_e[idx < 0], t.sigma_px[idx < 0])
        assert len(res.detections.points_px) == t.beacon_id.size, "a false detection"
        assert res.ok, res.reason
        np.testing.assert_array_equal(res.detections.beacon_ids[idx], t.beacon_id)
