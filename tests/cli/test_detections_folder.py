"""A folder made by ``deckpose detect -o`` given where a run folder is needed: said what it is, and what to run.

Before, evaluate, estimate --run, track, export and report took it for an unfinished run folder
and suggested rendering into it.
"""

from __future__ import annotations

import shlex
from pathlib import Path

import pandas as pd
import pytest

from deckpose.cli import exit_codes, main


@pytest.fixture(scope="module")
def detections_folder(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """(dataset, the folder 'deckpose detect DATASET -o' wrote), with spaces in both paths."""
    from deckpose.detect.synthetic_dataset import SyntheticDatasetConfig, write_synthetic_dataset

    root = tmp_path_factory.mktemp("detfolder")
    cfg = SyntheticDatasetConfig(cameras=("160x120",), heights_m=(30.0,), frames_per_config=1)
    dataset = Path(write_synthetic_dataset(cfg, root / "my data"))
    out = root / "det out"
    assert main(["detect", str(dataset), "-o", str(out), "--no-progress", "--workers", "0"]) == 0
    return dataset, out


@pytest.mark.parametrize("argv", [["evaluate"], ["estimate", "--run"], ["track"], ["report"],
                                  ["export", "--format", "coco", "-o", "EXPORT"]])
def test_a_detections_folder_is_named_with_what_to_run_instead(
        detections_folder: tuple[Path, Path], argv: list[str], tmp_path: Path,
        capsys: pytest.CaptureFixture[str]) -> None:
    dataset, out = detections_folder
    argv = [str(tmp_path / "export") if a == "EXPORT" else a for a in argv]
    command = [argv[0], *argv[1:2]] if argv[0] == "estimate" else [argv[0]]
    assert main([*command, str(out), *argv[len(command):]]) == exit_codes.USAGE
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1
    assert f"{out} is a detections folder" in err and str(dataset.resolve()) in err
    assert "deckpose render" not in err  # no longer: render into it
    # the suggested commands come back from a shell as they were meant: detect into the dataset,
    # or estimate from the folder (its table, camera and layout)
    detect_cmd = err.split("to this command, e.g.: ", 1)[1].split(" then ", 1)[0]
    assert shlex.split(detect_cmd) == ["deckpose", "detect", str(dataset.resolve()), "--detector", "cog"]
    assert shlex.split(err.split("from its table alone: ", 1)[1]) == ["deckpose", "estimate", str(out)]


def test_the_suggested_table_estimate_runs(detections_folder: tuple[Path, Path], tmp_path: Path,
                                           capsys: pytest.CaptureFixture[str]) -> None:
    _, out = detections_folder
    assert main(["evaluate", str(out)]) == exit_codes.USAGE
    suggested = shlex.split(capsys.readouterr().err.split("from its table alone: ", 1)[1])
    estimates = out / "estimates.parquet"  # the folder form's default output
    estimates.unlink(missing_ok=True)
    assert main([*suggested[1:], "--no-progress"]) == exit_codes.OK
    assert estimates.is_file()
    # the same as the table form with the folder's camera
    camera = next((out / "cameras").glob("*.yaml"))
    explicit = tmp_path / "explicit.parquet"
    assert main(["estimate", str(out / "detections.parquet"), "--camera", str(camera), "-o", str(explicit),
                 "--no-progress"]) == exit_codes.OK
    pd.testing.assert_frame_equal(pd.read_parquet(estimates), pd.read_parquet(explicit))


def test_a_folder_is_estimated_with_the_layout_its_frames_had(tmp_path: Path) -> None:
    # A detections folder of a deck whose ring is 6 m, not the default 10 m: given the folder (or its
    # table), estimate uses the recorded layout. Before, the table alone was solved on the default
    # ring, which scales the pose: the heights came out 10/6 too large.
    import yaml
    from deckpose.detect.synthetic_dataset import SyntheticDatasetConfig, write_synthetic_dataset

    from deckpose.layout import DeckLayout, layout_to_dict

    layout = DeckLayout(radius_m=6.0)
    cfg = SyntheticDatasetConfig(cameras=("320x240",), heights_m=(30.0,), frames_per_config=2, layout=layout)
    dataset = Path(write_synthetic_dataset(cfg, tmp_path / "ds"))
    out = tmp_path / "det"
    assert main(["detect", str(dataset), "-o", str(out), "--no-progress", "--workers", "0"]) == exit_codes.OK
    assert main(["estimate", str(out), "--no-progress"]) == exit_codes.OK
    folder = pd.read_parquet(out / "estimates.parquet")
    camera = next((out / "cameras").glob("*.yaml"))
    layout_file = tmp_path / "layout.yaml"
    layout_file.write_text(yaml.safe_dump(layout_to_dict(layout)))
    runs = {}
    for name, extra in (("explicit", ["--layout", str(layout_file)]), ("table", []),
                        ("default", ["--layout", str(_default_layout_file(tmp_path))])):
        path = tmp_path / f"{name}.parquet"
        assert main(["estimate", str(out / "detections.parquet"), "--camera", str(camera), "-o", str(path),
                     "--no-progress", *extra]) == exit_codes.OK
        runs[name] = pd.read_parquet(path)
    assert folder["ok"].all()
    pd.testing.assert_frame_equal(folder, runs["explicit"])
    pd.testing.assert_frame_equal(runs["table"], runs["explicit"])
    # the default ring gives heights scaled by the radii's ratio (the check above can fail)
    ratio = runs["default"]["height_m"].to_numpy() / folder["height_m"].to_numpy()
    assert ratio == pytest.approx(10.0 / 6.0, rel=1e-3)


def _default_layout_file(tmp_path: Path) -> Path:
    import yaml

    from deckpose.layout import DeckLayout, layout_to_dict

    path = tmp_path / "default_layout.yaml"
    path.write_text(yaml.safe_dump(layout_to_dict(DeckLayout())))
    return path


def test_estimate_names_a_folder_that_is_not_a_detections_folder(
        detections_folder: tuple[Path, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    dataset, _ = detections_folder
    assert main(["estimate", str(dataset), "--no-progress"]) == exit_codes.USAGE
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "is a run folder" in err
    assert shlex.split(err.split("estimate it as a run, ", 1)[1]) == ["deckpose", "estimate", "--run", str(dataset)]
    empty = tmp_path / "empty dir"
    empty.mkdir()
    assert main(["estimate", str(empty), "--no-progress"]) == exit_codes.USAGE
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "without detect_run.json" in err
    assert not list(empty.iterdir())


@pytest.fixture(scope="module")
def two_camera_folder(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """(dataset of two cameras of different sizes, the folder 'deckpose detect DATASET -o' wrote)."""
    from deckpose.detect.synthetic_dataset import SyntheticDatasetConfig, write_synthetic_dataset

    root = tmp_path_factory.mktemp("detfolder2")
    cfg = SyntheticDatasetConfig(cameras=("160x120", "320x240"), heights_m=(30.0,), frames_per_config=1)
    dataset = Path(write_synthetic_dataset(cfg, root / "two cams"))
    out = root / "det out"
    assert main(["detect", str(dataset), "-o", str(out), "--no-progress", "--workers", "0"]) == 0
    return dataset, out


def test_a_table_of_two_cameras_is_not_estimated_with_one(
        two_camera_folder: tuple[Path, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # With one --camera, the other camera's frames were solved with the wrong intrinsics and
    # looked ok (a 960x540 frame as 640x480: 20 m for a true 30 m); now it is refused.
    _, out = two_camera_folder
    for cam in sorted((out / "cameras").glob("*.yaml")):
        code = main(["estimate", str(out / "detections.parquet"), "--camera", str(cam),
                     "-o", str(tmp_path / "e.parquet"), "--no-progress"])
        err = capsys.readouterr().err
        assert code == exit_codes.USAGE and "2 cameras" in err, err
        assert not (tmp_path / "e.parquet").exists()
    # nor given as the folder, without a camera
    assert main(["estimate", str(out), "--no-progress"]) == exit_codes.USAGE
    err = capsys.readouterr().err
    assert "2 cameras" in err and not (out / "estimates.parquet").exists()
    # the folder's message offers no table estimate then
    assert main(["evaluate", str(out)]) == exit_codes.USAGE
    err = capsys.readouterr().err
    assert "2 cameras" in err and "from its table alone" not in err


def test_a_camera_of_another_size_is_refused(detections_folder: tuple[Path, Path], tmp_path: Path,
                                             capsys: pytest.CaptureFixture[str]) -> None:
    from deckpose.camera import preset
    from deckpose.camera_info import write_camera_info

    _, out = detections_folder
    other = tmp_path / "other.yaml"
    write_camera_info(preset("4mp-thesis").with_size(320, 240), other)
    code = main(["estimate", str(out / "detections.parquet"), "--camera", str(other),
                 "-o", str(tmp_path / "e.parquet"), "--no-progress"])
    err = capsys.readouterr().err
    assert code == exit_codes.USAGE and "are 160x120" in err and "--camera is 320x240" in err, err


def test_detect_names_a_detections_folder_and_refuses_a_dataset_as_output(
        detections_folder: tuple[Path, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    dataset, out = detections_folder
    assert main(["detect", str(out), "--no-progress"]) == exit_codes.USAGE
    err = capsys.readouterr().err
    assert "is a detections folder" in err and str(dataset.resolve()) in err
    # -o into a rendered dataset wrote its tables beside the dataset's own: refused, nothing written
    before = sorted(p.name for p in dataset.iterdir())
    assert main(["detect", str(dataset), "-o", str(dataset), "--no-progress", "--workers", "0"]) == exit_codes.USAGE
    err = capsys.readouterr().err
    assert "is a rendered dataset" in err and "without -o" in err
    assert sorted(p.name for p in dataset.iterdir()) == before


def test_detecting_again_into_a_folder_removes_its_estimates_of_the_old_detections(
        detections_folder: tuple[Path, Path], tmp_path: Path, caplog: pytest.LogCaptureFixture) -> None:
    """The folder's estimates.parquet was made from its old detections; after a new detect its frame
    ids would name other frames, so it goes (and the log says so); a file of the user's stays."""
    import shutil

    dataset, out = detections_folder
    folder = tmp_path / "again"
    shutil.copytree(out, folder)
    assert main(["estimate", str(folder), "--no-progress"]) == exit_codes.OK
    (folder / "notes.txt").write_text("mine")
    assert (folder / "estimates.parquet").is_file()
    with caplog.at_level("WARNING"):
        assert main(["detect", str(dataset), "-o", str(folder), "--no-progress", "--workers", "0",
                     "--detector", "gauss"]) == exit_codes.OK
    assert not (folder / "estimates.parquet").exists()
    assert "estimates.parquet" in caplog.text and "replaces" in caplog.text
    assert (folder / "notes.txt").read_text() == "mine"


def test_detecting_a_dataset_again_removes_what_was_made_from_its_old_detections(
        detections_folder: tuple[Path, Path], tmp_path: Path, caplog: pytest.LogCaptureFixture) -> None:
    """estimates/cog--*.parquet (and tracks) were made from detections/cog.parquet; a new detect of
    cog replaces it, so they go (the log says so); another detector's stay."""
    import shutil

    dataset, _ = detections_folder
    run = tmp_path / "run"
    shutil.copytree(dataset, run)
    for det in ("cog", "gauss"):
        assert main(["detect", str(run), "--detector", det, "--no-progress", "--workers", "0"]) == exit_codes.OK
        assert main(["estimate", "--run", str(run), "--detector", det, "--method", "pnp",
                     "--no-progress"]) == exit_codes.OK
    assert (run / "estimates" / "cog--pnp.parquet").is_file()
    with caplog.at_level("WARNING"):
        assert main(["detect", str(run), "--detector", "cog", "--no-progress", "--workers", "0"]) == exit_codes.OK
    assert not (run / "estimates" / "cog--pnp.parquet").exists()
    assert (run / "estimates" / "gauss--pnp.parquet").is_file()
    assert "cog--pnp.parquet" in caplog.text and "replaces" in caplog.text
