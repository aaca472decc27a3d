"""The deck model: one flat surface, the beacons' centres first, read back exactly from its PLY."""

from __future__ import annotations

import io

import numpy as np
import pytest
import trimesh
from deckpose.evaluate.deck_model import PLATE_RGB8, deck_mesh, ply_text

from deckpose.errors import ConfigError
from deckpose.layout import DeckLayout, thesis_layout


@pytest.mark.parametrize("layout", [DeckLayout(), thesis_layout(), DeckLayout(n_ring=5, radius_m=3.0)])
def test_the_mesh_tiles_the_plate_with_a_disc_per_beacon(layout: DeckLayout) -> None:
    half = layout.radius_m + 2.0
    mesh = deck_mesh(layout, half, disc_segments=12)
    n = layout.n_beacons
    np.testing.assert_array_equal(mesh.vertices_m[:n], layout.positions_deck_m())
    tm = trimesh.Trimesh(mesh.vertices_m, mesh.faces, process=False)
    assert tm.area == pytest.approx((2 * half) ** 2, rel=1e-12)  # no overlap, no hole
    assert np.all(tm.face_normals[:, 2] > 0)  # every face counter-clockwise seen from above
    disc = np.pi * layout.beacon_radius_m**2 * (12 / (2 * np.pi)) * np.sin(2 * np.pi / 12)
    coloured = np.all(mesh.colours_rgb8[mesh.faces] != PLATE_RGB8, axis=(1, 2))
    assert tm.area_faces[coloured].sum() == pytest.approx(n * disc, rel=1e-9)
    assert not mesh.vertices_m.flags.writeable


def test_the_ply_gives_the_vertices_back_exactly() -> None:
    mesh = deck_mesh(DeckLayout(), 14.0)
    text = ply_text(mesh, scale=1000.0, comments=("a comment",))
    assert text.startswith("ply\nformat ascii 1.0\ncomment a comment\n")
    tm = trimesh.load(io.BytesIO(text.encode()), file_type="ply", process=False)
    assert isinstance(tm, trimesh.Trimesh)
    np.testing.assert_array_equal(tm.vertices, mesh.vertices_m * 1000.0)
    np.testing.assert_array_equal(tm.faces, mesh.faces)


def test_a_plate_smaller_than_the_ring_is_refused() -> None:
    with pytest.raises(ConfigError, match="must exceed the ring radius"):
        deck_mesh(DeckLayout(), 10.0)
    with pytest.raises(ConfigError, match="disc_segments"):
        deck_mesh(DeckLayout(), 14.0, disc_segments=3)
