"""Compile the kernels ahead of the first render: ``cloudmeta compile [--jobs N]``.

The first render on a machine compiles its kernels (0.5-1.5 minutes of one core each, then cached; README
"Compilation cache"). A render compiles only what its scene needs (kernels.features), so a fresh machine
pays again for the first scene of each kind. This compiles every kind at once, in ``jobs`` processes side by
side: for a worker image, before a Dask cluster starts, or before a test run. Each job renders a tiny scene
(or traces a few rays) in a fresh process; the compiled kernels land in the shared cache, and whatever a job
finds there already is loaded, not compiled again (an entry that cannot be read is compiled again and
replaced: this repairs a damaged cache).
"""
from __future__ import annotations

import os
import subprocess
import sys
import tempfile
import threading
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

_MEDIUM = """
  - density: {mode: field, scale: 4.0}
    albedo: 0.9
    phase: {type: hg, g: 0.5}
    balls: [{center: [0, 0, 0], radius: 1.5}, {center: [0.8, 0.2, 0.3], radius: 1.0}]
"""
_SCENE = """
image: {{width: 4, height: 3}}
camera: {{position: [0, -6, 0], look_at: [0, 0, 0], up: [0, 0, 1], fov: 40}}
background: {{sky: {{elevation: 40, azimuth: 200, ground_height: -4}}}}
lights:
  - {{type: directional, direction: [0.3, -0.5, 0.8], irradiance: 3.0}}
  - {{type: point, position: [2, -2, 2], intensity: 5.0}}
render: {{shadows: {shadows}, shadow_map: 8, scattering: {scattering}, ms_spp: 2, max_order: 3{extra}}}
media:{medium}
{surfaces}
"""
_SURFACES = """surfaces:
  - color: [0.6, 0.5, 0.4]
    balls: [{center: [0, 0, -3], radii: [6, 6, 1]}]
"""
#: name -> (shadows, scattering, with surfaces, more render keys): the kinds of scene that compile their own kernels;
#: a list of several renders them in turn in one process (the shared method's tails call the paths' vertices,
#: which the paths' kernel has compiled in that process already: 43 s more there, 93 s in a process of its own)
SCENES = {
    "single scattering, media only": ("exact", "single", False, ""),
    "single scattering with surfaces and shadow maps": ("map", "single", True, ""),
    "multiple scattering, media only, and the shared method": [
        ("exact", "multiple", False, ""),
        ("exact", "approximate", False, ", method: shared, shared: {stride: 2, tails: 4}")],
    "multiple scattering with surfaces": ("exact", "multiple", True, ""),
    # the grid's photons and lookups (kernels.fluence); a few photons, so that the job's time is the compile's
    "approximate multiple scattering, grid method": ("exact", "approximate", False,
                                                     ", method: grid, grid: {cells: 8, photons: 4096}"),
}
_RENDER = "import cloudmeta as cm\nfor path in {paths!r}: cm.render(cm.load_scene(path), progress=False)"
_RAYS = """
import numpy as np, cloudmeta as cm
b = cm.Blob(centers=[[0, 0, 0], [0.8, 0.2, 0.3]], radii=[1.5, 1.0])
o = np.array([[0.0, -5.0, 0.0], [0.1, -5.0, 0.2]]); d = np.array([[0.0, 1.0, 0.0], [0.0, 1.0, 0.0]])
cm.roots(b, o, d); cm.segments(b, o, d); cm.optical_depth(b, o, d); cm.first_hit(b, o, d)
p = np.zeros((2, 3)); cm.field(b, p); cm.gradient(b, p); cm.normal(b, p)
"""


def jobs(folder):
    """[(name, python code)]: the vectorised ray API and one job per kind of scene, in an order that keeps two
    processes busy (the ray API and the kernel with surfaces and maps share least with the others; the grid's
    kernels, last, fill the second process while the first compiles multiple scattering with surfaces)."""
    out = [("the ray API (roots, segments, optical depth, first hit, field)", _RAYS)]
    for i, (name, kinds) in enumerate(SCENES.items()):
        paths = []
        for k, (shadows, scattering, surfaces, extra) in enumerate(kinds if isinstance(kinds, list) else [kinds]):
            path = Path(folder) / f"kind{i}_{k}.yaml"
            path.write_text(_SCENE.format(shadows=shadows, scattering=scattering, medium=_MEDIUM, extra=extra,
                                          surfaces=_SURFACES if surfaces else ""))
            paths.append(str(path))
        out.append((name, _RENDER.format(paths=paths)))
    return [out[0], out[2], out[1], out[4], out[3], out[5]]


def precompile(n_jobs=2, report=print):
    """Run every job, ``n_jobs`` processes at a time; returns [(name, seconds, ok)], ok where the job ran
    and its kernels were cached. A failed job reports its last line of error and the others go on (its
    kernels then compile on first use). What the jobs said of the cache (an entry that could not be read and
    was compiled again, a folder that cannot be written) is passed on, each line once."""
    from ..kernels.config import UNCACHED
    said, lock = set(), threading.Lock()
    with tempfile.TemporaryDirectory(prefix="cloudmeta-compile-") as folder:
        todo = jobs(folder)
        env = dict(os.environ)
        package_root = str(Path(__file__).resolve().parent.parent)
        env["PYTHONPATH"] = os.pathsep.join(p for p in (package_root, env.get("PYTHONPATH")) if p)

        def run(job):
            name, code = job
            start = time.perf_counter()
            done = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True)
            took = time.perf_counter() - start
            notes = [line for line in done.stderr.splitlines() if line.startswith("cloudmeta: ")]
            with lock:
                for line in notes:
                    if line not in said:
                        said.add(line)
                        report(line)
            if done.returncode != 0:
                last = (done.stderr.strip().splitlines() or ["?"])[-1]
                report(f"cloudmeta: compiling {name} failed: {last}")
                return name, took, False
            cached = not any(UNCACHED in line for line in notes)
            report(f"cloudmeta: compiled {name} in {took:.0f} s" + ("" if cached else ", not cached"))
            return name, took, cached

        with ThreadPoolExecutor(max(1, n_jobs)) as pool:
            return list(pool.map(run, todo))
