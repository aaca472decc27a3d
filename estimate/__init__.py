"""Estimation stage: ship attitude and position from identified beacon detections."""
