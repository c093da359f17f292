"""Shared helpers of the end-to-end tests: run `./sabo`, wait for events, find leftover processes."""
import csv
import filecmp
import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
import tomllib
import unittest

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))
SABO = os.path.join(ROOT, "sabo")
FAKES = os.path.join(HERE, "fakes")
BUILD_DIR = os.path.abspath(os.environ.get("SABO_BUILD_DIR") or os.path.join(ROOT, "build"))
# scene_variant()'s replace and append that give configs/tests/sph_boulders_tank.toml penalty walls (a stiffness
# that keeps their contact step, 0.4 ms, above the fluid's): the boulders then place the only wall particles,
# which the coupler sends before the fluid's state is in (docs/protocol.md, "Walls ahead").
TANK_PENALTY_WALLS = {"replace": [('wall_model = "boundary_particles"', 'wall_model = "penalty"')],
                      "append": "\n[contact.sph_fem]\nnormal_stiffness = 1e4\n"}


# Martin & Moyce 1952, n^2 = 2: the dam-break front Z = z / a at T = t sqrt(2 g / a) (docs/benchmarks.md S1).
S1_T = [0.41, 0.84, 1.19, 1.43, 1.63, 1.83, 1.98, 2.20, 2.32, 2.51, 2.65, 2.83, 2.98, 3.11, 3.33]
S1_Z = [1.11, 1.22, 1.44, 1.67, 1.89, 2.11, 2.33, 2.56, 2.78, 3.00, 3.22, 3.44, 3.67, 3.89, 4.11]


def interpolate(x, xs, ys):
    """y at x of the piecewise-linear curve (xs, ys), xs increasing; extrapolated linearly past its ends."""
    for k in range(1, len(xs)):
        if x <= xs[k]:
            return ys[k - 1] + (ys[k] - ys[k - 1]) * (x - xs[k - 1]) / (xs[k] - xs[k - 1])
    return ys[-1] + (ys[-1] - ys[-2]) * (x - xs[-1]) / (xs[-1] - xs[-2])


def read_text(path):
    with open(path, encoding="utf-8", errors="replace") as handle:
        return handle.read()


def read_json(path):
    with open(path, encoding="utf-8") as handle:
        return json.load(handle)


def load_scene(path):
    """A scene file as the TOML reader sees it."""
    with open(path, "rb") as handle:
        return tomllib.load(handle)


def read_events(run_dir):
    """The coupler events recorded by the supervisor so far (complete lines only)."""
    try:
        with open(os.path.join(run_dir, "coupler.events.jsonl"), encoding="utf-8") as handle:
            text = handle.read()
    except OSError:
        return []
    events = []
    for line in text.split("\n")[:-1]:
        try:
            events.append(json.loads(line))
        except ValueError:
            pass
    return events


def _process_state(pid):
    try:
        with open("/proc/{}/stat".format(pid), encoding="utf-8", errors="replace") as handle:
            return handle.read().rsplit(")", 1)[1].split()[0]
    except (OSError, IndexError):
        return None


def processes_in(run_dir):
    """(pid, command line) of live processes whose command line or working folder mention `run_dir`."""
    run_dir = os.path.realpath(run_dir)
    found = []
    for name in os.listdir("/proc"):
        if not name.isdigit() or int(name) == os.getpid():
            continue
        pid = int(name)
        try:
            with open("/proc/{}/cmdline".format(pid), "rb") as handle:
                command = handle.read().replace(b"\0", b" ").decode("utf-8", "replace").strip()
        except OSError:
            continue
        try:
            cwd = os.readlink("/proc/{}/cwd".format(pid))
        except OSError:
            cwd = ""
        if _process_state(pid) in (None, "Z", "X"):
            continue
        if run_dir in command or cwd == run_dir or cwd.startswith(run_dir + "/"):
            found.append((pid, command))
    return found


def pid_alive(pid):
    return _process_state(pid) not in (None, "Z", "X")


def read_csv(path):
    with open(path, newline="") as handle:
        return list(csv.DictReader(handle))


def vtp_series(run_dir, name):
    """(time, path) of each file of RUN_DIR/NAME.pvd."""
    import xml.etree.ElementTree as ET
    root = ET.parse(os.path.join(run_dir, name + ".pvd")).getroot()
    return [(float(e.get("timestep")), os.path.join(run_dir, e.get("file"))) for e in root.iter("DataSet")]


