"""Configs are typed exactly: every type hole a config had is refused with one line naming the key.

Each case is a config a user could write (the findings of the reliability issue:
truthy strings, silent int truncation, quoted numbers, duplicate keys, a binary
file, ranges, sizes beyond memory or OpenGL), through the function the CLI calls.
"""

from __future__ import annotations

import copy
from pathlib import Path

import pytest
import yaml
from deckpose.detect.synthetic_dataset import read_config as read_synthetic_config
from deckpose.render.config import DEFAULT_CONFIG, config_from_dict, load_config

from deckpose.camera_info import read_camera_info
from deckpose.cli import main
from deckpose.errors import CameraFileError, ConfigError
from deckpose.layout import read_layout
from deckpose.typed_config import coerce, parse_yaml

STRING_HINT = "a string; numbers and true/false go without quotes"


def _cfg(section: str | None, **over: object) -> dict:
    doc = copy.deepcopy(DEFAULT_CONFIG)
    if section is None:
        doc.update(over)
    else:
        doc.setdefault(section, {}).update(over)
    return doc


@pytest.mark.parametrize(
    ("section", "over", "match"),
    [
        # a non-empty string is truthy: noise "no" used to turn noise on
        ("sensor", {"noise": "no"}, r"sensor\.noise: expected true or false, got 'no'"),
        ("sensor", {"noise": "false"}, r"sensor\.noise: expected true or false"),
        ("sensor", {"exposure": True}, r"sensor\.exposure: expected a number, got true"),
        ("sensor", {"exposure": "1.0"}, r"sensor\.exposure: expected a number, got '1\.0'"),
        ("sensor", {"bit_depth": "12"}, r"sensor\.bit_depth: expected an integer, got '12'"),
        ("sensor", {"halo_fraction": 2}, r"sensor\.halo_fraction: must be >= 0 and < 1, got 2"),
        ("scene", {"sea_drift_m_per_s": "fast"}, r"scene\.sea_drift_m_per_s: expected a number"),
        ("scene", {"freeboard_m": "6"}, r"scene\.freeboard_m: expected a number, got '6'"),
        ("scene", {"texture_px": 100.0}, r"scene\.texture_px: expected an integer, got 100\.0"),
        ("layout", {"has_centre": "no"}, r"layout\.has_centre: expected true or false"),
        # 12.5 used to become 12
        ("layout", {"n_ring": 12.5}, r"layout\.n_ring: expected an integer, got 12\.5"),
        ("layout", {"n_ring": "twelve"}, r"layout\.n_ring: expected an integer, got 'twelve'"),
        ("layout", {"bow_rgb": "red"}, r"layout\.bow_rgb: expected a list, got 'red'"),
        ("motion", {"attitudes_deg": [["a", 0, 0]]}, r"motion\.attitudes_deg\[0\]\[0\]: expected a number"),
        ("motion", {"attitudes_deg": "level"}, r"motion\.attitudes_deg: expected a list"),
        (None, {"seed": 1.5}, r"seed: expected an integer, got 1\.5"),
        (None, {"heights_m": ["30"]}, r"heights_m\[0\]: expected a number, got '30'"),
        (None, {"cameras": [{"size": [640, 480], "K": "abc"}]}, r"cameras\[0\]\.K: expected a list"),
        (None, {"cameras": [{"size": [640, 480], "focal_angle_deg": "wide"}]},
         r"cameras\[0\]\.focal_angle_deg: expected a number, got 'wide'"),
        (None, {"cameras": [{"preset": "4mp", "dist_coeffs": "none"}]},
         r"cameras\[0\]\.dist_coeffs: expected a list"),
        (None, {"cameras": [{"preset": "4mp", "dist_coeffs": [0.1, 0, 0]}]},
         r"cameras\[0\]: distortion needs 0, 4, 5, 8, 12 or 14 coefficients"),
        (None, {"cameras": [{"preset": "4mp", "size": [True, 480]}]},
         r"cameras\[0\]\.size\[0\]: expected an integer, got true"),
        # a 27.9 GiB allocation used to crash the render after its folder was made
        (None, {"cameras": [{"preset": "4mp", "size": [100000, 100000]}]},
         r"cameras\[0\]\.size: 100000x100000 px is beyond what OpenGL renders"),
    ],
)
def test_render_config_type_holes_are_refused(section, over, match):
    with pytest.raises(ConfigError, match=match) as err:
        config_from_dict(_cfg(section, **over), "job.yaml")
    msg = str(err.value)
    assert msg.startswith(("job.yaml: ", "scene.deck")), msg
    assert "\n" not in msg
    if "got '" in match:
        assert STRING_HINT in msg


