"""Baseline detectors compared with GRAD in the benchmarks."""
