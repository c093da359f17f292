#!/usr/bin/env python3
"""B1, a Newtonian surge stopped by a rigid wall (Armanini & Scotton 1992), through a scene (`./sabo run`:
coupler, sph_solver, fem_solver). A block of water of depth h moving at v = Fr sqrt(g h) meets a vertical
wall; it reflects as a bore of height r h, Fr^2 = (r - 1)^2 (1 + r) / (2 r), and while the bore runs
upstream the wall carries the quasi-steady force per unit width F = rho g (r h)^2 / 2 = alpha rho v^2 h,
alpha = r^2 / (2 Fr^2) (2.35 at Fr = 1, 1.53 at 2, 1.22 at 4). For every Froude number asked for, prints
the force plateau per unit width against alpha rho v^2 h, the bore's height read by a line gauge, the peak
force, steps and wall time, as a markdown table (bench/RESULTS.md), and draws alpha(Fr) against the theory
curve (`--plot`, needs matplotlib).

    bench/surge_wall.py                                   # Fr = 1, 2, 4 at h = 8 dx
    bench/surge_wall.py --froude 1 --spacings 6 --keep /tmp/surge --plot /tmp/alpha.png
    bench/surge_wall.py --replot fr12.json fr4.json --plot /tmp/alpha.png   # runs of several invocations

The channel is periodic across its width (`sph.periodic_y`, 8 spacings: a slice of an infinitely wide
surge); floor and wall are rigid planes sampled as boundary particles. The block is long enough that the
plateau lasts `--window` (in T = h / sqrt(g h)) after the impact's transient: at Fr > 1 the front first
runs up the wall as a jet and falls back (about 2 v / g), and the plateau ends when the rarefaction from
the block's tail has met the bore and its echo has come back to the wall (a block of about 16 h at
Fr = 1, 84 h at Fr = 4 for the default window). Python 3.8+, standard library
only for the runs; it builds nothing (run ./sabo setup first; $SABO_BUILD_DIR picks the build folder).
"""
import argparse
import csv
import json
import math
import os
import sys
import tempfile

sys.path.insert(0, os.path.dirname(os.path.realpath(__file__)))
from scene_runs import pvd_frames, read_vtu, run_scene  # noqa: E402

GRAVITY = 9.81
DENSITY = 1000.0
# docs/benchmarks.md's table of alpha (F = alpha rho v^2 h per unit width) for a surge of Froude number Fr.
ALPHA_TABLE = {1.0: 2.35, 2.0: 1.53, 4.0: 1.22}
TOLERANCE = 0.10


def bore_ratio(froude):
    """r > 1 of the bore reflected from the wall: Fr^2 = (r - 1)^2 (1 + r) / (2 r) (mass and momentum
    across the bore in the wall's frame), by bisection; the right side grows with r."""
    def excess(r):
        return (r - 1.0) ** 2 * (1.0 + r) / (2.0 * r) - froude ** 2
    lo, hi = 1.0, 2.0
    while excess(hi) < 0.0:
        hi *= 2.0
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if excess(mid) < 0.0 else (lo, mid)
    return 0.5 * (lo + hi)


def alpha_theory(froude):
    return bore_ratio(froude) ** 2 / (2.0 * froude ** 2)


