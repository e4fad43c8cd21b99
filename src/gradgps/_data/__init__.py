"""Evaluation data: the drive simulator, fault injection, datasets."""
