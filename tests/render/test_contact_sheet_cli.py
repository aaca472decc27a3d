"""The contact sheet's command line: bad input is one line on stderr and exit status 2, nothing written."""

from __future__ import annotations

from pathlib import Path

import pytest
from deckpose.render.contact_sheet import main


@pytest.mark.parametrize(("argv", "says"), [
    (["--config", "no/such.yaml"], "cannot read render config no/such.yaml"),
    (["--presets", "8mp-sqare"], "unknown camera preset '8mp-sqare'"),
])
def test_bad_input_is_one_line_and_status_2(argv: list[str], says: str, tmp_path: Path,
                                            capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "sheet.png"
    assert main([str(out), *argv]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("contact_sheet: error: ") and says in err
    assert not out.exists()
