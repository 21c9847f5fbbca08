"""What the validation scripts share: the results folder, CSV files, plots, the error measure, the command line.

Imports nothing of cloudmeta (a script may have to set the environment before cloudmeta is imported: see
``fresh_kernels_when_run``), and only numpy besides the standard library (matplotlib when a plot is drawn).
Every script runs from the repository root as a module, ``python -m validation.FOLDER.NAME``.
"""
from __future__ import annotations

import argparse
import csv
import os
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np

#: the repository root (scenes/, docs/, cloudmeta/)
ROOT = Path(__file__).resolve().parent.parent
#: where full runs write their figures; quick runs (the tests) write nothing there
RESULTS = ROOT / "validation" / "results"


# --- the command line -----------------------------------------------------------------------------------------

def parser(doc, quick=None, no_csv=False):
    """An argument parser described by the first paragraph of ``doc`` (the script's docstring), with a
    ``--quick`` flag (``quick``: its help) unless quick is None, and a ``--no-csv`` flag if asked for."""
    ap = argparse.ArgumentParser(description=doc.split("\n\n")[0])
    if quick is not None:
        ap.add_argument("--quick", action="store_true", help=quick)
    if no_csv:
        ap.add_argument("--no-csv", action="store_true",
                        help="do not write validation/results/*.csv (quick runs never do)")
    return ap


def parse(ap, argv, quick=False):
    """(args, quick): ``argv`` parsed (None is no arguments: a call from Python never reads sys.argv), and
    quick mode if asked for either way, by the caller or by ``--quick``."""
    args = ap.parse_args([] if argv is None else argv)
    return args, bool(quick or getattr(args, "quick", False))


def run_main(main):
    """A script's ``if __name__ == "__main__"``: main(sys.argv[1:]), then exit with status 0 if its result
    passed (or gives no verdict), 1 if not."""
    result = main(sys.argv[1:])
    passed = result.get("passed", True) if isinstance(result, dict) else True
    sys.exit(0 if passed else 1)


def fresh_kernels_when_run(name):
    """Called with ``__name__`` before cloudmeta is imported: a script run from the command line compiles the
    engine fresh unless CLOUDMETA_NO_CACHE says otherwise (numba's cache does not notice when a kernel's
    callee in another file changes: clip_roots keeps a stale copy of bernstein.subdivide). Imported by a
    test, it leaves the cache alone."""
    if name == "__main__":
        os.environ.setdefault("CLOUDMETA_NO_CACHE", "1")


def alternate(commands, repeats, run):
    """{key: [seconds]} of ``run(*command)`` (which returns its wall time) for every command in turn: one
    untimed round first (it fills the caches), then ``repeats`` timed rounds."""
    for command in commands.values():
        run(*command)
    times = {key: [] for key in commands}
    for _ in range(repeats):
        for key, command in commands.items():
            times[key].append(run(*command))
    return times


def cache_note():
    """One line: whether this run's kernels came from numba's cache or were compiled fresh."""
    from cloudmeta.kernels import config
    problem = config.cache_problem()
    if problem is None:
        return f"engine kernels: cached in {config.CACHE_FOLDER} (keyed by a hash of the kernel sources)"
    return f"engine kernels: not saved for later runs ({problem})"


# --- files ----------------------------------------------------------------------------------------------------

def write_csv(path, rows, fieldnames=None):
    """Write ``rows`` to ``path`` (relative to RESULTS, or absolute) and return the path. Dict rows get a
    header of ``fieldnames``, by default every key in the order first seen; list rows are written as they
    are, after ``fieldnames`` as the header when given. The file is written beside and renamed over the old
    one, so that an interrupted run leaves the last complete file."""
    path = RESULTS / path
    path.parent.mkdir(parents=True, exist_ok=True)
    rows = list(rows)
    as_dicts = bool(rows) and isinstance(rows[0], dict)
    if as_dicts and fieldnames is None:
        fieldnames = list(dict.fromkeys(k for r in rows for k in r))
    tmp = path.with_name(f".{path.name}.tmp")
    with open(tmp, "w", newline="") as f:
        if as_dicts:
            w = csv.DictWriter(f, fieldnames=fieldnames)
            w.writeheader()
        else:
            w = csv.writer(f)
            if fieldnames is not None:
                w.writerow(fieldnames)
        w.writerows(rows)
    tmp.replace(path)
    return path


def read_csv(path, floats=(), ints=(), bools=()):
    """The rows of a CSV this package wrote (relative to RESULTS, or absolute), as dicts, with the columns
    named in ``floats``, ``ints`` and ``bools`` converted back (to redraw a plot without running again)."""
    with open(RESULTS / path) as f:
        rows = list(csv.DictReader(f))
    for r in rows:
        for k in floats:
            r[k] = float(r[k])
        for k in ints:
            r[k] = int(r[k])
        for k in bools:
            r[k] = r[k] == "True"
    return rows


def write_results(name, rows, plot=None):
    """RESULTS/name.csv of the rows and, where ``plot`` is given, RESULTS/name.png drawn by plot(rows, path);
    prints what it wrote."""
    written = [write_csv(f"{name}.csv", rows)]
    if plot is not None:
        written.append(RESULTS / f"{name}.png")
        plot(rows, written[-1])
    print(f"wrote {' and '.join(str(w) for w in written)}")


def print_head(head, file=None):
    """A table's header line and a rule under it."""
    print(head, file=file)
    print("-" * len(head), file=file)


def pyplot():
    """matplotlib.pyplot on the Agg backend (files only, no display)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def save_figure(fig, out, dpi=120):
    """Lay out, write and close a figure."""
    fig.tight_layout()
    fig.savefig(out, dpi=dpi)
    pyplot().close(fig)


def finish_time_error(fig, axes, names, ylabel, title, out):
    """Finish a grid of per-scene panels of error against time (axes: 2-d, one panel per name, the curves drawn):
    log axes, the scenes' names, labels, the first panel's legend, the title; then save_figure to ``out``."""
    for ax, name in zip(axes.flat, names):
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_title(name, fontsize=10)
        ax.grid(True, which="both", alpha=0.3)
    for ax in axes[-1]:
        ax.set_xlabel("render time (s, 2 cores)")
    for ax in axes[:, 0]:
        ax.set_ylabel(ylabel)
    axes.flat[0].legend(fontsize=8)
    fig.suptitle(title)
    save_figure(fig, out)


# --- images ---------------------------------------------------------------------------------------------------

def rel_rmse(img, ref, norm=None):
    """The relative RMSE of an image against a reference over every pixel and RGB channel (an alpha channel
    is left out):

        sqrt(mean (L - L_ref)^2) / sqrt(mean L_ref^2)

    or, where ``norm`` is given, sqrt(mean (L - L_ref)^2) / norm."""
    a = np.asarray(img, np.float64)[..., :3]
    b = np.asarray(ref, np.float64)[..., :3]
    rmse = np.sqrt(np.mean((a - b) ** 2))
    return float(rmse / (np.sqrt(np.mean(b ** 2)) if norm is None else norm))


def with_settings(scene, **settings):
    """The scene with some of its render settings replaced (``quality="draft"``, ``shadows="map"``, ...)."""
    return replace(scene, render=replace(scene.render, **settings))
