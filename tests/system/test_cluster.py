"""Frames and tiles (cloudmeta.api.cluster): tiles equal to the whole frame, and a 2-worker local Dask cluster
that renders the same bits as this process, loses no frame when a worker dies, and writes each frame once."""
import logging
import os
from pathlib import Path

import numpy as np
import pytest
from distributed import Client, LocalCluster, WorkerPlugin

import cloudmeta as cm
from cloudmeta.api.cluster import render_frames, tile_windows

from tests.scene.test_animation import ANIMATED, write_scene

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    return write_scene(tmp_path_factory.mktemp("anim"), ANIMATED)


@pytest.fixture(scope="module")
def local(scene):
    """The 3 frames rendered in this process, whole."""
    return [cm.render(cm.load_scene(scene, frame=f), progress=False) for f in range(3)]


@pytest.fixture(scope="module")
def client():
    """One 2-process cluster on loopback for the module (start-up takes seconds); its workers import this
    checkout's cloudmeta (and these tests, for the plugin below)."""
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1", dashboard_address=None,
                      silence_logs=logging.ERROR, env={"PYTHONPATH": str(ROOT)}) as cluster, Client(cluster) as c:
        where = c.run(lambda: __import__("cloudmeta").__file__)
        assert len(where) == 2 and all(Path(p).is_relative_to(ROOT) for p in where.values())
        yield c


def read(path):
    return cm.read_exr(path)[0]


def test_tile_windows_cover_the_frame_once():
    for tiles in (1, 3, (2, 2), (3, 5)):
        cover = np.zeros((16, 24), int)
        for (r0, r1), (c0, c1) in tile_windows(16, 24, tiles):
            cover[r0:r1, c0:c1] += 1
        assert np.all(cover == 1)
    with pytest.raises(cm.InputError, match="tiles"):
        tile_windows(16, 24, (2, 25))


def test_tiles_in_this_process_equal_the_whole_frame(scene, local, tmp_path):
    image = cm.load_scene(scene, frame=1)
    tiles = np.zeros_like(local[1])
    for rows, cols in tile_windows(16, 24, (2, 2)):
        tiles[rows[0]:rows[1], cols[0]:cols[1]] = cm.render(image, progress=False, rows=rows, columns=cols)
    assert np.array_equal(tiles, local[1])
    jittered = cm.load_scene(scene, frame=1, spp=4)  # stratified, jittered samples: hashed per pixel too
    whole = cm.render(jittered, progress=False)
    for rows, cols in tile_windows(16, 24, (3, 2)):
        tile = cm.render(jittered, progress=False, rows=rows, columns=cols)
        assert np.array_equal(tile, whole[rows[0]:rows[1], cols[0]:cols[1]])
    report = render_frames(scene, [1], tmp_path / "t.exr", tiles=3, progress=False)
    assert report.rendered == [1] and np.array_equal(read(tmp_path / "t.exr"), local[1])


def test_frames_on_the_cluster_are_bit_identical_to_local(scene, local, client, tmp_path):
    report = render_frames(scene, range(3), tmp_path / "f_{frame:04d}.exr", png=tmp_path / "f_{frame:04d}.png",
                           client=client, progress=False)
    assert sorted(report.rendered) == [0, 1, 2] and report.skipped == []
    here = tmp_path / "here"
    here.mkdir()
    mine = render_frames(scene, range(3), here / "f_{frame:04d}.exr", png=here / "f_{frame:04d}.png", progress=False)
    assert mine.stops == report.stops and report.exposure_frame == 0
    for f in range(3):
        assert np.array_equal(read(tmp_path / f"f_{f:04d}.exr"), local[f])
        # the PNGs too: one exposure, from frame 0, whatever order the frames came back in
        assert (tmp_path / f"f_{f:04d}.png").read_bytes() == (here / f"f_{f:04d}.png").read_bytes()
    assert len(os.listdir(tmp_path)) == 7  # no temporary file left (6 files and the folder "here")


