"""Look at a scene in 3D: its field F and density sigma_t on a grid, with pyvista (``cloudmeta inspect``).

``sample_grid`` samples F (and sigma_t, docs/model.md §4) on a regular grid and returns a ``pyvista.ImageData``
that ParaView also reads (``--save grid.vti``). The grid sampler culls: each sample visits only the balls
whose support boxes share its cell (``kernels/grid.py``), and its values equal ``cloudmeta.field`` at the
same points.

``inspect_command`` draws three orthogonal slices of sigma_t (movable with widgets in a window), the
isosurface F = T of every blob, the ball centres, the camera frustum and the lights; ``--slice z=2.0``
draws one plane instead, coloured by sigma_t with the contour F = T on it. Above BALLS_AS_SPRITES balls the
centres are a sample of small dots and F = T is drawn as lines on the slices, so that the slices stay
visible (``--balls``). ``--grid GRID`` draws a layer of a voxel grid, the scene's sigma_t at the same voxel
centres and their difference side by side (``compare_slice``, ``draw_compare``; docs/inspect.md).

Off screen (``--screenshot``) no display and no X server (nor Xvfb) is needed. VTK's Linux wheels (9.4
and later) choose an OpenGL window at run time: X when ``DISPLAY`` is set, else EGL, else OSMesa. EGL
needs the system's ``libEGL.so.1`` and Mesa's EGL driver with its software rasteriser (Debian/Ubuntu:
``libegl1``, ``libegl-mesa0``, ``libgl1-mesa-dri``; installed on this project's Debian 12 machines); OSMesa
needs ``libOSMesa.so.8`` (``libosmesa6``). With no display and a libEGL on the system, this module asks
VTK for EGL at once (``VTK_DEFAULT_OPENGL_WINDOW=vtkEGLRenderWindow``, unless the variable is already
set), so that VTK does not try X first and print "bad X server connection".
"""
from __future__ import annotations

import ctypes.util
import os
import sys
from pathlib import Path

import numpy as np

from .io import atomic_output
from .rays import blob_record
from ..errors import InputError
from ..kernels.density import rho_value
from ..kernels.grid import bin_balls, sample_field
from ..kernels.kinds import DENSITY_MODES
from ..kernels.records import CellGrid
from ..renderer.pack import camera_frame
from ..scene import DirectionalLight, PointLight, Scene, load_scene
from ..scene.blob import Blob

#: default bounds: the bounding box grown by this fraction of its longest side on every side
PAD = 0.05
#: largest accepted ``resolution`` (a 1024^3 grid is 8 GiB per array already)
MAX_RESOLUTION = 1024
#: the cull grid has at most this many cells in all, and at most CULL_AXIS_CELLS along one axis
CULL_MAX_CELLS = 1 << 21
CULL_AXIS_CELLS = 256
#: a ``--slice`` plane is 2D, so it is sampled this many times finer than the 3D grid
SLICE_REFINE = 4
SIGMA_TITLE = "sigma_t [1/length]"
FIELD_TITLE = "F"
CMAP = "viridis"
WINDOW_SIZE = (1200, 900)
#: the 3D view's direction, in the scene camera's frame (right + BEYOND forward + ABOVE up), and the part
#: of the picture (width, height) that what is drawn fills, clear of the legend and the scalar bar
VIEW_BEYOND, VIEW_ABOVE, VIEW_FILL = 0.5, 0.6, (0.74, 0.84)
#: opacity of the 3D slices where sigma_t = 0 (1 where it is above 1/64 of its maximum)
SLICE_EMPTY_OPACITY = 0.25
#: colours of the media's isosurfaces F = T, in scene order (a surface is drawn in its own colour)
ISO_COLOURS = ((0.55, 0.8, 1.0), (1.0, 0.6, 0.85), (0.7, 1.0, 0.6), (1.0, 0.95, 0.55))
SCREENSHOT_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff")
#: ``--balls``: how the ball centres are drawn. ``auto`` draws them all as round sprites up to BALLS_AS_SPRITES
#: balls and as ``points`` above: small flat dots, at most POINTS_MAX of them (every k-th ball), half
#: transparent, so that thousands of centres do not hide the density slices they stand in
BALL_MODES = ("auto", "all", "points", "none")
BALLS_AS_SPRITES = 500
POINTS_MAX = 1000
POINT_SIZE, POINT_OPACITY = 2.0, 0.4
#: with many balls the colour map of sigma_t ends at this quantile of its non-zero values
CLIM_QUANTILE = 0.98
#: the grid | fit | difference view: picture size and the diverging colour map of the difference
COMPARE_WINDOW = (1800, 680)
DIFF_CMAP = "RdBu_r"
DIFF_FLOOR = 1e-6
#: voxels of empty margin kept around the cloud in the grid | fit | difference panels
COMPARE_MARGIN = 3


# ------------------------------------------------------------------------------------------- sampling

