"""The shared method against the planned unbiased paths at equal preset, timed side by side.

Per scene of validation.accuracy.approximate's report (512 wide unless --size), ``render_frame`` (seed 1, no
error estimate) of the approximate mode's ``method: shared`` and of ``scattering: multiple`` with paths planned
to the same ``--quality`` (or, with ``--against no-cache``, of the shared method without its cache of the deep
orders, ``shared: {cache: 0}``; with ``--against cache``, with the preset's cache built whatever share of the light
it holds, ``shared: {cache: K}``; with ``--against preset-quadrature``, with its exact order 1 calibrated to the
preset's own target instead of renderer.quality.SHARED_QUADRATURE of the tails'), alternated
(validation.common.alternate: one untimed round, then ``--repeats``); prints each one's median and range of wall
time.

    python -m validation.performance.ms_shared_speed [--scenes deck_low_sun wispy_puffs] [--repeats 2]
        [--against paths|no-cache|cache|preset-quadrature]
"""
from __future__ import annotations

import time

import cloudmeta as cm
from cloudmeta.renderer import quality as quality_module
from cloudmeta.renderer.quality import PRESETS
from validation.accuracy.approximate import FIT, REPORT, scene_of
from validation.common import alternate, parse, parser, run_main, with_settings


def _run(scene, quadrature_share=None):
    """render_frame's wall time; quadrature_share: renderer.quality.SHARED_QUADRATURE for this render (None: its
    own)."""
    own = quality_module.SHARED_QUADRATURE
    quality_module.SHARED_QUADRATURE = own if quadrature_share is None else quadrature_share
    try:
        t0 = time.perf_counter()
        cm.render_frame(scene, progress=False, seed=1)
        return time.perf_counter() - t0
    finally:
        quality_module.SHARED_QUADRATURE = own


def main(argv=None):
    ap = parser(__doc__)
    ap.add_argument("--scenes", nargs="+", default=["deck_low_sun", "wispy_puffs"], choices=list(REPORT) + list(FIT))
    ap.add_argument("--size", type=int, default=512)
    ap.add_argument("--quality", default="draft")
    ap.add_argument("--repeats", type=int, default=2)
    ap.add_argument("--against", choices=["paths", "no-cache", "cache", "preset-quadrature"], default="paths")
    args, _ = parse(ap, argv)
    rows = []
    for name in args.scenes:
        path = {**REPORT, **FIT}[name]
        shared = with_settings(scene_of(path, args.size, "approximate", method="shared"), quality=args.quality)
        if args.against == "paths":
            paths = with_settings(scene_of(path, args.size, "multiple"), quality=args.quality)
            other = ("planned paths", paths)
        elif args.against == "cache":
            other = ("cache always", with_settings(shared, shared=(None, None, PRESETS[args.quality].cache[0])))
        elif args.against == "preset-quadrature":
            preset = PRESETS[args.quality]
            other = ("preset's quad.", (shared, preset.target / preset.paths_target))
        else:
            other = ("no cache", with_settings(shared, shared=(None, None, 0)))
        arguments = other[1] if isinstance(other[1], tuple) else (other[1],)
        times = alternate({"shared": (shared,), other[0]: arguments}, args.repeats, _run)
        for key, ts in times.items():
            ts = sorted(ts)
            median = ts[len(ts) // 2] if len(ts) % 2 else 0.5 * (ts[len(ts) // 2 - 1] + ts[len(ts) // 2])
            print(f"{name:14s} {key:14s} median {median:7.1f} s  (range {ts[0]:.1f}-{ts[-1]:.1f} s, {len(ts)} runs)",
                  flush=True)
            rows.append(dict(scene=name, method=key, median=median, low=ts[0], high=ts[-1]))
    return dict(rows=rows)


if __name__ == "__main__":
    run_main(main)
