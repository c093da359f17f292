"""Issue 25, remote processes: solvers on another network stack, as on another host.

Three network namespaces stand for three hosts: the supervisor and the coupler run in A, the dem_solver in B
(through its scene launcher, `ip netns exec B`), a stranger in C; veth pairs join A to B and A to C. Over tcp
with CURVE:
  (a) the run's outputs are those of a run on one machine over ipc, bit for bit, and a process in C without
      the run's keys is refused at the handshake, its address logged;
  (b) when B's link vanishes mid-run (the veth pair deleted, then the namespace), the coupler reports the
      dem_solver lost within 10 s, naming it and its address, and the run stops with its files readable;
  (c) with restart = "auto", a dem_solver in B that stops answering (SIGSTOP) is killed and started again
      from its checkpoint through its launcher, in B, and the outputs are those of the local run.
Needs root and iproute2 (CI runs as root on Debian); skipped with the reason otherwise."""
import filecmp
import os
import subprocess
import sys
import time
import unittest

import h5py

from e2e_support import BUILD_DIR, SABO, RealRunTestCase, Sabo, read_events, read_json

CHUTE_SMALL = "configs/tests/chute_small.toml"


def ip(*args, check=True):
    return subprocess.run(["ip"] + list(args), stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                          stderr=subprocess.PIPE, universal_newlines=True, check=check)


def namespaces_problem():
    """Why this machine cannot run the tests (None: it can)."""
    if os.geteuid() != 0:
        return "network namespaces need root (CI runs as root)"
    try:
        probe = "sabo-probe-{}".format(os.getpid())
        result = ip("netns", "add", probe, check=False)
        if result.returncode != 0:
            return "ip netns add fails here: {}".format(result.stderr.strip())
        ip("netns", "del", probe, check=False)
    except OSError as error:
        return "no ip command (Debian's iproute2): {}".format(error)
    return None


class NetworkNamespaceTestCase(RealRunTestCase):
    """Three network namespaces per test; the tests are in the classes below (one ctest each)."""

    @classmethod
    def setUpClass(cls):
        problem = namespaces_problem()
        if problem:
            raise unittest.SkipTest(problem)

    def setUp(self):
        super().setUp()
        tag = "{}{}".format(os.getpid() % 10000, len(self.id()) % 10)
        self.ns = {name: "sabo-{}-{}".format(name, tag) for name in ("a", "b", "c")}
        subnet = os.getpid() % 250
        self.address = {"a-b": "10.231.{}.1".format(subnet), "b": "10.231.{}.2".format(subnet),
                        "a-c": "10.232.{}.1".format(subnet), "c": "10.232.{}.2".format(subnet)}
        self.links = {"b": "sb{}".format(tag), "c": "sc{}".format(tag)}
        for name in self.ns.values():
            ip("netns", "add", name)
            ip("-n", name, "link", "set", "lo", "up")
        for host in ("b", "c"):
            here, there = self.links[host] + "a", self.links[host] + "z"
            ip("link", "add", here, "netns", self.ns["a"], "type", "veth", "peer", "name", there, "netns",
               self.ns[host])
            ip("-n", self.ns["a"], "addr", "add", self.address["a-" + host] + "/24", "dev", here)
            ip("-n", self.ns[host], "addr", "add", self.address[host] + "/24", "dev", there)
            ip("-n", self.ns["a"], "link", "set", here, "up")
            ip("-n", self.ns[host], "link", "set", there, "up")

    def tearDown(self):
        super().tearDown()  # kills what a failed test left behind
        for name in self.ns.values():
            ip("netns", "del", name, check=False)

    def in_ns(self, host, command):
        return ["ip", "netns", "exec", self.ns[host]] + command

    def write_scene(self, name, end_time=None, fem_late_s=None, restart="off"):
        """chute_small over tcp on every interface of A, the dem_solver launched in B, which reaches the coupler at
        A's address on their link (connect_host)."""
        with open(self.scene_path(CHUTE_SMALL), encoding="utf-8") as handle:
            text = handle.read()
        text = text.replace("[run]\n", '[run]\nendpoint = "tcp://0.0.0.0:*"\nconnect_host = "{}"\nrestart = "{}"\n'.format(
            self.address["a-b"], restart), 1)
        if end_time is not None:
            text = text.replace("end_time = 4.0\n", "end_time = {!r}\n".format(end_time))
        text = text.replace("[solvers.dem]\n", '[solvers.dem]\nlauncher = ["ip", "netns", "exec", "{}"]\n'.format(
            self.ns["b"]), 1)
        if fem_late_s:
            text += ('\n[solvers.fem]\ncommand = ["bash", "-c", "sleep {}; exec {} \\"$@\\"", "fem_solver"]\n'.format(
                fem_late_s, os.path.join(BUILD_DIR, "bin", "fem_solver")))
        scene = os.path.join(self.tmp, name + ".toml")
        with open(scene, "w", encoding="utf-8") as handle:
            handle.write(text)
        return scene

    def run_in_a(self, scene, out):
        """./sabo run SCENE in namespace A."""
        sabo = Sabo(self.in_ns("a", [sys.executable, SABO, "run", scene, "--out", out, "--no-setup", "--no-plots"]),
                    env={"SABO_BUILD_DIR": BUILD_DIR, "SABO_PLAN_OVERRIDE": "", "SABO_WATCHDOG_MIN_S": ""},
                    work_dir=self.tmp, raw=True)
        self.started.append(sabo)
        return sabo

    def wait_event(self, out, sabo, predicate, timeout_s, what):
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            for event in read_events(out):
                if predicate(event):
                    return event
            if sabo.popen.poll() is not None:
                self.fail("./sabo exited with {} before {}\n{}".format(sabo.popen.returncode, what, sabo.output()))
            time.sleep(0.02)
        self.fail("no {} within {} s".format(what, timeout_s))


