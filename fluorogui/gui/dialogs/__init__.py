"""The windows that open over the main window: calibration wizard, import, export, crash report, missing files,
anatomical frames and the guided tour."""
