"""What the presets' promise costs: two checkouts alternating on the same renders, and each one's true error.

For each case (scenes/cumulus.yaml front-lit, scenes/cumulus_backlit.yaml back-lit, scenes/dense_1000.yaml
the 1,200-ball bank; each lit as shipped, and "lightless": the same scene with its lights removed, ambient
only), at ``--size`` squared and ``default`` with exact shadows (``--shadows`` sets each checkout's mode, in
order: ``--shadows exact hybrid`` compares the old checkout's exact shadows with the new one's hybrid): a
fresh process per checkout loads the kernels outside the clock (a 4 x 4 render), then times ``--repeat``
renders; the checkouts alternate ``--rounds`` times. Where a checkout reports them (RenderResult.cost), its
counters are printed too: per pixel with media, quadrature nodes, exact shadow rays, shadow-map lookups and
lookups kept. Prints the median and the spread (min - max) of the render time, the ratio of the
medians (second checkout / first), and, with ``--error``, each checkout's relative RMSE against a render at
``quality: reference`` (cached in validation/results/promise/), divided by the mean scattered radiance
(docs/error_estimate.md).

    python -m validation.performance.promise_speed OLD NEW [--size 512] [--rounds 3] [--repeat 1] [--error]
        [--cases front back bank front-lightless] [--shadows OLD_MODE NEW_MODE]

Both checkouts must have their kernels compiled (a render of each once); timings are of the renders only.
"""
from __future__ import annotations

import json
import os
import statistics
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np

from validation.common import RESULTS, ROOT, parse, parser, run_main
from validation.references import suite as S

CASES = {
    "front": ("scenes/cumulus.yaml", True),
    "back": ("scenes/cumulus_backlit.yaml", True),
    "bank": ("scenes/dense_1000.yaml", True),
    "front-lightless": ("scenes/cumulus.yaml", False),
}

_RUN = textwrap.dedent("""
    import json, sys, time
    from dataclasses import replace
    import numpy as np
    import cloudmeta as cm
    path, size, lit, repeat, out = sys.argv[1], int(sys.argv[2]), sys.argv[3] == "1", int(sys.argv[4]), sys.argv[5]
    shadows = sys.argv[6]
    try:  # a checkout that counts its work (RenderResult.cost) reports it
        from cloudmeta.renderer.frame import render_frame
    except ImportError:
        render_frame = None
    def scene(w):
        s = cm.load_scene(path, width=w, height=w)
        s = replace(s, render=replace(s.render, quality="default", shadows=shadows))
        return s if lit else replace(s, lights=())
    counts = render_frame is not None and hasattr(render_frame(scene(4), progress=False), "cost")
    if render_frame is None:
        cm.render(scene(4), progress=False)
    s = scene(size)
    times = []
    cost = None
    for _ in range(repeat):
        t0 = time.perf_counter()
        if counts:
            result = render_frame(s, progress=False)
            img = result.image
            cost = {k: float(v) for k, v in result.cost().items()}
        else:
            img = cm.render(s, progress=False)
        times.append(time.perf_counter() - t0)
    if out != "-":
        np.save(out, np.asarray(img, np.float64))
    print(json.dumps(dict(times=times, cost=cost)))
""")


def run(root, case, size, repeat, out="-", shadows="exact"):
    """(times, cost) of ``repeat`` renders of the case by the checkout at ``root`` (cost None where the checkout
    does not count its work)."""
    path, lit = CASES[case]
    env = dict(os.environ, PYTHONPATH=str(root))
    done = subprocess.run([sys.executable, "-c", _RUN, str(ROOT / path), str(size), "1" if lit else "0",
                           str(repeat), str(out), shadows], env=env, capture_output=True, text=True, cwd=root)
    if done.returncode != 0:
        raise SystemExit(f"{root}: {case}: {done.stderr.strip().splitlines()[-1]}")
    got = json.loads(done.stdout.strip().splitlines()[-1])
    return got["times"], got["cost"]


def reference(case, size):
    """The case's converged image (the current checkout at ``quality: reference``), cached."""
    folder = RESULTS / "promise"
    folder.mkdir(parents=True, exist_ok=True)
    f = folder / f"{case}_{size}.npy"
    if not f.exists():
        import cloudmeta as cm
        from dataclasses import replace
        path, lit = CASES[case]
        s = cm.load_scene(ROOT / path, width=size, height=size)
        s = replace(s, render=replace(s.render, quality="reference", shadows="exact"))
        s = s if lit else replace(s, lights=())
        np.save(f, np.asarray(cm.render(s, progress=False), np.float64))
    return np.load(f)


def scattered_error(img, ref, case, size):
    """RMSE over the mean scattered radiance of the reference (suite.rel_rmse_scattered)."""
    import cloudmeta as cm
    s = cm.load_scene(ROOT / CASES[case][0], width=size, height=size)
    if s.sky is not None:
        raise SystemExit(f"{case}: a sky background is not supported here")
    return S.rel_rmse_scattered(img, ref, s.background)


def main(argv=None, quick=False):
    ap = parser(__doc__)
    ap.add_argument("roots", nargs=2, help="the checkouts: OLD NEW")
    ap.add_argument("--size", type=int, default=512)
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--repeat", type=int, default=1)
    ap.add_argument("--error", action="store_true", help="also each checkout's true error (a reference render)")
    ap.add_argument("--cases", nargs="+", default=list(CASES), choices=list(CASES))
    ap.add_argument("--shadows", nargs=2, default=["exact", "exact"], metavar=("OLD", "NEW"),
                    help="each checkout's render.shadows (default: exact for both)")
    args, _ = parse(ap, argv, quick)
    roots = [Path(r).resolve() for r in args.roots]
    out = {}
    for case in args.cases:
        times = {r: [] for r in roots}
        costs = {}
        for _ in range(args.rounds):
            for r, mode in zip(roots, args.shadows):
                got, costs[r] = run(r, case, args.size, args.repeat, shadows=mode)
                times[r] += got
        med = [statistics.median(times[r]) for r in roots]
        spans = [f"{statistics.median(times[r]):7.2f} s ({min(times[r]):.2f}-{max(times[r]):.2f})" for r in roots]
        line = f"{case:16s} " + "  ".join(spans) + f"  ratio {med[1] / med[0]:.3f}"
        if args.error:
            ref = reference(case, args.size)
            errs = []
            for i, r in enumerate(roots):
                f = RESULTS / "promise" / f"{case}_{args.size}_{i}.npy"
                run(r, case, args.size, 1, f, shadows=args.shadows[i])
                errs.append(scattered_error(np.load(f), ref, case, args.size))
            line += "  error " + " / ".join(f"{e:.2e}" for e in errs)
        print(line, flush=True)
        for r in roots:
            if costs[r] is not None:
                c = costs[r]
                print(f"{'':16s} {r.name}: per media pixel {c['nodes']:.1f} nodes, {c['exact_rays']:.1f} exact shadow "
                      f"rays, {c['lookups']:.1f} map lookups ({c['trusted']:.1f} kept)"
                      + (f", {c['steps']:.2f} steps ({c['kronrod']:.2f} with Kronrod nodes), {c['splits']:.2f} splits "
                         f"({c['folds']:.2f} at folds)" if "steps" in c else ""), flush=True)
        out[case] = dict(times={str(r): times[r] for r in roots})
    return out


if __name__ == "__main__":
    run_main(main)
