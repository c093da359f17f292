"""Resuming a run (issue 19, part 3): the coupler's own checkpoint, `./sabo resume RUN_DIR` after the supervisor
and every process were killed, and the restart of a killed coupler. Each continued run's outputs (forces.csv,
energy.csv, gauges.csv and sensors.csv where the scene has them, the .pvd series, every .vtp frame) are byte for byte those of an uninterrupted run, and its
traffic.h5 holds the same messages (the processes' timings and registrations, which name their pids, aside).

The boulder tank (water, two boulders as boundary particles, the tank's walls; 751 steps, a checkpoint every
0.03 s) is killed at seeded random steps; the breaking block (FEM erosion: the surface changes before the
checkpoint) is resumed from a copy of a completed run's folder."""
import json
import os
import random
import shutil
import signal
import time

from e2e_support import BUILD_DIR, RealRunTestCase, read_json

TANK = "configs/tests/sph_boulders_tank.toml"
BLOCK = "configs/tests/sphere_breaks_block.toml"
# Gauges (sph_solver: gauges.csv) and sensors (coupler: sensors.csv) in the tank: their files are checkpointed
# with their writers and cut back on a resume, so they too come out byte for byte.
INSTRUMENTS = """
[[gauges]]
name = "column"
kind = "line"
start = [0.15, 0.05, 0.0]
end = [0.15, 0.05, 0.15]
points = 6
interval = 0.005

[[gauges]]
name = "corner"
kind = "point"
position = [0.05, 0.25, 0.03]

[[sensors]]
name = "wall_x0"
part = "wall_x0"

[[sensors]]
name = "floor_pad"
part = "floor"
min = [0.1, 0.1, -0.001]
max = [0.2, 0.2, 0.001]
"""


class ResumeTestCase(RealRunTestCase):
    def write_scene(self, relative, name, extra_run_lines="", extra_tables=""):
        with open(self.scene_path(relative), encoding="utf-8") as handle:
            text = handle.read()
        self.assertIn("[run]\n", text)
        text = text.replace("[run]\n", "[run]\n" + extra_run_lines + "\n", 1) + extra_tables
        scene = os.path.join(self.tmp, name + ".toml")
        with open(scene, "w", encoding="utf-8") as handle:
            handle.write(text)
        return scene

    def resume(self, run_dir):
        env = {"SABO_BUILD_DIR": BUILD_DIR, "SABO_PLAN_OVERRIDE": "", "SABO_WATCHDOG_MIN_S": ""}
        return self.sabo(["resume", run_dir, "--no-setup", "--no-plots"], env=env)

    def kill_at(self, scene, out, roles, at_step):
        """Runs `scene`; once the coupler reports step `at_step`, SIGKILL to `roles` (of pids.json; "all": the
        supervisor and every process). Returns the ./sabo process."""
        sabo = self.run_sabo(scene, out)
        events = os.path.join(out, "coupler.events.jsonl")
        deadline = time.monotonic() + 120
        while sabo.popen.poll() is None and time.monotonic() < deadline:
            try:
                with open(events, encoding="utf-8") as handle:
                    steps = [json.loads(line).get("step", 0) for line in handle if '"progress"' in line]
                if steps and steps[-1] >= at_step:
                    pids = read_json(os.path.join(out, "pids.json"))
                    for role in (pids if roles == "all" else roles):
                        os.kill(pids[role], signal.SIGKILL)
                    return sabo, steps[-1]
            except (OSError, ValueError, KeyError):
                pass
            time.sleep(0.01)
        self.fail("the run ended before step {}".format(at_step))

    def assertSameOutputs(self, reference, run, expected=("forces.csv",)):
        self.assertSameRunOutputs(reference, run, expected=expected)
    def assertSameTraffic(self, reference, run):
        import h5py
        import numpy
        compared = []

        def walk(expected, actual, path):
            for name in expected:
                if name == "timing" or name.startswith("registration"):
                    continue
                self.assertIn(name, actual, "{}/{} is missing".format(path, name))
                if isinstance(expected[name], h5py.Group):
                    walk(expected[name], actual[name], path + "/" + name)
                    continue
                a, b = expected[name][()], actual[name][()]
                self.assertTrue(a.shape == b.shape and numpy.array_equal(a, b),
                                "traffic.h5 {}/{} differs from the uninterrupted run's".format(path, name))
                compared.append(name)

        with h5py.File(os.path.join(reference, "traffic.h5"), "r", swmr=True) as expected, \
                h5py.File(os.path.join(run, "traffic.h5"), "r", swmr=True) as actual:
            walk(expected, actual, "")
        print("traffic.h5: {} datasets identical".format(len(compared)))
        self.assertGreater(len(compared), 50)

    def reference_run(self, scene):
        reference = os.path.join(self.tmp, "reference")
        sabo = self.run_sabo(scene, reference)
        self.assertEqual(sabo.wait(180), 0, sabo.output())
        return reference, read_json(os.path.join(reference, "summary.json"))["steps"]


