#!/usr/bin/env python3
"""What writing checkpoints costs (issue 19, part 2; goal: at most 2 % of the wall time at the default
interval). Each scene is run once through ./sabo run --no-setup with its own checkpoint settings (the default:
a checkpoint every end_time / 10); every process reports the wall time it spent writing its checkpoints
(summary.json: processes.NAME.checkpoint_seconds; the coupler's includes flushing traffic.h5 first). The
processes write theirs at the same step, side by side, so the run's cost is about the largest of them.

    bench/checkpoint_cost.py                                   # the three product scenes
    bench/checkpoint_cost.py configs/tests/sph_boulders_tank.toml

Prints a markdown table: steps, wall time, checkpoints written, seconds per process, the largest share of
the wall time. Standard library only; runs the built binaries of build/ (or $SABO_BUILD_DIR).
"""
import json
import os
import subprocess
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.realpath(__file__)))
DEFAULT_SCENES = ["configs/boulders_chute.toml", "configs/sph_dam_break.toml", "configs/debris_flow_dam.toml"]


def measure(scene):
    with tempfile.TemporaryDirectory(prefix="sabo-checkpoint-cost-") as work:
        out = os.path.join(work, "run")
        env = dict(os.environ, SABO_PLAN_OVERRIDE="", SABO_WATCHDOG_MIN_S="")
        result = subprocess.run([os.path.join(ROOT, "sabo"), "run", scene, "--out", out, "--no-setup", "--quiet"],
                                env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, universal_newlines=True)
        if result.returncode != 0:
            sys.exit("{} failed (exit {}):\n{}".format(scene, result.returncode, result.stdout[-2000:]))
        with open(os.path.join(out, "summary.json"), encoding="utf-8") as handle:
            return json.load(handle)


def main():
    scenes = sys.argv[1:] or DEFAULT_SCENES
    print("| scene | steps | wall s | checkpoints | checkpoint s per process | largest share of the wall time |")
    print("|---|---|---|---|---|---|")
    for scene in scenes:
        summary = measure(os.path.join(ROOT, scene) if not os.path.isabs(scene) else scene)
        wall = summary["wall_seconds"]
        seconds = {name: p.get("checkpoint_seconds", 0.0) for name, p in summary["processes"].items()}
        print("| {} | {} | {:.1f} | {} | {} | {:.2%} |".format(
            os.path.basename(scene), summary["steps"], wall, summary["checkpoints"]["written"],
            ", ".join("{} {:.3f}".format(name, s) for name, s in seconds.items()),
            max(seconds.values()) / wall if wall > 0 else 0.0), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