def _cull_cells(blob):
    """(cell_origin, cell_size, cell_dims, pad) of the cull grid over ``blob``'s bounding box.

    Cells are about the size of a typical ball (the median support box), so a cell lists few balls; the
    total count is capped, so that a few balls far apart do not ask for a huge, empty cell grid.
    """
    lo, hi = blob.bbox
    extent = hi - lo
    sizes = (blob.bounds[:, 3:] - blob.bounds[:, :3]).max(axis=1)
    cell = max(float(np.median(sizes)), float(extent.max()) / CULL_AXIS_CELLS,
               float(np.prod(extent) / CULL_MAX_CELLS) ** (1.0 / 3.0))
    dims = np.clip(np.ceil(extent / cell), 1, CULL_AXIS_CELLS).astype(np.int64)
    while np.prod(dims) > CULL_MAX_CELLS:  # rounding up each side can overshoot the cap a little
        cell *= 1.05
        dims = np.clip(np.ceil(extent / cell), 1, CULL_AXIS_CELLS).astype(np.int64)
    # absorbs rounding in the support boxes: a ball is binned into every cell its support could touch
    pad = 1e-9 * (float(np.abs(blob.bounds).max()) + blob.diagonal)
    return np.ascontiguousarray(lo, dtype=np.float64), cell, dims, pad


def _field_on_grid(blob, origin, spacing, dims):
    """Flat F (x fastest) on the grid origin + (i, j, k) * spacing, (i, j, k) < dims."""
    cell_origin, cell_size, cell_dims, pad = _cull_cells(blob)
    cell_start, cell_items = bin_balls(blob.bounds, pad, cell_origin, cell_size, cell_dims)
    out = np.empty(int(np.prod(dims)))
    sample_field(origin, spacing, dims, blob_record(blob),
                 CellGrid(cell_origin, cell_size, cell_dims, cell_start, cell_items), out)
    return out


def sigma_t(medium, field):
    """sigma_t = scale * rho of a scene medium (docs/model.md §4) from its field values: 0 where F < T. rho is
    the kernels' own formula (kernels.density.rho_value, run here by Python on the arrays)."""
    t = medium.blob.threshold
    rho = rho_value.py_func(field, DENSITY_MODES[medium.density.mode], t)
    return np.where(field >= t, medium.density.scale * rho, 0.0)


def field_names(scene_or_blob):
    """[(array name, blob, medium or None)] of what ``sample_grid`` samples, in its order.

    A Blob gives ``field``. A scene's one medium gives ``field``; several give ``field:NAME``; each surface
    gives ``field:NAME`` (``field:surface:NAME`` if a medium already has that name).
    """
    if isinstance(scene_or_blob, Blob):
        return [("field", scene_or_blob, None)]
    media = scene_or_blob.media
    out = [("field" if len(media) == 1 else f"field:{m.name}", m.blob, m) for m in media]
    taken = {name for name, _, _ in out}
    for s in scene_or_blob.surfaces:
        name = f"field:{s.name}"
        out.append((f"field:surface:{s.name}" if name in taken else name, s.blob, None))
    return out


def _check_resolution(resolution):
    if not (isinstance(resolution, (int, np.integer)) and not isinstance(resolution, (bool, np.bool_))
            and 2 <= resolution <= MAX_RESOLUTION):
        raise InputError(f"resolution: expected an integer in [2, {MAX_RESOLUTION}] (samples along the longest "
                         f"side), got {resolution!r}")
    return int(resolution)


def _check_bounds(bounds):
    """(lo, hi) from ``(lo, hi)`` (shape (2, 3)) or pyvista's (xmin, xmax, ymin, ymax, zmin, zmax)."""
    try:
        b = np.array(bounds, dtype=np.float64)
    except (TypeError, ValueError):
        b = None
    if b is None or b.shape not in ((2, 3), (6,)) or not np.all(np.isfinite(b)):
        raise InputError(f"bounds: expected (lo, hi) with lo, hi 3 finite numbers each, or 6 finite numbers "
                         f"(xmin, xmax, ymin, ymax, zmin, zmax), got {bounds!r}")
    lo, hi = (b[0], b[1]) if b.shape == (2, 3) else (b[0::2], b[1::2])
    if not np.all(hi > lo):
        raise InputError(f"bounds: expected hi > lo on every axis, got lo = {lo.tolist()}, hi = {hi.tolist()}")
    return lo, hi


def _default_bounds(scene_or_blob):
    """The box of the inside (Blob.inside_bbox: carving balls outside it are left out), padded."""
    blobs = [scene_or_blob] if isinstance(scene_or_blob, Blob) else [
        thing.blob for thing in scene_or_blob.media + scene_or_blob.surfaces]
    boxes = [blob.inside_bbox() for blob in blobs]
    lo, hi = np.min([b for b, _ in boxes], axis=0), np.max([b for _, b in boxes], axis=0)
    pad = PAD * float((hi - lo).max())
    return lo - pad, hi + pad


def _geometry(lo, hi, resolution, min_dim):
    """origin, spacing (3,) and dims (3,) int64 of a grid with equal spacing on every axis, ``resolution``
    samples along the longest side, covering [lo, hi] and centred on it; an axis with lo == hi gets
    ``min_dim`` samples (1 for a plane)."""
    extent = hi - lo
    h = float(extent.max()) / (resolution - 1)
    # the 1e-9 keeps rounding from adding a sample to the longest side, where extent / h = resolution - 1
    dims = np.maximum(np.ceil(extent / h - 1e-9).astype(np.int64) + 1, min_dim)
    dims[int(np.argmax(extent))] = resolution
    origin = 0.5 * (lo + hi) - 0.5 * (dims - 1) * h
    return origin, np.full(3, h), dims


