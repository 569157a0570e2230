"""graspstab: predicting grasp instability from fingertip forces (ORCA hand, YCB, MuJoCo)."""

__version__ = "0.1.0"
