"""Allan deviation: the exact kernel, streaming over run chunks, EDF, noise identification and fit."""
