"""An unknown option is reported by the command it was given to, with that command's usage."""

from __future__ import annotations

import pytest

from deckpose.cli import main


@pytest.mark.parametrize("command", ["estimate", "detect", "render"])
def test_unknown_option_names_the_command(command, capsys):
    with pytest.raises(SystemExit) as exc:
        main([command, "--no-such-option"])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert err.startswith(f"usage: deckpose {command} ")
    assert f"deckpose {command}: error: unrecognized arguments: --no-such-option" in err


def test_unknown_top_level_option_keeps_the_top_level_usage(capsys):
    with pytest.raises(SystemExit):
        main(["--no-such-option"])
    assert capsys.readouterr().err.startswith("usage: deckpose [-h]")
