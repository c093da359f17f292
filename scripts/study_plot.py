#!/usr/bin/python3
"""The figures of a study folder (`./sabo study` writes study.json there and calls this script):

    pareto.png               error against wall time (log-log), one marker series per measure, each point
                             labelled with its parameters, the Pareto front of each measure drawn as a step line;
    convergence_<key>.png    for each swept number with three values or more: error against the value
                             (log-log), the other keys at their finest, with the least-squares line and the
                             fitted order in the legend.

    scripts/study_plot.py STUDY_DIR

Needs Debian's python3-numpy and python3-matplotlib (Agg backend). Exit status: 0 figures written, 2 bad input,
3 matplotlib missing."""
import json
import math
import os
import re
import sys

try:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
except ImportError:
    print("study_plot: matplotlib cannot be imported: sudo apt-get install python3-matplotlib", file=sys.stderr)
    sys.exit(3)


def label(run, keys):
    return ", ".join("{}={:g}".format(k.rsplit(".", 1)[-1], run["parameters"][k])
                     if isinstance(run["parameters"][k], (int, float)) and not isinstance(run["parameters"][k], bool)
                     else "{}={}".format(k.rsplit(".", 1)[-1], run["parameters"][k]) for k in keys)


def main():
    if len(sys.argv) != 2:
        print("usage: study_plot.py STUDY_DIR", file=sys.stderr)
        return 2
    folder = sys.argv[1]
    try:
        with open(os.path.join(folder, "study.json"), encoding="utf-8") as handle:
            study = json.load(handle)
    except (OSError, ValueError) as error:
        print("study_plot: {}: no readable study.json ({})".format(folder, error), file=sys.stderr)
        return 2
    keys = study["parameters"]
    runs = [r for r in study["runs"] if str(r["status"]).startswith("completed")]
    # The keys that take one value only are settings of the study, not what tells the runs apart.
    swept = [k for k in keys if len({json.dumps(r["parameters"][k]) for r in study["runs"]}) > 1] or keys
    written = []

    figure, axes = plt.subplots(figsize=(8, 6))
    markers = "osD^v<>"
    plotted = False
    for index, measure in enumerate(study["measures"]):
        name = measure["name"]
        points = [(r["wall_s"], r["errors"].get(name), r) for r in runs
                  if r.get("wall_s") and r["errors"].get(name) not in (None, 0)]
        if not points:
            continue
        plotted = True
        xs, ys = [p[0] for p in points], [p[1] * 100 for p in points]
        axes.scatter(xs, ys, marker=markers[index % len(markers)], label=name, zorder=3)
        for x, y, (_, _, run) in zip(xs, ys, points):
            axes.annotate(label(run, swept), (x, y), textcoords="offset points", xytext=(4, 4), fontsize=7)
        # The front as ./sabo study found it (study.json "pareto": the run names, by wall time).
        on_front = study.get("pareto", {}).get(name, [])
        front = sorted((k for k, (_, _, run) in enumerate(points) if run["run"] in on_front), key=lambda k: xs[k])
        fx, fy = [xs[k] for k in front], [ys[k] for k in front]
        axes.step(fx, fy, where="post", linewidth=1, alpha=0.7, label="{}: Pareto front".format(name))
    if plotted:
        axes.set_xscale("log")
        axes.set_yscale("log")
        axes.set_xlabel("wall time of the run (s)")
        axes.set_ylabel("error against the reference (%)")
        axes.set_title("Study {}: error against wall time".format(study["name"]))
        axes.grid(True, which="both", alpha=0.3)
        axes.legend(fontsize=8)
        figure.tight_layout()
        figure.savefig(os.path.join(folder, "pareto.png"), dpi=120)
        written.append("pareto.png")
    plt.close(figure)

    orders = {(o["parameter"], o["measure"]): o["order"] for o in study.get("orders", [])}
    finest = {k: None for k in keys}
    for r in study["runs"]:
        if r.get("finest"):
            finest = r["parameters"]
    for key in swept:
        others = {k: v for k, v in finest.items() if k != key}
        line = [r for r in runs if all(r["parameters"][k] == v for k, v in others.items())]
        values = [r["parameters"][key] for r in line]
        if len(line) < 2 or not all(isinstance(v, (int, float)) and v > 0 for v in values):
            continue
        figure, axes = plt.subplots(figsize=(7, 5))
        drawn = False
        for index, measure in enumerate(study["measures"]):
            name = measure["name"]
            # The finest run is left out where it is the reference (its error is 0 by definition).
            pairs = sorted((r["parameters"][key], r["errors"].get(name)) for r in line
                           if r["errors"].get(name) not in (None, 0)
                           and not (r.get("finest") and measure.get("reference_is_finest")))
            if len(pairs) < 2:
                continue
            drawn = True
            xs, ys = [p[0] for p in pairs], [p[1] * 100 for p in pairs]
            order = orders.get((key, name))
            axes.plot(xs, ys, markers[index % len(markers)] + "-", label="{} (order {})".format(
                name, "{:.2f}".format(order) if order is not None else "n/a"))
            if order is not None:
                # The fitted line through the geometric mean of the points.
                mx = sum(math.log(x) for x in xs) / len(xs)
                my = sum(math.log(y) for y in ys) / len(ys)
                fx = [min(xs), max(xs)]
                axes.plot(fx, [math.exp(my + order * (math.log(x) - mx)) for x in fx], ":", color="grey")
        if drawn:
            axes.set_xscale("log")
            axes.set_yscale("log")
            axes.set_xlabel(key)
            axes.set_ylabel("error against the reference (%)")
            axes.set_title("Convergence in {} (other keys at their finest)".format(key))
            axes.grid(True, which="both", alpha=0.3)
            axes.legend(fontsize=8)
            figure.tight_layout()
            name = "convergence_{}.png".format(re.sub(r"[^A-Za-z0-9]+", "_", key).strip("_"))
            figure.savefig(os.path.join(folder, name), dpi=120)
            written.append(name)
        plt.close(figure)
    print("study_plot: wrote {}: {}".format(folder, ", ".join(written) if written else "nothing (no errors to plot)"))
    return 0


if __name__ == "__main__":
    sys.exit(main())
