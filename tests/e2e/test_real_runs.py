"""`./sabo run` with the real coupler and solvers: a completed run, a refused run folder, a killed
process in turn (coupler, dem_solver, fem_solver, the supervisor itself) and Ctrl-C, each leaving readable
files and no process behind; endpoints the coupler cannot bind."""
import os
import signal
import socket
import time
import unittest

from e2e_support import (BUILD_DIR, RealRunTestCase, progress_count, read_events, read_json, read_text,
                         wait_for_events)


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
        # With restarts off: a killed solver stops the run (test_restart.py covers restart = "auto").
        scene = os.path.join(self.tmp, "chute_small_no_restart.toml")
        with open(self.scene_path(CHUTE_SMALL), encoding="utf-8") as handle:
            text = handle.read()
        self.assertIn("[run]\n", text)
        with open(scene, "w", encoding="utf-8") as handle:
            handle.write(text.replace("[run]\n", '[run]\nrestart = "off"\n', 1))
        for role in ("coupler", "dem_solver", "fem_solver"):
            with self.subTest(role=role):
                out = os.path.join(self.tmp, "kill_" + role)
                sabo = self.run_sabo(scene, out)
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
                if role == "coupler":
                    # Issue 18, item 5: the supervisor repairs what the killed coupler left.
                    self.assertOpensWithoutSwmr(out)
                    summary = read_json(os.path.join(out, "summary.json"))
                    print("kill -9 coupler: summary.json status {!r} (expected 'killed'), written by {!r}".format(
                        summary.get("status"), summary.get("written_by")))
                    self.assertEqual(summary.get("status"), "killed")
                    self.assertIn("coupler (pid {}) was killed by SIGKILL".format(pids[role]), summary.get("failure"))
                    self.assertIn("repaired", sabo.stderr)
                    self.assertFalse(os.path.exists(os.path.join(out, "coupler.sock")))

    def assertOpensWithoutSwmr(self, run_dir):
        """traffic.h5 opens with a plain h5py.File(path, "r"), as h5ls and other ordinary tools open it."""
        import h5py
        path = os.path.join(run_dir, "traffic.h5")
        try:
            with h5py.File(path, "r") as traffic:
                groups = sorted(traffic)
        except OSError as error:
            self.fail("traffic.h5 does not open without swmr=True: {}".format(error))
        print("traffic.h5 opens with a plain h5py.File(path, 'r'): groups {}".format(groups))

    def test_killed_supervisor_leaves_a_folder_the_next_command_repairs(self):
        """kill -9 of ./sabo: every process dies with it (SIGKILL when the parent dies), leaving traffic.h5
        flagged open for writing, coupler.sock and no summary.json; `./sabo status` repairs all three."""
        out = os.path.join(self.tmp, "kill_supervisor")
        sabo = self.run_sabo(self.scene_path(CHUTE_SMALL), out)
        wait_for_events(sabo, out, lambda events: progress_count(events) >= 3, STARTUP_TIMEOUT_S,
                        "3 progress events")
        sabo.signal(signal.SIGKILL)
        sabo.wait(30)
        self.assertNoProcessLeft(out, wait_s=5.0)
        import h5py
        left = sorted(os.listdir(out))
        print("left by kill -9 of the supervisor: {}".format(left))
        self.assertIn("coupler.sock", left)
        self.assertNotIn("summary.json", left)
        with self.assertRaises(OSError) as refused:
            h5py.File(os.path.join(out, "traffic.h5"), "r").close()
        print("a plain h5py open refuses it: {}".format(refused.exception))
        status = self.sabo(["status", out], env={"SABO_BUILD_DIR": BUILD_DIR})
        self.assertEqual(status.wait(60), 0, status.output())
        print(status.stdout)
        self.assertIn("repaired", status.stdout)
        self.assertIn("removed the leftover coupler.sock", status.stdout)
        self.assertIn('wrote summary.json with status "killed"', status.stdout)
        self.assertFalse(os.path.exists(os.path.join(out, "coupler.sock")))
        self.assertEqual(read_json(os.path.join(out, "summary.json")).get("status"), "killed")
        self.assertOpensWithoutSwmr(out)
        self.assertTrafficHoldsEveryStepUpTo(out, progress_steps(read_events(out)))
        again = self.sabo(["status", out], env={"SABO_BUILD_DIR": BUILD_DIR})
        self.assertEqual(again.wait(60), 0, again.output())
        self.assertNotIn("repaired", again.stdout)
        self.assertIn("killed", again.stdout)


