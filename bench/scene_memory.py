#!/usr/bin/env python3
"""Memory per entity of a whole run: the constants of libsabo/scene/estimate.hpp.

Runs small scenes through `./sabo run` at two sizes each, every process under
/usr/bin/time (peak RSS, through SABO_PLAN_OVERRIDE), and prints the bytes per
entity of all the processes together (the slope between the two sizes) and what
the processes take before their first entity (the intercept). One kind of entity
grows per scene: fluid particles (penalty walls), wall particles (boundary
walls of the same tank, the fluid's share taken off), spheres, hexahedra,
shells and rigid surface triangles. Each run is a few steps.

    bench/scene_memory.py [--json OUT]          (about a minute on 2 cores)

Figures in bench/RESULTS.md ("Scene size"). Standard library only.
"""
import argparse
import json
import os
import re
import subprocess
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
BUILD = os.environ.get("SABO_BUILD_DIR") or os.path.join(ROOT, "build")

MATERIALS = """
[materials.water]
density = 1000.0
youngs_modulus = 2.2e9
poisson_ratio = 0.0

[materials.steel]
density = 7850.0
youngs_modulus = 200e9
poisson_ratio = 0.3
"""

TANK_WALLS = "".join("""
[[structures]]
name = "{name}"
material = "steel"
shape = "plane"
origin = {origin}
normal = {normal}
direction = {direction}
length = {length}
width = {width}
""".format(name=name, origin=origin, normal=normal, direction=direction, length=length, width=width)
    for name, origin, normal, direction, length, width in (
        ("floor", "[0.5, 0.5, 0.0]", "[0.0, 0.0, 1.0]", "[1.0, 0.0, 0.0]", 1.0, 1.0),
        ("wall_x0", "[0.0, 0.5, 0.25]", "[1.0, 0.0, 0.0]", "[0.0, 1.0, 0.0]", 1.0, 0.5),
        ("wall_x1", "[1.0, 0.5, 0.25]", "[-1.0, 0.0, 0.0]", "[0.0, 1.0, 0.0]", 1.0, 0.5),
        ("wall_y0", "[0.5, 0.0, 0.25]", "[0.0, 1.0, 0.0]", "[1.0, 0.0, 0.0]", 1.0, 0.5),
        ("wall_y1", "[0.5, 1.0, 0.25]", "[0.0, -1.0, 0.0]", "[1.0, 0.0, 0.0]", 1.0, 0.5)))


def tank(dx, walls):
    return """format_version = 1
[run]
end_time = {end}
output_interval = 1.0
[recording]
enabled = false
{materials}
[sph]
particle_spacing = {dx}
sound_speed = 20.0
wall_model = "{walls}"
[[fluids]]
name = "water"
material = "water"
shape = "box"
min = [0.0, 0.0, 0.0]
max = [1.0, 1.0, 0.5]
{tank}""".format(end=3 * 0.25 * 1.5 * dx / 20.0, materials=MATERIALS, dx=dx, walls=walls, tank=TANK_WALLS)


def spheres(count):
    return """format_version = 1
[run]
end_time = 0.002
output_interval = 1.0
[recording]
enabled = false
{materials}
[[particles]]
name = "gravel"
material = "steel"
fill = {{ min = [0.0, 0.0, 0.0], max = [{side}, {side}, {side}], count = {count}, diameter = [0.01, 0.01] }}
""".format(materials=MATERIALS, count=count, side=round(0.0212 * count ** (1 / 3), 4))


def solid(divisions):
    return """format_version = 1
[run]
end_time = 2e-5
output_interval = 1.0
[recording]
enabled = false
{materials}
[[structures]]
name = "block"
material = "steel"
rigid = false
shape = "box"
min = [0.0, 0.0, 0.0]
max = [1.0, 1.0, 1.0]
element_size = {size}
""".format(materials=MATERIALS, size=1.0 / divisions)


def shell(divisions):
    return """format_version = 1
[run]
end_time = 2e-5
output_interval = 1.0
[recording]
enabled = false
{materials}
[[structures]]
name = "panel"
material = "steel"
rigid = false
shape = "plane"
thickness = 0.01
origin = [0.0, 0.0, 0.0]
normal = [0.0, 0.0, 1.0]
length = 1.0
width = 1.0
element_size = {size}
""".format(materials=MATERIALS, size=1.0 / divisions)


def triangles(divisions):
    return """format_version = 1
[run]
end_time = 0.002
output_interval = 1.0
[recording]
enabled = false
{materials}
[[particles]]
name = "boulder"
material = "steel"
spheres = [ {{ center = [0.0, 0.0, 0.5], radius = 0.1 }} ]
[[structures]]
name = "floor"
material = "steel"
shape = "plane"
origin = [0.0, 0.0, 0.0]
normal = [0.0, 0.0, 1.0]
length = 10.0
width = 10.0
element_size = {size}
""".format(materials=MATERIALS, size=10.0 / divisions)


