"""`./sabo study STUDY.toml`: what accuracy costs in time (docs/accuracy-cost.md).

A study file names a base scene, the scene keys to sweep and the measures to take from each run. Every
combination of the swept values is a variant of the scene (checked by sabo_scene like any scene before anything
runs), run through the real supervisor, as many at once as the cores allow, skipping those a previous
invocation completed. Each measure is read from the run folder (summary.json, a CSV file of the run, or a
script), compared with its reference (a number, or the study's finest run) and written, with the wall and CPU
time of the run, to study.csv and study.md (sorted by cost, the Pareto-optimal runs marked); the observed order
of convergence is fitted for each swept number. scripts/study_plot.py draws pareto.png and one
convergence_<key>.png per swept number (Debian's python3 with matplotlib).

The study file (TOML):

    format_version = 1
    [study]
    scene = "../sph_dam_break.toml"     # relative to the study file
    threads_per_run = 1                 # OMP_NUM_THREADS of each run
    runs_at_once = 0                    # 0: the cores / threads_per_run
    [[parameters]]
    key = "sph.particle_spacing"        # TABLE.KEY of the scene (a [table] written as a header)
    values = [0.04, 0.02, 0.01]         # coarse to fine: the last is the finest
    # or: from = 0.04, to = 0.01, count = 3, spacing = "log" | "linear"
    [[measures]]
    name = "peak_force"
    unit = "N"
    source = "csv"                      # "summary" (field = "a.b.c"), "csv", or "script" (command = [...])
    file = "forces.csv"
    column = "F_peak"
    where = { part = "dam", source = "fluid" }
    reduce = "max"                      # max, min, max_abs, mean, last, or at (with time = 0.3)
    reference = "finest"                # a number, or "finest": the run at every parameter's last value
"""
from __future__ import annotations

import csv
import itertools
import json
import math
import os
import re
import shutil
import subprocess
import sys
import time
from typing import Any

from .display import format_duration, is_number
from .errors import SaboError, EXIT_BAD_INPUT, EXIT_FAILED
from .plan import check_scene
from .scene_text import absolute_file_keys, apply_overrides

SOURCES = ("summary", "csv", "script")
REDUCTIONS = ("max", "min", "max_abs", "mean", "last", "at")
STUDY_KEYS = {"scene", "name", "threads_per_run", "runs_at_once", "timeout"}
PARAMETER_KEYS = {"key", "values", "from", "to", "count", "spacing"}
MEASURE_KEYS = {"name", "unit", "source", "field", "file", "column", "where", "reduce", "time", "command",
                "reference"}
PLOT_SCRIPT = os.path.join("scripts", "study_plot.py")
RESERVED_COLUMNS = ("run", "status", "wall_s", "cpu_s", "steps")
SCRIPT_TIMEOUT_S = 300.0


# ---------------------------------------------------------------------------------------------------- the file

class StudyFile:
    """The study file's text, for errors that name the line of a key."""

    def __init__(self, path: str) -> None:
        self.path = os.path.abspath(path)
        try:
            with open(path, encoding="utf-8") as handle:
                self.text = handle.read()
        except OSError as error:
            raise SaboError(f"{path}: cannot read the study file: {error.strerror}", EXIT_BAD_INPUT)
        self.lines = self.text.splitlines()

    def line_of(self, key: str, table: str | None = None, index: int = 0) -> int:
        """The line of `key` in the `index`-th [table] or [[table]] (top level: None); 0 when not found."""
        start, seen = 0, -1
        if table is not None:
            header = re.compile(rf"^\s*\[\[?\s*{re.escape(table)}\s*\]\]?\s*(#.*)?$")
            for number, line in enumerate(self.lines):
                if header.match(line):
                    seen += 1
                    if seen == index:
                        start = number + 1
                        break
            else:
                return 0
        pattern = re.compile(rf"^\s*{re.escape(key)}\s*=")
        for number in range(start, len(self.lines)):
            if number > start and table is not None and self.lines[number].lstrip().startswith("["):
                break
            if pattern.match(self.lines[number]):
                return number + 1
        return start

    def error(self, key_path: str, value: Any, problem: str, fix: str, line: int) -> SaboError:
        shown = "" if value is None else f" = {json.dumps(value)}"
        return SaboError(f"{self.path}:{line}: key '{key_path}'{shown}: {problem}. Fix: {fix}.", EXIT_BAD_INPUT)


