"""cloudmeta.generate and ``cloudmeta generate`` (docs/generate.md): deterministic clouds of exactly N balls,
a flat base, puffs on puffs, scenes that load and render, and the command's files and errors."""
import re
import shlex
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

import cloudmeta as cm
from cloudmeta.cli import main
from cloudmeta.errors import InputError, OutputError
from cloudmeta.generate import CUTTER, EROSION, FADE, KINDS, MARK, PARAMETERS, THRESHOLD, csv_text, iso_u

ROOT = Path(__file__).resolve().parents[2]
SCENES = ROOT / "scenes"


@pytest.fixture(scope="module")
def clouds():
    """One cloud of each kind, 600 balls, seed 7."""
    return {kind: cm.generate(kind, balls=600, seed=7) for kind in KINDS}


def test_generate_is_the_function_however_imported():
    """``cloudmeta.generate`` is the function even when the package was imported first by its full name."""
    code = ("from cloudmeta.generate import MARK, write_scene\n"
            "import cloudmeta.generate\n"
            "import cloudmeta as cm\n"
            "from cloudmeta.generate import generate\n"
            "print(cm.generate is generate, cm.write_scene is write_scene, len(cm.generate('cumulus', balls=40)))\n")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, cwd=ROOT)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.split() == ["True", "True", "40"]


def test_the_kinds():
    assert {"cumulus", "stratocumulus", "tower", "cumulonimbus"} <= set(KINDS)
    for kind, params in PARAMETERS.items():
        for name, p in params.items():
            assert p.unit and p.doc and p.lo <= p.hi, (kind, name)
            assert p.default is None or p.lo <= p.default <= p.hi, (kind, name)


@pytest.mark.parametrize("kind", KINDS)
def test_deterministic_by_seed(kind, clouds):
    again = cm.generate(kind, balls=600, seed=7)
    assert np.array_equal(again.balls, clouds[kind].balls)
    assert np.array_equal(again.levels, clouds[kind].levels)
    assert dict(again.medium) == dict(clouds[kind].medium)
    other = cm.generate(kind, balls=600, seed=8)
    assert other.balls.shape == clouds[kind].balls.shape
    assert not np.array_equal(other.balls, clouds[kind].balls)


@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("n", [8, 57, 200, 1001])
def test_exactly_n_balls(kind, n):
    cloud = cm.generate(kind, balls=n, seed=n)
    assert len(cloud) == n and cloud.balls.shape == (n, 10) and cloud.levels.shape == (n,)
    assert np.all(np.isfinite(cloud.balls))
    assert np.all(cloud.balls[:, 3:6] > 0)
    assert np.count_nonzero(cloud.levels == CUTTER) == 1
    assert not cloud.balls.flags.writeable


def test_sizes_and_scale(clouds):
    for kind, cloud in clouds.items():
        (x0, y0, z0), (x1, y1, z1) = cloud.extent
        assert x1 - x0 == pytest.approx(cloud.size, rel=1e-9)  # size is the visible extent along x
        assert z0 == 0.0 and abs(x0 + x1) < 1e-9
        height = cloud.params["thickness" if kind == "stratocumulus" else "height_ratio"] * cloud.size
        if 0.5 < cloud.params["stretch"] < 2.0:  # the stretch reached the height asked for
            assert z1 == pytest.approx(height, rel=1e-9)
    small = cm.generate("cumulus", balls=600, seed=7, size=0.01)
    assert np.allclose(small.balls[:, :6], clouds["cumulus"].balls[:, :6] * 1e-3, rtol=1e-12, atol=1e-15)
    assert small.medium["density"]["scale"] == pytest.approx(clouds["cumulus"].medium["density"]["scale"] * 1e3)


@pytest.mark.parametrize("kind", KINDS)
def test_flat_base(kind, clouds):
    """F < T everywhere below z = 0 (sampled through every positive support that reaches below it), no
    positive support deeper than cloud.depth, and the underside flat."""
    cloud = clouds[kind]
    b, size = cloud.balls, cloud.size
    positive = b[:, 9] > 0
    assert cloud.base == 0.0
    assert np.all(b[positive, 2] - b[positive, 5] >= -cloud.depth - 1e-12)  # no ball is turned off the z axis
    assert np.all(b[:, 6:8] == 0)
    assert cloud.depth <= 0.35 * size
    rng = np.random.default_rng(1)
    low = positive & (b[:, 2] - b[:, 5] < 0)
    centres = b[low, :3][rng.integers(0, np.count_nonzero(low), 20000)]
    radii = b[low, 3:6][rng.integers(0, np.count_nonzero(low), 20000)]
    pts = centres + rng.uniform(-1, 1, (20000, 3)) * radii
    pts[:, 2] = -rng.uniform(1e-9, 1.0, 20000) * cloud.depth
    assert np.max(cloud.field(pts)) < THRESHOLD
    # the underside: in the column through each ball of the body that the cut trims (its own visible
    # ellipsoid reaches below z = 0; for a deck, whose cells sit on the base, every cell), the lowest point
    # inside lies at the same height, within 2 % of size above z = 0
    body = b[cloud.levels == 0]
    cut = body[body[:, 2] - np.sqrt(iso_u(body[:, 9])) * body[:, 5] < 0]
    columns = (cut if len(cut) else body)[:, :2]
    zs = np.linspace(-0.02, 0.1, 121) * size
    pts = np.concatenate([np.repeat(columns, len(zs), 0), np.tile(zs, len(columns))[:, None]], 1)
    inside = (cloud.field(pts) >= THRESHOLD).reshape(len(columns), len(zs))
    assert inside.any(axis=1).all()
    lowest = zs[np.argmax(inside, axis=1)]
    assert np.all(lowest >= 0) and np.all(lowest <= 0.02 * size)
    assert np.ptp(lowest) <= 0.01 * size


