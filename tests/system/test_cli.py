"""The command line: a render end to end to a readable EXR, and clean errors for bad scenes."""
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import OpenEXR
import pytest

from cloudmeta import read_exr
from cloudmeta.cli import main
from tests.system.children import cli_argv, signal_state

ROOT = Path(__file__).resolve().parents[2]


def test_render_cumulus_writes_exr_and_png(tmp_path, capsys):
    exr, png = tmp_path / "c.exr", tmp_path / "c.png"
    code = main(["render", str(ROOT / "scenes" / "cumulus.yaml"), "-o", str(exr), "--png", str(png),
                 "--width", "40", "--height", "30", "--quality", "draft", "-q"])
    assert code == 0
    out = capsys.readouterr().out
    assert "40 x 30" in out and str(exr) in out and str(png) in out and " s, " in out
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


def _lines(out):
    """stdout's lines less the notice of a first compile (once per machine)."""
    return [ln for ln in out.splitlines() if not ln.startswith("cloudmeta: compiling")]


def test_a_render_prints_one_line_in_the_users_terms(tmp_path, capsys):
    """What scene, how big, how long, the estimated error against its target, what was written: one line."""
    import re

    from cloudmeta.renderer import render_frame
    from cloudmeta.scene import load_scene
    exr, png = tmp_path / "c.exr", tmp_path / "c.png"
    scene = str(ROOT / "scenes" / "cumulus.yaml")
    assert main(["render", scene, "-o", str(exr), "--png", str(png), "--width", "40", "--height", "30",
                 "--quality", "draft", "-q"]) == 0
    lines = _lines(capsys.readouterr().out)
    assert len(lines) == 1
    match = re.fullmatch(rf"cloudmeta: {re.escape(scene)} 40 x 30, single scattering, quality draft: "
                         rf"([0-9.e+-]+) s, estimated error ([0-9.e+-]+) \(target 3\.0e-03\); "
                         rf"wrote {re.escape(str(exr))}, {re.escape(str(png))}", lines[0])
    assert match, lines[0]
    assert float(match[1]) > 0.0
    # the estimate is the calibration's measure of this frame (renders are deterministic), within its target
    result = render_frame(load_scene(scene, width=40, height=30, render={"quality": "draft"}), progress=False)
    assert match[2] == f"{result.scattered.predicted:.1e}" and float(match[2]) <= 3e-3
    assert "calibrated" not in lines[0] and "rays" not in lines[0]  # the details are behind -v


def test_verbose_adds_the_details(tmp_path, capsys):
    exr = tmp_path / "c.exr"
    assert main(["render", str(ROOT / "scenes" / "cumulus.yaml"), "-o", str(exr), "--width", "40", "--height", "30",
                 "--quality", "draft", "-q", "-v"]) == 0
    lines = _lines(capsys.readouterr().out)
    assert lines[0].startswith(f"cloudmeta: rendering {ROOT / 'scenes' / 'cumulus.yaml'}: 40 x 30, 1 spp, "
                               "quality draft, exact shadows, 77 balls in 1 media")
    calibrated = [ln for ln in lines if ln.startswith("cloudmeta: quadrature calibrated for quality draft: ")]
    assert len(calibrated) == 1 and "relative RMSE" in calibrated[0] and "rays" in calibrated[0]
    assert lines[-1].startswith(f"cloudmeta: {ROOT / 'scenes' / 'cumulus.yaml'} 40 x 30, single scattering")
    assert lines[-1].endswith(f"; wrote {exr}") and len(lines) == 3


@pytest.mark.parametrize("extra", [[], ["--error"]], ids=["image", "with --error"])
def test_overwrite_on_one_image_replaces_it_and_stays_one_image(workdir, monkeypatch, capsys, extra):
    """--overwrite means for one image what it means for frames (replace what exists), and never turns the
    render into the frames path: each run prints the one image's line, never "frames"; --error works with it."""
    monkeypatch.chdir(workdir)
    (workdir / "o.exr").write_bytes(b"old")
    for _ in range(2):
        before = (workdir / "o.exr").stat().st_mtime_ns
        assert main(SMALL + ["-o", "o.exr", "--overwrite", *extra]) == 0
        out = capsys.readouterr().out
        assert "frames" not in out and "tiles" not in out
        assert _lines(out)[-1].startswith("cloudmeta: cumulus.yaml 8 x 8, single scattering, quality draft: ")
        assert _lines(out)[-1].endswith("; wrote o.exr")
        assert (workdir / "o.exr").stat().st_mtime_ns != before
        assert (workdir / "o.exr").read_bytes()[:4] == b"\x76\x2f\x31\x01"  # the EXR magic number
    image, _ = read_exr(workdir / "o.exr")
    assert image.shape == (8, 8, 7 if extra else 4)  # with --error: the error channels too
    if extra:
        assert "estimated error" in out


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


