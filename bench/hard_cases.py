#!/usr/bin/env python3
"""The hard cases of issue 24 at full size (tests/e2e/test_hard_cases.py runs them reduced): each scene of
configs/tests/hard/ made longer or larger, run through `./sabo run`, and judged as the tests judge them: it
completes at its end time (the instability check stops a run at its first bad step), energy.csv stays finite
and its total never rises above the initial value by more than 0.1 % of the largest kinetic energy, no particle
is lost (every particle of the first frame is in the last, active) or tunnelled (every particle centre of the
last frame inside its container, the half-spaces of the case's walls and floor). Prints a markdown table
(bench/RESULTS.md): steps, wall time, the largest energy rise, the largest kinetic energy, the particles.

    bench/hard_cases.py                          # every case (about half an hour; --count 2000: 10 min)
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
from scene_runs import ROOT, pvd_frames, read_vtu, run_scene  # noqa: E402

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


def dense_bin_height(count):
    """m: the fill region's height for `count` spheres of 0.8-1.2 m at 30 % of its volume, and 2 m."""
    return math.ceil(count * math.pi / 6 * 1.1 / (0.3 * 100.0)) + 2


def dense_bin(count):
    """The bin of dense_bin.toml, widened so that `count` spheres of 0.8-1.2 m fill it: 10 m x 10 m, the fill
    region as tall as random filling needs (30 % of its volume), the walls above it."""
    height = dense_bin_height(count)
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


def dense_boulders():
    """dense_boulders.toml at twice the resolution (dx = 10 mm: 8 spacings a boulder) with nine boulders
    instead of three, dropped from 0.15-0.23 m into the 0.1 m of water, for 1 s."""
    spheres = ", ".join(
        "{{ center = [{:.3f}, {:.3f}, {:.3f}], radius = 0.04 }}".format(x, y, 0.15 + 0.01 * k)
        for k, (x, y) in enumerate((x, y) for x in (0.055, 0.15, 0.245) for y in (0.055, 0.15, 0.245)))
    text = replaced(read("dense_boulders"), [("particle_spacing = 0.02", "particle_spacing = 0.01"),
                                             ("end_time = 0.5", "end_time = 1.0"),
                                             ("output_interval = 0.02", "output_interval = 0.05")])
    start = text.index("spheres = [")
    end = text.index("\n\n", start)
    return text[:start] + "spheres = [ " + spheres + " ]" + text[end:]


def box(low, high, what):
    """The six half-spaces of an axis-aligned box: (unit normal into it, a point on its face, what)."""
    faces = []
    for axis in range(3):
        inward = [0.0, 0.0, 0.0]
        inward[axis] = 1.0
        faces.append((tuple(inward), tuple(low), what))
        inward = [0.0, 0.0, 0.0]
        inward[axis] = -1.0
        faces.append((tuple(inward), tuple(high), what))
    return faces


def chute(length, half_width):
    """The half-spaces of a chute of `length` m along its floor (through the origin, sloping down along x at 20
    degrees), its side walls at y = +-half_width and its end wall normal to the floor: a centre passes none."""
    slope = math.radians(20.0)
    end = (length * math.cos(slope), 0.0, -length * math.sin(slope))
    return [((math.sin(slope), 0.0, math.cos(slope)), (0.0, 0.0, 0.0), "the chute's floor"),
            ((0.0, 1.0, 0.0), (0.0, -half_width, 0.0), "the chute's side wall at y = -{:g} m".format(half_width)),
            ((0.0, -1.0, 0.0), (0.0, half_width, 0.0), "the chute's side wall at y = {:g} m".format(half_width)),
            ((-math.cos(slope), 0.0, math.sin(slope)), end, "the chute's end wall")]


TANK = box((0.0, 0.0, 0.0), (0.4, 0.4, 0.35), "the tank")


