"""Experiment tracking: MLflow runs for jobs, parent runs for sweeps."""
