"""Analysis of runs: metrics, statistics, tables and plots, all made from logs and results."""
