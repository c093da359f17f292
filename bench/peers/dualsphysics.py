#!/usr/bin/env python3
"""Sabo's SPH beside DualSPHysics (CPU), runs interleaved on this machine (issue 26).

DualSPHysics is not part of the project: build it yourself (its README) and give this script the
executable and a case GenCase has already written (the dam break of its examples/main/01_DamBreak):

    bench/peers/dualsphysics.py --dualsphysics DSPH/bin/linux/DualSPHysics5.4CPU_linux64 \\
        --case OUT/CaseDambreak [--runs 5] [--steps 100] [--threads 2]

Each round runs DualSPHysics for --steps steps (`-cpu -ompthreads:T -sv:none -svres -nsteps:N`) and then
Sabo's `bench_sph_throughput` at the same neighbour count per fluid particle (cubic spline, h = 1.732 dx,
DualSPHysics' own ratio, at dx = 0.009 m: about 170 000 fluid particles and 167 neighbours each, against
DualSPHysics' 163 on its 128 310 fluid particles). What each side counts:

- DualSPHysics: its "Simulation Runtime" (the main loop, from Run.out) over the steps; particle-steps/s
  counted twice, fluid particles only and with its boundary particles (DBC boundary particles are computed
  like fluid ones, density included);
- Sabo: the fluid particle-steps/s `bench_sph_throughput` reports (its wall particles, which the fluid
  sees as boundary particles, are not counted).

Prints every run, the medians and both ratios (Sabo's fluid rate over DualSPHysics' fluid rate, and over
its rate with the boundary particles). Standard library only; Sabo's benchmark from build/bin (or
$SABO_BUILD_DIR/bin). Give --dualsphysics twice (e.g. the stock and the -march=native build) to measure
both in each round.
"""
import argparse
import json
import os
import re
import shutil
import statistics
import subprocess
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.realpath(__file__))))
SABO_ARGS = ["--kernel", "cubic_spline", "--ratio", "1.732", "--spacing", "0.009"]


class PeerError(Exception):
    """The peer could not be run or its output not read: the message says which and how to mend it."""


def read_counts(run_out):
    """Fluid and boundary particle counts from DualSPHysics' Run.out."""
    with open(run_out, encoding="utf-8", errors="replace") as handle:
        text = handle.read()
    match = re.search(r"Total particles:\s*([\d,]+)\s*\(bound=([\d,]+).*?fluid=([\d,]+)", text)
    if not match:
        raise PeerError("{}: no 'Total particles: N (bound=B ... fluid=F)' line; is it DualSPHysics 5.x's "
                        "Run.out?".format(run_out))
    return int(match.group(3).replace(",", "")), int(match.group(2).replace(",", "")), text


def read_runtime(text, run_out):
    """The main loop's seconds and the steps it took, from Run.out."""
    runtime = re.search(r"Simulation Runtime\.*:\s*([0-9.eE+-]+)", text)
    steps = re.search(r"Steps of simulation\.*:\s*(\d+)", text)
    if not runtime or not steps:
        raise PeerError("{}: no 'Simulation Runtime' and 'Steps of simulation' lines (the run did not "
                        "finish?)".format(run_out))
    return float(runtime.group(1)), int(steps.group(1))


def run_dualsphysics(executable, case, steps, threads):
    out = tempfile.mkdtemp(prefix="sabo-peer-dsph-")
    try:
        command = [executable, case, out, "-cpu", "-ompthreads:{}".format(threads), "-sv:none", "-svres",
                   "-nsteps:{}".format(steps), "-tout:1000"]
        env = dict(os.environ, OMP_NUM_THREADS=str(threads))
        env["LD_LIBRARY_PATH"] = os.pathsep.join(
            filter(None, [os.path.dirname(os.path.abspath(executable)), env.get("LD_LIBRARY_PATH", "")]))
        result = subprocess.run(command, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                                universal_newlines=True)
        run_out = os.path.join(out, "Run.out")
        if result.returncode != 0 or not os.path.exists(run_out):
            raise PeerError("{} failed (exit {}): {}".format(" ".join(command), result.returncode,
                                                             result.stdout[-1500:]))
        fluid, bound, text = read_counts(run_out)
        runtime, taken = read_runtime(text, run_out)
        return {"fluid": fluid, "boundary": bound, "seconds": runtime, "steps": taken,
                "fluid_rate": fluid * taken / runtime, "all_rate": (fluid + bound) * taken / runtime}
    finally:
        shutil.rmtree(out, ignore_errors=True)


