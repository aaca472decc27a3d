"""The README's commands, as written: every one parses, the cheap ones run, and their printed
figures are the README's.

The quick start's two scripts run in CI (``.ci/run`` runs ``scripts/test.sh``; the demo is
``tests/cli/test_demo_cmd.py``). The full-scale examples (the thesis sweep, full thesis
tables) take hours, so they are parsed by the real parser, which catches a renamed option
or command; the others run here in a scratch folder holding the repository's configs.
"""

from __future__ import annotations

import re
import shlex
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from deckpose.camera import preset
from deckpose.camera_info import write_camera_info
from deckpose.cli import build_parser
from deckpose.layout import DeckLayout
from deckpose.pose import CameraPose, ShipPose
from deckpose.projection import project_layout

REPO = Path(__file__).resolve().parents[1]
README = (REPO / "README.md").read_text()


def readme_commands() -> list[str]:
    """The ``deckpose ...`` command lines of the README's bash blocks (continuations joined)."""
    cmds = []
    for block in re.findall(r"```bash\n(.*?)```", README, re.DOTALL):
        text = block.replace("\\\n", " ")
        for line in text.splitlines():
            line = line.split(" #")[0].strip()
            if line.startswith((".venv/bin/deckpose ", "deckpose ")):
                cmds.append(line.removeprefix(".venv/bin/"))
    return cmds


COMMANDS = readme_commands()


def test_the_readme_has_commands():
    assert len(COMMANDS) >= 10
    assert any(c.startswith("deckpose motion ") for c in COMMANDS)


@pytest.mark.parametrize("cmd", COMMANDS)
def test_every_readme_command_parses(cmd):
    args = build_parser().parse_args(shlex.split(cmd)[1:])
    assert getattr(args, "func", None) is not None


def _run(cmd: str, cwd: Path) -> str:
    argv = [sys.executable, "-m", "deckpose", *shlex.split(cmd)[1:]]
    p = subprocess.run(argv, cwd=cwd, capture_output=True, text=True, timeout=300, check=False)
    assert p.returncode == 0, f"{cmd}: {p.stderr}"
    return p.stdout


@pytest.fixture
def scratch(tmp_path: Path) -> Path:
    (tmp_path / "configs").symlink_to(REPO / "configs")
    return tmp_path


def test_readme_motion_example_runs_and_prints_the_readme_figures(scratch):
    cmd = next(c for c in COMMANDS if c.startswith("deckpose motion sea "))
    out = _run(cmd, scratch)
    block = README[README.index("deckpose motion sea "):]
    stated = re.search(r"# (significant amplitudes .*)", block).group(1)
    assert stated in out, (stated, out)
    assert (scratch / "runs" / "ss6.parquet").is_file()
    assert (scratch / "reports" / "figures" / "motion_ss6_frigate.png").stat().st_size > 10_000


def test_readme_estimate_example_runs_as_written(scratch):
    cmd = next(c for c in COMMANDS if c.startswith("deckpose estimate detections.csv"))
    cam = preset("8mp")
    write_camera_info(cam, scratch / "camera_info.yaml")
    rows = []
    for fid, (roll, pitch) in enumerate([(0.02, -0.01), (0.05, 0.03)]):
        pr = project_layout(DeckLayout(), ShipPose(roll, pitch, 0.3), CameraPose.nadir(40.0), cam)
        for bid, (u, v) in enumerate(pr.points_px):
            rows.append({"frame_id": fid, "beacon_id": bid, "u_px": u, "v_px": v})
    pd.DataFrame(rows).to_csv(scratch / "detections.csv", index=False)
    _run(cmd, scratch)
    poses = pd.read_csv(scratch / "poses.csv")
    assert poses.ok.all() and np.allclose(np.radians(poses.roll_deg), [0.02, 0.05], atol=1e-6)


def test_readme_smoke_render_examples_run_as_written(scratch):
    first, resume = (c for c in COMMANDS if c.startswith("deckpose render configs/smoke.yaml"))
    assert "--resume" in resume
    _run(first, scratch)
    frames = pd.read_parquet(scratch / "datasets" / "smoke" / "frames.parquet")
    assert len(frames) == 24  # "24 small frames"
    _run(resume, scratch)  # a finished dataset resumes to itself