class ResumeAfterAKillTest(ResumeTestCase):
    def test_a_run_killed_with_its_supervisor_resumes_with_the_same_bits(self):
        scene = self.write_scene(TANK, "tank", "checkpoint_interval = 0.03", INSTRUMENTS)
        reference, steps = self.reference_run(scene)
        randomness = random.Random(1919)
        for trial in range(2):
            out = os.path.join(self.tmp, "killed-{}".format(trial))
            sabo, at_step = self.kill_at(scene, out, "all", randomness.randrange(150, steps - 200))
            sabo.wait(30)
            self.assertNoProcessLeft(out, wait_s=5)
            self.assertFalse(os.path.exists(os.path.join(out, "summary.json")))
            # The processes may step on between the progress event seen and the kill landing: what bounds the
            # resume is the checkpoints the coupler left.
            checkpoints = sorted(int(name[len("coupler_"):-len(".h5")])
                                 for name in os.listdir(os.path.join(out, "checkpoints"))
                                 if name.startswith("coupler_") and name.endswith(".h5"))
            resumed = self.resume(out)
            code = resumed.wait(180)
            summary = read_json(os.path.join(out, "summary.json"))
            print("trial {}: killed once step {} was reported, the coupler's checkpoints at steps {}, resumed: {}".format(
                trial, at_step, checkpoints, summary["resumes"]))
            self.assertEqual(code, 0, resumed.output())
            self.assertEqual(summary["status"], "completed")
            self.assertEqual(summary["steps"], steps)
            self.assertEqual(len(summary["resumes"]), 1)
            from_step = summary["resumes"][0]["from_step"]
            self.assertIn(from_step, checkpoints)
            self.assertIn("resuming {} at step {}".format(out, from_step), resumed.output())
            self.assertSameOutputs(reference, out, ("forces.csv", "gauges.csv", "sensors.csv"))
            self.assertSameTraffic(reference, out)
            self.assertNoProcessLeft(out)

    def test_an_eroded_structure_resumes_with_the_same_bits(self):
        # The block loses elements at t < 0.01 s; the newest checkpoint is at 0.027 s. A completed run's folder
        # without its summary is what a run killed after that checkpoint leaves (the later rows are cut).
        scene = self.write_scene(BLOCK, "block")
        reference, steps = self.reference_run(scene)
        history = read_json(os.path.join(reference, "summary.json"))["energies"]["structures"]["block"]["history"]
        self.assertGreater(history["eroded_elements"][1], 0)
        out = os.path.join(self.tmp, "copy")
        shutil.copytree(reference, out)
        os.unlink(os.path.join(out, "summary.json"))
        resumed = self.resume(out)
        self.assertEqual(resumed.wait(120), 0, resumed.output())
        summary = read_json(os.path.join(out, "summary.json"))
        print("resumed: {}".format(summary["resumes"]))
        self.assertEqual(summary["resumes"][0]["from_step"], 540)
        self.assertSameOutputs(reference, out)
        self.assertSameTraffic(reference, out)

    def test_what_cannot_be_resumed_is_refused_and_left_as_it_was(self):
        scene = self.write_scene(TANK, "tank", "checkpoint_interval = 0.03")
        completed = os.path.join(self.tmp, "completed")
        sabo = self.run_sabo(scene, completed)
        self.assertEqual(sabo.wait(180), 0, sabo.output())
        refused = self.resume(completed)
        self.assertEqual(refused.wait(30), 2)
        self.assertIn("the run completed: nothing to resume", refused.output())

        not_a_run = os.path.join(self.tmp, "empty")
        os.makedirs(not_a_run)
        refused = self.resume(not_a_run)
        self.assertEqual(refused.wait(30), 2)
        self.assertIn("not a run folder", refused.output())

        # Killed before its first checkpoint.
        early = os.path.join(self.tmp, "early")
        sabo, _ = self.kill_at(self.write_scene(TANK, "late_checkpoints", "checkpoint_interval = 0.25"), early, "all",
                               1)
        sabo.wait(30)
        refused = self.resume(early)
        self.assertEqual(refused.wait(30), 2)
        self.assertIn("no step that every process (coupler, sph_solver, dem_solver, fem_solver) has a checkpoint of",
                      refused.output())

        # The scene changed since: the coupler refuses its checkpoint before anything is started or cut.
        killed = os.path.join(self.tmp, "killed")
        sabo, _ = self.kill_at(scene, killed, "all", 400)
        sabo.wait(30)
        forces = open(os.path.join(killed, "forces.csv"), encoding="utf-8").read()
        with open(scene, "a", encoding="utf-8") as handle:
            handle.write("# edited after the run\n")
        refused = self.resume(killed)
        self.assertEqual(refused.wait(60), 2, refused.output())
        print(refused.output()[-600:])
        self.assertIn("a checkpoint of another scene", refused.output())
        self.assertEqual(open(os.path.join(killed, "forces.csv"), encoding="utf-8").read(), forces)
        self.assertFalse(os.path.exists(os.path.join(killed, "summary.json")))
        self.assertNoProcessLeft(killed)


