"""Validation tools that share no code with the matcher (``xray``: an X-ray image model)."""
