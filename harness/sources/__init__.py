"""Where data comes from: the bench (motion, simulation, measurement) and a measured log."""
