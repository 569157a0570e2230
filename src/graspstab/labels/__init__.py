"""Labelling stage (thesis 3.3): usable interval, timestep labels, predictive windows."""