class Surge:
    """One case: its geometry, the plateau window and the scene, in SI units. x runs towards the wall
    (at x = 0), z up, y across the periodic width."""

    def __init__(self, froude, spacings=8, depth=0.04, window=8.0, length=None, alpha_viscosity=0.005,
                 free_slip=False, width=None, settle=None, wall_spacing_ratio=1.0):
        self.froude = froude
        # sph.wall_spacing_ratio: at 1 a Fr = 4 surge's bottom row, sliding at a tenth of the sound speed, is pumped
        # by the floor's lattice and falls through it (docs/physics.md, "Walls"); at 0.5 it stays on it.
        self.wall_spacing_ratio = wall_spacing_ratio
        self.artificial_viscosity = alpha_viscosity
        self.free_slip = free_slip  # floor and wall free-slip ([sph] free_slip_walls): the bore theory's walls
        self.depth = depth
        self.spacing = depth / spacings
        self.celerity = math.sqrt(GRAVITY * depth)
        self.time_unit = depth / self.celerity
        self.speed = froude * self.celerity
        self.ratio = bore_ratio(froude)
        self.alpha = alpha_theory(froude)
        self.bore_speed = self.speed / (self.ratio - 1.0)  # upstream, in the ground's frame
        self.width = width if width is not None else 8 * self.spacing  # m, the periodic span across
        # The window's start: the jet up and back, then a few T (or `settle` T after the impact).
        self.settled = (settle if settle is not None else 2.0 * froude + 3.0) * self.time_unit
        # The head of the rarefaction from the block's tail runs into the block at c relative to the water,
        # v + c towards the wall; it meets the bore after L / (v + c + w), and that news reaches the wall at the
        # speed sqrt(g r h) of the still water behind the bore.
        closing = self.speed + self.celerity + self.bore_speed
        echo = 1.0 + self.bore_speed / math.sqrt(GRAVITY * self.ratio * depth)
        if length is None:
            wanted = self.settled + window * self.time_unit
            length = math.ceil(wanted * closing / echo / depth) * depth
        self.length = length
        self.plateau_end = length / closing * echo
        self.end_time = self.plateau_end + 1.0 * self.time_unit
        # The jet runs up the wall to about v^2 / 2g = Fr^2 h / 2 and its splash about twice that: the wall and the
        # domain stand above it, so that no water leaves over the wall (at (Fr^2 + r + 2) h, a Fr = 4 surge lost a
        # third of its water over it, and with it the plateau). A whole number of spacings, so that the wall's
        # lattice of wall particles coincides with the floor's in the corner (at 676.04 wall spacings a Fr = 4
        # surge lost 976 particles below the wall's foot; the cause is not known: docs/physics.md, concave corners).
        self.wall_height = math.ceil((2.0 * froude ** 2 + self.ratio + 4.0) * depth / self.spacing) * self.spacing
        self.sound_speed = 10.0 * max(self.speed, math.sqrt(GRAVITY * self.ratio * depth))
        self.output_interval = self.time_unit / 8.0

    def expected_force(self):
        """alpha rho v^2 h per unit width (N/m)."""
        return self.alpha * DENSITY * self.speed ** 2 * self.depth

    def scene_text(self):
        h, dx, L, W = self.depth, self.spacing, self.length, self.width
        tail = 3.0 * h
        floor_length = L + tail
        gauge_x = -3.0 * h
        lines = [
            "# B1 surge on a rigid wall, Fr = {:g}: h = {:g} m, v = {:.6g} m/s, block {:g} m long ({:g} h), "
            "dx = {:g} m".format(self.froude, h, self.speed, L, L / h, dx),
            "format_version = 1",
            "",
            "[run]",
            "end_time = {:.6g}".format(self.end_time),
            "output_interval = {:.6g}".format(self.output_interval),
            "gravity = [0.0, 0.0, {}]".format(-GRAVITY),
            "checkpoint_interval = 0",
            "",
            "[materials.water]",
            "density = {}".format(DENSITY),
            "youngs_modulus = 2.2e9",
            "poisson_ratio = 0.0",
            'eos = "tait"',
            "",
            "[materials.concrete]",
            "density = 2400.0",
            "youngs_modulus = 30e9",
            "poisson_ratio = 0.2",
            "",
            "[sph]",
            "particle_spacing = {!r}".format(dx),
            "sound_speed = {:.6g}".format(self.sound_speed),
            'wall_model = "boundary_particles"',
            "wall_spacing_ratio = {:g}".format(self.wall_spacing_ratio),
            "artificial_viscosity = {:g}".format(self.artificial_viscosity),
            "periodic_y = [0.0, {:.9g}]".format(W),
            'free_slip_walls = ["floor", "wall"]' if self.free_slip else "# no-slip floor and wall",
            "domain_min = [{:.9g}, {:.9g}, {:.9g}]".format(-floor_length - 2 * h, -W, -2 * h),
            "domain_max = [{:.9g}, {:.9g}, {:.9g}]".format(2 * h, 2 * W, self.wall_height + 4 * h),
            "",
            "[[fluids]]",
            'name = "surge"',
            'material = "water"',
            'shape = "box"',
            "min = [{:.9g}, 0.0, 0.0]".format(-L),
            "max = [0.0, {:.9g}, {:.9g}]".format(W, h),
            "velocity = [{:.9g}, 0.0, 0.0]".format(self.speed),
            "",
            "[[structures]]",
            'name = "floor"',
            'material = "concrete"',
            'shape = "plane"',
            "origin = [{:.9g}, {:.9g}, 0.0]".format(-floor_length / 2, W / 2),
            "normal = [0.0, 0.0, 1.0]",
            "direction = [1.0, 0.0, 0.0]",
            "length = {:.9g}".format(floor_length),
            "width = {:.9g}".format(W),
            "element_size = {:.9g}".format(max(W, h)),
            "",
            "[[structures]]",
            'name = "wall"',
            'material = "concrete"',
            'shape = "plane"',
            "origin = [0.0, {:.9g}, {:.9g}]".format(W / 2, self.wall_height / 2),
            "normal = [-1.0, 0.0, 0.0]",
            "direction = [0.0, 0.0, 1.0]",
            "length = {:.9g}".format(self.wall_height),
            "width = {:.9g}".format(W),
            "element_size = {:.9g}".format(max(W, h)),
            "",
            "[[gauges]]",
            'name = "bore"',
            'kind = "line"',
            "start = [{:.9g}, {:.9g}, 0.0]".format(gauge_x, W / 2),
            "end = [{:.9g}, {:.9g}, {:.9g}]".format(gauge_x, W / 2, (self.ratio + 3.0) * h),
            "points = 2",
            "interval = {:.6g}".format(self.output_interval),
            "",
            "# The pressure one spacing in front of the wall, integrated over the height: the wall's load as the",
            "# fluid carries it, beside the force the wall particles pass to the wall.",
            "[[gauges]]",
            'name = "wall_profile"',
            'kind = "line"',
            "start = [{!r}, {!r}, 0.0]".format(-dx, W / 2),
            "end = [{!r}, {!r}, {!r}]".format(-dx, W / 2, self.wall_height),
            "points = {}".format(int(round(self.wall_height / (0.5 * dx))) + 1),
            "interval = {:.6g}".format(self.output_interval),
            "",
            "[recording]",
            "enabled = false",
            "",
        ]
        return "\n".join(lines)


