#!/usr/bin/python3
"""Figures of a Sabo run folder, as PNG files in RUN_DIR/plots/ (`./sabo plot RUN_DIR` runs this).

    scripts/sabo_plot.py RUN_DIR                 # RUN_DIR/plots/*.png
    scripts/sabo_plot.py RUN_A RUN_B [--out DIR]  # A solid, B dashed: RUN_A/plots/compare_<basename of B>/

One figure per concern, each only when its data are in the folder:

  forces.png      forces.csv: per structure part, the magnitude F of the mean force of each source (fluid,
                  particles, ...) and, with two sources or more, the magnitude of their vector sum
                  |sum of (Fx, Fy, Fz)|; dots: F_peak, the largest instantaneous magnitude within each output
                  interval; the largest F_peak of each source is marked, its value written above the curves.
  energy.png      energy.csv: every term (J) and, below, the residual of the balance
                  (total + dissipated) - (total + dissipated at the first row); `dissipated` is cumulative
                  (docs/protocol.md, `energies`), so the residual is what the coupled run gained (> 0) or
                  lost (< 0) beyond what it reports as dissipated.
  fem_energy.png  fem_energy.csv: the deformable FEM parts' energy accounts (summed over the parts) and, when
                  any element eroded, the number of eroded elements.
  gauges.png      gauges.csv: pressure per point gauge, free-surface depth per line gauge (distance from the
                  line's start to the free surface), velocity magnitude per point gauge.
  fronts.png      fronts.csv: each front's position along its path, its speed (the advance between two
                  samples over the time between them) and the mean flow speed just behind it.
  front_stations.png  front_stations.csv: the flow depth at each station of each front.
  sensors.png     sensors.csv: force magnitude F per sensor and source; the sensor's mean normal pressure
                  (the sum over its sources).
  inflows.png     inflows.csv: each inflow's discharge Q(t), the volume released through its section and the
                  hydrograph's integral less it.
  steps.png       coupler.events.jsonl: the time step and the step rate over simulated time. Every step's dt
                  is only in traffic.h5 (<role>/forces/dt, when the run records it; a large file, and h5py);
                  the coupler's progress events (about two a second of wall time) give the dt of the step
                  they report and steps_per_second, the steps since the coupler process started over its
                  wall time; from these, between two events, the mean dt (time difference / step difference)
                  and the step rate (step difference / wall time difference).

Exit status: 0 figures written; 2 bad input (not a run folder, none of the files above, a malformed file:
the message names the file, the line and what is wrong), with whatever could be drawn still written;
3 numpy or matplotlib cannot be imported (Debian: sudo apt-get install python3-matplotlib).
"""
import argparse
import csv
import json
import math
import os
import sys

EXIT_BAD_INPUT = 2
EXIT_NO_MATPLOTLIB = 3

try:
    import numpy as np
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.lines import Line2D
except ImportError as import_error:
    print("sabo_plot: cannot draw: {} ({}). Fix: sudo apt-get install python3-numpy python3-matplotlib".format(
        import_error, sys.executable), file=sys.stderr)
    sys.exit(EXIT_NO_MATPLOTLIB)

PLOTS_FOLDER = "plots"
EVENTS_FILE = "coupler.events.jsonl"
FIGURE_WIDTH_IN = 10.0
PANEL_HEIGHT_IN = 2.9
DPI = 120
LEGEND_CHARACTER_IN = 0.075  # width of a legend label's character at font size 9
LEGEND_HANDLE_IN = 0.8       # a legend entry's line and the gaps around it
RUN_LINESTYLES = ("-", "--")
SUM_COLOUR = "black"
ANNOTATION_HEIGHT = 0.1  # axes fraction of a peak's annotation line

# Columns each file must have (more are allowed); the text columns, all others numeric (empty fields: nan).
FORCES_COLUMNS = ("time", "part", "source", "Fx", "Fy", "Fz", "F", "F_peak")
ENERGY_COLUMNS = ("time", "kinetic", "potential", "solver_elastic", "contact_elastic", "total", "dissipated")
FEM_ENERGY_COLUMNS = ("time_s", "kinetic_J", "internal_J", "plastic_work_J", "hourglass_J", "eroded_J",
                      "external_work_J", "eroded_elements")
GAUGES_COLUMNS = ("time", "gauge", "point", "x", "y", "z", "kernel_sum", "pressure", "velocity_x", "velocity_y",
                  "velocity_z", "depth")
