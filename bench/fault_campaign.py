#!/usr/bin/env python3
"""Fault campaign of the restarts (issue 19, part 5): a scene is run once undisturbed, then once per trial
with one process killed by SIGKILL at a seeded random step. Each trial must complete and write output files
byte for byte those of the undisturbed run: a killed solver is restarted from its newest checkpoint and the
coupler catches it up from its journal, checking every replayed state; a killed coupler makes the supervisor
resume every process from their newest common checkpoint (docs/restart.md).

    bench/fault_campaign.py                                  # boulders_chute, 10 kills per solver
    bench/fault_campaign.py --scene configs/sph_dam_break.toml --roles sph_solver --trials 10
    bench/fault_campaign.py --trials 2 --no-recording --json /tmp/faults.json

Per role it prints: trials completed, trials identical, catch-up steps and seconds (the coupler's figures;
for the coupler itself: the steps every process computes again, from the common checkpoint to the kill),
the restart's wall time (kill to the replacement's registration, or to the resumed coupler's first
step), and how much longer the other processes waited than in the undisturbed run (summary.json's
wait_seconds). Standard library only; runs the built
binaries of build/ (or $SABO_BUILD_DIR) through ./sabo run --no-setup.
"""
import argparse
import filecmp
import json
import os
import random
import signal
import statistics
import subprocess
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.realpath(__file__)))
OUTPUTS = ["forces.csv", "energy.csv", "dem.pvd", "sph.pvd", "fem.pvd", "fem_energy.csv"]
FRAME_FOLDERS = ["dem", "sph", "fem"]


def read_json(path):
    with open(path, encoding="utf-8") as handle:
        return json.load(handle)


def events(run_dir):
    try:
        with open(os.path.join(run_dir, "coupler.events.jsonl"), encoding="utf-8") as handle:
            lines = handle.read().split("\n")[:-1]
    except OSError:
        return []
    out = []
    for line in lines:
        try:
            out.append(json.loads(line))
        except ValueError:
            pass
    return out


def start(scene, out):
    env = dict(os.environ, SABO_PLAN_OVERRIDE="", SABO_WATCHDOG_MIN_S="")
    return subprocess.Popen([os.path.join(ROOT, "sabo"), "run", scene, "--out", out, "--no-setup"], env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, universal_newlines=True)


def differing_outputs(reference, run):
    """Names of the output files of `run` that are not byte for byte those of `reference`."""
    bad = []
    for name in OUTPUTS:
        a, b = os.path.join(reference, name), os.path.join(run, name)
        if os.path.exists(a) != os.path.exists(b) or (os.path.exists(a) and not filecmp.cmp(a, b, shallow=False)):
            bad.append(name)
    for folder in FRAME_FOLDERS:
        a, b = os.path.join(reference, folder), os.path.join(run, folder)
        if not os.path.isdir(a) and not os.path.isdir(b):
            continue
        names = sorted(os.listdir(a)) if os.path.isdir(a) else []
        if not os.path.isdir(b) or names != sorted(os.listdir(b)):
            bad.append(folder + "/")
            continue
        _, mismatch, errors = filecmp.cmpfiles(a, b, names, shallow=False)
        bad += [folder + "/" + n for n in mismatch + errors]
    return bad


def waits(summary):
    """Seconds each process waited for the others (summary.json: processes.NAME.wait_seconds)."""
    return {name: p.get("wait_seconds", 0.0) for name, p in summary.get("processes", {}).items()}


