"""cloudmeta.api.io: linear OpenEXR out and back, sRGB PNG previews."""
import os

import numpy as np
import OpenEXR
import pytest
from PIL import Image

from cloudmeta.scene.colour import chromaticities
from cloudmeta.errors import InputError
from cloudmeta.api.io import read_exr, write_exr, write_png


def image(h=5, w=7, c=4, seed=1):
    # float32-representable values so that a FLOAT round trip is exact
    return np.random.default_rng(seed).uniform(0, 4, (h, w, c)).astype(np.float32).astype(np.float64)


def test_01_exr_round_trip_float_rgba(tmp_path):
    path = tmp_path / "a.exr"
    im = image()
    write_exr(im, path)
    with OpenEXR.File(str(path), separate_channels=True) as f:
        channels = f.channels()
        header = dict(f.header())  # a copy: File clears its own header dict when it closes
        assert set(channels) == {"R", "G", "B", "A"}
        for i, name in enumerate("RGBA"):
            assert channels[name].pixels.dtype == np.float32
            assert channels[name].pixels.shape == (5, 7)
            np.testing.assert_array_equal(channels[name].pixels, im[:, :, i])
    assert header["chromaticities"] == pytest.approx(chromaticities(), abs=1e-7)
    back, header2 = read_exr(path)
    assert back.dtype == np.float32 and back.shape == (5, 7, 4)
    np.testing.assert_array_equal(back, im)
    assert "chromaticities" in header2


def test_02_exr_half_rgb(tmp_path):
    path = tmp_path / "b.exr"
    im = image(c=3)
    write_exr(im, path, colourspace="ACEScg", half=True)
    with OpenEXR.File(str(path), separate_channels=True) as f:
        assert set(f.channels()) == {"R", "G", "B"}
        assert all(ch.pixels.dtype == np.float16 for ch in f.channels().values())
    back, header = read_exr(path)
    assert back.shape == (5, 7, 3)
    np.testing.assert_allclose(back, im, rtol=1e-3)
    assert header["chromaticities"] == pytest.approx(chromaticities("ACEScg"), abs=1e-7)


@pytest.mark.parametrize("bad, fragment", [
    (np.zeros((4, 4)), "shape"),
    (np.zeros((4, 4, 2)), "shape"),
    (np.zeros((0, 4, 3)), "shape"),
    (np.full((2, 2, 3), np.nan), "finite"),
    (np.full((2, 2, 3), "x"), "real numbers"),
])
def test_03_write_exr_refuses_bad_images(tmp_path, bad, fragment):
    with pytest.raises(InputError, match=fragment) as exc:
        write_exr(bad, tmp_path / "c.exr")
    assert str(exc.value).startswith("image")


def test_04_half_overflow_is_an_error(tmp_path):
    with pytest.raises(InputError, match="HALF"):
        write_exr(np.full((2, 2, 3), 1e6), tmp_path / "d.exr", half=True)


def test_05_png_is_srgb_rgb(tmp_path):
    path = tmp_path / "a.png"
    im = np.zeros((3, 4, 4))
    im[0, 0, :3] = 0.5
    im[1, 1, :3] = 0.25
    im[:, :, 3] = 0.3  # alpha is dropped: RGB is already over the background
    write_png(im, path, exposure=1.0, display="raw")  # raw: linear x 2 ** exposure, the sRGB curve
    px = np.asarray(Image.open(path))
    assert px.shape == (3, 4, 3) and px.dtype == np.uint8
    np.testing.assert_array_equal(px[0, 0], [255, 255, 255])
    np.testing.assert_array_equal(px[1, 1], [188, 188, 188])
    assert px[2, 3].tolist() == [0, 0, 0]


def test_atomic_output_renames_only_on_success(tmp_path):
    from cloudmeta.api.io import atomic_output
    target = tmp_path / "out.exr"
    target.write_bytes(b"old")
    try:
        with atomic_output(target) as tmp:
            assert tmp.endswith(".exr") and os.path.dirname(tmp) == str(tmp_path)
            with open(tmp, "wb") as f:
                f.write(b"half")
            raise RuntimeError("fails mid-write")
    except RuntimeError:
        pass
    assert target.read_bytes() == b"old"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.exr"]
    with atomic_output(target) as tmp:
        with open(tmp, "wb") as f:
            f.write(b"new")
    assert target.read_bytes() == b"new"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.exr"]


