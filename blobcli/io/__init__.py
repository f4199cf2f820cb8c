"""Files in and out: the H5MD trajectory format, the run loop that writes it, rerun recordings."""
