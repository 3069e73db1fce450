"""Depth sources and their conversion to the pipeline's normalised disparity."""

from photo3d.depth.normalize import DepthInput, prepare_depth

__all__ = ["DepthInput", "prepare_depth"]
