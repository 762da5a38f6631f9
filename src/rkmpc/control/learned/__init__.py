"""Learned controllers: the Koopman MPC and the residual Koopman MPCs (RKMPC)."""
