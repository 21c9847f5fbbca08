"""The command line: a render end to end to a readable EXR, and clean errors for bad scenes."""
import subprocess
import sys
from pathlib import Path

import numpy as np
import OpenEXR
import pytest

from cloudmeta.cli import main

ROOT = Path(__file__).resolve().parent.parent


def test_render_cumulus_writes_exr_and_png(tmp_path, capsys):
    exr, png = tmp_path / "c.exr", tmp_path / "c.png"
    code = main(["render", str(ROOT / "scenes" / "cumulus.yaml"), "-o", str(exr), "--png", str(png),
                 "--width", "40", "--height", "30", "--quality", "draft", "-q"])
    assert code == 0
    out = capsys.readouterr().out
    assert "40 x 30" in out and str(exr) in out and "rendered in" in out
    with OpenEXR.File(str(exr), separate_channels=True) as f:
        header = dict(f.header())
        channels = f.channels()
        names = set(channels)
        rgba = np.stack([channels[c].pixels for c in "RGBA"], axis=-1)
    assert {"R", "G", "B", "A"} <= names
    assert rgba.shape == (30, 40, 4)
    assert "chromaticities" in header
    assert 0 < rgba[..., 3].max() <= 1 and rgba[..., 3].min() == 0  # the cloud and the sky are both in view
    assert png.stat().st_size > 0


def test_bad_scene_exits_nonzero_with_the_loader_message(tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text("image: {width: 8, height: 8}\ncamera: {position: [0, -5, 0], look_at: [0, 0, 0]}\n"
                   "media:\n  - balls: [{center: [0, 0, 0], radius: -1}]\n")
    proc = subprocess.run([sys.executable, "-m", "cloudmeta.cli", "render", str(bad)], capture_output=True,
                          text=True, timeout=120)
    assert proc.returncode == 2
    assert "bad.yaml" in proc.stderr and "media[0].balls[0].radius" in proc.stderr
    assert "Traceback" not in proc.stderr


def test_shadow_map_options_reach_the_renderer(tmp_path, capsys):
    """--shadows map --shadow-map N renders with a map: close to the exact-shadow image, not equal to it."""
    exrs = []
    for extra in ([], ["--shadows", "map", "--shadow-map", "64"]):
        exr = tmp_path / f"c{len(exrs)}.exr"
        assert main(["render", str(ROOT / "scenes" / "cumulus.yaml"), "-o", str(exr), "--width", "24",
                     "--height", "24", "--quality", "draft", "-q", *extra]) == 0
        with OpenEXR.File(str(exr), separate_channels=True) as f:
            exrs.append(np.stack([f.channels()[c].pixels for c in "RGB"], axis=-1))
    assert "map shadows" in capsys.readouterr().out
    diff = np.abs(exrs[1] - exrs[0]).max()
    assert 0 < diff < 0.05 * exrs[0].max()


def test_shadow_map_size_must_be_two_or_more(capsys):
    with pytest.raises(SystemExit) as e:
        main(["render", str(ROOT / "scenes" / "cumulus.yaml"), "--shadow-map", "1"])
    assert e.value.code == 2
    assert "expected an integer >= 2" in capsys.readouterr().err
