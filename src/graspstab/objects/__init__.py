"""Object preprocessing (thesis 3.1.1): repair, COM frame, inertia, CoACD parts, SDF, MJCF."""
