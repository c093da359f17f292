#!/usr/bin/env python3
"""The sph_solver's model on several MPI ranks (docs/architecture.md, "The slurry on several processes"):
bench_sph_throughput's dam break alone and under `mpirun -n R` for each R asked for, in interleaved rounds.
Prints each run, then per rank count the median particle-steps/s, the speed-up against one rank, the halo (the
particles a step reads from other ranks) and the largest rank's share of the particles, and the digest of the
state after the timed steps (XXH3 of every particle's position, velocity and density). The digests must be
one: the same bits on every rank count, alone included (exit status 1 when they are not). Every rank runs one
thread; rank counts above the cores run oversubscribed (their rates then say nothing; their digests do).
Python 3.8+, standard library only; it builds nothing ($SABO_BUILD_DIR picks the build folder).

    bench/sph_ranks.py                                  # alone, 1, 2 and 4 ranks, 0.02 m spacing, 20 steps
    bench/sph_ranks.py --ranks 1 2 --spacing 0.009 --rounds 3 --steps 10    # strong scaling at 170 368 particles
    bench/sph_ranks.py --ratio 1.5 --rheology bingham
"""
import argparse
import json
import os
import statistics
import subprocess
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.realpath(__file__)))
# mpirun as root needs these; a rank waiting in a collective gives its core away.
MPI_ENV = {"OMPI_ALLOW_RUN_AS_ROOT": "1", "OMPI_ALLOW_RUN_AS_ROOT_CONFIRM": "1", "OMPI_MCA_mpi_yield_when_idle": "1",
           "OMP_NUM_THREADS": "1", "OMP_WAIT_POLICY": "passive"}


def run(command):
    env = dict(os.environ, **MPI_ENV)
    done = subprocess.run(command, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, check=False)
    lines = [line for line in done.stdout.splitlines() if line.startswith("{")]
    if done.returncode != 0 or not lines:
        raise RuntimeError("{} failed ({}):\n{}".format(" ".join(command), done.returncode, done.stdout))
    return json.loads(lines[-1])


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--ranks", type=int, nargs="+", default=[1, 2, 4], help="rank counts under mpirun")
    parser.add_argument("--no-alone", dest="alone", action="store_false",
                        help="leave out the run without mpirun (the model with no ranks)")
    parser.add_argument("--spacing", type=float, default=0.02, help="particle spacing, m (0.009: 170 368 particles)")
    parser.add_argument("--steps", type=int, default=20, help="timed steps")
    parser.add_argument("--ratio", type=float, default=1.5, help="h / dx")
    parser.add_argument("--rheology", default="inviscid", choices=["inviscid", "newtonian", "bingham"])
    parser.add_argument("--rounds", type=int, default=1, help="interleaved rounds of every rank count")
    args = parser.parse_args()
    build = os.path.abspath(os.environ.get("SABO_BUILD_DIR") or os.path.join(ROOT, "build"))
    program = os.path.join(build, "bin", "bench_sph_throughput")
    if not os.path.exists(program):
        sys.exit("{} is missing: run ./sabo setup first".format(program))
    bench = [program, "--spacing", str(args.spacing), "--steps", str(args.steps), "--ratio", str(args.ratio),
             "--rheology", args.rheology]
    cores = os.cpu_count() or 1
    labels = (["alone"] if args.alone else []) + ["{} rank{}".format(r, "s" if r > 1 else "") for r in args.ranks]
    commands = ([bench] if args.alone else []) + [
        ["mpirun", "-n", str(r)] + (["--bind-to", "core"] if r <= cores else ["--oversubscribe"]) + bench
        for r in args.ranks]
    results = {label: [] for label in labels}
    for round_index in range(args.rounds):
        for label, command in zip(labels, commands):
            figures = run(command)
            results[label].append(figures)
            print("round {} {}: {:.4g} particle-steps/s, halo {:.0f} a step, digest {}".format(
                round_index + 1, label, figures["particle_steps_per_second"], figures["halo_per_step"],
                figures["state_digest"]), file=sys.stderr)
    particles = results[labels[0]][0]["particles"]
    one = next((label for label in labels if label == "1 rank"), labels[0])
    base = statistics.median(f["particle_steps_per_second"] for f in results[one])
    print("{} particles, {} walls, h/dx {}, {}, {} timed steps, {} round(s), {} cores".format(
        particles, results[labels[0]][0]["walls"], args.ratio, args.rheology, args.steps, args.rounds, cores))
    print("| run | particle-steps/s (median) | against {} | halo a step (share of N) | largest rank / (N / R) | "
          "state digest |".format(one))
    print("|---|---|---|---|---|---|")
    for label in labels:
        runs = results[label]
        rate = statistics.median(f["particle_steps_per_second"] for f in runs)
        ranks = runs[0]["ranks"]
        halo = runs[0]["halo_per_step"]
        digests = sorted({f["state_digest"] for f in runs})
        oversubscribed = label != "alone" and ranks > cores
        print("| {} | {:.4g}{} | {:.2f}x | {:.0f} ({:.1%}) | {:.2f} | {} |".format(
            label, rate, " (oversubscribed)" if oversubscribed else "", rate / base, halo, halo / particles,
            runs[0]["largest_rank_particles"] * ranks / particles, ", ".join(digests)))
    digests = {f["state_digest"] for runs in results.values() for f in runs}
    if len(digests) != 1:
        print("the states differ between rank counts: {}".format(", ".join(sorted(digests))))
        return 1
    print("the same bits on every rank count: one digest, {}".format(digests.pop()))
    return 0


if __name__ == "__main__":
    sys.exit(main())
