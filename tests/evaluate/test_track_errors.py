"""A track's errors against the truth, against errors planted by construction and a brute-force hold-last."""

from __future__ import annotations

import math
import shutil

import numpy as np
import pandas as pd
import pytest
from deckpose.evaluate.report import write_report
from deckpose.evaluate.track_errors import (
    filtered_by_height,
    predicted_roll_errors,
    prediction_errors,
    track_frame_errors,
)

from deckpose import run_folder as rl

DT_S, N = 0.5, 40


def _run():
    """Truth; estimates 0.1 deg off in roll (frame 7 not ok); a track 0.05 deg off with sigma 0.025 deg;
    predictions exactly 0.2 deg off the truth at the frame each is made for."""
    t = np.arange(N) * DT_S
    roll = 3 * np.sin(0.7 * t)
    cam_z = np.where(t < 10, 50.0, 30.0)        # two height bands: 40-60 and 20-40 m
    frames = pd.DataFrame({"frame_id": np.arange(N), "t_s": t, "stamp_ns": (t * 1e9).astype(np.int64),
                           "camera": "c", "camera_height_m": cam_z, "roll_deg": roll, "pitch_deg": 0.5 * roll,
                           "yaw_deg": 10.0, "heave_m": 0.3 * np.sin(t), "surge_m": 0.0, "sway_m": 0.0,
                           "cam_x_m": 0.0, "cam_y_m": 0.0, "cam_z_m": cam_z})
    true_h = cam_z - frames["heave_m"].to_numpy()
    pose = {"roll_deg": roll, "pitch_deg": 0.5 * roll, "yaw_deg": np.full(N, 10.0), "surge_m": np.zeros(N),
            "sway_m": np.zeros(N)}
    est = pd.DataFrame({"frame_id": np.arange(N), "method": "pnp", "ok": np.arange(N) != 7, "reason": "",
                        **pose, "height_m": true_h + 0.01})
    est["roll_deg"] += 0.1
    tracks = pd.DataFrame({"frame_id": np.arange(N), "sequence": 0, "stamp_ns": frames["stamp_ns"],
                           "status": "updated", **pose, "height_m": true_h - 0.02,
                           "sigma_roll_deg": 0.025, "sigma_pitch_deg": 0.1, "sigma_yaw_deg": 0.1,
                           "sigma_height_m": 0.01})
    tracks["roll_deg"] += 0.05
    rows = []
    for i in range(N):
        for h in (1.0, 2.0):
            j = i + round(h / DT_S)
            target = roll[j] if j < N else 0.0
            rows.append({"frame_id": i, "horizon_s": h, "stamp_ns": int(frames["stamp_ns"][i] + h * 1e9),
                         "roll_deg": target + 0.2, "pitch_deg": (0.5 * roll[j] if j < N else 0.0) - 0.1,
                         "height_m": true_h[j] if j < N else 0.0,
                         "sigma_roll_deg": 0.1, "sigma_pitch_deg": 0.1, "sigma_height_m": 0.5})
    return frames, est, tracks, pd.DataFrame(rows)


def test_filtered_and_per_frame_errors_and_their_ratio_by_height():
    frames, est, tracks, _ = _run()
    errs = track_frame_errors(frames, est, tracks)
    np.testing.assert_allclose(errs["roll_err_deg_filtered"], 0.05, atol=1e-9)
    np.testing.assert_allclose(errs["roll_z_filtered"], 2.0, atol=1e-6)
    np.testing.assert_allclose(errs["height_err_m_filtered"], -0.02, atol=1e-9)
    assert np.isnan(errs.loc[errs["frame_id"] == 7, "roll_err_deg_estimate"]).all()   # not ok: not scored
    np.testing.assert_allclose(errs["roll_err_deg_estimate"].drop(index=7), 0.1, atol=1e-9)
    by_h = filtered_by_height(errs).set_index("height_band_m")
    assert list(by_h.index) == ["20-40", "40-60"] and by_h["frames"].tolist() == [20, 20]
    np.testing.assert_allclose(by_h["roll_err_deg_ratio"], 0.5, atol=1e-9)
    np.testing.assert_allclose(by_h["height_err_m_ratio"], 2.0, atol=1e-9)
    assert by_h.loc["40-60", "estimates_ok"] == pytest.approx(19 / 20)
    # the ratio compares both on the frames with an ok estimate: a filter far off where it only
    # predicts (frame 7, no estimate) shows in the all-frames column, not in the ratio
    errs.loc[errs["frame_id"] == 7, "roll_err_deg_filtered"] = 2.0
    by_h = filtered_by_height(errs).set_index("height_band_m")
    np.testing.assert_allclose(by_h["roll_err_deg_ratio"], 0.5, atol=1e-9)
    band = "40-60" if 7 in errs.loc[errs["true_height_m"] >= 40, "frame_id"].to_numpy() else "20-40"
    want = np.sqrt((19 * 0.05 ** 2 + 2.0 ** 2) / 20)
    assert by_h.loc[band, "roll_err_deg_rms_filtered_all"] == pytest.approx(want, rel=1e-9)