FRONTS_COLUMNS = ("time", "front", "position", "speed", "flow_speed", "x", "y", "z")
INFLOWS_COLUMNS = ("time", "body", "discharge", "hydrograph_volume", "released_volume", "buffer_speed")
FRONT_STATIONS_COLUMNS = ("time", "front", "station", "at", "depth")
SENSORS_COLUMNS = ("time", "sensor", "part", "source", "Fx", "Fy", "Fz", "F", "F_peak", "area", "pressure")
TEXT_COLUMNS = ("part", "source", "gauge", "sensor", "front", "station", "body")

SI_PREFIXES = ((1e9, "G"), (1e6, "M"), (1e3, "k"), (1.0, ""), (1e-3, "m"), (1e-6, "µ"))


class InputError(Exception):
    """Bad input: reported as one message, exit status 2."""


class Table:
    """The columns of a CSV file: numpy arrays, float or (TEXT_COLUMNS) str."""

    def __init__(self, columns, rows):
        self.columns = columns
        self.rows = rows

    def __getitem__(self, name):
        return self.columns[name]

    def has(self, name):
        return name in self.columns


def number_at(path, line, column, text):
    try:
        return float(text)
    except ValueError:
        raise InputError("{} line {}: column {} holds '{}', not a number".format(path, line, column, text))


def read_csv(path, required):
    """The Table of `path`, or InputError naming the file, the line and what is wrong. A last line without
    its newline that does not fit (a run killed while writing it) is left out."""
    try:
        with open(path, newline="", encoding="utf-8", errors="replace") as handle:
            text = handle.read()
    except OSError as error:
        raise InputError("{}: cannot read it: {}".format(path, error.strerror))
    lines = list(csv.reader(text.splitlines()))
    if not lines or not lines[0]:
        raise InputError("{}: empty, no header line (expected: {})".format(path, ",".join(required)))
    header = [name.strip() for name in lines[0]]
    missing = [name for name in required if name not in header]
    if missing:
        raise InputError("{}: no column {} (its header: {}; expected: {}): a file of an older format? Run the "
                         "scene again with this version of Sabo".format(path, ", ".join(missing), ",".join(header),
                                                                       ",".join(required)))
    body = lines[1:]
    if body and len(body[-1]) != len(header) and not text.endswith("\n"):
        body = body[:-1]
    for number, fields in enumerate(body, start=2):
        if len(fields) != len(header):
            raise InputError("{} line {}: {} fields, the header has {}".format(path, number, len(fields),
                                                                               len(header)))
    columns = {}
    for index, name in enumerate(header):
        if name in TEXT_COLUMNS:
            columns[name] = np.array([fields[index].strip() for fields in body], dtype=str)
            continue
        values = np.array([fields[index].strip() or "nan" for fields in body], dtype=str)
        try:
            columns[name] = values.astype(float)
        except ValueError:
            columns[name] = np.array([number_at(path, line, name, value) for line, value in enumerate(values, 2)])
    return Table(columns, len(body))


def read_progress(path):
    """Arrays (step, time, dt, steps_per_second) of the progress events of coupler.events.jsonl; lines that are
    not JSON objects (a partial last line) are left out. None when there is no progress event."""
    try:
        with open(path, encoding="utf-8", errors="replace") as handle:
            lines = handle.read().splitlines()
    except OSError as error:
        raise InputError("{}: cannot read it: {}".format(path, error.strerror))
    keys = ("step", "time", "dt", "steps_per_second")
    rows = []
    for line in lines:
        try:
            event = json.loads(line)
        except ValueError:
            continue
        if not isinstance(event, dict) or event.get("event") != "progress":
            continue
        row = [event.get(key) for key in keys]
        rows.append([value if isinstance(value, (int, float)) and not isinstance(value, bool) else math.nan
                     for value in row])
    if not rows:
        return None
    return dict(zip(keys, np.array(rows, dtype=float).T))


class Run:
    """A run folder: its label in legends (the folder's name), its scene's name, its summary.json."""

    def __init__(self, path):
        if not os.path.isdir(path):
            raise InputError("{}: not a folder (give a run folder, e.g. runs/<scene>-<date>-<time>)".format(path))
        self.path = os.path.normpath(path)
        self.label = os.path.basename(os.path.abspath(self.path))
        self.scene = self._scene_name()
        self.summary = self._summary()

    def _scene_name(self):
        try:
            with open(os.path.join(self.path, "run.json"), encoding="utf-8") as handle:
                scene = json.load(handle).get("scene")
            return os.path.splitext(os.path.basename(scene))[0]
        except (OSError, ValueError, AttributeError, TypeError):
            return self.label

    def _summary(self):
        try:
            with open(os.path.join(self.path, "summary.json"), encoding="utf-8") as handle:
                summary = json.load(handle)
            return summary if isinstance(summary, dict) else {}
        except (OSError, ValueError):
            return {}

    def file(self, name):
        return os.path.join(self.path, name)

    def has(self, name):
        return os.path.isfile(self.file(name))

    def title(self):
        return self.scene if self.scene == self.label else "{} (run {})".format(self.scene, self.label)


