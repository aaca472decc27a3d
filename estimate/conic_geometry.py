"""The conic method's geometry, batch-first (a lone frame is a batch of one).

* :func:`fit_ellipses`: the ring's ellipse, a direct least-squares fit in float64
  (Fitzgibbon, Pilu & Fisher 1999 in the numerically stable form of Halíř & Flusser
  1998, with Hartley normalisation: the conic ``a x² + b xy + c y² + d x + e y + f = 0``
  minimising the algebraic distance subject to ``4ac - b² = 1``, always an ellipse;
  nothing is rounded to float32, unlike OpenCV's ``fitEllipse*``).
* :func:`circle_planes`: the two candidate supporting planes of a circle of known
  radius imaged as a conic (the eigen route).
* :func:`imaged_centres` and :func:`planes_from_centres`: the image of the deck centre,
  from the centre beacon and the lines through diametrically opposite ring beacons, and
  the plane whose vanishing line is its polar (no ambiguity).
* :func:`in_plane_alignment`: the deck's rotation about the plane normal and its
  centre offset from the labelled beacons (2-D Procrustes).

Every function takes ``F`` frames stacked and returns a validity mask where a frame has
no answer. NaN and inf are expected in the frames that are not valid: call these under
``np.errstate(all="ignore")`` (:func:`~estimate.frames_driver.settle_batch` does).

The geometry. In normalised camera coordinates the image of a circle is the cone
``X^T C X = 0`` (C symmetric, signature (+, +, -) after a sign flip). With the
eigenvalues ``l1 >= l2 > 0 > l3`` and eigenvectors ``e1, e2, e3``,
``C - l2 I = (a.X)(b.X)`` with ``a, b = sqrt(l1 - l2) e1 ± sqrt(l2 - l3) e3``,
so on every plane ``a.X = k`` (or ``b.X = k``) the cone meets the sphere
``l2 |X|² + k (b.X) = 0`` through the camera centre: a circle. Those are the two
candidate supporting planes; the known radius fixes ``k``. The image of the
circle's centre is the pole of the plane's vanishing line, ``C^-1 n``, which is
what lets the imaged centre beacon tell the two candidates apart.

Conversely, when the image of the centre is known, the plane follows without
the eigen-decomposition and its two-fold ambiguity (:func:`planes_from_centres`):
the centre is the pole of the line at infinity, and poles and polars survive
projection, so the vanishing line of the deck is the polar ``l = C c`` of the
imaged centre ``c``, and in normalised coordinates the deck normal is ``l``
itself. The imaged centre is measured by :func:`imaged_centres`: the centre
beacon, and the lines through diametrically opposite ring beacons, which all
meet at the image of the centre (incidence is projective too). Using every
labelled ring beacon this way makes the normal first-order in the tilt and keeps
the closed-form pose near the Cramér–Rao bound, where the eigen route, whose
tilt comes from the ellipse's eccentricity (second order in the tilt), is
several times above it near nadir.
"""

from __future__ import annotations

import functools

import numpy as np
from deckpose.estimate.least_squares import solve_batch
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

#: Inverse of the ellipse constraint matrix C1 of the Halir-Flusser direct fit (4ac - b^2 = 1).
C1_INV = np.array([[0.0, 0.0, 0.5], [0.0, -1.0, 0.0], [0.5, 0.0, 0.0]])
C1_INV.setflags(write=False)

#: Two ring beacons are diametrically opposite when their positions sum to less than this x radius.
_OPPOSITE_TOL = 1e-9


