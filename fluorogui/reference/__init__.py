"""Reference results that share no code with the matcher: an X-ray image model, pose fits by region overlap and hull outlines."""
