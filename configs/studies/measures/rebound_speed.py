#!/usr/bin/python3
"""A study measure: the speed of DEM sphere 0 at the end of a run, m/s, from RUN_DIR/traffic.h5 (the last
state the dem_solver sent with the sphere in it). Prints one number.

    rebound_speed.py RUN_DIR"""
import os
import sys

import h5py
import numpy


def main():
    with h5py.File(os.path.join(sys.argv[1], "traffic.h5"), "r") as traffic:
        state = traffic["dem_solver/state"]
        index, offsets, counts = state["index"][()], state["index_offset"][()], state["index_count"][()]
        velocity, velocity_offsets = state["velocity"][()], state["velocity_offset"][()]
    for offset, count, at in zip(reversed(offsets), reversed(counts), reversed(velocity_offsets)):
        ids = list(index[offset:offset + count])
        if 0 in ids:
            k = ids.index(0)
            at = int(at) + 3 * k
            print(float(numpy.linalg.norm(velocity[at:at + 3])))
            return 0
    print("rebound_speed.py: sphere 0 is in no recorded state", file=sys.stderr)
    return 1


if __name__ == "__main__":
    sys.exit(main())
