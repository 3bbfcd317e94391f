"""Evaluation: the HOMER+ protocol, metrics, tables, plots and the experiments."""
