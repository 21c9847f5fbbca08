"""Writes the accuracy scene suite of issue #11: the procedural ball sets (CSV) and every scene (YAML).

Deterministic: each ball set comes from its own seeded numpy generator and is written with fixed
formatting, so that running this again writes the committed files byte for byte (tests/renderer/test_suite.py
checks it). The 77-ball cumulus and the 1,200-ball bank are the project's own (../cumulus.csv,
../dense_1000.csv, by relative balls_file paths), not copies.

Every scene is small (64 x 48 pixels, spp 1: the pixel centre) so that a converged reference costs seconds.
The first comment line of each YAML is its place in the suite, read by validation/references/suite.py:

    # suite: lighting=front geometry=cumulus density=field phase=hg ambient=yes

Axes and values (each value is covered by at least two scenes, validation/references/suite.py checks it):
lighting front (sun behind the camera) | back | side | grazing (sun a few degrees up) | point_inside |
point_outside; geometry cumulus (77 balls) | deck (flat stratus deck) | ellipsoids (150 rotated) |
puffs (500 small dense spheres) | bank (1,200 balls) | carved (negative balls) | generated (the generated
4,000-ball cumulus) | wisps (400 tiny puffs in filaments) | rotated (150 thin ellipsoids); density field | excess |
uniform; phase hg (g up to 0.9) | double_hg | rayleigh | isotropic; ambient yes | no. The six scenes of issue
#23 (generated_*, wisps_*, rotated_*) have a black background and no ambient light: the scattered light is
all there is, and they were held out of the presets' tuning.

Run from the repository root: python scenes/suite/make_suite.py [OUTDIR]
"""
import sys
from pathlib import Path

import numpy as np

HEADER_ELLIPSOIDS = "x,y,z,rx,ry,rz,ax,ay,az,weight"
HEADER_SPHERES = "x,y,z,radius,weight"


def deck(seed=21):
    """A flat stratus deck, 16 x 12 units and about 1.2 thick: 240 flattened ellipsoids on a jittered grid
    at z ~ 1, long axes anywhere in the horizontal plane."""
    rng = np.random.default_rng(seed)
    gx, gy = np.meshgrid(np.linspace(-7.5, 7.5, 16), np.linspace(-5.5, 5.5, 15))
    xy = np.stack([gx.ravel(), gy.ravel()], axis=1) + rng.uniform(-0.35, 0.35, (gx.size, 2))
    rows = []
    for x, y in xy:
        a = rng.uniform(1.1, 1.5)
        rows.append((x, y, rng.uniform(0.9, 1.1), a, a * rng.uniform(0.7, 1.0), rng.uniform(0.45, 0.6),
                     0.0, 0.0, rng.uniform(0.0, 180.0), rng.uniform(0.9, 1.1)))
    return HEADER_ELLIPSOIDS, rows


def ellipsoids(n=150, seed=22):
    """150 ellipsoids with random orientations (every Euler angle) and aspect ratios up to 3, in a cloud
    about 8 x 5 x 5 units: the case where shadow rays graze tilted supports."""
    rng = np.random.default_rng(seed)
    rows = []
    for _ in range(n):
        c = rng.normal(0.0, 1.0, 3) * np.array([1.8, 1.1, 1.0]) + np.array([0.0, 0.0, 2.5])
        r = rng.uniform(0.45, 1.35, 3)
        r[rng.integers(3)] = min(3.0 * r.min(), 1.6)  # one long axis: aspect up to 3
        rows.append((*c, *r, rng.uniform(-180, 180), rng.uniform(-90, 90), rng.uniform(-180, 180),
                     rng.uniform(0.8, 1.1)))
    return HEADER_ELLIPSOIDS, rows


def puffs(n=500, seed=23):
    """500 small spheres (radius 0.22-0.45) scattered through a 9 x 4 x 3 slab: many small, dense puffs
    whose shadows are narrower than a shadow-map texel."""
    rng = np.random.default_rng(seed)
    rows = []
    for _ in range(n):
        c = rng.uniform([-4.5, -2.0, 1.0], [4.5, 2.0, 4.0])
        rows.append((*c, rng.uniform(0.22, 0.45), rng.uniform(0.9, 1.2)))
    return HEADER_SPHERES, rows


