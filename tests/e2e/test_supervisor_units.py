"""The supervisor's pieces on their own: progress line, launch plan validation, endpoints, exit texts."""
import json
import os
import signal
import sys
import time
import unittest

from e2e_support import ROOT

sys.path.insert(0, ROOT)
from supervisor.display import format_duration, format_progress, wrap_items  # noqa: E402
from supervisor.errors import SaboError  # noqa: E402
from supervisor.plan import parse_plan  # noqa: E402
from supervisor.processes import describe_exit  # noqa: E402
from supervisor.processes import start_process  # noqa: E402
from supervisor.run import connect_endpoint, resolve_endpoint, started_by, watchdog_seconds  # noqa: E402
from supervisor.scene_text import absolute_file_keys, apply_overrides  # noqa: E402
from supervisor.study import observed_order, pareto_front, relative_error  # noqa: E402

PLAN = {"scene": "/s.toml", "end_time": 2.0, "output_interval": 0.1, "hang_timeout": 10.0, "endpoint": "ipc",
        "processes": [{"role": "dem_solver", "command": ["/b/dem_solver"]},
                      {"role": "coupler", "command": ["/b/coupler"]},
                      {"role": "fem_solver", "command": ["/b/fem_solver", "--threads", "2"]}],
        "bodies": {"spheres": 3}}


def plan_with(**changes):
    plan = json.loads(json.dumps(PLAN))
    plan.update(changes)
    return json.dumps(plan)


class ProgressLineTest(unittest.TestCase):
    def test_the_documented_line(self):
        event = {"event": "progress", "step": 1200, "time": 3.2071, "end_time": 20.0, "dt": 6.1e-4,
                 "steps_per_second": 1850.2, "eta_seconds": 12.4}
        self.assertEqual(format_progress(event),
                         "step 1200  t = 3.21 / 20.00 s  dt = 6.1e-04 s  1850 steps/s  ETA 0:00:12")

    def test_short_runs_get_more_decimals_and_unknown_eta_dashes(self):
        event = {"step": 7, "time": 0.01234, "end_time": 0.05, "dt": 1e-5, "steps_per_second": 3.25,
                 "eta_seconds": -1}
        self.assertEqual(format_progress(event), "step 7  t = 0.0123 / 0.0500 s  dt = 1.0e-05 s  3.2 steps/s  ETA --")
        self.assertEqual(format_progress({"step": 0}), "step 0  ETA --")

    def test_durations_and_wrapping(self):
        self.assertEqual(format_duration(3725.4), "1:02:05")
        self.assertEqual(wrap_items(["aaaa", "bbbb", "cccc"], "> ", "  ", width=13), ["> aaaa, bbbb,", "  cccc"])


class LaunchPlanTest(unittest.TestCase):
    def test_valid_plan_puts_the_coupler_first(self):
        plan = parse_plan(json.dumps(PLAN), "test")
        self.assertEqual([p.role for p in plan.processes], ["coupler", "dem_solver", "fem_solver"])
        self.assertEqual(plan.solvers[1].command, ["/b/fem_solver", "--threads", "2"])
        self.assertEqual((plan.end_time, plan.hang_timeout, plan.endpoint), (2.0, 10.0, "ipc"))

    def test_invalid_plans_are_explained(self):
        cases = [
            ("not json", "not valid JSON"),
            (plan_with(endpoint="udp://x"), "\"endpoint\" must be \"ipc\", \"tcp\" or \"tcp://HOST:PORT\""),
            (plan_with(tcp_security="tls"), "\"tcp_security\" must be \"curve\" or \"none\", got 'tls'"),
            (plan_with(hang_timeout=0), "\"hang_timeout\" must be a positive number, got 0"),
            (plan_with(end_time="2"), "\"end_time\" must be a positive number"),
            (plan_with(processes=[]), "\"processes\" must be a non-empty list"),
            (plan_with(processes=[{"role": "coupler", "command": []}]), "\"command\" must be a non-empty list"),
            (plan_with(processes=[{"role": "coupler", "command": ["c"]}, {"role": "coupler", "command": ["c"]}]),
             "role \"coupler\" appears twice"),
            (plan_with(processes=[{"role": "dem_solver", "command": ["d"]}]), "exactly one process with role"),
            (plan_with(processes=[{"role": "coupler", "command": ["c"]},
                                  {"role": "dem_solver", "command": ["d"], "launcher": "ssh node2"}]),
             "\"launcher\" must be a list of strings, got 'ssh node2'"),
            (plan_with(connect_host=""), "\"connect_host\" must be a host name"),
        ]
        for text, message in cases:
            with self.subTest(message=message):
                with self.assertRaises(SaboError) as raised:
                    parse_plan(text, "plan.json")
                self.assertIn(message, str(raised.exception))
                self.assertTrue(str(raised.exception).startswith("plan.json"))