class CouplerRestartTest(ResumeTestCase):
    def test_a_killed_coupler_is_restarted_and_the_run_is_unchanged(self):
        scene = self.write_scene(TANK, "tank", "checkpoint_interval = 0.03", INSTRUMENTS)
        reference, steps = self.reference_run(scene)
        randomness = random.Random(2019)
        for trial in range(3):
            out = os.path.join(self.tmp, "coupler-{}".format(trial))
            sabo, at_step = self.kill_at(scene, out, ["coupler"], randomness.randrange(150, steps - 200))
            code = sabo.wait(180)
            summary = read_json(os.path.join(out, "summary.json"))
            print("trial {}: coupler killed at step {}: exit {}, {}".format(trial, at_step, code, summary["resumes"]))
            self.assertEqual(code, 0, sabo.output())
            self.assertEqual(summary["status"], "completed")
            self.assertEqual(len(summary["resumes"]), 1)
            resume = summary["resumes"][0]
            self.assertIn("coupler (pid", resume["reason"])
            self.assertIn("killed by SIGKILL", resume["reason"])
            self.assertIn("resuming every process from their checkpoints of step {}".format(resume["from_step"]),
                          sabo.output())
            self.assertSameOutputs(reference, out, ("forces.csv", "gauges.csv", "sensors.csv"))
            self.assertSameTraffic(reference, out)
            self.assertNoProcessLeft(out)

    def test_with_restart_off_a_killed_coupler_stops_the_run(self):
        scene = self.write_scene(TANK, "tank_off", 'checkpoint_interval = 0.03\nrestart = "off"')
        out = os.path.join(self.tmp, "off")
        sabo, _ = self.kill_at(scene, out, ["coupler"], 300)
        self.assertNotEqual(sabo.wait(60), 0)
        self.assertIn("coupler", sabo.output())
        self.assertNotIn("resuming every process", sabo.output())
        self.assertNoProcessLeft(out)