def test_atomic_outputs_renames_all_or_none(tmp_path):
    from cloudmeta.api.io import atomic_outputs
    a, b = tmp_path / "a.exr", tmp_path / "b.png"
    a.write_bytes(b"old")
    with pytest.raises(RuntimeError):
        with atomic_outputs([a, b]) as (ta, tb):
            open(ta, "wb").write(b"new a")
            raise RuntimeError("the second output fails")
    assert a.read_bytes() == b"old" and sorted(p.name for p in tmp_path.iterdir()) == ["a.exr"]
    with atomic_outputs([a, b]) as (ta, tb):
        open(ta, "wb").write(b"new a")
        open(tb, "wb").write(b"new b")
    assert a.read_bytes() == b"new a" and b.read_bytes() == b"new b"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.exr", "b.png"]


def test_a_failed_rename_puts_back_what_was_renamed(tmp_path, monkeypatch):
    from cloudmeta.api import io
    a, b = tmp_path / "a.exr", tmp_path / "b.png"
    a.write_bytes(b"old a")
    real = os.replace

    def replace(src, dst):
        if str(dst) == str(b):
            raise OSError(5, "Input/output error")
        return real(src, dst)
    monkeypatch.setattr(io.os, "replace", replace)
    with pytest.raises(OSError):
        with io.atomic_outputs([a, b]) as (ta, tb):
            open(ta, "wb").write(b"new a")
            open(tb, "wb").write(b"new b")
    monkeypatch.setattr(io.os, "replace", real)
    assert a.read_bytes() == b"old a" and sorted(p.name for p in tmp_path.iterdir()) == ["a.exr"]


@pytest.mark.parametrize("name, ext, fragment", [
    ("x.png", ".exr", "ending in .exr"),
    ("missing/x.exr", ".exr", "does not exist"),
    ("a" * 300 + ".exr", ".exr", "too long"),
    ("/dev/null", ".exr", "not a regular file"),
    ("sub", ".exr", "is a folder"),
    ("in.yaml", ".exr", "input of the scene"),
    ("link.exr", ".exr", "input of the scene"),
])
def test_check_output_path(tmp_path, monkeypatch, name, ext, fragment):
    from cloudmeta.errors import OutputError
    from cloudmeta.api.io import check_output_path
    monkeypatch.chdir(tmp_path)
    (tmp_path / "sub").mkdir()
    (tmp_path / "in.yaml").write_text("x")
    os.link(tmp_path / "in.yaml", tmp_path / "link.exr")  # a hard link to an input
    with pytest.raises(OutputError, match=fragment):
        check_output_path(name, ext, "-o", inputs=[str(tmp_path / "in.yaml")])
    assert check_output_path("fine.exr", ".exr", "-o") == str(tmp_path / "fine.exr")


def test_png_exposure_is_bounded(tmp_path):
    with pytest.raises(InputError, match="exposure"):
        write_png(np.zeros((2, 2, 3)), tmp_path / "a.png", exposure=2000)
    assert not list(tmp_path.iterdir())


def test_outputs_get_ordinary_permissions_not_mkstemps(tmp_path):
    from cloudmeta.api.io import _UMASK, atomic_output, atomic_outputs
    with atomic_output(tmp_path / "a.exr") as tmp:
        open(tmp, "wb").close()
    with atomic_outputs([tmp_path / "b.exr", tmp_path / "b.png"]) as tmps:
        for t in tmps:
            open(t, "wb").close()
    for name in ("a.exr", "b.exr", "b.png"):
        assert (tmp_path / name).stat().st_mode & 0o777 == 0o666 & ~_UMASK


# --- issue #27: what a killed writer leaves, and errors that name the user's path ------------------------------

def _dead_pid():
    """The PID of a process that has just ended (and been reaped)."""
    import subprocess
    import sys
    proc = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True)
    return int(proc.stdout)


def test_a_writer_killed_with_sigkill_leaves_temporaries_that_the_next_write_removes(tmp_path):
    import subprocess
    import sys
    code = ("import os, signal, sys\n"
            "from cloudmeta.api.io import atomic_outputs\n"
            "block = atomic_outputs([sys.argv[1], sys.argv[2]])\n"
            "block.__enter__()\n"
            "os.kill(os.getpid(), signal.SIGKILL)\n")
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    proc = subprocess.run([sys.executable, "-c", code, str(tmp_path / "a.exr"), str(tmp_path / "a.png")],
                          env=dict(os.environ, PYTHONPATH=root), capture_output=True, timeout=120)
    assert proc.returncode == -9, proc.stderr
    left = sorted(p.name for p in tmp_path.iterdir())
    assert len(left) == 2 and left[0].startswith(".a.exr.tmp-") and left[1].startswith(".a.png.tmp-"), left
    assert all((tmp_path / n).stat().st_size == 0 for n in left)
    write_exr(image(), tmp_path / "b.exr")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["b.exr"]


