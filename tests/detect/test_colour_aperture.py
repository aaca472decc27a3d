"""A blob's colour where the beacon sits in a dark fitting on a bright deck (day frames).

By day a beacon's dark housing is darker than the deck around it. A colour aperture wider
than the housing (a detector's wide fitted size on a clipped spot) takes in the housing,
and the annulus's deck level, subtracted over it, made the flux negative: the red bow
read as not red. The flux of a light is positive; :func:`blob_rgb_flux` measures such a
blob again in a smaller aperture. The frame here is built by hand (no renderer): a flat
deck, dark discs, pixel-integrated Gaussian spots.
"""

from __future__ import annotations

import numpy as np
from deckpose.detect.colour import blob_rgb_flux, redness
from deckpose.detect.identify import identify_beacons
from scipy.special import erf

from deckpose.camera import CameraModel
from deckpose.layout import DeckLayout

DECK_DN = np.array([1480.0, 1420.0, 1360.0])  # a day deck, 12-bit (the ladder's real rung)
FITTING_DN = np.array([300.0, 300.0, 300.0])
FITTING_PX = 40.0
SIGMA_PX = 3.0


def _pixel_gauss(c: float, sigma: float, n: int) -> np.ndarray:
    edges = (np.arange(n + 1) - 0.5 - c) / (np.sqrt(2) * sigma)
    return 0.5 * np.diff(erf(edges))


def _day_frame(points: np.ndarray, colours: np.ndarray, flux_dn: float) -> np.ndarray:
    """(540, 960, 3) float frame: deck, a dark fitting under each beacon, its spot on top."""
    H, W = 540, 960
    img = np.broadcast_to(DECK_DN, (H, W, 3)).copy()
    vv, uu = np.mgrid[0:H, 0:W]
    for (u, v), rgb in zip(points, colours):
        img[np.hypot(uu - u, vv - v) <= FITTING_PX] = FITTING_DN
        spot = np.outer(_pixel_gauss(v, SIGMA_PX, H), _pixel_gauss(u, SIGMA_PX, W))
        img += flux_dn * spot[..., None] * rgb[None, None, :]
    return img


def _ring(n: int = 12, radius_px: float = 200.0) -> np.ndarray:
    ang = np.pi / 2 - 2 * np.pi * np.arange(n) / n  # bow (id 0) at the top, ids clockwise as displayed
    return np.column_stack([480 + radius_px * np.cos(ang), 270 - radius_px * np.sin(ang)])


def test_a_wide_aperture_over_a_dark_fitting_still_sees_a_red_bow() -> None:
    bow = np.array([[480.0, 270.0]])
    img = _day_frame(bow, np.array([[0.8, 0.1, 0.1]]), 3e5)
    right = blob_rgb_flux(img, bow, np.array([2.0 * SIGMA_PX]))
    assert redness(right)[0] > 0.7  # the spot's own colour, 0.8 (the deck's level is subtracted)
    # 46 px, as a wide fitted size gave: the whole fitting in the aperture, deck in the annulus
    wide = blob_rgb_flux(img, bow, np.array([46.0]))
    assert wide.sum() > 0  # no negative flux for a light
    assert redness(wide)[0] > 0.7


def test_the_colour_in_a_right_sized_aperture_is_unchanged() -> None:
    """The rule only acts on a non-positive flux: a spot on a flat deck is measured as before."""
    pt = np.array([[300.3, 200.7]])
    img = np.broadcast_to(DECK_DN, (540, 960, 3)).copy()
    img += 2e5 * np.outer(_pixel_gauss(200.7, SIGMA_PX, 540), _pixel_gauss(300.3, SIGMA_PX, 960))[..., None] \
        * np.array([0.8, 0.1, 0.1])
    got = blob_rgb_flux(img, pt, np.array([4 * SIGMA_PX]))
    # the aperture holds all but the spot's tail beyond 4 sigma; the annulus is flat deck
    np.testing.assert_allclose(got[0], 2e5 * np.array([0.8, 0.1, 0.1]), rtol=2e-3)


def test_identification_finds_the_bow_with_oversized_apertures_on_dark_fittings() -> None:
    pts = np.vstack([_ring(), [[480.0, 270.0]]])  # 12 ring beacons and the centre
    colours = np.ones((13, 3)) / 3
    colours[0] = [0.8, 0.1, 0.1]
    img = _day_frame(pts, colours, 3e5)
    rgb = blob_rgb_flux(img, pts, np.full(13, 46.0))  # every aperture wider than its fitting
    cam = CameraModel(960, 540, np.array([[800.0, 0, 479.5], [0, 800.0, 269.5], [0, 0, 1]]))
    ident = identify_beacons(pts, DeckLayout(), cam, rgb_flux=rgb)
    assert ident.ok, ident.reason
    assert ident.beacon_ids[0] == 0 and ident.beacon_ids[12] == 12
    assert sorted(ident.beacon_ids[1:12]) == list(range(1, 12))
