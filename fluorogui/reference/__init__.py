"""References that share no code with the matcher: an X-ray image model (with bone and cement
about an implant), region-overlap fits, hull outlines."""