def test_a_frame_larger_than_memory_is_refused_before_rendering(monkeypatch):
    from deckpose.render import camera_spec

    monkeypatch.setattr(camera_spec, "_physical_memory_bytes", lambda: 2**30)  # a 1 GiB machine
    with pytest.raises(ConfigError, match=r"needs about \d+ GiB while it is rendered, more than"):
        config_from_dict(_cfg(None, cameras=[{"preset": "4mp", "size": [9000, 7000]}]), "job.yaml")


def test_tall_frames_are_drawn_in_tiles_within_the_opengl_limit(tmp_path):
    """16 x 100000 failed with a GL error hidden behind a pickling one: a frame taller than
    OpenGL's side limit is now drawn in tiles within it (16 x 20000 here, two tiles; the
    100000 px frame renders too, in 18 s)."""
    p = tmp_path / "tall.yaml"
    p.write_text("cameras: [{preset: 4mp, size: [16, 20000]}]\nheights_m: [30]\n"
                 "scene: {texture_px: 256}\n")
    assert main(["render", str(p), "-o", str(tmp_path / "ds"), "--workers", "0",
                 "--no-progress"]) == 0
    import cv2

    img = cv2.imread(str(tmp_path / "ds" / "images" / "000000.png"), cv2.IMREAD_UNCHANGED)
    assert img.shape[:2] == (20000, 16)
    # both tiles were drawn: the dark night sea shows alike at the top and at the bottom (an
    # undrawn tile is zeros or uninitialised memory)
    top, bottom = float(img[:1000].mean()), float(img[-1000:].mean())
    assert 0.3 < top < 30 and 0.3 < bottom < 30 and abs(top - bottom) < 0.5 * top


def test_the_shipped_configs_still_load():
    for p in sorted((Path(__file__).resolve().parents[1] / "configs").glob("*.yaml")):
        text = p.read_text()
        if "cameras:" in text and "heights_m:" in text and "frames_per_config" not in text:
            load_config(p)


@pytest.mark.parametrize(
    ("name", "body", "match"),
    [
        ("dup.yaml", b"seed: 1\nseed: 2\ncameras: [4mp]\nheights_m: [30]\n",
         r"key 'seed' appears twice \(lines 1 and 2\); keep one"),
        ("nested_dup.yaml", b"cameras: [4mp]\nheights_m: [30]\nsensor:\n  noise: true\n  noise: false\n",
         r"key 'noise' appears twice \(lines 4 and 5\)"),
        ("binary.yaml", b"\x89PNG\r\n\x1a\n\x00\x00\x00\rIHDR", r"not a text file \(byte 0 is not UTF-8\)"),
        ("nul.yaml", b"seed: 1\x00\n", r"not a text file \(it holds NUL bytes\)"),
        ("broken.yaml", b"cameras: [4mp\nheights_m: [30]\n", r"not valid YAML: .* at line \d+, column \d+"),
    ],
)
def test_bad_yaml_files_are_one_line(tmp_path, name, body, match):
    p = tmp_path / name
    p.write_bytes(body)
    for reader in (load_config, read_layout, read_synthetic_config):
        with pytest.raises(ConfigError, match=match) as err:
            reader(p)
        assert "\n" not in str(err.value) and str(p) in str(err.value)


def test_camera_info_yaml_faults_are_one_line(tmp_path):
    p = tmp_path / "cam.yaml"
    p.write_text("image_width: 640\nimage_width: 641\n")
    with pytest.raises(CameraFileError, match=r"key 'image_width' appears twice"):
        read_camera_info(p)
    p.write_text("image_width: [640\n")
    with pytest.raises(CameraFileError, match=r"not valid YAML: .* line \d+") as err:
        read_camera_info(p)
    assert "\n" not in str(err.value)