def diameter_pairs(points_deck_m: FloatArray, ring: BoolArray) -> list[tuple[int, int]]:
    """Pairs of rows whose deck positions are diametrically opposite ring beacons.

    Parameters
    ----------
    points_deck_m : (N, 3) array of float
        Deck positions of the observations, metres (centre at the origin).
    ring : (N,) array of bool
        Which rows are ring beacons.

    Returns
    -------
    list of (int, int)
        Row pairs ``(i, j)``, ``i < j``, with ``p_i = -p_j``.
    """
    idx = np.flatnonzero(ring)
    p = points_deck_m[idx, :2]
    scale = float(np.max(np.linalg.norm(p, axis=1))) if len(idx) else 0.0
    sums = np.linalg.norm(p[:, None, :] + p[None, :, :], axis=2)
    a, b = np.nonzero(np.triu(sums <= _OPPOSITE_TOL * max(scale, 1.0), k=1))
    return [(int(idx[i]), int(idx[j])) for i, j in zip(a, b)]


#: The camera's x and y axes (the in-plane basis of :func:`in_plane_alignment` starts from them).
_UNIT_X = np.array([1.0, 0.0, 0.0])
_UNIT_Y = np.array([0.0, 1.0, 0.0])
_UNIT_X.setflags(write=False)
_UNIT_Y.setflags(write=False)

_EYE2 = np.eye(2)
_EYE2.setflags(write=False)

#: Machine epsilon of float64 (numpy.linalg.lstsq's rank cut-off).
_EPS = float(np.finfo(np.float64).eps)


def _cross(a: FloatArray, b: FloatArray) -> FloatArray:
    """``np.cross`` of (F, 3) vectors, the same products and differences without its axis handling."""
    out = np.empty(np.broadcast_shapes(a.shape, b.shape))
    a0, a1, a2 = a[:, 0], a[:, 1], a[:, 2]
    b0, b1, b2 = b[:, 0], b[:, 1], b[:, 2]
    out[:, 0] = a1 * b2 - a2 * b1
    out[:, 1] = a2 * b0 - a0 * b2
    out[:, 2] = a0 * b1 - a1 * b0
    return out


@functools.lru_cache(maxsize=64)
def _diameter_rows_cached(points: bytes, ring: bytes, n: int) -> NDArray[np.int64]:
    pts = np.frombuffer(points, dtype=np.float64).reshape(n, 3)
    rows = np.asarray(diameter_pairs(pts, np.frombuffer(ring, dtype=np.bool_)), dtype=np.int64).reshape(-1, 2)
    rows.flags.writeable = False
    return rows


def _diameter_rows(points_deck_m: FloatArray, ring: BoolArray) -> NDArray[np.int64]:
    """:func:`diameter_pairs` as a (P, 2) array, computed once per beacon set."""
    pts = np.ascontiguousarray(points_deck_m, dtype=np.float64)
    return _diameter_rows_cached(pts.tobytes(), np.ascontiguousarray(ring, dtype=np.bool_).tobytes(),
                                 pts.shape[0])


def _eig_batch(M: FloatArray) -> tuple[FloatArray, FloatArray, BoolArray]:
    """Real parts of the eigenvalues (F, 3) and eigenvectors (F, 3, 3) of each matrix, and success."""
    ok = np.ones(M.shape[0], dtype=bool)
    try:
        w, V = np.linalg.eig(M)
    except np.linalg.LinAlgError:
        w, V = np.zeros((M.shape[0], 3), dtype=complex), np.zeros(M.shape, dtype=complex)
        for i in range(M.shape[0]):
            try:
                w[i], V[i] = np.linalg.eig(M[i])
            except np.linalg.LinAlgError:
                ok[i] = False
    return np.real(w), np.real(V), ok


#: Columns of the normalised points whose products are the quadratic terms (x x, x y, y y).
_QUADRATIC_LEFT = np.array([0, 0, 1])
_QUADRATIC_RIGHT = np.array([0, 1, 1])
#: The first two diagonal entries of a 3 x 3 matrix.
_DIAGONAL_XY = np.array([0, 1])

#: The conic matrix (row-major, 9) of the coefficients ``(A, B, C, D, E, F)`` of
#: ``A x^2 + B xy + C y^2 + D x + E y + F``: each entry one coefficient times 1 or 1/2 (exact).
_CONIC_FROM_COEFFICIENTS = np.zeros((6, 9))
for _entry, (_k, _f) in enumerate(((0, 1.0), (1, 0.5), (3, 0.5), (1, 0.5), (2, 1.0), (4, 0.5), (3, 0.5),
                                    (4, 0.5), (5, 1.0))):
    _CONIC_FROM_COEFFICIENTS[_k, _entry] = _f