def test_predictions_against_holding_the_last_ok_estimate():
    frames, est, tracks, preds = _run()
    res = prediction_errors(frames, est, tracks, preds).set_index("horizon_s")
    roll = frames["roll_deg"].to_numpy()
    for h in (1.0, 2.0):
        k = round(h / DT_S)
        assert res.loc[h, "scored"] == N - k
        assert res.loc[h, "roll_deg_rms_predicted"] == pytest.approx(0.2, abs=1e-9)
        assert res.loc[h, "pitch_deg_rms_predicted"] == pytest.approx(0.1, abs=1e-9)
        assert res.loc[h, "roll_deg_z_rms"] == pytest.approx(2.0, abs=1e-6)
        # brute force: the last ok estimate as of frame i (frame 7 is not ok: frame 6's is held), against truth at i+k
        held = []
        for i in range(N - k):
            last = max(j for j in range(i + 1) if j != 7)
            held.append(roll[last] + 0.1 - roll[i + k])
        rms = math.sqrt(np.mean(np.square(held)))
        assert res.loc[h, "roll_deg_rms_held"] == pytest.approx(rms, rel=1e-9)
        assert res.loc[h, "roll_deg_ratio"] == pytest.approx(0.2 / rms, rel=1e-9)
    series = predicted_roll_errors(frames, tracks, preds, 1.0)
    assert series.attrs["horizon_s"] == 1.0 and len(series) == N - 2
    np.testing.assert_allclose(series["roll_err_deg"], 0.2, atol=1e-9)
    assert series["t_s"].is_monotonic_increasing and series["t_s"].iloc[0] == pytest.approx(1.0)


def test_the_report_of_a_tracked_run_has_a_tracking_section(tracked_run, tmp_path):
    root = tmp_path / "run"
    shutil.copytree(tracked_run, root)
    md = write_report(rl.run_paths(root)).read_text()
    assert "## Tracking: fake+thesis (wave-bank)" in md
    assert "(figures/track_fake--thesis--wave-bank.png)" in md
    assert (root / "report" / "figures" / "track_fake--thesis--wave-bank.png").stat().st_size > 10_000
    assert "| horizon_s | scored |" in md


def test_a_track_shorter_than_every_horizon_has_no_prediction_rows_and_still_plots(tmp_path):
    from deckpose.evaluate.report_figures import plot_track_errors

    frames, est, tracks, preds = _run()
    short = [f[f["frame_id"] < 3].reset_index(drop=True) for f in (frames, est, tracks)]
    late = preds[(preds["frame_id"] < 3) & (preds["horizon_s"] == 2.0)]  # due 4 frames later: none is
    pred = prediction_errors(*short, late)
    assert len(pred) == 0 and {"horizon_s", "scored", "roll_deg_ratio"} <= set(pred.columns)
    errs = track_frame_errors(short[0], short[1], short[2])
    plot_track_errors(errs, predicted_roll_errors(short[0], short[2], late, 2.0), pred, "short", tmp_path / "t.png")
    assert (tmp_path / "t.png").stat().st_size > 1000
