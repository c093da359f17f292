"""`./sabo run` against fake processes: dead, failing, hung processes are reported and everything stops."""
import os
import signal
import time
import unittest

from e2e_support import FakeRunTestCase, progress_count, read_json, wait_for_events

LONG_RUN = {"steps": 2000, "step_seconds": 0.02}  # 40 s: always stopped by the fault long before


class DeadProcessTest(FakeRunTestCase):
    def test_killed_process_is_named_with_its_signal(self):
        for role in ("coupler", "dem_solver", "fem_solver"):
            with self.subTest(role=role):
                out = self.out_dir("kill_" + role)
                sabo = self.run_sabo(self.scene(**LONG_RUN), out=out)
                wait_for_events(sabo, out, lambda events: progress_count(events) >= 3, 30, "3 progress events")
                pid = read_json(os.path.join(out, "pids.json"))[role]
                os.kill(pid, signal.SIGKILL)
                killed_at = time.monotonic()
                self.assertEqual(sabo.wait(30), 1, sabo.output())
                self.assertLess(sabo.ended - killed_at, 10.0, "seconds from the kill to the end of ./sabo")
                self.assertIn("{} (pid {}) was killed by SIGKILL".format(role, pid), sabo.stderr)
                self.assertIn("sabo: run FAILED: {} (pid {}) was killed by SIGKILL".format(role, pid), sabo.stdout)
                self.assertIn("last lines of {}/{}.log".format(out, role), sabo.stderr)
                self.assertNoProcessLeft(out)
                if role == "coupler":  # issue 18, item 5: the supervisor writes the summary the coupler could not
                    summary = read_json(os.path.join(out, "summary.json"))
                    print("kill -9 coupler: summary.json {}".format(summary))
                    self.assertEqual(summary["status"], "killed")
                    self.assertIn("coupler (pid {}) was killed by SIGKILL".format(pid), summary["failure"])
                    self.assertGreaterEqual(summary["steps"], 3)

    def test_failing_solver_is_named_with_its_exit_code_and_log(self):
        out = self.out_dir()
        sabo = self.run_sabo(self.scene(dem_solver={"exit_at_step": [5, 7]}, **LONG_RUN), out=out)
        self.assertEqual(sabo.wait(30), 1, sabo.output())
        pid = read_json(os.path.join(out, "pids.json"))["dem_solver"]
        self.assertIn("dem_solver (pid {}) exited with code 7".format(pid), sabo.stderr)
        stderr_lines = sabo.stderr.splitlines()
        tail_start = stderr_lines.index("sabo: last lines of {}/dem_solver.log:".format(out))
        tail = stderr_lines[tail_start + 1:tail_start + 11]
        self.assertEqual(len(tail), 10, sabo.stderr)
        self.assertTrue(tail[-1].endswith("failing on purpose at step 5 with code 7"), tail)
        self.assertTrue(tail[0].endswith("diagnostic line 6"), tail)
        self.assertNoProcessLeft(out)

    def test_solver_crashing_with_a_signal(self):
        out = self.out_dir()
        sabo = self.run_sabo(self.scene(fem_solver={"signal_at_step": [4, int(signal.SIGSEGV)]}, **LONG_RUN), out=out)
        self.assertEqual(sabo.wait(30), 1, sabo.output())
        pid = read_json(os.path.join(out, "pids.json"))["fem_solver"]
        self.assertIn("fem_solver (pid {}) was killed by SIGSEGV".format(pid), sabo.stderr)
        self.assertNoProcessLeft(out)

    def test_coupler_failing_with_an_unexpected_code(self):
        out = self.out_dir()
        sabo = self.run_sabo(self.scene(coupler={"exit_at_step": [3, 9]}, **LONG_RUN), out=out)
        self.assertEqual(sabo.wait(30), 1, sabo.output())
        pid = read_json(os.path.join(out, "pids.json"))["coupler"]
        self.assertIn("coupler (pid {}) exited with code 9".format(pid), sabo.stderr)
        self.assertIn("the coupler reports: coupler: fake failure with code 9", sabo.stderr)
        self.assertNoProcessLeft(out)

    def test_solver_exiting_at_once_is_reported_at_once(self):
        # Issue 18, item 4: a command that exits 0 before registering was reported only after hang_timeout + 3 s
        # (13 s here; the coupler gives up waiting for its registration at 10 s).
        out = self.out_dir()
        sabo = self.run_sabo(self.scene(hang_timeout=10.0, commands={"dem_solver": ["true"]}, **LONG_RUN), out=out)
        self.assertEqual(sabo.wait(30), 1, sabo.output())
        elapsed = sabo.ended - sabo.started
        pid = read_json(os.path.join(out, "pids.json"))["dem_solver"]
        print("a solver command that exits 0 at once: reported after {:.1f} s (expected under 3 s)".format(elapsed))
        self.assertIn("dem_solver (pid {}) exited with code 0".format(pid), sabo.stderr)
        self.assertIn("before registering with the coupler", sabo.stderr)
        self.assertLess(elapsed, 3.0)
        self.assertNoProcessLeft(out)

    def test_solver_leaving_early_with_success_is_a_failure(self):
        # The coupler never notices (never_detect): the supervisor must, after hang_timeout + a grace.
        out = self.out_dir()
        scene = self.scene(hang_timeout=0.5, coupler={"never_detect": True}, dem_solver={"exit_at_step": [5, 0]},
                           **LONG_RUN)
        sabo = self.run_sabo(scene, out=out)
        self.assertEqual(sabo.wait(30), 1, sabo.output())
        pid = read_json(os.path.join(out, "pids.json"))["dem_solver"]
        self.assertIn("dem_solver (pid {}) exited with code 0 before the coupler reported the end of the run"
                      .format(pid), sabo.stderr)
        self.assertNoProcessLeft(out)


