"""Identification: least squares, estimators, base parameters, consistency, excitation."""