def read_csv(path):
    with open(path, newline="") as handle:
        return list(csv.DictReader(handle))


def measure(run_dir, surge):
    """The wall's force history per unit width (forces.csv: the fluid on `wall`, each row the mean over one
    output interval), its plateau over [settled, plateau_end], the peak, the bore's depth at the gauge and the
    wall profile's pressure integrated over the height (N/m), over the same window."""
    history = []
    for row in read_csv(os.path.join(run_dir, "forces.csv")):
        if row["part"] == "wall" and row["source"] == "fluid":
            history.append((float(row["time"]), float(row["Fx"]) / surge.width))
    window = [f for t, f in history if surge.settled <= t <= surge.plateau_end]
    if not window:
        raise RuntimeError("{}: no forces.csv row of the wall inside the plateau window".format(run_dir))
    plateau = sum(window) / len(window)
    # gauges.csv once: the bore line's depth and the wall profile's pressures, inside the window.
    depths, profiles = [], {}
    for row in read_csv(os.path.join(run_dir, "gauges.csv")):
        if not surge.settled <= float(row["time"]) <= surge.plateau_end:
            continue
        if row["gauge"] == "bore" and row["point"] == "0":
            depths.append(float(row["depth"]))
        elif row["gauge"] == "wall_profile":
            profiles.setdefault(row["time"], []).append((float(row["z"]), float(row["pressure"])))
    bore = sum(depths) / len(depths) if depths else float("nan")
    integrals = []
    for points in profiles.values():
        points.sort()
        integrals.append(sum(0.5 * (p0 + p1) * (z1 - z0) for (z0, p0), (z1, p1) in zip(points, points[1:])))
    profile_force = sum(integrals) / len(integrals) if integrals else float("nan")
    return {
        "history": history,
        "plateau": plateau,
        "alpha": plateau / (DENSITY * surge.speed ** 2 * surge.depth),
        "peak": max(f for _, f in history),
        "bore_depth": bore,
        "profile_force": profile_force,
    }


