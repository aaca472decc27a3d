"""``deckpose pipeline``: one command from a render config to a published report."""

from __future__ import annotations

import json
from pathlib import Path

import pandas as pd
import pytest
import yaml

from deckpose.cli import main
from deckpose.cli.pipeline_cmd import publish_report
from deckpose.errors import DeckposeError


def _tiny_config(tmp_path: Path) -> Path:
    doc = {"name": "tiny", "seed": 3, "cameras": [{"preset": "4mp", "size": [640, 480]}], "heights_m": [30],
           "lighting": ["night"], "motion": {"source": "fixed", "attitudes_deg": [[0, 0, 0], [3, -2, 10]]},
           "sensor": {"bit_depth": 8, "read_noise_e": 5}, "scene": {"texture_px": 128},
           "layout": {"n_ring": 12, "radius_m": 10.0, "has_centre": True}}
    cfg = tmp_path / "tiny.yaml"
    cfg.write_text(yaml.safe_dump(doc))
    return cfg


def test_pipeline_runs_every_stage_publishes_and_resumes(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    cfg, run, pub = _tiny_config(tmp_path), tmp_path / "run", tmp_path / "reports" / "tiny"
    argv = ["pipeline", str(cfg), str(run), "--method", "conic,pnp+mean", "--workers", "1", "--no-progress",
            "--publish", str(pub)]
    assert main(argv) == 0
    errors = pd.read_parquet(run / "evaluation" / "errors.parquet")
    assert set(errors.method) == {"conic", "pnp+mean"} and len(errors) == 4  # 2 frames x 2 methods
    assert errors.ok.all()
    # published: the report with its figures and tables, the record, not the dataset or the log
    for name in ("report.md", "resolution_tables.md", "resolution_tables.csv", "pipeline.json",
                 "figures/error_vs_height.png"):
        assert (pub / name).exists(), name
    assert not (pub / "log.mcap").exists() and not (pub / "images").exists()
    record = json.loads((pub / "pipeline.json").read_text())
    assert record["methods"] == ["conic", "pnp+mean"] and record["detectors"] == ["cog"]
    assert record["command"][:4] == ["deckpose", "pipeline", str(cfg), str(run)]
    assert set(record["stage_seconds"]) >= {"render", "detect", "estimate", "evaluate"}
    # the load each stage ran under and the peak memory: what a stage time means on a shared machine
    assert set(record["stage_load_1min"]) == set(record["stage_seconds"])
    for load in record["stage_load_1min"].values():
        assert 0 <= load["mean"] <= load["max"] and load["samples"] >= 1
    assert record["peak_rss_gib"]["this_process"] > 0.05  # python with numpy and pyrender loaded
    assert record["log_seconds"] >= 0  # the log is written after the report, which it attaches
    from mcap.reader import make_reader

    with open(run / "log.mcap", "rb") as fh:
        attached = {a.name for a in make_reader(fh).iter_attachments()}
        fh.seek(0)
        topics = {c.topic for c in make_reader(fh).get_summary().channels.values()}
    assert "report/report.md" in attached
    # the per-frame errors the layout plots are in the log (it was written after evaluate, from its table)
    plotted = {p["value"].rsplit(".", 1)[0].strip('"')
               for p in json.loads((run / "foxglove_layout.json").read_text())["configById"]["Plot!errors"]["paths"]}
    assert plotted == {"/errors/cog--conic", "/errors/cog--pnp+mean"} and plotted <= topics
    report = (pub / "report.md").read_text()
    assert report.startswith("# deckpose report: tiny\n")  # titled by the config, not the folder
    assert "## How this was made" in report and "config `tiny`" in report and "seed 3" in report
    assert str(pub / "report.md") in capsys.readouterr().out
    # a second run keeps the rendered frames (resume) and rewrites the later stages
    image = min((run / "images").rglob("*.png"))
    before = image.stat().st_mtime_ns
    assert main(argv) == 0
    assert image.stat().st_mtime_ns == before
    assert not list(pub.parent.glob(".tiny.*"))  # no half-written copy left beside the published report


def test_unknown_names_fail_before_rendering(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    cfg, run = _tiny_config(tmp_path), tmp_path / "run"
    assert main(["pipeline", str(cfg), str(run), "--method", "thesis,nosuch", "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert "unknown estimator nosuch" in err and "pnp" in err
    assert main(["pipeline", str(cfg), str(run), "--method", "thesis,pnp+nosuch", "--no-progress"]) == 2
    assert "unknown variant '+nosuch'" in capsys.readouterr().err
    assert not run.exists()


def test_publish_needs_a_report(tmp_path: Path) -> None:
    (tmp_path / "run").mkdir()
    with pytest.raises(DeckposeError, match="deckpose report"):
        publish_report(tmp_path / "run", tmp_path / "pub")
    assert not (tmp_path / "pub").exists()


def test_from_stage_reuses_earlier_outputs_and_keeps_their_record(tmp_path: Path) -> None:
    cfg, run = _tiny_config(tmp_path), tmp_path / "run"
    assert main(["pipeline", str(cfg), str(run), "--method", "pnp", "--workers", "1", "--no-progress",
                 "--no-mcap"]) == 0
    detections = run / "detections" / "cog.parquet"
    before = detections.stat().st_mtime_ns
    first = json.loads((run / "pipeline.json").read_text())
    assert main(["pipeline", str(cfg), str(run), "--method", "pnp", "--no-progress", "--no-mcap",
                 "--from-stage", "report"]) == 0
    assert detections.stat().st_mtime_ns == before  # detection was not run again
    second = json.loads((run / "pipeline.json").read_text())
    assert second["from_stage"] == "report"
    assert second["stage_seconds"]["detect"] == first["stage_seconds"]["detect"]
    # the earlier stages keep the load they ran under, and the peak memory covers both runs
    assert second["stage_load_1min"]["detect"] == first["stage_load_1min"]["detect"]
    for k, v in first["peak_rss_gib"].items():
        assert second["peak_rss_gib"][k] >= v
    assert second["earlier_stages_command"] == first["command"]
    report = (run / "report" / "report.md").read_text()
    assert "came from an earlier run of" in report
    detect = first["stage_load_1min"]["detect"]
    assert f"detect {detect['mean']:.1f} ({detect['max']:.1f})" in report  # the load each stage ran under
    assert "Peak memory: the pipeline process" in report


def test_from_stage_needs_a_dataset(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    cfg = _tiny_config(tmp_path)
    assert main(["pipeline", str(cfg), str(tmp_path / "none"), "--from-stage", "detect", "--no-progress"]) == 2
    assert "needs a rendered dataset" in capsys.readouterr().err


def test_track_on_fixed_attitudes_is_refused_before_rendering(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    cfg, run = _tiny_config(tmp_path), tmp_path / "run"
    assert main(["pipeline", str(cfg), str(run), "--method", "pnp", "--track", "--no-progress"]) != 0
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--track needs frames in time" in err[0] and "motion source 'fixed'" in err[0]
    assert not run.exists()
