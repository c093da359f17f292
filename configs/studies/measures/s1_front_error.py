#!/usr/bin/python3
"""A study measure for S1 (configs/sph_dam_break.toml): the RMS relative error of the dam-break front
against Martin & Moyce 1952 (docs/benchmarks.md, S1), Z = z / a against T = t sqrt(2 g / a), over
0.84 <= T <= 3.33, with the best time shift within +-0.3 in T (the experiment's gate lag, as the benchmark
allows). The front is the largest x of the active particles of each frame of RUN_DIR/sph.pvd. Prints the
RMS relative error (a fraction: 0.05 is 5 %).

    s1_front_error.py RUN_DIR [--width A] [--gravity G]"""
import argparse
import math
import os
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.realpath(__file__)), "..", "..", "..", "scripts"))
from render_snapshot import read_vtk, series  # noqa: E402

T_REF = [0.41, 0.84, 1.19, 1.43, 1.63, 1.83, 1.98, 2.20, 2.32, 2.51, 2.65, 2.83, 2.98, 3.11, 3.33]
Z_REF = [1.11, 1.22, 1.44, 1.67, 1.89, 2.11, 2.33, 2.56, 2.78, 3.00, 3.22, 3.44, 3.67, 3.89, 4.11]


def interpolate(xs, ys, x):
    for k in range(1, len(xs)):
        if xs[k] >= x:
            w = (x - xs[k - 1]) / (xs[k] - xs[k - 1])
            return ys[k - 1] + w * (ys[k] - ys[k - 1])
    return None


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run_dir")
    parser.add_argument("--width", type=float, default=0.1, help="the column's width a, m")
    parser.add_argument("--gravity", type=float, default=9.81, help="m/s^2")
    args = parser.parse_args()
    scale = math.sqrt(2 * args.gravity / args.width)
    front_t, front_z = [], []
    for time, path in series(os.path.join(args.run_dir, "sph.pvd")):
        arrays = read_vtk(path)
        points = arrays["Points"]
        active = arrays.get("active")
        xs = points[:, 0] if active is None else points[active == 1, 0]
        front_t.append(time * scale)
        front_z.append(float(xs.max()) / args.width)
    best = None
    for shift in [k * 0.01 for k in range(-30, 31)]:
        errors = []
        for t, z in zip(T_REF, Z_REF):
            if t < 0.84:
                continue
            measured = interpolate(front_t, front_z, t - shift)
            if measured is None:
                break
            errors.append(((measured - z) / z) ** 2)
        else:
            rms = math.sqrt(sum(errors) / len(errors))
            if best is None or rms < best:
                best = rms
    if best is None:
        print("s1_front_error.py: the run does not reach T = 3.33 (its frames end too soon)", file=sys.stderr)
        return 1
    print(best)
    return 0


if __name__ == "__main__":
    sys.exit(main())