def test_only_stale_temporaries_of_cloudmetas_kind_from_this_machine_are_swept(tmp_path):
    import subprocess
    import sys
    from cloudmeta.api.io import _HOST, sweep_stale
    dead, other = _dead_pid(), "000000" if _HOST != "000000" else "111111"
    stale = [f".a.exr.tmp-{dead}-{_HOST}-abcd1234.exr", f".a.png.tmp-{dead}-{_HOST}-abcd1234.png",
             f".a.exr.tmp-{dead}-{_HOST}-abcd1234.exr.old", f".x.tmp-{dead}-{_HOST}-abcd1234"]
    kept = [f".b.exr.tmp-{os.getpid()}-{_HOST}-abcd1234.exr",   # a live writer (this process)
            f".c.exr.tmp-{dead}-{other}-abcd1234.exr",          # another machine's: its PID means nothing here
            ".d.exr.tmp-abcd1234.exr",                          # no PID (cloudmeta before #27): unknown writer
            f".e.exr.tmp-{dead}-{_HOST}-abcd1234.png",          # not the extension of its name
            f".f.exr.tmp-{dead}-{_HOST}-notes.txt",             # someone else's name
            f"g.exr.tmp-{dead}-{_HOST}-abcd1234.exr",           # not hidden
            f".h.exr.tmp-{dead}-{_HOST}-abcd1234.exr",          # locked: a writer in another PID namespace
            "a.exr"]
    for name in stale + kept:
        (tmp_path / name).write_bytes(b"")
    os.symlink(tmp_path / "a.exr", tmp_path / f".s.exr.tmp-{dead}-{_HOST}-abcd1234.exr")  # not a file: kept
    kept.append(f".s.exr.tmp-{dead}-{_HOST}-abcd1234.exr")
    locked = f".h.exr.tmp-{dead}-{_HOST}-abcd1234.exr"
    holder = subprocess.Popen([sys.executable, "-c", "import fcntl, sys; f = open(sys.argv[1]); "
                               "fcntl.flock(f, fcntl.LOCK_EX); print('locked', flush=True); sys.stdin.read()",
                               str(tmp_path / locked)], stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline() == "locked\n"
        assert sorted(sweep_stale(tmp_path)) == sorted(stale)
    finally:
        holder.communicate("")
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(kept)


def test_a_temporary_file_is_locked_while_its_writer_works(tmp_path):
    from cloudmeta.api.io import _lock_free, atomic_outputs, sweep_stale
    with atomic_outputs([tmp_path / "a.exr"]) as (tmp,):
        assert not _lock_free(tmp)
        assert sweep_stale(tmp_path) == []
        assert os.path.exists(tmp)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.exr"]


@pytest.mark.parametrize("target, fragment", [
    ("missing/a.exr", "missing/a.exr: cannot create a file in"),
    ("", "path: expected a file name, got an empty path"),
    (".", "is a folder"),
])
def test_write_errors_name_the_users_path_not_the_temporary_file(tmp_path, monkeypatch, target, fragment):
    from cloudmeta.errors import OutputError
    monkeypatch.chdir(tmp_path)
    for write in (write_exr, write_png):
        with pytest.raises(OutputError, match=fragment) as e:
            write(image(), target)
        assert ".tmp-" not in str(e.value)
    assert not list(tmp_path.iterdir())


def test_a_failed_encode_names_the_users_path(tmp_path, monkeypatch):
    from cloudmeta.api import io

    def full(image, path, *args):
        raise OSError(f"cannot write {path}: disk full")
    monkeypatch.setattr(io, "encode_exr", full)
    with pytest.raises(OSError, match="a.exr: disk full") as e:
        io.write_exr(image(), tmp_path / "a.exr")
    assert ".tmp-" not in str(e.value) and not list(tmp_path.iterdir())


def test_check_output_path_refuses_an_empty_path():
    from cloudmeta.errors import OutputError
    from cloudmeta.api.io import check_output_path
    with pytest.raises(OutputError, match="^-o: expected a file name, got an empty path$"):
        check_output_path("", ".exr", "-o")
