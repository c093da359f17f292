#!/usr/bin/env python3
"""Sabo's DEM beside LIGGGHTS-PUBLIC, runs interleaved on this machine (issue 26).

LIGGGHTS is not part of the project: build it yourself (`make auto` in its src/, with Open MPI from Debian:
openmpi-bin libopenmpi-dev) and give this script the executable:

    bench/peers/liggghts.py --liggghts LIGGGHTS/src/lmp_auto [--ranks 1 2] [--runs 3]

The case is `bench_dem_box`'s (bench/dem_box.cpp): 30 000 spheres of 5 mm (rho 2500 kg/m^3, E 5 MPa,
nu 0.45, restitution 0.3, friction 0.5, no rolling resistance), Hertz with tangential history, placed at
random at a solid fraction of 0.25 in a box as wide as bench_dem_box's (side sqrt(N V / 0.25 / H), H = 40
diameters) with a floor and four side walls, settled for 0.3 s at 5e-5 s, then 1000 steps of 1e-5 s timed on
the settled bed. The neighbour skin is Sabo's (a quarter of the radius), rebuilt when a sphere has moved
half of it. This script writes the two LIGGGHTS inputs itself (settle, once per rank count; timed, each
round); LIGGGHTS splits the box along x and y only (`processors * * 1`: a split along z puts most of the bed
on one rank). What each side counts: sphere-steps per second of the timed steps, LIGGGHTS' "Loop time",
Sabo's settled phase; contacts per sphere are printed for both so that the beds can be compared.

Prints every run, the medians and the ratio Sabo / LIGGGHTS for each rank count (Sabo on as many OpenMP
threads). Standard library only; Sabo's benchmark from build/bin (or $SABO_BUILD_DIR/bin).
"""
import argparse
import json
import math
import os
import re
import shutil
import statistics
import subprocess
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.realpath(__file__))))
SPHERES = 30000
DIAMETER = 5e-3
HEIGHT = 40 * DIAMETER
SIDE = math.sqrt(SPHERES * math.pi / 6 * DIAMETER ** 3 / 0.25 / HEIGHT)
SKIN = 0.25 * 0.5 * DIAMETER
SETTLE_TIME, SETTLE_DT, DT, STEPS = 0.3, 5e-5, 1e-5, 1000

COMMON = """\
atom_style granular
atom_modify map array
boundary f f f
newton off
communicate single vel yes
units si
processors * * 1
neighbor {skin} bin
neigh_modify delay 0
"""

MODEL = """\
fix m1 all property/global youngsModulus peratomtype 5.0e6
fix m2 all property/global poissonsRatio peratomtype 0.45
fix m3 all property/global coefficientRestitution peratomtypepair 1 0.3
fix m4 all property/global coefficientFriction peratomtypepair 1 0.5
pair_style gran model hertz tangential history
pair_coeff * *
fix gravity all gravity 9.81 vector 0.0 0.0 -1.0
fix floor all wall/gran model hertz tangential history primitive type 1 zplane 0.0
fix xlow all wall/gran model hertz tangential history primitive type 1 xplane 0.0
fix xhigh all wall/gran model hertz tangential history primitive type 1 xplane {side}
fix ylow all wall/gran model hertz tangential history primitive type 1 yplane 0.0
fix yhigh all wall/gran model hertz tangential history primitive type 1 yplane {side}
fix integrate all nve/sphere
"""

SETTLE = COMMON + """\
region box block 0.0 {side} 0.0 {side} 0.0 {height} units box
create_box 1 box
""" + MODEL + """\
timestep {settle_dt}
fix template all particletemplate/sphere 15485863 atom_type 1 density constant 2500 radius constant {radius}
fix distribution all particledistribution/discrete 32452843 1 template 1.0
fix insert all insert/pack seed 49979687 distributiontemplate distribution insert_every once overlapcheck yes \
all_in yes particles_in_region {spheres} region box
run 1
unfix insert
run {settle_steps}
write_restart settled.restart
"""

TIMED = COMMON + """\
read_restart settled.restart
""" + MODEL + """\
timestep {dt}
compute contacts all contact/atom
compute total all reduce sum c_contacts
thermo_style custom step atoms c_total
thermo {steps}
run {steps}
"""

LOOP = re.compile(r"Loop time of ([0-9.eE+-]+) on (\d+) procs for (\d+) steps with (\d+) atoms")


class PeerError(Exception):
    """LIGGGHTS could not be run or its output not read: the message says which and how to mend it."""


def deck(template):
    return template.format(skin=SKIN, side=SIDE, height=HEIGHT, radius=0.5 * DIAMETER, spheres=SPHERES,
                           settle_dt=SETTLE_DT, settle_steps=int(round(SETTLE_TIME / SETTLE_DT)), dt=DT,
                           steps=STEPS)


