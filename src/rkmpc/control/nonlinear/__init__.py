"""Nonlinear MPCs on CasADi (IPOPT, SQP) and, with the optional extra, acados."""