class Parameter:
    def __init__(self, key: str, values: list) -> None:
        self.key = key
        self.values = values

    @property
    def numeric(self) -> bool:
        return all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in self.values)


class Measure:
    def __init__(self, spec: dict, folder: str) -> None:
        self.name = spec["name"]
        self.unit = spec.get("unit", "")
        self.source = spec["source"]
        self.field = spec.get("field")
        self.file = spec.get("file")
        self.column = spec.get("column")
        self.where = spec.get("where", {})
        self.reduce = spec.get("reduce", "max")
        self.time = spec.get("time")
        self.command = [os.path.join(folder, part) if i > 0 and part.endswith(".py") and not os.path.isabs(part)
                        else part for i, part in enumerate(spec.get("command", []))]
        self.reference = spec.get("reference")


class Study:
    def __init__(self, path: str, scene: str, name: str, parameters: list[Parameter], measures: list[Measure],
                 threads_per_run: int, runs_at_once: int, timeout: float) -> None:
        self.path = path
        self.scene = scene
        self.name = name
        self.parameters = parameters
        self.measures = measures
        self.threads_per_run = threads_per_run
        self.runs_at_once = runs_at_once
        self.timeout = timeout

    def combinations(self) -> list[dict]:
        """Every combination of the swept values, the first parameter varying slowest."""
        return [dict(zip([p.key for p in self.parameters], values))
                for values in itertools.product(*[p.values for p in self.parameters])]

    def finest(self) -> dict:
        return {p.key: p.values[-1] for p in self.parameters}


