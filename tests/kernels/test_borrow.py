"""kernels.borrow: borrowed records change no pixel, and the work arrays a ray grows stay owned."""
import numpy as np
from numba import njit

import cloudmeta as cm
from cloudmeta.kernels.borrow import borrow, hold_grown, release
from cloudmeta.kernels.lighting import N_COUNTS
from cloudmeta.kernels.media import alloc_ray_pieces, grow_ray_pieces
from cloudmeta.kernels.intervals import alloc_node_work
from cloudmeta.kernels.records import RayWork
from cloudmeta.kernels.single import render_pixels
from cloudmeta.kernels.sweep import alloc_scratch, capacity_of
from cloudmeta.renderer.pack import pack_scene

#: a thin sausage of 100 overlapping balls and a string of 143 beads on the view axis, seen through a
#: 0.2 degree lens: every camera ray meets ~200 chords and ~300-400 inside pieces, so the first ray grows
#: the sweep scratch (room for 64 chords) and the ray pieces (64) of render_pixels' work arrays
BEADS = """
image: {width: 8, height: 8, spp: 1}
camera: {position: [0, -60, 0], look_at: [0, 0, 0], up: [0, 0, 1], fov: 0.2}
lights:
  - {type: directional, direction: [0.3, -0.5, 0.8], irradiance: 3.0}
media:
  - name: sausage
    kernel: wyvill6
    threshold: 0.5
    density: {mode: field, scale: 2.0}
    albedo: 0.9
    phase: {type: hg, g: 0.5}
    balls: [%s]
  - name: beads
    kernel: wyvill6
    threshold: 0.3
    density: {mode: uniform, scale: 1.0}
    albedo: 0.9
    phase: {type: isotropic}
    balls: [%s]
""" % (", ".join("{center: [0, %.2f, 0], radius: 0.3, weight: 1.0}" % (-5 + 0.1 * k) for k in range(100)),
       ", ".join("{center: [0, %.2f, 0], radius: 0.3, weight: 1.0}" % (-50 + 0.7 * k) for k in range(143)))


def test_grown_work_arrays_give_the_same_pixels(tmp_path):
    """One call over all pixels (the later ones use the grown arrays that hold_grown handed to the owner
    and borrowed) equals one call per pixel (each with fresh arrays that it grows)."""
    path = tmp_path / "beads.yaml"
    path.write_text(BEADS)
    scene = cm.load_scene(path)
    p = pack_scene(scene, 0)
    n = 64
    out = [(np.zeros((8, 8, 4)), np.full((8, 8), np.inf), np.zeros((8, 8, N_COUNTS))) for _ in range(2)]
    render_pixels(p.camera, p.records, p.quadrature, np.int64(0), np.int64(0), np.int64(n), *out[0])
    for k in range(n):
        render_pixels(p.camera, p.records, p.quadrature, np.int64(0), np.int64(k), np.int64(k + 1), *out[1])
    for a, b in zip(*out):
        np.testing.assert_array_equal(a, b)
    image = out[0][0]
    assert image[..., 3].min() > 0.5 and image[..., :3].min() > 0.0  # the beads are seen and lit
    assert out[0][2][..., 0].min() > 10  # quadrature nodes on every pixel


@njit
def _grow_and_hold():
    own = RayWork(alloc_scratch(np.int64(4)), alloc_ray_pieces(np.int64(4), np.int64(1)), np.empty(4, np.int64),
                  np.empty(8, np.int64), alloc_node_work(np.int64(1)))
    work = borrow(own)
    work.pieces.t0[1] = 2.5
    # a ray grows the pieces (copying what it holds) but not the scratch
    work = RayWork(work.scratch, grow_ray_pieces(work.pieces, np.int64(2), np.int64(10), np.int64(1)), work.cand,
                   work.stack, work.nodes)
    own, work = hold_grown(own, work)
    work.pieces.t0[7] = 1.5  # written through the borrowed view, read through the owner
    work.scratch.chord_t0[3] = 4.0
    result = (capacity_of(own.scratch), own.pieces.t0.shape[0], own.pieces.t0[1], own.pieces.t0[7],
              own.scratch.chord_t0[3], work.pieces.t0.shape[0])
    # then the scratch grows
    work = RayWork(alloc_scratch(np.int64(16)), work.pieces, work.cand, work.stack, work.nodes)
    work.scratch.chord_t0[12] = 7.0
    own, work = hold_grown(own, work)
    release(own)
    return result + (capacity_of(own.scratch), own.scratch.chord_t0[12], own.pieces.t0[7])


def test_hold_grown_hands_the_grown_record_to_the_owner():
    assert _grow_and_hold() == (4, 20, 2.5, 1.5, 4.0, 20, 16, 7.0, 1.5)
