"""The virtual fluoroscope: views and projection, poses, meshes, exact silhouettes and the paper's point-cloud outline."""
