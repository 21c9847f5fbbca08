"""``cloudmeta fit GRID -o scene.yaml``: fit metaballs to a voxel cloud, write the scene and its balls file,
print the fit's errors (docs/fit.md)."""
from __future__ import annotations

import argparse
import os
import sys


def _balls(text):
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected an integer >= 1, got {text}") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"expected an integer >= 1, got {text}")
    return value


def _error(text):
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number in (0, 1), got {text}") from None
    if not 0.0 < value < 1.0:
        raise argparse.ArgumentTypeError(f"expected a number in (0, 1), got {text}")
    return value


def add_parser(subparsers):
    """Add ``fit`` to the ``cloudmeta`` command's subparsers."""
    p = subparsers.add_parser("fit", help="fit metaballs to a voxel cloud (.npy/.npz, NetCDF, OpenVDB): a scene "
                                          "(YAML) and its balls file (CSV), with the fit's error (docs/fit.md)")
    p.add_argument("grid", help="the voxel grid: .npy (box in NAME.box.json), .npz, .nc, .vdb")
    p.add_argument("-o", "--output", required=True, help="the scene to write (.yaml); the balls file is the "
                                                         "same name with .csv")
    p.add_argument("--balls", type=_balls, help="at most this many balls")
    p.add_argument("--error", type=_error, help="stop once the optical depth's relative RMSE along the random "
                                                "rays is at most this (default 0.03 when --balls is not given)")
    p.add_argument("--var", dest="variable", help="the grid's variable (NetCDF variable, VDB grid, npz array)")
    p.add_argument("--time", type=int, help="NetCDF: the index along the time dimension")
    p.add_argument("--overwrite", action="store_true", help="replace the scene and balls file if cloudmeta fit "
                                                            "wrote them")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    p.set_defaults(run=command)
    return p


def command(args) -> int:
    """Run ``cloudmeta fit``; errors are CloudmetaError (the caller prints one line and returns 2)."""
    from .fit import fit_volume
    from .writer import check_paths
    check_paths(args.output, args.overwrite, [args.grid] if os.path.exists(args.grid) else [])
    parts = [f"cloudmeta fit {args.grid} -o {args.output}"]
    for flag, value in (("--balls", args.balls), ("--error", args.error), ("--var", args.variable),
                        ("--time", args.time)):
        if value is not None:
            parts.append(f"{flag} {value}")
    result = fit_volume(args.grid, args.output, balls=args.balls, error=args.error, variable=args.variable,
                        time=args.time, overwrite=args.overwrite,
                        progress=not args.quiet and sys.stderr.isatty(), command=" ".join(parts))
    e = result.errors
    yaml_path, csv_path = result.paths
    print(f"cloudmeta: wrote {yaml_path} and {os.path.basename(csv_path)}: {len(result):,} balls in "
          f"{result.seconds:.1f} s ({result.cpu_seconds:.1f} s CPU)")
    print(f"cloudmeta: density relative L2 error on the grid {e['density']:.4f}; optical-depth relative RMSE "
          f"{e['depth']:.4f} along {e['rays']:,} random rays (docs/fit.md)")
    return 0

