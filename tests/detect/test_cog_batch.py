"""``cog`` measures all the candidates of a frame together: each as it would be alone."""

from __future__ import annotations

import dataclasses

import numpy as np
from deckpose.detect.candidates import find_candidates
from deckpose.detect.centroid import cog_centroids
from deckpose.detect.crb import centroid_crb_px2
from deckpose.detect.registry import DetectorOptions
from deckpose.detect.synthetic import SensorModel, render_spots

from deckpose.camera import preset
from deckpose.records import Frame

SENSOR = SensorModel(gain_dn_per_e=1.0, read_noise_e=3.0, background_e=20.0, bit_depth=16)


def _frame() -> tuple[Frame, np.ndarray, np.ndarray, np.ndarray]:
    """Spots of three sizes (windows of different shapes), one 6 px from the frame's left edge."""
    rng = np.random.default_rng(11)
    pts = np.array([[6.3, 150.2], [120.6, 60.3], [250.1, 200.8], [400.4, 90.6], [520.7, 250.2]])
    sigma = np.array([1.5, 1.2, 2.5, 4.0, 2.5])
    # the same peak for every spot (flux ~ sigma^2), so the bright-spot search finds them all
    flux = 2e5 * (sigma / 2.5) ** 2
    img = render_spots((300, 640), pts, sigma, flux, SENSOR, rng)
    return Frame(img, preset("8mp").with_size(640, 300)), pts, sigma, flux


def test_a_batch_measures_each_candidate_as_alone_and_near_the_truth() -> None:
    frame, pts, sigma, flux = _frame()
    cands, reason = find_candidates(frame, DetectorOptions(gain_dn_per_e=1.0))
    assert not reason and len(cands) == len(pts)
    assert len({c.pixels.shape for c in cands}) > 2  # stacked windows of different shapes
    assert all(c.clip_signal for c in cands)  # bright spots: the disc-windowed iteration
    assert min(c.u0 for c in cands) == 0  # one window at the frame's edge
    together = cog_centroids(cands)
    for c, row in zip(cands, together):
        alone = cog_centroids([c])[0]
        assert row is not None and alone is not None
        # the same sums, added in another order: equal to float rounding (1e-9 px is a
        # million times below these spots' bounds)
        np.testing.assert_allclose(row[:2], alone[:2], rtol=0, atol=1e-9)
        np.testing.assert_allclose(row[2], alone[2], rtol=1e-9)
        np.testing.assert_allclose(row[3:5], alone[3:5], rtol=1e-12)  # flux and sigma
    # and each centre within 5 of its Cramer-Rao sigmas of the truth (the disc-windowed cog is
    # 1.0-1.2x the bound on such spots: 5 sigma is a 1e-6 chance per axis)
    got = np.array([r[:2] for r in together if r is not None])
    for p, s, f in zip(pts, sigma, flux):
        k = int(np.argmin(np.hypot(*(got - p).T)))
        crb = np.sqrt(np.diag(centroid_crb_px2(p[0], p[1], s, f, SENSOR)))
        assert np.all(np.abs(got[k] - p) < 5 * crb), (p, got[k], crb)


def test_degenerate_candidates_are_none_in_their_place() -> None:
    frame, _pts, _sigma, _flux = _frame()
    cands, _ = find_candidates(frame, DetectorOptions(gain_dn_per_e=1.0))
    # a candidate without any signal has no centroid; the others are measured as before
    empty = dataclasses.replace(cands[1], pixels=np.zeros_like(cands[1].pixels), background_dn=0.0)
    rows = cog_centroids([cands[0], empty, cands[2]])
    assert rows[1] is None
    assert rows[0] is not None and rows[2] is not None
    np.testing.assert_allclose(rows[2][:2], cog_centroids([cands[2]])[0][:2], rtol=0, atol=1e-9)
    assert cog_centroids([]) == []
