"""Bands of rows on threads: how a frame's pixels are handed to a nogil kernel, with a progress bar.

Each band is one call of the kernel with its own work arrays, written to its own rows: threads share
nothing, so an image does not depend on their number or order (bit-identical for any thread count).
"""
from __future__ import annotations

import operator
from concurrent.futures import ThreadPoolExecutor

import numba

from ..errors import InputError

#: the image is cut into bands of rows, about this many per thread (uneven rows balance out) and no
#: taller than MAX_BAND_ROWS; the progress bar moves once per band. With 16 bands of 16 rows a thread, the other
#: thread waited 2-3.5 % of the cumulus's frame at 512 x 512 for the last band; 32 of 8 took 1.1-1.4 % less time
#: (the bank: +0.4 %, within noise; docs/benchmarks.md)
BANDS_PER_THREAD = 32
MAX_BAND_ROWS = 8


def n_chunks(n_items):
    """Work chunks for a parallel kernel: several per thread, so that uneven rays balance out."""
    return max(1, min(n_items, 8 * numba.get_num_threads()))


def run_bands(kernel, window, width, progress):
    """Call kernel(row0, p0, p1) over the tile ``window`` = ((r_lo, r_hi), (c_lo, c_hi)) of a frame
    ``width`` pixels wide, in bands of rows on threads, with a progress bar."""
    (r_lo, r_hi), (c_lo, c_hi) = window
    bar = progress_bar(r_hi - r_lo, progress)
    threads = numba.get_num_threads()
    rows = max(1, min(MAX_BAND_ROWS, -(-(r_hi - r_lo) // (BANDS_PER_THREAD * threads))))
    bands = [(r0, min(r_hi, r0 + rows)) for r0 in range(r_lo, r_hi, rows)]

    def band(rows):
        r0, r1 = rows
        # a whole row is one run of pixels; part of a row (a tile) takes one call per row
        runs = [(r0, 0, (r1 - r0) * width)] if (c_lo, c_hi) == (0, width) else [(r, c_lo, c_hi)
                                                                                  for r in range(r0, r1)]
        for row0, p0, p1 in runs:
            kernel(row0, p0, p1)
        return r1 - r0

    # each band is one call of a nogil kernel with its own work arrays, written to its own rows: threads
    # share nothing, so the image does not depend on their number or order
    with ThreadPoolExecutor(threads) as pool:
        for done in pool.map(band, bands):
            bar.update(done)
    bar.close()


def tile_window(span, size, name):
    """(start, stop) of a tile's ``rows`` or ``columns``: the whole range when None."""
    if span is None:
        return 0, size
    try:
        start, stop = (operator.index(v) for v in span)
    except (TypeError, ValueError):
        start, stop = -1, -1
    if not 0 <= start < stop <= size:
        raise InputError(f"{name}: expected (start, stop) with 0 <= start < stop <= {size}, got {span!r}")
    return start, stop


class _NoBar:
    def update(self, n):
        pass

    def close(self):
        pass


def progress_bar(total, enabled, unit="row", desc="render", mininterval=0.5):
    """A tqdm bar of ``total`` units (tqdm imported only when one is shown), or one that shows nothing."""
    if not enabled:
        return _NoBar()
    from tqdm import tqdm
    return tqdm(total=total, unit=unit, desc=desc, leave=False, mininterval=mininterval)
