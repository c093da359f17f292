#!/usr/bin/python3
"""A study measure: the cantilever's tip under its suddenly applied weight (configs/tests/
cantilever_self_weight.toml), from the beam's own series RUN_DIR/fem_beam.pvd (the mean vertical displacement
of the nodes at its free end in every frame). Prints one number:

    cantilever_tip.py --static RUN_DIR       the static deflection, m: midway between the extremes of the swing
    cantilever_tip.py --frequency RUN_DIR    the frequency of the swing, Hz: from its upward crossings of that
                                             middle, first to last"""
import argparse
import os
import sys
import xml.etree.ElementTree as ET

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "..", "bench"))
from taylor_bar import read_vtu  # noqa: E402  (Sabo's .vtu reader)


def tip_history(run_dir, part="beam"):
    root = ET.parse(os.path.join(run_dir, "fem_{}.pvd".format(part))).getroot()
    frames = sorted((float(e.get("timestep")), e.get("file")) for e in root.iter("DataSet"))
    times, deflection = [], []
    for time, name in frames:
        arrays = read_vtu(os.path.join(run_dir, name))
        reference = [p[0] - u[0] for p, u in zip(arrays["Points"], arrays["displacement"])]
        end = max(reference)
        tip = [u[2] for x, u in zip(reference, arrays["displacement"]) if x > end - 1e-9]
        times.append(time)
        deflection.append(-sum(tip) / len(tip))
    return times, deflection


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    which = parser.add_mutually_exclusive_group(required=True)
    which.add_argument("--static", action="store_true")
    which.add_argument("--frequency", action="store_true")
    parser.add_argument("run_dir")
    args = parser.parse_args()
    times, deflection = tip_history(args.run_dir)
    middle = 0.5 * (min(deflection) + max(deflection))
    if args.static:
        print(middle)
        return 0
    crossings = [times[k - 1] + (middle - deflection[k - 1]) / (deflection[k] - deflection[k - 1]) *
                 (times[k] - times[k - 1]) for k in range(1, len(times)) if deflection[k - 1] < middle <= deflection[k]]
    if len(crossings) < 2:
        print("cantilever_tip.py: {} upward crossings of the middle in {}: the run is shorter than a period".format(
            len(crossings), args.run_dir), file=sys.stderr)
        return 1
    print((len(crossings) - 1) / (crossings[-1] - crossings[0]))
    return 0


if __name__ == "__main__":
    sys.exit(main())