def run(name, text, work):
    """Peak RSS of every process (bytes), and the run's logs."""
    scene = os.path.join(work, name + ".toml")
    with open(scene, "w") as handle:
        handle.write(text)
    checker = subprocess.run([os.path.join(BUILD, "bin", "sabo_scene"), "check", scene], capture_output=True,
                             text=True, check=True)
    plan = json.loads(checker.stdout)
    out = os.path.join(work, name)
    for process in plan["processes"]:
        process["command"] = ["/usr/bin/time", "-f", "%M", "-o",
                              os.path.join(work, "{}.{}.rss".format(name, process["role"]))] + process["command"]
    override = os.path.join(work, name + ".plan.json")
    with open(override, "w") as handle:
        json.dump(plan, handle)
    environment = dict(os.environ, SABO_PLAN_OVERRIDE=override, OMP_NUM_THREADS="1", SABO_BUILD_DIR=BUILD)
    result = subprocess.run([os.path.join(ROOT, "sabo"), "run", scene, "--out", out, "--no-setup", "--quiet"],
                            env=environment, capture_output=True, text=True)
    if result.returncode != 0:
        sys.exit("{}: ./sabo run failed:\n{}{}".format(name, result.stdout, result.stderr))
    rss = {}
    for process in plan["processes"]:
        with open(os.path.join(work, "{}.{}.rss".format(name, process["role"]))) as handle:
            rss[process["role"]] = 1024 * int(handle.read().split()[-1])  # kB
    logs = ""
    for log in os.listdir(out):
        if log.endswith(".log"):
            with open(os.path.join(out, log), errors="replace") as handle:
                logs += handle.read()
    return rss, logs, plan["estimate"]


def count(pattern, logs):
    found = re.findall(pattern, logs)
    if not found:
        raise RuntimeError("no match for {!r} in the logs".format(pattern))
    return sum(int(value) for value in found)


CASES = [
    # name, scene at two sizes, (what is counted, how, from the logs)
    ("fluid particles", lambda k: tank(0.04 / k, "penalty"),
     lambda logs, e: count(r"(\d+) SPH particles in", logs)),
    ("wall particles", lambda k: tank(0.04 / k, "boundary_particles"),
     lambda logs, e: count(r"sampled the FEM surface into (\d+) boundary particles", logs)),
    ("spheres", lambda k: spheres(2000 * k ** 3), lambda logs, e: count(r"(\d+) spheres in \d+ sets", logs)),
    ("hexahedra", lambda k: solid(12 * k), lambda logs, e: round(e["elements"])),
    ("shells", lambda k: shell(60 * k), lambda logs, e: round(e["elements"])),
    ("surface triangles", lambda k: triangles(60 * k), lambda logs, e: count(r"(\d+) faces", logs)),
]


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--json", metavar="OUT", help="also write the figures to OUT")
    args = parser.parse_args()
    results = []
    fluid_slope = None
    with tempfile.TemporaryDirectory(prefix="sabo-memory-") as work:
        for name, scene, counted in CASES:
            points = []
            for k in (1, 2):
                rss, logs, estimate = run("{}-{}".format(name.replace(" ", "_"), k), scene(k), work)
                points.append((counted(logs, estimate), sum(rss.values()), rss, estimate))
            (n1, m1, _, e1), (n2, m2, rss2, e2) = points
            slope = (m2 - m1) / (n2 - n1)
            intercept = m1 - slope * n1
            if name == "fluid particles":
                fluid_slope = slope
            if name == "wall particles":  # the same tank: take off the fluid's share
                f1, f2 = e1["fluid_particles"], e2["fluid_particles"]
                slope = ((m2 - m1) - fluid_slope * (f2 - f1)) / (n2 - n1)
            row = {"entity": name, "counts": [n1, n2], "peak_rss_bytes": [m1, m2], "bytes_per_entity": slope,
                   "intercept_bytes": intercept, "processes": len(rss2),
                   "estimated_memory_bytes": [e1["memory_bytes"], e2["memory_bytes"]]}
            results.append(row)
            print("{:18s} {:>9} -> {:>9}  peak RSS {:7.1f} -> {:7.1f} MB  {:7.0f} B per entity  "
                  "(intercept {:5.1f} MB over {} processes; estimate {:7.1f} -> {:7.1f} MB)".format(
                      name, n1, n2, m1 / 1e6, m2 / 1e6, slope, intercept / 1e6, len(rss2),
                      e1["memory_bytes"] / 1e6, e2["memory_bytes"] / 1e6), flush=True)
    if args.json:
        with open(args.json, "w") as handle:
            json.dump(results, handle, indent=2)
    return 0


if __name__ == "__main__":
    sys.exit(main())