def test_a_2x2_tiled_frame_on_the_cluster_equals_the_whole_frame(scene, local, client, tmp_path):
    report = render_frames(scene, [2], tmp_path / "tiled.exr", tiles=(2, 2), client=client, progress=False)
    assert report.rendered == [2]
    assert np.array_equal(read(tmp_path / "tiled.exr"), local[2])


class DieOnce(WorkerPlugin):
    """Kills its worker process (no clean-up, as a crash or a lost machine) when a task whose key holds
    ``needle`` starts, the first time only: a marker file remembers it."""

    def __init__(self, marker, needle):
        self.marker, self.needle = str(marker), needle

    def transition(self, key, start, finish, **kwargs):
        if finish == "executing" and self.needle in str(key) and not os.path.exists(self.marker):
            Path(self.marker).write_text(str(os.getpid()))
            os._exit(1)


def test_a_worker_killed_mid_run_loses_no_frame(scene, local, client, tmp_path):
    marker = tmp_path / "killed"
    out = tmp_path / "out"
    out.mkdir()
    pids = set(client.run(os.getpid).values())
    client.register_plugin(DieOnce(marker, "-frame-1-"), name="die-once")
    try:
        report = render_frames(scene, range(3), out / "f_{frame}.exr", client=client, progress=False)
    finally:
        client.unregister_worker_plugin("die-once")
    assert marker.exists() and int(marker.read_text()) in pids  # a worker did die, in the middle of frame 1
    assert sorted(report.rendered) == [0, 1, 2]  # each frame written once
    assert sorted(os.listdir(out)) == ["f_0.exr", "f_1.exr", "f_2.exr"]  # and no partial file
    for f in range(3):
        assert np.array_equal(read(out / f"f_{f}.exr"), local[f])
    client.wait_for_workers(2, timeout=120)  # the nanny restarted it
    assert set(client.run(os.getpid).values()) != pids


def test_a_rerun_on_the_cluster_skips_finished_frames(scene, client, tmp_path):
    pattern = tmp_path / "f_{frame}.exr"
    assert sorted(render_frames(scene, [0, 2], pattern, client=client, progress=False).rendered) == [0, 2]
    mtimes = {f: (tmp_path / f"f_{f}.exr").stat().st_mtime_ns for f in (0, 2)}
    report = render_frames(scene, range(3), pattern, client=client, progress=False)
    assert report.rendered == [1] and report.skipped == [0, 2]
    assert {f: (tmp_path / f"f_{f}.exr").stat().st_mtime_ns for f in (0, 2)} == mtimes


def test_a_bad_frame_comes_back_as_the_scene_error(tmp_path, client):
    text = ANIMATED.replace("radius: 1.2", "radius: {keys: {0: 1.2, 2: -1.0}}")
    path = write_scene(tmp_path, text)
    with pytest.raises(cm.SceneError, match=r"frame 2: media\[0\].balls\[0\].radius: expected a finite number > 0"):
        render_frames(path, [2], tmp_path / "f_{frame}.exr", client=client, progress=False)
    with pytest.raises(cm.SceneError, match=r"frame 2: media\[0\].balls\[0\].radius"):  # the first frame is not
        render_frames(path, [0, 2], tmp_path / "f_{frame}.exr", client=client, progress=False)
    assert set(os.listdir(tmp_path)) <= {"scene.yaml", "f_0.exr"}  # no partial file, nothing for frame 2


def test_cli_workers_start_a_local_cluster(scene, local, tmp_path, capsys):
    """--workers 2 --tiles 2x2: the command's own cluster (started and closed by it) writes the same bits."""
    from cloudmeta.cli import main
    assert main(["render", str(scene), "--frames", "1:3", "-o", str(tmp_path / "c_{frame}.exr"), "--workers", "2",
                 "--tiles", "2x2", "-q"]) == 0
    out = capsys.readouterr().out
    assert "on a local cluster of 2 worker processes, 4 tiles a frame" in out and "rendered 2 frames" in out
    for f in (1, 2):
        assert np.array_equal(read(tmp_path / f"c_{f}.exr"), local[f])
