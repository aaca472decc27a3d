"""The ``deckpose render`` subcommand: help, clear errors, a dataset from a YAML file."""

from __future__ import annotations

import re
from pathlib import Path

import pandas as pd
import pytest
import yaml

from deckpose.cli import main


def test_render_help(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exc:
        main(["render", "--help"])
    assert exc.value.code == 0
    out = capsys.readouterr().out
    assert "--workers" in out and "--resume" in out and "--scheduler" in out and "--backend" in out
    import dataclasses

    from deckpose.render.config import RenderConfig

    flat = " ".join(out.split())
    assert all(f.name in flat for f in dataclasses.fields(RenderConfig))  # every config key is named


def test_bad_config_exits_2_with_a_message(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    cfg = tmp_path / "bad.yaml"
    cfg.write_text(yaml.safe_dump({"cameras": [{"preset": "4mp"}], "heights_m": [-1]}))
    assert main(["render", str(cfg), str(tmp_path / "out"), "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert "heights_m" in err and "must be > 0" in err
    assert not (tmp_path / "out").exists()  # nothing rendered, nothing written


def test_render_cli_writes_a_dataset(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    doc = {"name": "cli", "cameras": [{"preset": "4mp", "size": [160, 120]}], "heights_m": [30],
           "lighting": ["dusk"], "motion": {"source": "fixed", "attitudes_deg": [[0, 0, 0], [2, 1, 5]]},
           "scene": {"texture_px": 128}}
    cfg = tmp_path / "cfg.yaml"
    cfg.write_text(yaml.safe_dump(doc))
    # --workers 1: rendering happens in a spawned worker, so this test process needs no GL context
    assert main(["render", str(cfg), str(tmp_path / "ds"), "--workers", "1", "--no-progress",
                 "--seed", "5"]) == 0
    frames = pd.read_parquet(tmp_path / "ds" / "frames.parquet")
    assert len(frames) == 2 and (frames.seed != 0).all()
    # the closing line says what was made and how long it took
    out = capsys.readouterr().out.strip().splitlines()[-1]
    assert out.startswith("dataset of 2 frames written to ") and str(tmp_path / "ds") in out
    assert re.search(r" in \d+\.\d s$", out), out


@pytest.mark.parametrize(("seconds", "text"), [(0.04, "0.0 s"), (59.94, "59.9 s"), (59.96, "1 min 00 s"), (61.2, "1 min 01 s"),
                                               (3599.4, "59 min 59 s"), (7384.0, "2 h 03 min")])
def test_render_duration_reads_as_a_person_would(seconds: float, text: str) -> None:
    from deckpose.cli.render_cmd import _duration

    assert _duration(seconds) == text