def si_scale(largest, unit):
    """(factor, 'kN'): the SI prefix that shows `largest` (in `unit`) with 1 to 3 digits before the point."""
    if not math.isfinite(largest) or largest <= 0:
        return 1.0, unit
    if "²" in unit or "³" in unit:  # a prefix would read as the length's: mm³ is not a milli-m³
        exponent = 3 * math.floor(math.log10(largest) / 3)
        return 10.0 ** exponent, unit if exponent == 0 else "1e{} {}".format(exponent, unit)
    for factor, prefix in SI_PREFIXES:
        if largest >= factor:
            return factor, prefix + unit
    return SI_PREFIXES[-1][0], SI_PREFIXES[-1][1] + unit


def largest_abs(arrays):
    values = [np.nanmax(np.abs(a)) for a in arrays if len(a) and np.isfinite(a).any()]
    return max(values) if values else 0.0


def format_value(value, unit):
    factor, scaled_unit = si_scale(abs(value), unit)
    return "{:.3g} {}".format(value / factor, scaled_unit)


def colour(index):
    return "C{}".format(index % 10)


def new_figure(rows, columns=1, height=None):
    """A figure of rows x columns panels sharing the time axis, with grid lines."""
    height = height or max(6.0, PANEL_HEIGHT_IN * rows + 1.2)
    fig, axes = plt.subplots(rows, columns, figsize=(FIGURE_WIDTH_IN, height), sharex=True, squeeze=False)
    for ax in axes.flat:
        ax.grid(True, alpha=0.35)
    return fig, axes


def finish(fig, title, entries, path, runs):
    """The title, one legend for the whole figure above the panels (never over data: series by colour, runs
    by line style when two runs are overlaid), then the PNG."""
    handles, labels = [handle for handle, _ in entries], [label for _, label in entries]
    if len(runs) > 1:
        for run, style in zip(runs, RUN_LINESTYLES):
            handles.append(Line2D([], [], color="dimgray", linestyle=style))
            labels.append("run " + run.path)
    widest_in = max((LEGEND_HANDLE_IN + LEGEND_CHARACTER_IN * len(label) for label in labels), default=1.0)
    columns = max(1, min(len(handles), 4, int(0.95 * FIGURE_WIDTH_IN / widest_in)))
    height, renderer = fig.get_figheight(), fig.canvas.get_renderer()
    above = fig.suptitle(title, y=1 - 0.08 / height, va="top", fontsize=12)
    above.set_in_layout(False)  # the panels go below the title and the legend: the layout's rectangle
    if handles:
        below_title = above.get_window_extent(renderer).y0 / fig.bbox.height - 0.05 / height
        above = fig.legend(handles, labels, loc="upper center", ncol=columns, frameon=False, fontsize=9,
                           bbox_to_anchor=(0.5, below_title))
        above.set_in_layout(False)
    lowest = above.get_window_extent(renderer).y0 / fig.bbox.height
    fig.tight_layout(rect=(0, 0, 1, lowest - 0.1 / height))
    fig.savefig(path, dpi=DPI)
    plt.close(fig)


def figure_title(runs, what):
    if len(runs) == 1:
        return "{}: {}".format(runs[0].title(), what)
    return "{}\n{} (solid) vs {} (dashed)".format(what, runs[0].title(), runs[1].title())


# ------------------------------------------------------------------------------------------- forces


def force_series(table, key, name):
    """Rows of `table` whose column `key` (part, sensor) is `name`: {source: (time, F, F_peak)}, and
    (time, |sum over the sources of (Fx, Fy, Fz)|)."""
    mine = table[key] == name
    times = np.unique(table["time"][mine])
    total = np.zeros((len(times), 3))
    series = {}
    for source in dict.fromkeys(table["source"][mine]):
        rows = mine & (table["source"] == source)
        time = table["time"][rows]
        series[source] = (time, table["F"][rows], table["F_peak"][rows])
        vector = np.column_stack([table[axis][rows] for axis in ("Fx", "Fy", "Fz")])
        np.add.at(total, np.searchsorted(times, time), np.nan_to_num(vector))
    return series, (times, np.linalg.norm(total, axis=1))


