"""The deck as a 3-D model: a flat square plate with a coloured disc per beacon, and its PLY file.

The mesh lies in the deck frame (x bow, y port, z up; origin at the deck centre, which is
the centre of its bounding box, as BOP wants a model's origin). Vertex ``i`` for
``i < layout.n_beacons`` is beacon id ``i``'s centre, so a reader finds the beacons in the
file without the layout. Each beacon is a fan of triangles (its emitting disc, the layout's
colour: the bow's red, the others' ``beacon_rgb``); the plate around them is a Delaunay
triangulation of the disc rims and the plate's corners, grey. Plate and discs share no
vertex (a rim point appears once in each colour), so colours do not bleed, and nothing
overlaps: one surface at z = 0.
"""

from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from deckpose.atomic_io import atomic_open
from deckpose.errors import ConfigError, check_shape
from deckpose.layout import DeckLayout

__all__ = ["PLATE_RGB8", "DeckMesh", "deck_mesh", "ply_text", "write_ply"]

#: Vertex colour of the deck plate (8-bit RGB).
PLATE_RGB8 = (90, 90, 90)


def _ro(a: np.ndarray) -> np.ndarray:
    out = np.array(a)
    out.setflags(write=False)
    return out


@dataclass(frozen=True)
class DeckMesh:
    """A triangle mesh with per-vertex normals and colours.

    Attributes
    ----------
    vertices_m : (V, 3) array of float, metres
        Deck-frame positions; rows ``0..n_beacons-1`` are the beacon centres.
    faces : (M, 3) array of int
        Vertex indices, counter-clockwise seen from +z (normals up).
    normals : (V, 3) array of float
        Unit vertex normals.
    colours_rgb8 : (V, 3) array of uint8
    n_beacons : int
    """

    vertices_m: NDArray[np.float64]
    faces: NDArray[np.int64]
    normals: NDArray[np.float64]
    colours_rgb8: NDArray[np.uint8]
    n_beacons: int

    def __post_init__(self) -> None:
        v = np.asarray(self.vertices_m)
        check_shape("vertices_m", v, (None, 3))
        check_shape("faces", np.asarray(self.faces), (None, 3))
        check_shape("normals", np.asarray(self.normals), (v.shape[0], 3))
        check_shape("colours_rgb8", np.asarray(self.colours_rgb8), (v.shape[0], 3))
        f = np.asarray(self.faces)
        if f.size and (f.min() < 0 or f.max() >= v.shape[0]):
            raise ConfigError(f"faces index vertices 0..{v.shape[0] - 1}, got {f.min()}..{f.max()}")
        for name in ("vertices_m", "faces", "normals", "colours_rgb8"):
            object.__setattr__(self, name, _ro(getattr(self, name)))


def _rgb8(rgb: tuple[float, float, float]) -> NDArray[np.uint8]:
    return np.round(np.clip(np.asarray(rgb, float), 0.0, 1.0) * 255.0).astype(np.uint8)


