#!/usr/bin/env python3
"""C1, a water column on a clamped elastic plate (Fourey et al. 2017), through a scene (`./sabo run`: coupler,
sph_solver, fem_solver): an aluminium plate 1 m long and 0.05 m thick (E 67.5 GPa, nu 0.34, rho 2700),
clamped at both ends, under 2 m of water at rest, gravity 9.81 with the plate's own weight. Benchmarks.md's
midspan deflection is -6.86e-5 m (tolerance 3 %): Euler-Bernoulli's q L^4 / (384 D) in plane strain,
D = E t^3 / (12 (1 - nu^2)), q = rho_w g H + rho_p g t. A Mindlin plate adds the shear deflection
q L^2 / (8 kappa G t) (kappa = 5/6): -7.11e-5 m, 3.6 % more; both are printed beside the measurement.

The plate is a deformable shell panel (`plane` with a `thickness`), clamped on its two short edges
(`fixed = ["x-", "x+"]`) and held in cylindrical bending (every node: no y displacement, no rotation about
x), the water periodic across the width (`sph.periodic_y`, 8 spacings), between two rigid walls; the
plate's surface is sampled as boundary particles (`sph.wall_model = "boundary_particles"`) or met by the
penalty law (`--wall-models penalty`). The plate is loaded at once at t = 0 and rings about its static
deflection; the water's `settle_time` (`--settle`) damps the column's own start; the measured deflection
is the mean of the midspan nodes' vertical displacement over [--from, end_time]. For every shell
formulation and wall model asked for, prints
a markdown table (bench/RESULTS.md). Python 3.8+, standard library only; it builds nothing (run ./sabo setup
first; $SABO_BUILD_DIR picks the build folder).

    bench/plate_under_water.py                                        # both shells, boundary particles
    bench/plate_under_water.py --formulations one_point --spacing 0.1 --keep /tmp/plate
    bench/plate_under_water.py --formulations fully_integrated --spacing 0.1 --multirate off on

With `--multirate off on` each case runs in lock-step (every process at the shells' step, 1.3e-5 s) and with
`[run] multirate = true` (the water at its own step, the shells taking up to 64 steps in it with the fluid's
forces held), and the table gives the multirate deflection and the RMS of its midspan history against
lock-step's (issue 22: within 1 %).
"""
import argparse
import json
import math
import os
import sys
import tempfile

sys.path.insert(0, os.path.dirname(os.path.realpath(__file__)))
from scene_runs import pvd_frames, read_vtu, run_scene  # noqa: E402

GRAVITY = 9.81
WATER_DENSITY = 1000.0
DEPTH = 2.0
SPAN = 1.0
THICKNESS = 0.05
YOUNGS = 67.5e9
POISSON = 0.34
PLATE_DENSITY = 2700.0
REFERENCE = -6.86e-5  # m, docs/benchmarks.md C1
TOLERANCE = 0.03
OUTPUT_INTERVAL = 0.0025  # s: the plate's frames, the midspan history
FORMULATIONS = ("fully_integrated", "one_point")


def load_per_area():
    return WATER_DENSITY * GRAVITY * DEPTH + PLATE_DENSITY * GRAVITY * THICKNESS


def bending_deflection():
    rigidity = YOUNGS * THICKNESS ** 3 / (12.0 * (1.0 - POISSON ** 2))
    return -load_per_area() * SPAN ** 4 / (384.0 * rigidity)


def shear_deflection():
    shear_modulus = YOUNGS / (2.0 * (1.0 + POISSON))
    return -load_per_area() * SPAN ** 2 / (8.0 * 5.0 / 6.0 * shear_modulus * THICKNESS)


