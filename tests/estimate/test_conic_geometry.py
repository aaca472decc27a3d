"""The circle's plane from its image: eigen route (two candidates) and imaged-centre route (one).

Each function is batch-first; these tests give it a batch of one frame (``[None]``), and the
last ones stack frames to check that a frame's answer does not depend on its neighbours.
"""

from __future__ import annotations

import numpy as np
import pytest
from deckpose.estimate.conic_geometry import (
    circle_planes,
    diameter_pairs,
    fit_ellipses,
    imaged_centres,
    planes_from_centres,
)
from scipy.spatial.transform import Rotation

from deckpose.layout import DeckLayout
from deckpose.pose import CameraPose, ShipPose, T_cam_from_deck


def imaged_centre(xy, points_deck_m, ring, centre):
    """One frame's imaged centre (a batch of one), None where there is none."""
    c, ok = imaged_centres(xy[None], points_deck_m, ring, centre)
    return c[0] if ok[0] else None


def fit_ellipse(xy):
    C, ok = fit_ellipses(xy[None])
    assert ok[0]
    return C


def _normalised_view(layout: DeckLayout, ship: ShipPose, cam: CameraPose) -> tuple[np.ndarray, np.ndarray]:
    """Exact normalised image points of every beacon and T_cam_from_deck (independent of K)."""
    T = T_cam_from_deck(ship, cam)
    X = layout.positions_deck_m() @ T[:3, :3].T + T[:3, 3]
    return X[:, :2] / X[:, 2:3], T


VIEWS = [
    (ShipPose(0.0, 0.0, 0.0), CameraPose.nadir(40.0)),
    (ShipPose(np.radians(6), np.radians(-4), np.radians(30), surge_m=2.0, sway_m=-1.5, heave_m=0.7),
     CameraPose.nadir(25.0, x_m=1.0)),
    (ShipPose(np.radians(-3), np.radians(8), np.radians(-120)),
     CameraPose.nadir(60.0, R_nadir_from_cam=Rotation.from_euler("xy", [12, -7], degrees=True).as_matrix())),
]


@pytest.mark.parametrize("ship,cam", VIEWS)
@pytest.mark.parametrize("use_centre_beacon", [True, False])
def test_imaged_centre_plane_is_exact_without_noise(ship, cam, use_centre_beacon):
    layout = DeckLayout()
    xy, T = _normalised_view(layout, ship, cam)
    ids = np.arange(layout.n_beacons)
    ring = ids < layout.n_ring
    centre = (ids == layout.centre_id) & use_centre_beacon
    c = imaged_centre(xy, layout.positions_deck_m(), ring, centre)
    # independent truth: the deck origin projected through T
    assert c == pytest.approx(T[:2, 3] / T[2, 3], abs=1e-12)
    normal, centre_m, ok = planes_from_centres(fit_ellipse(xy[ring]), c[None], xy[ring][None], layout.radius_m)
    assert ok[0]
    assert normal[0] == pytest.approx(T[:3, 2], abs=1e-9)  # deck +z in the camera frame
    assert centre_m[0] == pytest.approx(T[:3, 3], abs=1e-7 * T[2, 3])


def test_the_eigen_route_contains_the_same_plane():
    layout = DeckLayout()
    ship, cam = VIEWS[1]
    xy, T = _normalised_view(layout, ship, cam)
    ring = np.arange(layout.n_beacons) < layout.n_ring
    normals, centres, valid = circle_planes(fit_ellipse(xy[ring]), layout.radius_m)
    assert valid[0].all()
    assert min(np.linalg.norm(n - T[:3, 2]) for n in normals[0]) < 1e-8
    # the matching plane's centre is the deck origin's
    k = int(np.argmin(np.linalg.norm(normals[0] - T[:3, 2], axis=1)))
    assert centres[0, k] == pytest.approx(T[:3, 3], abs=1e-6 * T[2, 3])


