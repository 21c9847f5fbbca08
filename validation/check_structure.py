"""Structure check of the kernels: parameters and nesting depth of every function in cloudmeta/kernels,
bare integer indexing of packed records, and the length of cloudmeta/render.py.

Nesting depth counts the compound statements (for, while, if, with, try) around the deepest statement
of a function's body; an ``elif`` is the same level as its ``if``. Bare integer indexing is a subscript
by an integer literal of a name that holds a packed record (``med[15]``), or of such a subscript
(``surf[13][s]``). Prints one line per function over the limits (and the totals), then PASS or FAIL.

    python -m validation.check_structure [--all] [--max-params 10] [--max-depth 5]
"""
from __future__ import annotations

import argparse
import ast
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
KERNELS = ROOT / "cloudmeta" / "kernels"
#: names that hold packed records in the kernels (and did, as tuples, before the records)
RECORD_NAMES = {"med", "media", "surf", "surfaces", "lights", "maps", "quad", "scratch", "rp", "work", "nodes",
                "scene", "bvh", "light_buf", "camera", "blob", "rows", "out_rec"}
COMPOUND = (ast.For, ast.While, ast.If, ast.With, ast.Try)


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
        elif isinstance(st, (ast.FunctionDef, ast.AsyncFunctionDef)):
            deepest = max(deepest, depth_of(st.body, level))
    return deepest


def bare_indexing(tree):
    hits = []
    for node in ast.walk(tree):
        if not isinstance(node, ast.Subscript):
            continue
        idx = node.slice
        if not (isinstance(idx, ast.Constant) and isinstance(idx.value, int)) and not (
                isinstance(idx, ast.UnaryOp) and isinstance(idx.operand, ast.Constant)):
            continue
        base = node.value
        if isinstance(base, ast.Name) and base.id in RECORD_NAMES:
            hits.append((node.lineno, ast.unparse(node)))
        elif isinstance(base, ast.Attribute) and base.attr in RECORD_NAMES:
            hits.append((node.lineno, ast.unparse(node)))
    return hits


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--all", action="store_true", help="print every function, not only those over the limits")
    ap.add_argument("--max-params", type=int, default=10)
    ap.add_argument("--max-depth", type=int, default=5)
    args = ap.parse_args(argv)
    ok = True
    n_fun = 0
    worst_p = worst_d = 0
    for path in sorted(KERNELS.glob("*.py")):
        tree = ast.parse(path.read_text())
        for node in ast.walk(tree):
            if not isinstance(node, ast.FunctionDef):
                continue
            n_fun += 1
            a = node.args
            n_par = len(a.posonlyargs) + len(a.args) + len(a.kwonlyargs) + bool(a.vararg) + bool(a.kwarg)
            d = depth_of(node.body)
            worst_p, worst_d = max(worst_p, n_par), max(worst_d, d)
            over = n_par > args.max_params or d > args.max_depth
            ok &= not over
            if over or args.all:
                print(f"{'OVER ' if over else '     '}{path.name}:{node.lineno} {node.name}: {n_par} parameters, "
                      f"nesting {d}")
        for line, text in bare_indexing(tree):
            ok = False
            print(f"BARE {path.name}:{line} {text}")
    n_render = len((ROOT / "cloudmeta" / "render.py").read_text().splitlines())
    ok &= n_render <= 250
    print(f"{n_fun} kernel functions; most parameters {worst_p} (limit {args.max_params}), deepest nesting "
          f"{worst_d} (limit {args.max_depth}); render.py {n_render} lines (limit 250)")
    print("PASS" if ok else "FAIL")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
