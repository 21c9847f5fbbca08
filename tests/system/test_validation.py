"""A small, fast version of every validation script (validation/README.md): the error bounds are asserted,
the timings are not (they depend on the machine). Quick runs write nothing under validation/results/."""
import numpy as np
import pytest

from validation.accuracy import (far_geometry, optical_depth, optical_depth_vs_quadrature, paper_examples,
                                 render_quality, root_finding, root_finding_table, single_scattering, stability)
from validation.performance import time_vs_error


def test_optical_depth_every_case_below_1e_9():
    out = optical_depth.main(["--rays-per-blob", "2"], quick=True)
    assert out["passed"]
    assert out["max_rel_err"] < 1e-9
    assert set(out["not_traceable"]) <= {"nishimura", "blinn"}
    checked = [case for case, s in out["per_case"].items() if s["status"] == "checked"]
    assert {c[0] for c in checked} >= {"wyvill6", "murakami4"}


def test_optical_depth_vs_quadrature_quick():
    out = optical_depth_vs_quadrature.main(["--rays", "48"], quick=True)
    assert out["passed"]
    assert out["max_rel_err"] < 1e-9


def test_single_scattering_within_each_settings_promise():
    out = single_scattering.main(quick=True)
    for r in out["rows"]:
        assert r["rel_rmse"] < single_scattering.BOUND[r["setting"]], r
        assert r["alpha_max_abs"] < single_scattering.ALPHA_BOUND, r
    assert out["passed"]


def test_time_vs_error_default_within_1e_3():
    out = time_vs_error.main(quick=True)
    rows = out["rows"]
    assert all(r["finite"] for r in rows)
    assert all(r["rel_rmse"] < 1e-3 for r in rows if r["setting"] == "default")
    front = [r for r in rows if r["pareto"]]
    assert front and all(np.isfinite(r["seconds"]) for r in front)


def test_stability_no_failures():
    out = stability.main(quick=True)
    failing = [(r["category"], r["case"], r["status"], r["error"], r["tolerance"]) for r in out["failing"]]
    assert out["failures"] == 0, failing[:10]


def test_root_finding_solvers_agree():
    out = root_finding.main(quick=True)
    assert out["mismatches"] == 0
    for r in out["rows"]:
        assert r["max_root_diff"] <= root_finding.AGREE


def test_root_finding_table_roots_agree():
    out = root_finding_table.main(["--reps", "20", "--runs", "1"], quick=True)
    assert all(r["roots_agree"] for r in out["rows"])  # the speed ratios depend on the machine: not asserted


def test_paper_examples():
    out = paper_examples.main(quick=True)
    assert out["passed"], [r for r in out["rows"] if not r["ok"]]


def test_far_geometry_changes_no_pixel():
    out = far_geometry.main(quick=True)
    assert out["worst"] == 0.0 and len(out["rows"]) == 8


def test_render_quality_default_within_1e_3():
    out = render_quality.main(["--quick"])
    assert out["passed"]


@pytest.mark.parametrize("mode", ["field", "excess", "uniform"])
def test_plain_model_matches_the_engine(mode):
    """validation/references/plain.py (the references' numpy model) against the engine on random rays."""
    import cloudmeta as cm
    from validation.references import plain as P

    rng = np.random.default_rng(11)
    c = rng.uniform(-2, 2, (20, 3))
    r = rng.uniform(0.7, 2.0, (20, 3))
    a = rng.uniform(0, 360, (20, 3))
    w = rng.uniform(0.6, 1.4, 20)
    w[::4] *= -0.5
    blob = cm.Blob(c, r, w, threshold=0.45, rotations=a)
    med = P.Medium.build(c, r, w, a, threshold=0.45, mode=mode, scale=1.7)
    o = rng.normal(size=(200, 3))
    o *= 10 / np.linalg.norm(o, axis=1)[:, None]
    d = rng.uniform(-2, 2, (200, 3)) - o
    d /= np.linalg.norm(d, axis=1)[:, None]
    ref = P.optical_depth(med, o, d)
    got = cm.optical_depth(blob, o, d, density=mode, scale=1.7)
    np.testing.assert_allclose(got, ref, rtol=1e-9, atol=1e-12)


def test_base_top_regions_and_a_tiny_run():
    from validation.accuracy import base_top
    image = np.zeros((40, 30, 4))
    image[10:30, 5:25, 3] = 1.0                      # the cloud: rows 10-29
    image[10:30, 5:25, :3] = 1.0
    image[10, 5, :3] = 4.0                           # one bright pixel on top
    image[27:30, 5:25, :3] = 0.25                    # a darker base: the lowest 15 % of 20 rows are 3
    cloud, top, base, rows = base_top.regions(image)
    assert rows == (27, 29) and base.sum() == 60 and cloud.sum() == 400
    assert top[10, 5] and top.sum() >= 1
    b, t, r = base_top.ratio(image, top, base)
    assert b == pytest.approx(0.25) and r == pytest.approx(b / t) and r < 0.25
    out = base_top.main(["--size", "24", "--ms-spp", "2"])
    assert set(out) == {"approximate (octaves)", "multiple, 2 paths a pixel"}
    assert all(0.0 < v < 2.0 for v in out.values())
