"""The accuracy scene suite (scenes/suite/): the scenes, their axes, the settings and the cache.

Shared by validation/accuracy/suite_references.py (converged references, cached),
validation/accuracy/suite_accuracy.py (the presets' true error), validation/accuracy/error_estimate.py and
tests/renderer/test_suite.py. The scenes themselves are written by
scenes/suite/make_suite.py; each YAML's first line names its place on every axis:

    # suite: lighting=front geometry=cumulus density=field phase=hg ambient=yes

Error measure (validation/common.py's ``rel_rmse``, over the RGB of the whole image):

    rel. RMSE = sqrt(mean over pixels and RGB of (L - L_ref)^2) / sqrt(mean over pixels and RGB of L_ref^2)

the same relative to the scattered light alone (``rel_rmse_scattered``: over the mean scattered radiance,
the presets' measure, so that a bright sky does not dilute the error), and the worst
pixel's relative error,
max over pixels of max_c |L - L_ref| / max_c L_ref (the largest channel of the reference pixel: dark
pixels are not divided by their own small channels).
"""
from __future__ import annotations

import hashlib
import json
from pathlib import Path

import numpy as np

import cloudmeta as cm
from validation.common import ROOT, rel_rmse, with_settings

SUITE = ROOT / "scenes" / "suite"
#: the committed converged references, read by the tests (validation/reference_images/suite/)
CACHE = ROOT / "validation" / "reference_images" / "suite"

#: every axis and its values; each value must be covered by at least two scenes
AXES = {
    "lighting": ("front", "back", "side", "grazing", "point_inside", "point_outside"),
    "geometry": ("cumulus", "deck", "ellipsoids", "puffs", "bank", "carved", "generated", "wisps", "rotated"),
    "density": ("field", "excess", "uniform"),
    "phase": ("hg", "double_hg", "rayleigh", "isotropic"),
    "ambient": ("yes", "no"),
}
#: the presets' image-level targets of relative RMSE against the converged image
TARGETS = {"draft": 3e-3, "default": 1e-3, "fine": 3e-4}
#: the converged reference: the renderer's tightest preset
REFERENCE = dict(quality="reference")
#: tighter still, only to show that REFERENCE has converged (max_length: this fraction of the diagonal)
TIGHTER = dict(quality="reference", tolerance=1e-8, max_tau=0.05, max_angle=0.0125, cutoff=0.0)
TIGHTER_LENGTH = 1 / 256
#: the pixels the independent numpy reference computes: every STRIDE-th row and column of the image,
#: starting at STRIDE // 2 (a 16 x 12 grid of a 64 x 48 image)
STRIDE = 4


def scene_paths():
    return sorted(SUITE.glob("*.yaml"))


def tags(path):
    """{axis: [values]} from the YAML's first line (``# suite: axis=value[,value] ...``)."""
    first = Path(path).read_text(encoding="utf-8").splitlines()[0]
    if not first.startswith("# suite:"):
        raise ValueError(f"{path}: the first line must be '# suite: axis=value ...', got {first!r}")
    out = {}
    for item in first[len("# suite:"):].split():
        axis, values = item.split("=")
        out[axis] = values.split(",")
    return out


def coverage(paths=None):
    """{axis: {value: [scene names]}} over the suite."""
    cov = {axis: {v: [] for v in values} for axis, values in AXES.items()}
    for p in paths or scene_paths():
        for axis, values in tags(p).items():
            for v in values:
                cov[axis].setdefault(v, []).append(p.stem)
    return cov


def tighter(scene):
    lo, hi = scene.bbox()
    return with_settings(scene, **TIGHTER, max_length=TIGHTER_LENGTH * float(np.linalg.norm(hi - lo)))


def scattered(ref, background):
    """S_ref = L_ref - L_bg T_ref (T_ref = 1 - alpha): the reference's scattered light, what the quadrature
    approximates (the background seen through the media is exact at every setting)."""
    b = np.asarray(ref, np.float64)
    return b[..., :3] - np.asarray(background, np.float64) * (1.0 - b[..., 3:4])


def rel_rmse_scattered(img, ref, background):
    """The presets' measure (docs/error_estimate.md): sqrt(mean over pixels and RGB of
    (L - L_ref)^2) / mean over pixels and RGB of S_ref. It does not shrink as the sky gets brighter or
    covers more of the frame."""
    return rel_rmse(img, ref, norm=float(scattered(ref, background).mean()))


def worst_pixel(img, ref):
    """max over pixels of max_c |L - L_ref| / max_c L_ref, and the pixel (row, col)."""
    a = np.asarray(img, np.float64)[..., :3]
    b = np.asarray(ref, np.float64)[..., :3]
    rel = np.abs(a - b).max(axis=-1) / np.maximum(b.max(axis=-1), 1e-300)
    k = np.unravel_index(int(np.argmax(rel)), rel.shape)
    return float(rel[k]), (int(k[0]), int(k[1]))


def fingerprint(path):
    """A hash of what a reference depends on: the YAML (less its comment lines, which change no pixel), the
    balls files it names, the two settings."""
    path = Path(path)
    text = path.read_text(encoding="utf-8")
    h = hashlib.sha256("\n".join(line for line in text.splitlines() if not line.lstrip().startswith("#")).encode())
    scene = cm.load_scene(path)
    for text in path.read_text(encoding="utf-8").splitlines():
        if "balls_file:" in text:
            h.update((path.parent / text.split("balls_file:")[1].strip()).read_bytes())
    h.update(json.dumps([REFERENCE, TIGHTER, TIGHTER_LENGTH, scene.image.width, scene.image.height],
                        sort_keys=True).encode())
    return h.hexdigest()[:16]


def cached(name):
    """(reference, tighter, metadata) of a scene from the cache, or None where it is missing."""
    files = [CACHE / f"{name}.npy", CACHE / f"{name}.tighter.npy", CACHE / f"{name}.json"]
    if not all(f.exists() for f in files):
        return None
    return np.load(files[0]), np.load(files[1]), json.loads(files[2].read_text())
