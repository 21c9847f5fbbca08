"""Speed benchmark: start-up, compile times, BVH build, rays per second, and render time and error.

Prints, in one run:
- start-up: the whole process ``python -m cloudmeta.cli render scenes/cumulus.yaml --width 4
  --height 3`` with a warm kernel cache, median and spread of ``--repeats`` runs (with ``--against DIR``
  alternating with the same command in another checkout DIR, e.g. the version before a change), and the
  wall time of ``python -c "import cloudmeta"`` next to that of ``python -c pass``;
- with ``--cold``: the first render of the cumulus (4 x 3) from an empty kernel cache in a fresh process,
  split into compiling and the rest, with the functions that take longest to compile
  (validation/performance/compile_profile.py; minutes);
- with ``--peer``: the POV-Ray comparison of validation/peers/povray_peer.py when ``povray`` is on PATH;
- JIT compile time, cold (an empty cache, in a fresh process) and cached (a second fresh process), each
  as the wall time of a process that imports cloudmeta and renders a 16 x 16 image;
- BVH build time for 1,000 to 100,000 balls;
- camera rays and shadow rays per second through the cumulus (the engine alone: chords, compositing,
  clipping, exact optical depth, on both cores);
- the 77-ball cumulus at 512 x 512: wall time and relative RMSE against the reference setting, with
  exact shadows and with shadow maps;
- scenes of 1,000, 10,000 and 100,000 balls at fixed image size and fixed on-screen coverage: a cloud
  sheet over a fixed area whose balls shrink as N^(-1/2), so that a ray meets about as many balls at every
  N and the time measures the cost of culling, not of deeper clouds.

    python -m validation.performance.bench [--size 512] [--scale-size 256] [--quick] [--repeats 7] [--cold] [--peer]
    python -m validation.performance.bench --startup [--against /tmp/old-checkout] [--cold] [--peer]  # start-up only
    python -m validation.performance.bench --lit [--repeats 5]  # lit against lightless only

Writes validation/results/bench.csv.
"""
from __future__ import annotations

import os
import statistics
import subprocess
import sys
import tempfile
import textwrap
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

import cloudmeta as cm
from cloudmeta.kernels.bvh import build_bvh
from validation.common import RESULTS, ROOT, alternate, parse, parser, rel_rmse, run_main, with_settings, write_csv

CUMULUS = ROOT / "scenes" / "cumulus.yaml"

_PROBE = textwrap.dedent(f"""
    import time; t = time.perf_counter()
    import cloudmeta as cm
    cm.render(cm.load_scene({str(CUMULUS)!r}, width=16, height=16), progress=False)
    print(time.perf_counter() - t)
""")


def process_time(cache_dir):
    env = dict(os.environ, CLOUDMETA_CACHE_DIR=str(cache_dir))
    env.pop("NUMBA_CACHE_DIR", None)
    start = time.perf_counter()
    out = subprocess.run([sys.executable, "-c", _PROBE], env=env, capture_output=True, text=True, check=True)
    return time.perf_counter() - start, float(out.stdout.strip().splitlines()[-1])


