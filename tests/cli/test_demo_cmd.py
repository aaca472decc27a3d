import re

from deckpose.cli import main


def test_demo_runs_the_whole_pipeline(tmp_path, capsys):
    out = tmp_path / "demo"
    assert main(["demo", "-o", str(out), "--repetitions", "1", "--workers", "1", "--no-progress"]) == 0
    text = (out / "thesis_tables.md").read_text()
    assert "## Table 4.15" in text and "495 images per row" in text
    run = out / "run"
    for p in ("frames.parquet", "detections/cog.parquet", "estimates/cog--thesis.parquet",
              "estimates/cog--pnp.parquet", "evaluation/errors.parquet", "log.mcap", "report/report.md"):
        assert (run / p).exists(), p
    printed = capsys.readouterr().out
    assert str(run / "report" / "report.md") in printed and str(run / "log.mcap") in printed
    # each step is numbered once, counting up to the total: [1/N] .. [N/N]
    steps = [(int(n), int(t)) for n, t in re.findall(r"^\[(\d+)/(\d+)\]", printed, re.MULTILINE)]
    total = steps[-1][1]
    assert steps == [(n, total) for n in range(1, total + 1)], steps
    # the short approach: detected at render time (no frame kept), estimated, tracked and logged with its track
    approach = out / "approach"
    for p in ("detections/cog.parquet", "estimates/cog--pnp.parquet", "tracks/cog--pnp--wave-bank.parquet",
              "tracks/cog--pnp--wave-bank.predictions.parquet", "log.mcap"):
        assert (approach / p).exists(), p
    assert not (approach / "images").exists()
    from mcap.reader import make_reader

    with open(approach / "log.mcap", "rb") as fh:
        topics = {c.topic for c in make_reader(fh).get_summary().channels.values()}
    assert {"/tracks/cog--pnp--wave-bank", "/predictions/cog--pnp--wave-bank/1s"} <= topics
    assert str(approach / "log.mcap") in printed


def test_bad_repetitions_are_refused_before_any_work(tmp_path, capsys):
    from deckpose.cli import main

    assert main(["demo", "--repetitions", "0", "-o", str(tmp_path / "demo")]) == 2
    err = capsys.readouterr().err.strip()
    assert "repetitions must be at least 1" in err and "\n" not in err
    assert not (tmp_path / "demo").exists()  # nothing rendered, nothing written
