"""OpenVDB float grids in, as a dense VoxelGrid: a small reader of the .vdb file format in numpy.

Supported (anything else is refused with one line naming the file):

    file format      versions 222-225 (OpenVDB 2.0 onwards), with grid offsets
    grid types       Tree_float_5_4_3 (also saved as half floats, "_HalfFloat"), Tree_double_5_4_3
    compression      none, zlib, Blosc (optional extra: the blosc package), active-mask compression
    tree             root tiles, tiles of constant value in both internal levels, leaves
    transform        UniformScaleTranslateMap, ScaleTranslateMap, UniformScaleMap, ScaleMap,
                     TranslationMap, and an AffineMap without rotation or shear (negative scales flip)
    grid class       fog volume or unknown, background 0 (a level set is refused)

The dense box spans the grid's active voxels (active tiles included, as OpenVDB's active-voxel bounding
box); every voxel in it takes the tree's value there, active or not (the background where nothing is
stored). A voxel of index (i, j, k) is centred at index-space point (i, j, k), so the box runs from
imin - 0.5 to imax + 0.5 through the transform. The box's unit is "" (a .vdb states none) unless the grid
carries a string metadata "units".

The layout (little-endian) as OpenVDB writes it: a header (magic, format and library versions, grid-offset
flag, UUID), file metadata, then per grid a descriptor (name, type, instance parent, offsets) followed by the
grid: its compression flags, metadata, transform, topology (root background, tiles, children; each internal
node's child and value masks and its compressed tile values; each leaf's value mask) and then the leaf
buffers, depth first with root children in coordinate order.
"""
from __future__ import annotations

import functools
import struct
import zlib
from pathlib import Path

import numpy as np

from ..errors import InputError

MAGIC = b" BDV\x00\x00\x00\x00"  # the int64 0x56444220
#: format versions read here: per-grid compression and node-mask compression (222) to half grids (225)
VERSIONS = range(222, 226)
GRID_TYPES = {"Tree_float_5_4_3": np.dtype("<f4"), "Tree_double_5_4_3": np.dtype("<f8")}
HALF_SUFFIX = "_HalfFloat"
NAME_SEPARATOR = "\x1e"  # between a grid's name and the number that makes it unique in its file
COMPRESS_ZIP, COMPRESS_ACTIVE_MASK, COMPRESS_BLOSC = 0x1, 0x2, 0x4
#: node-mask compression: what follows the per-node flag byte
(NO_MASK_OR_INACTIVE_VALS, NO_MASK_AND_MINUS_BG, NO_MASK_AND_ONE_INACTIVE_VAL, MASK_AND_NO_INACTIVE_VALS,
 MASK_AND_ONE_INACTIVE_VAL, MASK_AND_TWO_INACTIVE_VALS, NO_MASK_AND_ALL_VALS) = range(7)
#: log2 of the node widths, root's children first (5-4-3: 4096, 128 and 8 voxels wide)
LOG2 = (5, 4, 3)
#: the densest grid read: float64 voxels (8 bytes each)
MAX_VOXELS = 1 << 30