def force_panel(ax, tables, key, name, sources):
    """The force on one part or sensor: per source F and the F_peak dots, and with two sources or more the
    magnitude of their sum; the largest F_peak of each source marked, its value written in the headroom
    above the curves. True when a sum was drawn."""
    peaks = [table["F_peak"][table[key] == name] for table in tables]
    means = [table["F"][table[key] == name] for table in tables]
    factor, unit = si_scale(largest_abs(peaks + means), "N")
    largest, summed = [], False  # (time, F_peak, colour) of each source's largest F_peak
    for table, style in zip(tables, RUN_LINESTYLES):
        series, (times, total) = force_series(table, key, name)
        for source, (time, magnitude, peak) in series.items():
            tint = colour(sources.index(source))
            ax.plot(time, magnitude / factor, color=tint, linestyle=style, linewidth=1.4)
            ax.plot(time, peak / factor, color=tint, linestyle="none", marker=".", markersize=4, alpha=0.55)
            if np.isfinite(peak).any() and np.nanmax(peak) > 0:
                at = int(np.nanargmax(peak))
                largest.append((time[at], peak[at], tint))
                ax.plot(time[at], peak[at] / factor, color=tint, marker="v", markersize=8, markeredgecolor="black",
                        linestyle="none")
        if len(series) > 1:
            summed = True
            ax.plot(times, total / factor, color=SUM_COLOUR, linestyle=style, linewidth=1.8)
    ax.set_title(name, fontsize=10, loc="left")
    ax.set_ylabel("force [{}]".format(unit))
    ax.set_ylim(0, ax.get_ylim()[1] * (1.1 + ANNOTATION_HEIGHT * len(largest)))
    left, right = ax.get_xlim()
    for index, (time, peak, tint) in enumerate(largest):
        on_the_right = time > left + 0.6 * (right - left)
        ax.annotate("{} at {:.3g} s".format(format_value(peak, "N"), time), (time, peak / factor),
                    xytext=(time, 0.97 - ANNOTATION_HEIGHT * index), textcoords=("data", "axes fraction"),
                    ha="right" if on_the_right else "left", va="top", fontsize=8, color=tint,
                    arrowprops=dict(arrowstyle="-", color=tint, linewidth=0.7))
    return summed


def force_entries(sources, summed):
    entries = [(Line2D([], [], color=colour(sources.index(s))), "{}: F (mean over the output interval)".format(s))
               for s in sources]
    if summed:
        entries.append((Line2D([], [], color=SUM_COLOUR, linewidth=1.8), "sum of the sources |ΣF|"))
    entries.append((Line2D([], [], color="gray", marker=".", linestyle="none"), "F_peak (within each interval)"))
    entries.append((Line2D([], [], color="gray", marker="v", markeredgecolor="black", linestyle="none"),
                    "largest F_peak"))
    return entries


def panel_grid(count):
    """(figure, axes) of `count` panels: one column up to two panels, else two."""
    columns = 1 if count <= 2 else 2
    return new_figure(math.ceil(count / columns), columns)


def finish_grid(axes, used):
    """Hides the cells beyond `used`; the lowest panel of each column shows the time axis."""
    columns = axes.shape[1]
    for index, ax in enumerate(axes.flat):
        if index >= used:
            ax.set_visible(False)
        elif index + columns >= used:
            ax.xaxis.set_tick_params(labelbottom=True)
            ax.set_xlabel("time [s]")


def plot_forces(runs, tables, path):
    parts = list(dict.fromkeys(part for table in tables for part in table["part"]))
    sources = list(dict.fromkeys(source for table in tables for source in table["source"]))
    fig, axes = panel_grid(len(parts))
    summed = [force_panel(ax, tables, "part", part, sources) for ax, part in zip(axes.flat, parts)]
    finish_grid(axes, len(parts))
    finish(fig, figure_title(runs, "force on each structure part (forces.csv)"), force_entries(sources, any(summed)),
           path, runs)


# ------------------------------------------------------------------------------------------- energy


def balance(table):
    """total + dissipated - inflow per row: what the run's energy is without what inflows brought in (the
    inflow column is absent in files of older runs)."""
    inflow = table["inflow"] if table.has("inflow") else 0.0
    return table["total"] + table["dissipated"] - inflow