# --- issue #15: outputs checked before any work, nothing overwritten or half-written, Ctrl-C -----------------

def _cli(args, cwd):
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    return subprocess.run([sys.executable, "-m", "cloudmeta.cli", *args], capture_output=True, text=True,
                          timeout=300, cwd=cwd, env=env)


def _snapshot(folder):
    return {p.name: (p.stat().st_mtime_ns, p.read_bytes() if p.is_file() else None)
            for p in sorted(Path(folder).iterdir())}


@pytest.fixture
def workdir(tmp_path):
    shutil.copy(ROOT / "scenes" / "cumulus.yaml", tmp_path)
    shutil.copy(ROOT / "scenes" / "cumulus.csv", tmp_path)
    (tmp_path / "adir").mkdir()
    os.mkfifo(tmp_path / "fifo.exr")
    return tmp_path


SMALL = ["render", "cumulus.yaml", "--width", "8", "--height", "8", "--quality", "draft", "-q"]
BAD_OUTPUTS = [
    (["-o", "missing/out.exr"], "folder", "does not exist"),
    (["-o", "/dev/full"], "/dev/full", "not a regular file"),
    (["-o", "fifo.exr"], "fifo.exr", "not a regular file"),
    (["-o", "adir"], "adir", "is a folder"),
    (["-o", "a" * 300 + ".exr"], "aaaa", "too long"),
    (["-o", "cumulus.yaml"], "cumulus.yaml", "input of the scene"),
    (["-o", "o.exr", "--png", "cumulus.yaml"], "--png cumulus.yaml", "input of the scene"),
    (["-o", "cumulus.csv"], "cumulus.csv", "input of the scene"),
    (["-o", "out.exr", "--png", "out.exr"], "--png out.exr", "ending in .png"),
    (["-o", "out.png"], "-o out.png", "ending in .exr"),
    (["-o", "o.exr", "--png", "missing/x.png"], "--png missing/x.png", "does not exist"),
    (["-o", "o.exr", "--png", "o.png", "--exposure", "2000"], "--exposure", "within +-64"),
    (["-o", "o.exr", "--exposure", "nan"], "--exposure", "within +-64"),
    (["-o", "o.exr", "--shadows", "map", "--shadow-map", "1000000"], "render.shadow_map", "<= 8192"),
    (["-o", "o.exr", "--width", "1000000000"], "image.width", "<= 16384"),
    (["-o", "o.exr", "--width", "abc"], "--width", "invalid int"),
    (["-o", ""], "-o", "expected a file name, got an empty path"),
    (["-o", "o.exr", "--png", ""], "--png", "expected a file name, got an empty path"),
    (["--png", ""], "--png", "expected a file name, got an empty path"),
    (["-o", "", "--frames", "0:2"], "-o", "expected a file name, got an empty path"),
]


@pytest.mark.parametrize("extra, names, fragment", BAD_OUTPUTS, ids=[" ".join(b[0])[:40] for b in BAD_OUTPUTS])
def test_bad_outputs_fail_before_any_work_and_change_nothing(workdir, monkeypatch, capsys, extra, names, fragment):
    monkeypatch.chdir(workdir)
    before = _snapshot(workdir)
    try:
        code = main(SMALL + extra)
    except SystemExit as exc:  # argparse's own errors
        code = exc.code
    assert code == 2
    out, err = capsys.readouterr()
    lines = err.splitlines()
    assert len(lines) == 1 and lines[0].startswith("cloudmeta: error: "), err
    assert names in lines[0] and fragment in lines[0]
    assert "Traceback" not in err and "rendering" not in out  # refused before the render
    assert _snapshot(workdir) == before


@pytest.mark.parametrize("extra", [["-o", "cumulus.yaml"], ["-o", "out.exr", "--png", "missing/x.png"]])
def test_bad_outputs_through_a_subprocess(workdir, extra):
    before = _snapshot(workdir)
    proc = _cli(SMALL + extra, workdir)
    assert proc.returncode == 2 and len(proc.stderr.splitlines()) == 1 and "Traceback" not in proc.stderr
    assert _snapshot(workdir) == before


