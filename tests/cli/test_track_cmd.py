"""``deckpose track``: the happy path against the Python API, and bad input as one line, exit 2."""

from __future__ import annotations

import pandas as pd

from deckpose.cli import main
from deckpose.run_folder import run_paths
from deckpose.tables import read_table
from deckpose.tracking.config import TrackConfig
from deckpose.tracking.run import track_table
from tests.tracking.synthetic_run import write_run


def test_track_writes_what_the_api_computes(tmp_path, capsys):
    frames, est = write_run(tmp_path / "run", duration_s=5.0, not_ok=(7,))
    assert main(["track", str(tmp_path / "run"), "--no-progress", "--horizons", "1,3"]) == 0
    out = capsys.readouterr().out
    assert "51 frames in 1 sequence: 50 updated, 0 gated out, 1 skipped" in out
    paths = run_paths(tmp_path / "run")
    got = read_table(paths.tracks("cog", "pnp", "wave-bank"), "tracks")
    want, want_pred = track_table(frames, est, TrackConfig(horizons_s=(1.0, 3.0)))
    pd.testing.assert_frame_equal(got, want, check_dtype=False)
    pred = read_table(paths.track_predictions("cog", "pnp", "wave-bank"), "track predictions")
    pd.testing.assert_frame_equal(pred, want_pred, check_dtype=False)
    assert paths.track_run_record("cog", "pnp", "wave-bank").exists()


def test_bad_input_is_one_line_and_status_2(tmp_path, capsys):
    assert main(["track", str(tmp_path / "nothing")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "deckpose render CONFIG.yaml" in err
    write_run(tmp_path / "run", duration_s=2.0)
    (tmp_path / "t.yaml").write_text("gate_probability: 1.5\n")
    assert main(["track", str(tmp_path / "run"), "--config", str(tmp_path / "t.yaml")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "gate_probability: must be" in err
    assert main(["track", str(tmp_path / "run"), "--horizons", "1,x"]) == 2
    assert "--horizons" in capsys.readouterr().err
    assert main(["track", str(tmp_path / "run"), "--estimates", "conic"]) == 2
    assert "the run has: --detector cog --estimates pnp" in capsys.readouterr().err


def test_an_estimator_given_as_the_tracker_is_pointed_to_estimates(tmp_path, capsys):
    write_run(tmp_path / "run", duration_s=2.0)
    assert main(["track", str(tmp_path / "run"), "--method", "pnp"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1
    assert "unknown tracker 'pnp'" in err and "the estimator is --estimates pnp" in err
    assert main(["track", str(tmp_path / "run"), "--estimates", "pnp,conic"]) == 2
    err = capsys.readouterr().err.strip()
    assert "one estimates table per call" in err and "detector any" not in err


def test_a_run_of_fixed_attitudes_is_refused(tmp_path, capsys):
    # fixed attitudes are no time series: filtering them "succeeded" with most frames gated out
    import json

    write_run(tmp_path / "run", duration_s=2.0)
    manifest = tmp_path / "run" / "manifest.json"
    doc = json.loads(manifest.read_text())
    doc["config"] = {"motion": {"source": "fixed", "attitudes_deg": [[0, 0, 0]]}}
    manifest.write_text(json.dumps(doc))
    assert main(["track", str(tmp_path / "run")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "not a time series" in err and "approach" in err
    assert not (tmp_path / "run" / "tracks").exists()
