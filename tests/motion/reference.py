"""Where the shared reference files live: ``<repo>/../shared`` (CI has it beside the clone)."""

from pathlib import Path

SHARED = Path(__file__).resolve().parents[2] / ".." / "shared"
THESIS_CSV = SHARED / "reference" / "thesis_motion_series.csv"
