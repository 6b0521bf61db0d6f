"""Windows over the main window: calibration, import, export, crash report, missing model files, anatomical frames."""
