"""Writers check their output before the work, lock it, and clean what a killed writer left."""

from __future__ import annotations

import errno
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from deckpose import output_folder
from deckpose.cli import main, os_error_line
from deckpose.output_folder import LOCK_NAME, OutputFolderError, claim_output, release


def _holder(folder: Path) -> subprocess.Popen:
    """Another process that claims ``folder`` and keeps it until killed."""
    code = (
        "import sys, time\n"
        "from deckpose.output_folder import claim_output\n"
        f"claim_output({str(folder)!r}, what='render')\n"
        "print('held', flush=True)\n"
        "time.sleep(60)\n"
    )
    proc = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, text=True)
    assert proc.stdout is not None and proc.stdout.readline().strip() == "held"
    return proc


def test_a_second_job_on_a_folder_is_refused_and_a_killed_one_leaves_no_lock(tmp_path):
    folder = tmp_path / "ds"
    proc = _holder(folder)
    try:
        with pytest.raises(OutputFolderError, match=rf"being written by another deckpose job "
                                                    rf"\(deckpose render, pid {proc.pid}, since "):
            claim_output(folder, what="detect")
    finally:
        proc.send_signal(signal.SIGKILL)
        proc.wait()
        assert proc.stdout is not None
        proc.stdout.close()
    # the kernel dropped the dead process's lock: the same command runs now
    p = claim_output(folder, what="detect")
    assert (p / LOCK_NAME).is_file()
    release(p)
    assert not (folder / LOCK_NAME).exists()  # released and removed


def test_one_process_may_claim_a_folder_again(tmp_path):
    a = claim_output(tmp_path / "run", what="pipeline")
    try:
        assert claim_output(tmp_path / "run", what="detect") == a  # the pipeline's own stage
    finally:
        release(a)


def test_stale_temporary_files_go_when_a_folder_is_claimed(tmp_path):
    run = tmp_path / "run"
    (run / "detections").mkdir(parents=True)
    stale = [run / ".log.mcap.k2j3h4.tmp.mcap", run / "detections" / ".cog.parquet.abc.tmp.parquet"]
    keep = [run / "log.mcap", run / "detections" / "cog.parquet", run / ".hidden_notes"]
    for p in stale + keep:
        p.write_text("x")
    release(claim_output(run, what="evaluate"))
    assert not any(p.exists() for p in stale)
    assert all(p.exists() for p in keep)


def test_read_only_output_is_refused_before_any_frame_is_detected(tiny_dataset_path, tmp_path,
                                                                  monkeypatch, capsys):
    import deckpose.detect.run as run_mod

    def read_only(*_a, **_k):
        raise OSError(errno.EROFS, "Read-only file system")

    monkeypatch.setattr(output_folder.tempfile, "mkstemp", read_only)
    monkeypatch.setattr(run_mod, "detect_frames", lambda *a, **k: pytest.fail("frames were detected"))
    code = main(["detect", str(tiny_dataset_path), "-o", str(tmp_path / "out"), "--no-progress"])
    err = capsys.readouterr().err
    assert code == 2, err
    assert "cannot write in" in err and "Read-only file system" in err and "-o DIR" in err
    assert "Traceback" not in err and err.count("\n") == 1


def test_no_room_is_said_before_the_work(tmp_path, monkeypatch):
    class Usage:
        free = 10_000

    monkeypatch.setattr(output_folder.shutil, "disk_usage", lambda _p: Usage)
    with pytest.raises(OutputFolderError, match=r"writes about 2\.0 MB but the disk has 10\.0 kB free"):
        output_folder.ensure_writable(tmp_path / "o", need_bytes=2_000_000)


def test_file_system_errors_are_one_line_with_the_fix():
    line, code = os_error_line(OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), "/d/x.parquet"))
    assert code == 1 and "the disk is full (writing /d/x.parquet)" in line and "same command" in line
    line, code = os_error_line(PermissionError(errno.EACCES, "Permission denied", "/d"))
    assert code == 2 and "cannot write /d: Permission denied" in line and "choose a folder you can write to" in line and "-o DIR" not in line


def test_a_full_disk_in_estimate_is_one_line(tmp_path, monkeypatch, capsys):
    import deckpose.cli.estimate_cmd as cmd

    def full(*_a, **_k):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(tmp_path / "o.csv"))

    monkeypatch.setattr(cmd, "_method_spec", full)
    code = main(["estimate", "d.csv", "--camera", "c.yaml", "-o", str(tmp_path / "o.csv")])
    err = capsys.readouterr().err
    assert code == 1 and "the disk is full" in err and "Traceback" not in err