class _Bytes:
    """A cursor over the file's bytes: every read is bounds-checked, so a truncated file stops at its end
    with one line."""

    def __init__(self, data, path):
        self.data, self.pos, self.path = memoryview(data), 0, path

    def fail(self, message):
        raise InputError(f"{self.path}: {message} (at byte {self.pos})")

    def take(self, n, what):
        if n < 0 or self.pos + n > len(self.data):
            raise InputError(f"{self.path}: truncated file: {what} needs {n} bytes at byte {self.pos}, "
                             f"the file has {len(self.data)}")
        chunk = self.data[self.pos:self.pos + n]
        self.pos += n
        return chunk

    def unpack(self, fmt, what):
        values = struct.unpack("<" + fmt, self.take(struct.calcsize("<" + fmt), what))
        return values if len(values) > 1 else values[0]

    def string(self, what):
        n = self.unpack("I", what)
        if n > 1 << 20:
            self.fail(f"corrupt file: {what} claims {n} bytes")
        return bytes(self.take(n, what)).decode("utf-8", errors="replace")

    def array(self, dtype, count, what):
        dtype = np.dtype(dtype)
        return np.frombuffer(self.take(dtype.itemsize * count, what), dtype=dtype, count=count)

    def mask(self, bits, what):
        """A node mask of ``bits`` bits as a bool array (bit n: word n >> 6, bit n & 63, little-endian)."""
        return np.unpackbits(self.array(np.uint8, bits // 8, what), bitorder="little").astype(bool)

    def seek(self, pos, what):
        if not 0 <= pos <= len(self.data):
            self.fail(f"corrupt file: {what} points to byte {pos}, outside the file ({len(self.data)} bytes)")
        self.pos = pos


def read_vdb(path, *, variable=None, time=None, box=None):
    """The raw grid (grid.read_grid's record) of a float grid of a .vdb file."""
    path = Path(path)
    if time is not None:
        raise InputError(f"{path}: a time index applies to NetCDF files only")
    if box is not None:
        raise InputError(f"{path}: a .vdb file's transform gives the box: drop the box argument")
    f, version, (name, kind, grid_pos, end_pos) = _open(path, variable)
    where = f"{path}: grid {name!r}"
    half = kind.endswith(HALF_SUFFIX)
    f.seek(grid_pos, f"grid {name!r}'s offset")
    density, lower, upper, units = _grid(f, GRID_TYPES[kind.removesuffix(HALF_SUFFIX)], half, where)
    if f.pos != end_pos:
        raise InputError(f"{where}: corrupt file: the grid ends at byte {f.pos}, its descriptor says {end_pos}")
    return {"values": density, "lower": lower, "upper": upper, "units": units, "variable": name,
            "value_units": ""}


def describe_vdb(path, *, variable=None):
    """What ``read_vdb`` would read, without the voxels: {"version", "grid", "type", "half", "compression"
    (the flags: 1 zlib, 2 active mask, 4 Blosc), "class", "transform", "scale", "translation"}."""
    path = Path(path)
    f, version, (name, kind, grid_pos, _) = _open(path, variable)
    f.seek(grid_pos, f"grid {name!r}'s offset")
    compression = f.unpack("I", "grid compression")
    meta = _metadata(f, "grid metadata")
    start = f.pos
    transform = f.string("transform type")
    f.pos = start
    scale, translation = _transform(f, f"{path}: grid {name!r}")
    return {"version": version, "grid": name, "type": kind.removesuffix(HALF_SUFFIX),
            "half": kind.endswith(HALF_SUFFIX), "compression": compression, "class": meta.get("class", "unknown"),
            "transform": transform, "scale": scale.tolist(), "translation": translation.tolist()}


def _open(path, variable):
    """(cursor, format version, (name, type, grid offset, end offset)) of the grid to read: ``variable``, or
    the file's only grid; an InputError for a file or grid this reader does not take."""
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise InputError(f"{path}: cannot read ({exc.strerror or exc})") from None
    f = _Bytes(data, path)
    version = _header(f)
    _metadata(f, "file metadata")
    count = f.unpack("i", "grid count")
    if count < 0:
        f.fail(f"corrupt file: grid count {count}")
    grids = []
    for _ in range(count):
        unique = f.string("grid name")
        kind = f.string("grid type")
        parent = f.string("instance parent")
        grid_pos, _, end_pos = f.unpack("qqq", "grid offsets")  # grid, its leaf buffers, its end
        name = unique.split(NAME_SEPARATOR)[0]
        grids.append((name, kind, parent, grid_pos, end_pos))
        if (variable is None and count == 1) or name == variable:
            break
        f.seek(end_pos, f"grid {name!r}'s end offset")
    if grids and (grids[-1][0] == variable or (variable is None and count == 1)):
        name, kind, parent, grid_pos, end_pos = grids[-1]
    else:
        listed = ", ".join(f"{n} ({k})" for n, k, *_ in grids) or "none"
        what = f"no grid named {variable!r}" if variable is not None else f"{count} grids: name the one to read"
        raise InputError(f"{path}: {what} (grids: {listed})")
    where = f"{path}: grid {name!r}"
    if kind.removesuffix(HALF_SUFFIX) not in GRID_TYPES:
        raise InputError(f"{where}: unsupported grid type {kind} (expected {' or '.join(GRID_TYPES)}, "
                         f"optionally {HALF_SUFFIX})")
    if parent:
        raise InputError(f"{where}: an instance of grid {parent!r}: unsupported (write the grid itself)")
    return f, version, (name, kind, grid_pos, end_pos)


def _header(f):
    magic = bytes(f.take(8, "magic number"))
    if magic != MAGIC:
        raise InputError(f"{f.path}: not an OpenVDB file (bad magic number {magic.hex()})")
    version = f.unpack("I", "file format version")
    if version not in VERSIONS:
        raise InputError(f"{f.path}: unsupported OpenVDB file format version {version} "
                         f"(read: {VERSIONS.start}-{VERSIONS.stop - 1})")
    f.unpack("II", "library version")
    if not f.unpack("B", "grid offset flag"):
        raise InputError(f"{f.path}: a VDB stream without grid offsets: unsupported (save it as a file)")
    f.take(36, "UUID")
    return version


def _metadata(f, what):
    """{name: value} of a metadata map; string, bool and number values decoded, others kept as bytes."""
    count = f.unpack("I", f"{what} count")
    if count > 1 << 20:
        f.fail(f"corrupt file: {what} claims {count} entries")
    meta = {}
    for _ in range(count):
        name = f.string(f"{what} name")
        kind = f.string(f"{what} {name!r} type")
        size = f.unpack("I", f"{what} {name!r} size")
        raw = bytes(f.take(size, f"{what} {name!r}"))
        formats = {"bool": "?", "int32": "i", "int64": "q", "float": "f", "double": "d"}
        if kind == "string":
            meta[name] = raw.decode("utf-8", errors="replace")
        elif kind in formats and size == struct.calcsize(formats[kind]):
            meta[name] = struct.unpack("<" + formats[kind], raw)[0]
        else:
            meta[name] = raw
    return meta


def _grid(f, dtype, half, where):
    """(dense float64 density, lower, upper, units) of the grid that starts at the cursor."""
    compression = f.unpack("I", "grid compression")
    if compression & ~(COMPRESS_ZIP | COMPRESS_ACTIVE_MASK | COMPRESS_BLOSC):
        raise InputError(f"{where}: unsupported compression flags {compression:#x}")
    meta = _metadata(f, "grid metadata")
    grid_class = meta.get("class", "unknown")
    if grid_class not in ("fog volume", "unknown", ""):
        raise InputError(f"{where}: grid class {grid_class!r}: expected a fog volume (density), not a "
                         f"{grid_class}")
    units = meta.get("units", "")
    units = units if isinstance(units, str) else ""
    scale, translation = _transform(f, where)
    codec = _Codec(f, compression, dtype, half, where)
    tree = _topology(f, dtype, codec, where)
    _buffers(f, tree, codec)
    lo, hi, density = _dense(tree, where)
    # index-space voxel (i, j, k) spans (i - 0.5, i + 0.5) per axis, mapped by world = index * scale + t
    a = (lo - 0.5) * scale + translation
    b = (hi + 0.5) * scale + translation
    for axis in np.flatnonzero(scale < 0):
        density = np.flip(density, axis)
    return density, np.minimum(a, b), np.maximum(a, b), units


def _transform(f, where):
    """(scale, translation), each (3,), of an axis-aligned map: world = index * scale + translation."""
    kind = f.string("transform type")
    vec = lambda what: np.array(f.unpack("ddd", what))  # noqa: E731
    if kind in ("UniformScaleTranslateMap", "ScaleTranslateMap"):
        translation, scale = vec("translation"), vec("scale")
        f.take(4 * 24, "map cache")  # voxel size, inverse scale and its square, inverse twice scale
    elif kind in ("UniformScaleMap", "ScaleMap"):
        translation, scale = np.zeros(3), vec("scale")
        f.take(4 * 24, "map cache")
    elif kind == "TranslationMap":
        translation, scale = vec("translation"), np.ones(3)
    elif kind == "AffineMap":
        m = np.array(f.unpack("d" * 16, "affine matrix")).reshape(4, 4)  # row vectors: world = (i, j, k, 1) m
        linear = m[:3, :3]
        if np.any(linear != np.diag(np.diag(linear))) or np.any(m[:3, 3] != 0) or m[3, 3] != 1:
            raise InputError(f"{where}: unsupported transform: an AffineMap with rotation, shear or projection "
                             f"(only scale and translation)")
        translation, scale = m[3, :3].copy(), np.diag(linear).copy()
    else:
        raise InputError(f"{where}: unsupported transform {kind} (only scale and translation)")
    if not (np.all(np.isfinite(scale)) and np.all(np.isfinite(translation)) and np.all(scale != 0)):
        raise InputError(f"{where}: corrupt transform: scale {scale.tolist()}, translation {translation.tolist()}")
    return scale, translation


class _Codec:
    """Reads a node's compressed values (OpenVDB's readCompressedValues): a flag byte, up to two inactive
    values and a selection mask, then the active values (mask compression) or all of them, half floats
    where the grid was saved so, each chunk raw, zlib or Blosc."""

    def __init__(self, f, compression, dtype, half, where):
        self.f, self.dtype, self.where = f, dtype, where
        self.stored = np.dtype("<f2") if half else dtype
        self.half = half
        self.mask_compressed = bool(compression & COMPRESS_ACTIVE_MASK)
        self.blosc = bool(compression & COMPRESS_BLOSC)
        self.zip = bool(compression & COMPRESS_ZIP) and not self.blosc
        self.background = 0.0
        self._blosc = _blosc_module(where) if self.blosc else None

    def values(self, count, active):
        f = self.f
        flag = f.unpack("b", "mask-compression flag")
        if not 0 <= flag <= NO_MASK_AND_ALL_VALS:
            f.fail(f"corrupt file: mask-compression flag {flag}")
        inactive1 = self.background
        inactive0 = self.background if flag == NO_MASK_OR_INACTIVE_VALS else -self.background
        if flag in (NO_MASK_AND_ONE_INACTIVE_VAL, MASK_AND_ONE_INACTIVE_VAL, MASK_AND_TWO_INACTIVE_VALS):
            inactive0 = float(f.array(self.dtype, 1, "inactive value")[0])
            if flag == MASK_AND_TWO_INACTIVE_VALS:
                inactive1 = float(f.array(self.dtype, 1, "inactive value")[0])
        selection = None
        if flag in (MASK_AND_NO_INACTIVE_VALS, MASK_AND_ONE_INACTIVE_VAL, MASK_AND_TWO_INACTIVE_VALS):
            selection = f.mask(count, "selection mask")
        stored = count
        if self.mask_compressed and flag != NO_MASK_AND_ALL_VALS:
            stored = int(np.count_nonzero(active))
        read = self._chunk(stored)
        if stored == count:
            return read
        out = np.full(count, inactive0, dtype=np.float64)
        if selection is not None:
            out[selection] = inactive1
        out[active] = read
        return out

    def _chunk(self, count):
        f, dtype = self.f, self.stored
        nbytes = count * dtype.itemsize
        if self.half and count < 1:
            return np.zeros(0)  # OpenVDB writes nothing at all for no half values
        if not (self.blosc or self.zip):
            return f.array(dtype, count, "voxel values").astype(np.float64)
        size = f.unpack("q", "compressed chunk size")
        if size <= 0:
            if -size != nbytes:
                f.fail(f"corrupt file: an uncompressed chunk of {-size} bytes where {nbytes} were expected")
            return f.array(dtype, count, "voxel values").astype(np.float64)
        packed = bytes(f.take(size, "compressed voxel values"))
        try:
            raw = self._blosc_decompress(packed, nbytes) if self.blosc else zlib.decompress(packed)
        except Exception as exc:  # zlib.error, blosc's own error type, ValueError from the header check
            f.fail(f"corrupt {'Blosc' if self.blosc else 'zlib'} chunk ({' '.join(str(exc).split())})")
        if len(raw) != nbytes:
            f.fail(f"corrupt file: a chunk decompressed to {len(raw)} bytes where {nbytes} were expected")
        return np.frombuffer(raw, dtype=dtype).astype(np.float64)

    def _blosc_decompress(self, packed, nbytes):
        # check Blosc's own header (sizes of the chunk, compressed and not) before handing it over
        if len(packed) < 16:
            raise ValueError("chunk shorter than its header")
        raw_size, _, packed_size = struct.unpack("<III", packed[4:16])
        if raw_size != nbytes or packed_size != len(packed):
            raise ValueError(f"header gives {raw_size} bytes from {packed_size}, expected {nbytes} from "
                             f"{len(packed)}")
        return self._blosc.decompress(packed)


def _blosc_module(where):
    try:
        import blosc
    except ImportError:
        raise InputError(f"{where}: Blosc-compressed: reading it needs the optional extra fit: pip install blosc "
                         "(or pip install -e '.[fit]')") from None
    return blosc


@functools.lru_cache(maxsize=None)
def _offsets(log2, child_total):
    """(n, 3) local origins of a node's n = 2^(3 log2) entries, in index units, entry n = x << 2 log2 |
    y << log2 | z."""
    dim = 1 << log2
    n = np.arange(dim ** 3)
    local = np.stack([n >> (2 * log2), (n >> log2) & (dim - 1), n & (dim - 1)], axis=1) << child_total
    local.flags.writeable = False
    return local


def _topology(f, dtype, codec, where):
    """The tree's tiles (origin, width, value, active) and leaves (origin, value mask), leaves in the order
    of their buffers."""
    buffers = f.unpack("i", "buffer count")
    if buffers != 1:
        f.fail(f"corrupt or unsupported tree: {buffers} buffers (expected 1)")
    background = float(f.array(dtype, 1, "background")[0])
    if background != 0:
        raise InputError(f"{where}: background value {background:g}, expected 0 (a density is 0 outside its "
                         f"voxels)")
    codec.background = background
    tiles, leaves = [], []
    n_tiles, n_children = f.unpack("II", "root tile and child counts")
    widths = [1 << sum(LOG2[i:]) for i in range(len(LOG2))]  # 4096, 128, 8
    for _ in range(n_tiles):
        origin = np.array(f.unpack("iii", "root tile origin"))
        value = float(f.array(dtype, 1, "root tile value")[0])
        active = f.unpack("?", "root tile state")
        tiles.append((origin, widths[0], value, active))
    children = []
    for _ in range(n_children):
        origin = f.unpack("iii", "root child origin")
        if any(o % widths[0] for o in origin):
            f.fail(f"corrupt file: root child origin {origin} not a multiple of {widths[0]}")
        children.append((origin, _internal(f, np.array(origin), 0, codec, tiles, widths)))
    # OpenVDB reads buffers in the root's table order: children sorted by origin (x, then y, then z)
    for _, leaf_list in sorted(children, key=lambda c: c[0]):
        leaves.extend(leaf_list)
    return tiles, leaves


def _internal(f, origin, level, codec, tiles, widths):
    """An internal node's topology (masks, tile values, children); its leaves as [(origin, mask)]."""
    log2 = LOG2[level]
    count = 1 << (3 * log2)
    children = f.mask(count, "child mask")
    active = f.mask(count, "value mask")
    values = codec.values(count, active)
    child_total = sum(LOG2[level + 1:])
    local = _offsets(log2, child_total)
    tile = ~children
    for n in np.flatnonzero(tile & ((values != 0) | active)):  # tiles of the background that are inactive add nothing
        tiles.append((origin + local[n], widths[level + 1], float(values[n]), bool(active[n])))
    leaves = []
    for n in np.flatnonzero(children):
        if level + 1 < len(LOG2) - 1:
            leaves.extend(_internal(f, origin + local[n], level + 1, codec, tiles, widths))
        else:
            leaves.append((origin + local[n], f.mask(1 << (3 * LOG2[-1]), "leaf value mask")))
    return leaves


def _buffers(f, tree, codec):
    """Each leaf's buffer: its value mask again, then its compressed values (stored into the leaf list)."""
    _, leaves = tree
    size = 1 << (3 * LOG2[-1])
    for i, (origin, mask) in enumerate(leaves):
        again = f.mask(size, "leaf value mask")
        if not np.array_equal(again, mask):
            f.fail(f"corrupt file: leaf at {origin.tolist()} has two different value masks")
        leaves[i] = (origin, mask, codec.values(size, mask))


def _dense(tree, where):
    """(index lower corner, index upper corner, dense values) over the active voxels' bounding box."""
    tiles, leaves = tree
    dim = 1 << LOG2[-1]
    lows, highs = [], []
    for origin, width, value, active in tiles:
        if active:
            lows.append(origin)
            highs.append(origin + width - 1)
    if leaves:
        origins = np.array([leaf[0] for leaf in leaves])
        masks = np.array([leaf[1] for leaf in leaves]).reshape(-1, dim, dim, dim)
        on = masks.any(axis=(1, 2, 3))
        if on.any():
            low, high = np.zeros(3, dtype=np.int64), np.zeros(3, dtype=np.int64)
            for axis in range(3):
                # which slabs along this axis hold active voxels, per leaf: the first and last of them
                lit = masks[on].any(axis=tuple(a for a in (1, 2, 3) if a != axis + 1))
                low[axis] = (origins[on, axis] + lit.argmax(axis=1)).min()
                high[axis] = (origins[on, axis] + dim - 1 - lit[:, ::-1].argmax(axis=1)).max()
            lows.append(low)
            highs.append(high)
    if not lows:
        raise InputError(f"{where}: the grid has no active voxels")
    lo, hi = np.min(lows, axis=0), np.max(highs, axis=0)
    shape = hi - lo + 1
    if np.prod(shape.astype(np.float64)) > MAX_VOXELS:
        raise InputError(f"{where}: active voxels span {' x '.join(map(str, shape.tolist()))} voxels, more than "
                         f"{MAX_VOXELS} as a dense grid")
    density = np.zeros(tuple(shape.tolist()), dtype=np.float64)
    blocks = [(origin, width, np.float64(value)) for origin, width, value, _ in tiles]
    blocks += [(origin, dim, values.reshape(dim, dim, dim)) for origin, _, values in leaves]
    for origin, width, value in blocks:
        # clipped to the box: a leaf's or tile's voxels past it are inactive
        a = origin - lo
        b = a + width
        ca, cb = np.maximum(a, 0), np.minimum(b, shape)
        if np.all(cb > ca):
            if np.ndim(value):
                value = value[ca[0] - a[0]:cb[0] - a[0], ca[1] - a[1]:cb[1] - a[1], ca[2] - a[2]:cb[2] - a[2]]
            density[ca[0]:cb[0], ca[1]:cb[1], ca[2]:cb[2]] = value
    return lo.astype(np.float64), hi.astype(np.float64), density
