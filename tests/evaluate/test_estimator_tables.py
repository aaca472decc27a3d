import pandas as pd
from deckpose.evaluate.estimator_tables import END, START

from deckpose.cli import main


def test_estimator_tables_splice_into_existing_report(tmp_path):
    md = tmp_path / "estimators.md"
    md.write_text("# Estimators\n\nCRB section written by the benchmark.\n")
    for _ in range(2):  # a second run replaces the section instead of appending another
        assert main(["estimator-tables", "--methods", "thesis", "--repetitions", "1", "--workers", "1",
                     "-o", str(tmp_path)]) == 0
    text = md.read_text()
    assert "CRB section written by the benchmark." in text
    assert text.count(START) == 1 and text.count(END) == 1
    for n in list(range(2, 14)) + [15]:
        assert f"### Table 4.{n}:" in text
    df = pd.read_csv(tmp_path / "estimators_thesis_tables.csv")
    assert set(df.method) == {"thesis"} and (df.n_ok == 495).all()


def test_unknown_method_is_refused(tmp_path, capsys):
    assert main(["estimator-tables", "--methods", "nope", "-o", str(tmp_path)]) == 2
    assert "unknown estimator" in capsys.readouterr().err
