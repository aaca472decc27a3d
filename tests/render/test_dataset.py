"""Datasets on disk: contract, determinism across workers, resume after SIGKILL, Dask, OSMesa."""

from __future__ import annotations

import dataclasses
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import cv2
import numpy as np
import pandas as pd
import pytest
import yaml
from deckpose.render.config import Backend, config_from_dict
from deckpose.render.dataset import render_dataset

from deckpose.camera_info import read_camera_info
from deckpose.errors import ConfigError
from deckpose.output_folder import LOCK_NAME
from deckpose.run_folder import DATASET_FORMAT as FORMAT

from .conftest import tiny_doc

FRAME_COLS = ["frame_id", "image", "camera", "stamp_ns", "t_s", "camera_height_m", "roll_deg", "pitch_deg",
              "yaw_deg", "heave_m", "surge_m", "sway_m", "thesis_roll_deg", "thesis_pitch_deg",
              "thesis_yaw_deg", "lighting", "seed", "n_visible", *[f"R_world_from_cam_{i}{j}" for i in range(3) for j in range(3)],
              "cam_x_m", "cam_y_m", "cam_z_m"]
BEACON_COLS = ["frame_id", "beacon_id", "u_px", "v_px", "visible", "in_image", "facing",
               "apparent_radius_px", "spot_sigma_px", "spot_flux_e", "spot_background_e",
               "spot_peak_e", "unit_factor", "occluded_fraction", "light_u_px", "light_v_px", "global_u_px",
               "global_v_px", "spot_crb_px", "defocus_px", "field_blur_sigma_px", "vignetting", "u_r_px", "v_r_px",
               "u_b_px", "v_b_px", "spot_flux_r_e", "spot_flux_g_e", "spot_flux_b_e"]


def _images(ds: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted((ds / "images").glob("*.png"))}


def _files(ds: Path) -> dict[str, bytes]:
    """Every file of a dataset but the lock (a killed ``deckpose render`` leaves its own)."""
    return {p.relative_to(ds).as_posix(): p.read_bytes() for p in sorted(ds.rglob("*"))
            if p.is_file() and p.name != LOCK_NAME}


def assert_same_dataset(a: Path, b: Path) -> None:
    """The same tables and, byte for byte, the same files (images, previews, parts, manifest...)."""
    assert _images(a) == _images(b)
    for t in ("frames.parquet", "beacons.parquet"):
        pd.testing.assert_frame_equal(pd.read_parquet(a / t), pd.read_parquet(b / t))
    fa, fb = _files(a), _files(b)
    assert sorted(fa) == sorted(fb)
    assert [k for k in fa if fa[k] != fb[k]] == []


@pytest.fixture(scope="module")
def reference(tmp_path_factory: pytest.TempPathFactory, egl_renderer_factory) -> Path:
    egl_renderer_factory(config_from_dict(tiny_doc()))  # select EGL in this process
    return render_dataset(config_from_dict(tiny_doc()), tmp_path_factory.mktemp("ref") / "ds", workers=0,
                          progress=False)