@pytest.fixture
def tiny_dataset_path(tmp_path) -> Path:
    from deckpose.detect.synthetic_dataset import SyntheticDatasetConfig, write_synthetic_dataset

    cfg = SyntheticDatasetConfig(cameras=("160x120",), heights_m=(30.0,), frames_per_config=1)
    return Path(write_synthetic_dataset(cfg, tmp_path / "ds"))


def test_lock_file_records_holder(tmp_path):
    p = claim_output(tmp_path / "x", what="render")
    try:
        text = (p / LOCK_NAME).read_text()
        assert f"pid {os.getpid()}" in text and "deckpose render" in text
        assert time.strftime("%Y-") in text
    finally:
        release(p)


def test_a_full_disk_in_render_says_the_disk_is_full(tmp_path, monkeypatch, capsys):
    # the disk fills while a frame's image is written: the error names no file (a write
    # or fsync), and OpenCV, which used to write the frames, only said that it had failed
    cfg = tmp_path / "job.yaml"
    cfg.write_text("cameras: [{preset: 4mp, size: [64, 48]}]\nheights_m: [30]\n")
    real_fsync = os.fsync

    def fsync(fd: int) -> None:
        if f"{os.sep}images{os.sep}" in os.readlink(f"/proc/self/fd/{fd}"):
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        real_fsync(fd)

    monkeypatch.setattr(os, "fsync", fsync)
    code = main(["render", str(cfg), "-o", str(tmp_path / "ds"), "--workers", "0", "--no-progress"])
    err = capsys.readouterr().err
    assert code == 1 and "the disk is full" in err and "same command again" in err
    assert f"{tmp_path / 'ds' / 'images'}" in err, err  # the file it was writing
    assert "Traceback" not in err and err.count("\n") == 1


def test_read_only_output_is_one_line_for_every_writer(tmp_path, monkeypatch, capsys):
    # render, pipeline, motion and estimate said "OSError [Errno 30]" (exit 1)
    from deckpose.camera import preset
    from deckpose.camera_info import write_camera_info

    cfg = tmp_path / "job.yaml"
    cfg.write_text("cameras: [{preset: 4mp, size: [64, 48]}]\nheights_m: [30]\n")
    cam = tmp_path / "cam.yaml"
    write_camera_info(preset("8mp"), cam)
    det = tmp_path / "d.csv"
    det.write_text("frame_id,beacon_id,u_px,v_px\n0,0,1.0,2.0\n")

    def read_only(*_a, **_k):
        raise OSError(errno.EROFS, "Read-only file system")

    monkeypatch.setattr(output_folder.tempfile, "mkstemp", read_only)
    ro = tmp_path / "ro"
    for argv in (["render", str(cfg), "-o", str(ro / "ds"), "--no-progress"],
                 ["pipeline", str(cfg), str(ro / "run"), "--no-progress"],
                 ["motion", "thesis", "-o", str(ro / "m.csv")],
                 ["estimate", str(det), "--camera", str(cam), "-o", str(ro / "p.csv")]):
        code = main(argv)
        err = capsys.readouterr().err
        assert code == 2, (argv[0], err)
        assert "cannot write in" in err and "Read-only file system" in err, (argv[0], err)
        assert "Traceback" not in err and err.count("\n") == 1


def test_reading_a_dataset_another_job_is_rendering_says_so(tmp_path):
    """An unfinished dataset a live render holds: wait for it (not 'finish it with --resume')."""
    import json

    from deckpose.detect.sources import open_dataset

    from deckpose.errors import InputDataError
    from deckpose.output_folder import held_by_another
    from deckpose.run_folder import DATASET_FORMAT

    folder = tmp_path / "ds"
    folder.mkdir()
    (folder / "manifest.json").write_text(json.dumps({"format": DATASET_FORMAT, "complete": False, "n_frames": 4}))
    with pytest.raises(InputDataError, match="unfinished dataset.*--resume"):
        open_dataset(folder)  # nobody holds it: a killed render, to be resumed
    proc = _holder(folder)
    try:
        assert (held_by_another(folder) or "").startswith(f"deckpose render, pid {proc.pid}, since ")
        with pytest.raises(InputDataError, match=rf"still being rendered by another deckpose job \(deckpose "
                                                 rf"render, pid {proc.pid}.*0 of 4 frames so far\); wait"):
            open_dataset(folder)
    finally:
        proc.send_signal(signal.SIGKILL)
        proc.wait()
        assert proc.stdout is not None
        proc.stdout.close()
    assert held_by_another(folder) is None  # the dead job's lock file is no one's
