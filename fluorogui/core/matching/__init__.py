"""Pose of a component from its outlines: the objective, the optimisers, the segment-and-match loop, quality checks and uncertainty."""
