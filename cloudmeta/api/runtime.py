"""What a long run needs from the process it runs in: a render on a thread of its own so that Ctrl-C and
SIGTERM stop it at once, and a notice before the kernels compile. Used by the CLI and the cluster library
alike (neither imports the other)."""
from __future__ import annotations

import threading

#: exit status of a run stopped by Ctrl-C or SIGTERM (128 + SIGINT, as a shell reports it)
INTERRUPTED = 130


def compile_notice(note=""):
    """Say so, before a render, when the kernels are not compiled yet (the first run on a machine, or every
    run where they cannot be cached: then a line on stderr says why, once per process)."""
    # imported here, not at the top: numba and the kernel modules cost start-up, and --help needs neither
    from ..kernels.config import CACHE, cache_problem, is_compiled, say_uncached
    from ..kernels.single import render_pixels
    if is_compiled(render_pixels):
        return
    if cache_problem() is None:
        print(f"cloudmeta: compiling the kernels for this machine (once per kind of scene, about a minute on an idle core, then cached"
              f"{'; ' + note if note else ''})", flush=True)
    else:  # caching off, or a folder that cannot be written (said on stderr, with what to do)
        print("cloudmeta: compiling the kernels for this run (about a minute on an idle core; not cached"
              f"{'' if CACHE else ': CLOUDMETA_NO_CACHE is set'})", flush=True)
        say_uncached()


def interruptible(work, *args, **kwargs):
    """``work(*args, **kwargs)`` on a thread of its own, so that this (the main) thread stays free to take
    Ctrl-C and SIGTERM at once: the kernels run without the GIL and cannot be stopped midway, so the
    KeyboardInterrupt leaves the work running, goes up through this thread's ``atomic_outputs`` (which
    remove their temporary files) and cloudmeta.cli.main then ends the process without waiting (``RENDERS``)."""
    result = {}

    def run():
        try:
            result["value"] = work(*args, **kwargs)
        except BaseException as exc:  # handed to the main thread
            result["error"] = exc
        finally:
            RENDERS.remove(worker)

    worker = threading.Thread(target=run, name="cloudmeta-render", daemon=True)
    RENDERS.append(worker)
    worker.start()
    while worker.is_alive():
        worker.join(0.2)
    if "error" in result:
        raise result["error"]
    return result["value"]


#: render threads still running (an interrupt then ends the process at once instead of waiting for them)
RENDERS = []