@pytest.mark.parametrize("extra, written", [
    (["-o", "o.exr"], {"o.exr"}),  # -o alone: the EXR alone, not the scene's output.png beside the scene
    (["-o", "f_{frame}.exr", "--frames", "0:2"], {"f_0.exr", "f_1.exr"}),
    (["-o", "o.exr", "--png", "o.png"], {"o.exr", "o.png"}),
    ([], {"cumulus.exr", "cumulus.png"}),  # no -o: the scene's output.path and output.png
    (["--frames", "0:1"], {"cumulus.exr", "cumulus.png"}),
], ids=["-o", "-o --frames", "-o --png", "scene's", "scene's --frames"])
def test_a_png_only_where_asked_for(workdir, monkeypatch, capsys, extra, written):
    """The scene's output.png goes with its output.path: -o without --png writes no PNG (issue #27)."""
    monkeypatch.chdir(workdir)
    before = set(os.listdir(workdir))
    assert main(SMALL + extra) == 0
    capsys.readouterr()
    assert set(os.listdir(workdir)) - before == written


def test_render_frames_with_an_output_writes_no_png_unless_asked(workdir):
    """The API's sequences follow the same rule: an explicit output without png writes no PNG; an empty
    path is refused naming its label (Outputs) before any work."""
    import cloudmeta as cm
    from cloudmeta.api.cluster import Outputs
    before = set(os.listdir(workdir))
    small = dict(width=8, height=8, render={"quality": "draft"}, progress=False)
    report = cm.render_frames(workdir / "cumulus.yaml", [0], str(workdir / "f_{frame}.exr"), **small)
    assert report.outputs == {0: (str(workdir / "f_0.exr"), None)}
    assert set(os.listdir(workdir)) - before == {"f_0.exr"}
    for outputs, label in ((Outputs(exr="", exr_label="-o"), "-o"), (Outputs(png="", png_label="--png"), "--png")):
        with pytest.raises(cm.CloudmetaError, match=f"^{label}: expected a file name, got an empty path$"):
            cm.render_frames(workdir / "cumulus.yaml", [0], outputs, **small)
    assert set(os.listdir(workdir)) - before == {"f_0.exr"}


def test_version_and_plain_help(capsys):
    import cloudmeta
    with pytest.raises(SystemExit) as e:
        main(["--version"])
    assert e.value.code == 0 and capsys.readouterr().out == f"cloudmeta {cloudmeta.__version__}\n"
    assert cloudmeta.__version__ == "0.1.0"
    for argv in (["--help"], ["render", "--help"]):
        with pytest.raises(SystemExit) as e:
            main(argv)
        out = capsys.readouterr().out
        assert e.value.code == 0 and out.startswith("usage: cloudmeta")
        assert "``" not in out and ":func:" not in out  # no reST markup in the help


def test_a_failing_png_leaves_no_exr(workdir, monkeypatch, capsys):
    """Both outputs are renamed into place only when both are written: a PNG that fails to encode leaves
    neither (nor a temporary file)."""
    from cloudmeta import cli
    from cloudmeta.api import io

    def broken_png(*args, **kwargs):
        raise OSError(28, "No space left on device")
    monkeypatch.setattr(io, "encode_png", broken_png)
    monkeypatch.chdir(workdir)
    before = _snapshot(workdir)
    assert cli.main(SMALL + ["-o", "o.exr", "--png", "o.png"]) == 2
    assert "No space left on device" in capsys.readouterr().err
    assert _snapshot(workdir) == before


def test_outputs_replace_existing_files_only_on_success(workdir, monkeypatch, capsys):
    (workdir / "o.exr").write_bytes(b"old")
    monkeypatch.chdir(workdir)
    assert main(SMALL + ["-o", "o.exr", "--png", "o.png"]) == 0
    assert (workdir / "o.exr").read_bytes()[:4] == b"\x76\x2f\x31\x01"  # the EXR magic number
    assert (workdir / "o.png").read_bytes()[:4] == b"\x89PNG"
    assert not [p for p in workdir.iterdir() if ".tmp-" in p.name]


LONG = ["render", "cumulus.yaml", "--width", "256", "--height", "256", "--spp", "64", "-o", "long.exr",
        "--png", "long.png", "-q"]


