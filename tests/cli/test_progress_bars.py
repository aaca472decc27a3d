"""evaluate and report show progress bars; estimate's bar has a total (as the other commands' bars)."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pandas as pd
import pytest

from deckpose.cli import exit_codes, main

#: Every bar the commands opened: (description, unit, total at the end, count at the end).
Bars = list[tuple[str, str, Any, int]]


@pytest.fixture(scope="module")
def dataset(tmp_path_factory: pytest.TempPathFactory) -> Path:
    from deckpose.detect.synthetic_dataset import SyntheticDatasetConfig, write_synthetic_dataset

    cfg = SyntheticDatasetConfig(cameras=("160x120",), heights_m=(30.0,), frames_per_config=3)
    ds = Path(write_synthetic_dataset(cfg, tmp_path_factory.mktemp("bars") / "ds"))
    assert main(["detect", str(ds), "--workers", "0", "--no-progress"]) == exit_codes.OK
    return ds


class _CountingBar:
    """What the commands use of a tqdm bar: total, n, update, a context; records itself on close."""

    def __init__(self, desc: str, unit: str, total: int | None, seen: Bars) -> None:
        self.desc, self.unit, self.total, self.n, self._seen = desc, unit, total, 0, seen

    def update(self, k: int = 1) -> None:
        self.n += k

    def __enter__(self) -> _CountingBar:  # noqa: PYI034
        return self

    def __exit__(self, *exc: object) -> None:
        self._seen.append((self.desc, self.unit, self.total, self.n))


@pytest.fixture
def bars(monkeypatch: pytest.MonkeyPatch) -> Iterator[Bars]:
    """Record every frame_bar the commands open (a real one draws nothing off a terminal)."""
    seen: Bars = []

    def recording(desc: str, *, enabled: bool, total: int | None = None, unit: str = "frame") -> Any:
        assert enabled  # --no-progress not given
        return _CountingBar(desc, unit, total, seen)

    from deckpose.cli import estimate_cmd, evaluate_cmd

    for mod in (estimate_cmd, evaluate_cmd):
        monkeypatch.setattr(mod, "frame_bar", recording)
    yield seen


def test_estimate_evaluate_and_report_bars_run_to_their_total(dataset: Path, bars: Bars) -> None:
    n_frames = len(pd.read_parquet(dataset / "frames.parquet"))
    assert main(["estimate", "--run", str(dataset), "--method", "pnp"]) == exit_codes.OK
    assert bars[-1] == ("estimate (pnp)", "frame", n_frames, n_frames)
    # every frame once for its errors (and once more as it is logged, with the MCAP log, which a
    # synthetic dataset like this one cannot have: its config is not a render config)
    assert main(["evaluate", str(dataset), "--no-mcap"]) == exit_codes.OK
    assert bars[-1] == ("evaluate", "frame", n_frames, n_frames)
    assert main(["report", str(dataset)]) == exit_codes.OK
    figures = sorted((dataset / "report" / "figures").glob("*.png"))
    assert bars[-1] == ("report", "figure", len(figures), len(figures))  # one step per figure drawn


def test_estimate_from_a_table_has_a_total(dataset: Path, tmp_path: Path, bars: Bars) -> None:
    table = pd.read_parquet(dataset / "detections" / "cog.parquet")
    camera = next((dataset / "cameras").glob("*.yaml"))
    assert main(["estimate", str(dataset / "detections" / "cog.parquet"), "--camera", str(camera),
                 "-o", str(tmp_path / "e.parquet")]) in (exit_codes.OK, exit_codes.NO_FRAME_OK)
    n = table["frame_id"].nunique()
    assert bars[-1] == ("estimate (pnp)", "frame", n, n)
