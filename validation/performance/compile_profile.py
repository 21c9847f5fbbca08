"""Where the first render's time goes: numba compiles and cache loads per jitted function.

Renders one scene (default: the cumulus at 4 x 3, as the CLI does) in this process and prints

- the wall time of ``import cloudmeta``, of loading the scene, of the first render and of writing the EXR;
- per jitted function compiled in this run: the inclusive compile time (numba's ``numba:compile`` event,
  which includes the compiles of the non-inlined functions it calls) and the exclusive time (without them),
  and the time numba spent saving it to the cache;
- per jitted function loaded from numba's cache: the load time (``Cache.load_overload``).

    python -m validation.performance.compile_profile            # the usual cache (warm after a first run)
    python -m validation.performance.compile_profile --cold     # an empty cache folder: everything compiles
    python -m validation.performance.compile_profile --scene scenes/hand.yaml --width 8 --height 6
    python -m validation.performance.compile_profile --cold --kinds   # every kind `cloudmeta compile` does

With ``--passes N`` the N functions of the longest exclusive compile also get numba's own record of their
compile: wall seconds per pass of its pipeline (type inference includes the compiles of the callees it meets,
lowering the LLVM function passes) and, run with NUMBA_LLVM_PASS_TIMINGS=1, LLVM's per stage.

With ``--kinds`` the jobs of ``cloudmeta compile`` (the ray API and one tiny scene of each kind) run one after
another in this process instead of the one render, so the table counts every signature each function
compiles across all kinds (a top-level kernel compiled twice for two kinds shows 2), and the process CPU time
of each job is printed (later jobs load or reuse what earlier ones compiled).

Run it in a fresh process each time (it patches numba's cache class before cloudmeta is imported).
"""
from __future__ import annotations

import os
import tempfile
import time
from pathlib import Path

from validation.common import ROOT, parse, parser, run_main

CUMULUS = ROOT / "scenes" / "cumulus.yaml"


def _short(dispatcher_or_function):
    func = getattr(dispatcher_or_function, "py_func", dispatcher_or_function)
    if hasattr(func, "__qualname__"):
        return f"{func.__module__.rsplit('.', 1)[-1]}.{func.__qualname__}"
    return str(func)


def install_probes():
    """Patch numba so that cache loads and saves are timed and compiles are recorded with their nesting.
    Returns (loads, saves, compiles): lists filled while the program runs."""
    from numba.core import caching, event

    loads, saves, compiles = [], [], []

    def timed(method, into):
        def wrapper(self, *args, **kwargs):
            start = time.perf_counter()
            try:
                return method(self, *args, **kwargs)
            finally:
                into.append((self._py_func, time.perf_counter() - start))
        return wrapper

    orig_load = caching.Cache.load_overload

    def load(self, sig, target_context):
        start, cpu = time.perf_counter(), time.thread_time()
        cres = orig_load(self, sig, target_context)
        loads.append((self._py_func, time.perf_counter() - start, cres is not None, time.thread_time() - cpu))
        return cres

    caching.Cache.load_overload = load
    caching.Cache.save_overload = timed(caching.Cache.save_overload, saves)

    class Nesting(event.Listener):
        """Inclusive compile times, and each compile's children (compiles started while it ran)."""

        def __init__(self):
            self.stack = []

        def on_start(self, ev):
            self.stack.append([ev.data["dispatcher"], ev.data["args"], time.perf_counter(), time.thread_time(),
                               0.0, 0.0])

        def on_end(self, ev):
            dispatcher, sig, start, cpu_start, children, cpu_children = self.stack.pop()
            took, cpu = time.perf_counter() - start, time.thread_time() - cpu_start
            if self.stack:
                self.stack[-1][4] += took
                self.stack[-1][5] += cpu
            compiles.append((dispatcher, took, took - children, cpu - cpu_children, sig))

    event.register("numba:compile", Nesting())
    return loads, saves, compiles


def _print_passes(dispatcher):
    """numba's pipeline times (and LLVM's, where recorded) of each signature the dispatcher compiled."""
    for sig, cres in getattr(dispatcher, "overloads", {}).items():
        metadata = getattr(cres, "metadata", None) or {}
        print(f"\n  {_short(dispatcher)} {sig}: numba's passes (wall s, nested compiles included)")
        for pipeline, passes in metadata.get("pipeline_times", {}).items():
            rows = sorted(((t.init + t.run + t.finalize, name) for name, t in passes.items()), reverse=True)
            for took, name in rows[:10]:
                print(f"    {pipeline:10s} {name:44s} {took:9.2f}s")
        llvm = metadata.get("llvm_pass_timings")
        if llvm is not None:
            for record in sorted(llvm, key=lambda r: -r.timings.get_total_time())[:6]:
                print(f"    llvm       {record.name[:44]:44s} {record.timings.get_total_time():9.2f}s")


def _run_kinds(args, t_probe, t_import):
    """Every job of ``cloudmeta compile``, one after another in this process: (wall s, process CPU s)."""
    from cloudmeta.cli.compile import jobs

    print(f"every kind of `cloudmeta compile`, in one process, {'empty' if args.cold else 'usual'} cache")
    print(f"  numba import + probes            {t_probe:8.3f} s")
    print(f"  import cloudmeta (+ io)          {t_import:8.3f} s")
    wall0, cpu0 = time.perf_counter(), time.process_time()
    with tempfile.TemporaryDirectory() as folder:
        for name, code in jobs(folder):
            t0, c0 = time.perf_counter(), time.process_time()
            exec(compile(code, name, "exec"), {})
            print(f"  {name[:60]:60s} {time.perf_counter() - t0:7.1f} s wall {time.process_time() - c0:7.1f} s CPU")
    wall, cpu = time.perf_counter() - wall0, time.process_time() - cpu0
    print(f"  {'all kinds':60s} {wall:7.1f} s wall {cpu:7.1f} s CPU")
    return wall, cpu


