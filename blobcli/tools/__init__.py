"""Tools over the library (bench, stress, study, render, compare): they call it, never the reverse."""
