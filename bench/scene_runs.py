"""Runs a scene written by a benchmark script through `./sabo run` (the built binaries, no set-up, no
plots): the run folder, its wall time and summary.json; reads the run's VTK files. Standard library only."""
import json
import os
import re
import struct
import subprocess
import time
import xml.etree.ElementTree as ET

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


def pvd_frames(run_dir, name):
    """(time, path) of each frame of RUN_DIR/NAME.pvd, in the series' order."""
    root = ET.parse(os.path.join(run_dir, name + ".pvd")).getroot()
    return [(float(e.get("timestep")), os.path.join(run_dir, e.get("file"))) for e in root.iter("DataSet")]


def read_vtu(path):
    """Points and point arrays of one of Sabo's VTK XML files (.vtu, .vtp: appended raw, UInt64 headers), by
    name: a list of tuples of the array's components."""
    with open(path, "rb") as handle:
        raw = handle.read()
    start = raw.index(b"<AppendedData")
    head = raw[:start].decode()
    data = raw.index(b"_", start) + 1
    sizes = {"Float64": ("d", 8), "Int64": ("q", 8), "UInt64": ("Q", 8), "UInt8": ("B", 1)}
    arrays = {}
    pattern = r'<DataArray type="(\w+)" Name="(\w+)" NumberOfComponents="(\d+)" format="appended" offset="(\d+)"'
    for match in re.finditer(pattern, head):
        kind, name, components, offset = match.group(1), match.group(2), int(match.group(3)), int(match.group(4))
        if kind not in sizes:
            continue
        code, width = sizes[kind]
        at = data + offset
        size = struct.unpack_from("<Q", raw, at)[0]
        values = struct.unpack_from("<{}{}".format(size // width, code), raw, at + 8)
        arrays[name] = [values[k:k + components] for k in range(0, len(values), components)]
    return arrays
