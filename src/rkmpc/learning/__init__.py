"""Learning: data sets, feature maps, recipes, Koopman models and physical identification."""
