"""Structure check of the kernels: nesting depth of every function in cloudmeta/kernels, no tuple or record
indexed by an integer literal, and the length of cloudmeta/renderer/frame.py.

Nesting depth counts the compound statements (for, while, if, with, try) around the deepest statement
of a function's body; an ``elif`` is the same level as its ``if``.

Indexing: a subscript by an integer literal (``x[3]``, ``x[-1]``; not a multi-dimensional index such as
``light_buf[li, 0]``, and not a slice) is flagged where its base holds a tuple or a record, whose parts
have names and should be read by name or unpacked:

- a name or attribute of RECORD_NAMES, the names the kernels give their records (``med[15]``, ``key[0]``,
  ``scene.media[2]``); a subscript of such a subscript (``surf[13][s]``) is flagged with it;
- a name bound in the same function to a whole tuple: ``x = (a, b)``, ``x = SomeRecord(...)`` (a
  namedtuple of kernels/records.py), or ``x = f(...)`` where f is a kernel function that returns a tuple
  (a tuple display or a record) on every path it returns.

Arrays indexed by a literal (``out[0]``, ``d[2]``, ``geo[12]``) are fine: parameters and other names are
taken for arrays unless the rules above say otherwise (a type checker could tell more; this is an AST
check). Parts unpacked from a call (``left, right = _casteljau_rows(...)``) are named by the unpacking;
where such a part is itself a tuple (a row of de Casteljau's triangle), indexing it by position is
flagged too (ROW): unpack the row instead (``(_, _, _, _, _, _, apex), _ = _casteljau_rows(...)``).

Prints one line per function over the depth limit, per flagged subscript (and with ``--all`` every
function and every ROW), then the totals and PASS or FAIL.

    python -m validation.tools.check_structure [--all] [--max-depth 5] [--max-frame-lines 250]
"""
from __future__ import annotations

import ast

from validation.common import ROOT, parse, parser, run_main

KERNELS = ROOT / "cloudmeta" / "kernels"
FRAME = ROOT / "cloudmeta" / "renderer" / "frame.py"
#: names that hold records in the kernels (namedtuples of kernels/records.py, and before them tuples)
RECORD_NAMES = {"med", "media", "surf", "surfaces", "lights", "maps", "quad", "scratch", "rp", "work", "nodes",
                "scene", "bvh", "light_buf", "camera", "blob", "rows", "out_rec",
                "state", "cursor", "key", "vectors", "segment", "camera_segment", "packed", "result"}
COMPOUND = (ast.For, ast.While, ast.If, ast.With, ast.Try)
FUNCTIONS = (ast.FunctionDef, ast.AsyncFunctionDef)


def depth_of(stmts, level=0):
    deepest = level
    for st in stmts:
        if isinstance(st, COMPOUND):
            inner = level + 1
            deepest = max(deepest, inner)
            deepest = max(deepest, depth_of(st.body, inner))
            orelse = getattr(st, "orelse", [])
            if isinstance(st, ast.If) and len(orelse) == 1 and isinstance(orelse[0], ast.If):
                deepest = max(deepest, depth_of(orelse, level))  # elif: the same level
            else:
                deepest = max(deepest, depth_of(orelse, inner))
            for h in getattr(st, "handlers", []):
                deepest = max(deepest, depth_of(h.body, inner))
            deepest = max(deepest, depth_of(getattr(st, "finalbody", []), inner))
        elif isinstance(st, FUNCTIONS):
            deepest = max(deepest, depth_of(st.body, level))
    return deepest


def int_literal(node):
    """Whether a subscript's index is an integer literal (``3``, ``-1``)."""
    if isinstance(node, ast.UnaryOp) and isinstance(node.op, (ast.USub, ast.UAdd)):
        node = node.operand
    return isinstance(node, ast.Constant) and isinstance(node.value, int) and not isinstance(node.value, bool)


def callee(call):
    """The name a call calls (``f(...)``, ``records.F(...)``), or None."""
    f = call.func
    return f.id if isinstance(f, ast.Name) else f.attr if isinstance(f, ast.Attribute) else None


def record_types(trees):
    """Names bound to ``namedtuple(...)`` at the top of a module (kernels/records.py's records)."""
    return {t.id for tree in trees for st in tree.body if isinstance(st, ast.Assign)
            and isinstance(st.value, ast.Call) and callee(st.value) == "namedtuple"
            for t in st.targets if isinstance(t, ast.Name)}


def returns_of(fn):
    """The values a function returns (not those of functions nested in it)."""
    out, todo = [], list(fn.body)
    while todo:
        node = todo.pop()
        if isinstance(node, ast.Return):
            out.append(node.value)
        elif not isinstance(node, (*FUNCTIONS, ast.Lambda, ast.ClassDef)):
            todo.extend(ast.iter_child_nodes(node))
    return out


