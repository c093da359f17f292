#!/usr/bin/env python3
"""The hard cases of issue 24 at full size (tests/e2e/test_hard_cases.py runs them reduced): each scene of
configs/tests/hard/ made longer or larger, run through `./sabo run`, and judged as the tests judge them: it
completes at its end time (the instability check stops a run at its first bad step), energy.csv stays finite
and its total never rises above the initial value by more than 0.1 % of the largest kinetic energy, no particle
is lost. Prints a markdown table (bench/RESULTS.md): steps, wall time, the largest energy rise, the largest
kinetic energy.

    bench/hard_cases.py                          # every case (about half an hour)
    bench/hard_cases.py --only long_tank stiff_penalty_sph --keep /tmp/hard

Python 3.8+, standard library only; it builds nothing (run ./sabo setup first; $SABO_BUILD_DIR picks the
build folder)."""
import argparse
import csv
import math
import os
import sys
import tempfile

sys.path.insert(0, os.path.dirname(os.path.realpath(__file__)))
from scene_runs import ROOT, run_scene  # noqa: E402

HARD = os.path.join(ROOT, "configs", "tests", "hard")


def read(name, folder=HARD):
    with open(os.path.join(folder, name + ".toml"), encoding="utf-8") as handle:
        return handle.read()


def replaced(text, pairs):
    for old, new in pairs:
        if old not in text:
            raise SystemExit("bench/hard_cases.py: '{}' is not in the scene any more: update this script".format(
                old.strip()))
        text = text.replace(old, new, 1)
    return text


def dense_bin(count):
    """The bin of dense_bin.toml, widened so that `count` spheres of 0.8-1.2 m fill it: 10 m x 10 m, the fill
    region as tall as random filling needs (30 % of its volume), the walls above it."""
    height = math.ceil(count * math.pi / 6 * 1.1 / (0.3 * 100.0)) + 2
    text = replaced(read("dense_bin"), [
        ("max = [5.0, 5.0, 12.0], count = 150", "max = [10.0, 10.0, {:.1f}], count = {}".format(height, count)),
        ("end_time = 2.5", "end_time = {:.1f}".format(math.sqrt(2 * height / 9.81) + 1.5))])
    text = text.replace("origin = [2.5, 2.5, 0.0]", "origin = [5.0, 5.0, 0.0]")
    text = text.replace("origin = [0.0, 2.5, 7.0]", "origin = [0.0, 5.0, {:.1f}]".format(height / 2 + 1))
    text = text.replace("origin = [5.0, 2.5, 7.0]", "origin = [10.0, 5.0, {:.1f}]".format(height / 2 + 1))
    text = text.replace("origin = [2.5, 0.0, 7.0]", "origin = [5.0, 0.0, {:.1f}]".format(height / 2 + 1))
    text = text.replace("origin = [2.5, 5.0, 7.0]", "origin = [5.0, 10.0, {:.1f}]".format(height / 2 + 1))
    text = text.replace("length = 5.0\nwidth = 5.0", "length = 10.0\nwidth = 10.0")
    return text.replace("length = 5.0\nwidth = 14.0", "length = 10.0\nwidth = {:.1f}".format(height + 2))


CASES = {
    "long_tank": ("the hydrostatic tank, 100 000 steps",
                  lambda args: replaced(read("long_tank"), [("end_time = 19.0", "end_time = 94.0"),
                                                            ("output_interval = 1.0", "output_interval = 5.0")])),
    "stiff_penalty_sph": ("SPH-FEM penalty at k1 = 1, the tank's 0.6 s",
                          lambda args: replaced(read("stiff_penalty_sph"), [("end_time = 0.06", "end_time = 0.6"),
                                                                            ("output_interval = 0.01",
                                                                             "output_interval = 0.1")])),
    "stiff_penalty_dem": ("DEM-FEM penalty at k1 = 1, configs/boulders_chute.toml (200 boulders)",
                          lambda args: replaced(read("boulders_chute", os.path.join(ROOT, "configs")),
                                                [("penalty_scale = 0.1", "penalty_scale = 1.0")])),
    "slurry_40ms": ("slurry at 40 m/s into a rigid dam, dx = 10 mm (4000 particles)",
                    lambda args: replaced(read("slurry_40ms"), [("particle_spacing = 0.02", "particle_spacing = 0.01")])),
    "dense_bin": ("a dense pile in a bin", lambda args: dense_bin(args.count)),
}


def judge(out):
    with open(os.path.join(out, "energy.csv"), newline="") as handle:
        rows = list(csv.DictReader(handle))
    finite = all(math.isfinite(float(v)) for row in rows for v in row.values())
    initial = float(rows[0]["total"])
    rise = max(float(row["total"]) for row in rows) - initial
    kinetic = max(float(row["kinetic"]) for row in rows)
    return finite, rise, kinetic


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--only", nargs="+", choices=sorted(CASES), help="these cases only")
    parser.add_argument("--count", type=int, default=10000, help="dense_bin: the number of boulders")
    parser.add_argument("--keep", help="run folders here (default: a temporary folder, removed)")
    args = parser.parse_args()
    work = args.keep or tempfile.mkdtemp(prefix="sabo-hard-")
    os.makedirs(work, exist_ok=True)
    print("| case | what | steps | wall time, s | largest energy rise, J | largest kinetic energy, J | verdict |")
    print("|---|---|---|---|---|---|---|")
    failed = 0
    for name in args.only or sorted(CASES):
        what, make = CASES[name]
        if name == "dense_bin":
            what += " of {} boulders".format(args.count)
        try:
            out, wall, summary = run_scene(make(args), work, name)
        except RuntimeError as error:
            print("| {} | {} | | | | | **failed**: {} |".format(name, what, str(error).splitlines()[0]))
            failed += 1
            continue
        finite, rise, kinetic = judge(out)
        ok = summary["status"] == "completed" and finite and rise <= 1e-3 * kinetic
        failed += 0 if ok else 1
        print("| {} | {} | {} | {:.0f} | {:.3g} | {:.4g} | {} |".format(
            name, what, summary["steps"], wall, rise, kinetic, "stable" if ok else "**not stable**"), flush=True)
    if not args.keep:
        import shutil
        shutil.rmtree(work, ignore_errors=True)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