def test_dataset_follows_the_contract(reference: Path) -> None:
    man = json.loads((reference / "manifest.json").read_text())
    assert man["format"] == FORMAT and man["complete"] and man["seed"] == 3 and man["n_frames"] == 8
    assert {"numpy", "scikit-robot-pyrender", "PyOpenGL"} <= set(man["versions"])
    assert man["layout"]["n_ring"] == 12
    # the noise model behind the CRB: 8-bit, default full well 20000 e, read noise 5 e, RGB
    assert man["sensor"]["gain_dn_per_e"] == pytest.approx(255 / 20000.0)
    assert man["sensor"]["read_noise_e"] == 5 and man["sensor"]["full_well_e"] == 20000.0
    assert man["sensor"]["bit_depth"] == 8 and man["sensor_channels"] == 3
    cam = read_camera_info(reference / man["cameras"][0]["file"])
    assert (cam.width_px, cam.height_px) == (320, 240)
    frames = pd.read_parquet(reference / "frames.parquet")
    beacons = pd.read_parquet(reference / "beacons.parquet")
    assert list(frames.columns) == FRAME_COLS and list(beacons.columns) == BEACON_COLS
    assert frames["frame_id"].dtype == np.int64 and frames["stamp_ns"].dtype == np.int64
    assert len(frames) == 8 and len(beacons) == 8 * 13
    for row in frames.itertuples():
        img = cv2.imread(str(reference / row.image), cv2.IMREAD_UNCHANGED)
        assert img.shape == (240, 320, 3) and img.dtype == np.uint8
        b = beacons[beacons.frame_id == row.frame_id]
        assert row.n_visible == b.visible.sum()
        vis = b[b.visible]
        assert (vis.spot_sigma_px > 0).all() and (vis.spot_flux_e > 0).all()
        assert (vis.spot_peak_e > vis.spot_background_e).all()
    # the bow beacon (id 0) is red, the others white: check the pixel at its projection
    f0 = frames.iloc[0]
    img = cv2.imread(str(reference / f0.image))  # BGR
    b = beacons[beacons.frame_id == f0.frame_id].set_index("beacon_id")
    bow = img[round(b.loc[0, "v_px"]), round(b.loc[0, "u_px"])].astype(int)
    other = img[round(b.loc[3, "v_px"]), round(b.loc[3, "u_px"])].astype(int)
    assert bow[2] > 200 and bow[0] < bow[2] - 80  # red dominates blue
    assert abs(other[2] - other[0]) < 40


def test_same_images_and_tables_for_any_number_of_workers(reference: Path, tmp_path: Path) -> None:
    two = render_dataset(config_from_dict(tiny_doc()), tmp_path / "w2", workers=2, progress=False)
    assert_same_dataset(reference, two)


def test_existing_dataset_needs_resume(reference: Path) -> None:
    with pytest.raises(ConfigError, match="--resume"):
        render_dataset(config_from_dict(tiny_doc()), reference, workers=0, progress=False)
    with pytest.raises(ConfigError, match="another config"):
        render_dataset(config_from_dict(tiny_doc(seed=4)), reference, workers=0, resume=True, progress=False)


def test_resume_after_sigkill(tmp_path: Path, egl_renderer_factory) -> None:
    doc = tiny_doc(heights_m=[25.0, 40.0, 60.0],
                   motion={"source": "fixed", "attitudes_deg": [[i, -i / 2, 3 * i] for i in range(10)]})
    cfg_path = tmp_path / "cfg.yaml"
    cfg_path.write_text(yaml.safe_dump(doc))
    out = tmp_path / "killed"
    proc = subprocess.Popen([sys.executable, "-m", "deckpose", "render", str(cfg_path), str(out), "--workers", "1",
                             "--no-progress"], start_new_session=True, stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL)
    deadline = time.monotonic() + 60
    n_total = 3 * 2 * 10
    while time.monotonic() < deadline:
        parts = list((out / ".parts").glob("*.json")) if (out / ".parts").exists() else []
        if len(parts) >= 5:
            break
        time.sleep(0.02)
    os.killpg(proc.pid, signal.SIGKILL)
    proc.wait()
    done = len(list((out / ".parts").glob("*.json")))
    assert 5 <= done < n_total, "the run should have been killed midway"
    assert not (out / "frames.parquet").exists()
    for p in (out / "images").glob("[0-9]*.png"):  # every complete-named file is whole
        assert cv2.imread(str(p)) is not None, p
    for p in (out / ".parts").glob("[0-9]*.json"):
        json.loads(p.read_text())
    egl_renderer_factory(config_from_dict(doc))
    render_dataset(config_from_dict(doc), out, workers=0, resume=True, progress=False)
    assert not list(out.rglob(".*.tmp*"))
    fresh = render_dataset(config_from_dict(doc), tmp_path / "fresh", workers=0, progress=False)
    assert_same_dataset(out, fresh)


