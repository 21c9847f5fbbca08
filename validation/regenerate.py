"""Regenerate the outputs the validation scripts write: validation/results/, the suite's references and the
docs/ figures the scripts draw.

    python -m validation.regenerate --list            # each job: its command, the files it writes, its run time
    python -m validation.regenerate                   # every job but the slow ones, one after the other
    python -m validation.regenerate --all             # the slow ones too (hours in all)
    python -m validation.regenerate NAME [NAME ...]   # these jobs only (names from --list)

Each job is one script run as ``python -m MODULE ARGS`` from the repository root, in a process of its own;
a job that fails is reported and the others still run (exit status 1 if any failed). Jobs run in the order
listed, which puts the references before the scripts that read them. Run times are rough, for 2 idle cores
with a warm kernel cache; after a run, put the dated figures in docs/benchmarks.md.
"""
from __future__ import annotations

import argparse
import subprocess
import sys
import time
from dataclasses import dataclass

from validation.common import ROOT


@dataclass(frozen=True)
class Job:
    name: str
    module: str
    args: tuple = ()
    writes: tuple = ()
    minutes: float = 1.0
    #: slow: only with --all or when named
    slow: bool = False
    note: str = ""


A, P = "validation.accuracy.", "validation.performance."
JOBS = (
    Job("optical_depth", A + "optical_depth", (), ("optical_depth.csv", "optical_depth_sizes.csv", "optical_depth.png"), 1.5),
    Job("optical_depth_vs_quadrature", A + "optical_depth_vs_quadrature", (), ("optical_depth_vs_quadrature.csv",), 2),
    Job("single_scattering", A + "single_scattering", (),
        ("single_scattering.csv", "single_scattering_pixels.csv", "single_scattering.png"), 0.5),
    Job("render_quality", A + "render_quality", (), ("render_quality.csv", "render_quality.png"), 2),
    Job("stability", A + "stability", (), ("stability.csv", "stability_cases.csv", "stability.png"), 0.5),
    Job("root_finding", A + "root_finding", (), ("root_finding.csv", "root_finding.png"), 0.5),
    Job("root_finding_table", A + "root_finding_table", (), ("root_finding_table.csv",), 1),
    Job("paper_examples", A + "paper_examples", (), ("paper_examples.csv",), 1),
    Job("tracking", A + "tracking", (), ("tracking.csv",), 5),
    Job("suite_references", A + "suite_references", (),
        ("suite_references.csv", "../reference_images/suite/*.npy, *.json (only scenes whose fingerprint changed)"),
        1, note="about an hour when every reference must be rendered again; seconds when they are current"),
    Job("suite_accuracy", A + "suite_accuracy", (), ("suite_accuracy.csv", "suite_accuracy.png"), 5),
    Job("error_estimate", A + "error_estimate", (), ("error_estimate.csv",), 1),
    Job("error_estimate_hybrid", A + "error_estimate", ("--shadows", "hybrid"), ("error_estimate_hybrid.csv",), 1),
    Job("error_targets", A + "error_estimate", ("--targets",), ("error_targets.csv",), 2),
    Job("error_estimate_256x192", A + "error_estimate", ("--size", "256", "192"),
        ("error_estimate_256x192.csv", "suite_256x192/ (cached references, not committed)"), 14, slow=True),
    Job("far_geometry", A + "far_geometry", (), (), 1, note="prints its table; writes nothing"),
    Job("multiple_scattering", A + "multiple_scattering", (), ("multiple_scattering.csv",), 25, slow=True),
    Job("multiple_figures", A + "multiple_scattering", ("--figures", "docs/multiple_cumulus.png", "--size", "160",
                                                         "--paths", "512"), ("../../docs/multiple_cumulus.png",),
        20, slow=True),
    Job("approximate_references", A + "approximate", ("references",), ("approximate/*.npz (not committed)",), 26,
        slow=True, note="needed once by the approximate, denoise and ms_methods jobs"),
    Job("approximate_fit", A + "approximate", ("fit",), (), 4, note="prints the fit; writes nothing"),
    Job("approximate_report", A + "approximate", ("report",), ("approximate.csv",), 0.5),
    Job("approximate_tune", A + "approximate", ("tune", "--paths", "4096"), ("approximate_grid_tuning.csv",), 30,
        slow=True),
    Job("approximate_deposits", A + "approximate", ("deposits", "--paths", "4096"), ("approximate_deposits.csv",), 30,
        slow=True),
    Job("approximate_figure", A + "approximate", ("figure", "--size", "128", "--paths", "1024"),
        ("../../docs/approximate_cumulus.png",), 15, slow=True),
    Job("approximate_bias", A + "approximate", ("bias", "--paths", "16384"), ("../../docs/approximate_grid_bias.png",),
        30, slow=True),
    Job("ms_shared", A + "ms_shared", ("--quality", "draft", "default", "--planned", "draft", "--scenes",
                                       "cumulus_front", "deck_low_sun", "wispy_puffs"),
        ("ms_shared_512.csv", "ms_shared_512.png"), 60, slow=True),
    Job("readme_pictures", "validation.tools.readme_pictures", ("--tails", "4096", "--cache", "0"),
        ("../../docs/cumulus_pair.png",), 4,
        slow=True),
    Job("denoise", A + "denoise", (), ("denoise_64.csv",), 2),
    Job("ms_methods", A + "ms_methods", (), ("ms_methods_64.csv", "ms_methods_64.png"), 3),
    Job("time_vs_error", P + "time_vs_error", (), ("time_vs_error.csv", "time_vs_error.png"), 1.5),
    Job("bench", P + "bench", (), ("bench.csv",), 7),
    Job("scale", P + "scale", (), ("scale.csv", "scale.png"), 10, slow=True),
    Job("mitsuba_peer", "validation.peers.mitsuba_peer", (), ("mitsuba/agreement.csv", "mitsuba/equal_time.csv"), 40,
        slow=True, note="needs pip install mitsuba==3.8.0; exits 0 without it"),
)


