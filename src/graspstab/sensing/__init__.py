"""Sensor realism (our extension, the reference's 5.3): what a real fingertip sensor would report
instead of the simulator's clean 2 kHz forces."""