def carved(seed=24):
    """A blob of 36 positive balls (radius 1-1.7) carved by 12 negative balls (weight -0.8 to -1.6): tunnels
    and dents whose walls the view and shadow rays cross several times."""
    rng = np.random.default_rng(seed)
    rows = []
    for _ in range(36):
        c = rng.normal(0.0, 1.0, 3) * np.array([1.9, 1.2, 0.9]) + np.array([0.0, 0.0, 2.5])
        rows.append((*c, rng.uniform(1.0, 1.7), rng.uniform(0.9, 1.1)))
    for _ in range(12):
        c = rng.normal(0.0, 1.0, 3) * np.array([1.6, 1.0, 0.8]) + np.array([0.0, 0.0, 2.5])
        rows.append((*c, rng.uniform(0.6, 1.1), -rng.uniform(0.8, 1.6)))
    return HEADER_SPHERES, rows


def wisps(n=400, seed=31):
    """400 tiny dense puffs (radius 0.08-0.22) strung along three drifting filaments about 8 units long:
    thin wisps whose scattered light is a small share of a black frame (issue #23's held-out kind)."""
    rng = np.random.default_rng(seed)
    rows = []
    for i in range(n):
        f = i % 3
        x = rng.uniform(-4.0, 4.0)
        c = np.array([x, 0.8 * np.sin(0.7 * x + 2.0 * f) + rng.normal(0.0, 0.25),
                      1.5 + 1.2 * f + 0.4 * np.cos(0.9 * x + f) + rng.normal(0.0, 0.2)])
        rows.append((*c, rng.uniform(0.08, 0.22), rng.uniform(0.8, 1.2)))
    return HEADER_SPHERES, rows


def rotated(n=150, seed=32):
    """150 thin rotated ellipsoids (aspect 2-5: sheets and needles) in a cloud about 8 x 4 x 4 units, another
    draw than ellipsoids_150: shadow lines graze tilted, flattened supports."""
    rng = np.random.default_rng(seed)
    rows = []
    for _ in range(n):
        c = rng.normal(0.0, 1.0, 3) * np.array([2.0, 0.9, 0.9]) + np.array([0.0, 0.0, 2.5])
        r = np.full(3, rng.uniform(0.5, 1.2))
        r[rng.integers(3)] /= rng.uniform(2.0, 5.0)
        rows.append((*c, *r, rng.uniform(-180, 180), rng.uniform(-90, 90), rng.uniform(-180, 180),
                     rng.uniform(0.8, 1.2)))
    return HEADER_ELLIPSOIDS, rows


BALL_SETS = {"deck.csv": deck, "ellipsoids_150.csv": ellipsoids, "puffs_500.csv": puffs, "carved.csv": carved,
             "wisps_400.csv": wisps, "rotated_150.csv": rotated}

# --- the scenes ---------------------------------------------------------------------------------------------------
IMAGE = "image: {width: 64, height: 48, spp: 1}"
CAM_CUMULUS = "camera: {position: [0, -22, 2.2], look_at: [0, 0, 2.2], up: [0, 0, 1], fov: 30}"
CAM_SMALL = "camera: {position: [0, -15, 4.0], look_at: [0, 0, 2.5], up: [0, 0, 1], fov: 34}"
CAM_DECK = "camera: {position: [0, -16, 5.5], look_at: [0, 0, 1.0], up: [0, 0, 1], fov: 44}"
CAM_BANK = "camera: {position: [0, -44, 24], look_at: [0, -2, 1.0], up: [0, 0, 1], fov: 44}"
CAM_GENERATED = "camera: {position: [0, -29, 1.0], look_at: [0, 0, 2.75], up: [0, 0, 1], fov: 34}"
BLACK = "[0, 0, 0]"


def medium(name, balls_file, kernel, threshold, mode, scale, albedo, phase):
    return (f"media:\n  - name: {name}\n    kernel: {kernel}\n    threshold: {threshold}\n"
            f"    density: {{mode: {mode}, scale: {scale}}}\n    albedo: {albedo}\n    phase: {phase}\n"
            f"    balls_file: {balls_file}\n")


