"""Voxel clouds in: the readers (.npy/.npz, NetCDF, OpenVDB) and their common record, VoxelGrid; and
``fit_volume``, which fits metaballs to one (docs/fit.md)."""
from .grid import LiquidWater, VoxelGrid, parse_conversion, read_grid

__all__ = ["LiquidWater", "VoxelGrid", "fit_volume", "parse_conversion", "read_grid"]


def __getattr__(name):
    # fit_volume on first use: the command line imports this package, and the fit needs scipy
    if name == "fit_volume":
        from .fit import fit_volume
        return fit_volume
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
