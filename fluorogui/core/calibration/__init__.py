"""Fluoroscope calibration: image-intensifier distortion (a perforated plate) and view geometry (a bead phantom)."""