def test_plumb_bob_with_eight_coefficients_is_refused(tmp_path):
    p = tmp_path / "cam.yaml"
    p.write_text(
        "image_width: 640\nimage_height: 480\n"
        "camera_matrix: {rows: 3, cols: 3, data: [500, 0, 320, 0, 500, 240, 0, 0, 1]}\n"
        "distortion_model: plumb_bob\n"
        "distortion_coefficients: {rows: 1, cols: 8, data: [0.1, 0.01, 0, 0, 0, 0.01, 0, 0]}\n"
    )
    with pytest.raises(CameraFileError, match=r"plumb_bob takes 5 coefficients .* has 8; for 8 "
                                              r"write distortion_model: rational_polynomial"):
        read_camera_info(p)


def test_layout_file_typed(tmp_path):
    p = tmp_path / "deck.yaml"
    p.write_text("n_ring: twelve\n")
    with pytest.raises(ConfigError, match=r"deck\.yaml: n_ring: expected an integer, got 'twelve'"):
        read_layout(p)
    p.write_text("layout: {n_ring: 8, radius_m: 6}\n")
    lay = read_layout(p)
    assert (lay.n_ring, lay.radius_m) == (8, 6.0)


def test_render_cli_says_one_line_for_a_type_hole(tmp_path, capsys):
    p = tmp_path / "job.yaml"
    p.write_text("cameras: [{preset: 4mp, size: [64, 48]}]\nheights_m: [30]\nsensor: {noise: 'no'}\n")
    out = tmp_path / "ds"
    code = main(["render", str(p), "-o", str(out)])
    err = capsys.readouterr().err
    assert code == 2 and "sensor.noise: expected true or false" in err and "Traceback" not in err
    assert not out.exists()  # refused before anything was written


@pytest.mark.parametrize(
    ("hint", "value", "expected"),
    [
        (int, 3, 3), (float, 3, 3.0), (bool, False, False), (str, "a", "a"),
        (int | None, None, None), (tuple[float, ...], [1, 2.5], (1.0, 2.5)),
        (tuple[int, int], [1, 2], (1, 2)),
    ],
)
def test_coerce_keeps_good_values(hint, value, expected):
    got = coerce(hint, value, "x")
    assert got == expected and type(got) is type(expected)


def test_a_mistyped_key_is_named_with_the_key_it_was_meant_for():
    # a required key mistyped: the message names the typo, not only the missing key
    doc = copy.deepcopy(DEFAULT_CONFIG)
    doc["height_m"] = doc.pop("heights_m")
    with pytest.raises(ConfigError, match=r"'heights_m' is missing \(the config has 'height_m' instead: a typo\?\)"):
        config_from_dict(doc, "job.yaml")
    # an optional key mistyped inside a section
    doc = copy.deepcopy(DEFAULT_CONFIG)
    doc["sensor"] = {**doc.get("sensor", {}), "bitdepth": 12}
    with pytest.raises(ConfigError, match=r"sensor: unknown key\(s\) \['bitdepth'\] \(did you mean 'bit_depth' instead of 'bitdepth'\?\)"):
        config_from_dict(doc, "job.yaml")


def test_an_unrelated_unknown_key_gets_no_guess():
    doc = {**copy.deepcopy(DEFAULT_CONFIG), "colour_grading": 1}
    with pytest.raises(ConfigError, match=r"unknown key\(s\) \['colour_grading'\]; valid keys") as info:
        config_from_dict(doc, "job.yaml")
    assert "did you mean" not in str(info.value)


def test_exponent_numbers_without_a_dot_are_numbers(tmp_path):
    # PyYAML (YAML 1.1) reads 1e-5 as the string '1e-5'; a config author means the number,
    # as YAML 1.2 and other readers do. Quoted, it stays a string.
    doc = parse_yaml("a: 1e-5\nb: -2E+3\nc: 1.5e2\nd: '1e-5'\ne: e5\nf: 7\n", "x.yaml")
    assert doc == {"a": 1e-5, "b": -2000.0, "c": 150.0, "d": "1e-5", "e": "e5", "f": 7}
    assert type(doc["a"]) is float and type(doc["f"]) is int
    assert yaml.safe_load("a: 1e-5") == {"a": "1e-5"}  # PyYAML's own loader is left as it was
    p = tmp_path / "job.yaml"
    p.write_text("cameras: [{preset: 4mp, size: [64, 48]}]\nheights_m: [30]\nshutter: {line_delay_s: 1e-5}\n")
    assert load_config(p).shutter.line_delay_s == 1e-5
