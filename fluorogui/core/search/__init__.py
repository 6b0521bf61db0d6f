"""Finding components with no start: the orientation grid, the coarse shape search and find implants."""