def sun(direction, irradiance, temperature=5600):
    return (f"  - {{type: directional, direction: [{', '.join(map(str, direction))}], irradiance: {irradiance}, "
            f"color: {{temperature: {temperature}}}}}\n")


def lamp(position, intensity, temperature=3000):
    return (f"  - {{type: point, position: [{', '.join(map(str, position))}], intensity: {intensity}, "
            f"color: {{temperature: {temperature}}}}}\n")


#: name -> (tags, description, camera, background, ambient or None, lights, medium)
SCENES = {
    "cumulus_front": (
        "lighting=front geometry=cumulus density=field phase=hg ambient=yes",
        "the 77-ball cumulus, sun behind the camera and above: the lit face, HG g = 0.6 seen at backscatter",
        CAM_CUMULUS, "[0.22, 0.38, 0.72]", "[0.10, 0.14, 0.22]", [sun((-0.25, -0.9, 0.35), 12.0)],
        medium("cumulus", "../cumulus.csv", "wyvill6", 0.5, "field", 2.0, 0.95, "{type: hg, g: 0.6}")),
    "cumulus_back": (
        "lighting=back geometry=cumulus density=field phase=hg ambient=no",
        "the cumulus against the sun (HG g = 0.9): bright silver lining on the thin edges, dark core",
        CAM_CUMULUS, "[0.20, 0.34, 0.66]", None, [sun((0.15, 0.93, 0.33), 4.0)],
        medium("cumulus", "../cumulus.csv", "wyvill6", 0.5, "field", 2.0, 0.95, "{type: hg, g: 0.9}")),
    "cumulus_point_inside": (
        "lighting=point_inside geometry=cumulus density=field phase=isotropic ambient=no",
        "a lamp inside the cumulus (lightning-like glow): the 1/r^2 peak inside the medium, thin density",
        CAM_CUMULUS, "[0.01, 0.01, 0.02]", None, [lamp((0.3, 0.2, 2.4), 60.0)],
        medium("cumulus", "../cumulus.csv", "wyvill6", 0.5, "field", 0.6, 0.9, "{type: isotropic}")),
    "puffs_front": (
        "lighting=front geometry=puffs density=field phase=isotropic ambient=yes",
        "500 small dense puffs, front-lit: many small shadows cast onto puffs further back",
        CAM_SMALL, "[0.22, 0.38, 0.72]", "[0.08, 0.10, 0.16]", [sun((-0.3, -0.85, 0.45), 10.0)],
        medium("puffs", "puffs_500.csv", "wyvill6", 0.4, "field", 8.0, 0.95, "{type: isotropic}")),
    "puffs_point_outside": (
        "lighting=point_outside geometry=puffs density=uniform phase=rayleigh ambient=no",
        "the puffs lit by a lamp above and in front of them: uniform density (sigma_t jumps at every "
        "isosurface), Rayleigh phase",
        CAM_SMALL, "[0.02, 0.02, 0.04]", None, [lamp((2.5, -4.0, 6.5), 300.0)],
        medium("puffs", "puffs_500.csv", "wyvill6", 0.4, "uniform", 4.0, 0.9, "{type: rayleigh}")),
    "ellipsoids_side": (
        "lighting=side geometry=ellipsoids density=excess phase=hg ambient=no",
        "150 rotated ellipsoids, soft edges (excess), HG g = 0.85, sun from the side",
        CAM_SMALL, "[0.20, 0.34, 0.66]", None, [sun((1.0, 0.0, 0.15), 10.0)],
        medium("ellipsoids", "ellipsoids_150.csv", "wyvill6", 0.3, "excess", 6.0, 0.95, "{type: hg, g: 0.85}")),
    "ellipsoids_back": (
        "lighting=back geometry=ellipsoids density=uniform phase=double_hg ambient=no",
        "the ellipsoids against the sun, uniform density, double HG (0.8 / -0.3)",
        CAM_SMALL, "[0.20, 0.34, 0.66]", None, [sun((-0.2, 0.9, 0.4), 5.0)],
        medium("ellipsoids", "ellipsoids_150.csv", "wyvill6", 0.3, "uniform", 1.2, 0.9,
               "{type: double_hg, g1: 0.8, g2: -0.3, w: 0.85}")),
    "ellipsoids_two_lights": (
        "lighting=side,point_outside geometry=ellipsoids density=field phase=isotropic ambient=yes",
        "the ellipsoids lit by a side sun and a warm lamp outside on the other side",
        CAM_SMALL, "[0.10, 0.15, 0.30]", "[0.05, 0.06, 0.08]",
        [sun((-0.9, -0.2, 0.35), 6.0), lamp((4.6, -3.0, 3.1), 120.0)],
        medium("ellipsoids", "ellipsoids_150.csv", "wyvill6", 0.3, "field", 3.0, 0.9, "{type: isotropic}")),
    "deck_grazing": (
        "lighting=grazing geometry=deck density=uniform phase=rayleigh ambient=yes",
        "a flat stratus deck under a sun 5 degrees up: long shadow rays skimming the deck's top",
        CAM_DECK, "[0.22, 0.38, 0.72]", "[0.08, 0.10, 0.16]", [sun((0.6, 0.79, 0.087), 12.0, 4000)],
        medium("deck", "deck.csv", "wyvill6", 0.5, "uniform", 1.5, 0.95, "{type: rayleigh}")),
    "deck_point_inside": (
        "lighting=point_inside geometry=deck density=excess phase=hg ambient=no",
        "a lamp inside the deck (a city light seen through stratus), HG g = 0.9",
        CAM_DECK, "[0.01, 0.01, 0.02]", None, [lamp((1.15, 0.5, 1.1), 80.0)],
        medium("deck", "deck.csv", "wyvill6", 0.5, "excess", 3.0, 0.9, "{type: hg, g: 0.9}")),
    "bank_grazing": (
        "lighting=grazing geometry=bank density=field phase=hg ambient=yes",
        "the 1,200-ball stratocumulus bank (../dense_1000.csv) under a sun 6 degrees up",
        CAM_BANK, "[0.16, 0.30, 0.62]", "[0.08, 0.11, 0.18]", [sun((0.7, 0.71, 0.105), 12.0, 4500)],
        medium("stratocumulus", "../dense_1000.csv", "wyvill6", 0.3, "field", 1.0, 0.96, "{type: hg, g: 0.6}")),
    "bank_front": (
        "lighting=front geometry=bank density=excess phase=double_hg ambient=no",
        "the bank with the sun behind the aircraft: soft-edged cells, double HG (0.75 / -0.25)",
        CAM_BANK, "[0.16, 0.30, 0.62]", None, [sun((-0.2, -0.75, 0.63), 10.0)],
        medium("stratocumulus", "../dense_1000.csv", "wyvill6", 0.3, "excess", 3.0, 0.96,
               "{type: double_hg, g1: 0.75, g2: -0.25, w: 0.9}")),
    "carved_point_outside": (
        "lighting=point_outside geometry=carved density=excess phase=double_hg ambient=yes",
        "a murakami4 blob carved by 12 negative balls, lit by a lamp outside in front of it",
        CAM_SMALL, "[0.05, 0.07, 0.12]", "[0.05, 0.06, 0.08]", [lamp((-3.0, -5.0, 5.0), 200.0)],
        medium("carved", "carved.csv", "murakami4", 0.3, "excess", 3.0, 0.9,
               "{type: double_hg, g1: 0.7, g2: -0.3, w: 0.8}")),
    "carved_side": (
        "lighting=side geometry=carved density=field phase=rayleigh ambient=yes",
        "the carved blob under a side sun: shadow rays through the tunnels, Rayleigh phase",
        CAM_SMALL, "[0.20, 0.34, 0.66]", "[0.06, 0.08, 0.12]", [sun((-1.0, 0.1, 0.2), 10.0)],
        medium("carved", "carved.csv", "murakami4", 0.3, "field", 2.0, 0.95, "{type: rayleigh}")),
    # issue #23: a black background and no ambient, so that every figure is relative to scattered light alone
    "generated_front": (
        "lighting=front geometry=generated density=excess phase=double_hg ambient=no",
        "the generated 4,000-ball cumulus (../generated_cumulus.csv) on black, sun behind the camera",
        CAM_GENERATED, BLACK, None, [sun((0.3, -0.8, 0.5), 8.0)],
        medium("cumulus", "../generated_cumulus.csv", "wyvill6", 0.5, "excess", 4.76305, 0.98,
               "{type: double_hg, g1: 0.75, g2: -0.3, w: 0.85}")),
    "generated_grazing": (
        "lighting=grazing geometry=generated density=field phase=hg ambient=no",
        "the generated cumulus on black under a sun 4 degrees up, from the side: long grazing shadow lines",
        CAM_GENERATED, BLACK, None, [sun((0.95, 0.3, 0.07), 10.0, 3800)],
        medium("cumulus", "../generated_cumulus.csv", "wyvill6", 0.5, "field", 3.0, 0.97, "{type: hg, g: 0.7}")),
    "wisps_front": (
        "lighting=front geometry=wisps density=field phase=hg ambient=no",
        "400 tiny dense puffs in three filaments on black, front-lit: little scattered light in the frame",
        CAM_SMALL, BLACK, None, [sun((-0.3, -0.85, 0.45), 10.0)],
        medium("wisps", "wisps_400.csv", "wyvill6", 0.4, "field", 12.0, 0.95, "{type: hg, g: 0.5}")),
    "wisps_point": (
        "lighting=point_outside geometry=wisps density=excess phase=isotropic ambient=no",
        "the wisps on black lit by a lamp just below the middle filament",
        CAM_SMALL, BLACK, None, [lamp((0.5, -0.5, 2.2), 40.0)],
        medium("wisps", "wisps_400.csv", "wyvill6", 0.4, "excess", 20.0, 0.9, "{type: isotropic}")),
    "rotated_side": (
        "lighting=side geometry=rotated density=field phase=hg ambient=no",
        "150 thin rotated ellipsoids on black, sun from the side, strong forward scattering (HG g = 0.9)",
        CAM_SMALL, BLACK, None, [sun((0.95, 0.25, 0.2), 10.0)],
        medium("rotated", "rotated_150.csv", "wyvill6", 0.3, "field", 4.0, 0.95, "{type: hg, g: 0.9}")),
    "rotated_back": (
        "lighting=back geometry=rotated density=excess phase=hg ambient=no",
        "the rotated ellipsoids on black against the sun (HG g = 0.85), soft edges",
        CAM_SMALL, BLACK, None, [sun((0.2, 0.9, 0.35), 6.0)],
        medium("rotated", "rotated_150.csv", "wyvill6", 0.3, "excess", 6.0, 0.95, "{type: hg, g: 0.85}")),
}


