"""Counts in messages say "1 frame" and "2 frames"."""

from __future__ import annotations

from deckpose.counted import counted


def test_one_is_singular_and_every_other_count_plural() -> None:
    assert counted(1, "frame") == "1 frame"
    assert [counted(n, "frame") for n in (0, 2, 13)] == ["0 frames", "2 frames", "13 frames"]
    assert counted(2, "sequence", "sequences") == "2 sequences"
    assert counted(3, "index", "indices") == "3 indices"
