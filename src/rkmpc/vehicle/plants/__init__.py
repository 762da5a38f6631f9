"""Simulated cars: the plant interface and the F1TENTH and full-size plants."""
