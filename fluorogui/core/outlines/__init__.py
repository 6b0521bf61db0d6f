"""Image outlines: field of view, Canny edges, periodic splines, outline editing and the metal rim's profile."""
