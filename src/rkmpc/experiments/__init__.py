"""Experiments: typed results, the one-track comparison, the model cache, parallel studies."""
