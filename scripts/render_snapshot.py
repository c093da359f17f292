#!/usr/bin/python3
"""A picture of a run folder at one time: the slurry's particles coloured by speed, the boulders as
circles of their radius, and the structures: seen from the side (x-z), their section by the vertical plane
through the middle of the scene's width, one colour per part; from above (x-y), their upward faces.

    scripts/render_snapshot.py RUN_DIR [--time T] [--view side|top] [--out FILE.png] [--range XMIN XMAX]

It reads the ParaView series of the run folder (sph.pvd, dem.pvd and fem.pvd, the structures' surfaces;
VTK XML with appended raw, base64 or ascii data) and takes from each the output
nearest to T (default: the last). Writes RUN_DIR/plots/snapshot_<T>.png unless --out is given.
Exit status: 0 written, 2 bad input (not a run folder, no series, a malformed file: the message names it).
"""
import argparse
import base64
import os
import re
import sys
import xml.etree.ElementTree as ElementTree

import numpy as np

TYPES = {"Float64": "<f8", "Float32": "<f4", "Int64": "<i8", "UInt64": "<u8", "Int32": "<i4", "UInt32": "<u4",
         "Int8": "i1", "UInt8": "u1", "Int16": "<i2", "UInt16": "<u2"}


class InputError(Exception):
    pass


def read_vtk(path):
    """{name: array} of a VTK XML PolyData or UnstructuredGrid file: "Points", the point and cell data, and
    "connectivity"/"offsets" of its polygons or cells."""
    with open(path, "rb") as handle:
        content = handle.read()
    marker = content.find(b"<AppendedData")
    appended = b""
    if marker >= 0:
        start = content.index(b"_", content.index(b">", marker)) + 1
        appended = content[start:]
        xml_text = content[:marker].decode("utf-8")
        xml_text += "".join("</{}>".format(tag) for tag in reversed(open_tags(xml_text)))
    else:
        xml_text = content.decode("utf-8")
    try:
        root = ElementTree.fromstring(xml_text)
    except ElementTree.ParseError as error:
        raise InputError("{}: not a VTK XML file ({})".format(path, error)) from error
    header = TYPES[root.get("header_type", "UInt32")]
    arrays = {}
    point_arrays = {id(element) for points in root.iter("Points") for element in points.iter("DataArray")}
    for element in root.iter("DataArray"):
        dtype = np.dtype(TYPES[element.get("type")])
        encoding = element.get("format")
        if encoding == "appended":
            offset = int(element.get("offset"))
            size = int(np.frombuffer(appended, dtype=header, count=1, offset=offset)[0])
            values = np.frombuffer(appended, dtype=dtype, count=size // dtype.itemsize,
                                   offset=offset + np.dtype(header).itemsize)
        elif encoding == "binary":
            raw = base64.b64decode("".join((element.text or "").split()))
            values = np.frombuffer(raw[np.dtype(header).itemsize:], dtype=dtype)
        else:
            values = np.array((element.text or "").split(), dtype=dtype)
        components = int(element.get("NumberOfComponents", "1"))
        name = "Points" if id(element) in point_arrays else element.get("Name")
        arrays[name] = values.reshape(-1, components) if components > 1 else values
    return arrays


def open_tags(xml_text):
    """The elements still open at the end of a truncated XML text, outermost first."""
    stack = []
    for match in re.finditer(r"<(/?)([A-Za-z]+)[^>]*?(/?)>", xml_text):
        closing, tag, empty = match.groups()
        if tag == "xml" or xml_text[match.start() + 1] == "?":
            continue
        if closing:
            stack.pop()
        elif not empty:
            stack.append(tag)
    return stack


def series(path):
    """[(time, file)] of a .pvd collection."""
    try:
        root = ElementTree.parse(path).getroot()
    except ElementTree.ParseError as error:
        raise InputError("{}: not a ParaView collection ({})".format(path, error)) from error
    folder = os.path.dirname(path)
    return [(float(d.get("timestep")), os.path.join(folder, d.get("file"))) for d in root.iter("DataSet")]


def nearest(entries, time):
    if not entries:
        return None
    if time is None:
        return entries[-1]
    return min(entries, key=lambda entry: abs(entry[0] - time))


def polygons(arrays):
    """The faces of a surface file as lists of point indices."""
    connectivity, offsets = arrays.get("connectivity"), arrays.get("offsets")
    if connectivity is None or offsets is None:
        return []
    starts = np.concatenate([[0], offsets[:-1]])
    return [connectivity[a:b] for a, b in zip(starts, offsets)]


PART_COLOURS = ["#4d4d4d", "#8c564b", "#1f77b4", "#9467bd", "#e377c2", "#7f7f7f"]