def _sample(scene_or_blob, origin, spacing, dims):
    import pyvista as pv

    grid = pv.ImageData(dimensions=tuple(int(d) for d in dims), spacing=tuple(spacing), origin=tuple(origin))
    sigmas = []
    for name, blob, medium in field_names(scene_or_blob):
        values = _field_on_grid(blob, origin, spacing, dims)
        grid.point_data[name] = values
        grid.field_data[f"threshold:{name}"] = [blob.threshold]
        if medium is not None:
            sigmas.append((medium.name, sigma_t(medium, values)))
    if len(sigmas) == 1:
        grid.point_data["sigma_t"] = sigmas[0][1]
    elif sigmas:
        for name, values in sigmas:
            grid.point_data[f"sigma_t:{name}"] = values
        grid.point_data["sigma_t"] = np.sum([v for _, v in sigmas], axis=0)
    if sigmas:
        grid.set_active_scalars("sigma_t")
    return grid


def sample_grid(scene_or_blob, resolution=96, bounds=None):
    """The field (and, for a scene, sigma_t) on a regular grid, as a ``pyvista.ImageData``.

    Parameters
    ----------
    scene_or_blob : a ``Blob`` or a ``Scene`` (from ``load_scene``).
    resolution : samples along the longest side of ``bounds`` (>= 2); the spacing is the same on every
        axis, and the other sides get as many samples as cover them (the grid is centred on the bounds).
    bounds : ``(lo, hi)`` or pyvista's ``(xmin, xmax, ymin, ymax, zmin, zmax)``, in scene units; default
        the bounding box of every ball's support, grown by 5 % of its longest side.

    Point arrays (x fastest, pyvista's order): for a Blob, ``field``. For a scene: each medium's ``field``
    and ``sigma_t`` (scale * rho where F >= T, else 0; docs/model.md §4), named exactly so when there is one
    medium, ``field:NAME`` and ``sigma_t:NAME`` with several, plus their sum ``sigma_t``; each surface's
    ``field:NAME``. ``field_data["threshold:ARRAY"]`` holds the threshold T of each field array, so that a
    saved grid can draw F = T on its own (in ParaView too).
    """
    if not isinstance(scene_or_blob, (Blob, Scene)):
        raise InputError(f"scene_or_blob: expected a cloudmeta.Blob or a Scene from load_scene, "
                         f"got {type(scene_or_blob).__name__}")
    resolution = _check_resolution(resolution)
    lo, hi = _default_bounds(scene_or_blob) if bounds is None else _check_bounds(bounds)
    return _sample(scene_or_blob, *_geometry(lo, hi, resolution, 2))


# ----------------------------------------------------------------------------------------- off screen

def _has_display():
    if not sys.platform.startswith("linux"):
        return True  # macOS and Windows always have a window system
    return bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))


def _prepare_off_screen():
    """Render without a window; with no X display, go straight to EGL when the system has libEGL."""
    import pyvista as pv

    pv.OFF_SCREEN = True
    if not _has_display() and ctypes.util.find_library("EGL"):
        os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")


# -------------------------------------------------------------------------------------------- drawing

def _display_colour(rgb, fallback=(1.0, 0.85, 0.4)):
    """A linear RGB (light or surface colour) scaled into [0, 1] for a glyph: hue kept, brightest = 1."""
    rgb = np.asarray(rgb, dtype=np.float64)
    top = float(rgb.max()) if rgb.size else 0.0
    return tuple(np.clip(rgb / top, 0.0, 1.0)) if top > 0 else fallback


def _camera_frustum(camera, width, height, distance):
    """PolyData lines: from the eye to the 4 corners of the image plane at ``distance``, the plane's
    rectangle, and a small triangle on its top edge that shows which way is up."""
    import pyvista as pv

    forward, right, up = camera_frame(camera)
    half_h = distance * np.tan(np.radians(camera.fov) / 2.0)
    half_w = half_h * width / height
    centre = camera.position + distance * forward
    corners = [centre + sx * half_w * right + sy * half_h * up for sx, sy in ((-1, 1), (1, 1), (1, -1), (-1, -1))]
    top = [centre + (-0.3 * half_w) * right + half_h * up, centre + 0.3 * half_w * right + half_h * up,
           centre + 1.3 * half_h * up]
    points = np.array([camera.position] + corners + top)
    lines = [2, 0, 1, 2, 0, 2, 2, 0, 3, 2, 0, 4, 5, 1, 2, 3, 4, 1, 4, 5, 6, 7, 5]
    return pv.PolyData(points, lines=np.array(lines))


def _contour(mesh, name, threshold):
    """The contour F = T of array ``name`` (surfaces in 3D, lines on a plane), or None where F never
    reaches T."""
    data = mesh.point_data[name]
    if not (data.min() < threshold <= data.max()):
        return None
    iso = mesh.contour([threshold], scalars=name)
    return iso if iso.n_points else None


def _density_array(grid):
    """(array name, scalar bar title): sigma_t, or with no medium the first field."""
    if "sigma_t" in grid.point_data:
        return "sigma_t", SIGMA_TITLE
    return grid.point_data.keys()[0], FIELD_TITLE


def _scalar_range(values):
    top = float(np.max(values)) if values.size else 0.0
    low = min(0.0, float(np.min(values))) if values.size else 0.0
    return [low, top if top > low else low + 1.0]


def _bar(title):
    return dict(title=title, color="white", title_font_size=20, label_font_size=16, fmt="%.3g",
                vertical=True, position_x=0.88, position_y=0.25, height=0.5, width=0.06)