def load_study(path: str) -> Study:
    """The study in `path`, every key checked; SaboError (exit 2) naming the file, line, key and the fix."""
    source = StudyFile(path)
    try:
        import tomllib
    except ImportError:
        raise SaboError(f"{path}: reading a study needs Python 3.11 or newer (tomllib); this is "
                        f"{sys.version_info[0]}.{sys.version_info[1]}", EXIT_FAILED)
    try:
        data = tomllib.loads(source.text)
    except tomllib.TOMLDecodeError as error:
        match = re.search(r"line (\d+)", str(error))
        raise SaboError(f"{source.path}:{match.group(1) if match else 0}: TOML syntax error: {error}. Fix: correct "
                        "the TOML (see https://toml.io)", EXIT_BAD_INPUT)
    folder = os.path.dirname(source.path)

    def unknown(table: dict, allowed: set, path: str, name: str | None, index: int = 0) -> None:
        for key in table:
            if key not in allowed:
                raise source.error(f"{path}.{key}" if path else key, table[key], "unknown key",
                                   f'use one of {", ".join(sorted(allowed))}', source.line_of(key, name, index))

    unknown(data, {"format_version", "study", "parameters", "measures"}, "", None)
    if data.get("format_version") != 1:
        raise source.error("format_version", data.get("format_version"), "this build reads format_version 1",
                           "write format_version = 1 at the top", source.line_of("format_version"))
    study = data.get("study")
    if not isinstance(study, dict):
        raise source.error("study", None, "missing: the study names its scene in a [study] table",
                           'add [study] with scene = "path/to/scene.toml"', 0)
    unknown(study, STUDY_KEYS, "study", "study")
    scene = study.get("scene")
    if not isinstance(scene, str) or not scene:
        raise source.error("study.scene", scene, "the base scene is required", 'give scene = "path/to/scene.toml" '
                           "(relative to the study file)", source.line_of("scene", "study"))
    scene_path = os.path.normpath(os.path.join(folder, scene))
    if not os.path.isfile(scene_path):
        raise source.error("study.scene", scene, f"no such file (looked for {scene_path})",
                           "give the path of a scene, relative to the study file's folder",
                           source.line_of("scene", "study"))
    integers = {"threads_per_run": (1, 1), "runs_at_once": (0, 0)}
    settings = {}
    for key, (default, least) in integers.items():
        value = study.get(key, default)
        if not isinstance(value, int) or isinstance(value, bool) or value < least:
            raise source.error(f"study.{key}", value, f"must be a whole number >= {least}",
                               f"write e.g. {key} = {max(least, 1)}", source.line_of(key, "study"))
        settings[key] = value
    timeout = study.get("timeout", 3600.0)
    if not is_number(timeout) or timeout <= 0:
        raise source.error("study.timeout", timeout, "must be a positive number of seconds",
                           "write e.g. timeout = 3600.0 (each run's limit)", source.line_of("timeout", "study"))
    study_name = study.get("name", os.path.splitext(os.path.basename(path))[0])
    if not isinstance(study_name, str) or not re.fullmatch(r"[A-Za-z0-9_.-]+", study_name):
        raise source.error("study.name", study_name, "must be letters, digits, '_', '.' or '-'",
                           'write e.g. name = "s1_front"', source.line_of("name", "study"))

    parameters = []
    entries = data.get("parameters")
    if not isinstance(entries, list) or not entries:
        raise source.error("parameters", None, "a study sweeps at least one scene key",
                           'add [[parameters]] with key = "TABLE.KEY" and values = [...]', 0)
    for index, entry in enumerate(entries):
        where = f"parameters[{index}]"
        line = lambda key: source.line_of(key, "parameters", index)  # noqa: E731
        unknown(entry, PARAMETER_KEYS, where, "parameters", index)
        key = entry.get("key")
        if not isinstance(key, str) or not re.fullmatch(r"[A-Za-z0-9_]+(\[[0-9]+\])?(\.[A-Za-z0-9_]+)+", key):
            raise source.error(f"{where}.key", key, "must be a scene key TABLE.KEY",
                               'write e.g. key = "sph.particle_spacing", "solvers.dem.beta" or '
                               '"structures[0].element_size"', line("key"))
        if any(p.key == key for p in parameters):
            raise source.error(f"{where}.key", key, "swept twice", "give each key one [[parameters]] table",
                               line("key"))
        if "values" in entry:
            values = entry["values"]
            if any(k in entry for k in ("from", "to", "count", "spacing")):
                raise source.error(f"{where}.values", values, "both values and a range", "keep one of them",
                                   line("values"))
            if not isinstance(values, list) or not values:
                raise source.error(f"{where}.values", values, "must be a non-empty array",
                                   "write e.g. values = [0.04, 0.02, 0.01]", line("values"))
            if any(isinstance(v, (dict, list)) for v in values):
                raise source.error(f"{where}.values", values, "must hold numbers, strings or booleans",
                                   "write one value per combination", line("values"))
        else:
            low, high, count = entry.get("from"), entry.get("to"), entry.get("count")
            spacing = entry.get("spacing", "linear")
            if not (is_number(low) and is_number(high)):
                raise source.error(f"{where}.from", low, "a parameter needs values = [...], or from and to",
                                   "write values = [...], or from = A, to = B, count = N", line("from") or line("key"))
            if not isinstance(count, int) or isinstance(count, bool) or count < 2:
                raise source.error(f"{where}.count", count, "a range needs a whole number count >= 2",
                                   "write e.g. count = 4", line("count") or line("from"))
            if spacing not in ("linear", "log"):
                raise source.error(f"{where}.spacing", spacing, 'must be "linear" or "log"',
                                   'write spacing = "log" for values evenly spaced in log scale', line("spacing"))
            if spacing == "log" and (low <= 0 or high <= 0):
                raise source.error(f"{where}.from", low, "a log range needs positive ends",
                                   'give positive from and to, or spacing = "linear"', line("from"))
            steps = [k / (count - 1) for k in range(count)]
            values = ([low * (high / low) ** s for s in steps] if spacing == "log"
                      else [low + (high - low) * s for s in steps])
            values = [float(f"{v:.12g}") for v in values]
        parameters.append(Parameter(key, values))

    measures = []
    entries = data.get("measures")
    if not isinstance(entries, list) or not entries:
        raise source.error("measures", None, "a study takes at least one measure from each run",
                           'add [[measures]] with name, source and where to read it', 0)
    for index, entry in enumerate(entries):
        where = f"measures[{index}]"
        line = lambda key: source.line_of(key, "measures", index)  # noqa: E731
        unknown(entry, MEASURE_KEYS, where, "measures", index)
        name = entry.get("name")
        if not isinstance(name, str) or not re.fullmatch(r"[A-Za-z][A-Za-z0-9_]*", name):
            raise source.error(f"{where}.name", name, "must be a name of letters, digits and '_'",
                               'write e.g. name = "peak_force"', line("name"))
        if any(m.name == name for m in measures) or name in RESERVED_COLUMNS:
            raise source.error(f"{where}.name", name,
                               "two measures of that name" if name not in RESERVED_COLUMNS else
                               f'a column of study.csv already ({", ".join(RESERVED_COLUMNS)})',
                               "give each measure a name of its own", line("name"))
        kind = entry.get("source")
        if kind not in SOURCES:
            raise source.error(f"{where}.source", kind, f'must be one of {", ".join(SOURCES)}',
                               'write source = "summary" (with field), "csv" (with file, column) or "script" '
                               "(with command)", line("source") or line("name"))
        needs = {"summary": ("field",), "csv": ("file", "column"), "script": ("command",)}[kind]
        for key in needs:
            if key not in entry:
                raise source.error(f"{where}.{key}", None, f'missing: source = "{kind}" needs {" and ".join(needs)}',
                                   f"add {key} = ...", line("source"))
        if kind == "csv":
            if entry.get("reduce", "max") not in REDUCTIONS:
                raise source.error(f"{where}.reduce", entry.get("reduce"), f'must be one of {", ".join(REDUCTIONS)}',
                                   'write e.g. reduce = "max"', line("reduce"))
            if entry.get("reduce") == "at" and not is_number(entry.get("time")):
                raise source.error(f"{where}.time", entry.get("time"), 'reduce = "at" needs the time (s)',
                                   "add time = 0.3", line("reduce"))
            if not isinstance(entry.get("where", {}), dict):
                raise source.error(f"{where}.where", entry.get("where"), "must be a table of column = value",
                                   'write e.g. where = { part = "dam", source = "fluid" }', line("where"))
        if kind == "script":
            command = entry["command"]
            if not isinstance(command, list) or not command or not all(isinstance(p, str) and p for p in command):
                raise source.error(f"{where}.command", command, "must be a non-empty array of strings",
                                   'write e.g. command = ["/usr/bin/python3", "measures/front.py"] (the run folder '
                                   "is appended; the script prints one number)", line("command"))
        reference = entry.get("reference")
        if reference is not None and not (is_number(reference) or reference == "finest"):
            raise source.error(f"{where}.reference", reference, 'must be a number or "finest"',
                               'write the reference value, or reference = "finest" (the run at every parameter\'s '
                               "last value)", line("reference"))
        measures.append(Measure(entry, folder))
    return Study(source.path, scene_path, study_name, parameters, measures, settings["threads_per_run"],
                 settings["runs_at_once"], float(timeout))


