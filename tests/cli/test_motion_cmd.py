import numpy as np
import pandas as pd
import pytest
import yaml

from deckpose.cli import main
from deckpose.motion.series import read_series
from tests.motion.reference import THESIS_CSV


def test_sea_writes_series_config_and_plot(tmp_path, capsys):
    out, png = tmp_path / "ss6.parquet", tmp_path / "ss6.png"
    rc = main(["motion", "sea", "--sea-state", "6", "--duration-s", "60", "--seed", "3",
               "-o", str(out), "--plot", str(png)])
    assert rc == 0
    s = read_series(out)
    assert len(s) == 601 and np.any(s.roll_rad) and np.any(s.surge_m)
    cfg = yaml.safe_load((tmp_path / "ss6.motion.yaml").read_text())
    assert cfg["seed"] == 3 and cfg["sea"]["hs_m"] == 5.0 and cfg["ship"]["name"] == "ffg7"
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert "significant amplitudes" in capsys.readouterr().out
    # Same seed, same series.
    again = tmp_path / "again.parquet"
    assert main(["motion", "sea", "--duration-s", "60", "--seed", "3", "-o", str(again)]) == 0
    np.testing.assert_array_equal(read_series(again).heave_m, s.heave_m)


@pytest.mark.parametrize(("suffix", "magic"), [(".jpg", b"\xff\xd8\xff"), (".pdf", b"%PDF"),
                                             (".svg", b"<?xml")])
def test_plot_format_follows_the_suffix(tmp_path, suffix, magic):
    # --plot x.jpg wrote PNG data into a .jpg
    path = tmp_path / f"motion{suffix}"
    assert main(["motion", "regular", "--duration-s", "20", "--plot", str(path)]) == 0
    assert path.read_bytes()[: len(magic)] == magic


def test_plot_with_an_unknown_suffix_is_one_line(tmp_path, capsys):
    assert main(["motion", "regular", "--duration-s", "20", "--plot", str(tmp_path / "m.xyz")]) == 2
    err = capsys.readouterr().err
    assert "m.xyz" in err and ".png" in err and "Traceback" not in err
    assert not list(tmp_path.iterdir())  # nothing half-written


def test_readme_motion_example_writes_under_runs(tmp_path, monkeypatch, capsys):
    # The README's example, run as typed from a checkout (here a copy of its configs):
    # its outputs land in runs/ (ignored by git), not in the repository root.
    import re
    import shutil
    from pathlib import Path

    repo = Path(__file__).resolve().parents[2]
    readme = (repo / "README.md").read_text()
    cmd = re.search(r"deckpose motion sea --config (\S+) \\\n\s+-o (\S+) --plot (\S+)", readme)
    assert cmd, "the README's motion example moved"
    cfg, out, plot = cmd.groups()
    assert out.startswith("runs/")
    shutil.copytree(repo / "configs", tmp_path / "configs")
    monkeypatch.chdir(tmp_path)
    assert main(["motion", "sea", "--config", cfg, "-o", out, "--plot", str(tmp_path / "m.png"),
                 "--duration-s", "60"]) == 0
    assert (tmp_path / out).is_file() and (tmp_path / out).with_suffix("").with_suffix(
        ".motion.yaml").is_file()
    assert plot.startswith("reports/")


def test_thesis_table_and_read_round_trip(tmp_path):
    if not THESIS_CSV.is_file():
        pytest.skip(f"reference file {THESIS_CSV} absent")
    table = tmp_path / "thesis.csv"
    assert main(["motion", "thesis", "--thesis-table", "-o", str(table)]) == 0
    ours, ref = pd.read_csv(table), pd.read_csv(THESIS_CSV)
    assert list(ours.columns) == list(ref.columns)
    np.testing.assert_allclose(ours.to_numpy(), ref.to_numpy(), atol=1e-12)


def test_regular_radians_then_read(tmp_path):
    out = tmp_path / "reg.csv"
    assert main(["motion", "regular", "--period-s", "9", "--duration-s", "30", "--radians", "-o", str(out)]) == 0
    assert "roll_rad" in pd.read_csv(out).columns
    png = tmp_path / "reg.png"
    assert main(["motion", "read", str(out), "--radians", "--plot", str(png)]) == 0
    assert png.stat().st_size > 0


@pytest.mark.parametrize("argv, message", [
    (["motion", "sea", "--sea-state", "10", "-o", "x.csv"], "1 to 9"),
    (["motion", "sea", "--hs-m", "-1", "-o", "x.csv"], "> 0 m"),
    (["motion", "read", "-o", "x.csv"], "needs an input FILE"),
    (["motion", "sea"], "nothing to do"),
])
def test_errors_are_clear(tmp_path, monkeypatch, capsys, argv, message):
    monkeypatch.chdir(tmp_path)
    assert main(argv) == 2
    assert message in capsys.readouterr().err


def test_read_file_with_missing_columns(tmp_path, capsys):
    bad = tmp_path / "bad.csv"
    pd.DataFrame({"t_s": [0.0, 1.0], "heave_m": [0.0, 1.0]}).to_csv(bad, index=False)
    assert main(["motion", "read", str(bad), "-o", str(tmp_path / "o.csv")]) == 2
    assert "missing column" in capsys.readouterr().err


def test_config_file_with_flag_override_and_rerun(tmp_path):
    from tests.motion.test_config import CONFIG

    first = tmp_path / "a.csv"
    assert main(["motion", "sea", "--config", str(CONFIG), "--duration-s", "20", "--speed-kn", "10",
                 "-o", str(first)]) == 0
    cfg = yaml.safe_load((tmp_path / "a.motion.yaml").read_text())
    assert cfg["seed"] == 1 and cfg["sea"]["speed_kn"] == 10.0 and cfg["duration_s"] == 20.0
    second = tmp_path / "b.csv"  # the resolved file repeats the run exactly
    assert main(["motion", "sea", "--config", str(tmp_path / "a.motion.yaml"), "-o", str(second)]) == 0
    assert first.read_text() == second.read_text()
