"""Pose of a circle of known radius from its image conic: the two candidate planes.

In normalised camera coordinates the image of a circle is the cone
``X^T C X = 0`` (C symmetric, signature (+, +, -) after a sign flip). With the
eigenvalues ``l1 >= l2 > 0 > l3`` and eigenvectors ``e1, e2, e3``,
``C - l2 I = (a.X)(b.X)`` with ``a, b = sqrt(l1 - l2) e1 ± sqrt(l2 - l3) e3``,
so on every plane ``a.X = k`` (or ``b.X = k``) the cone meets the sphere
``l2 |X|² + k (b.X) = 0`` through the camera centre: a circle. Those are the two
candidate supporting planes; the known radius fixes ``k``. The image of the
circle's centre is the pole of the plane's vanishing line, ``C^-1 n``, which is
what lets the imaged centre beacon tell the two candidates apart.

Conversely, when the image of the centre is known, the plane follows without
the eigen-decomposition and its two-fold ambiguity (:func:`plane_from_centre`):
the centre is the pole of the line at infinity, and poles and polars survive
projection, so the vanishing line of the deck is the polar ``l = C c`` of the
imaged centre ``c``, and in normalised coordinates the deck normal is ``l``
itself. The imaged centre is measured by :func:`imaged_centre`: the centre
beacon, and the lines through diametrically opposite ring beacons, which all
meet at the image of the centre (incidence is projective too). Using every
labelled ring beacon this way makes the normal first-order in the tilt and keeps
the closed-form pose near the Cramér–Rao bound, where the eigen route, whose
tilt comes from the ellipse's eccentricity (second order in the tilt), is
several times above it near nadir.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class CirclePlane:
    """One candidate supporting plane of the imaged circle, camera frame.

    Attributes
    ----------
    normal_up : (3,) array of float
        Unit normal of the circle's plane pointing toward the camera side (deck +z).
    centre_m : (3,) array of float
        Circle centre, metres, camera frame.
    """

    normal_up: FloatArray
    centre_m: FloatArray


def circle_planes(C: FloatArray, radius_m: float) -> list[CirclePlane]:
    """Both candidate planes of a circle of ``radius_m`` imaged as conic ``C``.

    Parameters
    ----------
    C : (3, 3) array of float
        Conic in normalised camera coordinates, ``[x, y, 1] C [x, y, 1]^T = 0``.
    radius_m : float

    Returns
    -------
    list of CirclePlane
        Two candidates (identical for a fronto-parallel view); empty if ``C``
        is not the image of a circle in front of the camera.
    """
    Cs = 0.5 * (C + C.T)
    w, V = np.linalg.eigh(Cs)  # ascending
    if w[1] < 0:
        w, V = -w[::-1], V[:, ::-1]
    l3, l2, l1 = w
    if not (l1 >= l2 > 0 > l3):
        return []
    s13 = np.sqrt(l1 - l2)
    s23 = np.sqrt(l2 - l3)
    a = s13 * V[:, 2] + s23 * V[:, 0]
    b = s13 * V[:, 2] - s23 * V[:, 0]
    out = []
    for u, v in ((a, b), (b, a)):
        uu = float(u @ u)
        S = -v / (2.0 * l2)  # sphere centre for k = 1
        us = float(u @ S)
        Xc1 = S + ((1.0 - us) / uu) * u
        r1_sq = float(S @ S) - (us - 1.0) ** 2 / uu
        if not r1_sq > 0:
            continue
        k = radius_m / np.sqrt(r1_sq)
        Xc = k * Xc1
        if Xc[2] < 0:
            Xc = -Xc
        n = u / np.sqrt(uu)
        if n @ Xc > 0:
            n = -n
        out.append(CirclePlane(n, Xc))
    return out


def _cross(a: FloatArray, b: FloatArray) -> FloatArray:
    return np.array([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]])


def in_plane_alignment(
    xy: FloatArray, points_deck_m: FloatArray, plane: CirclePlane
) -> tuple[FloatArray, FloatArray] | None:
    """Deck rotation about the plane normal and centre offset from labelled points (2-D Procrustes).

    Back-projects each normalised point onto the candidate plane and finds the
    rotation about the normal and the in-plane shift that best map the layout
    onto them (least squares, known scale).

    Parameters
    ----------
    xy : (N, 2) array of float
        Normalised image points.
    points_deck_m : (N, 3) array of float
        Their layout positions (z = 0).
    plane : CirclePlane

    Returns
    -------
    (R_cam_from_deck, t_cam_from_deck) or None
        None with fewer than 2 points or rays parallel to the plane.
    """
    n_up = plane.normal_up
    if xy.shape[0] < 2:
        return None
    d = float(-n_up @ plane.centre_m)  # plane: -n_up . X = d, d > 0
    den = -(xy @ n_up[:2] + n_up[2])
    if np.any(den <= 1e-12):
        return None
    s_ray = d / den
    # In-plane basis: e1 = camera x projected onto the plane, e2 = n_up x e1.
    ex = np.array([1.0, 0.0, 0.0]) - n_up[0] * n_up
    if ex @ ex < 1e-12:
        ex = np.array([0.0, 1.0, 0.0]) - n_up[1] * n_up
    e1 = ex / np.sqrt(ex @ ex)
    e2 = _cross(n_up, e1)
    # Coordinates of the back-projected points X = s_ray * (x, y, 1) about the centre.
    E = np.stack([e1, e2])  # (2, 3)
    q = (xy @ E[:, :2].T + E[:, 2]) * s_ray[:, None] - E @ plane.centre_m
    p = points_deck_m[:, :2]
    qm, pm = q.mean(axis=0), p.mean(axis=0)
    qc, pc = q - qm, p - pm
    sin_sum = float(np.sum(pc[:, 0] * qc[:, 1] - pc[:, 1] * qc[:, 0]))
    cos_sum = float(np.sum(pc[:, 0] * qc[:, 0] + pc[:, 1] * qc[:, 1]))
    psi = np.arctan2(sin_sum, cos_sum)
    c, s = np.cos(psi), np.sin(psi)
    shift = qm - np.array([c * pm[0] - s * pm[1], s * pm[0] + c * pm[1]])
    x_deck = c * e1 + s * e2
    y_deck = _cross(n_up, x_deck)
    R = np.column_stack([x_deck, y_deck, n_up])
    t = plane.centre_m + shift[0] * e1 + shift[1] * e2
    return R, t


#: Two ring beacons are diametrically opposite when their positions sum to less than this x radius.
_OPPOSITE_TOL = 1e-9


def diameter_pairs(points_deck_m: FloatArray, ring: NDArray[np.bool_]) -> list[tuple[int, int]]:
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


def imaged_centre(xy: FloatArray, points_deck_m: FloatArray, ring: NDArray[np.bool_],
                  centre: NDArray[np.bool_]) -> FloatArray | None:
    """Least-squares image of the deck centre from the centre beacon and the ring's diameters.

    Every line through two diametrically opposite ring beacons passes through the
    image of the centre; the centre beacon is an observation of it. The estimate
    minimises the squared distances to those lines (weight 2: the error of a line
    at its midpoint is the mean of its two end points' errors) and to the centre
    beacon (weight 1).

    Parameters
    ----------
    xy : (N, 2) array of float
        Normalised image points.
    points_deck_m : (N, 3) array of float
        Their deck positions.
    ring, centre : (N,) array of bool
        Which rows are ring beacons, and which is the centre beacon.

    Returns
    -------
    (2,) array of float or None
        The imaged centre, normalised coordinates; None unless there are at least
        two diameters, or the centre beacon, to fix it.
    """
    pairs = np.asarray(diameter_pairs(points_deck_m, ring), dtype=np.int64).reshape(-1, 2)
    p, q = xy[pairs[:, 0]], xy[pairs[:, 1]]
    # line through p and q: (a, b) . x + c = 0 with (a, b) the unit normal
    ab = np.column_stack([p[:, 1] - q[:, 1], q[:, 0] - p[:, 0]])
    norm = np.hypot(ab[:, 0], ab[:, 1])
    good = norm > 0
    ab = ab[good] / norm[good, None]
    c = -np.sum(ab * p[good], axis=1)
    k = np.flatnonzero(centre)
    if len(ab) < 2 and len(k) == 0:
        return None
    # weight 2 on a line, 1 on each coordinate of the centre beacon (rows scaled by sqrt(weight))
    A = np.vstack([np.sqrt(2.0) * ab, np.tile(np.eye(2), (len(k), 1))])
    b = np.concatenate([-np.sqrt(2.0) * c, xy[k].ravel()])
    sol, _, rank, _ = np.linalg.lstsq(A, b, rcond=None)
    if rank < 2 or not np.all(np.isfinite(sol)):
        return None
    return np.asarray(sol, dtype=float)


def plane_from_centre(C: FloatArray, centre_xy: FloatArray, ring_xy: FloatArray,
                      radius_m: float) -> CirclePlane | None:
    """The circle's plane from its image conic and the image of its centre (no ambiguity).

    The deck normal is the polar of the imaged centre, ``n ∝ C c``; the distance
    makes the ring's back-projected points lie, on average, ``radius_m`` from the
    back-projected centre.

    Parameters
    ----------
    C : (3, 3) array of float
        Ring conic, normalised coordinates.
    centre_xy : (2,) array of float
        Imaged circle centre, normalised (:func:`imaged_centre`).
    ring_xy : (M, 2) array of float
        Normalised ring points, M >= 1.
    radius_m : float
        Ring radius.

    Returns
    -------
    CirclePlane or None
        None if the polar is degenerate or a ring ray misses the plane.
    """
    c = np.array([centre_xy[0], centre_xy[1], 1.0])
    line = 0.5 * (C + C.T) @ c
    norm = float(np.linalg.norm(line))
    if not (np.isfinite(norm) and norm > 0):
        return None
    n_up = line / norm
    if n_up @ c > 0:
        n_up = -n_up  # the camera (origin) is on the +n_up side of the deck
    u = np.column_stack([ring_xy, np.ones(len(ring_xy))])
    den_ring = -(u @ n_up)
    den_c = -float(n_up @ c)
    if not (den_c > 1e-12 and np.all(den_ring > 1e-12)):
        return None
    # back-projections onto the plane -n_up . X = 1
    spread = float(np.mean(np.linalg.norm(u / den_ring[:, None] - c / den_c, axis=1)))
    if not spread > 0:
        return None
    d = radius_m / spread
    return CirclePlane(n_up, d * c / den_c)