def read_vtk(path):
    """The arrays of one of Sabo's VTK XML files (appended raw data, UInt64 headers), by name ("Points" too)."""
    import re
    import numpy as np
    types = {"Float64": np.float64, "Float32": np.float32, "UInt64": np.uint64, "Int64": np.int64,
             "UInt32": np.uint32, "Int32": np.int32, "UInt8": np.uint8}
    with open(path, "rb") as handle:
        raw = handle.read()
    start = raw.index(b"<AppendedData")
    head = raw[:start].decode()
    data = raw.index(b"_", start) + 1
    arrays = {}
    pattern = r'<DataArray type="(\w+)" Name="(\w+)" NumberOfComponents="(\d+)" format="appended" offset="(\d+)"'
    for match in re.finditer(pattern, head):
        kind, name, components, offset = match.group(1), match.group(2), int(match.group(3)), int(match.group(4))
        at = data + offset
        size = int(np.frombuffer(raw[at:at + 8], np.uint64)[0])
        values = np.frombuffer(raw[at + 8:at + 8 + size], types[kind])
        arrays[name] = values.reshape(-1, components) if components > 1 else values
    return arrays


def largest_energy_rise(run_dir):
    """The largest rise of energy.csv's total less its inflow (what inflows brought in) over its first row, J,
    and that first total."""
    rows = read_csv(os.path.join(run_dir, "energy.csv"))

    def own(row):
        return float(row["total"]) - float(row.get("inflow", 0.0))
    initial = own(rows[0])
    return max(own(row) for row in rows) - initial, initial


class Sabo:
    """`./sabo ARGS` (with `raw`, the command ARGS itself) started in the background, output to files (no pipe
    to fill up)."""

    def __init__(self, args, env=None, cwd=None, work_dir=None, raw=False):
        self.work_dir = work_dir or tempfile.mkdtemp(prefix="sabo-e2e-")
        self.stdout_path = os.path.join(self.work_dir, "sabo.stdout")
        self.stderr_path = os.path.join(self.work_dir, "sabo.stderr")
        full_env = dict(os.environ)
        full_env.update(env or {})
        with open(self.stdout_path, "wb") as out, open(self.stderr_path, "wb") as err:
            self.popen = subprocess.Popen(([] if raw else [SABO]) + list(args), cwd=cwd or ROOT, env=full_env,
                                          stdin=subprocess.DEVNULL, stdout=out, stderr=err)
        self.started = time.monotonic()
        self.ended = None

    def wait(self, timeout):
        try:
            code = self.popen.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            self.popen.kill()
            self.popen.wait()
            raise AssertionError("./sabo did not exit within {} s\nstdout:\n{}\nstderr:\n{}".format(
                timeout, self.stdout, self.stderr))
        if self.ended is None:
            self.ended = time.monotonic()
        return code

    def signal(self, number):
        self.popen.send_signal(number)

    @property
    def stdout(self):
        with open(self.stdout_path, encoding="utf-8", errors="replace") as handle:
            return handle.read()

    @property
    def stderr(self):
        with open(self.stderr_path, encoding="utf-8", errors="replace") as handle:
            return handle.read()

    def output(self):
        return "stdout:\n{}\nstderr:\n{}".format(self.stdout, self.stderr)


