"""Checkpoints (issue 19, part 2): a three-solver run (water, two boulders as SPH boundary particles, the tank's
walls) with [run] checkpoint_interval writes every process's checkpoint at the same steps and keeps the newest
two; each solver started from its checkpoint and fed the recorded StepForces from there (`./sabo replay --resume`,
what the coupler's catch-up after a restart does) sends the recorded states to the bit; a checkpoint of another
role, of another scene or a damaged file is refused before the solver starts, with exit status 2, and through
`./sabo replay` the refusal is reported within seconds."""
import json
import os
import re
import shutil
import subprocess
import time

from e2e_support import BUILD_DIR, RealRunTestCase

TANK = "configs/tests/sph_boulders_tank.toml"
ROLES = {"sph": "sph_solver", "dem": "dem_solver", "fem": "fem_solver"}


class CheckpointTest(RealRunTestCase):
    def setUp(self):
        super().setUp()
        with open(self.scene_path(TANK), encoding="utf-8") as handle:
            text = handle.read()
        self.assertIn("end_time = 0.3", text)
        self.assertIn('fields = ["position", "velocity", "force", "torque", "energies"]', text)
        text = text.replace("end_time = 0.3", "end_time = 0.04\ncheckpoint_interval = 0.01")
        text = text.replace('fields = ["position", "velocity", "force", "torque", "energies"]', "")
        self.scene = os.path.join(self.tmp, "tank.toml")
        with open(self.scene, "w", encoding="utf-8") as handle:
            handle.write(text)
        self.run_dir = os.path.join(self.tmp, "run")
        sabo = self.run_sabo(self.scene, self.run_dir)
        self.assertEqual(sabo.wait(120), 0, sabo.output())

    def checkpoints(self):
        """{role: [steps]} of RUN_DIR/checkpoints."""
        found = {}
        for name in sorted(os.listdir(os.path.join(self.run_dir, "checkpoints"))):
            match = re.fullmatch(r"([a-z]+_solver|coupler)_([0-9]{10})\.h5", name)
            self.assertIsNotNone(match, "unexpected file in checkpoints/: " + name)
            found.setdefault(match.group(1), []).append(int(match.group(2)))
        return found

    def checkpoint(self, role, step):
        return os.path.join(self.run_dir, "checkpoints", "{}_{:010d}.h5".format(role, step))

    def test_every_solver_resumes_from_its_checkpoint_with_the_same_bits(self):
        found = self.checkpoints()
        print("checkpoints kept:", found)
        self.assertEqual(sorted(found), sorted(list(ROLES.values()) + ["coupler"]))
        steps = found["dem_solver"]
        self.assertEqual(len(steps), 2, "checkpoints_kept = 2 (the default)")
        for role in list(ROLES.values()) + ["coupler"]:
            self.assertEqual(found[role], steps, "every process checkpoints at the same steps")
        with open(os.path.join(self.run_dir, "summary.json"), encoding="utf-8") as handle:
            summary = json.load(handle)
        print("summary checkpoints:", summary["checkpoints"])
        self.assertEqual(summary["checkpoints"]["interval"], 0.01)
        self.assertEqual(summary["checkpoints"]["written"], 3)  # t = 0.01, 0.02, 0.03 s (none at the end)
        env = {"SABO_BUILD_DIR": BUILD_DIR, "SABO_PLAN_OVERRIDE": ""}
        for short, role in ROLES.items():
            sabo = self.sabo(["replay", self.run_dir, short, "--no-setup", "--resume", self.checkpoint(role, steps[0])],
                             env=env)
            code = sabo.wait(120)
            first = sabo.stdout.splitlines()[0] if sabo.stdout else sabo.stderr
            print("{} resumed at step {}: exit {}; {}".format(role, steps[0], code, first))
            self.assertEqual(code, 0, sabo.stdout + sabo.stderr)
            replayed = int(re.search(r"every field matches over (\d+) steps", sabo.stdout).group(1))
            self.assertEqual(replayed, 85 - steps[0], "the recording from the checkpoint's step to the end")
        self.assertNoProcessLeft(self.run_dir, pids_file=False)

    def start_resumed(self, role, checkpoint, scene=None):
        """The solver started on its own with --resume; it must refuse before it needs a coupler."""
        command = [os.path.join(BUILD_DIR, "bin", role), "--scene", scene or self.scene, "--coupler",
                   "ipc://" + os.path.join(self.tmp, "nobody.sock"), "--out", os.path.join(self.tmp, "out"),
                   "--resume", checkpoint]
        return subprocess.run(command, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                              universal_newlines=True, timeout=60)

    def test_a_checkpoint_that_does_not_fit_is_refused_with_exit_status_2(self):
        step = self.checkpoints()["dem_solver"][0]
        damaged = os.path.join(self.tmp, "damaged.h5")
        with open(self.checkpoint("fem_solver", step), "rb") as source, open(damaged, "wb") as out:
            out.write(source.read(2000))
        other_scene = os.path.join(self.tmp, "other.toml")
        shutil.copy(self.scene, other_scene)
        with open(other_scene, "a", encoding="utf-8") as handle:
            handle.write("# a changed scene\n")
        cases = [
            ("fem_solver", self.checkpoint("dem_solver", step), None, "a checkpoint of dem_solver, not of fem_solver"),
            ("dem_solver", self.checkpoint("dem_solver", step), other_scene, "a checkpoint of another scene"),
            ("fem_solver", damaged, None, "not a Sabo checkpoint: it does not open as HDF5"),
            ("sph_solver", os.path.join(self.tmp, "missing.h5"), None, "no such checkpoint file"),
        ]
        for role, checkpoint, scene, expected in cases:
            result = self.start_resumed(role, checkpoint, scene)
            last = result.stdout.strip().splitlines()[-1] if result.stdout.strip() else ""
            print("{} --resume {}: exit {}; {}".format(role, os.path.basename(checkpoint), result.returncode, last))
            self.assertEqual(result.returncode, 2, result.stdout)
            self.assertIn(expected, result.stdout)
            self.assertIn("Fix:" if "missing" not in checkpoint else "checkpoints", result.stdout)
        # Through `./sabo replay --resume`, the solver's refusal is reported as soon as it exits, not after the
        # replay's 60 s wait for a registration that cannot come.
        started = time.monotonic()
        sabo = self.sabo(["replay", self.run_dir, "fem", "--no-setup", "--resume", self.checkpoint("dem_solver", step)],
                         env={"SABO_BUILD_DIR": BUILD_DIR, "SABO_PLAN_OVERRIDE": ""})
        code = sabo.wait(120)
        elapsed = time.monotonic() - started
        print("replay fem --resume dem_solver's checkpoint: exit {} after {:.1f} s (expected 3 within 15 s); {}".format(
            code, elapsed, sabo.stderr.strip().splitlines()[-3:]))
        self.assertEqual(code, 3, sabo.stdout + sabo.stderr)
        self.assertLess(elapsed, 15.0)
        self.assertIn("the fem_solver exited with code 2 before the replay ended", sabo.stderr)
        self.assertIn("a checkpoint of dem_solver, not of fem_solver", sabo.stderr)
        self.assertNoProcessLeft(self.run_dir, pids_file=False)