def trial(scene, out, role, at_step, timeout):
    """One run with `role` killed once the coupler has reported step `at_step`."""
    sabo = start(scene, out)
    events_file = os.path.join(out, "coupler.events.jsonl")
    killed_at = None
    killed_step = None
    registered_at = None
    rejoined = "resumed" if role == "coupler" else "restarted"
    deadline = time.monotonic() + timeout
    while sabo.poll() is None and time.monotonic() < deadline:
        if killed_at is None:
            steps = [e.get("step", 0) for e in events(out) if e.get("event") == "progress"]
            if steps and steps[-1] >= at_step:
                try:
                    os.kill(read_json(os.path.join(out, "pids.json"))[role], signal.SIGKILL)
                    killed_at = time.monotonic()
                    killed_step = steps[-1]
                except (OSError, ValueError, KeyError):
                    pass
        elif registered_at is None and any(e.get("event") == rejoined for e in events(out)):
            registered_at = time.monotonic()
        time.sleep(0.01 if os.path.exists(events_file) else 0.05)
    if sabo.poll() is None:
        sabo.send_signal(signal.SIGINT)
    output = sabo.communicate(timeout=60)[0]
    return {"exit": sabo.returncode, "killed": killed_at is not None, "killed_step": killed_step, "output": output,
            "restart_wall_s": (registered_at - killed_at) if killed_at and registered_at else None}


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--scene", default="configs/boulders_chute.toml")
    parser.add_argument("--roles", default="dem_solver,fem_solver,coupler",
                        help="comma-separated processes to kill (solvers of the scene, coupler)")
    parser.add_argument("--trials", type=int, default=10, help="kills per process")
    parser.add_argument("--seed", type=int, default=19)
    parser.add_argument("--timeout", type=float, default=900, help="s per run")
    parser.add_argument("--no-recording", action="store_true",
                        help="run a copy of the scene with [recording] enabled = false (the restart needs no "
                             "traffic.h5: the coupler's journal feeds the catch-up)")
    parser.add_argument("--keep", help="folder to keep the runs in (default: a temporary one, removed)")
    parser.add_argument("--json", help="write the figures here")
    args = parser.parse_args()

    scene = os.path.abspath(os.path.join(ROOT, args.scene) if not os.path.isabs(args.scene) else args.scene)
    work = args.keep or tempfile.mkdtemp(prefix="sabo-faults-")
    os.makedirs(work, exist_ok=True)
    if args.no_recording:
        with open(scene, encoding="utf-8") as handle:
            text = handle.read()
        text = text.replace("[recording]", "[recording]\nenabled = false", 1) if "[recording]" in text else (
            text + "\n[recording]\nenabled = false\n")
        scene = os.path.join(work, "scene.toml")
        with open(scene, "w", encoding="utf-8") as handle:
            handle.write(text)
    reference = os.path.join(work, "reference")
    began = time.monotonic()
    sabo = start(scene, reference)
    output = sabo.communicate(timeout=args.timeout)[0]
    if sabo.returncode != 0:
        sys.exit("the undisturbed run failed (exit {}):\n{}".format(sabo.returncode, output[-2000:]))
    reference_seconds = time.monotonic() - began
    summary = read_json(os.path.join(reference, "summary.json"))
    steps = summary["steps"]
    reference_waits = waits(summary)
    print("{}: {} steps, {:.1f} s undisturbed".format(args.scene, steps, reference_seconds), flush=True)

    randomness = random.Random(args.seed)
    figures = {"scene": args.scene, "steps": steps, "reference_seconds": reference_seconds, "roles": {}}
    for role in args.roles.split(","):
        rows = []
        for k in range(args.trials):
            at_step = randomness.randrange(steps // 10, steps - steps // 10)
            out = os.path.join(work, "{}-{}".format(role, k))
            result = trial(scene, out, role, at_step, args.timeout)
            row = {"at_step": at_step, "exit": result["exit"], "restart_wall_s": result["restart_wall_s"]}
            try:
                s = read_json(os.path.join(out, "summary.json"))
                row["status"] = s.get("status")
                row["restarts"] = s.get("restarts", [])
                if role == "coupler":
                    row["restarts"] = [{"process": "coupler", "from_step": r["from_step"],
                                        "catch_up_steps": result["killed_step"] - r["from_step"]}
                                       for r in s.get("resumes", []) if result["killed_step"] is not None]
                trial_waits = waits(s)
                row["others_extra_wait_s"] = {p: trial_waits[p] - reference_waits.get(p, 0.0)
                                              for p in trial_waits if p != role}
            except (OSError, ValueError):
                row["status"] = "no summary"
                row["restarts"] = []
            row["completed"] = result["exit"] == 0 and row["status"] == "completed"
            row["differs"] = differing_outputs(reference, out) if row["completed"] else ["(not completed)"]
            row["identical"] = not row["differs"]
            if not row["completed"]:
                row["output_tail"] = result["output"][-1500:]
            rows.append(row)
            restart = row["restarts"][0] if row["restarts"] else {}
            print("{} killed at step {}: {}, {}, catch-up {} steps in {} s, restart {} s".format(
                role, at_step, "completed" if row["completed"] else "FAILED (exit {})".format(result["exit"]),
                "identical" if row["identical"] else "differs: " + ", ".join(row["differs"][:4]),
                restart.get("catch_up_steps", "-"),
                "{:.2f}".format(restart["catch_up_seconds"]) if "catch_up_seconds" in restart else "-",
                "{:.2f}".format(row["restart_wall_s"]) if row["restart_wall_s"] is not None else "-"), flush=True)
        figures["roles"][role] = rows

    print("\n| process | trials | completed | identical | catch-up steps (median, max) | catch-up s (median) "
          "| restart s (median) | others' extra wait s (median) |")
    print("|---|---|---|---|---|---|---|---|")
    for role, rows in figures["roles"].items():
        restarts = [r["restarts"][0] for r in rows if r["restarts"]]
        catch_steps = [x["catch_up_steps"] for x in restarts]
        catch_s = [x["catch_up_seconds"] for x in restarts if "catch_up_seconds" in x]
        restart_s = [r["restart_wall_s"] for r in rows if r["restart_wall_s"] is not None]
        extra = [max(r["others_extra_wait_s"].values()) for r in rows if r.get("others_extra_wait_s")]

        def med(values, fmt="{:.2f}"):
            return fmt.format(statistics.median(values)) if values else "-"
        print("| {} | {} | {} | {} | {}, {} | {} | {} | {} |".format(
            role, len(rows), sum(r["completed"] for r in rows), sum(r["identical"] for r in rows),
            med(catch_steps, "{:.0f}"), max(catch_steps) if catch_steps else "-", med(catch_s), med(restart_s),
            med(extra)))
    if args.json:
        with open(args.json, "w", encoding="utf-8") as handle:
            json.dump(figures, handle, indent=1)
    if not args.keep:
        subprocess.run(["rm", "-rf", work], check=False)
    failed = sum(not r["identical"] for rows in figures["roles"].values() for r in rows)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
