"""Offline runs of the model: recorded histories, summaries and result files."""