def _start_long_render(workdir):
    """A long render in a child process (SIGINT at its default, see children.py), once it has reserved its
    outputs (the two temporary files exist): the render is on. Returns the Popen."""
    proc = subprocess.Popen(cli_argv(*LONG), cwd=workdir, env=dict(os.environ, PYTHONPATH=str(ROOT)),
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 600  # a cold kernel cache on a loaded machine: minutes before the render
    while len([n for n in os.listdir(workdir) if ".tmp-" in n]) < 2:
        if proc.poll() is not None or time.monotonic() > deadline:
            proc.kill()
            out, err = proc.communicate()
            pytest.fail(f"the render did not start: exit {proc.returncode}, {out!r} {err!r}")
        time.sleep(0.05)
    return proc


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
def test_interrupt_exits_130_with_one_line_and_no_temporary_files(workdir, sig):
    before = set(os.listdir(workdir))
    proc = _start_long_render(workdir)
    try:
        time.sleep(1.0)
        state = signal_state(proc.pid)  # in the message should it not exit: an ignored or blocked SIGINT
        proc.send_signal(sig)
        try:
            out, err = proc.communicate(timeout=60)
        except subprocess.TimeoutExpired:
            pytest.fail(f"still running 60 s after {sig.name} ({state})")
    finally:
        proc.kill()
    assert proc.returncode == 130, err
    assert err == "cloudmeta: interrupted\n"
    assert set(os.listdir(workdir)) == before


def test_a_render_killed_with_sigkill_leaves_temporaries_that_the_next_render_removes(workdir, monkeypatch, capsys):
    """kill -9 gives no chance to clean up: the two reserved temporary files stay (empty); the next render
    into the folder removes them (their writer is gone), and nothing else."""
    (workdir / ".notes.tmp-1.txt").write_text("not cloudmeta's")
    before = set(os.listdir(workdir))
    proc = _start_long_render(workdir)
    proc.kill()  # SIGKILL
    proc.communicate(timeout=60)  # reaped: the PID is gone
    assert proc.returncode == -signal.SIGKILL
    left = [n for n in os.listdir(workdir) if ".tmp-" in n and n not in before]
    assert sorted(n.split(".tmp-")[0] for n in left) == [".long.exr", ".long.png"]
    assert all((workdir / n).stat().st_size == 0 for n in left)
    monkeypatch.chdir(workdir)
    assert main(SMALL + ["-o", "o.exr", "--png", "o.png"]) == 0
    capsys.readouterr()
    assert set(os.listdir(workdir)) == before | {"o.exr", "o.png"}


def test_compile_jobs_cover_both_kinds_of_scene(tmp_path):
    """cloudmeta compile: its scenes load, and they are of both kinds the kernels compile for (without
    surfaces and maps: None records; with them: full records), in single and multiple scattering."""
    from cloudmeta.cli.compile import jobs
    from cloudmeta.renderer.pack import pack_scene
    from cloudmeta.scene import load_scene
    names = [name for name, _ in jobs(tmp_path)]
    assert len(names) == 6 and names[0].startswith("the ray API")
    kinds = set()
    for path in sorted(tmp_path.glob("kind*.yaml")):
        s = load_scene(path)
        assert s.ground is not None  # a placed ground: kernels.ground compiles in both kinds too
        records = pack_scene(s, 0).records
        kinds.add((records.surfaces is None, records.lights.maps is None, s.render.scattering))
    assert kinds == {(True, True, "single"), (False, False, "single"), (True, True, "multiple"),
                     (False, False, "multiple"), (True, True, "approximate")}


def test_the_summary_says_what_is_known():
    """cli.summary, without a render: the error where estimated (the image's own estimate first, else the
    calibration's measure), the target where the preset or render.error has one, the mode in words."""
    from dataclasses import replace
    from types import SimpleNamespace

    from cloudmeta.cli import summary
    from cloudmeta.renderer.approximate import ApproximationError
    from cloudmeta.renderer.quality import resolve_settings
    from cloudmeta.scene import load_scene
    scene = load_scene(ROOT / "scenes" / "cumulus.yaml", width=64, height=48)
    measured = SimpleNamespace(predicted=2.5e-4)

    def line(scene, estimated=None, scattered=measured, approximation=None, took=2.345):
        result = SimpleNamespace(settings=resolve_settings(scene), estimated=estimated, scattered=scattered,
                                 approximation=approximation)
        return summary("c.yaml", scene, result, took, ["c.exr"])

    assert line(scene) == ("cloudmeta: c.yaml 64 x 48, single scattering, quality default: 2.35 s, estimated error "
                           "2.5e-04 (target 1.0e-03); wrote c.exr")
    assert "estimated error 7.0e-04 (target 1.0e-03)" in line(scene, estimated=7e-4)
    assert "target error 1.0e-03 (not estimated; --error estimates it)" in line(scene, scattered=None)
    with_target = replace(scene, render=replace(scene.render, error=2e-3))
    assert "estimated error 1.5e-03 (target 2.0e-03)" in line(with_target, estimated=1.5e-3)
    reference = replace(scene, render=replace(scene.render, quality="reference", shadows="hybrid"), image=replace(
        scene.image, spp=4))
    assert line(reference, scattered=None) == ("cloudmeta: c.yaml 64 x 48, 4 spp, single scattering, hybrid "
                                               "shadows, quality reference: 2.35 s; wrote c.exr")
    multiple = replace(scene, render=replace(scene.render, scattering="multiple"))
    assert line(multiple, scattered=None).endswith("multiple scattering, quality default: 2.35 s; wrote c.exr")
    approximate = replace(scene, render=replace(scene.render, scattering="approximate", method="grid"))
    got = line(approximate, estimated=3e-4, approximation=ApproximationError(0.1234, 0.01, 512, 3000, 64))
    assert ("approximate multiple scattering (grid), quality default: 2.35 s, estimated error 3.0e-04 (target "
            "1.0e-03), approximation error 0.123 +- 0.010 against multiple scattering; wrote c.exr") in got
    # an estimate under its own noise is no measure: the line gives its bound, the estimate plus 2 standard errors
    got = line(approximate, estimated=3e-4, approximation=ApproximationError(0.033, 0.0364, 512, 3000, 1024))
    assert "approximation error 0.033 +- 0.036 (not resolved: at most 0.106) against multiple scattering" in got
    got = line(approximate, estimated=3e-4, approximation=ApproximationError(0.0, float("inf"), 512, 3000, 1024))
    assert "approximation error 0.000 +- inf (not resolved) against multiple scattering" in got


def test_every_error_class_is_exported_and_listed_in_the_docs():
    import inspect

    import cloudmeta
    from cloudmeta import errors
    classes = [name for name, c in inspect.getmembers(errors, inspect.isclass) if issubclass(c, errors.CloudmetaError)]
    assert sorted(classes) == ["CloudmetaError", "InputError", "OutputError", "SceneError"]
    text = (ROOT / "docs" / "errors.md").read_text()
    for name in classes:
        assert name in cloudmeta.__all__ and getattr(cloudmeta, name) is getattr(errors, name)
        assert f"| `{name}` |" in text


def test_errors_of_the_libraries_reach_the_user_as_cloudmetas(tmp_path, capsys):
    """OpenEXR's and dask's own exceptions do not escape: read_exr of a missing file is an InputError, and a
    scheduler address dask cannot use ends the command line with one line, exit 2."""
    import cloudmeta
    with pytest.raises(cloudmeta.InputError, match="missing.exr"):
        cloudmeta.read_exr(tmp_path / "missing.exr")
    pytest.importorskip("distributed")
    assert main(["render", str(ROOT / "scenes" / "cumulus.yaml"), "--frames", "1", "-o",
                 str(tmp_path / "c_{frame}.exr"), "--scheduler", "nosuchproto://nowhere:1", "-q"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("cloudmeta: error: scheduler nosuchproto://nowhere:1: cannot connect") and err.count("\n") == 1
    assert list(tmp_path.iterdir()) == []


def test_the_approximate_mode_writes_no_error_channels(workdir, monkeypatch, capsys):
    """--error in the approximate mode: the line gives the approximation's own estimate; the EXR holds no
    per-pixel error channels, which would be the quadrature's alone (docs/approximate.md)."""
    monkeypatch.chdir(workdir)
    text = (workdir / "cumulus.yaml").read_text()
    (workdir / "approx.yaml").write_text(text.replace("render: {quality: default}", "render: {quality: default, "
                                                      "scattering: approximate}").replace("ambient:", "# ambient:"))
    assert "scattering: approximate" in (workdir / "approx.yaml").read_text()
    assert main(["render", "approx.yaml", "--width", "8", "--height", "8", "--quality", "draft", "-q", "-o",
                 "a.exr", "--error"]) == 0
    assert "approximation error" in _lines(capsys.readouterr().out)[-1]
    image, _ = read_exr(workdir / "a.exr")
    assert image.shape == (8, 8, 4)