def test_puffs_on_puffs():
    """Cumulus of 3000 balls: a body and at least 3 levels of puffs, each level's balls smaller than its
    parents' and more numerous; the puffs sit on the surface, the interior is the body's few balls."""
    cloud = cm.generate("cumulus", balls=3000, seed=2)
    levels = sorted(k for k in set(cloud.levels.tolist()) if k >= 0)
    assert levels == list(range(len(levels))) and len(levels) >= 4
    sizes = [cloud.balls[cloud.levels == k, 3:6].max(axis=1).mean() for k in levels]
    counts = [np.count_nonzero(cloud.levels == k) for k in levels]
    assert all(a > b for a, b in zip(sizes, sizes[1:])), sizes
    assert all(a < b for a, b in zip(counts[1:], counts[2:])), counts
    assert counts[0] <= 20
    # the puffs sit on the surface: from (nearly) every puff's centre, one of 26 directions leaves the
    # cloud within the puff's own radius (the last level: 90 %, its smallest puffs fill the gaps between its
    # largest) or 1.5 of it (a level that the next ones cover)
    probe = np.stack(np.meshgrid([-1, 0, 1], [-1, 0, 1], [-1, 0, 1], indexing="ij"), -1).reshape(-1, 3)
    probe = probe[np.any(probe != 0, axis=1)]
    probe = probe / np.linalg.norm(probe, axis=1)[:, None]

    def reaches_out(rows, reach):
        rows = rows[:: max(1, len(rows) // 300)]  # at most ~300 of a level
        pts = (rows[:, None, :3] + reach * rows[:, None, 3:4] * probe[None]).reshape(-1, 3)
        pts[:, 2] = np.maximum(pts[:, 2], 0.0)
        return (cloud.field(pts).reshape(len(rows), -1) < THRESHOLD).any(axis=1)
    for k in levels[1:-1]:
        assert reaches_out(cloud.balls[cloud.levels == k], 1.5).mean() > 0.85, k
    assert reaches_out(cloud.balls[cloud.levels == levels[-1]], 1.0).mean() > 0.9
    # the suggested density gives the target optical depth; negative balls are the cutter and erosion
    assert set(np.flatnonzero(cloud.balls[:, 9] < 0)) == set(np.flatnonzero(cloud.levels < 0))
    assert np.count_nonzero(cloud.levels == EROSION) == round(PARAMETERS["cumulus"]["erosion"].default * 3000)
    assert cloud.medium["density"]["mode"] == "excess" and cloud.medium["density"]["scale"] > 0


def test_sizes_spread_and_the_base_fades():
    """The puffs' sizes spread over a power law (far wider than with size_spread=1), and the base-fade ball
    thins the density towards the base: F lower near z = 0 than without it, the same higher up."""
    def spread(cloud):
        keep = (cloud.levels > 0) & (cloud.balls[:, 9] > THRESHOLD)
        r = cloud.balls[keep, 3:6].max(axis=1)
        lo, hi = np.percentile(r, [5, 95])
        return hi / lo
    cloud = cm.generate("cumulus", balls=3000, seed=2)
    alike = cm.generate("cumulus", balls=3000, seed=2, size_spread=1.0, depth_power=100.0)
    wide = cm.generate("cumulus", balls=3000, seed=2, size_spread=8.0)
    assert spread(wide) > 1.3 * spread(alike)
    assert spread(cloud) > spread(alike)  # the cumulus's default spread (2) is narrower, still a spread
    fade = cloud.balls[cloud.levels == FADE]
    assert len(fade) == 1 and fade[0, 9] == -THRESHOLD and fade[0, 2] == 0.0
    assert fade[0, 5] == pytest.approx(0.15 * cloud.extent[1][2], rel=0.3)  # 0.15 of the height, roughly
    bare = cm.generate("cumulus", balls=3000, seed=2, base_fade=0.0)
    assert not np.any(bare.levels == FADE) and len(bare) == 3000
    # the fade ball's own field: -T at the base, 0 above its layer
    low = np.array([[0.0, 0.0, 0.01 * fade[0, 5]]])
    high = np.array([[0.0, 0.0, 1.01 * fade[0, 5]]])
    one = cm.Blob(fade[:, :3], fade[:, 3:6], fade[:, 9])
    assert cm.field(one, low)[0] == pytest.approx(-THRESHOLD, rel=1e-3) and cm.field(one, high)[0] == 0.0


def test_parameters_change_the_cloud():
    base = cm.generate("cumulus", balls=500, seed=3)
    tall = cm.generate("cumulus", balls=500, seed=3, height_ratio=1.0)
    assert tall.extent[1][2] > 1.5 * base.extent[1][2]
    deck = cm.generate("stratocumulus", balls=500, seed=3, thickness=0.05)
    assert deck.extent[1][2] == pytest.approx(0.5)
    assert deck.params["plan"] and deck.params["stretch"] > 0


def test_bad_arguments():
    with pytest.raises(InputError, match="kind: expected one of"):
        cm.generate("cirrus")
    with pytest.raises(InputError, match="balls: expected an integer from 8"):
        cm.generate("cumulus", balls=7)
    with pytest.raises(InputError, match="balls"):
        cm.generate("cumulus", balls=100.0)
    with pytest.raises(InputError, match="seed"):
        cm.generate("cumulus", seed=-1)
    with pytest.raises(InputError, match="size"):
        cm.generate("cumulus", size=float("nan"))
    with pytest.raises(InputError, match="height_ratio: expected a number from"):
        cm.generate("cumulus", height_ratio=100.0)
    with pytest.raises(InputError, match="thickness: not a parameter of cumulus"):
        cm.generate("cumulus", thickness=0.1)
    with pytest.raises(InputError, match="levels: expected an integer"):
        cm.generate("cumulus", levels=2.5)


def test_write_scene_loads_and_renders(tmp_path):
    cloud = cm.generate("cumulus", balls=300, seed=5)
    yaml_path, csv_path = cm.write_scene(cloud, tmp_path / "c.yaml", width=24, height=18)
    assert Path(csv_path) == tmp_path / "c.csv"
    text = Path(yaml_path).read_text()
    assert text.startswith(MARK) and "balls_file: c.csv" in text and "# Command: cloudmeta generate" in text
    scene = cm.load_scene(yaml_path, render={"quality": "draft"})
    blob = scene.media[0].blob
    assert len(blob) == 300 and scene.image.width == 24 and scene.image.height == 18
    assert np.allclose(blob.centers, cloud.balls[:, :3], rtol=1e-6, atol=1e-6 * cloud.size)
    assert np.allclose(blob.weights, cloud.balls[:, 9], rtol=1e-6)
    image = cm.render(scene, progress=False)
    assert image.shape == (18, 24, 4) and image[..., 3].max() > 0.5
    assert sorted(p.name for p in tmp_path.iterdir()) == ["c.csv", "c.yaml"]  # no temporary file left


def test_write_scene_refuses_to_overwrite(tmp_path):
    cloud = cm.generate("tower", balls=100, seed=1)
    cm.write_scene(cloud, tmp_path / "t.yaml")
    before = (tmp_path / "t.csv").read_bytes()
    with pytest.raises(OutputError, match="exists; refusing to overwrite"):
        cm.write_scene(cm.generate("tower", balls=100, seed=2), tmp_path / "t.yaml")
    assert (tmp_path / "t.csv").read_bytes() == before
    cm.write_scene(cm.generate("tower", balls=100, seed=2), tmp_path / "t.yaml", overwrite=True)
    assert (tmp_path / "t.csv").read_bytes() != before
    (tmp_path / "hand.csv").write_text("x,y,z,radius,weight\n0,0,0,1,1\n")  # a file generate did not write
    with pytest.raises(OutputError, match="not written by cloudmeta generate"):
        cm.write_scene(cloud, tmp_path / "hand.yaml", overwrite=True)
    assert not (tmp_path / "hand.yaml").exists()
    with pytest.raises(OutputError, match=r"\.yaml or \.yml"):
        cm.write_scene(cloud, tmp_path / "t.csv")
    with pytest.raises(OutputError, match="does not exist"):
        cm.write_scene(cloud, tmp_path / "no" / "t.yaml")


def _cli(*args):
    proc = subprocess.run([sys.executable, "-m", "cloudmeta.cli", "generate", *args], capture_output=True, text=True,
                          timeout=120, cwd=ROOT)
    return proc.returncode, proc.stdout, proc.stderr


def _main(capsys, *args):
    """``cloudmeta generate ARGS`` in this process: (exit status, stdout, stderr)."""
    try:
        code = main(["generate", *args])
    except SystemExit as exc:  # argparse's errors
        code = exc.code
    out = capsys.readouterr()
    return code, out.out, out.err


def test_cli_writes_both_files_and_refuses_to_overwrite(tmp_path, capsys):
    out = tmp_path / "s.yaml"
    code, stdout, _ = _main(capsys, "stratocumulus", "--balls", "400", "--seed", "3", "-o", str(out))
    line = stdout.strip()
    assert code == 0 and line.startswith("cloudmeta: wrote") and "400-ball stratocumulus" in line
    assert len(line.splitlines()) == 1
    assert out.exists() and (tmp_path / "s.csv").exists()
    assert "--balls 400 --seed 3" in out.read_text()
    csv = (tmp_path / "s.csv").read_bytes()
    assert csv == csv_text(cm.generate("stratocumulus", balls=400, seed=3),
                           command=f"cloudmeta generate stratocumulus --balls 400 --seed 3 -o {out}").encode()
    code, stdout, stderr = _main(capsys, "cumulus", "--balls", "400", "-o", str(out))
    assert code == 2 and stdout == ""
    assert stderr.startswith("cloudmeta: error: scene") and "refusing to overwrite" in stderr
    assert len(stderr.strip().splitlines()) == 1
    assert (tmp_path / "s.csv").read_bytes() == csv
    code, _, _ = _main(capsys, "cumulus", "--balls", "400", "-o", str(out), "--overwrite", "-p", "height_ratio=0.8")
    assert code == 0 and (tmp_path / "s.csv").read_bytes() != csv


@pytest.mark.parametrize("args, message", [
    (["cirrus"], "kind: expected one of cumulus"),
    (["cumulus", "--balls", "0"], "argument --balls"),
    (["cumulus", "--balls", "many"], "argument --balls"),
    (["cumulus", "--balls", "5"], "balls: expected an integer from 8"),
    (["cumulus", "--seed", "-3"], "argument --seed"),
    (["cumulus", "-p", "height_ratio"], "expected NAME=VALUE"),
    (["cumulus", "-p", "bogus=1"], "bogus: not a parameter of cumulus"),
    (["cumulus", "--size", "inf"], "size: expected a number"),
])
def test_cli_errors_are_one_line(tmp_path, capsys, args, message):
    code, stdout, stderr = _main(capsys, *args, "-o", str(tmp_path / "x.yaml"))
    assert code == 2, stderr
    assert stderr.startswith("cloudmeta: error: ") and message in stderr
    assert len(stderr.strip().splitlines()) == 1
    assert list(tmp_path.iterdir()) == []


def test_cli_process_exits_2_without_a_traceback(tmp_path):
    for args in (["cirrus", "-o", str(tmp_path / "x.yaml")], ["cumulus", "--balls", "7"]):
        code, stdout, stderr = _cli(*args)
        assert code == 2 and stdout == "" and stderr.startswith("cloudmeta: error: ")
        assert len(stderr.strip().splitlines()) == 1 and "Traceback" not in stderr
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("path", sorted(SCENES.glob("generated_*.yaml")), ids=lambda p: p.name)
def test_shipped_scenes_are_what_their_command_makes(path):
    """Each scenes/generated_*.yaml names the command that made it; that command makes its balls file
    again, byte for byte."""
    text = path.read_text()
    command = re.search(r"^# Command: (cloudmeta generate .*)$", text, re.M).group(1)
    argv = shlex.split(command)[2:]
    kind, rest = argv[0], argv[1:]
    opts = dict(zip(rest[::2], rest[1::2]))
    params = dict(p.split("=") for k, p in zip(rest[::2], rest[1::2]) if k == "-p")
    params = {k: (int(v) if v.lstrip("-").isdigit() else float(v)) for k, v in params.items()}
    cloud = cm.generate(kind, balls=int(opts["--balls"]), seed=int(opts["--seed"]),
                        size=float(opts.get("--size", 10.0)), **params)
    csv = path.with_suffix(".csv")
    assert csv.read_text() == csv_text(cloud, command)
    assert f"balls_file: {csv.name}" in text
    assert (SCENES / opts["-o"].split("/")[-1]) == path


def test_hundred_thousand_balls_in_under_ten_seconds():
    start = time.perf_counter()
    cloud = cm.generate("cumulus", balls=100_000, seed=1)
    took = time.perf_counter() - start
    assert len(cloud) == 100_000 and took < 10.0
    assert cloud.params["levels"] >= 5  # more balls: more levels, finer detail
    assert iso_u(np.array([1.0]))[0] == pytest.approx(0.25, abs=1e-9)  # k(1/4) = T: a lone ball's visible radius
