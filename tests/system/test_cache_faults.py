"""Faults of the kernel cache as a user meets them (issue #27): damaged cache files, cache folders that
cannot be written, ``cloudmeta compile`` on them. Each run is a fresh process that evaluates ``cm.field`` on
two balls (the ray API's smallest kernels: a cold compile of seconds, not minutes), with HOME redirected to
an empty folder so that anything numba's fallbacks would write (``~/.cache/numba``) shows, and the kernels'
``__pycache__`` watched for the same reason."""
import ctypes
import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace

import pytest

ROOT = Path(__file__).resolve().parents[2]
KERNELS = ROOT / "cloudmeta" / "kernels"

FIELD = """
import json, sys
import numpy as np, cloudmeta as cm
from numba.core.dispatcher import Dispatcher
b = cm.Blob(centers=[[0, 0, 0], [0.8, 0.2, 0.3]], radii=[1.5, 1.0])
values = cm.field(b, np.array([[0.0, 0.0, 0.0], [0.4, 0.1, 0.15]]))
kernels = {id(v): v for name, m in list(sys.modules.items()) if name.startswith("cloudmeta.kernels.")
           for v in vars(m).values() if isinstance(v, Dispatcher)}.values()
print(json.dumps({"field": values.tolist(),
                  "hits": sum(sum(k.stats.cache_hits.values()) for k in kernels),
                  "misses": sum(sum(k.stats.cache_misses.values()) for k in kernels)}))
"""
#: ``cloudmeta compile`` with its jobs replaced (the real ones compile every renderer: minutes)
COMPILE = """
import sys
import cloudmeta.cli.compile as precompile
precompile.jobs = lambda folder: {jobs!r}
from cloudmeta.cli import main
sys.exit(main(["compile", "--jobs", "1"]))
"""
#: kernels a run that finds them cached loads: the one it calls (trace.field_at, whose compiled code holds its
#: callees'); a cold run compiles those callees too
LOADED = 1
DISCARDED = re.compile(r"cloudmeta: the cached kernel \S+ in (\S+) could not be read \((truncated|damaged: .+)\); "
                       r"compiling it again")


def _obey_permissions():
    """preexec_fn: the child obeys file permissions as any user's process does. A root process writes into
    read-only folders (CAP_DAC_OVERRIDE), so where the tests run as root the child's bounding set loses
    that capability before it starts python (and python keeps only what the set allows)."""
    if os.geteuid() == 0:
        libc = ctypes.CDLL(None, use_errno=True)
        if libc.prctl(24, 1, 0, 0, 0) != 0:  # PR_CAPBSET_DROP, CAP_DAC_OVERRIDE
            raise OSError(ctypes.get_errno(), "prctl(PR_CAPBSET_DROP, CAP_DAC_OVERRIDE)")


def _run(tmp_path, code=FIELD, **env_extra):
    home = tmp_path / "home"
    home.mkdir(exist_ok=True)
    env = {k: v for k, v in os.environ.items()
           if k not in ("NUMBA_CACHE_DIR", "CLOUDMETA_CACHE_DIR", "CLOUDMETA_NO_CACHE", "XDG_CACHE_HOME",
                        "NUMBA_CACHE_LOCATOR_CLASSES")}
    env.update(HOME=str(home), PYTHONPATH=os.pathsep.join(p for p in (str(ROOT), env.get("PYTHONPATH")) if p),
               **env_extra)
    return subprocess.run([sys.executable, "-c", code], env=env, cwd=tmp_path, capture_output=True, text=True,
                          timeout=900, preexec_fn=_obey_permissions)


def _outside(tmp_path):
    """What numba's fallbacks would have written: anything under HOME, numba files beside the kernels."""
    return (sorted((tmp_path / "home").rglob("*")), sorted((KERNELS / "__pycache__").glob("*.nb[ic]")))


def _listing(folder):
    return {str(p.relative_to(folder)): (p.stat().st_size, p.stat().st_mtime_ns, p.stat().st_mode)
            for p in sorted(folder.rglob("*"))}


def _read_only(folder, request):
    for p in sorted(folder.rglob("*"), reverse=True) + [folder]:
        p.chmod(0o555 if p.is_dir() else 0o444)

    def writable_again():  # for pytest's clean-up where the tests do not run as root
        for p in [folder] + sorted(folder.rglob("*")):
            p.chmod(0o755 if p.is_dir() else 0o644)
    request.addfinalizer(writable_again)


