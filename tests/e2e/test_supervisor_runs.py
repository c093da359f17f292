"""`./sabo run` against fake processes: runs that complete, input errors, run folders, endpoints."""
import json
import os
import pty
import re
import select
import subprocess
import time
import unittest

from e2e_support import SABO, FakeRunTestCase, read_events, read_json, read_text


class CompletedRunTest(FakeRunTestCase):
    def test_completed_run_reports_and_cleans_up(self):
        out = self.out_dir()
        sabo = self.run_sabo(self.scene(steps=30, step_seconds=0.05), out=out)
        self.assertEqual(sabo.wait(30), 0, sabo.output())

        pids = read_json(os.path.join(out, "pids.json"))
        self.assertEqual(sorted(pids), ["coupler", "dem_solver", "fem_solver", "supervisor"])
        self.assertEqual(pids["supervisor"], sabo.popen.pid)
        self.assertEqual(read_json(os.path.join(out, "summary.json"))["status"], "completed")
        for role in ("dem_solver", "fem_solver"):  # the solvers were stopped through the protocol
            self.assertTrue(os.path.exists(os.path.join(out, role + ".out")), role)
            self.assertIn("connecting to ipc://" + out + "/coupler.sock", read_text(os.path.join(out, role + ".log")))
        self.assertIn("fake coupler starting", read_text(os.path.join(out, "coupler.log")))
        kinds = [event["event"] for event in read_events(out)]
        self.assertEqual(kinds[:3], ["listening", "registered", "registered"])
        self.assertEqual(kinds[-1], "done")
        self.assertEqual(kinds.count("progress"), 30)
        self.assertFalse(os.path.exists(os.path.join(out, "coupler.sock")), "the socket is removed")

        stdout = sabo.stdout
        self.assertIn("sabo: run completed", stdout)
        self.assertIn("step 30  t = 1.00 / 1.00 s  dt = 3.3e-02 s", stdout)
        self.assertIn("run folder:  " + out, stdout)
        self.assertIn("summary.json", stdout)
        # Not a TTY: a progress line every few seconds, not one per event.
        progress_lines = [line for line in stdout.splitlines() if line.startswith("step ")]
        self.assertLessEqual(len(progress_lines), 2, stdout)
        self.assertEqual(sabo.stderr, "")
        self.assertNoProcessLeft(out)

    def test_quiet_run_prints_only_the_summary(self):
        out = self.out_dir()
        sabo = self.run_sabo(self.scene(steps=5, step_seconds=0.01), out=out, extra=["--quiet"])
        self.assertEqual(sabo.wait(30), 0, sabo.output())
        self.assertTrue(sabo.stdout.startswith("sabo: run completed"), sabo.stdout)

    def test_progress_line_is_redrawn_on_a_tty(self):
        out = self.out_dir()
        scene = self.scene(steps=20, step_seconds=0.02)
        master, slave = pty.openpty()
        env = dict(os.environ, SABO_BUILD_DIR=self.build_dir, SABO_PLAN_OVERRIDE="")
        process = subprocess.Popen([SABO, "run", scene, "--no-setup", "--out", out], stdin=subprocess.DEVNULL,
                                   stdout=slave, stderr=slave, env=env)
        os.close(slave)
        output = b""
        deadline = time.monotonic() + 30
        while time.monotonic() < deadline:
            ready, _, _ = select.select([master], [], [], 0.2)
            if ready:
                try:
                    data = os.read(master, 65536)
                except OSError:  # EIO: the other side is closed
                    break
                if not data:
                    break
                output += data
            elif process.poll() is not None:
                break
        os.close(master)
        self.assertEqual(process.wait(10), 0, output)
        text = output.decode()
        redraws = re.findall(r"\rstep \d+  t = ", text)
        self.assertGreaterEqual(len(redraws), 10, text)  # every event redraws the line in place
        self.assertIn("sabo: run completed", text)
        self.assertNoProcessLeft(out)


