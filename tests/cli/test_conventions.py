"""One convention everywhere: checked on every command's parser, not a list kept by hand."""

from __future__ import annotations

import argparse

import pytest

from deckpose.cli import build_parser, main
from deckpose.cli.common_options import default_workers

PARSER = build_parser()
COMMANDS = next(a for a in PARSER._actions if isinstance(a, argparse._SubParsersAction)).choices
#: Commands that write files (each takes -o/--output, or writes into the run folder it is given).
WRITE_INTO_RUN = {"evaluate", "report", "pipeline", "track", "painted-ring"}
#: Commands with a progress bar.
LONG = {"demo", "pipeline", "render", "detect", "bench-detectors", "estimate", "painted-ring", "thesis-tables",
        "estimator-tables", "track"}


@pytest.mark.parametrize("name", sorted(COMMANDS))
def test_every_option_has_help_and_no_default_none(name):
    sp = COMMANDS[name]
    for a in sp._actions:
        if a.help == argparse.SUPPRESS or isinstance(a, argparse._HelpAction):
            continue
        assert a.help, f"{name}: {a.option_strings or a.dest} has no help"
    assert "default: None" not in sp.format_help()


@pytest.mark.parametrize("name", sorted(COMMANDS))
def test_one_spelling_for_output_camera_and_workers(name):
    sp = COMMANDS[name]
    listed = {s for a in sp._actions if a.help != argparse.SUPPRESS for s in a.option_strings}
    text = sp.format_help()
    assert "--out " not in text and "--camera-info" not in text  # old spellings parse, unlisted
    if name not in WRITE_INTO_RUN and name not in {"crb"}:
        assert {"-o", "--output"} <= listed, name
    workers = [a for a in sp._actions if "--workers" in a.option_strings]
    if workers:
        assert workers[0].default is None and f"{default_workers()} here" in workers[0].help
    if name in LONG:
        assert "--no-progress" in listed, name
    assert {"-v", "-q"} <= listed


def test_estimator_tables_takes_the_comma_list_as_pipeline_does(tmp_path):
    # the comma form used to fail ("unknown estimator(s) ['thesis,pnp']")
    assert main(["estimator-tables", "--method", "thesis,nosuch", "-o", str(tmp_path)]) == 2
    args = PARSER.parse_args(["estimator-tables", "--method", "thesis,pnp"])
    assert args.methods == ["thesis,pnp"]  # split in run(), as every comma list is
    old = PARSER.parse_args(["estimator-tables", "--methods", "thesis", "pnp"])
    assert old.methods == ["thesis", "pnp"]


def test_table_commands_write_under_runs_unless_told():
    # estimator-tables wrote ./reports by default: run from the checkout, it rewrote the committed
    # reports/estimators.md; both table commands now write under runs/ (-o reports for the report)
    from pathlib import Path

    assert PARSER.parse_args(["estimator-tables"]).output == Path("runs/estimator_tables")
    assert PARSER.parse_args(["thesis-tables"]).output.parts[0] == "runs"


def test_verbosity_after_the_command(tmp_path, capsys):
    args = PARSER.parse_args(["detect", "--list", "-v"])
    assert args.verbose == 1
    args = PARSER.parse_args(["-q", "detect", "--list"])
    assert args.quiet is True


@pytest.mark.parametrize("command", ["evaluate", "report"])
def test_a_missing_run_folder_is_named_as_such(tmp_path, capsys, command):
    # `report` on a folder that does not exist used to ask for `evaluate`, which then said
    # the folder does not exist: both now name the missing folder and the render step
    missing = tmp_path / "no_such_run"
    assert main([command, str(missing)]) != 0
    err = capsys.readouterr().err
    assert f"run folder {missing} does not exist" in err and "deckpose render" in err
    assert len(err.strip().splitlines()) == 1


def test_a_closed_pipe_ends_the_command_quietly(monkeypatch, capsys):
    # `deckpose crb | head -1`: the reader goes away and the next write raises BrokenPipeError;
    # the command stops with 128 + SIGPIPE and prints nothing (once "error: BrokenPipeError")
    import sys

    class ClosedPipe:
        def write(self, text: str) -> int:
            raise BrokenPipeError(32, "Broken pipe")

        def flush(self) -> None:
            pass

    monkeypatch.setattr(sys, "stdout", ClosedPipe())
    assert main(["crb"]) == 141
    assert capsys.readouterr().err == ""


def test_bad_workers_leave_no_folder_and_a_missing_source_is_named(tmp_path, capsys):
    # `render ... --workers -1` refused but left an empty output folder behind;
    # `detect nothere` said "not a deckpose dataset (no manifest.json)"
    from pathlib import Path

    repo = Path(__file__).resolve().parents[2]
    out = tmp_path / "w"
    assert main(["render", str(repo / "configs" / "smoke.yaml"), str(out), "--workers", "-1"]) == 2
    assert "--workers must be >= 0" in capsys.readouterr().err and not out.exists()
    assert main(["detect", str(tmp_path / "nothere")]) == 2
    err = capsys.readouterr().err.strip()
    assert "does not exist" in err and "\n" not in err
