"""graspstab: predicting grasp instability from fingertip forces (ORCA hand, YCB objects, MuJoCo)."""

__version__ = "0.1.0"
