"""Identification against the exact projection of the layout (deckpose.projection)."""

import numpy as np
import pytest
from deckpose.detect.identify import identify_beacons

from deckpose.camera import preset
from deckpose.layout import DeckLayout
from deckpose.pose import CameraPose, ShipPose
from deckpose.projection import project_layout
from deckpose.records import UNASSIGNED

LAYOUT = DeckLayout()
CAMERA = preset("8mp")
WHITE, RED = (100.0, 100.0, 90.0), (100.0, 10.0, 5.0)


def scene(rng, *, hide=None, glint=False, noise_px=0.1, tilt_deg=10.0, layout=LAYOUT):
    ship = ShipPose(
        *np.radians(rng.uniform([-tilt_deg, -tilt_deg, -180], [tilt_deg, tilt_deg, 180]))
    )
    pr = project_layout(layout, ship, CameraPose.nadir(float(rng.uniform(20, 80))), CAMERA)
    ids = np.flatnonzero(pr.visible)
    if hide is not None:
        ids = ids[ids != hide]
    pts = pr.points_px[ids] + rng.normal(0, noise_px, (len(ids), 2))
    rgb = np.array([RED if i == layout.bow_id else WHITE for i in ids])
    if glint:
        centre = pts.mean(axis=0)
        while True:  # a glint well away from every beacon
            g = centre + rng.uniform(-400, 400, 2)
            if np.min(np.linalg.norm(pts - g, axis=1)) > 60:
                break
        pts, ids, rgb = np.vstack([pts, g]), np.append(ids, UNASSIGNED), np.vstack([rgb, WHITE])
    perm = rng.permutation(len(ids))
    return pts[perm], ids[perm], rgb[perm]


@pytest.mark.parametrize("seed", range(8))
def test_ids_match_the_projection(seed):
    rng = np.random.default_rng(seed)
    pts, ids, rgb = scene(rng)
    r = identify_beacons(pts, LAYOUT, CAMERA, rgb_flux=rgb)
    assert r.ok, r.reason
    np.testing.assert_array_equal(r.beacon_ids, ids)


@pytest.mark.parametrize("seed", range(8))
def test_one_hidden_beacon_and_one_glint(seed):
    rng = np.random.default_rng(100 + seed)
    pts, ids, rgb = scene(rng, hide=int(rng.integers(1, LAYOUT.n_ring + 1)), glint=True)
    r = identify_beacons(pts, LAYOUT, CAMERA, rgb_flux=rgb)
    assert r.ok, r.reason
    np.testing.assert_array_equal(r.beacon_ids, ids)


def test_ring_ids_run_counter_clockwise_in_the_displayed_image():
    # Zero attitude, nadir camera, image top = bow: beacon 0 straight up in the image,
    # beacon 3 (90 deg toward port) to the image LEFT.
    pr = project_layout(LAYOUT, ShipPose(), CameraPose.nadir(40.0), CAMERA)
    c = pr.points_px[LAYOUT.n_ring]
    assert pr.points_px[0, 1] < c[1] and abs(pr.points_px[0, 0] - c[0]) < 1e-6
    assert pr.points_px[3, 0] < c[0]
    rgb = np.array([RED if i == 0 else WHITE for i in range(LAYOUT.n_beacons)])
    r = identify_beacons(pr.points_px, LAYOUT, CAMERA, rgb_flux=rgb)
    np.testing.assert_array_equal(r.beacon_ids, np.arange(LAYOUT.n_beacons))


def test_mono_frames_leave_ring_ids_unassigned_with_a_reason():
    rng = np.random.default_rng(1)
    pts, ids, _ = scene(rng)
    r = identify_beacons(pts, LAYOUT, CAMERA, rgb_flux=None)
    assert not r and "mono" in r.reason
    assert set(r.beacon_ids[ids != LAYOUT.n_ring]) == {UNASSIGNED}
    assert (
        r.beacon_ids[list(ids).index(LAYOUT.n_ring)] == LAYOUT.n_ring
    )  # the centre is still found


def test_hidden_bow_is_reported_not_guessed():
    rng = np.random.default_rng(2)
    pts, ids, rgb = scene(rng, hide=LAYOUT.bow_id)
    r = identify_beacons(pts, LAYOUT, CAMERA, rgb_flux=rgb)
    assert not r and "bow beacon not found" in r.reason
    assert set(r.beacon_ids[ids != LAYOUT.n_ring]) == {UNASSIGNED}


def test_too_few_blobs_is_a_reason_not_an_exception():
    r = identify_beacons(np.array([[10.0, 10.0], [20.0, 30.0]]), LAYOUT, CAMERA)
    assert not r and "only 2 blobs" in r.reason


def test_layout_without_centre_and_lens_distortion():
    lay = DeckLayout(n_ring=8, has_centre=False)
    cam = type(CAMERA)(CAMERA.width_px, CAMERA.height_px, CAMERA.K, [-0.15, 0.05, 0.0, 0.0, 0.0])
    ship = ShipPose(0.1, -0.05, 1.0)
    pr = project_layout(lay, ship, CameraPose.nadir(30.0), cam)
    rgb = np.array([RED if i == 0 else WHITE for i in range(lay.n_beacons)])
    r = identify_beacons(pr.points_px, lay, cam, rgb_flux=rgb)
    assert r.ok, r.reason
    np.testing.assert_array_equal(r.beacon_ids, np.arange(lay.n_beacons))


def test_a_colour_on_one_ring_blob_only_does_not_name_the_bow():
    # Colour measured on one ring blob (the others' flux not positive: redness NaN): its
    # margin over the others' median was NaN, which passed the margin test, and the ring ids
    # were assigned from that blob as if it were the bow.
    rng = np.random.default_rng(7)
    pts, ids, rgb = scene(rng)
    dark = np.zeros_like(rgb)
    dark[np.flatnonzero(ids == 5)[0]] = WHITE  # one white ring blob with colour, none red
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")  # and no "All-NaN slice" warning on the way
        r = identify_beacons(pts, LAYOUT, CAMERA, rgb_flux=dark)
    assert not r.ok and "only one ring blob" in r.reason