class Plate:
    def __init__(self, spacing=0.1, element_size=0.1, formulation="fully_integrated", wall_model="boundary_particles",
                 end_time=0.45, measure_from=0.2, settle_time=0.15, multirate=False, max_dt=None):
        self.multirate = multirate
        self.max_dt = max_dt
        self.spacing = spacing
        self.element_size = element_size
        self.formulation = formulation
        self.wall_model = wall_model
        self.end_time = end_time
        self.measure_from = measure_from
        self.settle_time = settle_time
        self.width = 8 * spacing
        self.sound_speed = 10.0 * math.sqrt(GRAVITY * DEPTH)

    def scene_text(self):
        W, dx = self.width, self.spacing
        # The walls stand on the plate's upper face: the corners behind them and the plate are filled with
        # wall particles (reaching below the face, they would take the plate's wall particles near them:
        # those in front of a wall closer than their depth are dropped).
        wall_bottom, wall_top = 0.0, DEPTH + 0.2
        wall_height = wall_top - wall_bottom
        lines = [
            "# C1 water column on a clamped aluminium plate: {} m of water on a plate {} m long, {} m thick; "
            "dx = {} m, shells of {} m ({}), {} walls".format(DEPTH, SPAN, THICKNESS, dx, self.element_size,
                                                             self.formulation, self.wall_model),
            "format_version = 1",
            "",
            "[run]",
            "end_time = {!r}".format(self.end_time),
            "output_interval = {!r}".format(OUTPUT_INTERVAL),
            "gravity = [0.0, 0.0, {}]".format(-GRAVITY),
            "checkpoint_interval = 0",
            "multirate = {}".format("true" if self.multirate else "false"),
        ] + (["max_dt = {!r}".format(self.max_dt)] if self.max_dt else []) + [
            "",
            "[materials.water]",
            "density = {}".format(WATER_DENSITY),
            "youngs_modulus = 2.2e9",
            "poisson_ratio = 0.0",
            'eos = "tait"',
            "",
            "[materials.aluminium]",
            "density = {}".format(PLATE_DENSITY),
            "youngs_modulus = {}".format(YOUNGS),
            "poisson_ratio = {}".format(POISSON),
            "",
            "[materials.concrete]",
            "density = 2400.0",
            "youngs_modulus = 30e9",
            "poisson_ratio = 0.2",
            "",
            "[sph]",
            "particle_spacing = {!r}".format(dx),
            "sound_speed = {!r}".format(self.sound_speed),
            'wall_model = "{}"'.format(self.wall_model),
            "periodic_y = [0.0, {!r}]".format(W),
            "",
            "[[fluids]]",
            'name = "water"',
            'material = "water"',
            'shape = "box"',
            "min = [0.0, 0.0, 0.0]",
            "max = [{!r}, {!r}, {!r}]".format(SPAN, W, DEPTH),
            "settle_time = {!r}".format(self.settle_time),
            "",
            "[[structures]]",
            'name = "plate"',
            'material = "aluminium"',
            "rigid = false",
            'shape = "plane"',
            "origin = [{!r}, {!r}, {!r}]".format(SPAN / 2, W / 2, -THICKNESS / 2),
            "normal = [0.0, 0.0, 1.0]",
            "direction = [1.0, 0.0, 0.0]",
            "length = {!r}".format(SPAN),
            "width = {!r}".format(W),
            "thickness = {!r}".format(THICKNESS),
            "element_size = {!r}".format(self.element_size),
            'element_formulation = "{}"'.format(self.formulation),
            'fixed = ["x-", "x+"]',
            "constraints = [ {{ box = {{ min = [-1.0, -1.0, -1.0], max = [{!r}, {!r}, 1.0] }}, "
            'dofs = ["y", "rx"] }} ]'.format(SPAN + 1.0, W + 1.0),
        ]
        for name, x, normal in (("wall_x0", 0.0, 1.0), ("wall_x1", SPAN, -1.0)):
            lines += [
                "",
                "[[structures]]",
                'name = "{}"'.format(name),
                'material = "concrete"',
                'shape = "plane"',
                "origin = [{!r}, {!r}, {!r}]".format(x, W / 2, wall_bottom + wall_height / 2),
                "normal = [{!r}, 0.0, 0.0]".format(normal),
                "direction = [0.0, 0.0, 1.0]",
                "length = {!r}".format(wall_height),
                "width = {!r}".format(W),
                "element_size = {!r}".format(max(W, 0.25)),
            ]
        lines += ["", "[recording]", "enabled = false", ""]
        return "\n".join(lines)


