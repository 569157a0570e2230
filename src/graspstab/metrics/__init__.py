"""Scores of a binary classifier on windows (thesis 3.5.3, 4.2): the one definition that
training (best epoch, validation threshold) and every evaluation use."""