def deck_mesh(layout: DeckLayout, deck_half_size_m: float, *, disc_segments: int = 16) -> DeckMesh:
    """The deck plate with its beacons as one flat mesh.

    Parameters
    ----------
    layout : DeckLayout
        Beacon positions, disc radius (``beacon_radius_m``) and colours.
    deck_half_size_m : float, metres
        Half the side of the square plate; must exceed the ring radius plus a disc.
    disc_segments : int
        Rim points per beacon disc (>= 6).

    Returns
    -------
    DeckMesh
    """
    from scipy.spatial import Delaunay

    half, r, s = float(deck_half_size_m), layout.beacon_radius_m, int(disc_segments)
    if s < 6:
        raise ConfigError(f"disc_segments must be at least 6, got {disc_segments}")
    if not half > layout.radius_m + r:
        raise ConfigError(f"deck half size {half} m must exceed the ring radius plus a beacon disc "
                          f"({layout.radius_m} + {r} m)")
    centres = np.asarray(layout.positions_deck_m(), float)  # (N, 3)
    n = centres.shape[0]
    ang = 2.0 * np.pi * np.arange(s) / s
    ring = np.stack([r * np.cos(ang), r * np.sin(ang), np.zeros(s)], 1)
    rims = (centres[:, None, :] + ring[None]).reshape(-1, 3)  # (N*S, 3), beacon b's at b*S..
    corners = np.array([[half, half, 0.0], [-half, half, 0.0], [-half, -half, 0.0], [half, -half, 0.0]])
    # vertices: centres | rims in the beacons' colours | rims in the plate's | plate corners
    vertices = np.vstack([centres, rims, rims, corners])
    col_rim0, col_grey0 = n, n + n * s
    colours = np.empty((vertices.shape[0], 3), np.uint8)
    beacon_rgb = np.array([_rgb8(layout.bow_rgb if i == layout.bow_id else layout.beacon_rgb)
                           for i in range(n)])
    colours[:n] = beacon_rgb
    colours[col_rim0:col_grey0] = np.repeat(beacon_rgb, s, axis=0)
    colours[col_grey0:] = PLATE_RGB8
    k = np.arange(s)
    fans = [np.stack([np.full(s, b), col_rim0 + b * s + k, col_rim0 + b * s + (k + 1) % s], 1)
            for b in range(n)]
    # the plate: Delaunay of the rims and corners; a triangle with all three corners on one
    # disc's rim lies inside that disc (the rim chords are Delaunay edges), so it is left out
    plate_pts = np.vstack([rims, corners])
    tri = np.asarray(Delaunay(plate_pts[:, :2]).simplices, np.int64)
    owner = np.concatenate([np.repeat(np.arange(n), s), np.full(4, -1)])
    o = owner[tri]
    inside_disc = (o[:, 0] >= 0) & (o[:, 0] == o[:, 1]) & (o[:, 1] == o[:, 2])
    plate = tri[~inside_disc] + col_grey0
    faces = np.vstack([*fans, plate])
    p = vertices[faces]
    up = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])[:, 2]
    faces[up < 0] = faces[up < 0][:, [0, 2, 1]]
    normals = np.tile([0.0, 0.0, 1.0], (vertices.shape[0], 1))
    return DeckMesh(vertices, faces, normals, colours, n)


def ply_text(mesh: DeckMesh, *, scale: float = 1.0, comments: tuple[str, ...] = ()) -> str:
    """The mesh as an ASCII PLY file (the layout of the BOP toolkit's ``save_ply``).

    Coordinates are written as ``double`` with 17 significant digits, so a reader gets the
    positions back exactly (BOP's own writer rounds to 0.1 um in ``float``); normals
    ``float``; colours ``uchar red, green, blue``; faces ``list uchar int vertex_indices``.

    Parameters
    ----------
    mesh : DeckMesh
    scale : float
        Multiplies the metre coordinates (1000: millimetres, as BOP wants).
    comments : tuple of str
        Header comments, one line each.
    """
    v = np.asarray(mesh.vertices_m, float) * float(scale)
    lines = ["ply", "format ascii 1.0", *(f"comment {c}" for c in comments),
             f"element vertex {v.shape[0]}",
             "property double x", "property double y", "property double z",
             "property float nx", "property float ny", "property float nz",
             "property uchar red", "property uchar green", "property uchar blue",
             f"element face {mesh.faces.shape[0]}", "property list uchar int vertex_indices",
             "end_header"]
    for p, nrm, c in zip(v, mesh.normals, mesh.colours_rgb8, strict=True):
        lines.append(f"{p[0]:.17g} {p[1]:.17g} {p[2]:.17g} {nrm[0]:.7g} {nrm[1]:.7g} {nrm[2]:.7g} "
                     f"{c[0]:d} {c[1]:d} {c[2]:d}")
    lines += [f"3 {a:d} {b:d} {c:d}" for a, b, c in np.asarray(mesh.faces)]
    return "\n".join(lines) + "\n"


def write_ply(path: str | os.PathLike[str], mesh: DeckMesh, *, scale: float = 1.0,
              comments: tuple[str, ...] = ()) -> None:
    """Write :func:`ply_text` to ``path`` atomically."""
    with atomic_open(path, "w") as fh:
        fh.write(ply_text(mesh, scale=scale, comments=comments))
