"""Helpers shared by every stage: atomic output writing, provenance, logging."""
