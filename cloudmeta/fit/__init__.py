"""Voxel clouds in: the readers (.npy/.npz, NetCDF, OpenVDB) and their common record, VoxelGrid."""
from .grid import LiquidWater, VoxelGrid, parse_conversion, read_grid

__all__ = ["LiquidWater", "VoxelGrid", "parse_conversion", "read_grid"]