_CONIC_FROM_COEFFICIENTS.setflags(write=False)


def fit_ellipses(points: FloatArray) -> tuple[FloatArray, BoolArray]:
    """Direct least-squares ellipse (Halíř–Flusser, normalised) of each frame's points.

    Parameters
    ----------
    points : (F, N, 2) array of float
        N >= 5 finite points per frame (normalised image coordinates).

    Returns
    -------
    C : (F, 3, 3) array of float
        Conic matrices scaled to unit Frobenius norm, signed so that their upper-left
        2 x 2 block (the quadratic part) is positive definite (NaN where not ok).
    ok : (F,) array of bool
        Where the points admit an ellipse (finite, not collinear or degenerate).
    """
    F, n = points.shape[0], points.shape[1]
    mean = points.sum(axis=1) / n  # (np.mean's arithmetic without its wrapper)
    q = points - mean[:, None, :]
    s = np.sqrt((q * q).sum(axis=2).sum(axis=1) / n)
    ok = s > 0
    q = q / s[:, None, None]
    D1 = q[..., _QUADRATIC_LEFT] * q[..., _QUADRATIC_RIGHT]  # (x x, x y, y y)
    D2 = np.empty(q.shape[:2] + (3,))
    D2[..., :2] = q
    D2[..., 2] = 1.0
    D1t = D1.swapaxes(1, 2)
    S1 = D1t @ D1
    S2 = D1t @ D2
    S3 = D2.swapaxes(1, 2) @ D2
    if not ok.all():
        S3[~ok] = np.eye(3)
    T, solved = solve_batch(S3, S2.swapaxes(1, 2))
    T = -T
    ok &= solved
    M = C1_INV @ (S1 + S2 @ T)
    ok &= np.isfinite(M).all(axis=(1, 2))
    if not ok.all():
        M[~ok] = np.eye(3)
    w, V, eig_ok = _eig_batch(M)
    ok &= eig_ok
    cond = 4.0 * V[:, 0, :] * V[:, 2, :] - V[:, 1, :] ** 2
    good = cond > 0
    ok &= good.any(axis=1)
    k = np.where(good, np.abs(w), np.inf).argmin(axis=1)
    a1 = V[np.arange(F), :, k]
    # an eigenvector's sign is LAPACK's choice, which a stacked call and a lone one (or two
    # machines) can make differently: fixed here so that A + C > 0 (an ellipse's A and C share
    # their sign, as 4 A C > B^2); the scaling to C's norm below keeps it
    a1 = a1 * np.where(a1[:, 0] + a1[:, 2] < 0, -1.0, 1.0)[:, None]
    coef = np.empty((F, 6))
    coef[:, :3] = a1
    coef[:, 3:] = np.einsum("fij,fj->fi", T, a1)
    # (A, B, C, D, E, F) -> [[A, B/2, D/2], [B/2, C, E/2], [D/2, E/2, F]]: one exact product
    Cn = (coef @ _CONIC_FROM_COEFFICIENTS).reshape(F, 3, 3)
    # x_n = N x with N = [[1/s, 0, -mx/s], [0, 1/s, -my/s], [0, 0, 1]]: C = N^T Cn N.
    N = np.zeros((F, 3, 3))
    N[:, _DIAGONAL_XY, _DIAGONAL_XY] = (1.0 / s)[:, None]
    N[:, :2, 2] = -mean / s[:, None]
    N[:, 2, 2] = 1.0
    Cm = N.swapaxes(1, 2) @ Cn @ N
    norm = np.sqrt((Cm * Cm).sum(axis=(1, 2)))
    ok &= np.isfinite(norm) & (norm != 0)
    C = Cm / norm[:, None, None]
    if not ok.all():
        C[~ok] = np.nan
    return C, ok