def plot_energy(runs, tables, path):
    terms = ENERGY_COLUMNS[1:]
    if any(table.has("inflow") and np.any(table["inflow"] != 0) for table in tables):
        terms += ("inflow",)
        tables = [table if table.has("inflow") else Table(dict(table.columns, inflow=0.0 * table["total"]),
                                                           table.rows) for table in tables]
    fig, axes = new_figure(2, height=7.5)
    top, bottom = axes[0, 0], axes[1, 0]
    factor, unit = si_scale(largest_abs([table[t] for table in tables for t in terms]), "J")
    residuals = [balance(table) - balance(table)[0] for table in tables]
    residual_factor, residual_unit = si_scale(largest_abs(residuals), "J")
    notes = []
    for run, table, residual, style in zip(runs, tables, residuals, RUN_LINESTYLES):
        for index, term in enumerate(terms):
            width = 2.0 if term == "total" else 1.3
            top.plot(table["time"], table[term] / factor, color=colour(index), linestyle=style, linewidth=width)
        bottom.plot(table["time"], residual / residual_factor, color=colour(len(terms)), linestyle=style)
        start = table["total"][0]
        share = "{:+.3g} % of the initial total".format(100.0 * residual[-1] / abs(start)) if start else \
            format_value(residual[-1], "J")
        notes.append((run.label + ": " if len(runs) > 1 else "") + share)
    top.set_ylabel("energy [{}]".format(unit))
    bottom.set_ylabel("residual [{}]".format(residual_unit))
    bottom.set_xlabel("time [s]")
    bottom.axhline(0.0, color="black", linewidth=0.8)
    bottom.set_title("residual = (total + dissipated − inflow) − (its value at the first row)\nat the end: " +
                     ", ".join(notes), fontsize=9, loc="left")
    entries = [(Line2D([], [], color=colour(i), linewidth=2.0 if t == "total" else 1.3), t)
               for i, t in enumerate(terms)]
    entries.append((Line2D([], [], color=colour(len(terms))), "residual of the balance"))
    finish(fig, figure_title(runs, "energy balance (energy.csv, dissipated: cumulative)"), entries, path, runs)


def plot_fem_energy(runs, tables, path):
    terms = list(dict.fromkeys(name for table in tables for name in table.columns if name.endswith("_J")))
    eroding = any(np.nansum(table["eroded_elements"]) > 0 for table in tables)
    fig, axes = new_figure(2 if eroding else 1, height=7.5 if eroding else 6.0)
    top = axes[0, 0]
    factor, unit = si_scale(largest_abs([table[t] for table in tables for t in terms if table.has(t)]), "J")
    for table, style in zip(tables, RUN_LINESTYLES):
        for index, term in enumerate(terms):
            if table.has(term):
                top.plot(table["time_s"], table[term] / factor, color=colour(index), linestyle=style)
        if eroding:
            axes[1, 0].plot(table["time_s"], table["eroded_elements"], color="black", linestyle=style,
                            drawstyle="steps-post")
    top.set_ylabel("energy [{}]".format(unit))
    if eroding:
        axes[1, 0].set_ylabel("eroded elements")
    axes[-1, 0].set_xlabel("time [s]")
    entries = [(Line2D([], [], color=colour(i)), t[:-2].replace("_", " ")) for i, t in enumerate(terms)]
    if eroding:
        entries.append((Line2D([], [], color="black"), "eroded elements (count)"))
    finish(fig, figure_title(runs, "deformable FEM parts, summed (fem_energy.csv)"), entries, path, runs)


# ------------------------------------------------------------------------------------------- gauges


def gauge_kinds(table):
    """{gauge name: 'point' or 'line'}: a line gauge has points beyond index 0 or a depth."""
    kinds = {}
    for name in dict.fromkeys(table["gauge"]):
        rows = table["gauge"] == name
        line = np.nanmax(table["point"][rows]) > 0 or np.isfinite(table["depth"][rows]).any()
        kinds[name] = "line" if line else "point"
    return kinds


def plot_gauges(runs, tables, path):
    kinds = {}
    for table in tables:
        kinds.update(gauge_kinds(table))
    points = [name for name, kind in kinds.items() if kind == "point"]
    lines = [name for name, kind in kinds.items() if kind == "line"]
    names = points + lines
    # Per panel: (column drawn, its unit, title); "speed" is the velocity's magnitude, added to the tables.
    panels = []
    if points:
        panels.append(("pressure", "Pa", "point gauges: pressure (0 where dry)"))
    if lines:
        panels.append(("depth", "m", "line gauges: distance from the line's start to the free surface"))
    if points:
        panels.append(("speed", "m/s", "point gauges: velocity magnitude"))
    fig, axes = new_figure(len(panels))
    for table in tables:
        table.columns["speed"] = np.linalg.norm(np.column_stack([table["velocity_" + a] for a in "xyz"]), axis=1)
    for ax, (quantity, unit, title) in zip(axes[:, 0], panels):
        kind = "line" if quantity == "depth" else "point"
        # A line gauge's depth is on each of its rows: its first point's rows hold it once per sample.
        shown = [np.isin(table["gauge"], lines if kind == "line" else points) & (table["point"] == 0)
                 for table in tables]
        factor, scaled_unit = si_scale(largest_abs([table[quantity][rows] for table, rows in zip(tables, shown)]),
                                       unit)
        for table, rows, style in zip(tables, shown, RUN_LINESTYLES):
            for name in names:
                mine = rows & (table["gauge"] == name)
                if mine.any():
                    ax.plot(table["time"][mine], table[quantity][mine] / factor, color=colour(names.index(name)),
                            linestyle=style)
        ax.set_ylabel("{} [{}]".format("velocity magnitude" if quantity == "speed" else quantity, scaled_unit))
        ax.set_title(title, fontsize=9, loc="left")
    axes[-1, 0].set_xlabel("time [s]")
    entries = [(Line2D([], [], color=colour(i)), "{} ({})".format(name, kinds[name])) for i, name in
               enumerate(names)]
    finish(fig, figure_title(runs, "gauges (gauges.csv)"), entries, path, runs)