def scene_text(name):
    tags, description, camera, background, ambient, lights, med = SCENES[name]
    text = (f"# suite: {tags}\n# {description}.\n# Accuracy suite of issue #11 (written by scenes/suite/make_suite.py; "
            f"validation/accuracy/suite_references.py).\n{IMAGE}\n{camera}\nbackground: {background}\n")
    if ambient is not None:
        text += f"ambient: {ambient}\n"
    return text + "lights:\n" + "".join(lights) + med + "render: {quality: default}\n" + \
        f"output: {{path: {name}.exr, png: {name}.png}}\n"


def ball_set_text(name):
    header, rows = BALL_SETS[name]()
    return header + "\n" + "".join(",".join(f"{v:.4f}" for v in row) + "\n" for row in rows)


def write_all(out):
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    written = []
    for name in BALL_SETS:
        (out / name).write_text(ball_set_text(name), encoding="utf-8", newline="\n")
        written.append(out / name)
    for name in SCENES:
        (out / f"{name}.yaml").write_text(scene_text(name), encoding="utf-8", newline="\n")
        written.append(out / f"{name}.yaml")
    return written


if __name__ == "__main__":
    for path in write_all(sys.argv[1] if len(sys.argv) > 1 else Path(__file__).resolve().parent):
        print(f"wrote {path}")
