"""Cold compile time and warm render time of the cumulus, for several checkouts side by side.

For each checkout (a folder holding the cloudmeta package), alternating between them ``--rounds`` times:
- cold: a fresh process with an empty cache folder (CLOUDMETA_CACHE_DIR) imports cloudmeta and renders
  scenes/cumulus.yaml at 64 x 64; the wall time of the whole process;
- warm: a fresh process with that (now filled) cache renders the cumulus once at 16 x 16 (load), then
  times the cumulus at ``--size`` (512) squared with the default settings ``--repeat`` times, in wall time
  and in process CPU time (all threads: the steadier figure on a shared machine).
Prints the median and the spread (min - max) of each figure per checkout.

    python -m validation.performance.compare_speed /path/to/old /path/to/new [--rounds 3] [--repeat 2]
    python -m validation.performance.compare_speed OLD NEW --caches OLD_CACHE NEW_CACHE   (warm only, filled caches)
"""
from __future__ import annotations

import os
import statistics
import subprocess
import sys
import tempfile
import textwrap
import time
from pathlib import Path

from validation.common import parse, parser, run_main

_COLD = textwrap.dedent("""
    import cloudmeta as cm
    cm.render(cm.load_scene({scene!r}, width=64, height=64), progress=False)
""")
_WARM = textwrap.dedent("""
    import time
    import cloudmeta as cm
    cm.render(cm.load_scene({scene!r}, width=16, height=16), progress=False)
    s = cm.load_scene({scene!r}, width={size}, height={size})
    for _ in range({repeat}):
        t, c = time.perf_counter(), time.process_time()
        cm.render(s, progress=False)
        print(time.perf_counter() - t, time.process_time() - c)
""")


def run(root, code, cache):
    env = dict(os.environ, CLOUDMETA_CACHE_DIR=str(cache), PYTHONPATH=str(root))
    env.pop("NUMBA_CACHE_DIR", None)
    start = time.perf_counter()
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True,
                         cwd=root)
    return time.perf_counter() - start, out.stdout


def main(argv=None):
    ap = parser(__doc__)
    ap.add_argument("roots", nargs="+")
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--repeat", type=int, default=2)
    ap.add_argument("--skip-cold", action="store_true")
    ap.add_argument("--size", type=int, default=512, help="the warm render's width and height")
    ap.add_argument("--caches", nargs="+", default=None,
                    help="an existing cache folder per checkout, for the warm figure only (no cold compile)")
    args, _ = parse(ap, argv)
    caches = dict(zip(args.roots, args.caches)) if args.caches else {}
    cold = {r: [] for r in args.roots}
    warm = {r: [] for r in args.roots}
    warm_cpu = {r: [] for r in args.roots}
    for k in range(args.rounds):
        for root in args.roots:
            scene = str(Path(root) / "scenes" / "cumulus.yaml")
            if root in caches:
                _, out = run(root, _WARM.format(scene=scene, repeat=args.repeat, size=args.size), caches[root])
            else:
                with tempfile.TemporaryDirectory() as cache:
                    if not args.skip_cold:
                        wall, _ = run(root, _COLD.format(scene=scene), cache)
                        cold[root].append(wall)
                    _, out = run(root, _WARM.format(scene=scene, repeat=args.repeat, size=args.size), cache)
            times = [line.split() for line in out.splitlines() if line.strip()]
            warm[root] += [float(t[0]) for t in times]
            warm_cpu[root] += [float(t[1]) for t in times]
            print(f"round {k}: {root}: cold {cold[root][-1:]} warm {warm[root][-args.repeat:]} "
                  f"CPU {warm_cpu[root][-args.repeat:]}", flush=True)
    for root in args.roots:
        for name, v in (("cold compile + 64x64 render (s)", cold[root]),
                        (f"warm {args.size}x{args.size} render (s)", warm[root]),
                        (f"warm {args.size}x{args.size} CPU (s)", warm_cpu[root])):
            if v:
                print(f"{root:40s} {name:34s} median {statistics.median(v):8.3f}  min {min(v):8.3f}  "
                      f"max {max(v):8.3f}  n {len(v)}")
    return dict(cold=cold, warm=warm, warm_cpu=warm_cpu)


if __name__ == "__main__":
    run_main(main)
