#!/usr/bin/python3
"""A study measure: alpha = F / (rho v^2 h) of B1's surge at Fr = 1 (configs/tests/b1_surge_fr1.toml), the
wall's force plateau per unit width over the window bench/surge_wall.py uses (after the impact's transient,
before the echo of the block's tail), from RUN_DIR/forces.csv. Prints one number.

    b1_alpha.py RUN_DIR"""
import os
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.realpath(__file__)), "..", "..", "..", "bench"))
from surge_wall import Surge, measure  # noqa: E402

# The base scene's surge: its window and v, h do not depend on the particle spacing the study sweeps.
SURGE = Surge(1.0, spacings=4, free_slip=True, width=0.08)


def main():
    try:
        figures = measure(sys.argv[1], SURGE)
    except (OSError, RuntimeError, KeyError, ValueError) as error:
        print("b1_alpha.py: {}".format(error), file=sys.stderr)
        return 1
    print(repr(figures["alpha"]))
    return 0


if __name__ == "__main__":
    sys.exit(main())
