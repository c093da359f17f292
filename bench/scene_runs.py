"""Runs a scene written by a benchmark script through `./sabo run` (the built binaries, no set-up, no
plots): the run folder, its wall time and summary.json. Standard library only."""
import json
import os
import subprocess
import time

ROOT = os.path.dirname(os.path.dirname(os.path.realpath(__file__)))


def run_scene(text, work, name):
    """Writes `text` to WORK/NAME.toml and runs it into WORK/NAME; raises RuntimeError with the output when the
    run fails. Returns (run folder, wall time in s, summary.json as a dict)."""
    scene = os.path.join(work, name + ".toml")
    with open(scene, "w", encoding="utf-8") as handle:
        handle.write(text)
    out = os.path.join(work, name)
    start = time.time()
    run = subprocess.run([os.path.join(ROOT, "sabo"), "run", scene, "--out", out, "--quiet", "--no-setup",
                          "--no-plots"], capture_output=True, text=True)
    wall = time.time() - start
    if run.returncode != 0:
        raise RuntimeError("{}: ./sabo run failed ({}):\n{}{}".format(name, run.returncode, run.stdout, run.stderr))
    with open(os.path.join(out, "summary.json"), encoding="utf-8") as handle:
        return out, wall, json.load(handle)
