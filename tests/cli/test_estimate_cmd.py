"""``deckpose estimate``: the happy path against the Python API, and every kind of bad input."""

import numpy as np
import pandas as pd
import pytest

from deckpose.camera import preset
from deckpose.camera_info import write_camera_info
from deckpose.cli import main
from deckpose.layout import DeckLayout
from deckpose.pose import CameraPose, ShipPose
from deckpose.projection import project_layout


def _detections(n_frames=6, seed=0):
    cam = preset("8mp")
    rng = np.random.default_rng(seed)
    rows, truth = [], []
    for f in range(n_frames):
        pose = ShipPose(*np.radians([rng.uniform(-15, 15), rng.uniform(-8, 8), rng.uniform(-180, 180)]))
        D = rng.uniform(20, 60)
        proj = project_layout(DeckLayout(), pose, CameraPose.nadir(D), cam)
        for b in np.flatnonzero(proj.visible):
            rows.append({"frame_id": f, "beacon_id": int(b), "u_px": proj.points_px[b, 0], "v_px": proj.points_px[b, 1]})
        truth.append((pose, D))
    return cam, pd.DataFrame(rows), truth


@pytest.fixture
def setup(tmp_path):
    cam, df, truth = _detections()
    cam_path = tmp_path / "cam.yaml"
    write_camera_info(cam, cam_path)
    return tmp_path, cam_path, df, truth


@pytest.mark.parametrize("ext", [".csv", ".parquet"])
def test_estimate_thesis_end_to_end(setup, ext, capsys):
    tmp, cam_path, df, truth = setup
    det = tmp / f"det{ext}"
    df.to_csv(det, index=False) if ext == ".csv" else df.to_parquet(det, index=False)
    out = tmp / f"est{ext}"
    assert main(["estimate", str(det), "--camera", str(cam_path), "-o", str(out), "--method", "thesis"]) == 0
    res = pd.read_csv(out) if ext == ".csv" else pd.read_parquet(out)
    expected_cols = ["frame_id", "method", "ok", "reason", "roll_deg", "pitch_deg", "yaw_deg",
                     "surge_m", "sway_m", "height_m", "thesis_roll_deg", "thesis_pitch_deg", "thesis_yaw_deg"]
    assert list(res.columns[:10]) == expected_cols[:10]
    assert set(expected_cols) <= set(res.columns)
    assert res["ok"].all() and len(res) == len(truth)
    for (pose, D), (_, row) in zip(truth, res.iterrows()):
        assert row.roll_deg == pytest.approx(np.degrees(pose.roll_rad), abs=1e-6)
        assert row.yaw_deg == pytest.approx(np.degrees(pose.yaw_rad), abs=1e-6)
        assert row.height_m == pytest.approx(D, rel=1e-9)
        tr = np.degrees(pose.thesis_angles_rad())
        assert row.thesis_pitch_deg == pytest.approx(tr[1], abs=1e-6)
    assert res["surge_m"].isna().all()
    assert "6 frames, 6 ok" in capsys.readouterr().out


def test_unsolvable_frame_becomes_a_failed_row(setup):
    tmp, cam_path, df, _ = setup
    df = df[~((df.frame_id == 2) & (df.beacon_id == 0))]  # hide the bow beacon of frame 2
    df = df[~((df.frame_id == 4) & (df.beacon_id.isin(range(1, 9))))]  # frame 4: too few beacons
    det = tmp / "det.csv"
    df.to_csv(det, index=False)
    out = tmp / "est.csv"
    assert main(["estimate", str(det), "--camera", str(cam_path), "-o", str(out),
                 "--method", "thesis"]) == 0
    res = pd.read_csv(out, keep_default_na=False).set_index("frame_id")
    assert not res.loc[2, "ok"] and "bow" in res.loc[2, "reason"]
    assert not res.loc[4, "ok"] and "fewer than 5" in res.loc[4, "reason"]
    assert res.loc[2, "roll_deg"] == "" and res.loc[[0, 1, 3, 5], "ok"].all()


def _run_bad(tmp, cam_path, df, capsys, **kw):
    det = tmp / "bad.csv"
    df.to_csv(det, index=False)
    out = tmp / "out.csv"
    code = main(["estimate", str(det), "--camera", str(kw.get("camera", cam_path)), "-o", str(out)])
    assert code == 2 and not out.exists()
    return capsys.readouterr().err


