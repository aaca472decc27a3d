"""Ctrl-C during a multi-worker ``deckpose render``: one line, exit 130, no traceback, resumable.

The interrupt goes to the whole process group, as a terminal's Ctrl-C does, so the
workers get it too (they must ignore it: :mod:`deckpose.worker_pool`).
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pandas as pd
import yaml

from deckpose.atomic_io import is_temp_name
from deckpose.cli import exit_codes

#: Seconds the interrupted command may take to exit. The workers get deckpose.worker_pool.GRACE_S
#: (3 s) to finish their frame before they are terminated; the rest is slack for a loaded 2-core
#: machine (a hang, the bug this guards against, never ends).
STOP_WITHIN_S = 20.0
#: Frames in the job. The pool hands out one frame a task, keeps ``workers + 1`` more queued to
#: its workers, and the workers finish what they hold in their grace period, so the frames written
#: by the time the command stops are a handful, not one (6 of 24 at 640 x 480 on an idle 2-core
#: machine; all 8 of the 320 x 240 job this test first used, on CI). 24 leaves a wide margin, and
#: the resume renders the rest in a few seconds.
N_FRAMES = 24


def _config(tmp_path: Path) -> Path:
    attitudes = [[float(i % 8), -float(i % 8) / 2, 5.0 * i] for i in range(N_FRAMES)]
    doc = {"name": "ctrlc", "seed": 2, "cameras": [{"preset": "4mp", "size": [640, 480]}], "heights_m": [30],
           "lighting": ["dusk"], "motion": {"source": "fixed", "attitudes_deg": attitudes},
           "scene": {"texture_px": 128}}
    cfg = tmp_path / "ctrlc.yaml"
    cfg.write_text(yaml.safe_dump(doc))
    return cfg


def _deckpose(*argv: str) -> list[str]:
    return [sys.executable, "-m", "deckpose", *argv]


def _wait_for_a_frame(proc: subprocess.Popen, parts: Path) -> None:
    """Until the render has written a frame (its part file); it must still be running."""
    deadline = time.monotonic() + 120.0
    while proc.poll() is None and time.monotonic() < deadline:
        if parts.is_dir() and any(parts.glob("*.json")):
            break
        time.sleep(0.05)
    assert proc.poll() is None, f"the render ended before it could be stopped: {proc.communicate()}"


def _stderr_once_stopped(proc: subprocess.Popen, what: str) -> str:
    """The stopped command's stderr; it must stop within :data:`STOP_WITHIN_S` (else killed, and fail)."""
    try:
        _, err = proc.communicate(timeout=STOP_WITHIN_S)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.communicate()
        raise AssertionError(f"deckpose render did not stop within {STOP_WITHIN_S} s of {what}") from None
    return err


def test_ctrl_c_stops_a_two_worker_render_with_one_line_and_it_resumes(tmp_path: Path) -> None:
    cfg, out = _config(tmp_path), tmp_path / "ds"
    # pytest started in the background of a shell (``&``, nohup) runs with SIGINT ignored, which
    # exec passes on (the command would never see the interrupt); handled here, it is reset in the child
    handler = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        proc = subprocess.Popen(_deckpose("render", str(cfg), str(out), "--workers", "2", "--no-progress"),
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True)
    finally:
        signal.signal(signal.SIGINT, handler)
    parts = out / ".parts"
    _wait_for_a_frame(proc, parts)
    os.killpg(proc.pid, signal.SIGINT)  # parent and workers, as Ctrl-C in a terminal
    err = _stderr_once_stopped(proc, "Ctrl-C")
    assert proc.returncode == exit_codes.INTERRUPTED, err
    assert "Traceback" not in err and "KeyboardInterrupt" not in err, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("deckpose render: interrupted") and "--resume" in lines[0]
    done = sorted(parts.glob("*.json"))
    assert 1 <= len(done) < N_FRAMES, "the interrupt should land mid-job"
    assert not (out / "frames.parquet").exists()  # the tables are written only when every frame is
    # resume: the same command with --resume renders the rest and leaves no temporary file
    rerun = subprocess.run(_deckpose("render", str(cfg), str(out), "--workers", "2", "--no-progress",
                                     "--resume"), capture_output=True, text=True, check=False, timeout=300)
    assert rerun.returncode == 0, rerun.stderr
    frames = pd.read_parquet(out / "frames.parquet")
    assert sorted(frames.frame_id) == list(range(N_FRAMES))
    assert all((out / image).is_file() for image in frames.image)
    assert not [p for p in out.rglob("*") if is_temp_name(p.name)]


def test_sigterm_to_the_parent_stops_the_workers_too_with_one_line(tmp_path: Path) -> None:
    """``kill PID`` or ``timeout`` signal the parent alone: it stops as for Ctrl-C (exit 143), and no
    worker outlives it (Python's default died at once and left the workers and their semaphores)."""
    cfg, out = _config(tmp_path), tmp_path / "ds"
    proc = subprocess.Popen(_deckpose("render", str(cfg), str(out), "--workers", "2", "--no-progress"),
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True)
    _wait_for_a_frame(proc, out / ".parts")
    proc.send_signal(signal.SIGTERM)  # the parent only
    err = _stderr_once_stopped(proc, "SIGTERM")
    assert proc.returncode == exit_codes.TERMINATED, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("deckpose render: interrupted"), err
    # the process group (the parent's session) empties: every worker has gone (an exited
    # worker may stay a zombie for a moment, until init reaps it)
    deadline = time.monotonic() + STOP_WITHIN_S
    while time.monotonic() < deadline:
        try:
            os.killpg(proc.pid, 0)
        except ProcessLookupError:
            return
        time.sleep(0.2)
    os.killpg(proc.pid, signal.SIGKILL)
    raise AssertionError("worker processes outlived the stopped render")
