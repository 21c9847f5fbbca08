"""Keyframes (cloudmeta.animation): interpolation, a scene read at a frame, errors that name the frame, and
the command line's sequences (one file per frame, finished frames skipped)."""
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

import cloudmeta as cm
from cloudmeta.scene.animation import interpolate, load_animation, parse_frames, resolve_frame
from cloudmeta.cli import main

ROOT = Path(__file__).resolve().parents[2]

#: a tiny keyframed scene: 3 frames, a drifting ball, a growing one, a moving camera and a changing sky
ANIMATED = """\
image: {width: 24, height: 16}
camera: {position: {keys: {0: [0, -8, 0], 2: [1, -8, 0.5]}, interpolate: smooth}, look_at: [0, 0, 0]}
background: {keys: {0: [0.2, 0.3, 0.6], 2: [0.3, 0.3, 0.5]}}
lights: [{type: directional, direction: [0.5, -0.5, 0.7], irradiance: {keys: {0: 3, 2: 5}}}]
media:
  - density: {scale: {keys: {0: 1.0, 1: 2.0, 2: 1.5}, interpolate: smooth}}
    phase: {type: hg, g: {keys: {0: 0.2, 2: 0.6}}}
    balls:
      - {center: {keys: {0: [-1.5, 0, 0], 2: [-0.6, 0, 0]}}, radius: 1.2}
      - {center: [1.2, 0, 0], radius: {keys: {0: 1.0, 2: 1.4}, interpolate: smooth}}
render: {quality: draft}
animation: {frames: 3, fps: 12}
"""

STATIC = """\
image: {width: 24, height: 16}
camera: {position: [0, -8, 0], look_at: [0, 0, 0]}
lights: [{type: directional, direction: [0.5, -0.5, 0.7], irradiance: 3}]
media: [{balls: [{center: [0, 0, 0], radius: 1.5}]}]
render: {quality: draft}
"""


def write_scene(folder, text, name="scene.yaml"):
    path = Path(folder) / name
    path.write_text(text)
    return path


# ------------------------------------------------------------------------------------ interpolation

def test_linear_is_exact_at_keys_straight_between_and_clamped_outside():
    keys = {0: 1.0, 10: 3.0, 20: 2}
    assert [interpolate(keys, k) for k in (0, 10, 20)] == [1.0, 3.0, 2]  # the keys' values as written
    assert interpolate(keys, 5) == pytest.approx(2.0)
    assert interpolate(keys, 15) == pytest.approx(2.5)
    assert interpolate(keys, -3) == 1.0 and interpolate(keys, 99) == 2.0
    assert interpolate({4: [0, 1, 2], 8: [4, 1, 0]}, 5) == pytest.approx([1.0, 1.0, 1.5])
    assert interpolate({7: 2.5}, 0) == 2.5 and interpolate({7: 2.5}, 30) == 2.5  # one key: constant


def test_smooth_goes_through_the_keys_and_is_c1():
    keys = {0: 0.0, 4: 2.0, 6: 1.0, 15: 3.0}
    f = lambda x: interpolate(keys, x, "smooth")  # noqa: E731
    for k, v in keys.items():
        assert f(k) == v
    # two keys: the smoothstep
    assert interpolate({0: 1.0, 10: 3.0}, 2.5, "smooth") == pytest.approx(1.0 + 2.0 * (3 * 0.25**2 - 2 * 0.25**3))
    h = 1e-6
    for k in keys:  # one-sided slopes agree at every key, and are 0 at the ends (clamped beyond them)
        left, right = (f(k) - f(k - h)) / h, (f(k + h) - f(k)) / h
        assert left == pytest.approx(right, abs=1e-4)
    assert (f(h) - f(0)) / h == pytest.approx(0.0, abs=1e-4)
    assert (f(15) - f(15 - h)) / h == pytest.approx(0.0, abs=1e-4)
    # the inner slope is the finite difference of the neighbouring keys
    assert (f(4 + h) - f(4 - h)) / (2 * h) == pytest.approx((1.0 - 0.0) / (6 - 0), rel=1e-4)
    # continuous (no jumps) on a fine grid
    xs = np.linspace(-2, 17, 2001)
    assert np.max(np.abs(np.diff([f(x) for x in xs]))) < 0.05


