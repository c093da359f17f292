"""`./sabo run` against fake processes: Ctrl-C, SIGTERM, a second Ctrl-C, a killed supervisor."""
import os
import signal
import time
import unittest

from e2e_support import FakeRunTestCase, progress_count, read_json, wait_for_events

LONG_RUN = {"steps": 2000, "step_seconds": 0.02}  # 40 s: always interrupted long before


class InterruptTest(FakeRunTestCase):
    def start_and_wait_for_progress(self, **behaviour):
        out = self.out_dir()
        scene = dict(LONG_RUN)
        scene.update(behaviour)
        sabo = self.run_sabo(self.scene(**scene), out=out)
        wait_for_events(sabo, out, lambda events: progress_count(events) >= 3, 30, "3 progress events")
        return sabo, out

    def test_ctrl_c_stops_the_run_cleanly(self):
        for number, name in ((signal.SIGINT, "Ctrl-C"), (signal.SIGTERM, "SIGTERM")):
            with self.subTest(signal=name):
                sabo, out = self.start_and_wait_for_progress()
                sabo.signal(number)
                sent_at = time.monotonic()
                self.assertEqual(sabo.wait(30), 130, sabo.output())
                print("{}: ./sabo exited {:.2f} s after the signal".format(name, sabo.ended - sent_at))
                self.assertLess(sabo.ended - sent_at, 6.0)
                self.assertIn("sabo: {}: stopping the run".format(name), sabo.stderr)
                self.assertIn("sabo: run stopped: stopped by " + name, sabo.stdout)
                self.assertNotIn("SIGKILL", sabo.stderr)
                # The coupler stopped the solvers through the protocol: they wrote their final output.
                self.assertEqual(read_json(os.path.join(out, "summary.json"))["status"], "stopped")
                for role in ("dem_solver", "fem_solver"):
                    self.assertTrue(os.path.exists(os.path.join(out, role + ".out")), role)
                self.assertNoProcessLeft(out)
                os.rename(out, out + "-" + name)

    def test_processes_ignoring_the_stop_are_killed_after_5_s(self):
        sabo, out = self.start_and_wait_for_progress(coupler={"ignore_sigterm": True})
        sabo.signal(signal.SIGINT)
        sent_at = time.monotonic()
        self.assertEqual(sabo.wait(30), 130, sabo.output())
        elapsed = sabo.ended - sent_at
        print("stubborn coupler: ./sabo exited {:.2f} s after Ctrl-C, expected about 5 s".format(elapsed))
        self.assertGreater(elapsed, 4.5)
        self.assertLess(elapsed, 7.0)
        pid = read_json(os.path.join(out, "pids.json"))["coupler"]
        self.assertIn("coupler (pid {}) still running 5 s after the stop request: killing it (SIGKILL)".format(pid),
                      sabo.stderr)
        self.assertNoProcessLeft(out)

    def test_second_ctrl_c_kills_at_once(self):
        sabo, out = self.start_and_wait_for_progress(coupler={"ignore_sigterm": True})
        sabo.signal(signal.SIGINT)
        time.sleep(0.5)
        sabo.signal(signal.SIGINT)
        sent_at = time.monotonic()
        self.assertEqual(sabo.wait(30), 130, sabo.output())
        print("second Ctrl-C: ./sabo exited {:.2f} s after it".format(sabo.ended - sent_at))
        self.assertLess(sabo.ended - sent_at, 1.5)
        self.assertIn("killing every process now", sabo.stderr)
        self.assertNoProcessLeft(out)

    def test_killed_supervisor_takes_its_processes_along(self):
        sabo, out = self.start_and_wait_for_progress()
        pids = read_json(os.path.join(out, "pids.json"))
        self.assertEqual(sorted(pids), ["coupler", "dem_solver", "fem_solver", "supervisor"])
        sabo.signal(signal.SIGKILL)
        self.assertEqual(sabo.wait(10), -signal.SIGKILL)
        self.assertNoProcessLeft(out, wait_s=3.0)


if __name__ == "__main__":
    unittest.main()