def section(points, triangles, axis):
    """The lines where the plane through the middle of the points' extent along `axis` cuts the triangles:
    (segments (k, 2, 3), the triangle of each segment). The plane is nudged off the vertices."""
    low, high = points[:, axis].min(), points[:, axis].max()
    level = 0.5 * (low + high) + 1e-7 * max(high - low, 1.0)
    distance = points[:, axis] - level
    ends = []
    for first, second in ((0, 1), (1, 2), (2, 0)):
        da, db = distance[triangles[:, first]], distance[triangles[:, second]]
        crossing = da * db < 0
        t = np.where(crossing, da / np.where(crossing, da - db, 1.0), 0.0)
        pa, pb = points[triangles[:, first]], points[triangles[:, second]]
        ends.append((crossing, pa + t[:, None] * (pb - pa)))
    crossed = np.stack([c for c, _ in ends], axis=1)
    cut = crossed.sum(axis=1) == 2
    segments = []
    for index in np.nonzero(cut)[0]:
        segments.append([ends[e][1][index] for e in range(3) if crossed[index, e]])
    return np.array(segments).reshape(-1, 2, 3), np.nonzero(cut)[0]


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run_dir", metavar="RUN_DIR")
    parser.add_argument("--time", type=float, help="simulated time, s (default: the last output)")
    parser.add_argument("--view", choices=("side", "top"), default="side")
    parser.add_argument("--out", help="PNG file (default RUN_DIR/plots/snapshot_<time>.png)")
    parser.add_argument("--range", nargs=2, type=float, metavar=("XMIN", "XMAX"), help="x range shown, m")
    parser.add_argument("--title", help="title above the picture")
    args = parser.parse_args(argv)
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.collections import LineCollection, PatchCollection, PolyCollection
    from matplotlib.patches import Circle

    run = args.run_dir
    axes_of_view = (0, 2) if args.view == "side" else (0, 1)
    found = {name: os.path.join(run, name) for name in sorted(os.listdir(run)) if name.endswith(".pvd")} \
        if os.path.isdir(run) else {}
    if not found:
        print("{}: no ParaView series (*.pvd) here. Fix: give a run folder of ./sabo run".format(run), file=sys.stderr)
        return 2
    try:
        chosen = {name: nearest(series(path), args.time) for name, path in found.items()}
        shown_time = next(entry[0] for entry in chosen.values() if entry)
        fig, ax = plt.subplots(figsize=(12, 3.6) if args.view == "side" else (12, 6), dpi=110)
        a, b = axes_of_view
        extents = []  # the points drawn, for the limits of a --range
        counts = {"fluid": 0, "boulders": 0, "structure": 0}
        if chosen.get("fem.pvd"):
            data = read_vtk(chosen["fem.pvd"][1])
            triangles = np.array([face for face in polygons(data) if len(face) == 3], dtype=np.int64).reshape(-1, 3)
            part = data.get("part")
            if args.view == "side":
                segments, owner = section(data["Points"], triangles, axis=1)
                parts = part[owner] if part is not None and len(part) == len(triangles) else np.zeros(len(owner))
                for k, value in enumerate(np.unique(parts)):
                    chosen_segments = segments[parts == value][:, :, [a, b]]
                    extents.append(chosen_segments.reshape(-1, 2))
                    counts["structure"] += len(chosen_segments)
                    ax.add_collection(LineCollection(chosen_segments, colors=PART_COLOURS[k % len(PART_COLOURS)],
                                                     linewidths=1.6, zorder=1))
            else:
                points = data["Points"]
                corners = points[triangles]
                normal = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
                upward = np.abs(normal[:, 2]) > 0.5 * np.linalg.norm(normal, axis=1)
                counts["structure"] += int(upward.sum())
                ax.add_collection(PolyCollection(corners[upward][:, :, [a, b]], facecolors="#8c8c8c",
                                                 edgecolors="#6c6c6c", linewidths=0.2, alpha=0.35, zorder=1))
        if chosen.get("sph.pvd"):
            data = read_vtk(chosen["sph.pvd"][1])
            points = data["Points"]
            active = data.get("active")
            keep = np.ones(len(points), dtype=bool) if active is None else active.astype(bool)
            order = np.argsort(points[keep][:, 3 - a - b] if args.view == "side" else points[keep][:, 2])
            speed = np.linalg.norm(data["velocity"][keep], axis=1)[order]
            shown = points[keep][order]
            extents.append(shown[:, [a, b]])
            counts["fluid"] = len(shown)
            scatter = ax.scatter(shown[:, a], shown[:, b], c=speed, s=4, cmap="viridis", linewidths=0, zorder=2)
            fig.colorbar(scatter, ax=ax, label="slurry speed (m/s)", pad=0.01, fraction=0.03)
        if chosen.get("dem.pvd"):
            data = read_vtk(chosen["dem.pvd"][1])
            circles = [Circle((p[a], p[b]), r) for p, r in zip(data["Points"], data["radius"])]
            counts["boulders"] = len(circles)
            ax.add_collection(PatchCollection(circles, facecolor="#d62728", edgecolor="black", linewidth=0.4,
                                              alpha=0.55, zorder=3))
            extents.append(np.column_stack([data["Points"][:, a], data["Points"][:, b] - data["radius"]]))
            extents.append(np.column_stack([data["Points"][:, a], data["Points"][:, b] + data["radius"]]))
    except (InputError, KeyError, ValueError, OSError) as error:
        print("{}: {}".format(run, error), file=sys.stderr)
        return 2
    ax.set_aspect("equal")
    ax.autoscale_view()
    if args.range:
        ax.set_xlim(*args.range)
        drawn = np.concatenate(extents) if extents else np.zeros((0, 2))
        inside = drawn[(drawn[:, 0] >= args.range[0]) & (drawn[:, 0] <= args.range[1])]
        if len(inside):
            low, high = inside[:, 1].min(), inside[:, 1].max()
            margin = 0.08 * max(high - low, 1e-9)
            ax.set_ylim(low - margin, high + margin)
    ax.set_xlabel("x (m)")
    ax.set_ylabel("z (m)" if args.view == "side" else "y (m)")
    ax.set_title(args.title or "{} at t = {:.2f} s".format(os.path.basename(os.path.normpath(run)), shown_time))
    out = args.out or os.path.join(run, "plots", "snapshot_{:.2f}.png".format(shown_time))
    os.makedirs(os.path.dirname(os.path.abspath(out)), exist_ok=True)
    fig.tight_layout()
    fig.savefig(out)
    print("{}: t = {:g} s, {} fluid particles, {} boulders, {} structure {}".format(
        out, shown_time, counts["fluid"], counts["boulders"], counts["structure"],
        "segments" if args.view == "side" else "faces"))
    return 0


if __name__ == "__main__":
    sys.exit(main())
