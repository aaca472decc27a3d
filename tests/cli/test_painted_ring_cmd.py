"""``deckpose painted-ring``: one-line errors for folders it cannot use, and a small run end to end."""

from __future__ import annotations

import json

import pandas as pd
from deckpose.render.config import config_from_dict
from deckpose.render.dataset import render_dataset

from deckpose.cli import main
from deckpose.tables import read_table


def test_not_a_dataset_or_no_ring_is_one_line(tmp_path, capsys):
    assert main(["painted-ring", str(tmp_path / "nothing")]) == 2
    err = capsys.readouterr().err.strip()
    assert "no manifest.json" in err and "\n" not in err
    (tmp_path / "ds").mkdir()
    (tmp_path / "ds" / "manifest.json").write_text(json.dumps({"config": {"layout": {}}}))
    assert main(["painted-ring", str(tmp_path / "ds")]) == 2
    err = capsys.readouterr().err.strip()
    assert "has no painted ring" in err and "painted_ring:" in err and "\n" not in err


def test_painted_ring_run_writes_its_tables(tmp_path, capsys):
    doc = {"name": "ring", "seed": 4, "cameras": [{"preset": "4mp-square", "size": [640, 480]}],
           "heights_m": [35.0], "lighting": ["day"], "motion": {"source": "fixed", "attitudes_deg": [[2, -1, 15]]},
           "sensor": {"bit_depth": 8, "read_noise_e": 5}, "scene": {"shading": "flat", "texture_px": 512},
           "painted_ring": {"radius_m": 8.0}}
    run = render_dataset(config_from_dict(doc), tmp_path / "run", workers=0, progress=False)
    assert main(["painted-ring", str(run), "--no-progress"]) == 0
    est = read_table(run / "estimates" / "ring-edges--painted-ring.parquet", "estimates")
    det = pd.read_parquet(run / "detections" / "ring-edges.parquet")
    bound = pd.read_parquet(run / "estimates" / "ring-edges--painted-ring.bound.parquet")
    assert est["ok"].all() and det["ok"].all() and len(bound) == 1
    frames = pd.read_parquet(run / "frames.parquet")
    # the estimate within 5 of its own sigmas of the truth (ZYX yaw, degrees)
    yaw_err = est["yaw_deg"].iloc[0] - 15.0
    assert abs(yaw_err) < 5 * est["sigma_yaw_deg"].iloc[0]
    assert (det["inner_n_points"] > 100).all() and (det["outer_n_points"] > 100).all()
    assert frames["frame_id"].tolist() == est["frame_id"].tolist()
    # evaluate and report read the ring's estimates as any other's (the .bound side table and
    # the per-frame ring detections are not beacon tables: they once crashed evaluate)
    assert main(["evaluate", str(run)]) == 0
    errors = pd.read_parquet(run / "evaluation" / "errors.parquet")
    assert set(errors["method"]) == {"painted-ring"} and len(errors) == 1
    assert abs(errors["yaw_err_deg"].iloc[0] - yaw_err) < 1e-9
    assert main(["report", str(run)]) == 0