# -------------------------------------------------------------------------------------------------- the runs

def format_value(value: Any) -> str:
    return f"{value:g}" if is_number(value) else str(value)


def run_id(index: int, combination: dict) -> str:
    """'r03-spacing_0.02-beta_0.5': the index, then each swept key's last part and value."""
    parts = [f"r{index:02d}"]
    for key, value in combination.items():
        parts.append(f'{key.rsplit(".", 1)[-1]}_{format_value(value)}')
    return re.sub(r"[^A-Za-z0-9_.=-]", "", "-".join(parts))[:120]


def toml_value(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return json.dumps(value)
    return repr(value)


def variant_text(study: Study, base: str, combination: dict) -> str:
    """The base scene's text `base` (its mesh paths made absolute) with the combination's keys set."""
    try:
        return apply_overrides(base, [f"{key}={toml_value(value)}" for key, value in combination.items()])
    except SaboError as error:
        raise SaboError(f"{study.path}: {error} (the base scene is {study.scene})", EXIT_BAD_INPUT)


def completed(run_dir: str) -> dict | None:
    try:
        with open(os.path.join(run_dir, "summary.json"), encoding="utf-8") as handle:
            summary = json.load(handle)
    except (OSError, ValueError):
        return None
    return summary if summary.get("status") == "completed" else None


class Progress:
    """One line: a bar over the runs, how many run, the ETA from the finished runs' mean wall time."""

    def __init__(self, total: int, stream=sys.stdout) -> None:
        self.total = total
        self.done = 0
        self.walls: list[float] = []
        self.stream = stream
        self.tty = stream.isatty()
        self.last = 0.0

    def show(self, running: int, at_once: int, force: bool = False) -> None:
        now = time.monotonic()
        if not force and not self.tty and now - self.last < 10:
            return
        self.last = now
        width = 30
        filled = int(width * self.done / max(self.total, 1))
        left = self.total - self.done
        eta = (sum(self.walls) / len(self.walls) * left / max(at_once, 1)) if self.walls else None
        line = (f'[{"#" * filled}{"." * (width - filled)}] {self.done}/{self.total} runs, {running} running, '
                f'ETA {format_duration(eta) if eta is not None else "--"}')
        self.stream.write(("\r" + line + "   ") if self.tty else line + "\n")
        self.stream.flush()

    def end(self) -> None:
        if self.tty:
            self.stream.write("\n")
            self.stream.flush()


def cores() -> int:
    try:
        return len(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        return os.cpu_count() or 1


def execute(root: str, build_dir: str, study: Study, out: str, plan: list[tuple[str, dict, str]],
            at_once: int) -> dict[str, dict]:
    """Runs what `plan` ([(id, combination, scene file)]) has not completed yet; {id: {"summary", "cpu_s",
    "status"}} of every run. The CPU time is that of the run's whole process tree (the supervisor waits for
    its processes, so their usage is in its own rusage), kept in logs/ID.cpu for a later invocation."""
    results: dict[str, dict] = {}
    pending = []
    for rid, combination, scene in plan:
        run_dir = os.path.join(out, "runs", rid)
        summary = completed(run_dir)
        if summary is not None:
            results[rid] = {"summary": summary, "cpu_s": _read_cpu(out, rid), "status": "completed (earlier)"}
        else:
            if os.path.exists(run_dir):
                shutil.rmtree(run_dir)  # an unfinished run of an earlier invocation: run it again
            pending.append((rid, combination, scene, run_dir))
    if results:
        print(f"sabo: {len(results)} of {len(plan)} runs completed earlier: taken as they are")
    progress = Progress(len(plan))
    progress.done = len(results)
    env = dict(os.environ, OMP_NUM_THREADS=str(study.threads_per_run), SABO_BUILD_DIR=build_dir)
    running: list[tuple[str, int, str, float]] = []
    sabo = os.path.join(root, "sabo")
    try:
        while pending or running:
            while pending and len(running) < at_once:
                rid, combination, scene, run_dir = pending.pop(0)
                with open(os.path.join(out, "logs", rid + ".log"), "wb") as log:
                    popen = subprocess.Popen([sys.executable, sabo, "run", scene, "--out", run_dir, "--quiet",
                                              "--no-setup", "--no-plots"], stdin=subprocess.DEVNULL, stdout=log,
                                             stderr=subprocess.STDOUT, env=env)
                running.append((rid, popen.pid, run_dir, time.monotonic()))
            progress.show(len(running), at_once)
            time.sleep(0.2)
            still, finished = [], False
            for rid, pid, run_dir, started in running:
                waited, status, usage = os.wait4(pid, os.WNOHANG)
                if waited == 0 and time.monotonic() - started >= study.timeout:
                    os.kill(pid, 15)  # over the study's limit: SIGTERM, as Ctrl-C would; the supervisor cleans up
                    waited, status, usage = os.wait4(pid, 0)
                if waited == 0:
                    still.append((rid, pid, run_dir, started))
                    continue
                finished = True
                code = os.WEXITSTATUS(status) if os.WIFEXITED(status) else -os.WTERMSIG(status)
                cpu = usage.ru_utime + usage.ru_stime
                summary = completed(run_dir)
                if summary:
                    with open(os.path.join(out, "logs", rid + ".cpu"), "w", encoding="utf-8") as handle:
                        handle.write(f"{cpu:.3f}\n")
                results[rid] = {"summary": summary or {}, "cpu_s": cpu,
                                "status": "completed" if summary else f"failed (exit {code}; logs/{rid}.log)"}
                progress.done += 1
                if summary:
                    progress.walls.append(float(summary.get("wall_seconds", time.monotonic() - started)))
                else:
                    progress.end()
                    print(f"sabo: {rid} failed (exit {code}): see {os.path.join(out, 'logs', rid + '.log')}")
            running = still
            if finished:
                progress.show(len(running), at_once, force=True)
    except KeyboardInterrupt:
        for _, pid, _, _ in running:
            try:
                os.kill(pid, 15)
                os.waitpid(pid, 0)
            except OSError:
                pass
        raise
    progress.end()
    return results


def _read_cpu(out: str, rid: str) -> float | None:
    try:
        with open(os.path.join(out, "logs", rid + ".cpu"), encoding="utf-8") as handle:
            return float(handle.read())
    except (OSError, ValueError):
        return None


# -------------------------------------------------------------------------------------------------- measures

def measure_value(measure: Measure, run_dir: str) -> float:
    """The measure's value in a completed run; ValueError saying what is missing."""
    if measure.source == "summary":
        node: Any = completed(run_dir) or {}
        for part in measure.field.split("."):
            if isinstance(node, dict) and part in node:
                node = node[part]
            elif isinstance(node, list) and part.isdigit() and int(part) < len(node):
                node = node[int(part)]
            else:
                raise ValueError(f"summary.json has no {measure.field} (no '{part}')")
        if not is_number(node):
            raise ValueError(f"summary.json {measure.field} is {node!r}, not a number")
        return float(node)
    if measure.source == "csv":
        path = os.path.join(run_dir, measure.file)
        try:
            with open(path, newline="", encoding="utf-8") as handle:
                rows = list(csv.DictReader(handle))
        except OSError as error:
            raise ValueError(f"{measure.file}: {error.strerror}")
        rows = [r for r in rows if all(str(r.get(k)) == str(v) for k, v in measure.where.items())]
        if not rows:
            raise ValueError(f"{measure.file} has no row where {measure.where}")
        if measure.column not in rows[0]:
            raise ValueError(f"{measure.file} has no column {measure.column} (it has {', '.join(rows[0])})")
        values = [float(r[measure.column]) for r in rows]
        if measure.reduce == "at":
            times = [float(r["time"]) for r in rows]
            return _interpolate(times, values, float(measure.time))
        return {"max": max, "min": min, "last": lambda v: v[-1], "mean": lambda v: sum(v) / len(v),
                "max_abs": lambda v: max(abs(x) for x in v)}[measure.reduce](values)
    result = subprocess.run(measure.command + [run_dir], stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, universal_newlines=True, timeout=SCRIPT_TIMEOUT_S)
    if result.returncode != 0:
        raise ValueError(f'{" ".join(measure.command)} exited with {result.returncode}: {result.stderr.strip()[-300:]}')
    try:
        return float(result.stdout.strip().splitlines()[-1])
    except (ValueError, IndexError):
        raise ValueError(f'{" ".join(measure.command)} printed {result.stdout.strip()[-100:]!r}, not a number')


def _interpolate(times: list[float], values: list[float], at: float) -> float:
    if at <= times[0]:
        return values[0]
    for k in range(1, len(times)):
        if times[k] >= at:
            w = (at - times[k - 1]) / (times[k] - times[k - 1]) if times[k] > times[k - 1] else 1.0
            return values[k - 1] + w * (values[k] - values[k - 1])
    raise ValueError(f"the run ends at t = {times[-1]:g} s, before {at:g} s")


def relative_error(value: float | None, reference: float | None) -> float | None:
    if value is None or reference is None:
        return None
    return abs(value - reference) / abs(reference) if reference != 0 else abs(value - reference)


def pareto_front(points: list[tuple[float, float]]) -> list[int]:
    """The indices of the points (cost, error) that no other point beats in both (lower or equal in both,
    lower in one), sorted by cost."""
    order = sorted(range(len(points)), key=lambda k: (points[k][0], points[k][1]))
    front, best = [], math.inf
    for k in order:
        if points[k][1] < best:
            front.append(k)
            best = points[k][1]
    return front


def observed_order(steps: list[float], errors: list[float]) -> float | None:
    """The slope of log(error) against log(step) by least squares (error ~ C step^p), over the points with a
    positive step and error; None for fewer than two."""
    pairs = [(math.log(s), math.log(e)) for s, e in zip(steps, errors) if s > 0 and e is not None and e > 0]
    if len(pairs) < 2:
        return None
    mx = sum(x for x, _ in pairs) / len(pairs)
    my = sum(y for _, y in pairs) / len(pairs)
    sxx = sum((x - mx) ** 2 for x, _ in pairs)
    if sxx == 0:
        return None
    return sum((x - mx) * (y - my) for x, y in pairs) / sxx


# ----------------------------------------------------------------------------------------------- the command

def command_study(root: str, build_dir: str, args) -> int:
    study = load_study(args.study)
    out = os.path.abspath(args.out or os.path.join("studies", study.name))
    combinations = study.combinations()
    at_once = args.runs_at_once or study.runs_at_once or max(1, cores() // study.threads_per_run)
    for folder in ("scenes", "runs", "logs"):
        os.makedirs(os.path.join(out, folder), exist_ok=True)
    plan = []
    bin_dir = os.path.join(build_dir, "bin")
    with open(study.scene, encoding="utf-8") as handle:
        base = absolute_file_keys(handle.read(), os.path.dirname(study.scene))
    for index, combination in enumerate(combinations):
        rid = run_id(index, combination)
        scene = os.path.join(out, "scenes", rid + ".toml")
        text = variant_text(study, base, combination)
        with open(scene, "w", encoding="utf-8") as handle:
            handle.write(text)
        try:
            check_scene(scene, bin_dir)  # every variant is a valid scene before anything runs
        except SaboError as error:
            print(str(error), file=sys.stderr)
            raise SaboError(f"{study.path}: the variant {rid} ({', '.join(f'{k} = {format_value(v)}' for k, v in combination.items())}) "
                            "is not a valid scene (above); nothing was started", error.exit_code)
        plan.append((rid, combination, scene))
    print(f"sabo: study {study.name}: {len(plan)} runs of {study.scene}, {at_once} at once with "
          f"{study.threads_per_run} thread{'s' if study.threads_per_run > 1 else ''} each; folder {out}")
    if args.dry_run:
        for rid, combination, _ in plan:
            print(f"  {rid}: " + ", ".join(f"{k} = {format_value(v)}" for k, v in combination.items()))
        return 0
    started = time.monotonic()
    results = execute(root, build_dir, study, out, plan, at_once)
    rows = tabulate(study, plan, results, out)
    write_outputs(root, study, rows, out)
    failed = [row for row in rows if not row["status"].startswith("completed")]
    print(f"sabo: study {study.name}: {len(rows) - len(failed)} of {len(rows)} runs completed in "
          f"{format_duration(time.monotonic() - started)}; {os.path.join(out, 'study.md')}")
    return 1 if failed else 0


def tabulate(study: Study, plan: list, results: dict, out: str) -> list[dict]:
    rows = []
    finest = study.finest()
    for rid, combination, _ in plan:
        result = results.get(rid, {"summary": {}, "cpu_s": None, "status": "not run"})
        summary = result["summary"]
        row = {"run": rid, "status": result["status"], "parameters": combination,
               "wall_s": summary.get("wall_seconds"), "cpu_s": result["cpu_s"], "steps": summary.get("steps"),
               "values": {}, "errors": {}, "problems": []}
        if result["status"].startswith("completed"):
            for measure in study.measures:
                try:
                    row["values"][measure.name] = measure_value(measure, os.path.join(out, "runs", rid))
                except (ValueError, subprocess.TimeoutExpired) as error:
                    row["problems"].append(f"{measure.name}: {error}")
        row["finest"] = combination == finest
        rows.append(row)
    for measure in study.measures:
        if measure.reference == "finest":
            finest_row = next((r for r in rows if r["finest"]), None)
            reference = finest_row["values"].get(measure.name) if finest_row else None
        else:
            reference = measure.reference
        measure.reference_value = reference
        for row in rows:
            row["errors"][measure.name] = relative_error(row["values"].get(measure.name), reference)
    return rows


def write_outputs(root: str, study: Study, rows: list[dict], out: str) -> None:
    keys = [p.key for p in study.parameters]
    with open(os.path.join(out, "study.csv"), "w", newline="", encoding="utf-8") as handle:
        writer = csv.writer(handle)
        header = ["run", "status"] + keys + ["wall_s", "cpu_s", "steps"]
        for m in study.measures:
            header += [m.name, m.name + "_error"]
        writer.writerow(header)
        for row in rows:
            line = [row["run"], row["status"]] + [row["parameters"][k] for k in keys]
            line += [_cell(row["wall_s"], "r"), _cell(row["cpu_s"], "r"), _cell(row["steps"], "r")]
            for m in study.measures:
                line += [_cell(row["values"].get(m.name), "r"), _cell(row["errors"].get(m.name), "r")]
            writer.writerow(line)
    orders = {}
    for parameter in study.parameters:
        if not parameter.numeric or len(parameter.values) < 3:
            continue
        others = {k: v for k, v in study.finest().items() if k != parameter.key}
        line = [r for r in rows if all(r["parameters"][k] == v for k, v in others.items())]
        for m in study.measures:
            # The finest run is left out where it is the reference (its error is 0 by definition).
            fit = [r for r in line if not (r["finest"] and m.reference == "finest")]
            order = observed_order([float(r["parameters"][parameter.key]) for r in fit],
                                   [r["errors"].get(m.name) for r in fit])
            if order is not None:
                orders[(parameter.key, m.name)] = order
    findings = []  # the references and the orders: in study.md, and on the terminal
    for m in study.measures:
        ref = getattr(m, "reference_value", None)
        what = "the finest run" if m.reference == "finest" else "given"
        findings.append(f"**{m.name}**{f' ({m.unit})' if m.unit else ''}: reference {format_value(ref) if ref is not None else 'none'} "
                     f"({what}); error = |value - reference| / |reference|.")
    for (key, name), order in orders.items():
        findings.append(f"observed order of convergence of {name} in {key}: **{order:.2f}** (least squares of "
                        "log error against log value, the other keys at their finest)")
    lines = [f"# Study {study.name}", "",
             f"Base scene `{os.path.relpath(study.scene, root)}`; study file `{os.path.relpath(study.path, root)}`; "
             f"{len(rows)} runs, {study.threads_per_run} thread(s) each.", ""] + ["- " + f for f in findings]
    lines += ["", "Sorted by wall time; ★: Pareto-optimal for that measure (no run is both cheaper and more "
              "accurate).", ""]
    fronts = {}
    for m in study.measures:
        usable = [k for k, r in enumerate(rows) if is_number(r["wall_s"]) and r["errors"].get(m.name) is not None]
        front = pareto_front([(rows[k]["wall_s"], rows[k]["errors"][m.name]) for k in usable])
        fronts[m.name] = {usable[k] for k in front}
    head = "| run | " + " | ".join(keys) + " | wall, s | CPU, s | steps | " + " | ".join(
        f"{m.name}{f' ({m.unit})' if m.unit else ''} | error" for m in study.measures) + " |"
    lines += [head, "|" + "---|" * (head.count("|") - 1)]
    order_rows = sorted(range(len(rows)), key=lambda k: (rows[k]["wall_s"] is None, rows[k]["wall_s"] or 0))
    for k in order_rows:
        row = rows[k]
        cells = [row["run"] + ("" if row["status"].startswith("completed") else f" ({row['status']})")]
        cells += [format_value(row["parameters"][key]) for key in keys]
        cells += [_cell(row["wall_s"], ".1f"), _cell(row["cpu_s"], ".1f"), _cell(row["steps"])]
        for m in study.measures:
            error = row["errors"].get(m.name)
            mark = " ★" if k in fronts[m.name] else ""
            cells += [_cell(row["values"].get(m.name), ".5g"),
                      (f"{100 * error:.3g} %" if error is not None else "") + mark]
        lines.append("| " + " | ".join(cells) + " |")
    problems = [f"- {row['run']}: {p}" for row in rows for p in row["problems"]]
    if problems:
        lines += ["", "Measures that could not be read:", ""] + problems
    with open(os.path.join(out, "study.md"), "w", encoding="utf-8") as handle:
        handle.write("\n".join(lines) + "\n")
    with open(os.path.join(out, "study.json"), "w", encoding="utf-8") as handle:
        json.dump({"name": study.name, "parameters": keys,
                   "measures": [{"name": m.name, "unit": m.unit, "reference": getattr(m, "reference_value", None),
                                 "reference_is_finest": m.reference == "finest"} for m in study.measures],
                   "orders": [{"parameter": k, "measure": n, "order": o} for (k, n), o in orders.items()],
                   "pareto": {name: [rows[k]["run"] for k in sorted(front, key=lambda k: rows[k]["wall_s"])]
                              for name, front in fronts.items()},
                   "runs": rows}, handle, indent=1, default=str)
    for finding in findings:
        print("  " + finding)
    _plot(root, out)


def _cell(value: Any, spec: str = "g") -> str:
    """`spec` "r": every digit (study.csv), else a format spec (study.md)."""
    if value is None:
        return ""
    if not is_number(value):
        return str(value)
    return repr(value) if spec == "r" else format(value, spec)


def _plot(root: str, out: str) -> None:
    python = os.environ.get("SABO_PLOT_PYTHON") or "/usr/bin/python3"
    try:
        result = subprocess.run([python, os.path.join(root, PLOT_SCRIPT), out], stdin=subprocess.DEVNULL,
                                stdout=subprocess.PIPE, stderr=subprocess.STDOUT, universal_newlines=True,
                                timeout=300)
    except (OSError, subprocess.TimeoutExpired) as error:
        print(f"sabo: warning: no plots ({error}); install python3-matplotlib and run {PLOT_SCRIPT} {out}")
        return
    for line in result.stdout.strip().splitlines():
        print(line)
