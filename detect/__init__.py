"""Detection stage: sub-pixel beacon centroids and beacon identification."""