@pytest.fixture(scope="module")
def pristine(tmp_path_factory):
    """A cache filled by one cold run, to copy: its folder, the field it computed, the kernels it compiled."""
    tmp_path = tmp_path_factory.mktemp("pristine")
    cache = tmp_path / "cache"
    before = _outside(tmp_path)
    proc = _run(tmp_path, CLOUDMETA_CACHE_DIR=str(cache))
    assert proc.returncode == 0, proc.stderr
    assert proc.stderr == ""
    out = json.loads(proc.stdout)
    assert out["misses"] > 0 and out["hits"] == 0
    assert _outside(tmp_path) == before
    folder, = cache.glob("numba-*")
    assert len(list(folder.rglob("*.nbi"))) == out["misses"]
    return SimpleNamespace(cache=cache, values=out["field"], kernels=out["misses"])


def _copy(pristine, tmp_path):
    cache = tmp_path / "cache"
    shutil.copytree(pristine.cache, cache)
    return cache


@pytest.mark.parametrize("damage", ["index files truncated to half", "data files truncated to half",
                                    "random bytes in every file"])
def test_a_damaged_cache_is_repaired_with_one_line(pristine, tmp_path, damage):
    cache = _copy(pristine, tmp_path)
    names = _listing(cache).keys()
    suffixes = {"index": [".nbi"], "data": [".nbc"], "random": [".nbi", ".nbc"]}[damage.split()[0]]
    for suffix in suffixes:
        for path in cache.rglob(f"*{suffix}"):
            whole = path.read_bytes()
            path.write_bytes(whole[:len(whole) // 2] if "truncated" in damage else b"\xff" + os.urandom(len(whole)))
    before = _outside(tmp_path)

    first = _run(tmp_path, CLOUDMETA_CACHE_DIR=str(cache))
    assert first.returncode == 0, first.stderr
    lines = first.stderr.splitlines()
    assert len(lines) == 1, first.stderr
    match = DISCARDED.fullmatch(lines[0])
    assert match, lines[0]
    assert Path(match[1]).parent.parent == cache
    assert (match[2] == "truncated") == ("truncated" in damage)
    out = json.loads(first.stdout)
    assert out["field"] == pristine.values
    assert out["misses"] == pristine.kernels
    assert _listing(cache).keys() == names  # the broken files replaced, nothing else left

    second = _run(tmp_path, CLOUDMETA_CACHE_DIR=str(cache))  # the repaired cache
    assert second.returncode == 0 and second.stderr == ""
    out = json.loads(second.stdout)
    assert out == {"field": pristine.values, "hits": LOADED, "misses": 0}
    assert _outside(tmp_path) == before


def test_a_read_only_cache_filled_beforehand_is_read(pristine, tmp_path, request):
    cache = _copy(pristine, tmp_path)
    _read_only(cache, request)
    listing, before = _listing(cache), _outside(tmp_path)
    proc = _run(tmp_path, CLOUDMETA_CACHE_DIR=str(cache))
    assert proc.returncode == 0, proc.stderr
    assert proc.stderr == ""  # nothing compiled, so nothing to say
    assert json.loads(proc.stdout) == {"field": pristine.values, "hits": LOADED, "misses": 0}
    assert _listing(cache) == listing
    assert _outside(tmp_path) == before


@pytest.mark.parametrize("where", ["CLOUDMETA_CACHE_DIR is a file", "CLOUDMETA_CACHE_DIR is an empty read-only folder",
                                   "NUMBA_CACHE_DIR is a read-only folder", "NUMBA_CACHE_DIR is a file"])
def test_a_cache_that_cannot_be_written_compiles_in_memory_with_one_line(pristine, tmp_path, request, where):
    variable = where.split()[0]
    path = tmp_path / "cache"
    if where.endswith("file"):
        path.write_text("not a folder\n")
    else:
        path.mkdir()
        _read_only(path, request)
    def state():
        return _listing(path) if path.is_dir() else path.read_text()
    listing, before = state(), _outside(tmp_path)

    proc = _run(tmp_path, **{variable: str(path)})
    assert proc.returncode == 0, proc.stderr
    folder = re.escape(str(path)) + (r"/numba-[0-9a-f]{16}" if variable == "CLOUDMETA_CACHE_DIR" else "")
    why = {"CLOUDMETA_CACHE_DIR is a file": "a file stands in its path",
           "NUMBA_CACHE_DIR is a file": "a file stands where the folder should be"}.get(where, "permission denied")
    assert re.fullmatch(rf"cloudmeta: kernels will be compiled on every run: {folder} is not writable \({why}\); "
                        rf"set {variable} to a writable folder\n", proc.stderr), proc.stderr
    out = json.loads(proc.stdout)
    assert out == {"field": pristine.values, "hits": 0, "misses": pristine.kernels}
    assert state() == listing
    assert _outside(tmp_path) == before


def test_compile_repairs_a_damaged_cache_and_says_where_it_is(pristine, tmp_path):
    cache = _copy(pristine, tmp_path)
    for path in cache.rglob("*.nbi"):
        path.write_bytes(path.read_bytes()[:10])
    proc = _run(tmp_path, COMPILE.format(jobs=[("the field", FIELD)]), CLOUDMETA_CACHE_DIR=str(cache))
    assert proc.returncode == 0, proc.stderr
    lines = proc.stdout.splitlines()
    assert len(lines) == 3, proc.stdout
    assert DISCARDED.fullmatch(lines[0]) and "(truncated)" in lines[0]
    assert re.fullmatch(r"cloudmeta: compiled the field in \d+ s", lines[1])
    folder, = cache.glob("numba-*")
    assert re.fullmatch(rf"cloudmeta: compiled in \d+ s; kernels cached in {re.escape(str(folder))}", lines[2])
    assert proc.stderr == ""
    after = _run(tmp_path, CLOUDMETA_CACHE_DIR=str(cache))
    assert after.stderr == ""
    assert json.loads(after.stdout) == {"field": pristine.values, "hits": LOADED, "misses": 0}


def test_compile_with_a_failed_job_claims_nothing(pristine, tmp_path):
    cache = _copy(pristine, tmp_path)
    jobs = [("the field", FIELD), ("a job that fails", "raise SystemExit('no such kernel')")]
    proc = _run(tmp_path, COMPILE.format(jobs=jobs), CLOUDMETA_CACHE_DIR=str(cache))
    assert proc.returncode == 1
    assert "cached" not in proc.stdout
    assert "cloudmeta: compiling a job that fails failed: no such kernel" in proc.stdout.splitlines()
    assert re.fullmatch(r"cloudmeta: 1 of 2 jobs failed or were not cached \(\d+ s\): a job that fails; their "
                        r"kernels compile on first use\n", proc.stderr), proc.stderr


@pytest.mark.parametrize("setting", ["a file in place of the cache", "CLOUDMETA_NO_CACHE=1"])
def test_compile_where_nothing_can_be_cached_says_so_and_fails(tmp_path, setting):
    path = tmp_path / "cache"
    path.write_text("not a folder\n")
    env = {"CLOUDMETA_CACHE_DIR": str(path)}
    if setting.startswith("CLOUDMETA_NO_CACHE"):
        env["CLOUDMETA_NO_CACHE"] = "1"
    before = _outside(tmp_path)
    proc = _run(tmp_path, COMPILE.format(jobs=[("the field", FIELD)]), **env)
    assert proc.returncode == 1
    assert proc.stdout == ""
    problem = ("caching is off \\(CLOUDMETA_NO_CACHE is set\\)" if "NO_CACHE" in setting else
               re.escape(str(path)) + r"/numba-[0-9a-f]{16} is not writable \(a file stands in its path\)")
    assert re.fullmatch(rf"cloudmeta: nothing compiled: {problem}; kernels compile in every process that needs "
                        r"them\n", proc.stderr), proc.stderr
    assert path.read_text() == "not a folder\n" and _outside(tmp_path) == before


@pytest.mark.parametrize("state", ["cached", "not writable", "caching off"])
def test_compile_notice_says_then_cached_only_where_it_is(state, monkeypatch, capsys):
    from cloudmeta.api import runtime
    from cloudmeta.kernels import config
    monkeypatch.setattr(config, "is_compiled", lambda dispatcher: False)
    monkeypatch.setattr(config, "CACHE", state != "caching off")
    monkeypatch.setattr(config, "CACHE_FOLDER", Path("/nowhere/numba-1"))
    monkeypatch.setattr(config, "_PROBLEM", "permission denied" if state == "not writable" else None)
    monkeypatch.setattr(config, "_SAID", set())
    monkeypatch.delenv("NUMBA_CACHE_DIR", raising=False)
    for _ in range(2):
        runtime.compile_notice("workers on this machine share the cache")
    out, err = capsys.readouterr()
    out = out.splitlines()
    if state == "cached":
        assert out[0] == ("cloudmeta: compiling the kernels for this machine (once per kind of scene, about a minute "
                          "on an idle core, then cached; workers on this machine share the cache)")
        assert err == ""
    elif state == "not writable":
        assert out[0] == "cloudmeta: compiling the kernels for this run (about a minute on an idle core; not cached)"
        assert err == ("cloudmeta: kernels will be compiled on every run: /nowhere/numba-1 is not writable "
                       "(permission denied); set CLOUDMETA_CACHE_DIR to a writable folder\n")  # once
    else:
        assert out[0] == ("cloudmeta: compiling the kernels for this run (about a minute on an idle core; not cached: "
                          "CLOUDMETA_NO_CACHE is set)")
        assert err == ""
    assert out == [out[0], out[0]]  # the notice at each call; the line on stderr once a process
