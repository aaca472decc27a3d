"""Malformed files through every CLI reader: a one-line DeckposeError naming the file, never a
traceback (property-based, bounded to keep the suite fast).

Each case starts from a valid file of its kind (the repository's own) and damages it the
ways files get damaged: a line dropped, a value replaced by a random token, a key
repeated, bytes that are not text, a truncation.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml
from deckpose.detect.synthetic_dataset import read_config as read_synthetic_config
from deckpose.render.config import load_config
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from deckpose.camera import preset
from deckpose.camera_info import camera_to_dict, read_camera_info
from deckpose.detections_io import detections_from_frame
from deckpose.errors import DeckposeError
from deckpose.layout import DeckLayout, read_layout
from deckpose.motion.config import parse_sea_run
from deckpose.tables import read_table
from deckpose.typed_config import load_yaml

REPO = Path(__file__).resolve().parents[1]

VALID = {
    "camera": yaml.safe_dump(camera_to_dict(preset("8mp"))),
    "layout": "n_ring: 12\nradius_m: 10.0\nhas_centre: true\nbeacon_radius_m: 0.15\n",
    "render": (REPO / "configs" / "smoke.yaml").read_text(),
    "synthetic": "cameras: [160x120]\nheights_m: [30.0]\nframes_per_config: 1\ncolour: true\n",
    "motion": (REPO / "configs" / "motion" / "ss6_frigate.yaml").read_text(),
    "detections": "frame_id,beacon_id,u_px,v_px\n0,0,100.5,200.25\n0,1,120.0,210.0\n1,0,99.0,201.0\n",
}


def _read(kind: str, path: Path) -> None:
    if kind == "camera":
        read_camera_info(path)
    elif kind == "layout":
        read_layout(path)
    elif kind == "render":
        load_config(path)
    elif kind == "synthetic":
        read_synthetic_config(path)
    elif kind == "motion":
        doc = load_yaml(path, "motion configuration")
        if isinstance(doc, dict):
            doc = {k: v for k, v in doc.items() if k not in ("angles", "samples")}
        parse_sea_run(doc)  # type: ignore[arg-type]
    else:
        detections_from_frame(read_table(path, "detections"), DeckLayout(), str(path))


TOKENS = st.sampled_from(["", "x", "-1", "1e400", "nan", "true", "[1, 2", "{a: 1}", "null", "12.5",
                          "'3'", "[]", "- - -", "\t", ":", "&a", "*a", "!!python/object:os.system",
                          "9" * 40, "é", "0x10"])


@st.composite
def damaged(draw, kind: str) -> bytes:
    lines = VALID[kind].splitlines(keepends=True)
    for _ in range(draw(st.integers(1, 4))):
        if not lines:
            break
        i = draw(st.integers(0, len(lines) - 1))
        how = draw(st.sampled_from(["drop", "value", "repeat", "bytes", "truncate", "token_line"]))
        if how == "drop":
            del lines[i]
        elif how == "value" and (":" in lines[i] or "," in lines[i]):
            sep = ":" if ":" in lines[i] else ","
            head = lines[i].split(sep)[0]
            lines[i] = f"{head}{sep} {draw(TOKENS)}\n" if sep == ":" else f"{head},{draw(TOKENS)}\n"
        elif how == "repeat":
            lines.insert(i, lines[i])
        elif how == "bytes":
            raw = draw(st.binary(min_size=1, max_size=8))
            lines[i] = raw.decode("latin-1") + lines[i]
        elif how == "truncate":
            lines[i] = lines[i][: draw(st.integers(0, len(lines[i])))]
        else:
            lines.insert(i, draw(TOKENS) + "\n")
    return "".join(lines).encode("latin-1", "replace")


@pytest.mark.parametrize("kind", sorted(VALID))
@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.data())
def test_damaged_files_give_one_line_errors(kind, data, tmp_path):
    body = data.draw(damaged(kind))
    path = tmp_path / ("d.csv" if kind == "detections" else f"{kind}.yaml")
    path.write_bytes(body)
    try:
        _read(kind, path)
    except DeckposeError as exc:
        msg = str(exc)
        assert msg and len(msg) < 2000
        assert str(path) in msg or path.name in msg or kind in ("motion", "detections"), msg
    # anything but a DeckposeError escapes and fails the test (a traceback for the user)


@pytest.mark.parametrize("kind", sorted(VALID))
def test_the_valid_files_read(kind, tmp_path):
    path = tmp_path / ("d.csv" if kind == "detections" else f"{kind}.yaml")
    path.write_text(VALID[kind])
    _read(kind, path)


def test_detections_reader_on_random_tables(tmp_path):
    rng = np.random.default_rng(0)
    for k in range(60):
        n = int(rng.integers(0, 6))
        cols = {c: rng.choice([1.5, "x", None, 2**70, -1, True], n)
                for c in ("frame_id", "beacon_id", "u_px", "v_px") if rng.random() > 0.1}
        p = tmp_path / f"t{k}.csv"
        pd.DataFrame(cols).to_csv(p, index=False)
        try:
            detections_from_frame(read_table(p, "detections"), DeckLayout(), str(p))
        except DeckposeError as exc:
            assert str(p) in str(exc) or "detections" in str(exc)
