"""How far from white the PNG shows a cloud's sunlit top: the chromaticity (CIE 1976 u'v') of the sunlit top of
scenes/generated_cumulus.yaml in the PNG, against the display's white point (D65), for each way of making
the picture (cloudmeta.api.display, docs/display.md).

The scene is rendered once (the EXR's linear image; by default 128 x 128 at quality draft). The sunlit top is
the cloud's pixels (alpha > 0.5) whose luminance in the linear image is at or above its 97th percentile: the
same pixels for every picture. Their PNG codes are decoded with the sRGB curve, averaged as linear BT.709
RGB, and their u'v' compared with D65's. Pictures: raw (the preview as it was: linear x 2^exposure, sRGB
curve), raw white-balanced to the scene, aces without white balance, and aces with it (the default).

    python -m validation.accuracy.display_check [--size 128] [--quality draft] [--scene PATH]

Requirement: the default picture's sunlit top within 0.005 of the white point.
"""
from __future__ import annotations

import numpy as np

import cloudmeta as cm
from cloudmeta.api.display import _rgb_to_xyz, display_image, scene_illuminant
from validation.common import ROOT, parse, parser, run_main

#: the white balance's target and the display's white
D65_XY = (0.3127, 0.3290)
#: what the default picture's sunlit top may be from the white point, in u'v'
REQUIRED = 0.005
#: the sunlit top: the cloud's pixels at or above this percentile of its luminance
TOP_PERCENTILE = 97.0
#: sRGB (BT.709, D65) linear RGB -> XYZ, derived from the primaries and white as colour-science gives them
_RGB_TO_XYZ = _rgb_to_xyz("ITU-R BT.709")


def srgb_decode(codes):
    """Linear values of 8-bit sRGB codes (the sRGB EOTF, IEC 61966-2-1)."""
    v = np.asarray(codes, np.float64) / 255.0
    return np.where(v <= 0.04045, v / 12.92, ((v + 0.055) / 1.055) ** 2.4)


def uv_of_xyz(xyz):
    x, y, z = xyz
    d = x + 15.0 * y + 3.0 * z
    return np.array([4.0 * x / d, 9.0 * y / d])


def uv_of_xy(xy):
    x, y = xy
    return uv_of_xyz(np.array([x / y, 1.0, (1.0 - x - y) / y]))


def top_mask(image):
    """The sunlit top: cloud pixels (alpha > 0.5) at or above the TOP_PERCENTILE-th percentile of luminance."""
    y = image[..., :3] @ _RGB_TO_XYZ[1]
    cloud = image[..., 3] > 0.5
    return cloud & (y >= np.percentile(y[cloud], TOP_PERCENTILE))


def distance(codes, mask):
    """u'v' distance from D65 of the mean linear colour of the PNG ``codes`` over ``mask``."""
    rgb = srgb_decode(codes[mask]).mean(axis=0)
    return float(np.linalg.norm(uv_of_xyz(_RGB_TO_XYZ @ rgb) - uv_of_xy(D65_XY)))


PICTURES = (("raw (the preview as it was)", dict(display="raw")),
            ("raw, white balance scene", dict(display="raw", white_balance="scene")),
            ("aces, white balance none", dict(display="aces", white_balance="none")),
            ("aces, white balance scene (default)", dict(display="aces")))


def main(argv=None):
    ap = parser(__doc__)
    ap.add_argument("--size", type=int, default=128)
    ap.add_argument("--quality", default="draft")
    ap.add_argument("--scene", default=str(ROOT / "scenes" / "generated_cumulus.yaml"))
    args, _ = parse(ap, argv)
    scene = cm.load_scene(args.scene, width=args.size, height=args.size, render={"quality": args.quality})
    image = np.asarray(cm.render(scene, progress=False), np.float64)
    illuminant = scene_illuminant(scene)
    mask = top_mask(image)
    print(f"{args.scene}: {args.size} x {args.size}, quality {args.quality}; sunlit top: {int(mask.sum())} pixels "
          f"(alpha > 0.5, luminance >= its {TOP_PERCENTILE:g}th percentile)")
    print(f"the scene's illuminant (linear RGB): {np.round(illuminant, 4).tolist()}")
    print(f"{'picture':<38} {'exposure':>9} {'du_v_ from D65':>15}")
    result = {}
    for name, kw in PICTURES:
        codes, stops = display_image(image, scene.render.colourspace, illuminant=illuminant, **kw)
        result[name] = distance(codes, mask)
        print(f"{name:<38} {stops:>+9.2f} {result[name]:>15.4f}")
    default = result[PICTURES[-1][0]]
    result["passed"] = default <= REQUIRED
    print(f"requirement: the default picture's sunlit top within {REQUIRED} of D65: "
          f"{default:.4f} -> {'pass' if result['passed'] else 'FAIL'}")
    return result


if __name__ == "__main__":
    run_main(main)
