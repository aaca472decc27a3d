"""The detector ladder's "What breaks which detector" section, on a hand-built results table."""

from __future__ import annotations

import pandas as pd

from tests.detect.independent_generator import load_benchmark


def _ladder():
    return load_benchmark("detector_ladder")


def _row(dataset: str, detector: str, frames_ok: float, recall: float, precision: float, rank: int) -> dict:
    return {"dataset": dataset, "detector": detector, "frames_ok": frames_ok, "recall": recall,
            "precision": precision, "rank": rank}


def test_a_condition_breaks_the_detectors_whose_scores_fall_past_the_limits() -> None:
    ladder = _ladder()
    res = pd.DataFrame([
        _row("easy", "a", 1.0, 1.0, 1.0, 1), _row("easy", "b", 1.0, 1.0, 1.0, 2),
        # fog: a's frames ok fall by exactly the limit (broken), b's recall by less than its limit (not)
        _row("fog", "a", 1.0 - ladder.BREAK_FRAMES_OK, 1.0, 1.0, 2),
        _row("fog", "b", 1.0, 1.0 - ladder.BREAK_RECALL / 2, 1.0, 1),
        # glare: b's precision falls past the limit
        _row("glare", "a", 1.0, 1.0, 0.99, 1), _row("glare", "b", 1.0, 1.0, 0.9, 2),
    ])
    lines = ladder.breaks_markdown(res)
    rows = {ln.split(" | ")[0].lstrip("| "): ln for ln in lines if ln.startswith("| ") and "---" not in ln}
    assert rows["easy"].endswith("| none | a |")
    assert "a (frames ok -0.050)" in rows["fog"] and "b (" not in rows["fog"] and rows["fog"].endswith("| b |")
    assert "b (precision -0.100)" in rows["glare"] and "a (" not in rows["glare"]
    assert "0.950 (-0.050)" in rows["fog"]


def test_no_section_without_the_easy_rung() -> None:
    res = pd.DataFrame([_row("fog", "a", 1.0, 1.0, 1.0, 1)])
    assert _ladder().breaks_markdown(res) == []
