"""Evaluation: image metrics, real stereo pairs and synthetic scenes with exact ground truth."""
