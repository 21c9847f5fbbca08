"""Issue #15's rules, fuzzed: a few hundred seeded mutations of valid scenes (wrong types, numbers outside
the domain, unknown keys, missing keys, bad YAML, huge values, alias trees) through the loader, and a sample
through the command line. Every scene either loads to a valid Scene or is refused with a SceneError that
names the file and a key path (or, for YAML that does not parse, the line), in at most two lines; the
command line exits 2 with at most two lines on stderr, no traceback, and no file created or changed."""
import copy
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

from cloudmeta.scene import limits
from cloudmeta.errors import SceneError
from cloudmeta.scene import Scene, load_scene
from tests.scene.test_loader import BASE

ROOT = Path(__file__).resolve().parents[2]
SEED = 15
N_STRUCTURAL = 300
N_TEXTUAL = 100
N_CLI = 10

#: values a mutation puts in place of any value
ODD_VALUES = [None, True, False, "", "text", "1e3", "1_0", [], [1], [1, 2, 3, 4], {}, {"a": 1}, 0, -1, 1, 2 ** 64,
              10 ** 400, -(10 ** 400), 1e308, -1e308, 1e-300, -1e-300, 5e-324, float("inf"), float("-inf"),
              float("nan"), 1e100, 1e12, 1e-12, 0.5, 16385, 65537, 8193, 2 ** 31, "wyvill6", [1e308, 0, 0],
              [0, 0, 0], [1e-300, 1e-300, 1e-300], [float("nan"), 0, 0], ["a", "b", "c"], [[1, 2, 3]]]


def _paths(node, prefix=()):
    """Every path (tuple of keys and indices) into a loaded YAML tree."""
    out = [prefix] if prefix else []
    if isinstance(node, dict):
        for k, v in node.items():
            out += _paths(v, prefix + (k,))
    elif isinstance(node, list):
        for i, v in enumerate(node):
            out += _paths(v, prefix + (i,))
    return out


def _get(data, path):
    for key in path:
        data = data[key]
    return data


def _mutate(rng, data):
    """One random structural mutation of a copy of ``data``: a value replaced, a key removed or added, a
    list emptied or grown, a number scaled far out of range."""
    data = copy.deepcopy(data)
    paths = _paths(data)
    path = paths[rng.integers(len(paths))]
    parent, last = _get(data, path[:-1]), path[-1]
    kind = rng.integers(6)
    if kind == 0:
        parent[last] = copy.deepcopy(ODD_VALUES[rng.integers(len(ODD_VALUES))])
    elif kind == 1:
        del parent[last]
    elif kind == 2 and isinstance(parent, dict):
        parent[str(rng.choice(["colour", "radiuss", "x", "balls", "spp", "type", "name", "weight"]))] = 1
    elif kind == 3 and isinstance(parent[last], (int, float)) and not isinstance(parent[last], bool):
        parent[last] = parent[last] * float(10.0 ** rng.choice([-320, -200, -100, -12, 6, 12, 100, 200, 308]))
    elif kind == 4 and isinstance(parent[last], list) and parent[last]:
        parent[last] = parent[last] * int(rng.choice([0, 2, 50]))
    else:
        parent[last] = copy.deepcopy(ODD_VALUES[rng.integers(len(ODD_VALUES))])
    return data


def _laughs(levels, width=10):
    lines = ["    - &l0 [" + ", ".join(["x"] * width) + "]"]
    lines += [f"    - &l{i} [" + ", ".join([f"*l{i - 1}"] * width) + "]" for i in range(1, levels)]
    return "\n".join(lines)


def _text_mutation(rng, text):
    """One random textual mutation: truncated, characters inserted, YAML features a scene never needs."""
    kind = rng.integers(8)
    cut = int(rng.integers(1, len(text)))
    if kind == 0:
        return text[:cut]
    if kind == 1:
        junk = str(rng.choice(["\t", "[", "]", "{", "}", ":", "- ", "&a ", "*a", "!!python/object:os.system ",
                               "? [image, camera]\n: 1\n", "\x00", "%YAML 9.9\n", "---\n", "'", '"', "\ufeff"]))
        return text[:cut] + junk + text[cut:]
    if kind == 2:
        return text + "\n? [image, camera]\n: 1\n"
    if kind == 3:
        return "image:\n  height: 4\n  width:\n" + _laughs(int(rng.integers(7, 30))) + "\n" + \
            text.split("\n", 1)[1].replace("image:", "old_image:", 1)
    if kind == 4:
        depth = int(rng.integers(60, 5000))
        return text + "\ndeep: " + "[" * depth + "]" * depth + "\n"
    if kind == 5:
        return text.replace("64", "9" * int(rng.integers(20, 5000)), 1)
    if kind == 6:
        return text + "\nrecursive: &r [*r]\n"
    return text + "\n" + text  # every top-level key twice


def _check_scene(scene):
    assert isinstance(scene, Scene)
    assert 1 <= scene.image.width <= limits.MAX_SIDE and 1 <= scene.image.height <= limits.MAX_SIDE
    assert 1 <= scene.image.spp <= limits.MAX_SPP
    for arr in (scene.camera.position, scene.camera.look_at, scene.camera.up, scene.background):
        assert np.all(np.isfinite(arr))
    for thing in scene.media + scene.surfaces:
        assert np.all(np.isfinite(thing.blob.bounds)) and np.all(np.isfinite(thing.blob.frames))
    lo, hi = scene.bbox()
    assert 0 < np.linalg.norm(hi - lo) < np.inf


