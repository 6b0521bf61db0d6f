"""References that share no code with the matcher: an X-ray image model, region-overlap fits, hull outlines."""
