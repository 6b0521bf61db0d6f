"""A component's pose from its outlines: objective, optimisers, the segment-match loop, checks and uncertainty."""