class EndpointTest(unittest.TestCase):
    def test_ipc_socket_in_the_run_folder_unless_too_long(self):
        self.assertEqual(resolve_endpoint("ipc", "/data/runs/x"), ("ipc:///data/runs/x/coupler.sock", None))
        long_dir = "/data/" + "r" * 90
        endpoint, folder = resolve_endpoint("ipc", long_dir)
        try:
            self.assertTrue(os.path.isdir(folder))
            self.assertEqual(endpoint, "ipc://" + folder + "/coupler.sock")
            self.assertLessEqual(len(endpoint) - len("ipc://"), 100)
        finally:
            os.rmdir(folder)
        self.assertEqual(resolve_endpoint("tcp://10.0.0.2:5555", "/x"), ("tcp://10.0.0.2:5555", None))
        # "tcp": this machine only, at a port the system chooses.
        self.assertEqual(resolve_endpoint("tcp", "/x"), ("tcp://127.0.0.1:*", None))

    def test_a_launched_solver_connects_to_an_address_other_hosts_reach(self):
        self.assertEqual(connect_endpoint("tcp://0.0.0.0:5555", False, None), "tcp://0.0.0.0:5555")
        self.assertEqual(connect_endpoint("ipc:///r/coupler.sock", True, "head"), "ipc:///r/coupler.sock")
        self.assertEqual(connect_endpoint("tcp://10.0.0.1:5555", True, None), "tcp://10.0.0.1:5555")
        self.assertEqual(connect_endpoint("tcp://0.0.0.0:5555", True, "head.cluster"), "tcp://head.cluster:5555")
        host = connect_endpoint("tcp://0.0.0.0:5555", True, None)[len("tcp://"):].rsplit(":", 1)[0]
        self.assertNotIn(host, ("0.0.0.0", ""))
        plan = parse_plan(plan_with(processes=[{"role": "coupler", "command": ["c"]},
                                               {"role": "dem_solver", "command": ["d"], "launcher": ["ssh", "n2"]}],
                                    connect_host="head", tcp_security="none"), "test")
        self.assertEqual((plan.solvers[0].launcher, plan.connect_host, plan.tcp_security), (["ssh", "n2"], "head", "none"))
        self.assertEqual(parse_plan(json.dumps(PLAN), "test").solvers[0].launcher, [])

    def test_a_registration_is_the_started_process_or_one_it_started(self):
        log = os.path.join(os.environ.get("TMPDIR", "/tmp"), "sabo-started-by-{}.log".format(os.getpid()))
        process = start_process("dem_solver", ["/bin/sh", "-c", "sleep 30 & wait"], "/", log, stdout_to_pipe=False)
        try:
            child = None
            for _ in range(100):
                children = open("/proc/{}/task/{}/children".format(process.pid, process.pid)).read().split()
                if children:
                    child = int(children[0])
                    break
                time.sleep(0.02)
            self.assertIsNotNone(child)
            self.assertTrue(started_by(process.pid, process))
            self.assertTrue(started_by(child, process))   # a wrapper's child: the same process group
            self.assertFalse(started_by(os.getpid(), process))
            self.assertFalse(started_by(2 ** 22 + 7, process))  # no such process
        finally:
            process.send(signal.SIGKILL)
            process.popen.wait(5)
            process.sweep()
            os.unlink(log)

    def test_watchdog_is_three_hang_timeouts_or_30_s(self):
        os.environ.pop("SABO_WATCHDOG_MIN_S", None)
        self.assertEqual(watchdog_seconds(10.0), 30.0)
        self.assertEqual(watchdog_seconds(20.0), 60.0)
        self.assertEqual(watchdog_seconds(2.0), 30.0)