def run_liggghts(executable, mpirun, ranks, work, name, text):
    path = os.path.join(work, name)
    with open(path, "w", encoding="utf-8") as handle:
        handle.write(text)
    command = [mpirun, "-np", str(ranks), "--oversubscribe"]
    if os.geteuid() == 0:
        command.append("--allow-run-as-root")
    command += [executable, "-in", name, "-log", name + ".log"]
    result = subprocess.run(command, cwd=work, env=dict(os.environ, OMP_NUM_THREADS="1"), stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, universal_newlines=True)
    if result.returncode != 0:
        raise PeerError("{} (in {}) failed (exit {}): {}".format(" ".join(command), work, result.returncode,
                                                                 result.stdout[-1500:]))
    return result.stdout


def read_loop(output):
    """Seconds, steps and atoms of the last run, and the contacts counted at its end."""
    loops = LOOP.findall(output)
    if not loops:
        raise PeerError("no 'Loop time of S on P procs for N steps with A atoms' line in LIGGGHTS' output")
    seconds, _, steps, atoms = loops[-1]
    contacts = None
    rows = re.findall(r"^\s*(\d+)\s+(\d+)\s+([0-9.eE+-]+)\s*$", output, re.MULTILINE)
    if rows:
        contacts = float(rows[-1][2]) / float(rows[-1][1])  # contact/atom counts each contact at both spheres
    return float(seconds), int(steps), int(atoms), contacts


def run_sabo(binary, threads):
    env = dict(os.environ, OMP_NUM_THREADS=str(threads), OMP_WAIT_POLICY="passive")
    command = [binary, "--spheres", str(SPHERES), "--diameter", str(DIAMETER), "--settle-time", str(SETTLE_TIME),
               "--settle-dt", str(SETTLE_DT), "--dt", str(DT), "--steps", str(STEPS)]
    result = subprocess.run(command, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                            universal_newlines=True)
    if result.returncode != 0:
        raise PeerError("{} failed (exit {}): {}".format(" ".join(command), result.returncode, result.stdout[-1500:]))
    data = json.loads(result.stdout.strip().splitlines()[-1])
    return {"rate": data["sphere_steps_per_second"], "contacts": data["contacts_per_sphere"]}


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--liggghts", required=True, help="the LIGGGHTS executable (e.g. src/lmp_auto)")
    parser.add_argument("--mpirun", default="mpirun", help="Open MPI's mpirun")
    parser.add_argument("--ranks", type=int, nargs="+", default=[1, 2], help="MPI ranks (Sabo: as many threads)")
    parser.add_argument("--runs", type=int, default=3, help="interleaved rounds per rank count")
    args = parser.parse_args()
    build = os.environ.get("SABO_BUILD_DIR", os.path.join(ROOT, "build"))
    sabo = os.path.join(build, "bin", "bench_dem_box")
    for path in (args.liggghts, sabo):
        if not os.access(path, os.X_OK):
            sys.exit("liggghts.py: {} is not an executable. Fix: build it (Sabo: ./sabo test, or cmake --build "
                     "build; LIGGGHTS: make auto in its src/) and give its path".format(path))
    if shutil.which(args.mpirun) is None:
        sys.exit("liggghts.py: --mpirun {} not found. Fix: sudo apt-get install openmpi-bin, or give its "
                 "path".format(args.mpirun))

    summary = {"spheres": SPHERES, "box_side_m": SIDE, "skin_m": SKIN, "ranks": []}
    try:
        for ranks in args.ranks:
            work = tempfile.mkdtemp(prefix="sabo-peer-liggghts-")
            try:
                run_liggghts(args.liggghts, args.mpirun, ranks, work, "settle.in", deck(SETTLE))
                theirs, ours = [], []
                for round_ in range(1, args.runs + 1):
                    seconds, steps, atoms, contacts = read_loop(
                        run_liggghts(args.liggghts, args.mpirun, ranks, work, "timed.in", deck(TIMED)))
                    theirs.append(atoms * steps / seconds)
                    print("{} rank(s), round {}: LIGGGHTS {} spheres, {} steps in {:.3f} s: {:.3g} sphere-steps/s, "
                          "{} contacts per sphere".format(ranks, round_, atoms, steps, seconds, theirs[-1],
                                                          "?" if contacts is None else "{:.2f}".format(contacts)),
                          flush=True)
                    s = run_sabo(sabo, ranks)
                    ours.append(s["rate"])
                    print("{} thread(s), round {}: Sabo bench_dem_box: {:.3g} sphere-steps/s, {:.2f} contacts per "
                          "sphere".format(ranks, round_, s["rate"], s["contacts"]), flush=True)
            finally:
                shutil.rmtree(work, ignore_errors=True)
            liggghts, sabo_rate = statistics.median(theirs), statistics.median(ours)
            print("{} rank(s) / thread(s), medians of {}: LIGGGHTS {:.3g}, Sabo {:.3g} sphere-steps/s: Sabo / "
                  "LIGGGHTS {:.2f}x\n".format(ranks, args.runs, liggghts, sabo_rate, sabo_rate / liggghts))
            summary["ranks"].append({"ranks": ranks, "liggghts_rate": liggghts, "sabo_rate": sabo_rate,
                                     "ratio": sabo_rate / liggghts})
    except PeerError as error:
        sys.exit("liggghts.py: {}".format(error))
    print(json.dumps(summary))


if __name__ == "__main__":
    main()