class EndpointTest(RealRunTestCase):
    """Issue 18, item 4: an endpoint that cannot be bound is bad input (exit 2, not 1), named with what is
    wrong with it: a port in use and an unknown interface (found by the coupler when it binds), a host that is
    no IPv4 address (found by the scene check)."""

    def scene_with_endpoint(self, endpoint):
        with open(self.scene_path("configs/tests/sphere_collision.toml"), encoding="utf-8") as handle:
            text = handle.read()
        path = os.path.join(self.tmp, "endpoint.toml")
        with open(path, "w", encoding="utf-8") as handle:
            handle.write(text.replace("[run]\n", '[run]\nendpoint = "{}"\n'.format(endpoint), 1))
        return path

    def test_unbindable_endpoints_exit_with_two_naming_the_endpoint(self):
        holder = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        holder.bind(("127.0.0.1", 0))
        holder.listen(1)
        port = holder.getsockname()[1]
        cases = [("tcp://127.0.0.1:{}".format(port), "port {} is in use by another program".format(port)),
                 ("tcp://no-such-interface.invalid:5555", "is neither an IP address of this machine nor the name"),
                 ("tcp://999.1.1.1:5555", "the host 999.1.1.1 is not an IPv4 address")]
        try:
            for endpoint, expected in cases:
                with self.subTest(endpoint=endpoint):
                    out = os.path.join(self.tmp, "endpoint_{}".format(cases.index((endpoint, expected))))
                    sabo = self.run_sabo(self.scene_with_endpoint(endpoint), out)
                    code = sabo.wait(60)
                    print("{}: ./sabo exited with {} (expected 2): {}".format(
                        endpoint, code, sabo.stderr.strip().splitlines()[0] if sabo.stderr.strip() else ""))
                    self.assertEqual(code, 2, sabo.output())
                    self.assertIn(endpoint, sabo.stderr)
                    self.assertIn(expected, sabo.stderr)
                    self.assertNoProcessLeft(out, pids_file=os.path.exists(out))
        finally:
            holder.close()


class ExtremeInputTest(RealRunTestCase):
    """Issue 18, item 3: gravity = [0, 0, -1e300] ran to the end and exited 0 with inf and NaN in energy.csv.
    A non-finite value in a state now ends the run, naming the process, the step and what is not finite; the
    dem_solver's own instability check (issue 24) finds the sphere far above any speed after its first step,
    before a state with inf in it is sent."""

    def test_extreme_gravity_ends_the_run_naming_the_solver(self):
        with open(self.scene_path("configs/tests/sphere_collision.toml"), encoding="utf-8") as handle:
            text = handle.read()
        self.assertIn("gravity = [0.0, 0.0, 0.0]\n", text)
        scene = os.path.join(self.tmp, "gravity_1e300.toml")
        with open(scene, "w", encoding="utf-8") as handle:
            handle.write(text.replace("gravity = [0.0, 0.0, 0.0]\n", "gravity = [0.0, 0.0, -1e300]\n", 1))
        out = os.path.join(self.tmp, "run")
        sabo = self.run_sabo(scene, out)
        code = sabo.wait(120)
        headline = next((line for line in sabo.stdout.splitlines() if line.startswith("sabo: run FAILED")), "")
        print("gravity = -1e300: ./sabo exited with {} (expected 1): {}".format(code, headline))
        self.assertEqual(code, 1, sabo.output())
        self.assertRegex(headline, r"the coupler reports: dem_solver: .*unstable after step 0 .*2 spheres faster than "
                                   r"max_speed = 1000 m/s")
        energy_rows = read_text(os.path.join(out, "energy.csv")).split("\n", 1)[1]  # the values, not the header
        self.assertNotIn("inf", energy_rows)
        self.assertNotIn("nan", energy_rows)
        self.assertEqual(read_json(os.path.join(out, "summary.json"))["status"], "failed")
        self.assertNoProcessLeft(out)


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