class ExitTextTest(unittest.TestCase):
    def test_exit_descriptions(self):
        self.assertEqual(describe_exit(3), "exited with code 3")
        self.assertEqual(describe_exit(-signal.SIGKILL), "was killed by SIGKILL")
        self.assertEqual(describe_exit(-signal.SIGSEGV), "was killed by SIGSEGV")


if __name__ == "__main__":
    unittest.main()


class StudyUnitsTest(unittest.TestCase):
    def test_the_pareto_front_keeps_what_no_other_run_beats_in_cost_and_error(self):
        points = [(10.0, 0.5), (1.0, 2.0), (5.0, 0.5), (2.0, 3.0), (20.0, 0.1), (5.0, 0.6)]
        # (1, 2.0), then (5, 0.5) (cheaper than (10, 0.5) for the same error), then (20, 0.1).
        self.assertEqual(pareto_front(points), [1, 2, 4])
        self.assertEqual(pareto_front([]), [])

    def test_the_observed_order_is_the_slope_in_log_log(self):
        steps = [0.1, 0.05, 0.025, 0.0125]
        self.assertAlmostEqual(observed_order(steps, [3.0 * h ** 2 for h in steps]), 2.0, places=12)
        self.assertAlmostEqual(observed_order(steps, [0.7 * h for h in steps]), 1.0, places=12)
        self.assertIsNone(observed_order([0.1], [0.01]))
        self.assertIsNone(observed_order([0.1, 0.05], [0.0, None]))  # no error to fit
        self.assertAlmostEqual(relative_error(11474.0, 11470.0), 4.0 / 11470.0)
        self.assertEqual(relative_error(0.5, 0.0), 0.5)  # a zero reference: the absolute error
        self.assertIsNone(relative_error(None, 1.0))

    def test_an_override_replaces_a_key_adds_one_or_adds_its_table(self):
        text = "[run]\nend_time = 1.0\n\n[sph]\ncfl = 0.25\n"
        out = apply_overrides(text, ["run.end_time=2.0", "sph.sound_speed=40.0", "solvers.dem.beta=0.5"])
        self.assertIn("end_time = 2.0\n", out)
        self.assertNotIn("end_time = 1.0", out)
        self.assertIn("[sph]\nsound_speed = 40.0\ncfl = 0.25", out)
        self.assertTrue(out.rstrip().endswith("[solvers.dem]\nbeta = 0.5"))

    def test_every_file_key_is_made_absolute_against_the_scene_folder(self):
        text = ('file = "mesh.msh"\nprofile_file = "../wenjia/profile.csv"\nraster_file = "/data/dem.tif"\n'
                'hydrograph_file = "q.csv"\nname = "file.csv"\n')
        out = absolute_file_keys(text, "/runs/configs/tests")
        self.assertIn('file = "/runs/configs/tests/mesh.msh"\n', out)
        self.assertIn('profile_file = "/runs/configs/wenjia/profile.csv"\n', out)
        self.assertIn('raster_file = "/data/dem.tif"\n', out)  # already absolute
        self.assertIn('hydrograph_file = "/runs/configs/tests/q.csv"\n', out)
        self.assertIn('name = "file.csv"\n', out)  # not a path key

    def test_an_override_of_one_table_of_an_array_counts_from_zero(self):
        text = ('[[structures]]\nname = "floor"\nelement_size = 1.0\n\n[[structures]]\nname = "dam"\n'
                'element_size = 1.0\n[structures.extra]\n')
        out = apply_overrides(text, ["structures[1].element_size=0.5", 'structures[0].material="steel"'])
        self.assertIn('[[structures]]\nmaterial = "steel"\nname = "floor"\nelement_size = 1.0\n', out)
        self.assertIn('name = "dam"\nelement_size = 0.5\n', out)
        with self.assertRaises(SaboError) as raised:
            apply_overrides(text, ["structures[2].element_size=0.5"])
        self.assertIn("the scene has 2 [[structures]] table(s), so structures[2] is none of them", str(raised.exception))