def particles_lost(run_dir):
    """Fluid particles taken out of the domain by the end (active 0 in the last sph frame)."""
    frames = pvd_frames(run_dir, "sph")
    return sum(1 for flag in read_vtu(frames[-1][1])["active"] if flag[0] == 0)


def run_case(surge, work, name):
    out, wall, summary = run_scene(surge.scene_text(), work, name)
    figures = measure(out, surge)
    figures.update({"wall_s": wall, "steps": summary.get("steps"), "run_dir": out, "lost": particles_lost(out)})
    if figures["lost"]:
        print("{}: {} particles left the domain (through the floor or over the wall): the plateau is not the surge's".format(
            name, figures["lost"]), file=sys.stderr)
    return figures


def plot_alpha(results, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    froudes = [0.8 + 0.02 * k for k in range(200)]
    fig, ax = plt.subplots(figsize=(6, 4.5))
    ax.plot(froudes, [alpha_theory(fr) for fr in froudes], "k-", label="bore theory: alpha = r² / (2 Fr²)")
    ax.plot(list(ALPHA_TABLE), list(ALPHA_TABLE.values()), "ks", mfc="none", label="docs/benchmarks.md table")
    ax.fill_between(froudes, [(1 - TOLERANCE) * alpha_theory(fr) for fr in froudes],
                    [(1 + TOLERANCE) * alpha_theory(fr) for fr in froudes], color="0.85", label="±10 %")
    def variant(r):
        return r["spacings"], r.get("free_slip", False), r.get("wall_spacing_ratio", 1.0)

    markers = "osD^v<>"
    for k, (spacings, free_slip, ratio) in enumerate(sorted({variant(r) for r in results})):
        chosen = [r for r in results if variant(r) == (spacings, free_slip, ratio)]
        ax.plot([r["froude"] for r in chosen], [r["alpha"] for r in chosen], markers[k % len(markers)],
                label="Sabo, h = {} dx, {} walls, wall particles at {}".format(
                    spacings, "free-slip" if free_slip else "no-slip", "dx" if ratio == 1 else "{:g} dx".format(ratio)))
    ax.set_xlabel("Froude number Fr = v / sqrt(g h)")
    ax.set_ylabel("alpha = F / (rho v² h) per unit width")
    ax.set_title("B1: surge on a rigid wall")
    ax.grid(True, alpha=0.3)
    ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
    print("wrote {}".format(path), file=sys.stderr)


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--froude", type=float, nargs="+", default=sorted(ALPHA_TABLE))
    parser.add_argument("--spacings", type=int, nargs="+", default=[8], help="particles across the depth h")
    parser.add_argument("--depth", type=float, default=0.04, help="surge depth h (m)")
    parser.add_argument("--window", type=float, default=8.0, help="plateau length in T = h / sqrt(g h)")
    parser.add_argument("--settle", type=float,
                        help="the plateau window's start, in T after the impact (default 2 Fr + 3: the jet up and "
                             "back, then a few T); the block is made longer to match")
    parser.add_argument("--width-spacings", type=int, default=8,
                        help="the periodic channel's width in spacings (a slice of a wide surge; at least 7: "
                             "two kernel supports and a spacing)")
    parser.add_argument("--artificial-viscosity", type=float, default=0.005,
                        help="sph.artificial_viscosity (it also acts as a friction of the floor)")
    parser.add_argument("--free-slip", action="store_true",
                        help="free-slip floor and wall ([sph] free_slip_walls), as the bore theory's; default no-slip")
    parser.add_argument("--wall-spacing-ratio", type=float, default=0.5,
                        help="sph.wall_spacing_ratio, the wall particles' spacing over dx (default 0.5: at 1 the "
                             "surge's bottom row falls through the floor at Fr = 4)")
    parser.add_argument("--keep", help="folder for the scenes and run folders (default: a temporary one)")
    parser.add_argument("--json", help="also write the figures here")
    parser.add_argument("--plot", help="draw alpha(Fr) into this PNG")
    parser.add_argument("--replot", nargs="+", metavar="JSON",
                        help="run nothing: draw --plot from the figures that earlier runs wrote with --json (runs "
                             "of several invocations in one figure)")
    args = parser.parse_args()
    if args.replot:
        if not args.plot:
            parser.error("--replot draws a figure: name it with --plot FILE.png")
        results = []
        for path in args.replot:
            try:
                with open(path, encoding="utf-8") as handle:
                    figures = json.load(handle)
            except (OSError, ValueError) as error:
                parser.error("--replot {}: {} (a list of figures written by --json)".format(path, error))
            if not isinstance(figures, list) or not all(
                    isinstance(r, dict) and {"froude", "alpha", "spacings"} <= r.keys() for r in figures):
                parser.error("--replot {}: not a list of figures with froude, alpha and spacings (what --json "
                             "writes)".format(path))
            results.extend(figures)
        plot_alpha(results, args.plot)
        return
    work = args.keep or tempfile.mkdtemp(prefix="sabo_surge_")
    os.makedirs(work, exist_ok=True)
    results = []
    for spacings in args.spacings:
        for froude in args.froude:
            surge = Surge(froude, spacings, args.depth, args.window, alpha_viscosity=args.artificial_viscosity,
                          free_slip=args.free_slip, width=args.width_spacings * args.depth / spacings,
                          settle=args.settle, wall_spacing_ratio=args.wall_spacing_ratio)
            name = "fr{:g}_n{}_av{:g}{}{}{}{}".format(
                froude, spacings, args.artificial_viscosity, "_free_slip" if args.free_slip else "",
                "" if args.settle is None else "_from{:g}T".format(args.settle),
                "" if args.width_spacings == 8 else "_w{}".format(args.width_spacings),
                "" if args.wall_spacing_ratio == 0.5 else "_walls{:g}".format(args.wall_spacing_ratio))
            figures = run_case(surge, work, name)
            figures.update({"froude": froude, "spacings": spacings, "free_slip": args.free_slip,
                            "wall_spacing_ratio": args.wall_spacing_ratio, "length": surge.length,
                            "expected": surge.expected_force(), "alpha_theory": surge.alpha,
                            "bore_expected": surge.ratio * surge.depth, "window": [surge.settled, surge.plateau_end]})
            results.append(figures)
            print("{}: alpha {:.3f} (theory {:.3f}, {:+.1%}), bore {:.4f} m (theory {:.4f} m), the pressure 1 dx in "
                  "front of the wall integrated {:.2f} N/m against the wall's {:.2f} N/m, {:.0f} s".format(
                      name, figures["alpha"], surge.alpha, figures["alpha"] / surge.alpha - 1, figures["bore_depth"],
                      surge.ratio * surge.depth, figures["profile_force"], figures["plateau"], figures["wall_s"]),
                  file=sys.stderr)
    print("| Fr | h / dx | block (h) | plateau window (T) | F plateau (N/m) | alpha rho v^2 h (N/m) | alpha "
          "measured / theory | within 10 % | bore r h measured / theory (m) | pressure 1 dx in front, integrated "
          "(N/m) | peak / plateau | particles lost | steps | wall time |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    time_unit = math.sqrt(args.depth / GRAVITY)
    for r in results:
        off = r["alpha"] / r["alpha_theory"] - 1
        print("| {:g} | {} | {:g} | {:.1f}-{:.1f} | {:.2f} | {:.2f} | {:.3f} / {:.3f} ({:+.1%}) | {} | {:.4f} / "
              "{:.4f} | {:.2f} | {:.2f} | {} | {} | {:.0f} s |".format(
                  r["froude"], r["spacings"], r["length"] / args.depth, r["window"][0] / time_unit,
                  r["window"][1] / time_unit, r["plateau"], r["expected"], r["alpha"], r["alpha_theory"], off,
                  "yes" if abs(off) <= TOLERANCE else "no", r["bore_depth"], r["bore_expected"], r["profile_force"],
                  r["peak"] / r["plateau"], r["lost"], r["steps"], r["wall_s"]))
    if args.json:
        with open(args.json, "w", encoding="utf-8") as handle:
            json.dump(results, handle, indent=1)
    if args.plot:
        plot_alpha(results, args.plot)


if __name__ == "__main__":
    main()
