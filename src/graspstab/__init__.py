"""graspstab: predicting grasp instability from fingertip forces (ORCA hand, YCB, MuJoCo)."""

__version__ = "0.3.0"  # = pyproject.toml [project] version (tests/test_package_meta.py)