_WORKER_WRITES: list[str] = []


def _record_writes_under(root: str) -> None:
    """(Run on a worker.) Record each file or folder this process writes, makes or renames under ``root``.

    An audit hook sees every open, mkdir and rename made through Python, whatever the
    path is relative to; hooks stay for the life of the process (a worker's).
    """
    write_flags = os.O_WRONLY | os.O_RDWR | os.O_CREAT

    def hook(event: str, args: tuple) -> None:
        if event == "open":
            path, mode, flags = args
            if not ((mode is not None and any(c in mode for c in "wax+")) or (mode is None and flags & write_flags)):
                return
            paths = [path]
        elif event == "os.rename":
            paths = list(args[:2])
        elif event in ("os.mkdir", "os.remove"):
            paths = [args[0]]
        else:
            return
        for p in paths:
            if isinstance(p, (str, bytes, os.PathLike)):
                full = os.path.abspath(os.fsdecode(p))
                if full == root or full.startswith(root + os.sep):
                    _WORKER_WRITES.append(f"{event} {full}")

    sys.addaudithook(hook)


def _recorded_writes() -> list[str]:
    return list(_WORKER_WRITES)


@pytest.fixture(scope="module")
def dask_cluster(tmp_path_factory: pytest.TempPathFactory):
    """Two worker processes (one thread each) with their scratch space in a folder of their own."""
    distributed = pytest.importorskip("distributed")
    scratch = tmp_path_factory.mktemp("dask-scratch")
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0",
                                  local_directory=str(scratch)) as lc, distributed.Client(lc) as client:
        yield lc, client