def is_tuple(value, records):
    return isinstance(value, ast.Tuple) or (isinstance(value, ast.Call) and callee(value) in records)


def tuple_returners(trees, records):
    """{kernel function: its return values} for the functions that return a tuple (a display or a record) on
    every path that returns."""
    found = {}
    for tree in trees:
        for fn in ast.walk(tree):
            if isinstance(fn, FUNCTIONS):
                values = returns_of(fn)
                if values and all(v is not None and is_tuple(v, records) for v in values):
                    found[fn.name] = values
    return found


def bound_tuples(fn, records, returners):
    """(names bound to a whole tuple in fn, names bound to a row: a tuple display unpacked from a call)."""
    whole, rows = set(), set()
    for node in ast.walk(fn):
        if not isinstance(node, ast.Assign):
            continue
        value = node.value
        for target in node.targets:
            if isinstance(target, ast.Name):
                if is_tuple(value, records) or (isinstance(value, ast.Call) and callee(value) in returners):
                    whole.add(target.id)
            elif isinstance(target, ast.Tuple) and isinstance(value, ast.Call) and callee(value) in returners:
                for k, part in enumerate(target.elts):
                    if isinstance(part, ast.Name) and any(
                            isinstance(v, ast.Tuple) and k < len(v.elts) and isinstance(v.elts[k], ast.Tuple)
                            for v in returners[callee(value)]):
                        rows.add(part.id)
    return whole, rows


def literal_indexing(fn, records, returners):
    """([(line, text)] of flagged subscripts, [(line, text)] of rows indexed by position) in fn."""
    whole, rows = bound_tuples(fn, records, returners)
    hits, row_hits = [], []
    for node in ast.walk(fn):
        if not (isinstance(node, ast.Subscript) and int_literal(node.slice)):
            continue
        base = node.value
        name = base.id if isinstance(base, ast.Name) else base.attr if isinstance(base, ast.Attribute) else None
        if name in RECORD_NAMES or (isinstance(base, ast.Name) and name in whole):
            hits.append((node.lineno, ast.unparse(node)))
        elif isinstance(base, ast.Name) and name in rows:
            row_hits.append((node.lineno, ast.unparse(node)))
    return sorted(hits), sorted(row_hits)


def main(argv=None):
    ap = parser(__doc__)
    ap.add_argument("--all", action="store_true", help="print every function, not only failures")
    ap.add_argument("--max-depth", type=int, default=5)
    ap.add_argument("--max-frame-lines", type=int, default=250, help="limit of cloudmeta/renderer/frame.py")
    args, _ = parse(ap, argv)
    paths = sorted(KERNELS.glob("*.py"))
    trees = {path: ast.parse(path.read_text(encoding="utf-8")) for path in paths}
    records = record_types(trees.values())
    returners = tuple_returners(trees.values(), records)
    ok, n_fun, worst_d, n_hits, n_rows = True, 0, 0, 0, 0
    seen = set()
    for path, tree in trees.items():
        for fn in ast.walk(tree):
            if not isinstance(fn, FUNCTIONS):
                continue
            n_fun += 1
            d = depth_of(fn.body)
            worst_d = max(worst_d, d)
            over = d > args.max_depth
            ok &= not over
            if over or args.all:
                print(f"{'OVER ' if over else '     '}{path.name}:{fn.lineno} {fn.name}: nesting {d}")
            hits, row_hits = literal_indexing(fn, records, returners)
            for line, text in hits:
                if (path, line, text) not in seen:  # a nested function's subscripts are its parent's too
                    seen.add((path, line, text))
                    ok = False
                    n_hits += 1
                    print(f"INDEX {path.name}:{line} {text}")
            for line, text in row_hits:
                if (path, line, text) not in seen:
                    seen.add((path, line, text))
                    ok = False
                    n_rows += 1
                    print(f"ROW   {path.name}:{line} {text}")
    n_frame = len(FRAME.read_text(encoding="utf-8").splitlines())
    ok &= n_frame <= args.max_frame_lines
    print(f"{n_fun} kernel functions in {len(paths)} files; deepest nesting {worst_d} (limit {args.max_depth}); "
          f"{n_hits} tuples or records and {n_rows} tuple rows indexed by an integer literal (limit 0); "
          f"{len(records)} record types, {len(returners)} functions returning "
          f"tuples; renderer/frame.py {n_frame} lines (limit {args.max_frame_lines})")
    print("PASS" if ok else "FAIL")
    return dict(passed=ok, functions=n_fun, deepest=worst_d, indexed=n_hits, rows=n_rows, frame_lines=n_frame)


if __name__ == "__main__":
    run_main(main)
