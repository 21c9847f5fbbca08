"""The library behind the public API: the vectorised ray engine (``rays``), images in and out (``io``),
the 3D viewer (``viewer``), sequences, tiles and Dask clusters (``cluster``), and what a long run needs
from its process (``runtime``). Import the public names from ``cloudmeta`` itself."""
