"""fluorogui: six-degree-of-freedom pose of knee-implant components from biplane fluoroscopy."""

__version__ = "0.1.0"