def midspan_history(run_dir):
    """(time, vertical displacement) of the plate's midspan: the mean over the nodes nearest to x = L / 2
    across the width, from the plate's own series (fem_plate.pvd: its .vtu frames carry the displacement)."""
    history = []
    for time, path in pvd_frames(run_dir, "fem_plate"):
        arrays = read_vtu(path)
        points, displacement = arrays["Points"], arrays["displacement"]
        nearest = min(abs(p[0] - SPAN / 2) for p in points)
        middle = [k for k, p in enumerate(points) if abs(abs(p[0] - SPAN / 2) - nearest) < 1e-9]
        history.append((time, sum(displacement[k][2] for k in middle) / len(middle)))
    return history


def whole_periods(history, since):
    """(first, last, number of periods): the times of the first and the last deepest swing (a local minimum below
    the mean) of the midspan history (time, w) from `since` on."""
    window = [(t, w) for t, w in history if t >= since - 1e-12]
    mean = sum(w for _, w in window) / len(window)
    swings = []
    for k in range(1, len(window) - 1):
        t, w = window[k]
        if w < mean and w < window[k - 1][1] and w <= window[k + 1][1]:
            if swings and t - swings[-1][0] < 0.002:  # one swing (the period is about 4.3 ms): keep its deepest
                if w < swings[-1][1]:
                    swings[-1] = (t, w)
                continue
            swings.append((t, w))
    return swings[0][0], swings[-1][0], len(swings) - 1


def mean_between(history, first, last):
    """The time average of the history (time, value) over [first, last], two of its sample times (trapezoids)."""
    segment = [(t, v) for t, v in history if first - 1e-12 <= t <= last + 1e-12]
    area = sum(0.5 * (v0 + v1) * (t1 - t0) for (t0, v0), (t1, v1) in zip(segment, segment[1:]))
    return area / (segment[-1][0] - segment[0][0])


def measure(run_dir, plate):
    history = midspan_history(run_dir)
    window = [w for t, w in history if t >= plate.measure_from - 1e-12]
    if not window:
        raise RuntimeError("{}: no frame after t = {} s".format(run_dir, plate.measure_from))
    mean = sum(window) / len(window)
    return {"history": history, "deflection": mean, "min": min(window), "max": max(window)}


def history_rms(history, reference, interval):
    """m: the RMS difference of two midspan histories, frame by frame (each frame is written at the first
    exchange at or after its output time, so the two runs' frames of one output time lie within one step,
    less than half an output `interval`, of each other)."""
    pairs = [(w, v) for (t, w), (s, v) in zip(history, reference) if abs(t - s) < 0.5 * interval]
    if len(pairs) != min(len(history), len(reference)):
        raise RuntimeError("the two runs' frames are not at the same output times")
    return math.sqrt(sum((w - v) ** 2 for w, v in pairs) / len(pairs))