class RunFolderTest(FakeRunTestCase):
    def test_used_run_folder_is_refused_and_left_untouched(self):
        out = self.out_dir()
        os.makedirs(out)
        with open(os.path.join(out, "keep.txt"), "w") as handle:
            handle.write("previous results\n")
        sabo = self.run_sabo(self.scene(), out=out)
        self.assertEqual(sabo.wait(30), 2, sabo.output())
        self.assertIn("--out " + out, sabo.stderr)
        self.assertIn("not empty", sabo.stderr)
        self.assertIn("nothing was overwritten", sabo.stderr)
        self.assertEqual(os.listdir(out), ["keep.txt"])
        self.assertEqual(read_text(os.path.join(out, "keep.txt")), "previous results\n")

    def test_a_file_as_run_folder_is_refused(self):
        out = self.out_dir()
        with open(out, "w") as handle:
            handle.write("x")
        sabo = self.run_sabo(self.scene(), out=out)
        self.assertEqual(sabo.wait(30), 2, sabo.output())
        self.assertIn("is not a folder", sabo.stderr)

    def test_empty_run_folder_is_used(self):
        out = self.out_dir()
        os.makedirs(out)
        sabo = self.run_sabo(self.scene(steps=3, step_seconds=0.01), out=out)
        self.assertEqual(sabo.wait(30), 0, sabo.output())
        self.assertTrue(os.path.exists(os.path.join(out, "summary.json")))

    def test_default_run_folder_is_named_after_scene_and_time(self):
        scene = self.scene("drop_test", steps=3, step_seconds=0.01)
        first = self.run_sabo(scene, cwd=self.tmp)
        second = self.run_sabo(scene, cwd=self.tmp)  # same second: must not collide
        self.assertEqual(first.wait(30), 0, first.output())
        self.assertEqual(second.wait(30), 0, second.output())
        folders = sorted(os.listdir(os.path.join(self.tmp, "runs")))
        self.assertEqual(len(folders), 2, folders)
        for folder in folders:
            self.assertRegex(folder, r"^drop_test-\d{8}-\d{6}(-\d+)?$")
            self.assertTrue(os.path.exists(os.path.join(self.tmp, "runs", folder, "summary.json")))

    def test_long_run_folder_path_gets_a_short_socket(self):
        out = os.path.join(self.tmp, "a_rather_long_folder_name_" * 4, "run")
        sabo = self.run_sabo(self.scene(steps=5, step_seconds=0.01), out=out)
        self.assertEqual(sabo.wait(30), 0, sabo.output())
        endpoint = read_events(out)[0]["endpoint"]
        self.assertRegex(endpoint, r"^ipc:///tmp/sabo-[^/]+/coupler\.sock$")
        self.assertFalse(os.path.exists(os.path.dirname(endpoint[len("ipc://"):])), "the socket folder is removed")

    def test_tcp_endpoint_passes_through(self):
        out = self.out_dir()
        sabo = self.run_sabo(self.scene(steps=5, step_seconds=0.01, endpoint="tcp://127.0.0.1:0"), out=out)
        self.assertEqual(sabo.wait(30), 0, sabo.output())
        endpoint = read_events(out)[0]["endpoint"]  # the coupler reports the port it got
        self.assertRegex(endpoint, r"^tcp://127\.0\.0\.1:[1-9]\d*$")
        self.assertIn("connecting to " + endpoint, read_text(os.path.join(out, "dem_solver.log")))


class InputErrorTest(FakeRunTestCase):
    def test_scene_errors_are_printed_and_nothing_starts(self):
        out = self.out_dir()
        scene = self.scene("broken", errors=["line 4: key 'run.end_time': must be > 0, got -1"])
        sabo = self.run_sabo(scene, out=out)
        self.assertEqual(sabo.wait(30), 2, sabo.output())
        self.assertIn(scene + ": line 4: key 'run.end_time': must be > 0, got -1", sabo.stderr)
        self.assertIn("nothing was started", sabo.stderr)
        self.assertFalse(os.path.exists(out), "no run folder for a bad scene")

    def test_missing_scene_file(self):
        sabo = self.run_sabo(os.path.join(self.tmp, "nowhere.toml"), out=self.out_dir())
        self.assertEqual(sabo.wait(30), 2, sabo.output())
        self.assertIn("scene file not found", sabo.stderr)
        self.assertIn("nowhere.toml", sabo.stderr)

    def test_coupler_rejecting_the_input_exits_2(self):
        out = self.out_dir()
        sabo = self.run_sabo(self.scene(coupler={"exit_at_step": [0, 2]}), out=out)
        self.assertEqual(sabo.wait(30), 2, sabo.output())
        self.assertIn("the coupler rejected the input (exit code 2)", sabo.stderr)
        self.assertNoProcessLeft(out)

    def test_missing_solver_program_is_reported(self):
        out = self.out_dir()
        scene = self.scene(steps=50, commands={"fem_solver": ["/nonexistent/fem_solver"]})
        sabo = self.run_sabo(scene, out=out)
        self.assertEqual(sabo.wait(30), 1, sabo.output())
        self.assertIn("could not start fem_solver: /nonexistent/fem_solver: No such file or directory", sabo.stderr)
        self.assertNoProcessLeft(out)

    def test_plan_override_replaces_the_scene_check(self):
        out = self.out_dir()
        scene = self.scene(steps=3, step_seconds=0.01)
        plan = subprocess.run([os.path.join(self.build_dir, "bin", "sabo_scene"), "check", scene, "--bin-dir", "x"],
                              stdout=subprocess.PIPE, check=True).stdout
        plan_path = os.path.join(self.tmp, "plan.json")
        with open(plan_path, "wb") as handle:
            handle.write(plan)
        os.remove(os.path.join(self.build_dir, "bin", "sabo_scene"))
        sabo = self.run_sabo(scene, out=out, env={"SABO_PLAN_OVERRIDE": plan_path})
        self.assertEqual(sabo.wait(30), 0, sabo.output())

    def test_invalid_plan_is_reported(self):
        plan_path = os.path.join(self.tmp, "plan.json")
        with open(plan_path, "w") as handle:
            json.dump({"end_time": 1, "output_interval": 0.1, "hang_timeout": 1, "endpoint": "ipc",
                       "processes": [{"role": "dem_solver", "command": ["x"]}]}, handle)
        sabo = self.run_sabo(self.scene(), out=self.out_dir(), env={"SABO_PLAN_OVERRIDE": plan_path})
        self.assertEqual(sabo.wait(30), 1, sabo.output())
        self.assertIn("exactly one process with role \"coupler\"", sabo.stderr)

    def test_wrong_command_line(self):
        for args, message in ((["run"], "required: SCENE"), (["fly"], "invalid choice: 'fly'"),
                              (["run", "x.toml", "--outt", "y"], "unrecognized arguments: --outt")):
            with self.subTest(args=args):
                sabo = self.sabo(args)
                self.assertEqual(sabo.wait(30), 2, sabo.output())
                self.assertIn(message, sabo.stderr)


if __name__ == "__main__":
    unittest.main()
