"""A quick look at a scene from its own camera: every surface's isosurface F = T, opaque, in its colour, and
every medium's F = T as a faint translucent shell, lit by the scene's directional lights (pyvista, off screen).

Not the renderer: marching cubes on a sampled grid (``cloudmeta.api.viewer.sample_grid``), VTK's own shading,
no shadows, no scattering. It is for framing and shapes: does the camera show the whole object, is the
isosurface smooth and in one piece, does a hand have five fingers. Seconds per scene on two cores.

    python scenes/preview.py scenes/hand.yaml docs/preview_hand.png [--resolution 160] [--width 640]

The picture has the scene's aspect ratio and vertical field of view; --width sets its width in pixels
(default the scene's image width).
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))  # the repository's cloudmeta

from cloudmeta import load_scene  # noqa: E402
from cloudmeta.api.viewer import _prepare_off_screen, sample_grid  # noqa: E402
from cloudmeta.scene import DirectionalLight  # noqa: E402


def _display(rgb):
    """Linear RGB to the [0, 1] display colour VTK wants (sRGB-ish gamma, clipped)."""
    return tuple(np.clip(np.asarray(rgb, dtype=float), 0.0, 1.0) ** (1 / 2.2))


def isosurface(blob, resolution):
    """The mesh of F = T of ``blob`` (a pyvista.PolyData), or None where F never reaches T."""
    grid = sample_grid(blob, resolution)
    values = grid.point_data["field"]
    if not values.min() < blob.threshold <= values.max():
        return None
    mesh = grid.contour([blob.threshold], scalars="field")
    return mesh if mesh.n_points else None


def preview(scene_path, png, resolution=160, width=None):
    import pyvista as pv

    scene = load_scene(scene_path)
    w = width or scene.image.width
    h = max(1, round(w * scene.image.height / scene.image.width))
    _prepare_off_screen()
    plotter = pv.Plotter(off_screen=True, window_size=(w, h), lighting="none")
    top = _display(scene.background)
    plotter.set_background(top)
    summary = []
    for surface in scene.surfaces:
        mesh = isosurface(surface.blob, resolution)
        if mesh is not None:
            plotter.add_mesh(mesh, color=_display(surface.color), smooth_shading=True, specular=0.1)
            parts = mesh.connectivity().point_data["RegionId"].max() + 1
            summary.append(f"surface {surface.name}: {len(surface.blob)} balls, {parts} connected piece(s)")
    for medium in scene.media:
        mesh = isosurface(medium.blob, max(48, resolution // 2))
        if mesh is not None:
            plotter.add_mesh(mesh, color=(0.95, 0.95, 1.0), opacity=0.35, smooth_shading=True)
            summary.append(f"medium {medium.name}: {len(medium.blob)} balls")
    for light in scene.lights:
        if isinstance(light, DirectionalLight):
            vtk_light = pv.Light(light_type="scene light", intensity=0.9)
            vtk_light.positional = False
            vtk_light.position = tuple(light.direction)
            vtk_light.focal_point = (0.0, 0.0, 0.0)
            plotter.add_light(vtk_light)
    fill = pv.Light(light_type="headlight", intensity=0.25)
    plotter.add_light(fill)
    cam = scene.camera
    plotter.camera.position = tuple(cam.position)
    plotter.camera.focal_point = tuple(cam.look_at)
    plotter.camera.up = tuple(cam.up)
    plotter.camera.view_angle = cam.fov
    plotter.reset_camera_clipping_range()
    plotter.screenshot(png)
    plotter.close()
    return summary


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scene")
    parser.add_argument("png")
    parser.add_argument("--resolution", type=int, default=160, help="grid samples along each blob's longest side")
    parser.add_argument("--width", type=int, help="picture width in pixels (default: the scene's)")
    args = parser.parse_args(argv)
    for line in preview(args.scene, args.png, args.resolution, args.width):
        print(line)
    print(f"wrote {args.png}")


if __name__ == "__main__":
    main()
