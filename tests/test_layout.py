"""The package's layout, drawn from its imports (issue #22): three floors that import only downwards.

    top level   cloudmeta/              public API; cli/ (command line), api/ (rays, io, viewer, cluster,
                                        runtime), generate
    renderer    cloudmeta/renderer/     Scene -> linear image
    scene       cloudmeta/scene/        YAML -> validated, frozen Scene
    kernels     cloudmeta/kernels/      numba only
    ground      cloudmeta/errors.py     the exceptions, importing nothing

Every import of a cloudmeta module is counted, at the top of a module or inside a function (a lazy import
for start-up is fine, one that dodges a cycle is not: it would show here as an upward edge or a cycle).
"""
import ast
from pathlib import Path

PACKAGE = Path(__file__).resolve().parent.parent / "cloudmeta"
#: floor of each part: a module may import its own floor's modules and any floor below
FLOORS = {"errors": 0, "kernels": 0, "scene": 1, "renderer": 2}
TOP = 3


def module_name(path):
    rel = path.relative_to(PACKAGE.parent).with_suffix("")
    parts = list(rel.parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


def floor_of(name):
    parts = name.split(".")
    if len(parts) == 1:
        return TOP  # the package itself: the public API
    return FLOORS.get(parts[1], TOP)


def resolve(module, level, name, is_package):
    """The absolute module an ``import`` names (relative imports resolved)."""
    if level == 0:
        return name
    base = module.split(".") if is_package else module.split(".")[:-1]
    base = base[:len(base) - (level - 1)]
    return ".".join(base + ([name] if name else []))


def import_graph():
    """{module: {(imported module, line, inside a function)}} over every module of the package, each
    import resolved to the deepest cloudmeta module it names (``from .kernels import single`` -> the
    submodule, ``from .scene import load_scene`` -> the package)."""
    modules = {module_name(p): p for p in PACKAGE.rglob("*.py")}
    graph = {}
    for name, path in modules.items():
        tree = ast.parse(path.read_text())
        edges = set()
        functions = [n for n in ast.walk(tree) if isinstance(n, (ast.FunctionDef, ast.AsyncFunctionDef))]
        nested = {id(n) for f in functions for n in ast.walk(f) if n is not f}
        for node in ast.walk(tree):
            inside = id(node) in nested
            targets = []
            if isinstance(node, ast.Import):
                targets = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                base = resolve(name, node.level, node.module, path.name == "__init__.py")
                targets = [f"{base}.{a.name}" if f"{base}.{a.name}" in modules else base for a in node.names]
            for t in targets:
                if t.split(".")[0] == "cloudmeta" and t != name:
                    edges.add((t, node.lineno, inside))
        graph[name] = edges
    return graph


def test_no_import_goes_up_a_floor():
    upward = [f"{m}:{line} imports {t}" + (" (in a function)" if inside else "")
              for m, edges in import_graph().items() for t, line, inside in edges
              if floor_of(t) > floor_of(m) and t != "cloudmeta"]
    assert upward == []


def test_the_ground_floor_imports_nothing_of_cloudmeta():
    graph = import_graph()
    assert graph["cloudmeta.errors"] == set()
    kernels_out = [f"{m} imports {t}" for m, edges in graph.items() if m.startswith("cloudmeta.kernels")
                   for t, _, _ in edges if not t.startswith("cloudmeta.kernels")]
    assert kernels_out == []


def test_no_import_cycle():
    """No module imports, directly or through others, a module that imports it."""
    graph = {m: {t for t, _, _ in edges} for m, edges in import_graph().items()}
    cycles = []
    state = {}

    def visit(m, stack):
        state[m] = 1
        for t in sorted(graph.get(m, ())):
            if t not in graph:
                continue
            if state.get(t) == 1:
                cycles.append(" -> ".join(stack[stack.index(t):] + [t]))
            elif t not in state:
                visit(t, stack + [t])
        state[m] = 2

    for m in sorted(graph):
        if m not in state:
            visit(m, [m])
    assert cycles == []


def test_every_module_is_on_a_floor():
    names = set(import_graph())
    assert {"cloudmeta.scene.loader", "cloudmeta.renderer.frame", "cloudmeta.kernels.single",
            "cloudmeta.kernels.kinds", "cloudmeta.kernels.density", "cloudmeta.kernels.lighting"} <= names
    assert not (PACKAGE / "render.py").exists() and not (PACKAGE / "scene.py").exists()


if __name__ == "__main__":  # print the graph, floor by floor
    graph = import_graph()
    for floor in (TOP, 2, 1, 0):
        for m in sorted(n for n in graph if floor_of(n) == floor):
            deps = sorted({t.replace("cloudmeta.", "") for t, _, _ in graph[m]})
            print(f"[{floor}] {m.replace('cloudmeta.', '') or 'cloudmeta'}: {', '.join(deps)}")
