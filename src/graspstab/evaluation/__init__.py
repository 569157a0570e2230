"""Evaluation (thesis 4.2-4.7 and our extensions): reference scorers, study statistics and
the study drivers that score trained models; it reads what training wrote and never trains."""