def circle_planes(C: FloatArray, radius_m: float) -> tuple[FloatArray, FloatArray, BoolArray]:
    """Both candidate supporting planes of a circle imaged as conic ``C``, per frame.

    Parameters
    ----------
    C : (F, 3, 3) array of float
    radius_m : float

    Returns
    -------
    normal_up : (F, 2, 3) array of float
    centre_m : (F, 2, 3) array of float
    valid : (F, 2) array of bool
        Plane ``j`` exists (none where ``C`` is not the image of a circle in front of the camera).
    """
    finite = np.isfinite(C).all(axis=(1, 2))
    Cs = 0.5 * (C + C.swapaxes(1, 2))
    if not finite.all():
        Cs[~finite] = np.diag([1.0, 1.0, -1.0])
    w, V = np.linalg.eigh(Cs)
    flip = w[:, 1] < 0
    if flip.all():  # (views: no copy)
        w, V = -w[:, ::-1], V[:, :, ::-1]
    elif flip.any():
        w = np.where(flip[:, None], -w[:, ::-1], w)
        V = np.where(flip[:, None, None], V[:, :, ::-1], V)
    l2 = w[:, 1]
    ok = finite & (w[:, 2] >= l2) & (l2 > 0) & (0 > w[:, 0])
    # (sqrt(l2 - l3) V0, sqrt(l1 - l2) V2) as the two columns of one product
    Vs = V[:, :, ::2] * np.sqrt(w[:, 1:] - w[:, :2])[:, None, :]
    V0, V2 = Vs[:, :, 0], Vs[:, :, 1]
    # both planes at once: (u, v) = (a, b) for the first, (b, a) for the second, with
    # a = s13 V2 + s23 V0 and b = s13 V2 - s23 V0
    u = np.empty((V.shape[0], 2, 3))
    np.add(V2, V0, out=u[:, 0])
    np.subtract(V2, V0, out=u[:, 1])
    v = u[:, ::-1]
    uu = (u * u).sum(axis=2)
    S = -v / (2.0 * l2[:, None, None])
    us = (u * S).sum(axis=2)
    Xc1 = S + ((1.0 - us) / uu)[:, :, None] * u
    r1_sq = (S * S).sum(axis=2) - (us - 1.0) ** 2 / uu
    valid = ok[:, None] & (r1_sq > 0)
    centres = (radius_m / np.sqrt(r1_sq))[:, :, None] * Xc1
    np.negative(centres, out=centres, where=(centres[:, :, 2] < 0)[:, :, None])
    normals = u / np.sqrt(uu)[:, :, None]
    np.negative(normals, out=normals, where=((normals * centres).sum(axis=2) > 0)[:, :, None])
    if not valid.all():
        normals[~valid] = np.nan
        centres[~valid] = np.nan
    return normals, centres, valid


