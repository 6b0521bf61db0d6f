"""The virtual fluoroscope: views and projection, poses, meshes, silhouettes, the paper's point outline."""
