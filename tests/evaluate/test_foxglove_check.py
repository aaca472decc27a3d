"""The log and layout pass tools/foxglove_check (the Foxglove app's reader libraries), when it is installed.

Optional: needs ``node`` and the checker's packages (``npm ci --prefix tools/foxglove_check``).
"""

import json
import shutil
import subprocess
from pathlib import Path

import pytest

TOOL = Path(__file__).resolve().parents[2] / "tools" / "foxglove_check"
NODE = shutil.which("node")

pytestmark = pytest.mark.skipif(
    NODE is None or not (TOOL / "node_modules").is_dir(),
    reason="needs node and the Foxglove checker's packages; enable with: npm ci --prefix tools/foxglove_check",
)


def _check(*paths: Path) -> subprocess.CompletedProcess:
    return subprocess.run([NODE, str(TOOL / "check.mjs"), *map(str, paths)], capture_output=True, text=True,
                          timeout=120, check=False)


def test_log_and_layout_pass_the_app_readers(evaluated_run):
    r = _check(evaluated_run / "log.mcap", evaluated_run / "foxglove_layout.json")
    assert r.returncode == 0, r.stdout + r.stderr
    assert "OK: no problems" in r.stdout
    for topic in ("/camera/image", "/camera/calibration", "/annotations/truth", "/annotations/fake", "/tf",
                  "/errors/fake--thesis"):
        assert topic in r.stdout


def test_check_fails_on_a_layout_the_app_misreads(evaluated_run, tmp_path):
    layout = json.loads((evaluated_run / "foxglove_layout.json").read_text())
    del layout["playbackConfig"]
    layout["configById"]["3D!deckpose"]["transforms"] = {"axisScale": 3}
    layout["configById"]["Plot!errors"]["paths"][0]["value"] = "/errors/fake--thesis.no_such_field"
    bad = tmp_path / "layout.json"
    bad.write_text(json.dumps(layout))
    r = _check(evaluated_run / "log.mcap", bad)
    assert r.returncode == 1
    assert "playbackConfig" in r.stdout and 'transforms["axisScale"]' in r.stdout
    assert "no numeric field no_such_field" in r.stdout
