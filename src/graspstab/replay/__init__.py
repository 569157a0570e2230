"""Replay stage (thesis 3.2): hold each synthesised grasp under gravity and record the traces."""
