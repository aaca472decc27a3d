"""Suggested ``deckpose`` commands quote their paths (deckpose.shell_command), everywhere."""

from __future__ import annotations

import ast
import re
import shlex
from pathlib import Path

import pytest

from deckpose.cli import SUBCOMMAND_MODULES, main
from deckpose.shell_command import deckpose_command

REPO = Path(__file__).resolve().parents[1]


def test_every_word_comes_back_from_a_shell_unchanged() -> None:
    path = Path("my runs") / "it's $HOME" / "a;b"
    words = ["render", "CONFIG.yaml", path, "--method", "pnp+mean"]
    line = deckpose_command(*words)
    assert shlex.split(line) == ["deckpose", *map(str, words)]
    assert line.startswith("deckpose render CONFIG.yaml '")  # placeholders and names are left bare
    assert line.endswith(" --method pnp+mean")


def _hint(err: str, after: str) -> list[str]:
    """The command a one-line error suggests after ``after``, split as a shell would."""
    return shlex.split(err.split(after, 1)[1].strip())


def test_a_missing_run_folder_with_a_space_is_quoted_in_the_hint(tmp_path: Path,
                                                                 capsys: pytest.CaptureFixture[str]) -> None:
    run = tmp_path / "my runs" / "run 1"
    assert main(["estimate", "--run", str(run)]) == 2
    err = capsys.readouterr().err
    assert _hint(err, "make it with:") == ["deckpose", "render", "CONFIG.yaml", str(run)]


def test_report_before_evaluate_names_the_quoted_evaluate_command(tmp_path: Path,
                                                                  capsys: pytest.CaptureFixture[str]) -> None:
    run = tmp_path / "a run"
    run.mkdir()
    for name in ("manifest.json", "frames.parquet", "beacons.parquet"):  # present, as the check asks
        (run / name).write_text("{}")
    assert main(["report", str(run)]) == 2
    err = capsys.readouterr().err
    assert _hint(err, "make it with:") == ["deckpose", "evaluate", str(run)]


def _subcommands() -> list[str]:
    from deckpose.cli import build_parser

    parser = build_parser()
    sub = next(a for a in parser._actions if a.dest == "command")
    assert sub.choices is not None and len(sub.choices) >= len(SUBCOMMAND_MODULES)
    return sorted(sub.choices)


def test_no_message_writes_a_command_with_a_value_in_an_f_string() -> None:
    # "deckpose SUBCOMMAND <words> {value}" in an f-string is a hint that would print a path unquoted;
    # such hints are built by deckpose_command. (A title like "deckpose report: {...}" is not a command.)
    names = "|".join(map(re.escape, _subcommands()))
    pattern = re.compile(r"deckpose (" + names + r") [^;)`'\"]*\{")  # a command ends at ; ) ` or a quote
    found = []
    for folder in ("deckpose", "render", "detect", "estimate", "evaluate"):
        for path in sorted((REPO / folder).rglob("*.py")):
            for node in ast.walk(ast.parse(path.read_text())):
                if isinstance(node, ast.JoinedStr):
                    text = "".join(v.value if isinstance(v, ast.Constant) else "{}" for v in node.values)
                    if pattern.search(text):
                        found.append(f"{path.relative_to(REPO)}:{node.lineno}: {text[:100]}")
    assert not found, found