def in_plane_alignment(
    xy: FloatArray, points_deck_m: FloatArray, normal_up: FloatArray, centre_m: FloatArray
) -> tuple[FloatArray, FloatArray, BoolArray]:
    """Deck rotation about each frame's plane normal and centre offset (2-D Procrustes).

    Parameters
    ----------
    xy : (F, N, 2) array of float
        Normalised image points, N >= 2.
    points_deck_m : (N, 3) array of float
    normal_up, centre_m : (F, 3) array of float
        One candidate plane per frame.

    Returns
    -------
    R_cam_from_deck : (F, 3, 3) array of float
    t_cam_from_deck : (F, 3) array of float
    ok : (F,) array of bool
        False where a ray is parallel to or points away from the plane, or the plane
        is invalid.
    """
    n_up = normal_up
    d = -(n_up * centre_m).sum(axis=1)
    den = -(xy @ n_up[:, :2, None])[..., 0] - n_up[:, 2, None]
    ok = (np.logical_and.reduce(np.isfinite(n_up), axis=1) & ~np.logical_or.reduce(den <= 1e-12, axis=1)
          & np.logical_and.reduce(np.isfinite(den), axis=1))
    s_ray = d[:, None] / den
    ex = _UNIT_X - n_up[:, 0, None] * n_up
    ex2 = (ex * ex).sum(axis=1)
    alt = ex2 < 1e-12
    if alt.any():
        ex[alt] = _UNIT_Y - n_up[alt, 1, None] * n_up[alt]
        ex2 = (ex * ex).sum(axis=1)
    e1 = ex / np.sqrt(ex2)[:, None]
    e2 = _cross(n_up, e1)
    E = np.empty((e1.shape[0], 2, 3))
    E[:, 0], E[:, 1] = e1, e2
    q = ((xy @ E[:, :, :2].swapaxes(1, 2)) + E[:, None, :, 2]) * s_ray[:, :, None] - (
        E @ centre_m[:, :, None])[:, None, :, 0]
    p = points_deck_m[:, :2]
    qm, pm = q.sum(axis=1) / q.shape[1], p.sum(axis=0) / p.shape[0]  # (np.mean's arithmetic)
    qc, pc = q - qm[:, None, :], p - pm
    sin_sum = (pc[:, 0] * qc[:, :, 1] - pc[:, 1] * qc[:, :, 0]).sum(axis=1)
    cos_sum = (pc[:, 0] * qc[:, :, 0] + pc[:, 1] * qc[:, :, 1]).sum(axis=1)
    psi = np.arctan2(sin_sum, cos_sum)
    c, s = np.cos(psi), np.sin(psi)
    rot = np.empty((c.shape[0], 2))
    rot[:, 0] = c * pm[0] - s * pm[1]
    rot[:, 1] = s * pm[0] + c * pm[1]
    shift = qm - rot
    x_deck = c[:, None] * e1 + s[:, None] * e2
    y_deck = _cross(n_up, x_deck)
    R = np.empty((n_up.shape[0], 3, 3))
    R[:, :, 0], R[:, :, 1], R[:, :, 2] = x_deck, y_deck, n_up
    t = centre_m + shift[:, 0, None] * e1 + shift[:, 1, None] * e2
    return R, t, ok


