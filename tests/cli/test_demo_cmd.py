from deckpose.cli import main


def test_demo_writes_a_report(tmp_path, capsys):
    out = tmp_path / "demo"
    assert main(["demo", "-o", str(out), "--repetitions", "1", "--workers", "1"]) == 0
    text = (out / "thesis_tables.md").read_text()
    assert "## Table 4.15" in text and "495 images per row" in text
    assert str(out / "thesis_tables.md") in capsys.readouterr().out
