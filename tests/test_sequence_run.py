"""``deckpose estimate --run`` on a time sequence: frames detection left unidentified, identified by the prior.

The run is a two-ring descent from 5 m to 4 m at 10 Hz (640x480, 75 deg, the outer ring out
of view), synthesised with its detect-stage output (:mod:`tests.two_ring_run`); from frame 1
on the bow beacons are hidden, so detection identifies only frame 0.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest
from deckpose.estimate.registry import parse_method
from deckpose.estimate.run import estimate_run

from deckpose.cli import main
from deckpose.run_folder import run_paths
from deckpose.sequence_run import NO_PRIOR_NOTE
from deckpose.tables import read_table
from tests.two_ring_run import write_two_ring_run

N = 8
HIDDEN = tuple(range(1, N))
#: An ok estimate lies within this many of its own sigmas of the truth (the house's rule); with
#: Gaussian pixel noise and 6 x 7 comparisons, one beyond 5 sigma has a chance of about 2e-5.
MAX_SIGMAS = 5.0
NEW_COLUMNS = ["identified_by", "prior_age_s"]


def _estimates(root) -> pd.DataFrame:
    return read_table(run_paths(root).estimates("cog", "pnp"), "estimates")


def _errors_in_sigmas(row: pd.Series, truth: np.ndarray) -> np.ndarray:
    """|estimate - truth| / sigma for roll, pitch, yaw (degrees in the table), surge, sway, height."""
    est = np.array([row.roll_deg, row.pitch_deg, row.yaw_deg, row.surge_m, row.sway_m, row.height_m], float)
    want = np.concatenate([np.degrees(truth[:3]), truth[3:]])
    sig = np.array([row.sigma_roll_deg, row.sigma_pitch_deg, row.sigma_yaw_deg, row.sigma_surge_m,
                    row.sigma_sway_m, row.sigma_height_m], float)
    d = est - want
    d[2] = (d[2] + 180.0) % 360.0 - 180.0  # yaw wraps
    return np.abs(d) / sig


def test_frames_without_their_bow_are_identified_by_the_prior_and_lie_within_their_sigmas(tmp_path, capsys):
    truth = write_two_ring_run(tmp_path / "run", n_frames=N, bow_hidden=HIDDEN)
    assert main(["estimate", "--run", str(tmp_path / "run"), "--no-progress"]) == 0
    assert f"{N} frames, {N} ok" in capsys.readouterr().out
    df = _estimates(tmp_path / "run")
    assert list(df["identified_by"]) == ["frame"] + ["prior"] * len(HIDDEN)
    assert math.isnan(df["prior_age_s"].iloc[0])
    np.testing.assert_allclose(df["prior_age_s"].iloc[1:], 0.1, atol=1e-9)  # each frame's predecessor
    for k, row in df.iterrows():
        assert row.ok, row.reason
        z = _errors_in_sigmas(row, truth[int(row.frame_id)])
        assert np.all(z < MAX_SIGMAS), (k, z)


def test_no_prior_leaves_them_not_ok_saying_why(tmp_path, capsys):
    write_two_ring_run(tmp_path / "run", n_frames=N, bow_hidden=HIDDEN)
    assert main(["estimate", "--run", str(tmp_path / "run"), "--no-progress", "--no-prior"]) == 0
    assert f"{N} frames, 1 ok" in capsys.readouterr().out
    df = _estimates(tmp_path / "run")
    assert list(df["ok"]) == [True] + [False] * len(HIDDEN)
    assert list(df["identified_by"]) == ["frame"] + ["none"] * len(HIDDEN)
    assert df["prior_age_s"].isna().all()
    for reason in df["reason"].iloc[1:]:
        assert reason.endswith(NO_PRIOR_NOTE)


def test_a_prior_too_old_is_not_used_and_the_rows_stay_as_estimated(tmp_path):
    # frames 1 s apart: no prior is young enough (0.5 s), so the table is the estimate stage's own
    write_two_ring_run(tmp_path / "run", n_frames=4, bow_hidden=(1, 2, 3), dt_s=1.0)
    estimate_run(tmp_path / "run", parse_method("pnp"))  # the estimate stage alone, as read back
    want = _estimates(tmp_path / "run")
    assert main(["estimate", "--run", str(tmp_path / "run"), "--no-progress"]) == 0
    got = _estimates(tmp_path / "run")
    pd.testing.assert_frame_equal(got.drop(columns=NEW_COLUMNS), want.drop(columns=NEW_COLUMNS))
    assert list(got["identified_by"]) == ["frame", "none", "none", "none"]
    assert list(got["ok"]) == [True, False, False, False]


def test_a_run_identified_frame_by_frame_is_unchanged(tmp_path):
    write_two_ring_run(tmp_path / "run", n_frames=4)
    estimate_run(tmp_path / "run", parse_method("pnp"))  # the estimate stage alone, as read back
    want = _estimates(tmp_path / "run")
    assert main(["estimate", "--run", str(tmp_path / "run"), "--no-progress"]) == 0
    got = _estimates(tmp_path / "run")
    pd.testing.assert_frame_equal(got.drop(columns=NEW_COLUMNS), want.drop(columns=NEW_COLUMNS))
    assert (got["identified_by"] == "frame").all() and got["ok"].all()


@pytest.mark.parametrize("argv, words", [
    (["--no-prior", "det.csv", "--camera", "c.yaml", "-o", "e.csv"], "--no-prior applies to --run"),
    (["--run", "RUN", "--max-prior-age-s", "-1"], "max_prior_age_s must be >= 0"),
])
def test_bad_prior_options_are_one_line_and_status_2(tmp_path, capsys, argv, words):
    if "--run" in argv:
        write_two_ring_run(tmp_path / "run", n_frames=2)
        argv = [str(tmp_path / "run") if a == "RUN" else a for a in argv]
    assert main(["estimate", *argv, "--no-progress"]) == 2
    err = capsys.readouterr().err.strip()
    assert words in err and len(err.splitlines()) == 1