def _things(scene):
    """[(array name, blob, label, colour, opacity)] of the isosurfaces to draw."""
    colours = {id(s.blob): s.color for s in scene.surfaces}
    out = []
    for name, blob, medium in field_names(scene):
        if medium is not None:
            colour = ISO_COLOURS[len(out) % len(ISO_COLOURS)]
            out.append((name, blob, f"F = T ({medium.name})", colour, 0.45))
        else:
            surface = next(s for s in scene.surfaces if s.blob is blob)
            out.append((name, blob, f"F = T ({surface.name}, surface)", _display_colour(colours[id(blob)]), 0.7))
    return out


def _corners(mesh):
    """(8, 3) corners of a mesh's bounding box."""
    b = mesh.bounds
    return np.array([[x, y, z] for x in b[0:2] for y in b[2:4] for z in b[4:6]])


def _fit_view(plotter, points, towards_viewer, up, fill=VIEW_FILL):
    """Point the plotter's camera along -``towards_viewer`` and move it as close as it can be with every
    one of ``points`` inside the central ``fill`` (width, height) of the picture; tighter than
    ``reset_camera``, which fits a bounding sphere, and clear of the legend and the scalar bar."""
    d = towards_viewer / np.linalg.norm(towards_viewer)
    u = up - np.dot(up, d) * d
    u /= np.linalg.norm(u)
    r = np.cross(-d, u)
    p = np.asarray(points) - points.mean(axis=0)
    x, y, z = p @ r, p @ u, p @ d
    cx, cy = 0.5 * (x.min() + x.max()), 0.5 * (y.min() + y.max())
    focal = points.mean(axis=0) + cx * r + cy * u
    width, height = plotter.window_size
    tan_y = np.tan(np.radians(plotter.camera.view_angle) / 2.0)
    tan_x = tan_y * width / height
    dist = float(np.max(z + np.maximum(np.abs(x - cx) / (tan_x * fill[0]), np.abs(y - cy) / (tan_y * fill[1]))))
    plotter.camera.position = tuple(focal + dist * d)
    plotter.camera.focal_point = tuple(focal)
    plotter.camera.up = tuple(u)
    plotter.reset_camera_clipping_range()


def _ball_mode(scene, balls):
    """(mode, ball count) with ``auto`` resolved: ``all`` up to BALLS_AS_SPRITES balls, else ``points``."""
    if balls not in BALL_MODES:
        raise InputError(f"--balls: expected one of {', '.join(BALL_MODES)}, got {balls!r}")
    count = sum(len(blob.weights) for _, blob, _ in field_names(scene))
    if balls == "auto":
        balls = "all" if count <= BALLS_AS_SPRITES else "points"
    return balls, count