# ------------------------------------------------------------------------------------------- fronts


def plot_series_panels(runs, tables, path, key, panels, what):
    """One panel per (column, unit, title) of `panels`, a curve per value of the text column `key`."""
    names = list(dict.fromkeys(name for table in tables for name in table[key]))
    fig, axes = new_figure(len(panels))
    for ax, (quantity, unit, title) in zip(axes[:, 0], panels):
        factor, scaled_unit = si_scale(largest_abs([table[quantity] for table in tables]), unit)
        for table, style in zip(tables, RUN_LINESTYLES):
            for index, name in enumerate(names):
                rows = table[key] == name
                if rows.any():
                    ax.plot(table["time"][rows], table[quantity][rows] / factor, color=colour(index),
                            linestyle=style)
        ax.set_ylabel("{} [{}]".format(quantity.replace("_", " "), scaled_unit))
        ax.set_title(title, fontsize=9, loc="left")
    axes[-1, 0].set_xlabel("time [s]")
    entries = [(Line2D([], [], color=colour(i)), name) for i, name in enumerate(names)]
    finish(fig, figure_title(runs, what), entries, path, runs)


def plot_fronts(runs, tables, path):
    plot_series_panels(runs, tables, path, "front", (
        ("position", "m", "front: distance along its path"),
        ("speed", "m/s", "front speed: advance between two samples / time between them"),
        ("flow_speed", "m/s", "mean flow speed along the path within 2 h behind the front")),
        "fronts (fronts.csv)")


def plot_inflows(runs, tables, path):
    for table in tables:
        table.columns["shortfall"] = table["hydrograph_volume"] - table["released_volume"]
    plot_series_panels(runs, tables, path, "body", (
        ("discharge", "m³/s", "the hydrograph's discharge Q(t)"),
        ("released_volume", "m³", "volume released through the section"),
        ("shortfall", "m³", "the hydrograph's integral less the volume released (within half a layer)")),
        "inflows (inflows.csv)")


def plot_front_stations(runs, tables, path):
    for table in tables:
        table.columns["label"] = np.array(["{} {}".format(f, s) for f, s in zip(table["front"], table["station"])])
    plot_series_panels(runs, tables, path, "label", (
        ("depth", "m", "flow depth above each station's path point (front, station)"),),
        "front stations (front_stations.csv)")


# ------------------------------------------------------------------------------------------ sensors


def plot_sensors(runs, tables, path):
    """A force panel per sensor (as forces.png), then the mean pressure of every sensor."""
    sensors = list(dict.fromkeys(name for table in tables for name in table["sensor"]))
    sources = list(dict.fromkeys(source for table in tables for source in table["source"]))
    fig, axes = panel_grid(len(sensors) + 1)
    summed = [force_panel(ax, tables, "sensor", sensor, sources) for ax, sensor in zip(axes.flat, sensors)]
    pressure_ax = axes.flat[len(sensors)]
    factor, unit = si_scale(largest_abs([table["pressure"] for table in tables]), "Pa")
    for table, style in zip(tables, RUN_LINESTYLES):
        for index, sensor in enumerate(sensors):
            rows = table["sensor"] == sensor
            times, where = np.unique(table["time"][rows], return_inverse=True)
            pressure = np.zeros(len(times))
            np.add.at(pressure, where, np.nan_to_num(table["pressure"][rows]))
            pressure_ax.plot(times, pressure / factor, color=colour(len(sources) + index), linestyle=style)
    pressure_ax.set_title("mean normal pressure on each sensor (sum of its sources)", fontsize=10, loc="left")
    pressure_ax.set_ylabel("pressure [{}]".format(unit))
    finish_grid(axes, len(sensors) + 1)
    entries = force_entries(sources, any(summed))
    entries += [(Line2D([], [], color=colour(len(sources) + i)), "pressure: {}".format(sensor))
                for i, sensor in enumerate(sensors)]
    finish(fig, figure_title(runs, "force sensors (sensors.csv)"), entries, path, runs)


# -------------------------------------------------------------------------------------------- steps


