"""Evaluation stage: errors against ground truth, tables, logs and reports."""