def test_smooth_vectors_interpolate_each_component():
    keys = {0: [0.0, 10.0], 8: [4.0, 2.0], 12: [4.0, 0.0]}
    got = interpolate(keys, 5, "smooth")
    assert got == pytest.approx([interpolate({k: v[0] for k, v in keys.items()}, 5, "smooth"),
                                 interpolate({k: v[1] for k, v in keys.items()}, 5, "smooth")])


# ---------------------------------------------------------------------------------------- scenes

def test_resolve_frame_replaces_keyframes_and_leaves_the_document_alone():
    data = yaml.safe_load(ANIMATED)
    before = yaml.safe_dump(data)
    out, animated = resolve_frame("scene.yaml", data, 1)
    assert animated and "animation" not in out
    assert yaml.safe_dump(data) == before
    assert out["media"][0]["balls"][0]["center"] == pytest.approx([-1.05, 0, 0])
    assert out["media"][0]["density"]["scale"] == 2.0
    assert out["lights"][0]["irradiance"] == pytest.approx(4.0)
    assert resolve_frame("s.yaml", yaml.safe_load(STATIC), 5) == (yaml.safe_load(STATIC), False)


def test_load_scene_at_a_frame(tmp_path):
    path = write_scene(tmp_path, ANIMATED)
    s0, s2 = cm.load_scene(path), cm.load_scene(path, frame=2)
    assert s0.media[0].blob.centers[0].tolist() == [-1.5, 0, 0]
    assert s2.media[0].blob.centers[0].tolist() == [-0.6, 0, 0]
    assert s2.camera.position.tolist() == [1, -8, 0.5]
    assert s2.media[0].phase.g == 0.6 and s2.media[0].density.scale == 1.5
    assert load_animation(path).frames == 3 and load_animation(path).fps == 12.0
    assert load_animation(write_scene(tmp_path, STATIC, "static.yaml")) is None


def test_balls_file_per_frame(tmp_path):
    (tmp_path / "puffs").mkdir()
    for f in range(2):
        (tmp_path / "puffs" / f"cloud_{f:04d}.csv").write_text(f"x,y,z,radius,weight\n{f},0,0,1.0,1.0\n")
    path = write_scene(tmp_path, STATIC.replace("media: [{balls: [{center: [0, 0, 0], radius: 1.5}]}]",
                                                "media: [{balls_file: 'puffs/cloud_{frame:04d}.csv'}]"))
    assert cm.load_scene(path, frame=1).media[0].blob.centers[0].tolist() == [1, 0, 0]
    with pytest.raises(cm.SceneError, match=r"scene.yaml: frame 2: media\[0\].balls_file: cannot read"):
        cm.load_scene(path, frame=2)


@pytest.mark.parametrize("change, message", [
    # a value that is valid at the keys but not in between is refused at the frame that has it
    (("radius: 1.2", "radius: {keys: {0: 1.2, 2: 0.0}}"),
     r"scene.yaml: frame 2: media\[0\].balls\[0\].radius: expected a finite number > 0, from 1e-100 to 1e\+100, got 0.0"),
    (("interpolate: smooth}, look_at", "interpolate: cubic}, look_at"),
     r"scene.yaml: frame 1: camera.position.interpolate: expected one of linear, smooth, got the text 'cubic'"),
    (("{keys: {0: 3, 2: 5}}", "{keys: {0: 3, 2: [5, 1]}}"),
     r"frame 1: lights\[0\].irradiance.keys.2: expected a number like the other keys"),
    (("{keys: {0: 3, 2: 5}}", "{keys: {a: 3}}"),
     r"frame 1: lights\[0\].irradiance.keys: expected frame numbers \(integers\) as keys, got the text 'a'"),
    (("{keys: {0: 3, 2: 5}}", "{keys: {0: 3, 2: true}}"),
     r"frame 1: lights\[0\].irradiance.keys.2: expected a finite number or a list of finite numbers, got True"),
    (("{keys: {0: 3, 2: 5}}", "{keys: {0: 3}, ease: 1}"),
     r"frame 1: lights\[0\].irradiance.ease: unknown key in a keyframe mapping"),
    (("{keys: {0: 3, 2: 5}}", "{keys: {}}"), r"frame 1: lights\[0\].irradiance.keys: expected a mapping"),
    (("image: {width: 24,", "image: {width: {keys: {0: 24}},"),
     r"frame 1: image.width: keyframes animate the scene's values .* the image settings are fixed"),
    (("frames: 3", "frames: 0"), r"frame 1: animation.frames: expected an integer >= 1, got 0"),
    (("fps: 12", "fps: 12, length: 3"), r"frame 1: animation.length: unknown key"),
])
def test_errors_name_the_file_the_frame_and_the_key_path(tmp_path, change, message):
    text = ANIMATED.replace(*change)
    assert text != ANIMATED
    path = write_scene(tmp_path, text)
    frame = 2 if "frame 2" in message else 1
    with pytest.raises(cm.SceneError, match=message) as e:
        cm.load_scene(path, frame=frame)
    assert str(e.value).startswith(str(path))
    assert e.value.frame == frame and e.value.file == str(path)