def segment_starts(progress):
    """True at each event that starts a coupler process's stretch: its first event reports a rate of 0 (no
    wall time yet), and a resumed or restarted run goes back in simulated time."""
    starts = ~(progress["steps_per_second"] > 0)
    starts[1:] |= np.diff(progress["time"]) < 0
    starts[0] = True
    return starts


def wall_clock(progress, starts):
    """Wall seconds since the coupler process started, at each event: the coupler's steps_per_second is
    (step - the step it started at) / (wall seconds since it started)."""
    base = np.maximum.accumulate(np.where(starts, np.arange(len(starts)), 0))
    rate = progress["steps_per_second"]
    return np.where(rate > 0, (progress["step"] - progress["step"][base]) / np.where(rate > 0, rate, 1), 0.0)


def between_events(values, starts):
    """Per event, the value over the interval since the previous event; nan where a stretch starts."""
    result = np.full(len(starts), np.nan)
    result[1:] = values
    result[starts] = np.nan
    return result


def broken(values, starts):
    """`values` with nan before each stretch's start, so that stretches are drawn apart."""
    values = np.asarray(values, dtype=float).copy()
    values[1:][starts[1:]] = np.nan
    return values


def step_series(progress):
    """Per progress event: simulated time, the dt it reports, and over the interval since the previous event
    the mean dt and the steps per wall second; the coupler's steps per second since it started."""
    time, step = progress["time"], progress["step"]
    starts = segment_starts(progress)
    wall = wall_clock(progress, starts)
    with np.errstate(divide="ignore", invalid="ignore"):
        mean_dt = between_events(np.diff(time) / np.diff(step), starts)
        rate = between_events(np.diff(step) / np.diff(wall), starts)
    since_start = np.where(progress["steps_per_second"] > 0, progress["steps_per_second"], np.nan)
    return {"time": time, "dt": broken(progress["dt"], starts), "mean_dt": mean_dt, "rate": rate,
            "rate_since_start": broken(since_start, starts)}


def plot_steps(runs, progresses, path):
    fig, axes = new_figure(2, height=7.5)
    top, bottom = axes[0, 0], axes[1, 0]
    series = [step_series(progress) for progress in progresses]
    known = np.concatenate([s[key] for s in series for key in ("dt", "mean_dt")])
    known = known[np.isfinite(known) & (known > 0)]
    logarithmic = len(known) > 0 and known.max() > 20 * known.min()
    factor, unit = (1.0, "s") if logarithmic else si_scale(known.max() if len(known) else 0.0, "s")
    for s, style in zip(series, RUN_LINESTYLES):
        top.plot(s["time"], s["dt"] / factor, color=colour(0), linestyle=style, marker=".", markersize=5)
        top.plot(s["time"], s["mean_dt"] / factor, color=colour(1), linestyle=style, drawstyle="steps-pre")
        bottom.plot(s["time"], s["rate"], color=colour(2), linestyle=style, drawstyle="steps-pre")
        bottom.plot(s["time"], s["rate_since_start"], color=colour(3), linestyle=style, marker=".", markersize=4)
    if logarithmic:
        top.set_yscale("log")
    elif len(known):
        top.set_ylim(0, 1.15 * known.max() / factor)
    top.set_ylabel("time step [{}]".format(unit))
    bottom.set_ylabel("steps per wall second")
    bottom.set_xlabel("simulated time [s]")
    bottom.set_ylim(bottom=0)
    details = []
    for run in runs:
        if isinstance(run.summary.get("steps"), int) and isinstance(run.summary.get("wall_seconds"), (int, float)):
            details.append("{}{} steps in {:.1f} s wall".format(run.label + ": " if len(runs) > 1 else "",
                                                                run.summary["steps"], run.summary["wall_seconds"]))
    bottom.set_title("from the coupler's progress events (about two a second of wall time)" +
                     ("; " + ", ".join(details) if details else ""), fontsize=9, loc="left")
    entries = [(Line2D([], [], color=colour(0), marker="."), "dt of the step a progress event reports"),
               (Line2D([], [], color=colour(1)), "mean dt between two events (Δtime / Δstep)"),
               (Line2D([], [], color=colour(2)), "steps per wall second between two events"),
               (Line2D([], [], color=colour(3), marker="."), "steps per wall second since the coupler started")]
    finish(fig, figure_title(runs, "time steps (coupler.events.jsonl)"), entries, path, runs)


# --------------------------------------------------------------------------------------------- main