def _check_refusal(exc, file):
    assert exc.file == str(file)
    text = str(exc)
    assert text.startswith(f"{file}: ")
    assert len(text.splitlines()) <= 2, text
    # a key path, or the line of YAML that does not parse, or the file itself
    assert exc.key_path or " line " in exc.detail or "scene file" in exc.detail or \
        exc.detail.startswith("expected a mapping of sections") or exc.detail.startswith("invalid YAML"), text
    assert "Traceback" not in text


def _base_scenes(tmp_path):
    """(name, data, text) of the valid scenes the mutations start from."""
    shutil.copy(ROOT / "scenes" / "cumulus.csv", tmp_path)
    out = [("BASE", BASE)]
    for name in ("single_ball.yaml", "two_media.yaml", "cumulus.yaml", "kernels.yaml"):
        out.append((name, yaml.safe_load((ROOT / "scenes" / name).read_text())))
    return out


COUNTS = {}


def test_loader_fuzz(tmp_path):
    rng = np.random.default_rng(SEED)
    bases = _base_scenes(tmp_path)
    file = tmp_path / "fuzz.yaml"
    accepted = refused = 0
    for k in range(N_STRUCTURAL + N_TEXTUAL):
        name, data = bases[k % len(bases)]
        if k < N_STRUCTURAL:
            mutated = _mutate(rng, data)
            if rng.random() < 0.3:
                mutated = _mutate(rng, mutated)  # a second mutation now and then
            file.write_text(yaml.safe_dump(mutated, width=1000))
        else:
            file.write_text(_text_mutation(rng, yaml.safe_dump(data, width=1000)))
        try:
            scene = load_scene(file)
        except SceneError as exc:
            _check_refusal(exc, file)
            refused += 1
        else:
            _check_scene(scene)
            accepted += 1
    COUNTS.update(generated=accepted + refused, accepted=accepted, refused=refused)
    print(f"\nfuzz: {accepted + refused} generated scenes through the loader: {accepted} loaded, {refused} refused")
    assert accepted + refused == N_STRUCTURAL + N_TEXTUAL
    assert refused > 100 and accepted > 10  # the mutations reach both sides


#: refused scenes for the command line: (what, file text or a mutation of BASE)
def _cli_cases():
    base = yaml.safe_dump(BASE)
    edit = lambda f: yaml.safe_dump(f(copy.deepcopy(BASE)) or None)  # noqa: E731

    def put(path, value):
        def f(d):
            _get(d, path[:-1])[path[-1]] = value
            return d
        return yaml.safe_dump(f(copy.deepcopy(BASE)))
    return [
        ("width 1e9", put(("image", "width"), 10 ** 9)),
        ("width of 400 digits", put(("image", "width"), 10 ** 400)),
        ("spp 2**64", put(("image", "spp"), 2 ** 64)),
        ("centre 1e308", put(("media", 0, "balls", 0, "center"), [1e308, 0, 0])),
        ("irradiance 1e308", put(("lights", 0, "irradiance"), 1e308)),
        ("max_length 1e-12", put(("render", "max_length"), 1e-12)),
        ("balls_file /dev/zero", edit(lambda d: d["media"][0].pop("balls") and
                                      d["media"][0].update(balls_file="/dev/zero") or d)),
        ("complex key", base + "? [image, camera]\n: 1\n"),
        ("alias tree", "image:\n  height: 4\n  width:\n" + _laughs(30) + "\n" + base.replace("image:", "x:", 1)),
        ("truncated", base[: len(base) // 3] + "[\n"),
    ][:N_CLI]


def test_cli_fuzz_sample(tmp_path):
    """The sample through ``cloudmeta render`` as subprocesses (started together): exit 2, at most two lines
    on stderr, no traceback, nothing created or changed in the folder."""
    cases = _cli_cases()
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    procs = []
    for i, (what, text) in enumerate(cases):
        folder = tmp_path / f"case{i}"
        folder.mkdir()
        (folder / "scene.yaml").write_text(text)
        before = {p.name: p.read_bytes() for p in folder.iterdir()}
        proc = subprocess.Popen([sys.executable, "-m", "cloudmeta.cli", "render", "scene.yaml", "-o", "out.exr",
                                 "--png", "out.png", "-q"], cwd=folder, env=env, stdout=subprocess.PIPE,
                                stderr=subprocess.PIPE, text=True)
        procs.append((what, folder, before, proc))
    for what, folder, before, proc in procs:
        out, err = proc.communicate(timeout=300)
        assert proc.returncode == 2, (what, err)
        assert 1 <= len(err.splitlines()) <= 2 and "Traceback" not in err, (what, err)
        assert "scene.yaml" in err, (what, err)
        assert {p.name: p.read_bytes() for p in folder.iterdir()} == before, what
    print(f"\nfuzz: {len(procs)} refused scenes through the command line: all exit 2, one line, nothing written")


@pytest.mark.parametrize("levels", [8, 30])
def test_alias_trees_are_refused_at_once(tmp_path, levels):
    """A billion-laughs tree under a validated key: refused by the node bound (30 levels: 1e30 nodes)."""
    file = tmp_path / "laughs.yaml"
    file.write_text("image:\n  height: 4\n  width:\n" + _laughs(levels) + "\n" +
                    yaml.safe_dump(BASE).replace("image:", "x:", 1))
    with pytest.raises(SceneError) as exc:
        load_scene(file)
    _check_refusal(exc.value, file)
    if levels == 30:
        assert "YAML nodes" in exc.value.detail
