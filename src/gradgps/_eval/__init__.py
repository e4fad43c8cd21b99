"""Evaluation: metrics and the benchmark protocols."""