class HangTest(FakeRunTestCase):
    def test_hung_solver_detected_by_the_coupler(self):
        out = self.out_dir()
        sabo = self.run_sabo(self.scene(hang_timeout=0.5, fem_solver={"hang_at_step": 5}, **LONG_RUN), out=out)
        self.assertEqual(sabo.wait(30), 1, sabo.output())
        self.assertIn("fem_solver: hung: no message for 0.5 s (hang_timeout)", sabo.stderr)
        self.assertIn("last lines of {}/fem_solver.log".format(out), sabo.stderr)
        self.assertIn("hanging at step 5", sabo.stderr)
        # Issue 18, item 4: the headline names the hung solver first, and the peer that ended because of it as
        # such (it used to start with "dem_solver (pid N) exited with code 1").
        headline = next(line for line in sabo.stdout.splitlines() if line.startswith("sabo: run FAILED"))
        print("headline: " + headline)
        dem_pid = read_json(os.path.join(out, "pids.json"))["dem_solver"]
        self.assertTrue(headline.startswith("sabo: run FAILED: the coupler reports: fem_solver: hung"), headline)
        self.assertIn("stopped because of it: dem_solver (pid {}) exited with code 1".format(dem_pid), headline)
        self.assertNoProcessLeft(out)

    def test_watchdog_stops_a_run_without_progress(self):
        # The coupler freezes and ignores SIGTERM: watchdog after max(3 * 0.5 s, 2 s), SIGKILL 5 s later.
        out = self.out_dir()
        scene = self.scene(hang_timeout=0.5, coupler={"freeze_at_step": 5}, **LONG_RUN)
        sabo = self.run_sabo(scene, out=out, env={"SABO_WATCHDOG_MIN_S": "2"})
        wait_for_events(sabo, out, lambda events: progress_count(events) >= 5, 30, "5 progress events")
        frozen_at = time.monotonic()
        self.assertEqual(sabo.wait(30), 1, sabo.output())
        elapsed = sabo.ended - frozen_at
        print("watchdog: ./sabo ended {:.1f} s after the last progress, expected about 2 + 5 s".format(elapsed))
        self.assertGreater(elapsed, 6.5)
        self.assertLess(elapsed, 10.0)
        pid = read_json(os.path.join(out, "pids.json"))["coupler"]
        self.assertIn("no progress reported by the coupler for 2 s while every process is alive", sabo.stderr)
        self.assertIn("coupler (pid {}) still running 5 s after SIGTERM: killing it (SIGKILL)".format(pid),
                      sabo.stderr)
        self.assertNoProcessLeft(out)


if __name__ == "__main__":
    unittest.main()
