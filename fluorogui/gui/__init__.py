"""Desktop application: PySide6 widgets, the pyvista scene and workers. Presentation only."""
