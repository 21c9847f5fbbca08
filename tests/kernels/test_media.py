"""Every medium along one ray (cloudmeta.kernels.media) against its naive twin: the pieces a camera ray
integrates and the shadow transmittance through several overlapping media of every density mode."""
import numpy as np
import pytest

from cloudmeta.kernels.bvh import STACK
from cloudmeta.kernels.media import alloc_ray_pieces, collect_media, shadow_transmittance
from cloudmeta.kernels.sweep import alloc_scratch
from cloudmeta.renderer.pack import pack_media
from cloudmeta.scene import Density, Medium, Phase
from tests import naive
from tests.conftest import random_blob, random_rays


def media_of(rng):
    modes = (("field", 1.5), ("excess", 4.0), ("uniform", 0.7))
    media = [Medium(f"m{i}", random_blob(rng, n, ellipsoids=i == 1, negative=i == 0), Density(mode, scale), 0.9,
                    Phase()) for i, ((mode, scale), n) in enumerate(zip(modes, (12, 8, 3)))]
    return media, [(m.blob, m.density.mode, m.density.scale) for m in media]


@pytest.mark.parametrize("seed", [1, 2])
def test_pieces_and_shadow_transmittance_match_the_naive_walk(seed):
    rng = np.random.default_rng(seed)
    media, twin = media_of(rng)
    med = pack_media(media)
    n_balls = med.centers.shape[0]
    scratch = alloc_scratch(np.int64(4))
    rp = alloc_ray_pieces(np.int64(2), np.int64(len(media)))  # small: the walk must grow it
    cand, stack = np.empty(n_balls, np.int64), np.empty(2 * STACK, np.int64)
    o, d = random_rays(rng, 40)
    tol_t = 1e-12
    for k in range(len(o)):
        for tmax in (np.inf, 13.0):
            want = naive.media_optical_depth(twin, o[k], d[k], tmax)
            scratch, rp, n = collect_media(o[k], d[k], tmax, med, tol_t, scratch, rp, cand, stack)
            tau = sum((rp.t1[i] - rp.t0[i]) * rp.c[i].mean() for i in range(n))
            assert tau == pytest.approx(want, rel=1e-9, abs=1e-12)
            assert all(rp.t0[i] < rp.t1[i] <= tmax for i in range(n))
            t_l = shadow_transmittance(o[k], d[k], tmax, med, tol_t, np.inf, scratch, cand, stack)[1]
            assert t_l == pytest.approx(np.exp(-want), rel=1e-9, abs=1e-300)
