"""Stand-in for build/bin/sabo_scene in the supervisor tests.

`sabo_scene.py check SCENE --bin-dir DIR`. The "scene" is a JSON file that
describes how the fake processes behave (see coupler.py and solver.py). If it
has "errors", they are printed like scene errors and the exit status is 2.
Otherwise the launch plan is printed, with the fake coupler and solvers as
commands (or "commands": {role: [...]} from the scene).
"""
import json
import os
import sys

FAKES = os.path.dirname(os.path.abspath(__file__))


def main(argv):
    if len(argv) != 4 or argv[0] != "check" or argv[2] != "--bin-dir":
        print("usage: sabo_scene check SCENE --bin-dir DIR", file=sys.stderr)
        return 64
    scene_path = argv[1]
    with open(scene_path, encoding="utf-8") as handle:
        scene = json.load(handle)
    if scene.get("errors"):
        for error in scene["errors"]:
            print("{}: {}".format(scene_path, error), file=sys.stderr)
        return 2
    commands = scene.get("commands", {})
    coupler = [sys.executable, os.path.join(FAKES, "coupler.py")]
    processes = [{"role": "coupler", "command": commands.get("coupler", coupler)}]
    for role in scene.get("solvers", ["dem_solver", "fem_solver"]):
        default = [sys.executable, os.path.join(FAKES, "solver.py"), "--role", role]
        processes.append({"role": role, "command": commands.get(role, default)})
    plan = {"scene": os.path.abspath(scene_path), "end_time": scene.get("end_time", 1.0),
            "output_interval": 0.1, "hang_timeout": scene.get("hang_timeout", 1.0),
            "endpoint": scene.get("endpoint", "ipc"), "processes": processes}
    print(json.dumps(plan))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
