"""``-q``: errors only, plus the command's result (its main output's path, or the data asked for)."""

from __future__ import annotations

from pathlib import Path

import pytest

from deckpose.cli import exit_codes, main


@pytest.fixture(scope="module")
def dataset(tmp_path_factory: pytest.TempPathFactory) -> Path:
    from deckpose.detect.synthetic_dataset import SyntheticDatasetConfig, write_synthetic_dataset

    cfg = SyntheticDatasetConfig(cameras=("160x120",), heights_m=(30.0,), frames_per_config=2)
    return Path(write_synthetic_dataset(cfg, tmp_path_factory.mktemp("quiet") / "ds"))


def _run(argv: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str, str]:
    code = main(argv)
    out, err = capsys.readouterr()
    return code, out, err


def test_each_stage_prints_only_its_output_path_with_q(dataset: Path, capsys: pytest.CaptureFixture[str]) -> None:
    ds = str(dataset)
    steps = [  # (argv, the path it prints); -q before the command and after it
        (["-q", "detect", ds, "--workers", "0"], dataset / "detections" / "cog.parquet"),
        (["estimate", "--run", ds, "--method", "pnp", "-q"], dataset / "estimates" / "cog--pnp.parquet"),
        (["-q", "evaluate", ds, "--no-mcap"], dataset / "evaluation" / "errors.parquet"),
        (["report", ds, "-q"], dataset / "report" / "report.md"),
    ]
    for argv, path in steps:
        code, out, err = _run(argv, capsys)
        assert code == exit_codes.OK, err
        assert out == f"{path}\n", (argv, out)  # the path alone: no summary, no bar, no label
        assert err == "", (argv, err)
        assert path.is_file()
    # without -q the same command says more
    code, out, _ = _run(["estimate", "--run", ds, "--method", "pnp", "--no-progress"], capsys)
    assert code == exit_codes.OK and "frames" in out and out != f"{steps[1][1]}\n"


def test_q_keeps_the_data_asked_for_and_the_errors(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from deckpose.detect import registry

    code, out, _ = _run(["-q", "detect", "--list"], capsys)
    assert code == exit_codes.OK and out.split() == list(registry.names())
    code, out, err = _run(["-q", "estimate", "--run", str(tmp_path / "none")], capsys)
    assert code == exit_codes.USAGE and out == "" and err.startswith("deckpose estimate: error: ")


def test_motion_with_q_prints_the_series_path_only(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out_file = tmp_path / "reg.parquet"
    code, out, err = _run(["-q", "motion", "regular", "-o", str(out_file)], capsys)
    assert code == exit_codes.OK, err
    assert out == f"{out_file}\n" and out_file.is_file()


def test_failed_frames_that_fail_the_command_are_errors_also_with_q(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # -q hid why `detect --strict` exited 4 (it printed only the path); the failed frames are
    # now printed on stderr when they fail the command, and not when it succeeds
    import shutil

    from deckpose.detect.synthetic_dataset import SyntheticDatasetConfig, write_synthetic_dataset

    cfg = SyntheticDatasetConfig(cameras=("160x120",), heights_m=(30.0,), frames_per_config=2)
    ds = Path(write_synthetic_dataset(cfg, tmp_path / "ds"))
    image = min((ds / "images").iterdir())
    image.write_bytes(b"not an image")
    code, out, err = _run(["-q", "detect", str(ds), "--workers", "0", "--strict"], capsys)
    assert code == exit_codes.SOME_FAILED
    assert out.strip() == str(ds / "detections" / "cog.parquet")
    assert "frame 0:" in err and "cannot decode" in err, err
    code, out, err = _run(["-q", "detect", str(ds), "--workers", "0"], capsys)  # not failing: quiet
    assert code == exit_codes.OK and err == "", err
    # estimate lists its failed frames by reason (it printed only the counts), and with -q when
    # they fail the command
    shutil.rmtree(ds / "estimates", ignore_errors=True)
    code, out, err = _run(["estimate", "--run", str(ds), "--method", "pnp", "--no-progress", "--strict"], capsys)
    assert code == exit_codes.SOME_FAILED
    assert "1 frame: " in out, out
    code, out, err = _run(["-q", "estimate", "--run", str(ds), "--method", "pnp", "--strict"], capsys)
    assert code == exit_codes.SOME_FAILED and "1 frame: " in err, (out, err)