def _draw_centres(plotter, blob, mode, labels):
    """The centres of ``blob`` (white; carving balls red): every one as a round sprite (``all``), or at
    most POINTS_MAX of them as small translucent dots (``points``). Never a mesh per ball."""
    import pyvista as pv

    n = len(blob.weights)
    step = 1 if mode == "all" else max(1, -(-n // POINTS_MAX))
    keep = np.zeros(n, dtype=bool)
    keep[::step] = True
    positive = blob.weights >= 0
    for mask, colour, what in ((positive, "white", "ball centres"), (~positive, "red", "carving centres")):
        mask = mask & keep
        if not mask.any():
            continue
        label = what if step == 1 else f"{what} (1 in {step})"
        points = pv.PolyData(np.ascontiguousarray(blob.centers[mask]))
        if mode == "all":
            style = dict(point_size=7, render_points_as_spheres=True)
        else:
            style = dict(point_size=POINT_SIZE, render_points_as_spheres=False, opacity=POINT_OPACITY)
        plotter.add_mesh(points, color=colour, style="points", show_scalar_bar=False,
                         label=None if label in labels else label, name=f"centres:{len(labels)}:{what}", **style)
        labels.add(label)


def _moving_contours(plotter, actors, name, threshold, colour, label):
    """F = T as lines on each slice that a widget moves: a contour filter fed by the slice's cutter, so that
    the lines follow the slice. The slices' polygons are pushed back in depth a little, so that lines lying
    in them are not covered (the viewer turns, so a fixed lift towards it would not do)."""
    from vtkmodules.vtkFiltersCore import vtkContourFilter
    from vtkmodules.vtkCommonDataModel import vtkDataObject

    for k, actor in enumerate(actors):
        mapper = actor.GetMapper()
        mapper.SetResolveCoincidentTopologyToPolygonOffset()
        mapper.SetRelativeCoincidentTopologyPolygonOffsetParameters(2.0, 4.0)
        contour = vtkContourFilter()
        contour.SetInputConnection(mapper.GetInputConnection(0, 0))
        contour.SetInputArrayToProcess(0, 0, 0, vtkDataObject.FIELD_ASSOCIATION_POINTS, name)
        contour.SetValue(0, float(threshold))
        contour.ComputeScalarsOff()
        plotter.add_mesh(contour, color=colour, line_width=1.5, show_scalar_bar=False,
                         label=label if k == 0 else None)


def draw_volume(plotter, scene, grid, widgets, balls="auto"):
    """Slices of sigma_t (with slice widgets when ``widgets``), each blob's F = T, the ball centres, the
    camera frustum and the lights, on ``plotter``. ``balls`` (BALL_MODES) says how the centres are drawn."""
    import pyvista as pv

    balls, count = _ball_mode(scene, balls)
    many = count > BALLS_AS_SPRITES
    scalars, title = _density_array(grid)
    clim = _scalar_range(grid.point_data[scalars])
    if many:  # a few peaks where thousands of balls overlap would leave the rest of the map dark
        values = np.asarray(grid.point_data[scalars])
        inside = values[values > 0]
        if inside.size:
            clim[1] = max(float(np.quantile(inside, CLIM_QUANTILE)), clim[0] + 1e-12)
    # where sigma_t = 0 the slices are almost clear, so that they do not hide the isosurfaces behind them
    opacity = np.r_[SLICE_EMPTY_OPACITY, np.full(63, 1.0)]
    style = dict(scalars=scalars, cmap=CMAP, clim=clim, opacity=opacity, scalar_bar_args=_bar(title))
    slices = []
    if widgets:
        moving = plotter.add_mesh_slice_orthogonal(grid, **style)
    else:
        for normal in "xyz":  # one mesh each: a MultiBlock takes no opacity transfer function
            slices.append(grid.slice(normal=normal, origin=grid.center))
            plotter.add_mesh(slices[-1], **style)
    plotter.add_mesh(grid.outline(), color="gray", line_width=1)
    fit = [_corners(grid)]

    centre_labels = set()
    for name, blob, label, colour, opacity in _things(scene):
        if many:
            # thousands of balls crumple F = T into layers that hide the slices even when faint: drawn as
            # its contour lines on the (fixed) slices instead
            forward, right, up = camera_frame(scene.camera)
            towards_viewer = right + VIEW_BEYOND * forward + VIEW_ABOVE * up
            diagonal = float(np.linalg.norm(np.ptp(np.array(grid.bounds).reshape(3, 2), axis=1)))
            if widgets:
                _moving_contours(plotter, moving, name, blob.threshold, colour, label)
            for k, piece in enumerate(slices):
                lines = _contour(piece, name, blob.threshold)
                if lines is not None:
                    # lifted a hair off the slice towards the viewer: the slice, drawn after them as
                    # translucent, would cover lines that lie in it
                    lift = np.zeros(3)
                    lift[k] = (1.0 if towards_viewer[k] >= 0 else -1.0) * 2e-3 * diagonal
                    plotter.add_mesh(lines.translate(lift, inplace=False), color=colour, line_width=1.5,
                                     show_scalar_bar=False, label=label if k == 0 else None)
        else:
            iso = _contour(grid, name, blob.threshold)
            if iso is not None:
                plotter.add_mesh(iso, color=colour, opacity=opacity, smooth_shading=True, label=label,
                                 show_scalar_bar=False)
        if balls != "none":
            _draw_centres(plotter, blob, balls, centre_labels)

    lo, hi = np.array(grid.bounds[0::2]), np.array(grid.bounds[1::2])
    centre, diagonal = 0.5 * (lo + hi), float(np.linalg.norm(hi - lo))
    cam = scene.camera
    forward, right, up = camera_frame(cam)
    distance = float(np.dot(centre - cam.position, forward))
    if distance <= 0.0:  # the scene is behind the camera: show the image plane at the look-at point
        distance = float(np.linalg.norm(cam.look_at - cam.position))
    frustum = _camera_frustum(cam, scene.image.width, scene.image.height, distance)
    plotter.add_mesh(frustum, color="orange", line_width=2, label="camera")
    if not many:  # with many balls the view fits the cloud, and the frustum runs out of it towards the eye
        fit.append(frustum.points)

    for k, light in enumerate(scene.lights):
        if isinstance(light, DirectionalLight):
            # an arrow from outside the scene, pointing the way the light travels (against ``direction``)
            length = 0.25 * diagonal
            start = centre + light.direction * (0.6 * diagonal + length)
            glyph = pv.Arrow(start=start, direction=-light.direction, scale=length, shaft_radius=0.03,
                             tip_radius=0.08, tip_length=0.3)
            colour = _display_colour(light.irradiance)
        elif isinstance(light, PointLight):
            glyph = pv.Sphere(radius=0.03 * diagonal, center=light.position)
            colour = _display_colour(light.intensity)
        else:  # a light kind this view does not know yet: nothing to draw
            continue
        plotter.add_mesh(glyph, color=colour, label="lights" if k == 0 else None, show_scalar_bar=False)
        fit.append(_corners(glyph))

    # with many balls the view is closer, and the light's arrow may stand in the upper left
    plotter.add_legend(bcolor=(0.1, 0.1, 0.12), border=True, size=(0.2, 0.16),
                       loc="lower right" if many else "upper left", face=None)
    plotter.show_axes()
    # seen from the scene camera's right, a little beyond the scene and above: the frustum runs across the
    # picture from the eye to the scene, and the slices face the viewer at an angle
    _fit_view(plotter, np.vstack(fit), right + VIEW_BEYOND * forward + VIEW_ABOVE * up, up)


def _parse_slice(text):
    axis, sep, value = str(text).partition("=")
    axis = axis.strip().lower()
    try:
        number = float(value)
    except ValueError:
        number = None
    if not sep or axis not in ("x", "y", "z") or number is None or not np.isfinite(number):
        raise InputError(f"--slice: expected AXIS=VALUE with AXIS one of x, y, z and VALUE a number in scene "
                         f"units (e.g. z=2.0), got {text!r}")
    return "xyz".index(axis), number


def draw_slice(plotter, scene, axis, value, resolution):
    """One plane ``axis`` = ``value`` sampled exactly (not interpolated from the 3D grid), coloured by sigma_t,
    with the contour F = T of every blob on it. Returns the plane (a pyvista.ImageData)."""
    lo, hi = _default_bounds(scene)
    if not lo[axis] <= value <= hi[axis]:
        raise InputError(f"--slice: {'xyz'[axis]}={value:g} is outside the scene, whose {'xyz'[axis]} runs "
                         f"from {lo[axis]:.4g} to {hi[axis]:.4g} (bounding box with 5 % margin)")
    lo, hi = lo.copy(), hi.copy()
    lo[axis] = hi[axis] = value
    plane = _sample(scene, *_geometry(lo, hi, resolution, 1))
    scalars, title = _density_array(plane)
    plotter.add_mesh(plane, scalars=scalars, cmap=CMAP, clim=_scalar_range(plane.point_data[scalars]),
                     scalar_bar_args=_bar(title))
    names = "xyz"
    (plotter.view_yz, plotter.view_xz, plotter.view_xy)[axis]()
    # contour lines lifted a hair towards the viewer, so that they are never hidden in the plane
    towards_viewer = np.array(plotter.camera.position) - np.array(plotter.camera.focal_point)
    lift = np.zeros(3)
    lift[axis] = np.sign(towards_viewer[axis]) * 1e-3 * float(np.linalg.norm(hi - lo))
    labelled = False
    for name, blob, label, colour, _ in _things(scene):
        iso = _contour(plane, name, blob.threshold)
        if iso is not None:
            plotter.add_mesh(iso.translate(lift, inplace=False), color=colour, line_width=3, label=label,
                             show_scalar_bar=False)
            labelled = True
    plotter.add_text(f"{names[axis]} = {value:g}", position="upper_edge", font_size=14, color="white")
    titles = {f"{c}title": f"{c} [length]" for c in names}
    plotter.show_bounds(bounds=plane.bounds, color="white", font_size=10, **titles)
    if labelled:
        plotter.add_legend(bcolor=(0.1, 0.1, 0.12), border=True, size=(0.25, 0.08), loc="lower left", face=None)
    plotter.reset_camera()
    return plane


# ------------------------------------------------------------------------------- grid | fit | difference

def compare_slice(scene, voxels, axis=2, value=None):
    """One layer of voxels of a ``VoxelGrid`` beside the scene's sigma_t at the same voxel centres.

    ``axis`` 0, 1, 2 (x, y, z); ``value`` a coordinate in the grid's box (default its middle), which picks
    the layer of voxels that holds it. The scene is sampled exactly at the layer's voxel centres (the culled
    sampler, as ``sample_grid``), so the two are compared point by point, with no interpolation.

    Returns a ``pyvista.ImageData`` one voxel thick with point arrays ``grid``, ``fit`` (the scene's total
    sigma_t) and ``difference`` (fit - grid), and field data ``layer`` (the layer's index), ``error`` (the
    slice's relative L2 error, |fit - grid| / |grid|, nan where the grid's slice is all zero) and
    ``position`` (the layer centre's coordinate along ``axis``).
    """
    if not scene.media:
        raise InputError("--grid: the scene has no medium, so it has no sigma_t to compare with the grid")
    lower, upper, h, n = voxels.lower, voxels.upper, voxels.voxel, voxels.shape
    if value is None:
        value = 0.5 * (lower[axis] + upper[axis])
    if not lower[axis] <= value <= upper[axis]:
        raise InputError(f"--slice: {'xyz'[axis]}={value:g} is outside the grid {voxels.source}, whose "
                         f"{'xyz'[axis]} runs from {lower[axis]:.4g} to {upper[axis]:.4g}")
    layer = int(np.clip(np.floor((value - lower[axis]) / h[axis]), 0, n[axis] - 1))
    origin = lower + 0.5 * h
    origin[axis] = lower[axis] + (layer + 0.5) * h[axis]
    dims = np.array(n, dtype=np.int64)
    dims[axis] = 1
    plane = _sample(scene, origin, h.astype(np.float64), dims)
    fit = np.asarray(plane.point_data["sigma_t"], dtype=np.float64)
    index = [slice(None)] * 3
    index[axis] = slice(layer, layer + 1)
    grid = voxels.density[tuple(index)].ravel(order="F")  # pyvista's order: x fastest
    for name in list(plane.point_data.keys()):
        del plane.point_data[name]
    diff = fit - grid
    plane.point_data["grid"] = grid
    plane.point_data["fit"] = fit
    plane.point_data["difference"] = diff
    norm = float(np.linalg.norm(grid))
    plane.field_data["error"] = [float(np.linalg.norm(diff)) / norm if norm > 0 else float("nan")]
    plane.field_data["layer"] = [layer]
    plane.field_data["position"] = [float(origin[axis])]
    return plane


def _panel_bar(title):
    return dict(title=title, color="white", title_font_size=8, label_font_size=13, fmt="%.3g",
                vertical=False, position_x=0.15, position_y=0.02, height=0.1, width=0.7)


def _nice_range(top, lowest_steps):
    """(end, labels): the least end >= ``top`` that is a whole number of steps (from ``lowest_steps`` to
    twice that) of 1, 2, 2.5 or 5 x 10^k, and the number of ticks from 0 to it, so that a colour bar's
    ticks fall on round numbers."""
    best = None
    k0 = int(np.floor(np.log10(top)))
    for k in range(k0 - 2, k0 + 2):
        for m in (1.0, 2.0, 2.5, 5.0):
            step = m * 10.0 ** k
            steps = int(np.ceil(top / step * (1 - 1e-9)))
            if lowest_steps <= steps <= 2 * lowest_steps and (best is None or steps * step < best[0]):
                best = (steps * step, steps + 1)
    return best if best is not None else (top, lowest_steps + 1)


def _occupied(plane, axis, margin=COMPARE_MARGIN):
    """The part of ``plane`` where the grid or the fit is non-zero, grown by ``margin`` voxels (the whole
    plane where both are zero), so that the panels show the cloud rather than the empty box around it."""
    dims = np.array(plane.dimensions)
    full = tuple(dims.astype(int))
    busy = ((plane.point_data["grid"] > 0) | (plane.point_data["fit"] > 0)).reshape(full[::-1]).T
    if not busy.any():
        return plane
    voi = []
    for a in range(3):
        if dims[a] == 1:
            voi += [0, 0]
            continue
        other = tuple(b for b in range(3) if b != a)
        hit = np.nonzero(busy.any(axis=other))[0]
        voi += [max(0, int(hit[0]) - margin), min(int(dims[a]) - 1, int(hit[-1]) + margin)]
    return plane.extract_subset(voi)  # keeps the point arrays


def draw_compare(plotter, plane, axis, grid_label, fit_label):
    """Three panels on a 1 x 3 ``plotter``: the grid's slice, the fit's, and fit - grid (a diverging map,
    its range symmetric about 0), each seen straight along ``axis``, the same extent in each: the part of
    the layer that holds the cloud (the error in the title is the whole layer's)."""
    grid, fit, diff = (plane.point_data[k] for k in ("grid", "fit", "difference"))
    top = max(float(grid.max()), float(fit.max()))
    top = top if top > 0 else 1.0
    # differences below DIFF_FLOOR of the peak are rounding (the sampler agrees with cloudmeta.field to
    # ~1e-12): they stay white instead of being stretched over the whole map
    spread = max(float(np.abs(diff).max()), DIFF_FLOOR * top)
    top, top_labels = _nice_range(top, 4)
    spread, half_labels = _nice_range(spread, 2)
    plane = _occupied(plane, axis)
    error = float(plane.field_data["error"][0])
    where = f"{'xyz'[axis]} = {float(plane.field_data['position'][0]):.4g}"
    panels = (
        ("grid", f"sigma_t [1/length] at {where}", CMAP, [0.0, top], f"grid: {grid_label}"),
        ("fit", f"sigma_t [1/length] at {where}", CMAP, [0.0, top], f"fit: {fit_label}"),
        ("difference", f"fit - grid [1/length] at {where}", DIFF_CMAP, [-spread, spread],
         f"slice relative L2 error {error:.3g}"),
    )
    names = "xyz"
    titles = {f"{c}title": f"{c} [length]" for c in names if c != names[axis]}
    titles[f"show_{names[axis]}axis"] = False  # the plane is seen edge-on along its normal
    for column, (array, bar, cmap, clim, text) in enumerate(panels):
        plotter.subplot(0, column)
        # unlit, so that the colours are the map's (the difference's 0 is white, not shaded grey)
        # the bar's title (blank, one per panel: pyvista keys bars by title) would sit on its numbers; the
        # quantity and unit are in the panel's title instead
        bar_args = _panel_bar(" " * (column + 1))
        bar_args["n_labels"] = top_labels if column < 2 else 2 * half_labels - 1
        plotter.add_mesh(plane.copy(), scalars=array, cmap=cmap, clim=clim, lighting=False,
                         scalar_bar_args=bar_args)
        plotter.add_text(f"{text}\n{bar}", position="upper_edge", font_size=11, color="white")
        plotter.show_bounds(bounds=plane.bounds, color="white", font_size=9, location="outer", **titles)
        (plotter.view_yz, plotter.view_xz, plotter.view_xy)[axis]()
        plotter.reset_camera()
        plotter.camera.zoom(1.05)
        # the plane a little above the panel's middle: clear of the colour bar below it
        cam = plotter.camera
        lift = -0.07 * float(np.ptp(np.array(plane.bounds).reshape(3, 2), axis=1).max()) * np.array(cam.up)
        cam.position = tuple(np.array(cam.position) + lift)
        cam.focal_point = tuple(np.array(cam.focal_point) + lift)
    plotter.link_views()


# -------------------------------------------------------------------------------------------- command

def _check_output(option, path, suffixes):
    p = Path(path)
    if p.suffix.lower() not in suffixes:
        raise InputError(f"{option}: expected a path ending in {' or '.join(suffixes)}, got {path!r}")
    if not p.parent.is_dir() and str(p.parent) != "":
        raise InputError(f"{option}: the folder {str(p.parent)!r} does not exist")
    return str(p)


def _describe_grid(grid):
    nx, ny, nz = grid.dimensions
    return f"{nx} x {ny} x {nz} samples, spacing {grid.spacing[0]:.4g}"


def inspect_command(args):
    """``cloudmeta inspect SCENE [--screenshot PNG] [--save VTI] [--resolution N] [--slice AXIS=VALUE]
    [--balls auto|all|points|none] [--grid GRID [--var NAME]]``.

    With --screenshot the picture is rendered off screen and written there (no window, no display needed).
    Without it a window opens; where there is no display, --save alone writes the grid and opens nothing.
    --slice samples its plane SLICE_REFINE times finer than --resolution asks for the 3D grid.
    With --grid: three panels, a layer of the grid's voxels, the scene's sigma_t at the same voxel centres and
    their difference (``compare_slice``); --slice picks the layer (default the middle of the box along z),
    --save writes that layer's three arrays, and --resolution is not used.
    """
    scene = load_scene(args.scene)
    resolution = _check_resolution(args.resolution)
    screenshot = _check_output("--screenshot", args.screenshot, SCREENSHOT_SUFFIXES) if args.screenshot else None
    save = _check_output("--save", args.save, (".vti",)) if args.save else None
    plane = _parse_slice(args.slice) if args.slice is not None else None
    balls = getattr(args, "balls", None) or "auto"
    _ball_mode(scene, balls)
    grid_path, variable = getattr(args, "grid", None), getattr(args, "var", None)
    if variable is not None and grid_path is None:
        raise InputError("--var: names a variable of --grid GRID, which is not given")
    window = screenshot is None
    if window and not _has_display():
        if save is None:
            raise InputError("there is no display to open a window on (DISPLAY is not set): give --screenshot "
                             "PATH.png to render off screen, or --save PATH.vti to write the grid")
        window = False
    if grid_path is not None:
        return _inspect_against_grid(args, scene, grid_path, variable, plane, screenshot, save, window)

    grid = None
    if plane is None or save is not None:
        grid = sample_grid(scene, resolution)
        print(f"cloudmeta: sampled {args.scene}: {_describe_grid(grid)}")
    if save is not None:
        _save(grid, save)
    if not window and screenshot is None:
        return 0

    plotter = _plotter(screenshot, window_size=WINDOW_SIZE)
    plotter.set_background((0.08, 0.09, 0.12), top=(0.30, 0.34, 0.42))
    try:
        if plane is not None:
            axis, value = plane
            sampled = draw_slice(plotter, scene, axis, value, SLICE_REFINE * resolution)
            nx, ny, nz = sampled.dimensions
            print(f"cloudmeta: slice {'xyz'[axis]}={value:g}: {nx * ny * nz} samples, spacing "
                  f"{sampled.spacing[0]:.4g}")
        else:
            draw_volume(plotter, scene, grid, widgets=screenshot is None, balls=balls)
        _show(plotter, screenshot, f"cloudmeta inspect {args.scene}")
    finally:
        plotter.close()
    return 0


def _plotter(screenshot, **options):
    """A pyvista plotter: off screen when the view goes to a ``screenshot`` file."""
    import pyvista as pv

    if screenshot is not None:
        _prepare_off_screen()
    return pv.Plotter(off_screen=screenshot is not None, **options)


def _show(plotter, screenshot, title):
    """The view in a window, or its picture written atomically to ``screenshot`` (off screen)."""
    if screenshot is None:
        plotter.show(title=title)
        return
    with atomic_output(screenshot) as tmp:
        plotter.screenshot(tmp)
    print(f"cloudmeta: wrote {screenshot}")


def _save(data, path):
    """Write a pyvista dataset atomically (``--save``) and say which arrays it holds."""
    with atomic_output(path) as tmp:
        data.save(tmp)
    print(f"cloudmeta: wrote {path} (arrays: {', '.join(data.point_data.keys())})")


def _inspect_against_grid(args, scene, grid_path, variable, plane, screenshot, save, window):
    """``inspect SCENE --grid GRID``: the grid | fit | difference panels of one layer of voxels."""
    from ..fit import read_grid
    from .io import same_file

    for label, path in (("--screenshot", screenshot), ("--save", save)):
        if path and same_file(os.path.abspath(path), os.path.abspath(grid_path)):
            raise InputError(f"{label} {path}: is the grid --grid reads; refusing to overwrite it")
    voxels = read_grid(grid_path, variable=variable)
    axis, value = plane if plane is not None else (2, None)
    compared = compare_slice(scene, voxels, axis, value)
    error = float(compared.field_data["error"][0])
    nx, ny, nz = voxels.shape
    layer = int(compared.field_data["layer"][0])
    print(f"cloudmeta: {grid_path} ({nx} x {ny} x {nz} voxels) against {args.scene}: layer {layer} of "
          f"{voxels.shape[axis]} ({'xyz'[axis]} = {float(compared.field_data['position'][0]):.4g}), slice relative "
          f"L2 error {error:.4f}")
    if save is not None:
        _save(compared, save)
    if not window and screenshot is None:
        return 0
    plotter = _plotter(screenshot, shape=(1, 3), window_size=COMPARE_WINDOW, border=False)
    count = sum(len(m.blob.weights) for m in scene.media)
    grid_label = Path(grid_path).name + (f" ({voxels.variable})" if voxels.variable else "")
    try:
        for column in range(3):
            plotter.subplot(0, column)
            plotter.set_background((0.08, 0.09, 0.12), top=(0.30, 0.34, 0.42))
        draw_compare(plotter, compared, axis, grid_label, f"{Path(args.scene).name} ({count:,} balls)")
        _show(plotter, screenshot, f"cloudmeta inspect {args.scene} --grid {grid_path}")
    finally:
        plotter.close()
    return 0
