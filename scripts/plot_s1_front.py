#!/usr/bin/python3
"""Draws the S1 dam-break surge front (Z = z/a against T = t sqrt(2g/a)) against
Martin & Moyce 1952 (n^2 = 2) as a PNG.

    SABO_S1_FRONT_CSV=/tmp/s1.csv SABO_S1_PENALTY_FRONT_CSV=/tmp/s1_penalty.csv \
        build/bin/test_sph_model --gtest_filter='*S1*'
    scripts/plot_s1_front.py /tmp/s1.csv /tmp/s1_penalty.csv s1_front.png \
        --label "boundary particles" --label "penalty walls" [--shift S]

The CSV has a header T,Z; several CSVs may be given (one line each) with the
PNG path last.
"""
import argparse
import csv

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

T_REF = [0.41, 0.84, 1.19, 1.43, 1.63, 1.83, 1.98, 2.20, 2.32, 2.51, 2.65, 2.83, 2.98, 3.11, 3.33]
Z_REF = [1.11, 1.22, 1.44, 1.67, 1.89, 2.11, 2.33, 2.56, 2.78, 3.00, 3.22, 3.44, 3.67, 3.89, 4.11]


def read(path):
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    return [float(r["T"]) for r in rows], [float(r["Z"]) for r in rows]


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("files", nargs="+", help="front CSV files, then the output PNG")
    parser.add_argument("--shift", type=float, default=0.0, help="time shift added to the simulated T (gate lag)")
    parser.add_argument("--label", action="append", default=[], help="legend label per CSV")
    args = parser.parse_args()
    *inputs, output = args.files
    if not inputs or not output.endswith(".png"):
        parser.error("give at least one CSV and the output .png last")
    fig, ax = plt.subplots(figsize=(6, 4.5))
    ax.plot(T_REF, Z_REF, "ko", label="Martin & Moyce 1952 (n² = 2)")
    for k, path in enumerate(inputs):
        t, z = read(path)
        label = args.label[k] if k < len(args.label) else path
        ax.plot([v + args.shift for v in t], z, "-", label=label)
    ax.set_xlabel("T = t sqrt(2g/a)")
    ax.set_ylabel("Z = z/a")
    ax.set_xlim(0, 3.6)
    ax.set_ylim(1, 4.5)
    ax.grid(True, alpha=0.3)
    ax.legend()
    fig.tight_layout()
    fig.savefig(output, dpi=120)
    print(f"wrote {output}")


if __name__ == "__main__":
    main()
