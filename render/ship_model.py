"""The ship around the helideck: a hull down to the waterline and a superstructure block.

Both are :class:`trimesh.Trimesh` meshes in the deck frame (x bow, y port, z up, origin
at the deck centre, metres), so they move with the ship pose like the deck plate. The
helideck is at the stern, as on frigates and offshore vessels: the deck plate's aft edge
is the transom.

* hull: a convex prism from the waterline (``z = -freeboard``) up to ``z = -`` :data:`HULL_TOP_GAP_M`
  (a hair below the deck plate, so the plate is drawn over it); its outline runs from
  the transom (``x = -a``) along straight sides ``y = +-a`` to ``x = a + 30`` and closes
  in a pointed bow at ``x = a + 50`` (``a`` the deck's half side);
* superstructure: a deckhouse ``x`` in ``[a + 4, a + 18]``, ``|y| <= a - 4``, 6 m high, a
  bridge with wings on top (``x`` in ``[a + 8, a + 14]``, ``|y| <= a - 1.5``, up to 10 m)
  and a mast to 12 m, where :mod:`deckpose.render.ship_lights` puts the masthead light;
  the sidelights (``(a + 8, +-(a - 2), 4)``) sit outside it, under the bridge wings.

Everything forward of the deck is beyond the deck's edge, so from a camera above the
deck no line of sight to a beacon crosses it (``tests/render/test_ship_scene.py`` casts
the rays).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import trimesh

__all__ = ["HULL_TOP_GAP_M", "hull_mesh", "joined_mesh", "superstructure_mesh"]

#: The hull's top is this far below the deck plate, metres (no depth fight with the plate).
HULL_TOP_GAP_M = 0.02
#: Colours (RGBA, 0-255): hull sides (dark grey), main deck, superstructure (light grey).
HULL_RGBA = (70, 74, 80, 255)
MAIN_DECK_RGBA = (92, 98, 92, 255)
SUPERSTRUCTURE_RGBA = (150, 154, 158, 255)
WINDOW_RGBA = (25, 32, 40, 255)


def hull_outline_m(deck_half_size_m: float) -> np.ndarray:
    """The hull's outline in the deck plane, (5, 2) ``(x, y)`` metres, counter-clockwise."""
    a = deck_half_size_m
    return np.array([[-a, -a], [a + 30.0, -a], [a + 50.0, 0.0], [a + 30.0, a], [-a, a]])


def hull_mesh(deck_half_size_m: float, freeboard_m: float) -> trimesh.Trimesh:
    """The hull as a closed convex prism, deck frame, metres; sides and top coloured apart.

    Parameters
    ----------
    deck_half_size_m : float
        Half the side of the square deck plate.
    freeboard_m : float
        Deck height above the waterline (the hull's bottom is at ``-freeboard_m``).
    """
    xy = hull_outline_m(deck_half_size_m)
    top = np.column_stack([xy, np.full(len(xy), -HULL_TOP_GAP_M)])
    bottom = np.column_stack([xy, np.full(len(xy), -freeboard_m)])
    hull = trimesh.convex.convex_hull(np.vstack([top, bottom]))
    colours = np.tile(np.array(HULL_RGBA, np.uint8), (len(hull.faces), 1))
    colours[hull.face_normals[:, 2] > 0.99] = MAIN_DECK_RGBA
    return trimesh.Trimesh(hull.vertices, hull.faces, face_colors=colours, process=False)


def _box(lo: tuple[float, float, float], hi: tuple[float, float, float]) -> trimesh.Trimesh:
    lo_a, hi_a = np.asarray(lo, float), np.asarray(hi, float)
    box = trimesh.creation.box(extents=hi_a - lo_a)
    return trimesh.Trimesh(box.vertices + (lo_a + hi_a) / 2, box.faces, process=False)


def superstructure_mesh(deck_half_size_m: float) -> trimesh.Trimesh:
    """Deckhouse, bridge (with a dark window band facing aft) and mast, deck frame, metres."""
    a = deck_half_size_m
    parts = [
        (_box((a + 4.0, -(a - 4.0), 0.0), (a + 18.0, a - 4.0, 6.0)), SUPERSTRUCTURE_RGBA),
        (_box((a + 8.0, -(a - 1.5), 6.0), (a + 14.0, a - 1.5, 10.0)), SUPERSTRUCTURE_RGBA),
        (_box((a + 7.9, -(a - 2.0), 8.2), (a + 8.0, a - 2.0, 9.4)), WINDOW_RGBA),
        (_box((a + 13.8, -0.2, 10.0), (a + 14.2, 0.2, 12.0)), SUPERSTRUCTURE_RGBA),
    ]
    joined = joined_mesh([m for m, _ in parts])
    return trimesh.Trimesh(joined.vertices, joined.faces,
                           face_colors=np.vstack([np.tile(np.array(c, np.uint8), (len(m.faces), 1)) for m, c in parts]),
                           process=False)


def joined_mesh(parts: Sequence[trimesh.Trimesh]) -> trimesh.Trimesh:
    """One mesh of ``parts``' vertices and faces, in order (no colours, nothing merged).

    Parameters
    ----------
    parts : sequence of trimesh.Trimesh
        Meshes in one frame, metres.
    """
    offsets = np.cumsum([0] + [len(m.vertices) for m in parts[:-1]])
    return trimesh.Trimesh(np.vstack([m.vertices for m in parts]),
                           np.vstack([m.faces + o for m, o in zip(parts, offsets, strict=True)]), process=False)