def run_sabo(binary, steps, threads):
    env = dict(os.environ, OMP_NUM_THREADS=str(threads), OMP_WAIT_POLICY="passive")
    result = subprocess.run([binary] + SABO_ARGS + ["--steps", str(steps)], env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, universal_newlines=True)
    if result.returncode != 0:
        raise PeerError("{} failed (exit {}): {}".format(binary, result.returncode, result.stdout[-1500:]))
    line = result.stdout.strip().splitlines()[-1]
    data = json.loads(line)
    return {"fluid": data["particles"], "walls": data["walls"], "neighbours": data["neighbours_per_particle"],
            "fluid_rate": data["particle_steps_per_second"], "seconds": data["seconds"]}


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--dualsphysics", action="append", required=True,
                        help="DualSPHysics CPU executable (give it twice for two builds)")
    parser.add_argument("--case", required=True, help="the case GenCase wrote, without extension "
                                                      "(e.g. OUT/CaseDambreak for OUT/CaseDambreak.xml)")
    parser.add_argument("--runs", type=int, default=5, help="interleaved rounds")
    parser.add_argument("--steps", type=int, default=100, help="DualSPHysics steps per run")
    parser.add_argument("--sabo-steps", type=int, default=50, help="bench_sph_throughput's timed steps")
    parser.add_argument("--threads", type=int, default=2)
    args = parser.parse_args()
    build = os.environ.get("SABO_BUILD_DIR", os.path.join(ROOT, "build"))
    sabo = os.path.join(build, "bin", "bench_sph_throughput")
    for path in args.dualsphysics + [sabo]:
        if not os.access(path, os.X_OK):
            sys.exit("dualsphysics.py: {} is not an executable. Fix: build it (Sabo: ./sabo test, or cmake "
                     "--build build; DualSPHysics: make -f Makefile_cpu in its src/source) and give its "
                     "path".format(path))
    if not os.path.exists(args.case + ".xml") or not os.path.exists(args.case + ".bi4"):
        sys.exit("dualsphysics.py: --case {0}: {0}.xml and {0}.bi4 are needed. Fix: run GenCase on the case "
                 "definition first (GenCase CaseDambreak_Def {0} -save:all)".format(args.case))

    peers = {path: [] for path in args.dualsphysics}
    ours = []
    try:
        for round_ in range(1, args.runs + 1):
            for path in args.dualsphysics:
                r = run_dualsphysics(path, args.case, args.steps, args.threads)
                peers[path].append(r)
                print("round {} DualSPHysics {}: {} fluid + {} boundary particles, {} steps in {:.3f} s: "
                      "{:.3g} fluid particle-steps/s, {:.3g} with the boundary".format(
                          round_, path, r["fluid"], r["boundary"], r["steps"], r["seconds"],
                          r["fluid_rate"], r["all_rate"]), flush=True)
            s = run_sabo(sabo, args.sabo_steps, args.threads)
            ours.append(s)
            print("round {} Sabo bench_sph_throughput: {} fluid particles ({} wall particles not counted), "
                  "{:.1f} neighbours per fluid particle: {:.3g} fluid particle-steps/s".format(
                      round_, s["fluid"], s["walls"], s["neighbours"], s["fluid_rate"]), flush=True)
    except PeerError as error:
        sys.exit("dualsphysics.py: {}".format(error))

    sabo_rate = statistics.median(s["fluid_rate"] for s in ours)
    print("\nmedians over {} rounds, {} threads:".format(args.runs, args.threads))
    print("  Sabo: {:.3g} fluid particle-steps/s ({:.1f} neighbours per fluid particle)".format(
        sabo_rate, statistics.median(s["neighbours"] for s in ours)))
    summary = {"threads": args.threads, "runs": args.runs, "sabo_fluid_rate": sabo_rate, "peers": []}
    for path, runs in peers.items():
        fluid = statistics.median(r["fluid_rate"] for r in runs)
        everything = statistics.median(r["all_rate"] for r in runs)
        print("  DualSPHysics {}: {:.3g} fluid particle-steps/s, {:.3g} with its boundary particles".format(
            path, fluid, everything))
        print("    Sabo / DualSPHysics: {:.2f}x counting fluid particles, {:.2f}x counting its boundary "
              "particles too".format(sabo_rate / fluid, sabo_rate / everything))
        summary["peers"].append({"executable": path, "fluid_rate": fluid, "all_rate": everything,
                                 "ratio_fluid": sabo_rate / fluid, "ratio_all": sabo_rate / everything})
    print(json.dumps(summary))


if __name__ == "__main__":
    main()
