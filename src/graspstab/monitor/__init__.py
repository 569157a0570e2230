"""Monitor stage: run a trained window model on forces as they arrive, as a controller would."""