def whole_process(argv, cwd, env=None):
    start = time.perf_counter()
    subprocess.run(argv, cwd=cwd, env=env, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    return time.perf_counter() - start


def startup_commands(root, out):
    """The 4 x 3 CLI render of the cumulus run from checkout ``root`` (PYTHONPATH and cwd), its EXR and
    PNG (the scene asks for one) written to ``out``."""
    env = dict(os.environ, PYTHONPATH=str(root))
    render = [sys.executable, "-m", "cloudmeta.cli", "render", "scenes/cumulus.yaml", "--width", "4", "--height", "3",
              "-o", str(Path(out) / "x.exr"), "--png", str(Path(out) / "x.png"), "-q"]
    return {"render": (render, root, env),
            "import": ([sys.executable, "-c", "import cloudmeta"], root, env),
            "python": ([sys.executable, "-c", "pass"], root, env)}


def median_spread(values):
    return statistics.median(values), min(values), max(values)


def startup(repeats, against=None):
    """{(label, what): [wall times]} of the start-up commands, every command of every checkout in turn
    (one untimed round first: it fills the kernel and colour caches where they are empty)."""
    roots = {"this checkout": ROOT}
    if against is not None:
        roots["--against"] = Path(against).resolve()
    with tempfile.TemporaryDirectory() as out:
        commands = {(label, what): cmd for label, root in roots.items()
                    for what, cmd in startup_commands(root, out).items()}
        return alternate(commands, repeats, whole_process)


def cold_compile():
    """The compile_profile --cold summary of a fresh process: (wall of the process, its result lines)."""
    start = time.perf_counter()
    out = subprocess.run([sys.executable, "-m", "validation.performance.compile_profile", "--cold", "--top", "8"],
                         cwd=ROOT, env=dict(os.environ, PYTHONPATH=str(ROOT)), capture_output=True, text=True,
                         check=True)
    return time.perf_counter() - start, out.stdout


def startup_figures(report, repeats, against, cold, peer):
    """Start-up, import time, and (opt-in) cold compile and the POV-Ray peer."""
    times = startup(repeats, against)
    for (label, what), values in times.items():
        med, lo, hi = median_spread(values)
        name = {"render": "4x3 cumulus render, warm cache, whole process",
                "import": "python -c 'import cloudmeta'", "python": "python -c pass"}[what]
        report(f"{name} ({label}): median", med, "s")
        report(f"  spread (min-max) of {len(values)} runs", hi - lo, f"s  ({lo:.3f}-{hi:.3f})")
    if against is not None:
        ratio = (statistics.median(times[("this checkout", "render")])
                 / statistics.median(times[("--against", "render")]))
        report("4x3 render: this checkout / --against (medians)", ratio, "x")
    if cold:
        wall, text = cold_compile()
        report("cold start: fresh process, empty cache, 4x3 cumulus (whole process)", wall, "s")
        print(textwrap.indent(text.rstrip(), "    "))
    if peer:
        from validation.peers import povray_peer
        povray_peer.main(["--repeats", str(max(1, repeats // 2 + 1))])


def sheet_scene(n, size, path):
    """A stratocumulus-like sheet of n balls over a fixed 24 x 24 area, radii ~ n^-1/2."""
    rng = np.random.default_rng(n)
    side = int(np.ceil(np.sqrt(n)))
    spacing = 24.0 / side
    ij = np.stack(np.meshgrid(np.arange(side), np.arange(side), indexing="ij"), -1).reshape(-1, 2)[:n]
    xy = (ij + 0.5 + rng.uniform(-0.3, 0.3, (n, 2))) * spacing - 12.0
    z = rng.normal(0, 0.3 * spacing, n)
    r = spacing * rng.uniform(0.9, 1.3, n)
    np.savetxt(path.with_suffix(".csv"), np.c_[xy, z, r, np.ones(n)], delimiter=",", fmt="%.6f",
               header="x,y,z,radius,weight", comments="")
    path.write_text(textwrap.dedent(f"""
        image: {{width: {size}, height: {size}}}
        camera: {{position: [0, -30, 14], look_at: [0, 0, 0], up: [0, 0, 1], fov: 40}}
        background: [0.2, 0.35, 0.7]
        lights: [{{type: directional, direction: [0.5, -0.3, 0.8], irradiance: 6.0}}]
        media:
          - {{name: sheet, threshold: 0.5, density: {{mode: field, scale: {2.0 / spacing}}}, albedo: 0.9,
             phase: {{type: hg, g: 0.6}}, balls_file: {path.with_suffix('.csv').name}}}
        """))
    return path


def timed(scene):
    start = time.perf_counter()
    img = cm.render(scene, progress=False)
    return img, time.perf_counter() - start


def rays_per_second(n_rays):
    scene = cm.load_scene(CUMULUS)
    blob = scene.media[0].blob
    rng = np.random.default_rng(0)
    lo, hi = blob.bbox
    # camera rays: from the camera through random points of the cloud's box
    targets = rng.uniform(lo, hi, (n_rays, 3))
    origins = np.broadcast_to(scene.camera.position, (n_rays, 3))
    cm.optical_depth(blob, origins[:10], targets[:10] - origins[:10])
    start = time.perf_counter()
    cm.optical_depth(blob, origins, targets - origins)
    camera = n_rays / (time.perf_counter() - start)
    # shadow rays: from random points inside the cloud towards the sun
    pts = targets[cm.field(blob, targets) >= blob.threshold]
    dirs = np.broadcast_to(scene.lights[0].direction, pts.shape)
    start = time.perf_counter()
    cm.optical_depth(blob, pts, dirs)
    shadow = len(pts) / (time.perf_counter() - start)
    return camera, shadow


def lit_figures(report, repeats, size=512):
    """Lit against lightless: the cumulus front-lit (scenes/cumulus.yaml) and back-lit
    (scenes/cumulus_backlit.yaml) at size^2, ``default``, exact shadows, each against the same render with
    its lights removed (the view rays alone), alternating lit and lightless; and the 1,200-ball bank
    (scenes/dense_1000.yaml). Render time inside one process (kernels loaded outside the clock); median and
    spread of ``repeats`` renders each."""
    cases = [("cumulus front-lit", ROOT / "scenes" / "cumulus.yaml"),
             ("cumulus back-lit", ROOT / "scenes" / "cumulus_backlit.yaml"),
             ("bank, 1,200 balls", ROOT / "scenes" / "dense_1000.yaml")]
    for label, path in cases:
        lit = with_settings(cm.load_scene(path, width=size, height=size), quality="default", shadows="exact")
        dark = replace(lit, lights=())
        cm.render(cm.load_scene(path, width=4, height=4), progress=False)  # load the kernels outside the clock
        cm.render(replace(cm.load_scene(path, width=4, height=4), lights=()), progress=False)
        t_lit, t_dark = [], []
        for _ in range(repeats):
            t_lit.append(timed(lit)[1])
            t_dark.append(timed(dark)[1])
        med_lit, med_dark = statistics.median(t_lit), statistics.median(t_dark)
        report(f"{label} {size}^2 default exact: render time, median", med_lit, "s")
        report(f"  spread (min-max) of {repeats}: {min(t_lit):.2f}-{max(t_lit):.2f} s", max(t_lit) - min(t_lit), "s")
        report(f"{label} {size}^2 without lights: render time, median", med_dark, "s")
        report(f"  spread (min-max) of {repeats}: {min(t_dark):.2f}-{max(t_dark):.2f} s", max(t_dark) - min(t_dark), "s")
        report(f"{label}: lit / lightless (goal: at most 3x)", med_lit / med_dark, "x")


def main(argv=None, quick=False):
    ap = parser(__doc__, quick="small images, fewer balls, no cold start")
    ap.add_argument("--size", type=int, default=512)
    ap.add_argument("--scale-size", type=int, default=256)
    ap.add_argument("--repeats", type=int, default=7, help="runs of each start-up command (default 7)")
    ap.add_argument("--against", help="another checkout: its start-up alternates with this one's")
    ap.add_argument("--cold", action="store_true", help="also the first render from an empty cache (minutes)")
    ap.add_argument("--peer", action="store_true", help="also the POV-Ray comparison (needs povray)")
    ap.add_argument("--startup", action="store_true", help="only the start-up figures")
    ap.add_argument("--lit", action="store_true", help="only the lit against lightless speed figures")
    args, quick = parse(ap, argv, quick)
    size, scale_size = (32, 24) if quick else (args.size, args.scale_size)
    counts = (1000, 10000) if quick else (1000, 10000, 100000)
    rows = []

    def report(what, value, unit):
        rows.append(dict(what=what, value=value, unit=unit))
        print(f"{what:62s} {value:12.4g} {unit}", flush=True)

    if args.lit:
        lit_figures(report, 3 if quick else min(args.repeats, 5), size)
        return dict(rows=rows, passed=True)
    startup_figures(report, 3 if quick else args.repeats, args.against, args.cold, args.peer)
    if args.startup:
        return dict(rows=rows, passed=True)

    if not quick:
        with tempfile.TemporaryDirectory() as cache:
            wall, inner = process_time(cache)
            report("cold start: fresh process, empty cache, 16x16 render", wall, "s")
            wall, inner = process_time(cache)
            report("cached start: fresh process, warm cache, 16x16 render", wall, "s")
            report("  of which import + load kernels + render", inner, "s")
    rng = np.random.default_rng(1)
    for n in (1000, 10000, 100000):
        c = rng.uniform(-50, 50, (n, 3))
        r = rng.uniform(0.5, 2, n)
        b = np.concatenate([c - r[:, None], c + r[:, None]], 1)
        build_bvh(b[:4], 0)
        start = time.perf_counter()
        build_bvh(b, 0)
        report(f"BVH build, {n} balls", time.perf_counter() - start, "s")
    camera, shadow = rays_per_second(20000 if quick else 400000)
    report("camera rays per second (engine: roots + exact tau, 2 threads)", camera, "rays/s")
    report("shadow rays per second (from inside the cloud, 2 threads)", shadow, "rays/s")

    scene = cm.load_scene(CUMULUS, width=size, height=size)
    tiny = cm.load_scene(CUMULUS, width=8, height=8)
    cm.render(tiny, progress=False)  # compile (or load) both shadow modes outside the clock
    cm.render(with_settings(tiny, shadows="map", shadow_map=8), progress=False)
    ref, t_ref = timed(with_settings(scene, quality="reference"))
    report(f"cumulus {size}^2 reference (exact shadows)", t_ref, "s")
    for label, kw in (("default, exact shadows", dict(quality="default")),
                      ("draft, exact shadows", dict(quality="draft")),
                      ("default, shadow map 384", dict(quality="default", shadows="map", shadow_map=384)),
                      ("draft, shadow map 384", dict(quality="draft", shadows="map", shadow_map=384)),
                      ("draft, shadow map 256", dict(quality="draft", shadows="map", shadow_map=256))):
        img, t = timed(with_settings(scene, **kw))
        report(f"cumulus {size}^2 {label}: time", t, "s")
        report(f"cumulus {size}^2 {label}: rel. RMSE vs reference", rel_rmse(img, ref), "")

    with tempfile.TemporaryDirectory() as tmp:
        times = {}
        for n in counts:
            path = sheet_scene(n, scale_size, Path(tmp) / f"sheet_{n}.yaml")
            s = cm.load_scene(path)
            cm.render(cm.load_scene(path, width=4, height=4), progress=False)  # BVH and compile outside the clock
            img, t = timed(s)
            times[n] = t
            report(f"sheet of {n} balls, {scale_size}^2 default exact: time", t, "s")
            report(f"sheet of {n} balls: coverage (alpha > 0.5)", float((img[..., 3] > 0.5).mean()), "")
        ratio = times[counts[-1]] / times[1000]
        report(f"time ratio {counts[-1]} / 1000 balls", ratio, "x")
    if not quick:
        write_csv("bench.csv", rows, ["what", "value", "unit"])
        print(f"wrote {RESULTS / 'bench.csv'}")
    return dict(rows=rows, passed=True)


if __name__ == "__main__":
    run_main(main)
