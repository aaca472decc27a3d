"""The layout's optional inner ring: ids after the centre, positions, colours, validation; one ring unchanged."""

from __future__ import annotations

import math

import numpy as np
import pytest

from deckpose.errors import ConfigError
from deckpose.layout import DeckLayout, layout_from_dict, layout_to_dict
from tests.tolerances import ROUNDOFF


def test_one_ring_layout_is_unchanged() -> None:
    lay = DeckLayout()  # 12 at 10 m and the centre, no inner ring
    assert lay.n_beacons == 13 and lay.inner_first_id is None and lay.bow_ids == (0,)
    assert lay.inner_ring_ids().size == 0
    # the positions as the formula of the module docstring: ring i at 2 pi i / n, then the centre
    want = [(10 * math.cos(2 * math.pi * i / 12), 10 * math.sin(2 * math.pi * i / 12), 0.0) for i in range(12)]
    np.testing.assert_allclose(lay.positions_deck_m(), [*want, (0.0, 0.0, 0.0)], atol=ROUNDOFF)
    # manifests of one-ring runs keep their keys (no inner-ring keys written)
    assert set(layout_to_dict(lay)) == {"n_ring", "radius_m", "has_centre", "bow_id", "bow_rgb", "beacon_rgb",
                                        "beacon_radius_m", "intensity"}
    rgb = lay.beacon_rgb_all()
    assert tuple(rgb[0]) == lay.bow_rgb and all(tuple(r) == lay.beacon_rgb for r in rgb[1:])


@pytest.mark.parametrize("has_centre", [True, False])
def test_inner_ring_ids_follow_the_centre(has_centre: bool) -> None:
    lay = DeckLayout(n_ring=12, radius_m=10.0, has_centre=has_centre, inner_n_ring=6, inner_radius_m=1.5)
    first = 12 + int(has_centre)
    assert lay.inner_first_id == first and lay.n_beacons == first + 6
    assert lay.bow_ids == (0, first)
    P = lay.positions_deck_m()
    for k in range(6):  # inner beacon k at 2 pi k / 6 from the bow, radius 1.5
        a = 2 * math.pi * k / 6
        np.testing.assert_allclose(P[first + k], [1.5 * math.cos(a), 1.5 * math.sin(a), 0.0], atol=ROUNDOFF)
    np.testing.assert_array_equal(lay.inner_ring_ids(), first + np.arange(6))
    rgb = lay.beacon_rgb_all()
    red = [i for i in range(lay.n_beacons) if tuple(rgb[i]) == lay.bow_rgb]
    assert red == [0, first]
    again = layout_from_dict(layout_to_dict(lay))
    assert again == lay


@pytest.mark.parametrize(("doc", "words"), [
    ({"inner_n_ring": 4}, "inner_n_ring must be 0"),
    ({"inner_n_ring": 6, "inner_radius_m": 10.0}, "inner_radius_m must lie between"),
    ({"inner_n_ring": 6, "inner_radius_m": 0.2}, "inner_radius_m must lie between"),
    ({"inner_n_ring": "six"}, "inner_n_ring"),
])
def test_bad_inner_ring_is_one_line_error(doc: dict[str, object], words: str) -> None:
    with pytest.raises(ConfigError) as err:
        layout_from_dict(doc)
    assert words in str(err.value) and "\n" not in str(err.value)