def test_parse_frames():
    assert list(parse_frames("0:3")) == [0, 1, 2]
    assert list(parse_frames("2:9:3")) == [2, 5, 8]
    assert list(parse_frames("7")) == [7]
    for bad in ("a:b", "3:3", "1:5:0", "-1:4", "1:2:3:4", ""):
        with pytest.raises(cm.InputError, match="--frames"):
            parse_frames(bad)


# ----------------------------------------------------------------------------------- command line

def test_cli_renders_one_file_per_frame_each_equal_to_render(tmp_path, capsys):
    path = write_scene(tmp_path, ANIMATED)
    out = tmp_path / "out"
    out.mkdir()
    assert main(["render", str(path), "-o", str(out / "f_{frame:02d}.exr"), "--png", str(out / "f_{frame:02d}.png"),
                 "-q"]) == 0
    assert "rendered 3 frames" in capsys.readouterr().out
    assert sorted(os.listdir(out)) == [f"f_{f:02d}.{ext}" for f in range(3) for ext in ("exr", "png")]
    images = [cm.read_exr(out / f"f_{f:02d}.exr")[0] for f in range(3)]
    for f, image in enumerate(images):
        assert np.array_equal(image, cm.render(cm.load_scene(path, frame=f), progress=False))
    assert not np.array_equal(images[0], images[2])


def test_cli_skips_finished_frames_unless_overwrite(tmp_path, capsys):
    path = write_scene(tmp_path, STATIC)  # --frames on a static scene: the same image once per frame
    pattern = str(tmp_path / "s_{frame}.exr")
    assert main(["render", str(path), "--frames", "0:2", "-o", pattern, "-q"]) == 0
    first = [tmp_path / f"s_{f}.exr" for f in range(2)]
    assert np.array_equal(cm.read_exr(first[0])[0], cm.read_exr(first[1])[0])
    os.remove(first[1])
    old = first[0].stat().st_mtime_ns
    capsys.readouterr()
    assert main(["render", str(path), "--frames", "0:2", "-o", pattern, "-q"]) == 0  # a killed run resumes
    text = capsys.readouterr().out
    assert "skipped 1 finished frames" in text and "rendered 1 frames" in text
    assert first[0].stat().st_mtime_ns == old and first[1].exists()
    os.utime(first[0], ns=(old - 10**9, old - 10**9))
    assert main(["render", str(path), "--frames", "0:2", "-o", pattern, "--overwrite", "-q"]) == 0
    assert "rendered 2 frames" in capsys.readouterr().out
    assert first[0].stat().st_mtime_ns != old - 10**9


def test_cli_several_frames_need_a_frame_field_in_the_output(tmp_path):
    path = write_scene(tmp_path, STATIC)
    proc = subprocess.run([sys.executable, "-m", "cloudmeta.cli", "render", str(path), "--frames", "0:3", "-o",
                           str(tmp_path / "one.exr")], capture_output=True, text=True, timeout=120,
                          env=dict(os.environ, PYTHONPATH=str(ROOT)))
    assert proc.returncode == 2
    err = proc.stderr.strip().splitlines()
    assert len(err) == 1 and "one.exr: 3 frames would write the same file" in err[0] and "{frame:04d}" in err[0]
    assert not (tmp_path / "one.exr").exists()


