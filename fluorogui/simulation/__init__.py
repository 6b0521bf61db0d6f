"""Generated scenes with known answers: implant phantoms, pseudo-fluoroscopic renders, the demo, knee-bend sequences and the paper's validation protocols."""
