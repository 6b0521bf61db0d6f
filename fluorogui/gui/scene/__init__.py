"""The 3D fluoroscope: the pyvista scene of sources, image planes, rays and models, and the Qt widget showing it."""
