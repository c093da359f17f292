#!/usr/bin/env python3
"""F2, the Taylor bar through a scene (configs/tests/taylor_bar.toml, `./sabo run`): a copper cylinder at
227 m/s against a rigid wall, met through the fem_solver's contact between structures. For every
hexahedron formulation and mesh asked for, prints the final length (docs/benchmarks.md: 21.42-21.66 mm), the
final radius of the impact face, the energy balance error (the largest |total + dissipated - initial| over
the initial energy in energy.csv) and the wall time, as a markdown table (bench/RESULTS.md).

    bench/taylor_bar.py                                  # 3 formulations x meshes 8x30 and 12x45
    bench/taylor_bar.py --formulations one_point --meshes 4x15 --keep /tmp/taylor

Meshes SECTIONxAXIAL come from scripts/make_cylinder_msh.py. Python 3.8+, standard library only; it
builds nothing (run ./sabo setup first; $SABO_BUILD_DIR picks the build folder).
"""
import argparse
import csv
import json
import math
import os
import re
import subprocess
import sys
import tempfile
import time

sys.path.insert(0, os.path.dirname(os.path.realpath(__file__)))
from scene_runs import pvd_frames, read_vtu  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.realpath(__file__)))
SCENE = os.path.join(ROOT, "configs", "tests", "taylor_bar.toml")
BAND_MM = (21.42, 21.66)
FORMULATIONS = ("one_point", "fully_integrated", "enhanced_strain")


def last_volume(run_dir, part="bar"):
    return max(pvd_frames(run_dir, "fem_" + part))


def measure(run_dir):
    """Final length (m), impact-face radius (m), energy balance error, of a finished Taylor-bar run."""
    time_s, path = last_volume(run_dir)
    arrays = read_vtu(path)
    points, displacement = arrays["Points"], arrays["displacement"]
    zs = [p[2] for p in points]
    radius = 0.0
    for p, u in zip(points, displacement):
        if p[2] - u[2] == 0.0:  # a node of the impact face (z = 0 in the mesh)
            radius = max(radius, math.hypot(p[0], p[1]))
    with open(os.path.join(run_dir, "energy.csv"), newline="") as handle:
        rows = list(csv.DictReader(handle))
    initial = float(rows[0]["total"])
    balance = max(abs(float(r["total"]) + float(r["dissipated"]) - initial) for r in rows) / initial
    return {"time": time_s, "length": max(zs) - min(zs), "lowest": min(zs), "face_radius": radius,
            "balance": balance}


def scene_text(mesh_file, formulation):
    with open(SCENE, encoding="utf-8") as handle:
        text = handle.read()
    text = text.replace('file = "meshes/taylor_bar_8x30.msh"', 'file = "{}"'.format(mesh_file))
    return re.sub(r'element_formulation = "\w+"', 'element_formulation = "{}"'.format(formulation), text)


def mesh_path(folder, name):
    committed = os.path.join(ROOT, "configs", "tests", "meshes", "taylor_bar_{}.msh".format(name))
    if os.path.isfile(committed):
        return committed
    section, axial = (int(v) for v in name.split("x"))
    path = os.path.join(folder, "taylor_bar_{}.msh".format(name))
    subprocess.run([sys.executable, os.path.join(ROOT, "scripts", "make_cylinder_msh.py"), path, "--section",
                    str(section), "--axial", str(axial)], check=True)
    return path


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--formulations", nargs="+", default=list(FORMULATIONS), choices=FORMULATIONS)
    parser.add_argument("--meshes", nargs="+", default=["8x30", "12x45"], help="SECTIONxAXIAL")
    parser.add_argument("--keep", help="folder for the run folders (default: a temporary one, removed)")
    parser.add_argument("--json", help="also write the figures here")
    args = parser.parse_args()
    work = args.keep or tempfile.mkdtemp(prefix="sabo_taylor_")
    os.makedirs(work, exist_ok=True)
    env = dict(os.environ)
    results = []
    for mesh in args.meshes:
        mesh_file = mesh_path(work, mesh)
        for formulation in args.formulations:
            name = "{}_{}".format(mesh, formulation)
            scene = os.path.join(work, name + ".toml")
            with open(scene, "w", encoding="utf-8") as handle:
                handle.write(scene_text(mesh_file, formulation))
            out = os.path.join(work, name)
            start = time.time()
            run = subprocess.run([os.path.join(ROOT, "sabo"), "run", scene, "--out", out, "--quiet", "--no-setup"],
                                 env=env, capture_output=True, text=True)
            wall = time.time() - start
            if run.returncode != 0:
                sys.exit("{}: ./sabo run failed ({}):\n{}{}".format(name, run.returncode, run.stdout, run.stderr))
            figures = measure(out)
            figures.update({"mesh": mesh, "formulation": formulation, "wall_s": wall})
            with open(os.path.join(out, "summary.json"), encoding="utf-8") as handle:
                figures["steps"] = json.load(handle).get("steps")
            results.append(figures)
            print("{}: length {:.3f} mm, impact-face radius {:.3f} mm, balance {:.2f} %, {:.0f} s".format(
                name, 1e3 * figures["length"], 1e3 * figures["face_radius"], 100 * figures["balance"], wall),
                file=sys.stderr)
    print("| mesh | formulation | final length (mm) | in 21.42-21.66 | impact-face radius (mm) | energy balance "
          "| steps | wall time |")
    print("|---|---|---|---|---|---|---|---|")
    for r in results:
        inside = BAND_MM[0] <= 1e3 * r["length"] <= BAND_MM[1]
        print("| {} | {} | {:.2f} | {} | {:.2f} | {:.2f} % | {} | {:.0f} s |".format(
            r["mesh"], r["formulation"], 1e3 * r["length"], "yes" if inside else "no", 1e3 * r["face_radius"],
            100 * r["balance"], r["steps"], r["wall_s"]))
    if args.json:
        with open(args.json, "w", encoding="utf-8") as handle:
            json.dump(results, handle, indent=1)


if __name__ == "__main__":
    main()