def run_case(plate, work, name):
    out, wall, summary = run_scene(plate.scene_text(), work, name)
    figures = measure(out, plate)
    figures.update({"wall_s": wall, "steps": summary.get("steps"), "run_dir": out})
    return figures


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--formulations", nargs="+", default=list(FORMULATIONS), choices=FORMULATIONS)
    parser.add_argument("--wall-models", nargs="+", default=["boundary_particles"],
                        choices=["boundary_particles", "penalty"])
    parser.add_argument("--spacing", type=float, default=0.05, help="SPH particle spacing dx (m)")
    parser.add_argument("--element-size", type=float, default=0.1, help="shell element size (m)")
    parser.add_argument("--end-time", type=float, default=0.45)
    parser.add_argument("--from", dest="measure_from", type=float, default=0.2, help="start of the mean (s)")
    parser.add_argument("--settle", type=float, default=0.15, help="the water's settle_time (s)")
    parser.add_argument("--multirate", nargs="+", default=["off"], choices=["off", "on"],
                        help="[run] multirate: off (lock-step, the shells' step for all), on (the water at its own "
                        "step, the shells subcycling with its forces held), or both (the deflection and its history "
                        "against lock-step's)")
    parser.add_argument("--max-dt", type=float, nargs="+", default=[None],
                        help="[run] max_dt (s), one multirate run each: the longest exchange (the fluid's forces "
                        "held over at most this)")
    parser.add_argument("--keep", help="folder for the scenes and run folders (default: a temporary one)")
    parser.add_argument("--json", help="also write the figures here")
    args = parser.parse_args()
    work = args.keep or tempfile.mkdtemp(prefix="sabo_plate_")
    os.makedirs(work, exist_ok=True)
    results, failures = [], []
    for wall_model in args.wall_models:
        for formulation in args.formulations:
            # Lock-step runs once (max_dt does not change the shells' step); multirate once per max_dt.
            runs = ([("off", None)] if "off" in args.multirate else []) + (
                [("on", d) for d in args.max_dt] if "on" in args.multirate else [])
            for multirate, max_dt in runs:
                plate = Plate(args.spacing, args.element_size, formulation, wall_model, args.end_time,
                              args.measure_from, args.settle, multirate == "on", max_dt)
                name = "{}_{}_dx{:g}_e{:g}{}{}".format(wall_model, formulation, args.spacing, args.element_size,
                                                       "_multirate" if multirate == "on" else "",
                                                       "_max{:g}".format(max_dt) if max_dt else "")
                try:
                    figures = run_case(plate, work, name)
                except RuntimeError as error:
                    # An unstable run (the instability check stopped it) is a result too.
                    why = next((line for line in str(error).splitlines() if "unstable" in line), "")
                    failures.append((name, why[why.find("unstable"):].split(". ")[0] if why else
                                     str(error).splitlines()[0]))
                    print("{}: FAILED: {}".format(name, failures[-1][1]), file=sys.stderr)
                    continue
                figures.update({"formulation": formulation, "wall_model": wall_model, "multirate": multirate,
                                "max_dt": max_dt})
                results.append(figures)
                print("{}: midspan {:.4e} m ({:+.1%} of {:.3g}), range {:.3e}..{:.3e}, {} steps, {:.0f} s".format(
                    name, figures["deflection"], figures["deflection"] / REFERENCE - 1, REFERENCE, figures["min"],
                    figures["max"], figures["steps"], figures["wall_s"]), file=sys.stderr)
    bending, shear = bending_deflection(), shear_deflection()
    print("Euler-Bernoulli (plane strain) {:.4e} m, Mindlin {:.4e} m".format(bending, bending + shear))
    print("| wall model | shells | multirate, max_dt | dx | element | midspan deflection (m) | against -6.86e-5 | "
          "within 3 % | against Mindlin {:.3e} | oscillation min..max (m) | "
          "against lock-step: mean, RMS of the history | exchanges | wall time |".format(bending + shear))
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for r in results:
        off = r["deflection"] / REFERENCE - 1
        lock = next((q for q in results if q["multirate"] == "off" and q["formulation"] == r["formulation"]
                     and q["wall_model"] == r["wall_model"] and not q["max_dt"]), None)
        against = "" if lock is None or lock is r else "{:+.2%}, {:.2%}".format(
            r["deflection"] / lock["deflection"] - 1,
            history_rms(r["history"], lock["history"], OUTPUT_INTERVAL) / abs(lock["deflection"]))
        rate = r["multirate"] + (", {:g} s".format(r["max_dt"]) if r["max_dt"] else "")
        print("| {} | {} | {} | {:g} | {:g} | {:.4e} | {:+.1%} | {} | {:+.1%} | {:.2e}..{:.2e} | {} | {} | {:.0f} s |"
              .format(r["wall_model"], r["formulation"], rate, args.spacing, args.element_size,
                      r["deflection"], off, "yes" if abs(off) <= TOLERANCE else "no",
                      r["deflection"] / (bending + shear) - 1, r["min"], r["max"], against, r["steps"], r["wall_s"]))
    for name, why in failures:
        print("| {} | | | | | failed: {} | | | | | | | |".format(name, why))
    if args.json:
        with open(args.json, "w", encoding="utf-8") as handle:
            json.dump(results, handle, indent=1)


if __name__ == "__main__":
    main()