def test_diameters_need_opposite_beacons():
    layout = DeckLayout()
    ring = np.arange(layout.n_beacons) < layout.n_ring
    pairs = diameter_pairs(layout.positions_deck_m(), ring)
    assert sorted(pairs) == [(i, i + 6) for i in range(6)]
    # one beacon of each of five diameters missing: one line, no centre beacon -> not determined
    keep = np.array([i for i in range(layout.n_beacons) if i not in (1, 2, 3, 4, 5, layout.centre_id)])
    xy, _ = _normalised_view(layout, *VIEWS[1])
    assert imaged_centre(xy[keep], layout.positions_deck_m()[keep], keep < layout.n_ring,
                         keep == layout.centre_id) is None
    # an odd ring has no diameters: only the centre beacon can fix the centre
    odd = DeckLayout(n_ring=7)
    assert diameter_pairs(odd.positions_deck_m(), np.arange(odd.n_beacons) < 7) == []


def test_noisy_imaged_centre_beats_the_centre_beacon_alone():
    """12 ring beacons' diameters + the centre beacon: the centre's error shrinks well below one point's."""
    layout = DeckLayout()
    xy0, T = _normalised_view(layout, *VIEWS[1])
    truth = T[:2, 3] / T[2, 3]
    rng = np.random.default_rng(4)
    sigma = 1e-4
    ids = np.arange(layout.n_beacons)
    err_all, err_beacon = [], []
    for _ in range(400):
        xy = xy0 + rng.normal(0, sigma, xy0.shape)
        c = imaged_centre(xy, layout.positions_deck_m(), ids < layout.n_ring, ids == layout.centre_id)
        err_all.append(c - truth)
        err_beacon.append(xy[layout.centre_id] - truth)
    rms_all = np.sqrt(np.mean(np.square(err_all)))
    rms_beacon = np.sqrt(np.mean(np.square(err_beacon)))
    # 6 lines (variance ~sigma^2/2 each) + 1 point: expected ratio ~ sqrt(1/13) ~ 0.28; allow MC scatter
    assert rms_all < 0.45 * rms_beacon


def test_pure_geometric_conic_is_near_the_bound_near_nadir():
    """The imaged-centre route keeps the closed-form tilt near the CRB (the eigen route was ~6x here).

    200 noisy frames of a near-nadir deck (the regime where the eccentricity says least about the
    tilt); the RMS roll/pitch error of ``conic`` with no polish must stay below 2x the bound.
    Monte Carlo scatter of an RMS over 200 trials is ~5 %, and the measured ratio is ~1.1
    (benchmarks/bench_estimators.py), so 2x fails only if the construction regresses.
    """
    from deckpose.estimate import registry
    from deckpose.estimate.crb import cramer_rao_bound
    from deckpose.estimate.registry import EstimateOptions

    from deckpose.camera import preset
    from tests.estimate.synthetic import detections_for

    layout, camera = DeckLayout(), preset("8mp")
    ship, cam = ShipPose(np.radians(1.0), np.radians(-0.5), 0.3), CameraPose.nadir(40.0)
    sigma = 0.5
    crb = np.sqrt(np.diag(cramer_rao_bound(layout, camera, ship, cam, sigma).covariance))[:2]
    rng = np.random.default_rng(11)
    opts = EstimateOptions(sigma_px=sigma, conic_polish_steps=0)
    errs = []
    for _ in range(200):
        est = registry.get("conic")(detections_for(layout, ship, cam, camera, sigma_px=sigma, rng=rng),
                                    camera, layout, opts)
        assert est.ok, est.reason
        errs.append([est.roll_rad - ship.roll_rad, est.pitch_rad - ship.pitch_rad])
    ratio = np.sqrt(np.mean(np.square(errs), axis=0)) / crb
    assert np.all(ratio < 2.0), ratio


