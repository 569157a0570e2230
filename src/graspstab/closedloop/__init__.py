"""Closed loop (our extension): a grip reflex driven by the streaming monitor inside the replay."""