# ------------------------------------------------------------- issue #15's rules on the frames path

def _snapshot(folder):
    return {p.name: (p.stat().st_mtime_ns, p.read_bytes() if p.is_file() else None)
            for p in sorted(Path(folder).iterdir())}


@pytest.mark.parametrize("extra, names, fragment", [
    (["-o", "missing/f_{frame}.exr"], "missing", "does not exist"),
    (["-o", "scene.yaml", "--frames", "0"], "scene.yaml", "input of the scene"),
    (["-o", "f_{frame}.exr", "--png", "f_{frame}.exr"], "--png", "ending in .png"),
    (["-o", "f_{frame}.exr", "--png", "f_{frame}.png", "--exposure", "2000"], "--exposure", "within +-64"),
], ids=["missing folder", "scene file", "exr is png", "exposure"])
def test_cli_frames_refuse_bad_outputs_before_any_work(tmp_path, monkeypatch, capsys, extra, names, fragment):
    write_scene(tmp_path, ANIMATED)
    monkeypatch.chdir(tmp_path)
    before = _snapshot(tmp_path)
    assert main(["render", "scene.yaml", "-q", *extra]) == 2
    lines = capsys.readouterr().err.splitlines()
    assert len(lines) == 1 and lines[0].startswith("cloudmeta: error: "), lines
    assert names in lines[0] and fragment in lines[0] and "Traceback" not in lines[0]
    assert _snapshot(tmp_path) == before


def test_cli_frames_refuse_an_output_that_is_a_frames_balls_file(tmp_path, monkeypatch, capsys):
    (tmp_path / "puffs").mkdir()
    for f in range(2):
        (tmp_path / "puffs" / f"c_{f}.exr").write_text(f"x,y,z,radius,weight\n{f},0,0,1.0,1.0\n")
    write_scene(tmp_path, STATIC.replace("media: [{balls: [{center: [0, 0, 0], radius: 1.5}]}]",
                                         "media: [{balls_file: 'puffs/c_{frame}.exr'}]"))
    monkeypatch.chdir(tmp_path)
    before = _snapshot(tmp_path / "puffs")
    assert main(["render", "scene.yaml", "--frames", "0:2", "-o", "puffs/c_{frame}.exr", "--overwrite", "-q"]) == 2
    err = capsys.readouterr().err
    assert "input of the scene" in err and "c_0.exr" in err
    assert _snapshot(tmp_path / "puffs") == before


@pytest.mark.parametrize("sig", ["SIGINT", "SIGTERM"])
def test_cli_frames_interrupted_exit_130_and_leave_no_temporary_files(tmp_path, sig):
    import signal
    import time
    from tests.system.children import cli_argv, signal_state
    write_scene(tmp_path, STATIC.replace("width: 24, height: 16", "width: 128, height: 128, spp: 16"))
    # SIGINT at its default in the child, whatever the test runner's (children.py: a runner started in the
    # background by a shell ignores SIGINT, and so would the render)
    proc = subprocess.Popen(cli_argv("render", "scene.yaml", "--frames", "0:50", "-o", "f_{frame}.exr",
                                     "--png", "f_{frame}.png", "-q"), cwd=tmp_path,
                            env=dict(os.environ, PYTHONPATH=str(ROOT)), stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 600  # a cold kernel cache on a loaded machine: minutes
        while not (tmp_path / "f_0.png").exists():  # a frame finished: the sequence is under way
            assert proc.poll() is None and time.monotonic() < deadline
            time.sleep(0.05)
        state = signal_state(proc.pid)
        proc.send_signal(getattr(signal, sig))
        try:
            out, err = proc.communicate(timeout=60)
        except subprocess.TimeoutExpired:
            pytest.fail(f"still running 60 s after {sig} ({state})")
    finally:
        proc.kill()
    assert proc.returncode == 130, err
    assert err == "cloudmeta: interrupted\n"
    names = os.listdir(tmp_path)
    assert not [n for n in names if ".tmp-" in n]
    assert "f_49.exr" not in names
    for n in names:  # every frame left has both of its files, complete
        if n.endswith(".exr"):
            assert n[:-4] + ".png" in names
            cm.read_exr(tmp_path / n)
