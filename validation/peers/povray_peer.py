"""Opaque blob surfaces against POV-Ray 3.7, side by side: wall time, silhouettes, shading.

For each POV-Ray blob scene of shared/peers/povray (b94, b890, b1630: ``sphere { <x,y,z>, R, s }``
components, i.e. murakami4 balls of weight s, threshold 0.5, one point light with shadows, a background)
this builds the same scene for cloudmeta in a temporary folder and then

- runs the two whole processes alternately, ``--repeats`` times each after one untimed warm-up of each
  (``povray +I... +O... +W512 +H384 -A +WT2 -D +Q9`` and
  ``python -m cloudmeta.cli render scene.yaml -o x.exr --png x.png -q`` with PYTHONPATH = this checkout),
  and prints the median and the spread (min - max) of both wall times and their ratio cloudmeta / POV-Ray;
- compares the images (from one more, untimed POV-Ray run written as a 16-bit linear PPM): the fraction of
  pixels where both agree on hit or miss (cloudmeta: alpha > 0.5; POV-Ray: the pixel differs from the
  background), and on the pixels both hit the largest, the 99th percentile and the mean |difference| of
  the linear RGB once the light's falloff is matched (below).

Matching the two: POV-Ray's ``angle 50`` is the horizontal field of view and cloudmeta's ``fov`` the
vertical one, fov = 2 atan(tan(25 deg) * 384 / 512); ``right -x*4/3`` with ``sky z`` makes POV-Ray's
camera right-handed, like cloudmeta's. POV-Ray shades a surface as pigment * (0.1 ambient + diffuse * n.l)
with no distance falloff and writes linear values (these files set no ``assumed_gamma``); cloudmeta as
colour / pi * n.l * I / d^2 + colour * ambient (docs/model.md §6). The cloudmeta scene takes ambient 0.1 and
I = diffuse * pi * d_ref^2, d_ref the light's distance from the centroid of the balls; for the shading
comparison every hit pixel's direct part is multiplied by (d / d_ref)^2, d its hit point's distance from
the light (the hit points from ``cloudmeta.first_hit`` on the renderer's pixel-centre rays).

Needs Debian's ``povray`` (``apt-get install povray``); without it this prints how to get it and exits 0.
POV-Ray uses one thread per core it is given (+WT2); cloudmeta all of numba's threads.

    python -m validation.peers.povray_peer [--repeats 5] [--scenes b890 b1630] [--keep DIR]
"""
from __future__ import annotations

import math
import os
import re
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from validation.common import ROOT, alternate, parse, parser, run_main

PEERS = Path(os.environ.get("CLOUDMETA_POVRAY_PEERS", ROOT.parent / "shared" / "peers" / "povray"))  # shared/ beside the checkout
if not PEERS.is_dir():
    PEERS = ROOT / "validation" / "peers" / "povray"
SCENES = ("b94", "b890", "b1630")
WIDTH, HEIGHT = 512, 384
#: POV-Ray 3.7's default finish ambient (with the default global ambient_light 1)
POV_AMBIENT = 0.1

_VEC = r"<\s*([-+\d.eE]+)\s*,\s*([-+\d.eE]+)\s*,\s*([-+\d.eE]+)\s*>"
_NUM = r"([-+\d.eE]+)"


def _find(pattern, text, path, what):
    m = re.search(pattern, text, re.S)
    if m is None:
        raise SystemExit(f"{path}: no {what} found (expected the layout of shared/peers/povray)")
    return m


def parse_pov(path):
    """The parts of a peer scene cloudmeta needs: camera, light, background, blob threshold, pigment,
    diffuse and the components (N, 5): x, y, z, radius, strength."""
    text = Path(path).read_text()
    cam = _find(r"camera\s*{(.*?)}", text, path, "camera").group(1)
    vec = lambda key, body, what: np.array(_find(key + r"\s*" + _VEC, body, path, what).groups(), float)  # noqa: E731
    balls = np.array(re.findall(r"sphere\s*{\s*" + _VEC + r"\s*,\s*" + _NUM + r"\s*,\s*" + _NUM + r"\s*}", text),
                     float)
    if len(balls) == 0:
        raise SystemExit(f"{path}: no blob components `sphere {{ <x,y,z>, R, s }}` found")
    return dict(
        location=vec("location", cam, "camera location"), look_at=vec("look_at", cam, "camera look_at"),
        angle=float(_find(r"angle\s+" + _NUM, cam, path, "camera angle").group(1)),
        light=vec(r"light_source\s*{", text, "light_source"),
        background=vec(r"background\s*{\s*color\s+rgb", text, "background color"),
        threshold=float(_find(r"threshold\s+" + _NUM, text, path, "blob threshold").group(1)),
        pigment=vec(r"pigment\s*{\s*color\s+rgb", text, "pigment color"),
        diffuse=float(_find(r"diffuse\s+" + _NUM, text, path, "finish diffuse").group(1)),
        balls=balls)