class NetworkNamespaceSameBitsTest(NetworkNamespaceTestCase):
    def test_a_solver_on_another_host_gives_the_same_bits_and_strangers_are_refused(self):
        reference = os.path.join(self.tmp, "reference")
        local = self.run_sabo(self.scene_path(CHUTE_SMALL), reference)
        self.assertEqual(local.wait(180), 0, local.output())
        with h5py.File(os.path.join(reference, "traffic.h5"), "r") as traffic:
            start = int(traffic["fem_solver/registration_offset"][0])
            fem_register = bytes(traffic["fem_solver/registration"][start:start + int(
                traffic["fem_solver/registration_count"][0])])
        registration_file = os.path.join(self.tmp, "fem_register.bin")
        with open(registration_file, "wb") as handle:
            handle.write(fem_register)

        out = os.path.join(self.tmp, "remote")
        sabo = self.run_in_a(self.write_scene("remote", fem_late_s=5), out)
        listening = self.wait_event(out, sabo, lambda e: e.get("event") == "listening", 60, "the listening event")
        port = listening["endpoint"].rsplit(":", 1)[1]
        dem = self.wait_event(out, sabo, lambda e: e.get("event") == "registered" and e.get("role") == "dem_solver",
                              60, "the dem_solver's registration")
        # From C, with no keys and with a key of its own, the fem_solver's registration (A's C-side address).
        stranger = ("import struct, sys, zmq\nbody = open(sys.argv[1], 'rb').read()\nfor keys in (False, True):\n"
                    "    c = zmq.Context(); s = c.socket(zmq.DEALER); s.setsockopt(zmq.LINGER, 0)\n"
                    "    if keys:\n        s.curve_publickey, s.curve_secretkey = zmq.curve_keypair()\n"
                    "        s.curve_serverkey = zmq.curve_keypair()[0]\n"
                    "    s.connect(sys.argv[2]); s.send_multipart([struct.pack('<4sHH', b'SABO', 1, 1), body])\n"
                    "    print('answered' if s.poll(1500) else 'refused'); s.close(0); c.term()\n")
        attempt = subprocess.run(self.in_ns("c", [sys.executable, "-c", stranger, registration_file,
                                                  "tcp://{}:{}".format(self.address["a-c"], port)]),
                                 stdout=subprocess.PIPE, stderr=subprocess.STDOUT, universal_newlines=True, timeout=30)
        self.assertEqual(sabo.wait(180), 0, sabo.output())
        print("dem_solver registered from {} (in namespace {}); strangers from {}: {}".format(
            dem.get("address"), self.ns["b"], self.address["c"], attempt.stdout.split()))
        self.assertTrue(dem.get("address", "").startswith(self.address["b"] + ":"), dem)
        self.assertEqual(attempt.stdout.split(), ["refused", "refused"], attempt.stdout)
        for name in ("forces.csv", "energy.csv", "dem.pvd", "fem.pvd"):
            self.assertTrue(filecmp.cmp(os.path.join(reference, name), os.path.join(out, name), shallow=False),
                            "{} differs from the local run's".format(name))
        security = read_json(os.path.join(out, "summary.json"))["security"]
        print("summary.json security: {}".format(security))
        self.assertEqual(security["mechanism"], "curve")
        self.assertTrue(any(entry["address"].startswith(self.address["c"] + ":") for entry in security["refused"]),
                        security)
        self.assertNoProcessLeft(out)