def imaged_centres(xy: FloatArray, points_deck_m: FloatArray, ring: BoolArray, centre: BoolArray
                   ) -> tuple[FloatArray, BoolArray]:
    """Least-squares image of the deck centre from the centre beacon and the ring's diameters.

    Every line through two diametrically opposite ring beacons passes through the
    image of the centre; the centre beacon is an observation of it. The estimate
    minimises the squared distances to those lines (weight 2: the error of a line
    at its midpoint is the mean of its two end points' errors) and to the centre
    beacon (weight 1). A diameter whose two image points coincide has no line: its
    row is zero, which leaves the least-squares solution as if it were not there.

    Parameters
    ----------
    xy : (F, N, 2) array of float
        Normalised image points.
    points_deck_m : (N, 3) array of float
    ring, centre : (N,) array of bool
        Which rows are ring beacons, and which is the centre beacon.

    Returns
    -------
    centre_xy : (F, 2) array of float
        The imaged centre, normalised coordinates (NaN where not ``ok``).
    ok : (F,) array of bool
        Where at least two diameters' lines, or the centre beacon, fix it.
    """
    F = xy.shape[0]
    pairs = _diameter_rows(points_deck_m, ring)
    centre_rows = np.flatnonzero(centre)
    n_lines, n_centre = pairs.shape[0], centre_rows.size
    if n_lines < 2 and not n_centre:
        return np.full((F, 2), np.nan), np.zeros(F, dtype=bool)
    # rows: every diameter's line (weight 2), then both coordinates of each centre beacon (weight 1),
    # each scaled by the square root of its weight
    A = np.empty((F, n_lines + 2 * n_centre, 2))
    b = np.empty((F, n_lines + 2 * n_centre))
    p, q = xy[:, pairs[:, 0]], xy[:, pairs[:, 1]]  # (F, P, 2)
    xi, yi, xj, yj = p[..., 0], p[..., 1], q[..., 0], q[..., 1]
    L0, L1, L2 = yi - yj, xj - xi, xi * yj - yi * xj
    norm = np.hypot(L0, L1)
    w = np.sqrt(2.0)
    if not (norm > 0).all():  # a line of two coincident points (L = 0): a zero row
        norm = np.where(norm > 0, norm, np.inf)
    A[:, :n_lines, 0] = L0 / norm * w
    A[:, :n_lines, 1] = L1 / norm * w
    b[:, :n_lines] = -(L2 / norm) * w
    A[:, n_lines:] = _EYE2 if n_centre == 1 else np.tile(_EYE2, (n_centre, 1))
    b[:, n_lines:] = xy[:, centre_rows].reshape(F, 2 * n_centre)
    finite = np.isfinite(A).all(axis=(1, 2)) & np.isfinite(b).all(axis=1)
    if not finite.all():
        A[~finite] = np.eye(A.shape[1], 2)
        b[~finite] = 0.0
    # Minimum-norm least squares through the SVD, with numpy.linalg.lstsq's rank cut-off.
    U, s, Vt = np.linalg.svd(A, full_matrices=False)
    cut = _EPS * max(A.shape[1], 2) * s[:, :1]
    big = s > cut
    rank = big.sum(axis=1)
    coef = np.where(big, np.einsum("frk,fr->fk", U, b) / s, 0.0)
    sol = np.einsum("fkj,fk->fj", Vt, coef)
    ok = finite & (rank >= 2) & np.isfinite(sol).all(axis=1)
    if not ok.all():
        sol[~ok] = np.nan
    return sol, ok


def planes_from_centres(C: FloatArray, centre_xy: FloatArray, ring_xy: FloatArray, radius_m: float
                        ) -> tuple[FloatArray, FloatArray, BoolArray]:
    """The circle's plane from its conic and its imaged centre, per frame (its normal is the centre's polar).

    Parameters
    ----------
    C : (F, 3, 3) array of float
    centre_xy : (F, 2) array of float
    ring_xy : (F, M, 2) array of float
    radius_m : float

    Returns
    -------
    normal_up, centre_m : (F, 3) array of float
    ok : (F,) array of bool
        Where the polar is a line, the centre and every ring ray meet the plane in front of
        the camera, and the ring has a size.
    """
    F = C.shape[0]
    c = np.empty((F, 3))
    c[:, :2] = centre_xy
    c[:, 2] = 1.0
    line = ((0.5 * (C + C.swapaxes(1, 2))) @ c[:, :, None])[:, :, 0]
    norm = np.sqrt((line * line).sum(axis=1))
    ok = np.isfinite(norm) & (norm > 0)
    n_up = line / norm[:, None]
    # the camera (origin) is on the +n_up side: n_up . c < 0, and den_c = -n_up . c = |n_up . c|
    dot = (n_up * c).sum(axis=1)
    np.negative(n_up, out=n_up, where=(dot > 0)[:, None])
    den_c = np.abs(dot)
    u = np.empty(ring_xy.shape[:2] + (3,))
    u[:, :, :2] = ring_xy
    u[:, :, 2] = 1.0
    den_ring = -(u @ n_up[:, :, None])[:, :, 0]
    ok &= (den_c > 1e-12) & (den_ring > 1e-12).all(axis=1)
    # back-projections onto the plane -n_up . X = 1
    diff = u / den_ring[:, :, None] - (c / den_c[:, None])[:, None, :]
    spread = np.sqrt((diff * diff).sum(axis=2)).sum(axis=1) / diff.shape[1]
    ok &= spread > 0
    centre_m = (radius_m / spread)[:, None] * c / den_c[:, None]
    if not ok.all():
        n_up[~ok] = np.nan
        centre_m[~ok] = np.nan
    return n_up, centre_m, ok
