"""Fluoroscope calibration: image-intensifier distortion from a perforated plate and view geometry from a bead phantom."""