def vertical_fov(horizontal_deg, width, height):
    """POV-Ray's ``angle`` is the horizontal field of view; cloudmeta's ``fov`` the vertical one."""
    return math.degrees(2 * math.atan(math.tan(math.radians(horizontal_deg) / 2) * height / width))


def write_scene(pov, folder, name):
    """The cloudmeta scene of a parsed peer scene in ``folder``; returns (yaml path, d_ref)."""
    balls = pov["balls"]
    d_ref = float(np.linalg.norm(pov["light"] - balls[:, :3].mean(axis=0)))
    intensity = pov["diffuse"] * math.pi * d_ref ** 2
    csv = Path(folder) / f"{name}.csv"
    np.savetxt(csv, balls, delimiter=",", fmt="%.6f", header="x,y,z,radius,weight", comments="")
    fmt = lambda v: "[" + ", ".join(f"{float(x):.9g}" for x in v) + "]"  # noqa: E731
    path = Path(folder) / f"{name}.yaml"
    path.write_text(
        f"# {name}.pov of shared/peers/povray as a cloudmeta scene (validation/peers/povray_peer.py)\n"
        f"image: {{width: {WIDTH}, height: {HEIGHT}, spp: 1}}\n"
        f"camera: {{position: {fmt(pov['location'])}, look_at: {fmt(pov['look_at'])}, up: [0, 0, 1], "
        f"fov: {vertical_fov(pov['angle'], WIDTH, HEIGHT):.12g}}}\n"
        f"background: {fmt(pov['background'])}\n"
        f"ambient: {fmt([POV_AMBIENT] * 3)}\n"
        f"lights:\n  - {{type: point, position: {fmt(pov['light'])}, intensity: {intensity:.12g}}}\n"
        f"surfaces:\n  - {{name: blob, kernel: murakami4, threshold: {pov['threshold']:g}, "
        f"color: {fmt(pov['pigment'])}, balls_file: {csv.name}}}\n")
    return path, d_ref


def povray_argv(pov_path, out, extra=()):
    return ["povray", f"+I{pov_path}", f"+O{out}", f"+W{WIDTH}", f"+H{HEIGHT}", "-A", "+WT2", "-D", "+Q9", *extra]


def cloudmeta_argv(scene, exr, png):
    return [sys.executable, "-m", "cloudmeta.cli", "render", str(scene), "-o", str(exr), "--png", str(png), "-q"]


def run_timed(argv, env=None, cwd=None):
    """Wall time of one whole process; its output goes to a log beside its image."""
    start = time.perf_counter()
    done = subprocess.run(argv, env=env, cwd=cwd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT)
    took = time.perf_counter() - start
    if done.returncode != 0:
        tail = done.stdout.decode(errors="replace")[-2000:]
        raise SystemExit(f"{argv[0]} failed ({done.returncode}): {' '.join(map(str, argv))}\n{tail}")
    return took


def read_ppm16(path):
    """(H, W, 3) float64 in [0, 1] of a binary PPM (P6) as POV-Ray writes it, comments in the header."""
    data = Path(path).read_bytes()
    tokens, pos = [], 0
    while len(tokens) < 4:
        while data[pos:pos + 1].isspace():
            pos += 1
        if data[pos:pos + 1] == b"#":
            pos = data.index(b"\n", pos) + 1
            continue
        end = pos
        while not data[end:end + 1].isspace():
            end += 1
        tokens.append(data[pos:end])
        pos = end
    pos += 1  # the single whitespace after maxval
    magic, w, h, maxval = tokens[0], int(tokens[1]), int(tokens[2]), int(tokens[3])
    if magic != b"P6":
        raise SystemExit(f"{path}: expected a binary PPM (P6), found {magic!r}")
    dtype = ">u2" if maxval > 255 else "u1"
    pixels = np.frombuffer(data, dtype, count=w * h * 3, offset=pos).reshape(h, w, 3)
    return pixels.astype(np.float64) / maxval


def pixel_rays(pov, width, height):
    """Origins and unit directions of cloudmeta's pixel-centre camera rays (docs/model.md §8), row 0 on top."""
    position, look_at = pov["location"], pov["look_at"]
    fwd = (look_at - position) / np.linalg.norm(look_at - position)
    right = np.cross(fwd, [0.0, 0.0, 1.0])
    right /= np.linalg.norm(right)
    up = np.cross(right, fwd)
    half_h = math.tan(math.radians(vertical_fov(pov["angle"], width, height)) / 2)
    j, i = np.meshgrid(np.arange(width), np.arange(height))
    x = 2.0 * (j + 0.5) / width - 1.0
    y = 1.0 - 2.0 * (i + 0.5) / height
    d = fwd + (x * half_h * width / height)[..., None] * right + (y * half_h)[..., None] * up
    d /= np.linalg.norm(d, axis=-1, keepdims=True)
    return np.broadcast_to(position, d.shape).reshape(-1, 3), d.reshape(-1, 3)


