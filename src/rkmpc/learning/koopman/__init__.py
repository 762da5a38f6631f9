"""Koopman models: the lifted linear model, its liftings, their training and the model file."""
