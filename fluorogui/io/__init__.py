"""File formats: calibrations, images, meshes, project files, pose exports. No Qt."""