# name: (what, scene(args), {solver: container(args)}); a container is a list of half-spaces (box()).
CASES = {
    "long_tank": ("the hydrostatic tank, 100 000 steps",
                  lambda args: replaced(read("long_tank"), [("end_time = 19.0", "end_time = 94.0"),
                                                            ("output_interval = 1.0", "output_interval = 5.0")]),
                  {"sph": lambda args: TANK}),
    "stiff_penalty_sph": ("SPH-FEM penalty at k1 = 1, the tank's 0.6 s",
                          lambda args: replaced(read("stiff_penalty_sph"), [("end_time = 0.06", "end_time = 0.6"),
                                                                            ("output_interval = 0.01",
                                                                             "output_interval = 0.1")]),
                          {"sph": lambda args: box((0.0, 0.0, 0.0), (0.4, 0.4, 0.4), "the tank")}),
    "stiff_penalty_dem": ("DEM-FEM penalty at k1 = 1, configs/boulders_chute.toml (200 boulders)",
                          lambda args: replaced(read("boulders_chute", os.path.join(ROOT, "configs")),
                                                [("penalty_scale = 0.1", "penalty_scale = 1.0")]),
                          {"dem": lambda args: chute(60.0, 4.0)}),
    "slurry_40ms": ("slurry at 40 m/s into a rigid dam, dx = 10 mm (4000 particles)",
                    lambda args: replaced(read("slurry_40ms"), [("particle_spacing = 0.02", "particle_spacing = 0.01")]),
                    # The dam's plane is x = 0.4 m; its boundary particles lie a kernel support behind it.
                    {"sph": lambda args: box((-1.5, -2.0, 0.0), (0.46, 2.2, 3.0), "the floor, the dam, the domain")}),
    "dense_bin": ("a dense pile in a bin", lambda args: dense_bin(args.count),
                  # A smallest radius (0.4 m) inside the walls, less 5 cm of penalty overlap.
                  {"dem": lambda args: box((0.35, 0.35, 0.35), (9.65, 9.65, dense_bin_height(args.count) + 2.0),
                                           "the bin")}),
    "dense_boulders": ("nine boulders three times denser than the water settling through it, dx = 10 mm",
                       lambda args: dense_boulders(),
                       {"dem": lambda args: box((0.0, 0.0, 0.0), (0.3, 0.3, 0.25), "the tank")}),
    "dem_beta_nine": ("the DEM at 0.9 of its stable step: configs/tests/chute_small.toml for 10 s (4 s in the test)",
                      lambda args: replaced(read("chute_small", os.path.join(ROOT, "configs", "tests")),
                                            [("beta = 0.8", "beta = 0.9"), ("end_time = 4.0", "end_time = 10.0")]),
                      {"dem": lambda args: chute(15.0, 2.0)}),
    "sph_beta_nine": ("the SPH at 0.9 of its stable step: the hydrostatic tank, its 19 s",
                      lambda args: read("long_tank") + "\n[solvers.sph]\nbeta = 0.9\n",
                      {"sph": lambda args: TANK}),
}


def read_points(path):
    """Points (x, y, z tuples) and the `active` flags (None when absent) of one of Sabo's VTK XML files."""
    arrays = read_vtu(path)
    active = arrays.get("active")
    return arrays["Points"], None if active is None else [flag for (flag,) in active]


def particles_kept(out, solver, container):
    """(ok, text): every particle of the first frame of RUN/SOLVER.pvd is in the last, active, its centre
    inside every half-space of `container`."""
    frames = pvd_frames(out, solver)
    first, _ = read_points(frames[0][1])
    last, active = read_points(frames[-1][1])
    problems = []
    if len(last) != len(first):
        problems.append("{} of {} left".format(len(first) - len(last), len(first)))
    if active is not None and not all(active):
        problems.append("{} inactive".format(sum(1 for a in active if not a)))
    for normal, point, what in container:
        depth = min(sum((c[k] - point[k]) * normal[k] for k in range(3)) for c in last)
        if depth < 0:
            problems.append("a centre {:.3g} m past {}".format(-depth, what))
    return not problems, "{} {}: {}".format(len(last), solver, "; ".join(problems) if problems else "all kept")


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
    print("| case | what | steps | wall time, s | largest energy rise, J | largest kinetic energy, J | particles | "
          "verdict |")
    print("|---|---|---|---|---|---|---|---|")
    failed = 0
    for name in args.only or sorted(CASES):
        what, make, containers = CASES[name]
        if name == "dense_bin":
            what += " of {} boulders".format(args.count)
        try:
            out, wall, summary = run_scene(make(args), work, name)
        except RuntimeError as error:
            print("| {} | {} | | | | | | **failed**: {} |".format(name, what, str(error).splitlines()[0]))
            failed += 1
            continue
        finite, rise, kinetic = judge(out)
        kept = [particles_kept(out, solver, container(args)) for solver, container in containers.items()]
        ok = summary["status"] == "completed" and finite and rise <= 1e-3 * kinetic and all(k for k, _ in kept)
        failed += 0 if ok else 1
        print("| {} | {} | {} | {:.0f} | {:.3g} | {:.4g} | {} | {} |".format(
            name, what, summary["steps"], wall, rise, kinetic, "; ".join(text for _, text in kept),
            "stable" if ok else "**not stable**"), flush=True)
    if not args.keep:
        import shutil
        shutil.rmtree(work, ignore_errors=True)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
