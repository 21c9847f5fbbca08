"""Child processes for the interrupt tests: a ``cloudmeta`` CLI that takes SIGINT whatever this process's
disposition of it.

A POSIX shell without job control (``sh -c '... &'``, a script, a CI step or a test runner started in the
background) starts its background commands with SIGINT and SIGQUIT *ignored*, and an ignored signal stays
ignored across fork and exec: pytest inherits it, the render it starts inherits it from pytest, and Python
keeps an inherited SIG_IGN instead of installing its KeyboardInterrupt handler. The test's SIGINT then does
nothing and the render runs to its end (issue #27, item 6: "not exited 60 s after SIGINT" under load, where
the render is slow). A signal blocked in the starting thread's mask is inherited the same way. So the child
first resets SIGINT to its default and unblocks it, then execs the CLI, which then installs Python's handler
as it would when started from a terminal.
"""
import sys

_PRELUDE = ("import os, signal, sys; signal.signal(signal.SIGINT, signal.SIG_DFL); "
            "signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT}); "
            "os.execv(sys.executable, [sys.executable] + sys.argv[1:])")


def cli_argv(*args):
    """argv of ``python -m cloudmeta.cli ARGS`` started with SIGINT at its default, unblocked."""
    return [sys.executable, "-c", _PRELUDE, "-m", "cloudmeta.cli", *args]


def signal_state(pid):
    """The SigIgn / SigBlk / SigCgt lines of /proc/PID/status (for an assertion's message), or ''."""
    try:
        with open(f"/proc/{pid}/status") as f:
            return "; ".join(line.strip() for line in f if line.startswith(("SigBlk", "SigIgn", "SigCgt")))
    except OSError:
        return ""
