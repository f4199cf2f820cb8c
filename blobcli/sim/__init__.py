"""The simulation: static model, changing state, and the step as a list of stages."""
