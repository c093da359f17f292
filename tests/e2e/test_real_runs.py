"""`./sabo run` with the real coupler and solvers: a completed run, a refused run folder, a killed
process in turn (coupler, dem_solver, fem_solver) and Ctrl-C, each leaving readable files and no
process behind."""
import os
import signal
import time
import unittest

from e2e_support import RealRunTestCase, progress_count, read_events, read_json, read_text, wait_for_events


def progress_steps(events):
    return [event["step"] for event in events if event.get("event") == "progress"]

SPHERE_DROP = "configs/tests/sphere_drop.toml"
CHUTE_SMALL = "configs/tests/chute_small.toml"
STARTUP_TIMEOUT_S = 120  # scene loading, particle filling and registration included


class CompletedRunTest(RealRunTestCase):
    def test_sphere_drop_completes(self):
        out = os.path.join(self.tmp, "sphere_drop")
        sabo = self.run_sabo(self.scene_path(SPHERE_DROP), out)
        self.assertEqual(sabo.wait(240), 0, sabo.output())
        self.assertIn("sabo: run completed", sabo.stdout)
        self.assertEqual(read_json(os.path.join(out, "summary.json")).get("status"), "completed")
        self.assertTrafficReadable(out, self.solver_roles(out))
        self.assertNoProcessLeft(out)


class RunFolderTest(RealRunTestCase):
    def test_used_run_folder_is_refused_and_left_untouched(self):
        out = os.path.join(self.tmp, "used")
        os.makedirs(out)
        with open(os.path.join(out, "traffic.h5"), "w") as handle:
            handle.write("an earlier run\n")
        sabo = self.run_sabo(self.scene_path(SPHERE_DROP), out)
        self.assertEqual(sabo.wait(60), 2, sabo.output())
        self.assertIn("already exists and is not empty", sabo.stderr)
        self.assertEqual(os.listdir(out), ["traffic.h5"])
        self.assertEqual(read_text(os.path.join(out, "traffic.h5")), "an earlier run\n")


class FaultTest(RealRunTestCase):
    def test_killed_process_is_named_and_files_stay_readable(self):
        for role in ("coupler", "dem_solver", "fem_solver"):
            with self.subTest(role=role):
                out = os.path.join(self.tmp, "kill_" + role)
                sabo = self.run_sabo(self.scene_path(CHUTE_SMALL), out)
                wait_for_events(sabo, out, lambda events: progress_count(events) >= 3, STARTUP_TIMEOUT_S,
                                "3 progress events")
                pids = read_json(os.path.join(out, "pids.json"))
                self.assertIn(role, pids, "{} does not run {}".format(CHUTE_SMALL, role))
                os.kill(pids[role], signal.SIGKILL)
                killed_at = time.monotonic()
                code = sabo.wait(60)
                print("kill -9 {}: ./sabo exited with {} after {:.2f} s".format(role, code, sabo.ended - killed_at))
                self.assertNotEqual(code, 0, sabo.output())
                self.assertLess(sabo.ended - killed_at, 10.0)
                self.assertIn("{} (pid {}) was killed by SIGKILL".format(role, pids[role]), sabo.stderr)
                self.assertNoProcessLeft(out)
                self.assertTrafficReadable(out, self.solver_roles(out))
                self.assertTrafficHoldsEveryStepUpTo(out, progress_steps(read_events(out)))


class InterruptTest(RealRunTestCase):
    def test_ctrl_c_stops_everything_and_keeps_the_files(self):
        out = os.path.join(self.tmp, "interrupted")
        sabo = self.run_sabo(self.scene_path(CHUTE_SMALL), out)
        wait_for_events(sabo, out, lambda events: progress_count(events) >= 3, STARTUP_TIMEOUT_S,
                        "3 progress events")
        sabo.signal(signal.SIGINT)
        sent_at = time.monotonic()
        self.assertEqual(sabo.wait(60), 130, sabo.output())
        print("Ctrl-C: ./sabo exited after {:.2f} s".format(sabo.ended - sent_at))
        self.assertLess(sabo.ended - sent_at, 6.0)
        self.assertNotIn("SIGKILL", sabo.stderr, "every process stopped on its own")
        self.assertNoProcessLeft(out)
        self.assertEqual(read_json(os.path.join(out, "summary.json")).get("status"), "stopped")
        self.assertTrafficReadable(out, self.solver_roles(out))


if __name__ == "__main__":
    unittest.main()
