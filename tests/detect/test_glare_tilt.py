"""A bright spot's surround tilted by its neighbours' glare: the centre's bias goes into its covariance.

A large, bright spot is measured above a flat pedestal. A background tilt left in its window
moves the windowed centroid by ``g sum(w x^2) / F`` (:meth:`Candidate.surround_tilt_cov`). In
the rendered 2 m hover (spots of sigma 49 px, 12-15 sigmas apart, 5 % of each beacon's light in
a glow of 4x its sigma) the neighbours' glow moved ``cog``'s centres 0.03-0.04 px toward them,
against noise sigmas of 0.003 px, and the pose's height was 6-16 of its sigmas off. The
border's tilt now bounds that bias in the covariance.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from deckpose.detect.candidate import Candidate
from deckpose.detect.centroid import cog_centroid
from deckpose.detect.core_fit import core_fit
from deckpose.detect.frame_detection import detect_frame

from deckpose.camera import preset
from deckpose.layout import DeckLayout
from deckpose.records import Frame

H, W = 480, 640
SIGMA_PX = 9.0  # the hover's spots scaled to this frame
GLOW_SCALE = 4.0  # the renderer's default halo: 4x the core's sigma
GLOW_FRACTION = 0.05  # ... carrying 5 % of the light


def _frame(centres: np.ndarray, glow_fraction: float, seed: int) -> np.ndarray:
    """16-bit mono image, 1 DN per electron: Gaussian spots, each with its glow, on a dark deck.

    Shot noise and 2 e of read noise; peaks of 40 000 e, so each centre's noise sigma is
    about ``9 px / sqrt(2e7 e)`` = 0.002 px, as bright as the hover's spots relative to their size.
    """
    rng = np.random.default_rng(seed)
    vv, uu = np.mgrid[0:H, 0:W]
    img = np.full((H, W), 12.0)
    flux = 40000.0 * 2 * math.pi * SIGMA_PX**2
    for u, v in centres:
        d2 = (uu - u) ** 2 + (vv - v) ** 2
        s_core, s_glow = SIGMA_PX, GLOW_SCALE * SIGMA_PX
        img += (1 - glow_fraction) * flux / (2 * math.pi * s_core**2) * np.exp(-d2 / (2 * s_core**2))
        img += glow_fraction * flux / (2 * math.pi * s_glow**2) * np.exp(-d2 / (2 * s_glow**2))
    return np.clip(np.round(rng.normal(img, np.sqrt(img + 4.0))), 0, 65535).astype(np.uint16)


def _centres(seed: int) -> np.ndarray:
    # a centre and six around it, 10 spot sigmas away: each ring spot's surround is tilted
    # toward the centre by the centre's glow (2.5 glow sigmas away)
    rng = np.random.default_rng(100 + seed)
    ring = [[320.0 + 10 * SIGMA_PX * math.cos(a), 240.0 + 10 * SIGMA_PX * math.sin(a)]
            for a in np.linspace(0, 2 * math.pi, 6, endpoint=False)]
    return np.array([[320.0, 240.0]] + ring) + rng.uniform(-0.5, 0.5, (7, 2))


def _measure(glow_fraction: float, seed: int, detector: str = "cog") -> tuple[np.ndarray, np.ndarray]:
    """Per found spot: error against its drawn centre (px, (n, 2)) and its reported sd (px, (n, 2))."""
    centres = _centres(seed)
    img = _frame(centres, glow_fraction, seed)
    cam = preset("4mp-thesis").with_size(W, H)
    fd = detect_frame(Frame(np.repeat(img[..., None], 3, axis=2), cam), detector, DeckLayout(),
                      identify=False)
    pts = fd.detections.points_px
    assert len(pts) == 7, (len(pts), fd.reason)
    nearest = np.linalg.norm(pts[:, None, :] - centres[None, :, :], axis=2).argmin(axis=1)
    err = pts - centres[nearest]
    cov = fd.detections.covariance_px2
    sd = np.sqrt(np.stack([cov[:, 0, 0], cov[:, 1, 1]], axis=1))
    ring = nearest != 0
    return err[ring], sd[ring]


@pytest.mark.parametrize("detector", ["cog", "gauss"])
def test_glare_bias_is_inside_the_reported_covariance(monkeypatch, detector):
    # cog: a windowed centroid; gauss: a censored least-squares fit of the core (core_fit),
    # which propagates the tilt through its normal equations
    errs, sds, errs0, sds0 = [], [], [], []
    for seed in range(3):
        e, s = _measure(GLOW_FRACTION, seed, detector)
        e0, s0 = _measure(0.0, seed, detector)
        errs.append(e)
        sds.append(s)
        errs0.append(e0)
        sds0.append(s0)
    err, sd = np.concatenate(errs), np.concatenate(sds)
    err0, sd0 = np.concatenate(errs0), np.concatenate(sds0)
    # Without glow the ring spots are unbiased: their errors lie within a few of their
    # sigmas (Gaussian errors over 36 axis values: 4 sigmas is a 0.2 % event).
    assert np.abs(err0 / sd0).max() < 4.0, err0 / sd0
    # With glow the errors lie within the reported covariance, which bounds them ...
    assert np.abs(err / sd).max() < 3.0, err / sd
    # ... and the bound is not vacuous: the reported sd stays below 10x the largest error.
    assert sd.max() < 10 * np.abs(err).max(), (sd.max(), np.abs(err).max())
    # The same detector without the term reports the noise alone, which the glow's bias
    # exceeds many times: that covariance would lie.
    monkeypatch.setattr(Candidate, "surround_bias_cov", lambda self, *a: np.zeros((2, 2)))
    e_n, sd_n = _measure(GLOW_FRACTION, 0, detector)
    assert np.abs(e_n / sd_n).max() > 3.0, e_n / sd_n


def _spot_candidate(tilt_dn_per_px: tuple[float, float], noise_dn: float = 1.0) -> tuple[Candidate, float, float]:
    """A clipped-signal candidate of one unclipped Gaussian spot plus a linear tilt, no noise.

    ``noise_dn`` is the noise the candidate's model assumes (gain 1 DN/e).
    """
    n, uc, vc, s = 121, 60.3, 59.8, 8.0
    vv, uu = np.mgrid[0:n, 0:n].astype(float)
    spot = 2000.0 * np.exp(-((uu - uc) ** 2 + (vv - vc) ** 2) / (2 * s * s))
    gu, gv = tilt_dn_per_px
    pix = 50.0 + spot + gu * (uu - uc) + gv * (vv - vc)
    mask = spot > 1000.0
    cand = Candidate(pix, mask, np.zeros_like(mask), 0, 0, 50.0, (0.0, 0.0), noise_dn, 1.0, 1050.0,
                     clip_signal=True, frame_shape=(n, n), surround_grad=(gu, gv),
                     surround_grad_sd=0.0)
    return cand, uc, vc


@pytest.mark.parametrize(("above_floor", "noise_dn", "min_shift_px"), [
    (False, 1.0, 0.015),  # the disc
    # the floor pass's centre weighed by the pixels' noise (centroid.noise_weight): with
    # noise^2 / gain = 900 DN against a 2000 DN peak, the weight falls from 0.7 at the
    # centre, and the term takes the weight's slope and the disc edge's from the Newton
    # step's (0.007 px here)
    (True, 30.0, 0.005),
])
def test_tilt_term_is_the_shift_a_linear_tilt_gives(above_floor, noise_dn, min_shift_px):
    # The centroid of spot + tilt, against the same spot without the tilt: its shift must
    # equal the term's sd, |g| sum(w x^2) / F, to first order in g (here the shift is
    # ~0.02 px against a spot sigma of 8 px, so second-order terms are ~1e-3 of it).
    g = (0.04, -0.03)
    cand, _, _ = _spot_candidate(g, noise_dn)
    flat = dataclasses.replace(cand, pixels=cand.pixels - (
        g[0] * (np.arange(121)[None, :] - 60.3) + g[1] * (np.arange(121)[:, None] - 59.8)))
    tilted_row = cog_centroid(cand, 3.0, above_floor=above_floor)
    flat_row = cog_centroid(flat, 3.0, above_floor=above_floor)
    assert tilted_row is not None and flat_row is not None
    shift = math.hypot(tilted_row[0] - flat_row[0], tilted_row[1] - flat_row[1])
    no_tilt = dataclasses.replace(cand, surround_grad=(0.0, 0.0))
    noise_cov = cog_centroid(no_tilt, 3.0, above_floor=above_floor)
    assert noise_cov is not None
    term = math.sqrt(tilted_row[2][0, 0] - noise_cov[2][0, 0])
    assert shift > min_shift_px
    assert abs(term / shift - 1.0) < 0.05, (term, shift)


def test_a_tilt_within_the_noise_adds_nothing():
    cand, _, _ = _spot_candidate((0.01, 0.0))
    quiet = dataclasses.replace(cand, surround_grad_sd=0.02)  # |g|^2 < 2 sd^2: noise alone
    row, row_quiet = cog_centroid(cand, 3.0), cog_centroid(quiet, 3.0)
    base = cog_centroid(dataclasses.replace(cand, surround_grad=(0.0, 0.0)), 3.0)
    assert row is not None and row_quiet is not None and base is not None
    assert np.allclose(row_quiet[2], base[2])
    assert row[2][0, 0] > base[2][0, 0]


def test_core_fit_term_is_the_shift_a_linear_tilt_gives():
    # The same check for the censored fit (gauss's path for a bright spot): the shift a tilt
    # along u gives, against the fit without it, equals the term's sd (a round spot moves
    # alike for a tilt along u or v, so the term's larger response is this one, to ~1 %).
    g = (0.04, 0.0)
    cand, _, _ = _spot_candidate(g)
    ramp = g[0] * (np.arange(121)[None, :] - 60.3)
    flat = dataclasses.replace(cand, pixels=cand.pixels - ramp)
    start = cog_centroid(flat, 3.0, above_floor=False)
    assert start is not None
    tilted_row, flat_row = core_fit(cand, start), core_fit(flat, start)
    no_tilt_row = core_fit(dataclasses.replace(cand, surround_grad=(0.0, 0.0)), start)
    assert tilted_row is not None and flat_row is not None and no_tilt_row is not None
    shift = math.hypot(tilted_row[0] - flat_row[0], tilted_row[1] - flat_row[1])
    term = math.sqrt(tilted_row[2][0, 0] - no_tilt_row[2][0, 0])
    assert shift > 0.005
    assert abs(term / shift - 1.0) < 0.05, (term, shift)
