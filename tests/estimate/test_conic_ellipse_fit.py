"""The ring's direct least-squares ellipse fit (``conic_geometry.fit_ellipses``), frame by frame."""

import numpy as np
from deckpose.estimate.conic_geometry import fit_ellipses


def fit_ellipse_direct(pts):
    """One frame's conic (a batch of one), None where the points admit no ellipse."""
    with np.errstate(all="ignore"):
        C, ok = fit_ellipses(np.asarray(pts, dtype=float)[None])
    return C[0] if ok[0] else None


def test_exact_ellipse_recovered_in_float64():
    # Ellipse centre (0.3, -0.2), semi-axes 0.5, 0.2, rotated 30 deg, in "normalised" units.
    t = np.linspace(0, 2 * np.pi, 12, endpoint=False)
    c, s = np.cos(np.pi / 6), np.sin(np.pi / 6)
    x0 = 0.5 * np.cos(t)
    y0 = 0.2 * np.sin(t)
    pts = np.column_stack([0.3 + c * x0 - s * y0, -0.2 + s * x0 + c * y0])
    C = fit_ellipse_direct(pts)
    h = np.column_stack([pts, np.ones(len(pts))])
    assert np.max(np.abs(np.einsum("ni,ij,nj->n", h, C, h))) < 1e-14
    # Centre from the conic: C[:2,:2] x = -C[:2,2].
    np.testing.assert_allclose(np.linalg.solve(C[:2, :2], -C[:2, 2]), [0.3, -0.2], atol=1e-12)
    # Sub-0.005 px detail survives (OpenCV's float32 fitEllipse would not): shift by 1e-6.
    C2 = fit_ellipse_direct(pts + [1e-6, 0.0])
    np.testing.assert_allclose(np.linalg.solve(C2[:2, :2], -C2[:2, 2]), [0.3 + 1e-6, -0.2], atol=1e-12)


def test_degenerate_inputs_give_none():
    assert fit_ellipse_direct(np.zeros((5, 2))) is None
    line = np.column_stack([np.linspace(0, 1, 8), np.linspace(0, 2, 8)])
    assert fit_ellipse_direct(line) is None
    assert fit_ellipse_direct(np.full((6, 2), np.nan)) is None