def compare(pov, exr, ppm, d_ref):
    """Silhouette agreement and the shading differences after matching the falloff."""
    import cloudmeta as cm
    from cloudmeta.api.io import read_exr

    ours, _ = read_exr(exr)
    theirs = read_ppm16(ppm)
    cm_hit = ours[..., 3] > 0.5
    # every hit colour is the pigment (r > b) times a factor, the background has b > r: a miss is a pixel
    # equal to the background to within the 16-bit rounding
    pov_hit = np.abs(theirs - pov["background"]).max(axis=-1) > 1.0 / 4096
    agree = float((cm_hit == pov_hit).mean())
    blob = cm.Blob(pov["balls"][:, :3], pov["balls"][:, 3], weights=pov["balls"][:, 4], kernel="murakami4",
                   threshold=pov["threshold"])
    origins, dirs = pixel_rays(pov, WIDTH, HEIGHT)
    t = cm.first_hit(blob, origins, dirs).reshape(HEIGHT, WIDTH)
    hit_agree = float((np.isfinite(t) == cm_hit).mean())
    both = cm_hit & pov_hit & np.isfinite(t)
    points = origins.reshape(HEIGHT, WIDTH, 3) + t[..., None] * dirs.reshape(HEIGHT, WIDTH, 3)
    d = np.linalg.norm(np.where(both[..., None], points, 0.0) - pov["light"], axis=-1)
    ambient = POV_AMBIENT * pov["pigment"]
    matched = ambient + (ours[..., :3].astype(np.float64) - ambient) * ((d / d_ref) ** 2)[..., None]
    diff = np.abs(matched - theirs)[both]
    return dict(silhouette=agree, first_hit_vs_alpha=hit_agree, n_hit=int(both.sum()),
                max=float(diff.max()) if diff.size else 0.0,
                p99=float(np.quantile(diff.max(axis=-1), 0.99)) if diff.size else 0.0,
                mean=float(diff.mean()) if diff.size else 0.0)


def spread(values):
    return f"{statistics.median(values):7.3f} s ({min(values):.3f}-{max(values):.3f})"


def main(argv=None):
    ap = parser(__doc__)
    ap.add_argument("--repeats", type=int, default=5, help="timed runs of each process (default 5)")
    ap.add_argument("--scenes", nargs="+", default=list(SCENES), choices=SCENES)
    ap.add_argument("--peers", type=Path, default=PEERS, help="folder of the .pov files")
    ap.add_argument("--keep", type=Path, help="keep scenes and images in this folder")
    args, _ = parse(ap, argv)
    if shutil.which("povray") is None:
        print("povray_peer: skipped: `povray` is not on PATH. It is Debian's package `povray` "
              "(sudo apt-get install povray); this script installs nothing.")
        return dict(skipped=True)
    env = dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    results = {}
    with tempfile.TemporaryDirectory(prefix="cloudmeta-povray-") as tmp:
        folder = args.keep or Path(tmp)
        folder.mkdir(parents=True, exist_ok=True)
        print(f"POV-Ray vs cloudmeta, {WIDTH} x {HEIGHT}, whole processes alternating, "
              f"{args.repeats} timed runs each after one warm-up (this machine: {os.cpu_count()} cores)")
        print(f"{'scene':6s} {'balls':>6s} {'POV-Ray median (min-max)':>28s} {'cloudmeta median (min-max)':>28s} "
              f"{'ratio':>6s}")
        for name in args.scenes:
            pov_path = args.peers / f"{name}.pov"
            pov = parse_pov(pov_path)
            scene, d_ref = write_scene(pov, folder, name)
            commands = {
                "povray": (povray_argv(pov_path, folder / f"{name}_povray.png"), None, folder),
                "cloudmeta": (cloudmeta_argv(scene, folder / f"{name}.exr", folder / f"{name}.png"), env, ROOT),
            }
            times = alternate(commands, args.repeats, run_timed)
            ratio = statistics.median(times["cloudmeta"]) / statistics.median(times["povray"])
            print(f"{name:6s} {len(pov['balls']):6d} {spread(times['povray']):>28s} {spread(times['cloudmeta']):>28s} "
                  f"{ratio:5.2f}x", flush=True)
            run_timed(povray_argv(pov_path, folder / f"{name}_povray.ppm", ("+FP16",)), None, folder)
            cmp = compare(pov, folder / f"{name}.exr", folder / f"{name}_povray.ppm", d_ref)
            print(f"       silhouettes agree on {cmp['silhouette']:.6f} of pixels "
                  f"({(1 - cmp['silhouette']) * WIDTH * HEIGHT:.0f} differ); on the {cmp['n_hit']} pixels both hit, "
                  f"|shading difference| after matching the falloff: max {cmp['max']:.2e}, "
                  f"99th percentile {cmp['p99']:.2e}, mean {cmp['mean']:.2e} (linear RGB; 16-bit steps: 1.5e-5)",
                  flush=True)
            results[name] = dict(times=times, ratio=ratio, **cmp)
    print("ratio = cloudmeta median / POV-Ray median (the goal is at most 0.5 on b890 and b1630); "
          "timings are wall times on a machine that may be shared")
    return results


if __name__ == "__main__":
    run_main(main)