def writes(job):
    """The files a job writes, as paths relative to the repository root."""
    out = []
    for w in job.writes:
        if w.startswith("../../"):
            out.append(w[len("../../"):])
        elif w.startswith("../"):
            out.append("validation/" + w[len("../"):])
        else:
            out.append("validation/results/" + w)
    return out


def command(job):
    return [sys.executable, "-m", job.module, *job.args]


def show(jobs):
    for job in jobs:
        slow = " (slow: --all or by name)" if job.slow else ""
        print(f"{job.name}: python -m {' '.join([job.module, *job.args])}   ~{job.minutes:g} min{slow}")
        for w in writes(job):
            print(f"    writes {w}")
        if job.note:
            print(f"    {job.note}")


def main(argv=None):
    ap = argparse.ArgumentParser(prog="python -m validation.regenerate", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("names", nargs="*", help="jobs to run (default: every job that is not slow)")
    ap.add_argument("--list", action="store_true", help="list the jobs and what each writes, run nothing")
    ap.add_argument("--all", action="store_true", help="the slow jobs too")
    args = ap.parse_args(argv)
    by_name = {job.name: job for job in JOBS}
    unknown = [n for n in args.names if n not in by_name]
    if unknown:
        ap.error(f"unknown job {', '.join(unknown)}; --list names them")
    jobs = [by_name[n] for n in args.names] if args.names else [j for j in JOBS if args.all or not j.slow]
    if args.list:
        show(jobs if args.names else JOBS)
        return 0
    failed = []
    for job in jobs:
        print(f"== {job.name}: python -m {' '.join([job.module, *job.args])}", flush=True)
        start = time.perf_counter()
        rc = subprocess.run(command(job), cwd=ROOT).returncode
        print(f"== {job.name}: exit {rc} in {time.perf_counter() - start:.0f} s", flush=True)
        if rc != 0:
            failed.append(job.name)
    if failed:
        print(f"failed: {', '.join(failed)}")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