def test_missing_columns(setup, capsys):
    tmp, cam_path, df, _ = setup
    err = _run_bad(tmp, cam_path, df.drop(columns=["v_px"]), capsys)
    assert "missing column" in err and "v_px" in err


def test_nan_names_the_row(setup, capsys):
    tmp, cam_path, df, _ = setup
    df = df.copy()
    df.loc[5, "u_px"] = np.nan
    err = _run_bad(tmp, cam_path, df, capsys)
    assert "row 6" in err and "u_px" in err


def test_unknown_beacon_id(setup, capsys):
    tmp, cam_path, df, _ = setup
    df = df.copy()
    df.loc[3, "beacon_id"] = 40
    err = _run_bad(tmp, cam_path, df, capsys)
    assert "row 4" in err and "unknown beacon_id 40" in err


def test_a_list_of_methods_is_told_one_per_call(setup, capsys):
    tmp, cam_path, df, _ = setup
    det = tmp / "dets.csv"
    df.to_csv(det, index=False)
    out = tmp / "out.csv"
    assert main(["estimate", str(det), "--camera", str(cam_path), "--method", "thesis,pnp", "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert "one method per call" in err and "pipeline --method a,b" in err and "Traceback" not in err
    assert len(err.strip().splitlines()) == 1 and not out.exists()


def test_duplicate_beacon_id_in_a_frame(setup, capsys):
    tmp, cam_path, df, _ = setup
    df = pd.concat([df, df.iloc[[0]]])
    err = _run_bad(tmp, cam_path, df, capsys)
    assert "appears more than once in frame 0" in err


def test_camera_file_that_does_not_parse(setup, capsys):
    tmp, cam_path, df, _ = setup
    bad = tmp / "bad_cam.yaml"
    bad.write_text("image_width: 10\nimage_height: [oops\n")
    err = _run_bad(tmp, cam_path, df, capsys, camera=bad)
    assert "not valid YAML" in err


def test_wrong_extension_and_missing_file(setup, capsys):
    tmp, cam_path, _, _ = setup
    assert main(["estimate", str(tmp / "x.txt"), "--camera", str(cam_path), "-o", str(tmp / "o.csv")]) == 2
    assert ".csv or .parquet" in capsys.readouterr().err
    assert main(["estimate", str(tmp / "nope.csv"), "--camera", str(cam_path), "-o", str(tmp / "o.csv")]) == 2
    assert "does not exist" in capsys.readouterr().err


def test_radius_option_scales_the_height(setup):
    tmp, cam_path, df, truth = setup
    det = tmp / "det.csv"
    df.to_csv(det, index=False)
    out = tmp / "est.csv"
    assert main(["estimate", str(det), "--camera", str(cam_path), "-o", str(out), "--radius", "5"]) == 0
    res = pd.read_csv(out)
    # the height is proportional to the assumed ring radius; angles do not depend on it
    np.testing.assert_allclose(res.height_m, [D / 2 for _, D in truth], rtol=1e-9)


def test_posterior_mean_option(setup):
    """``--posterior-mean`` refines, reports the mean and keeps the ML pose in ml_* columns."""
    tmp, cam_path, df, truth = setup
    rng = np.random.default_rng(3)
    df = df.assign(u_px=df.u_px + rng.normal(0, 1.0, len(df)), v_px=df.v_px + rng.normal(0, 1.0, len(df)))
    det = tmp / "det.csv"
    df.to_csv(det, index=False)
    out = tmp / "est.csv"
    assert main(["estimate", str(det), "--camera", str(cam_path), "-o", str(out), "--method", "thesis",
                 "--posterior-mean", "--sigma-px", "1"]) == 0
    res = pd.read_csv(out)
    assert res["ok"].all() and (res["posterior_mean"] == 1).all() and (res["refined"] == 1).all()
    for (pose, D), (_, row) in zip(truth, res.iterrows()):
        assert abs(row.roll_deg - row.ml_roll_deg) < 0.5 * row.sigma_roll_deg
        assert abs(row.roll_deg - np.degrees(pose.roll_rad)) < 5 * row.sigma_roll_deg
        assert abs(row.height_m - D) < 5 * row.sigma_height_m


def test_sigma_px_out_of_range_is_refused(setup, capsys):
    tmp, cam_path, df, _truth = setup
    det = tmp / "det.csv"
    df.to_csv(det, index=False)
    for bad in ("0", "-1", "nan", "inf", "1e300"):
        assert main(["estimate", str(det), "--camera", str(cam_path), "-o", str(tmp / "e.csv"),
                     "--sigma-px", bad]) == 2, bad
        assert "sigma_px must be a pixel noise between" in capsys.readouterr().err
    assert not (tmp / "e.csv").exists()


def test_covariance_that_is_not_positive_definite_names_the_row(setup, capsys):
    tmp, cam_path, df, _truth = setup
    df = df.assign(cov_uu=0.25, cov_uv=0.0, cov_vv=0.25)
    df.loc[5, "cov_uu"] = -0.25
    det = tmp / "det.csv"
    df.to_csv(det, index=False)
    assert main(["estimate", str(det), "--camera", str(cam_path), "-o", str(tmp / "e.csv")]) == 2
    err = capsys.readouterr().err
    assert "row 6" in err and "not positive definite" in err


def test_frames_that_keep_the_ml_pose_are_counted(setup, capsys, monkeypatch):
    import deckpose.estimate.posterior_mean as pmm

    tmp, cam_path, df, _truth = setup
    det = tmp / "det.csv"
    df.to_csv(det, index=False)
    monkeypatch.setattr(pmm, "MIN_EFFECTIVE_NODES", 1e9)  # no frame's sample is good enough
    assert main(["estimate", str(det), "--camera", str(cam_path), "-o", str(tmp / "e.csv"),
                 "--method", "pnp+mean"]) == 0
    assert "6 ok frame(s) kept the maximum-likelihood pose (posterior_mean = 0)" in capsys.readouterr().out
    res = pd.read_csv(tmp / "e.csv")
    np.testing.assert_allclose(res.roll_deg, res.ml_roll_deg, rtol=1e-12)


def test_method_label_names_the_variant(setup, capsys):
    """``--method pnp+mean`` is ``--method pnp --posterior-mean``; the method column carries the label."""
    tmp, cam_path, df, _truth = setup
    det = tmp / "det.csv"
    df.to_csv(det, index=False)
    a, b = tmp / "a.csv", tmp / "b.csv"
    assert main(["estimate", str(det), "--camera", str(cam_path), "-o", str(a), "--method", "pnp+mean"]) == 0
    assert main(["estimate", str(det), "--camera", str(cam_path), "-o", str(b), "--method", "pnp",
                 "--posterior-mean"]) == 0
    ra, rb = pd.read_csv(a), pd.read_csv(b)
    assert (ra.method == "pnp+mean").all() and (rb.method == "pnp+mean").all()
    pd.testing.assert_frame_equal(ra, rb)
    assert main(["estimate", str(det), "--camera", str(cam_path), "-o", str(a), "--method", "conic",
                 "--refine"]) == 0
    assert (pd.read_csv(a).method == "conic+refine").all()
    assert main(["estimate", str(det), "--camera", str(cam_path), "-o", str(a), "--method", "pnp+fast"]) == 2
    err = capsys.readouterr().err
    assert "unknown variant '+fast'" in err and "+mean" in err


def test_help_of_every_subcommand(capsys):
    from deckpose.cli import build_parser

    parser = build_parser()
    sub = next(a for a in parser._actions if a.dest == "command")
    for name in sub.choices:
        with pytest.raises(SystemExit) as exc:
            main([name, "--help"])
        assert exc.value.code == 0
        assert "usage: deckpose " + name in capsys.readouterr().out


@pytest.mark.parametrize("bow_column", ["is_bow", "flux", None, "is_bow yes/no", "is_bow mixed",
                                        "is_bow, flux blank"])
def test_unidentified_detections_are_identified_or_the_reason_says_what_is_needed(
        setup, capsys, bow_column):
    # The README says beacon_id -1 = unidentified; estimate used to fail every such frame
    # with "0 usable". Shuffled rows, all ids -1: estimate identifies them from positions,
    # the bow from an is_bow column or per-channel flux, and the pose is the truth.
    tmp, cam_path, df, truth = setup
    d = df.sample(frac=1.0, random_state=1).reset_index(drop=True)
    bow = d.beacon_id == DeckLayout().bow_id
    if bow_column == "is_bow":
        d["is_bow"] = bow
    elif bow_column == "is_bow yes/no":  # text, as a spreadsheet writes it ("no" is not true)
        d["is_bow"] = np.where(bow, "yes", "no")
    elif bow_column == "is_bow mixed":  # one column of 1, True and blanks (blank: false)
        d["is_bow"] = np.where(bow, "1", np.where(np.arange(len(d)) % 2, "", "False"))
    elif bow_column == "is_bow, flux blank":  # flux columns present but empty: is_bow tells
        d["is_bow"] = bow
        d["flux_r"] = d["flux_g"] = d["flux_b"] = np.nan
    elif bow_column == "flux":
        d["flux_r"] = 100.0
        d["flux_g"] = np.where(bow, 8.0, 100.0)
        d["flux_b"] = np.where(bow, 5.0, 90.0)
    d["beacon_id"] = -1
    det, out = tmp / "unid.csv", tmp / "unid_est.csv"
    d.to_csv(det, index=False)
    code = main(["estimate", str(det), "--camera", str(cam_path), "-o", str(out),
                 "--method", "pnp"])
    assert code == (3 if bow_column is None else 0)  # 3: no frame succeeded
    res = pd.read_csv(out).sort_values("frame_id").reset_index(drop=True)
    if bow_column is None:
        assert not res["ok"].any()
        assert res["reason"].str.contains("is_bow").all(), res["reason"].tolist()
        return
    assert res["ok"].all(), res["reason"].tolist()
    for (pose, D), (_, row) in zip(truth, res.iterrows()):
        assert row.roll_deg == pytest.approx(np.degrees(pose.roll_rad), abs=1e-6)
        assert row.pitch_deg == pytest.approx(np.degrees(pose.pitch_rad), abs=1e-6)
        assert row.yaw_deg == pytest.approx(np.degrees(pose.yaw_rad), abs=1e-6)
        assert row.height_m == pytest.approx(D, rel=1e-6)


def test_exit_codes(setup, tmp_path, capsys, monkeypatch):
    # 0 the job ran; 3 no frame succeeded; 4 with --strict when any failed; 2 bad input;
    # 1 an unexpected error, one line (the traceback with --debug)
    tmp, cam_path, df, _truth = setup
    good, out = tmp / "good.csv", tmp / "o.csv"
    df.to_csv(good, index=False)
    base = ["estimate", str(good), "--camera", str(cam_path), "-o", str(out), "--method", "pnp"]
    assert main(base) == 0
    assert main([*base, "--strict"]) == 0
    part = tmp / "part.csv"
    d = df.copy()
    d = d[(d.frame_id != 0) | (d.beacon_id < 2)]  # frame 0: two beacons, unsolvable
    d.to_csv(part, index=False)
    pbase = ["estimate", str(part), "--camera", str(cam_path), "-o", str(out), "--method", "pnp"]
    assert main(pbase) == 0
    assert main([*pbase, "--strict"]) == 4
    none = tmp / "none.csv"
    df[df.beacon_id < 2].to_csv(none, index=False)
    assert main(["estimate", str(none), "--camera", str(cam_path), "-o", str(out)]) == 3
    assert main(["estimate", str(tmp / "missing.csv"), "--camera", str(cam_path),
                 "-o", str(out)]) == 2
    capsys.readouterr()

    import deckpose.estimate.run as stage

    def boom(*a, **k):
        raise RuntimeError("an internal failure\nover two lines")

    monkeypatch.setattr(stage, "estimate_batch", boom)
    assert main(base) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "RuntimeError: an internal failure over two lines" in err
    assert "Traceback" not in err and "--debug" in err
    with pytest.raises(RuntimeError):
        main(["--debug", *base])


def test_default_method_is_pnp_and_thesis_flags_an_off_centre_deck(tmp_path, capsys):
    # The case: exact projections at 40 m, roll = pitch = 3 deg; thesis returned
    # pitch 1.85 deg at 0.05 m surge, -19.4 deg at 1 m and roll 9.9 deg at 0.3 m sway, all ok.
    cam = preset("8mp")
    cam_path = tmp_path / "cam.yaml"
    write_camera_info(cam, cam_path)
    offsets = [(0.0, 0.0), (0.05, 0.0), (0.3, 0.0), (1.0, 0.0), (0.0, 0.3)]
    rows = []
    for f, (s, w) in enumerate(offsets):
        pose = ShipPose(np.radians(3.0), np.radians(3.0), 0.0, surge_m=s, sway_m=w)
        proj = project_layout(DeckLayout(), pose, CameraPose.nadir(40.0), cam)
        for b in np.flatnonzero(proj.visible):
            rows.append({"frame_id": f, "beacon_id": int(b), "u_px": proj.points_px[b, 0],
                             "v_px": proj.points_px[b, 1]})
    det = tmp_path / "det.csv"
    pd.DataFrame(rows).to_csv(det, index=False)
    out = tmp_path / "pnp.csv"
    assert main(["estimate", str(det), "--camera", str(cam_path), "-o", str(out)]) == 0
    res = pd.read_csv(out)
    assert (res["method"] == "pnp").all() and res["ok"].all()
    np.testing.assert_allclose(res["pitch_deg"], 3.0, atol=1e-6)
    np.testing.assert_allclose(res["surge_m"], [s for s, _ in offsets], atol=1e-6)
    out_t = tmp_path / "thesis.csv"
    assert main(["estimate", str(det), "--camera", str(cam_path), "-o", str(out_t),
                 "--method", "thesis"]) == 0
    t = pd.read_csv(out_t, keep_default_na=False).set_index("frame_id")
    assert t.loc[0, "ok"]  # centred: the assumption holds
    for f in range(1, len(offsets)):
        assert not t.loc[f, "ok"] and t.loc[f, "reason"].startswith("off-centre deck"), f
        assert t.loc[f, "thesis_pitch_deg"] != ""  # the faithful outputs stay in their columns


def test_frame_ids_stay_64_bit_integers(setup, tmp_path, capsys):
    # Ids went through float64: nanosecond-stamp ids were rounded (…001 -> …000), 1e19
    # became -2^63, and 2^62 + k collapsed into one frame with a false duplicate-id error.
    _tmp, cam_path, df, _ = setup
    big = {f: 1_700_000_000_000_000_001 + f for f in df.frame_id.unique()}
    d = df.assign(frame_id=df.frame_id.map(big))
    det, out = tmp_path / "ids.csv", tmp_path / "ids_out.parquet"
    d.to_csv(det, index=False)
    assert main(["estimate", str(det), "--camera", str(cam_path), "-o", str(out)]) == 0
    res = pd.read_parquet(out)
    assert res["frame_id"].dtype == np.int64
    assert sorted(res["frame_id"].tolist()) == sorted(big.values())
    two = df.assign(frame_id=df.frame_id.map(lambda f: 2**62 + int(f)))
    two.to_parquet(tmp_path / "two.parquet", index=False)
    assert main(["estimate", str(tmp_path / "two.parquet"), "--camera", str(cam_path),
                 "-o", str(out)]) == 0
    assert pd.read_parquet(out)["frame_id"].nunique() == df.frame_id.nunique()
    # beyond 64 bits, or a float column beyond 2^53: one line naming the row
    capsys.readouterr()
    d.assign(frame_id="10000000000000000000").to_csv(det, index=False)
    assert main(["estimate", str(det), "--camera", str(cam_path), "-o", str(out)]) == 2
    assert "row 1: frame_id" in capsys.readouterr().err
    d.assign(frame_id=float(2**60)).to_parquet(tmp_path / "f.parquet", index=False)
    assert main(["estimate", str(tmp_path / "f.parquet"), "--camera", str(cam_path),
                 "-o", str(out)]) == 2
    assert "beyond 2^53" in capsys.readouterr().err


@pytest.mark.parametrize("col", ["cov_uu", "cov_uv", "cov_vv", "snr"])
def test_a_string_in_an_optional_numeric_column_names_the_row(setup, capsys, col):
    # was a Python traceback (ValueError in to_numpy(float))
    tmp, cam_path, df, _ = setup
    d = df.assign(cov_uu=1.0, cov_uv=0.0, cov_vv=1.0, snr=5.0)
    d[col] = d[col].astype(object)
    d.loc[3, col] = "high"
    err = _run_bad(tmp, cam_path, d, capsys)
    assert f"row 4: {col} must be a number" in err and "Traceback" not in err


@pytest.mark.parametrize("content", [b"\xff\xfe\x00not text",
                                     (b"image_width: 64\nimage_height: 36\ncamera_matrix:\n"
                                     b"  rows: three\n  cols: 3\n  data: [1,0,0,0,1,0,0,0,1]\n")])
def test_a_broken_camera_file_is_one_line(setup, capsys, content):
    # non-UTF-8 bytes and `rows: three` were tracebacks
    tmp, cam_path, df, _ = setup
    bad = tmp / "bad_cam.yaml"
    bad.write_bytes(content)
    err = _run_bad(tmp, cam_path, df, capsys, camera=bad)
    assert str(bad) in err and "Traceback" not in err and err.count("\n") == 1


def test_messages_name_the_real_problem(setup, tmp_path, capsys):
    # `--run /nonexistent` said "needs --detector (... none)"; `--radius 1e-300` was
    # blamed on beacon_radius_m
    tmp, cam_path, df, _ = setup
    assert main(["estimate", "--run", str(tmp_path / "nope")]) == 2
    assert "does not exist" in capsys.readouterr().err
    det = tmp / "r.csv"
    df.to_csv(det, index=False)
    assert main(["estimate", str(det), "--camera", str(cam_path), "-o", str(tmp / "o.csv"),
                 "--radius", "1e-300"]) == 2
    assert "--radius 1e-300" in capsys.readouterr().err


def test_a_run_without_detections_says_to_detect(tmp_path, capsys):
    # it said "--run needs --detector (this run has detections of: none)"
    from deckpose.render.config import config_from_dict
    from deckpose.render.dataset import render_dataset

    doc = {"name": "nodet", "seed": 1, "cameras": [{"preset": "4mp-square", "size": [320, 240]}],
           "heights_m": [30.0], "lighting": ["night"], "motion": {"source": "fixed", "attitudes_deg": [[0, 0, 0]]},
           "scene": {"shading": "flat", "texture_px": 256}}
    run = render_dataset(config_from_dict(doc), tmp_path / "my run", workers=0, progress=False)
    assert main(["estimate", "--run", str(run), "--method", "pnp"]) == 2
    err = capsys.readouterr().err.strip()
    assert "no detections yet" in err and f"deckpose detect '{run}' --detector cog" in err and "\n" not in err


def test_a_header_without_rows_is_refused(setup, capsys):
    # it printed "0 frames, 0 ok, 0 failed" and exited 0
    tmp, cam_path, df, _ = setup
    err = _run_bad(tmp, cam_path, df.iloc[:0], capsys)
    assert "holds no detections" in err and err.count("\n") == 1


def test_is_bow_cells_read_as_a_person_wrote_them():
    from deckpose.detections_io import bow_flags
    from deckpose.errors import InputDataError

    assert bow_flags(pd.Series([True, False])).tolist() == [True, False]
    assert bow_flags(pd.Series([1, 0, np.nan, 2.0, np.inf])).tolist() == [True, False, False, True, True]
    assert bow_flags(pd.Series(["1.0", "0.0", "no"])).tolist() == [True, False, False]
    text = pd.Series(["yes", "no", " TRUE ", "false", "1", "0", "", None, "y", "n"])
    assert bow_flags(text).tolist() == [True, False, True, False, True, False, False, False, True, False]
    assert bow_flags(text.astype("string")).tolist() == bow_flags(text).tolist()
    assert bow_flags(pd.Series([True, "no", 1, None], dtype=object)).tolist() == [True, False, True, False]
    with pytest.raises(InputDataError, match=r"row 2 is 'maybe'.*true/false"):
        bow_flags(pd.Series(["no", "maybe"]))


def test_output_that_is_the_detections_table_is_refused_and_the_table_kept(setup, capsys):
    tmp, cam_path, df, _truth = setup
    det = tmp / "same.csv"
    df.to_csv(det, index=False)
    before = det.read_bytes()
    # the same file, also reached by another path to it
    for out in (det, tmp / "." / "same.csv"):
        assert main(["estimate", str(det), "--camera", str(cam_path), "-o", str(out)]) == 2
        err = capsys.readouterr().err
        assert "is the detections table itself" in err and err.count("\n") == 1
    assert det.read_bytes() == before


@pytest.mark.parametrize("radius", ["inf", "nan", "-3", "0"])
def test_a_radius_that_is_no_length_is_named_as_such(setup, capsys, radius):
    tmp, cam_path, df, _truth = setup
    det = tmp / "r.csv"
    df.to_csv(det, index=False)
    code = main(["estimate", str(det), "--camera", str(cam_path), "-o", str(tmp / "r_out.csv"),
                 f"--radius={radius}"])
    err = capsys.readouterr().err
    assert code == 2 and "--radius must be a finite positive number of metres" in err and err.count("\n") == 1
