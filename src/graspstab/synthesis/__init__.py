"""Grasp synthesis (thesis 3.1.3-3.1.4): structured pre-grasps and batched simulated annealing."""
