"""Scenes with known answers: implant phantoms, renders, the demo, knee bends and the paper's protocols."""