class NetworkNamespaceLostHostTest(NetworkNamespaceTestCase):
    def test_a_solver_whose_host_vanishes_is_reported_within_10_s(self):
        out = os.path.join(self.tmp, "vanished")
        sabo = self.run_in_a(self.write_scene("vanished", end_time=12.0), out)
        self.wait_event(out, sabo, lambda e: e.get("event") == "progress" and e.get("step", 0) >= 2000, 120,
                        "step 2000")
        ip("-n", self.ns["a"], "link", "del", self.links["b"] + "a")  # the pair goes: B is cut off
        ip("netns", "del", self.ns["b"])
        cut_at = time.monotonic()
        error = self.wait_event(out, sabo, lambda e: e.get("event") == "error", 30, "an error event")
        reported_after = time.monotonic() - cut_at
        code = sabo.wait(60)
        print("B's link deleted at step >= 2000: the coupler reported after {:.1f} s (limit 10 s): {}".format(
            reported_after, error["message"]))
        self.assertEqual(code, 1, sabo.output())
        self.assertLess(reported_after, 10.0)
        self.assertEqual(error["process"], "dem_solver")
        self.assertIn("lost its connection", error["message"])
        self.assertIn(self.address["b"], error["message"])
        self.assertEqual(read_json(os.path.join(out, "summary.json"))["status"], "failed")
        with h5py.File(os.path.join(out, "traffic.h5"), "r") as traffic:
            self.assertGreater(traffic["dem_solver/state/step"].shape[0], 2000)
        self.assertNoProcessLeft(out, wait_s=10)

    def test_a_stopped_solver_on_another_host_is_relaunched_through_its_launcher(self):
        reference = os.path.join(self.tmp, "reference")
        scene = self.write_scene("relaunched", end_time=12.0, restart="auto")
        with open(scene, encoding="utf-8") as handle:
            local_text = handle.read()
        local_scene = os.path.join(self.tmp, "local.toml")  # the same run on one machine, over ipc
        with open(local_scene, "w", encoding="utf-8") as handle:
            handle.write(local_text.replace('endpoint = "tcp://0.0.0.0:*"\n', "").replace(
                'connect_host = "{}"\n'.format(self.address["a-b"]), "").replace(
                'launcher = ["ip", "netns", "exec", "{}"]\n'.format(self.ns["b"]), ""))
        local = self.run_sabo(local_scene, reference)
        self.assertEqual(local.wait(180), 0, local.output())
        out = os.path.join(self.tmp, "relaunched")
        sabo = self.run_in_a(scene, out)
        self.wait_event(out, sabo, lambda e: e.get("event") == "progress" and e.get("step", 0) >= 5000, 120,
                        "step 5000")
        first = read_json(os.path.join(out, "pids.json"))["dem_solver"]
        os.kill(first, 19)  # SIGSTOP: alive, in B, and silent
        self.assertEqual(sabo.wait(180), 0, sabo.output())
        restarts = read_json(os.path.join(out, "summary.json"))["restarts"]
        registered = [e for e in read_events(out) if e.get("event") == "registered" and e.get("role") == "dem_solver"]
        rejoined = [e for e in read_events(out) if e.get("event") == "restarted"]
        print("restarts: {}; the dem_solver registered from {}, rejoined from {}".format(
            restarts, registered[0].get("address"), rejoined and rejoined[0].get("address")))
        self.assertEqual([r["process"] for r in restarts], ["dem_solver"])
        self.assertIn("lost its connection", sabo.output())
        self.assertEqual(len(rejoined), 1)
        # Relaunched through its launcher: in B again.
        self.assertTrue(rejoined[0].get("address", "").startswith(self.address["b"] + ":"), rejoined[0])
        for name in ("forces.csv", "energy.csv"):
            self.assertTrue(filecmp.cmp(os.path.join(reference, name), os.path.join(out, name), shallow=False),
                            "{} differs from the local run's".format(name))
        self.assertNoProcessLeft(out, wait_s=10)
