"""Simulation: the closed loop, its log, scenarios, faults, runs and data collection."""