def wait_for_events(sabo, run_dir, predicate, timeout, what):
    """Wait until predicate(events) holds; fail if ./sabo exits first or after `timeout` s."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        events = read_events(run_dir)
        if predicate(events):
            return events
        if sabo.popen.poll() is not None:
            raise AssertionError("./sabo exited with {} before {}\n{}".format(sabo.popen.returncode, what,
                                                                              sabo.output()))
        time.sleep(0.05)
    raise AssertionError("no {} within {} s\n{}".format(what, timeout, sabo.output()))


def progress_count(events):
    return sum(1 for event in events if event.get("event") == "progress")


class E2eTestCase(unittest.TestCase):
    """A temporary folder per test; kills whatever a failed test left behind."""

    def setUp(self):
        self.tmp = tempfile.mkdtemp(prefix="sabo-e2e-")
        self.started = []

    def tearDown(self):
        for sabo in self.started:
            if sabo.popen.poll() is None:
                sabo.popen.kill()
                sabo.popen.wait()
        for pid, _ in processes_in(self.tmp):
            try:
                os.kill(pid, signal.SIGKILL)
            except OSError:
                pass
        shutil.rmtree(self.tmp, ignore_errors=True)

    def sabo(self, args, env=None, cwd=None):
        sabo = Sabo(args, env=env, cwd=cwd, work_dir=self.tmp)
        self.started.append(sabo)
        return sabo

    def assertNoProcessLeft(self, run_dir, pids_file=True, wait_s=0.0):
        """No live process mentions `run_dir`, and none of the PIDs in its pids.json is alive."""
        deadline = time.monotonic() + wait_s
        while True:
            left = processes_in(run_dir)
            pids = {}
            if pids_file and os.path.exists(os.path.join(run_dir, "pids.json")):
                pids = read_json(os.path.join(run_dir, "pids.json"))
            alive = {role: pid for role, pid in pids.items() if role != "supervisor" and pid_alive(pid) and
                     any(pid == other for other, _ in left)}
            if (not left and not alive) or time.monotonic() >= deadline:
                break
            time.sleep(0.05)
        self.assertEqual(left, [], "processes left behind in {}".format(run_dir))
        self.assertEqual(alive, {}, "recorded processes still alive")


class FakeRunTestCase(E2eTestCase):
    """Runs `./sabo run --no-plots` against the fake coupler and solvers of fakes/: a temporary build folder
    whose bin/sabo_scene is fakes/sabo_scene.py, and fake scenes that say how the fakes behave."""

    def setUp(self):
        super().setUp()
        self.build_dir = os.path.join(self.tmp, "build")
        os.makedirs(os.path.join(self.build_dir, "bin"))
        checker = os.path.join(self.build_dir, "bin", "sabo_scene")
        with open(checker, "w", encoding="utf-8") as handle:
            handle.write('#!/bin/sh\nexec "{}" "{}" "$@"\n'.format(sys.executable,
                                                                  os.path.join(FAKES, "sabo_scene.py")))
        os.chmod(checker, 0o755)
        # The run's key set is made by the real tool (the fakes take --keys and ignore it).
        os.symlink(os.path.join(BUILD_DIR, "bin", "sabo_keys"), os.path.join(self.build_dir, "bin", "sabo_keys"))

    def scene(self, name="fake", **behaviour):
        """A fake scene file; `behaviour` as documented in fakes/coupler.py and fakes/solver.py."""
        path = os.path.join(self.tmp, name + ".json")
        with open(path, "w", encoding="utf-8") as handle:
            json.dump(behaviour, handle)
        return path

    def run_sabo(self, scene, out=None, env=None, extra=(), cwd=None):
        args = ["run", scene, "--no-setup", "--no-plots"] + list(extra)
        if out is not None:
            args += ["--out", out]
        full_env = {"SABO_BUILD_DIR": self.build_dir, "SABO_PLAN_OVERRIDE": "", "SABO_WATCHDOG_MIN_S": ""}
        full_env.update(env or {})
        return self.sabo(args, env=full_env, cwd=cwd)

    def out_dir(self, name="run"):
        return os.path.join(self.tmp, name)


class RealRunTestCase(E2eTestCase):
    """Runs `./sabo run --no-setup` with the built executables of BUILD_DIR (ctest builds them first);
    `plots`: draw the figures at the end (a second or two more per run; test_plot.py's concern)."""

    def run_sabo(self, scene, out, extra=(), plots=False, env=None):
        """`env`: more variables for the run (OMP_NUM_THREADS, say)."""
        full_env = {"SABO_BUILD_DIR": BUILD_DIR, "SABO_PLAN_OVERRIDE": "", "SABO_WATCHDOG_MIN_S": ""}
        full_env.update(env or {})
        args = ["run", scene, "--out", out, "--no-setup"] + ([] if plots else ["--no-plots"]) + list(extra)
        return self.sabo(args, env=full_env)

    def run_scene_text(self, text, name, timeout):
        """Writes TMP/NAME.toml with `text`, runs it into TMP/NAME and asserts the run succeeds within
        `timeout` s; returns the run folder."""
        scene = os.path.join(self.tmp, name + ".toml")
        with open(scene, "w", encoding="utf-8") as handle:
            handle.write(text)
        out = os.path.join(self.tmp, name)
        sabo = self.run_sabo(scene, out)
        self.assertEqual(sabo.wait(timeout), 0, sabo.output())
        return out

    def run_and_kill(self, scene, out, role, at_step):
        """Runs `scene`, sends SIGKILL to `role` once the coupler reports step `at_step`; returns the exit code
        and the run."""
        sabo = self.run_sabo(scene, out)
        events = os.path.join(out, "coupler.events.jsonl")
        deadline = time.monotonic() + 120
        killed = False
        while sabo.popen.poll() is None and not killed and time.monotonic() < deadline:
            try:
                with open(events, encoding="utf-8") as handle:
                    steps = [json.loads(line).get("step", 0) for line in handle if '"progress"' in line]
                if steps and steps[-1] >= at_step:
                    os.kill(read_json(os.path.join(out, "pids.json"))[role], signal.SIGKILL)
                    killed = True
            except (OSError, ValueError, KeyError):
                pass
            time.sleep(0.01)
        self.assertTrue(killed, "the run ended before step {}".format(at_step))
        return sabo.wait(180), sabo

    def replay(self, run_dir, role, extra=()):
        """`./sabo replay RUN_DIR ROLE EXTRA...`: its exit code, stdout and stderr."""
        sabo = self.sabo(["replay", run_dir, role, "--no-setup"] + list(extra),
                         env={"SABO_BUILD_DIR": BUILD_DIR, "SABO_PLAN_OVERRIDE": ""})
        code = sabo.wait(120)
        return code, sabo.stdout, sabo.stderr

    def scene_variant(self, source, name, replace=(), append=""):
        """TMP/NAME.toml: the repository's scene `source` with each (old, new) of `replace` done once (old must
        be there) and `append` added at the end."""
        with open(self.scene_path(source), encoding="utf-8") as handle:
            text = handle.read()
        for old, new in replace:
            self.assertIn(old, text)
            text = text.replace(old, new, 1)
        path = os.path.join(self.tmp, name + ".toml")
        with open(path, "w", encoding="utf-8") as handle:
            handle.write(text + append)
        return path

    def scene_path(self, relative):
        path = os.path.join(ROOT, relative)
        self.assertTrue(os.path.isfile(path), "missing test scene {}".format(relative))
        return path

    def assertSameRunOutputs(self, reference, run, files=None, expected=()):
        """The files `files` of two run folders (None: every .csv and .pvd of `reference`, among them
        `expected`) and every frame of their dem/, sph/ and fem/ (those `reference` has) are the same bits."""
        names = list(files) if files is not None else sorted(
            name for name in os.listdir(reference) if name.endswith((".csv", ".pvd")))
        for name in expected:
            self.assertIn(name, names)
        for name in names:
            self.assertTrue(filecmp.cmp(os.path.join(reference, name), os.path.join(run, name), shallow=False),
                            "{} differs from {}".format(os.path.join(run, name), os.path.join(reference, name)))
        for folder in ("dem", "sph", "fem"):
            if not os.path.isdir(os.path.join(reference, folder)):
                continue
            frames = sorted(os.listdir(os.path.join(reference, folder)))
            self.assertEqual(frames, sorted(os.listdir(os.path.join(run, folder))), folder)
            _, mismatch, errors = filecmp.cmpfiles(os.path.join(reference, folder), os.path.join(run, folder), frames,
                                                   shallow=False)
            self.assertEqual(mismatch + errors, [], "{}/ frames differ".format(folder))

    def assertTrafficReadable(self, run_dir, roles):
        """traffic.h5 opens (as after a crash: SWMR) and has recorded steps both ways for each solver role
        (layout: docs/traffic.md, /<role>/state/step and /<role>/forces/step)."""
        import h5py  # Debian's python3-h5py; imported here so that the fake-based tests do not need it
        path = os.path.join(run_dir, "traffic.h5")
        self.assertTrue(os.path.isfile(path), "no traffic.h5 in " + run_dir)
        try:
            traffic = h5py.File(path, "r", swmr=True)
        except (OSError, ValueError):
            traffic = h5py.File(path, "r")
        with traffic:
            for role in roles:
                for direction in ("state", "forces"):
                    name = "{}/{}/step".format(role, direction)
                    self.assertIn(name, traffic, "traffic.h5 has no " + name)
                    steps = traffic[name][()]
                    print("traffic.h5: {} holds {} recorded steps".format(name, len(steps)))
                    self.assertGreater(len(steps), 0, name)

    def assertTrafficHoldsEveryStepUpTo(self, run_dir, progress_steps):
        """Every step from 0 is recorded, without gaps, at least up to the step of the last-but-one
        progress event (progress events come every 0.5 s, traffic.h5 is flushed every 0.2 s, so
        that step was on disk before any failure that came after the last event)."""
        import h5py
        self.assertGreaterEqual(len(progress_steps), 2)
        with h5py.File(os.path.join(run_dir, "traffic.h5"), "r", swmr=True) as traffic:
            for role in self.solver_roles(run_dir):
                steps = traffic["{}/state/step".format(role)][()]
                print("traffic.h5: {} states recorded for steps 0..{}; progress reported step {}".format(
                    role, steps[-1], progress_steps[-1]))
                self.assertEqual(list(steps), list(range(len(steps))), "recorded steps have gaps")
                self.assertGreaterEqual(steps[-1], progress_steps[-2])

    def solver_roles(self, run_dir):
        pids = read_json(os.path.join(run_dir, "pids.json"))
        return sorted(role for role in pids if role not in ("supervisor", "coupler"))