# (figure, file, reader, drawer)
FIGURES = (
    ("forces.png", "forces.csv", lambda path: read_csv(path, FORCES_COLUMNS), plot_forces),
    ("energy.png", "energy.csv", lambda path: read_csv(path, ENERGY_COLUMNS), plot_energy),
    ("fem_energy.png", "fem_energy.csv", lambda path: read_csv(path, FEM_ENERGY_COLUMNS), plot_fem_energy),
    ("gauges.png", "gauges.csv", lambda path: read_csv(path, GAUGES_COLUMNS), plot_gauges),
    ("fronts.png", "fronts.csv", lambda path: read_csv(path, FRONTS_COLUMNS), plot_fronts),
    ("front_stations.png", "front_stations.csv", lambda path: read_csv(path, FRONT_STATIONS_COLUMNS),
     plot_front_stations),
    ("sensors.png", "sensors.csv", lambda path: read_csv(path, SENSORS_COLUMNS), plot_sensors),
    ("inflows.png", "inflows.csv", lambda path: read_csv(path, INFLOWS_COLUMNS), plot_inflows),
    ("steps.png", EVENTS_FILE, read_progress, plot_steps),
)


def sample_times(data):
    """How many distinct times `data` (a Table or the progress events) holds: a curve needs two."""
    if data is None:
        return 0
    times = data["time_s"] if isinstance(data, Table) and data.has("time_s") else data["time"]
    return len(np.unique(times))


def draw(runs, out_dir):
    """Writes every figure whose data some run has; returns (written, skipped notes, errors)."""
    written, skipped, errors = [], [], []
    for figure, name, reader, drawer in FIGURES:
        present, data, why = [], [], []
        for run in runs:
            if not run.has(name):
                why.append("no {}".format(name) if len(runs) == 1 else "{}: no {}".format(run.label, name))
                continue
            try:
                loaded = reader(run.file(name))
            except InputError as error:
                errors.append(str(error))
                why.append("{}{} is malformed".format(run.label + ": " if len(runs) > 1 else "", name))
                continue
            if sample_times(loaded) < 2:
                what = "progress events" if name == EVENTS_FILE else "output times"
                why.append("{}{} holds fewer than two {}".format(run.label + ": " if len(runs) > 1 else "", name,
                                                                 what))
                continue
            present.append(run)
            data.append(loaded)
        if not present:
            skipped.append("{} ({})".format(figure, "; ".join(why)))
            continue
        if why:
            skipped.append("{} drawn without {}".format(figure, "; ".join(why)))
        try:
            os.makedirs(out_dir, exist_ok=True)
        except OSError as error:
            raise InputError("{}: cannot create the plots folder: {}".format(out_dir, error.strerror))
        try:
            drawer(present, data, os.path.join(out_dir, figure))
        except OSError as error:
            raise InputError("{}: cannot write it: {}".format(os.path.join(out_dir, figure), error.strerror))
        written.append(figure)
    return written, skipped, errors


def parse_arguments(argv):
    parser = argparse.ArgumentParser(prog="sabo_plot.py", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("run_dir", metavar="RUN_DIR", help="a run folder")
    parser.add_argument("compare_dir", metavar="RUN_DIR_B", nargs="?",
                        help="a second run folder, overlaid (dashed) on the first (solid)")
    parser.add_argument("--out", metavar="DIR",
                        help="folder of the PNG files (default: RUN_DIR/plots, or RUN_DIR/plots/compare_<B>)")
    return parser.parse_args(argv)


def main(argv=None):
    args = parse_arguments(sys.argv[1:] if argv is None else argv)
    try:
        runs = [Run(args.run_dir)] + ([Run(args.compare_dir)] if args.compare_dir else [])
        for run in runs:
            if not any(run.has(name) for _, name, _, _ in FIGURES):
                raise InputError("{}: nothing to plot: none of {} is there (is it a run folder?)".format(
                    run.path, ", ".join(name for _, name, _, _ in FIGURES)))
        out_dir = args.out or os.path.join(runs[0].path, PLOTS_FOLDER)
        if args.out is None and len(runs) > 1:
            out_dir = os.path.join(out_dir, "compare_" + runs[1].label)
        written, skipped, errors = draw(runs, out_dir)
        if not written and not errors:
            raise InputError("{}: nothing to plot: {}".format(" and ".join(run.path for run in runs),
                                                              ", ".join(skipped)))
    except InputError as error:
        print("sabo_plot: error: {}".format(error), file=sys.stderr)
        return EXIT_BAD_INPUT
    if written:
        print("sabo_plot: wrote {}/: {}".format(out_dir, ", ".join(written)))
    if skipped:
        print("sabo_plot: skipped: {}".format(", ".join(skipped)))
    for error in errors:
        print("sabo_plot: error: {}".format(error), file=sys.stderr)
    return EXIT_BAD_INPUT if errors else 0


if __name__ == "__main__":
    sys.exit(main())