def main(argv=None):
    ap = parser(__doc__)
    ap.add_argument("--scene", default=str(CUMULUS))
    ap.add_argument("--width", type=int, default=4)
    ap.add_argument("--height", type=int, default=3)
    ap.add_argument("--cold", action="store_true", help="compile everything into an empty cache folder")
    ap.add_argument("--cache-dir", help="use this CLOUDMETA_CACHE_DIR (with --cold: keep the new cache there)")
    ap.add_argument("--top", type=int, default=25, help="rows of the per-function tables")
    ap.add_argument("--passes", type=int, default=0,
                    help="numba's per-pass times of the N functions of the longest exclusive compile")
    ap.add_argument("--kinds", action="store_true",
                    help="run the jobs of `cloudmeta compile` (every kind of scene) instead of one render")
    args, _ = parse(ap, argv)
    tmp = None
    if args.cold and not args.cache_dir:
        tmp = tempfile.TemporaryDirectory(prefix="cloudmeta-cold-")
        args.cache_dir = tmp.name
    if args.cache_dir:
        if args.cold and any(Path(args.cache_dir).glob("*/*")):
            raise SystemExit(f"--cache-dir {args.cache_dir}: not empty, so not a cold start")
        os.environ["CLOUDMETA_CACHE_DIR"] = args.cache_dir
        os.environ.pop("NUMBA_CACHE_DIR", None)
    t0 = time.perf_counter()
    loads, saves, compiles = install_probes()
    t_probe = time.perf_counter() - t0

    t0 = time.perf_counter()
    import cloudmeta as cm
    from cloudmeta.api.io import write_exr
    t_import = time.perf_counter() - t0
    if args.kinds:
        t_scene = t_exr = 0.0
        t_render, cpu_render = _run_kinds(args, t_probe, t_import)
    else:
        cpu0 = time.process_time()
        t0 = time.perf_counter()
        scene = cm.load_scene(args.scene, width=args.width, height=args.height)
        t_scene = time.perf_counter() - t0
        t0 = time.perf_counter()
        image = cm.render(scene, progress=False)
        t_render = time.perf_counter() - t0
        cpu_render = time.process_time() - cpu0
        with tempfile.TemporaryDirectory() as out:
            t0 = time.perf_counter()
            write_exr(image, os.path.join(out, "x.exr"))
            t_exr = time.perf_counter() - t0

        print(f"scene {args.scene} at {args.width} x {args.height}, {'empty' if args.cold else 'usual'} cache")
        print(f"  numba import + probes            {t_probe:8.3f} s")
        print(f"  import cloudmeta (+ io)          {t_import:8.3f} s")
        print(f"  load_scene                       {t_scene:8.3f} s")
        print(f"  first render                     {t_render:8.3f} s  (process CPU {cpu_render:.1f} s)")
        print(f"  write_exr (imports OpenEXR)      {t_exr:8.3f} s")
    if compiles:
        total = sum(c[2] for c in compiles)
        cpu = sum(c[3] for c in compiles)
        print(f"\ncompiled: {len(compiles)} signatures of {len({id(c[0]) for c in compiles})} functions, "
              f"{total:.1f} s wall ({cpu:.1f} s CPU) of exclusive compile time "
              f"(saving to the cache: {sum(s[1] for s in saves):.2f} s)")
        print(f"  {'function':44s} {'inclusive':>10s} {'exclusive':>10s} {'excl. CPU':>10s}  signatures")
        per = {}
        for d, inc, exc, exc_cpu, sig in compiles:
            row = per.setdefault(id(d), [d, 0.0, 0.0, 0.0, 0])
            row[1] += inc
            row[2] += exc
            row[3] += exc_cpu
            row[4] += 1
        for d, inc, exc, exc_cpu, n in sorted(per.values(), key=lambda c: -c[3])[:args.top]:
            print(f"  {_short(d):44s} {inc:9.2f}s {exc:9.2f}s {exc_cpu:9.2f}s  {n}")
        for d, *_ in sorted(per.values(), key=lambda c: -c[3])[:args.passes]:
            _print_passes(d)
    hits = [(f, t, c) for f, t, hit, c in loads if hit]
    misses = [(f, t) for f, t, hit, _ in loads if not hit]
    if loads:
        print(f"\nloaded from the cache: {len(hits)} functions in {sum(t for _, t, _ in hits):.3f} s "
              f"({sum(c for _, _, c in hits):.3f} s CPU); {len(misses)} looked up and missed in "
              f"{sum(t for _, t in misses):.3f} s (the first load also starts numba's code generator)")
        for f, t, c in sorted(hits, key=lambda h: -h[1])[:args.top]:
            print(f"  {_short(f):44s} {t:9.3f}s {c:9.3f}s CPU")
    if tmp is not None:
        tmp.cleanup()
    return dict(import_s=t_import, scene_s=t_scene, render_s=t_render, exr_s=t_exr,
                compile_s=sum(c[2] for c in compiles),
                compile_cpu_s=sum(c[3] for c in compiles), n_compiled=len(compiles),
                load_s=sum(t for _, t, _ in hits), n_loaded=len(hits))


if __name__ == "__main__":
    run_main(main)