def test_a_diameter_whose_ends_coincide_is_left_out():
    """Two opposite beacons imaged on one point have no line: the centre is the one the other
    diameters and the centre beacon give (the lines' least squares without that row)."""
    layout = DeckLayout()
    xy, _ = _normalised_view(layout, *VIEWS[1])
    ids = np.arange(layout.n_beacons)
    ring, centre = ids < layout.n_ring, ids == layout.centre_id
    rng = np.random.default_rng(3)
    xy = xy + rng.normal(0, 1e-4, xy.shape)
    bad = xy.copy()
    bad[6] = bad[0]  # beacons 0 and 6 (a diameter) on one image point
    without = np.array([i for i in ids if i not in (0, 6)])
    got = imaged_centre(bad, layout.positions_deck_m(), ring, centre)
    # independent: the same least squares with the pair's rows removed, by numpy.linalg.lstsq
    p = layout.positions_deck_m()
    pairs = [(i, j) for i, j in diameter_pairs(p, ring) if i not in (0, 6)]
    rows, rhs = [], []
    for i, j in pairs:
        n = np.array([xy[i, 1] - xy[j, 1], xy[j, 0] - xy[i, 0]])
        c = xy[i, 0] * xy[j, 1] - xy[i, 1] * xy[j, 0]
        rows.append(np.sqrt(2.0) * n / np.linalg.norm(n))
        rhs.append(-np.sqrt(2.0) * c / np.linalg.norm(n))
    rows += [[1.0, 0.0], [0.0, 1.0]]
    rhs += list(xy[layout.centre_id])
    want = np.linalg.lstsq(np.array(rows), np.array(rhs), rcond=None)[0]
    assert got == pytest.approx(want, abs=1e-12)
    assert got == pytest.approx(imaged_centre(xy[without], p[without], ring[without], centre[without]), abs=1e-12)


def test_stacked_frames_answer_as_each_alone():
    """Frames in one batch, one of them degenerate (collinear ring), answer as each frame alone
    (to rounding: a stacked matrix product may round its last bit differently)."""
    layout = DeckLayout()
    ids = np.arange(layout.n_beacons)
    ring = ids < layout.n_ring
    frames = [_normalised_view(layout, s, c)[0] for s, c in VIEWS]
    frames.append(np.column_stack([np.linspace(-1, 1, layout.n_beacons), np.zeros(layout.n_beacons)]))
    xy = np.stack(frames)
    with np.errstate(all="ignore"):
        C, ok = fit_ellipses(xy[:, ring])
        assert ok.tolist() == [True, True, True, False]
        for f in range(3):
            C1, _ = fit_ellipses(xy[f:f + 1, ring])
            np.testing.assert_allclose(C1[0], C[f], rtol=1e-12, atol=1e-15)
        n, X, valid = circle_planes(C, layout.radius_m)
        assert valid[:3].all() and not valid[3].any()
        for f in range(3):
            n1, X1, _ = circle_planes(C[f:f + 1], layout.radius_m)
            np.testing.assert_allclose(n1[0], n[f], rtol=1e-12, atol=1e-15)
            np.testing.assert_allclose(X1[0], X[f], rtol=1e-12, atol=1e-12)


def test_ellipse_conics_carry_one_sign_whatever_the_eigen_solver_returns():
    """The fitted conic's sign is fixed (quadratic part positive definite), so a frame's conic
    is the same alone or stacked, on any LAPACK (an eigenvector's sign is the solver's choice)."""
    rng = np.random.default_rng(3)
    t = np.linspace(0, 2 * np.pi, 12, endpoint=False)
    frames = []
    for _ in range(50):
        a, b = rng.uniform(0.05, 0.5, 2)
        phi, cx, cy = rng.uniform(-np.pi, np.pi), *rng.uniform(-0.5, 0.5, 2)
        x, y = a * np.cos(t), b * np.sin(t)
        frames.append(np.column_stack([cx + x * np.cos(phi) - y * np.sin(phi),
                                       cy + x * np.sin(phi) + y * np.cos(phi)]))
    xy = np.stack(frames)
    C, ok = fit_ellipses(xy)
    assert ok.all()
    assert (np.linalg.eigvalsh(C[:, :2, :2]) > 0).all()
    # each conic still passes through its points (the sign change keeps the curve)
    h = np.concatenate([xy, np.ones(xy.shape[:2] + (1,))], axis=2)
    residual = np.einsum("fni,fij,fnj->fn", h, C, h)
    assert np.abs(residual).max() < 1e-9
    for f in (0, 17, 49):
        np.testing.assert_allclose(fit_ellipses(xy[f:f + 1])[0][0], C[f], rtol=1e-12, atol=1e-15)