def test_dask_writes_into_a_relative_folder_and_the_workers_need_no_shared_disk(
        reference: Path, dask_cluster, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    # the workers used to write the frames into OUT under their own working folders, and
    # the client then missed OUT/.parts/000000.json (FileNotFoundError)
    lc, client = dask_cluster
    here, there = tmp_path / "client", tmp_path / "workers"
    here.mkdir()
    there.mkdir()
    client.run(os.chdir, str(there))
    client.run(_record_writes_under, str(here))
    monkeypatch.chdir(here)
    ds = render_dataset(config_from_dict(tiny_doc()), "ds", scheduler=lc.scheduler_address, progress=False)
    assert ds == Path("ds")
    assert_same_dataset(reference, here / "ds")
    assert list(there.iterdir()) == []  # nothing under the workers' working folder
    writes = client.run(_recorded_writes)
    assert len(writes) == 2 and all(w == [] for w in writes.values()), writes  # the client wrote it all


def test_dask_run_survives_a_worker_killed_mid_run(reference: Path, dask_cluster, tmp_path: Path,
                                                    monkeypatch: pytest.MonkeyPatch) -> None:
    from deckpose.render import dataset

    lc, client = dask_cluster
    pids = client.run(os.getpid)
    killed: list[str] = []
    write_frame = dataset.write_frame

    def kill_a_busy_worker_then_write(out_dir: Path, frame: dataset.EncodedFrame) -> int:
        if not killed:  # on the first frame back: a worker that is rendering dies
            busy = [w for w, keys in client.processing().items() if keys and w in pids]
            assert busy, "no worker was rendering when the first frame came back"
            os.kill(pids[busy[0]], signal.SIGKILL)
            killed.append(busy[0])
        return write_frame(out_dir, frame)

    monkeypatch.setattr(dataset, "write_frame", kill_a_busy_worker_then_write)
    ds = render_dataset(config_from_dict(tiny_doc()), tmp_path / "dask", scheduler=lc.scheduler_address,
                        progress=False)
    assert len(killed) == 1 and killed[0] not in client.run(os.getpid)
    assert_same_dataset(reference, ds)


def test_dask_workers_detect_at_render(dask_cluster, tmp_path: Path) -> None:
    # detection at render time runs on the cluster's workers; its table is the one the detect
    # stage writes from the frames the client wrote
    from deckpose.detect.run import detect_run
    from deckpose.render.render_detection import RenderDetection

    lc, _client = dask_cluster
    ds = render_dataset(config_from_dict(tiny_doc()), tmp_path / "dask", scheduler=lc.scheduler_address,
                        progress=False, detection=RenderDetection(("cog",)))
    fused = pd.read_parquet(ds / "detections" / "cog.parquet")
    assert len(fused) > 0
    decoded = detect_run(ds, "cog", out_dir=tmp_path / "decoded")
    pd.testing.assert_frame_equal(fused, pd.read_parquet(decoded.path))


def test_an_unreachable_or_malformed_scheduler_is_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    dask = pytest.importorskip("dask")
    pytest.importorskip("distributed")
    from deckpose.cli import main

    cfg = tmp_path / "job.yaml"
    cfg.write_text(yaml.safe_dump(tiny_doc()))
    with dask.config.set({"distributed.comm.timeouts.connect": "1s"}):
        for address in ("tcp://127.0.0.1:1", "localhost"):
            out = tmp_path / address.replace(":", "_").replace("/", "_")
            code = main(["render", str(cfg), "-o", str(out), "--scheduler", address, "--no-progress"])
            err = capsys.readouterr().err
            assert code == 2 and "cannot reach the Dask scheduler" in err and address in err, err
            assert "Traceback" not in err and err.count("\n") == 1
            assert not (out / "manifest.json").exists()  # nothing written before the scheduler answered


def test_osmesa_backend_renders_the_same_scene(reference: Path, tmp_path: Path) -> None:
    cfg = dataclasses.replace(config_from_dict(tiny_doc()), backend=Backend.OSMESA)
    ds = render_dataset(cfg, tmp_path / "osmesa", workers=1, progress=False)
    a, b = _images(reference), _images(ds)
    assert a.keys() == b.keys()
    for k in a:
        ia = cv2.imdecode(np.frombuffer(a[k], np.uint8), cv2.IMREAD_UNCHANGED).astype(int)
        ib = cv2.imdecode(np.frombuffer(b[k], np.uint8), cv2.IMREAD_UNCHANGED).astype(int)
        assert np.abs(ia - ib).mean() < 0.5
    pd.testing.assert_frame_equal(pd.read_parquet(reference / "beacons.parquet"),
                                  pd.read_parquet(ds / "beacons.parquet"))


def test_frame_with_every_beacon_out_of_view_is_still_written(tmp_path: Path, egl_renderer_factory) -> None:
    doc = tiny_doc(heights_m=[30.0], lighting=["dusk"],
                   motion={"source": "fixed", "attitudes_deg": [[0, 0, 0, 0.0, 400.0, 0.0]]})
    egl_renderer_factory(config_from_dict(doc))
    ds = render_dataset(config_from_dict(doc), tmp_path / "empty", workers=0, progress=False)
    frames = pd.read_parquet(ds / "frames.parquet")
    beacons = pd.read_parquet(ds / "beacons.parquet")
    assert frames.n_visible.tolist() == [0]
    assert not beacons.in_image.any() and not beacons.visible.any()
    assert cv2.imread(str(ds / frames.image[0])) is not None


def test_parent_process_never_creates_a_gl_context(tmp_path: Path) -> None:
    """With workers >= 1 the parent does not even import OpenGL; workers make their own context."""
    code = (
        "import sys\n"
        "from deckpose.render.config import config_from_dict\n"
        "from deckpose.render.dataset import render_dataset\n"
        f"doc = {tiny_doc(heights_m=[30.0], lighting=['night'])!r}\n"
        f"render_dataset(config_from_dict(doc), {str(tmp_path / 'ds')!r}, workers=1, progress=False)\n"
        "print('OpenGL' in sys.modules, 'pyrender' in sys.modules)\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, timeout=120)
    assert out.stdout.split() == ["False", "False"]
    assert len(list((tmp_path / "ds" / "images").glob("*.png"))) == 2


def test_each_frame_has_its_preview_made_from_the_frame_in_memory(reference: Path) -> None:
    """The log's preview is written at render time and equals the one made from the decoded frame."""
    from deckpose.preview import PREVIEW_PX, make_preview
    from deckpose.run_folder import RunPaths

    man = json.loads((reference / "manifest.json").read_text())
    assert man["preview_px"] == PREVIEW_PX
    frames = pd.read_parquet(reference / "frames.parquet")
    run = RunPaths(reference)
    for row in frames.itertuples():
        stored = cv2.imread(str(run.preview(int(row.frame_id))), cv2.IMREAD_UNCHANGED)
        full = cv2.imread(str(reference / row.image), cv2.IMREAD_UNCHANGED)
        assert stored is not None and full is not None
        np.testing.assert_array_equal(stored, make_preview(full, PREVIEW_PX))


def test_the_preview_rule_is_a_block_mean_and_keeps_the_top_8_bits() -> None:
    from deckpose.preview import make_preview, preview_size

    rng = np.random.default_rng(2)
    img16 = rng.integers(0, 65536, (40, 60, 3), dtype=np.uint16)
    small = make_preview(img16, 30)  # long side 60 -> 30: 2x2 blocks
    assert preview_size(60, 40, 30) == (30, 20) and small.shape == (20, 30, 3) and small.dtype == np.uint8
    top = (img16 >> 8).astype(float)
    block_mean = top.reshape(20, 2, 30, 2, 3).mean(axis=(1, 3))
    assert np.max(np.abs(small - block_mean)) <= 0.5 + 1e-9  # INTER_AREA: the mean, rounded
    np.testing.assert_array_equal(make_preview(img16, 4096), top.astype(np.uint8))  # never enlarged


def test_the_preview_of_a_channel_reversed_view_is_that_of_its_copy() -> None:
    # render makes the preview of the BGR view of an RGB frame; shrinking the frame as stored and
    # reversing the small result must give the pixels of shrinking a real BGR copy
    from deckpose.preview import make_preview

    rng = np.random.default_rng(3)
    for dtype, top in ((np.uint8, 256), (np.uint16, 65536)):
        rgb = rng.integers(0, top, (97, 143, 3), dtype=dtype)
        view = rgb[..., ::-1]
        small = make_preview(view, 50)
        np.testing.assert_array_equal(small, make_preview(np.ascontiguousarray(view), 50))
        assert small.flags.c_contiguous and small.shape == (34, 50, 3)


def test_resuming_a_dataset_of_an_older_version_says_so(tmp_path: Path) -> None:
    """A dataset whose manifest config lacks keys this version writes (with any value) is not mixed."""
    from deckpose.render.dataset import _prepare
    from deckpose.render.plan import plan_frames

    cfg = config_from_dict(tiny_doc())
    out = tmp_path / "old"
    out.mkdir()
    from deckpose.render.config import config_to_dict

    doc = json.loads(json.dumps(config_to_dict(cfg)))
    old = {k: v for k, v in doc.items() if k not in ("capture_epoch", "image_format")}
    old["cameras"] = [{k: v for k, v in c.items() if k != "distortion_model"} for c in doc["cameras"]]
    (out / "manifest.json").write_text(json.dumps({"format": FORMAT, "config": old}))
    with pytest.raises(ConfigError, match=r"older deckpose .*capture_epoch.*image_format.*new folder"):
        _prepare(cfg, plan_frames(cfg), out, resume=True)
    (out / "manifest.json").write_text(json.dumps({"format": FORMAT, "config": {**doc, "seed": 99}}))
    with pytest.raises(ConfigError, match=r"another config \(differs in seed\)"):
        _prepare(cfg, plan_frames(cfg), out, resume=True)
