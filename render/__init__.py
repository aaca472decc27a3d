"""Rendering stage: synthetic camera frames of the lit deck with exact ground truth."""
