"""Learning stage (thesis 3.4-3.5): model architectures and training."""
