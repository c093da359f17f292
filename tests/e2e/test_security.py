"""Issue 25, security: who may join a run (docs/security.md).

Over tcp the coupler takes only the CURVE keys of the run's roles (made per run in RUN_DIR/keys); over ipc only
the run's token, on a socket inside a folder only the user can enter; and the process that registers over ipc
must be the one the supervisor started. Each test runs configs/tests/chute_small.toml with attackers beside it
and checks that the run completes with the same bits as an undisturbed one (or, for a process of the user
that holds the token, that the run stops and says why).

The attackers speak ZeroMQ through pyzmq (Debian's python3-zmq) and send a real registration: the fem_solver's
Register recorded in the traffic.h5 of the undisturbed run. The replayed handshake is the byte stream of the
real dem_solver's connection, captured by a proxy between it and the coupler (the solver reaches the coupler
through its launcher's connect_host, 127.0.0.2, where the proxy listens)."""
import filecmp
import os
import signal
import socket
import stat
import struct
import subprocess
import sys
import threading
import time

import h5py
import zmq
import zmq.auth

from e2e_support import BUILD_DIR, RealRunTestCase, read_events, read_json, wait_for_events

CHUTE_SMALL = "configs/tests/chute_small.toml"
HEADER = struct.Struct("<4sHH")  # libsabo/protocol/wire.hpp: magic, protocol version, message type
REGISTER = 1
STARTUP_TIMEOUT_S = 120


def recorded_registration(run_dir, role):
    """The serialized Register of `role` recorded in RUN_DIR/traffic.h5."""
    with h5py.File(os.path.join(run_dir, "traffic.h5"), "r") as traffic:
        start = int(traffic[role + "/registration_offset"][0])
        length = int(traffic[role + "/registration_count"][0])
        return bytes(traffic[role + "/registration"][start:start + length])


def send_registration(endpoint, body, configure=None, wait_s=1.0):
    """Connects a DEALER (set up by `configure`) to `endpoint`, sends the Register `body`; the reply's frames,
    or None when nothing comes back within `wait_s` (the connection was refused at its handshake)."""
    context = zmq.Context()
    client = context.socket(zmq.DEALER)
    client.setsockopt(zmq.LINGER, 0)
    if configure is not None:
        configure(client)
    client.connect(endpoint)
    try:
        client.send_multipart([HEADER.pack(b"SABO", 1, REGISTER), body])
        if client.poll(int(wait_s * 1000)):
            return client.recv_multipart()
        return None
    finally:
        client.close(0)
        context.term()


def curve_client(public, secret, server):
    def configure(client):
        client.curve_publickey, client.curve_secretkey, client.curve_serverkey = public, secret, server
    return configure


def plain_client(user, token):
    def configure(client):
        client.plain_username, client.plain_password = user.encode(), token.encode()
    return configure


def free_port():
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


class Proxy(threading.Thread):
    """Listens on (host, port), forwards its first connection to (target_host, port) both ways and keeps what
    the client sent."""

    def __init__(self, host, target_host, port):
        super().__init__(daemon=True)
        self.listener = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        self.listener.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        self.listener.bind((host, port))
        self.listener.listen(1)
        self.target = (target_host, port)
        self.sent = bytearray()
        self.lock = threading.Lock()

    def run(self):
        client, _ = self.listener.accept()
        self.listener.close()
        server = socket.create_connection(self.target)

        def pump(source, sink, record):
            try:
                while True:
                    data = source.recv(65536)
                    if not data:
                        break
                    if record:
                        with self.lock:
                            self.sent += data
                    sink.sendall(data)
            except OSError:
                pass
            finally:
                for end in (source, sink):
                    try:
                        end.shutdown(socket.SHUT_RDWR)
                    except OSError:
                        pass

        back = threading.Thread(target=pump, args=(server, client, False), daemon=True)
        back.start()
        pump(client, server, True)
        back.join(5)

    def captured(self):
        with self.lock:
            return bytes(self.sent)


class SecurityTestCase(RealRunTestCase):
    def scene_text(self):
        with open(self.scene_path(CHUTE_SMALL), encoding="utf-8") as handle:
            return handle.read()

    def write_scene(self, name, run_keys="", dem_keys="", fem_table="", end_time=None):
        """chute_small with more [run] keys, more [solvers.dem] keys and a [solvers.fem] table."""
        text = self.scene_text().replace("[run]\n", "[run]\n" + run_keys, 1)
        if end_time is not None:
            self.assertIn("end_time = 4.0\n", text)
            text = text.replace("end_time = 4.0\n", "end_time = {!r}\n".format(end_time))
        text = text.replace("[solvers.dem]\n", "[solvers.dem]\n" + dem_keys, 1)
        scene = os.path.join(self.tmp, name + ".toml")
        with open(scene, "w", encoding="utf-8") as handle:
            handle.write(text + ("\n[solvers.fem]\n" + fem_table if fem_table else ""))
        return scene

    def late(self, program, seconds):
        """A command key that starts the built `program` `seconds` late (other processes connect first)."""
        return ('command = ["bash", "-c", "sleep {}; exec {} \\"$@\\"", "{}"]\n'
                .format(seconds, os.path.join(BUILD_DIR, "bin", program), program))

    def reference(self, scene=None):
        """An undisturbed run of chute_small (or `scene`): its folder."""
        out = os.path.join(self.tmp, "reference")
        sabo = self.run_sabo(scene or self.scene_path(CHUTE_SMALL), out)
        self.assertEqual(sabo.wait(180), 0, sabo.output())
        return out

    def listening(self, sabo, out):
        events = wait_for_events(sabo, out, lambda e: any(x.get("event") == "listening" for x in e),
                                 STARTUP_TIMEOUT_S, "the listening event")
        return next(x for x in events if x.get("event") == "listening")["endpoint"]

    def wait_registered(self, out, role, timeout_s=30):
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            if any(e.get("event") == "registered" and e.get("role") == role for e in read_events(out)):
                return
            time.sleep(0.05)
        self.fail("{} did not register".format(role))

    def assertSameForces(self, reference, run):
        self.assertTrue(filecmp.cmp(os.path.join(reference, "forces.csv"), os.path.join(run, "forces.csv"),
                                    shallow=False), "forces.csv differs from the undisturbed run's")
        self.assertTrue(filecmp.cmp(os.path.join(reference, "energy.csv"), os.path.join(run, "energy.csv"),
                                    shallow=False), "energy.csv differs from the undisturbed run's")


class TcpSecurityTest(SecurityTestCase):
    def test_strangers_are_refused_at_the_handshake_while_the_run_completes_unchanged(self):
        reference = self.reference()
        fem_register = recorded_registration(reference, "fem_solver")
        port = free_port()
        proxy = Proxy("127.0.0.2", "127.0.0.1", port)
        proxy.start()
        scene = self.write_scene(
            "tcp", 'endpoint = "tcp://127.0.0.1:{}"\nconnect_host = "127.0.0.2"\n'.format(port),
            dem_keys='launcher = ["env"]\n', fem_table=self.late("fem_solver", 6))
        out = os.path.join(self.tmp, "run")
        sabo = self.run_sabo(scene, out)
        endpoint = self.listening(sabo, out)
        self.assertEqual(endpoint, "tcp://127.0.0.1:{}".format(port))
        keys = os.path.join(out, "keys")
        server_key = zmq.auth.load_certificate(os.path.join(keys, "coupler.key"))[0]
        self.wait_registered(out, "dem_solver")  # through the proxy, which recorded its handshake

        # While the fem_solver is not there yet, strangers try to take its role.
        no_keys = send_registration(endpoint, fem_register)
        own_public, own_secret = zmq.curve_keypair()
        wrong_key = send_registration(endpoint, fem_register, curve_client(own_public, own_secret, server_key))
        dem_public, dem_secret = zmq.auth.load_certificate(os.path.join(keys, "dem_solver.key_secret"))
        stolen_key = send_registration(endpoint, fem_register, curve_client(dem_public, dem_secret, server_key))
        # The dem_solver's own connection replayed byte for byte: its HELLO decrypts, its INITIATE cannot.
        captured = proxy.captured()
        with socket.create_connection(("127.0.0.1", port), timeout=5) as raw:
            raw.sendall(captured)
            answered = b""
            try:
                while True:
                    chunk = raw.recv(65536)
                    if not chunk:
                        break
                    answered += chunk
            except OSError:
                pass
        print("no keys: reply {}; a key of its own: reply {}; the dem_solver's key: {}; the dem_solver's "
              "connection replayed ({} bytes): closed after {} bytes".format(
                  no_keys, wrong_key, stolen_key and stolen_key[1][:160], len(captured), len(answered)))
        self.assertIsNone(no_keys)
        self.assertIsNone(wrong_key)
        self.assertIsNotNone(stolen_key)  # authenticated as dem_solver: answered, and refused the fem role
        self.assertIn(b"authenticated as 'dem_solver'", stolen_key[1])
        self.assertIn(b"cannot register as fem_solver", stolen_key[1])
        self.assertGreater(len(captured), 500)

        self.assertEqual(sabo.wait(180), 0, sabo.output())
        self.assertSameForces(reference, out)
        security = read_json(os.path.join(out, "summary.json"))["security"]
        print("summary.json security: {}".format(security))
        self.assertEqual((security["transport"], security["mechanism"]), ("tcp", "curve"))
        reasons = " | ".join(entry["reason"] for entry in security["refused"])
        # The client without keys is refused for its mechanism, or gives up first when it sees the coupler's
        # greeting ask for CURVE (then the coupler sees it close the connection): both say "another security
        # mechanism".
        for reason in ("another security mechanism", "is not one of this run's", "replayed, forged or garbled"):
            self.assertIn(reason, reasons)
        registered = [e["role"] for e in read_events(out) if e.get("event") == "registered"]
        self.assertEqual(sorted(registered), ["dem_solver", "fem_solver"])
        # A connection that ends within microseconds of its start (the replayed one, sent all at once) may be
        # gone before its address is read: "unknown".
        self.assertTrue(all(entry["address"].startswith("127.0.0.1:") or entry["address"] == "unknown"
                            for entry in security["refused"]), security["refused"])
        self.assertTrue(any(entry["address"].startswith("127.0.0.1:") for entry in security["refused"]))
        with open(os.path.join(out, "coupler.log"), encoding="utf-8") as handle:
            log = handle.read()
        self.assertIn("refused a connection from 127.0.0.1:", log)
        self.assertIn("authenticated as 'dem_solver'", log)
        self.assertNoProcessLeft(out)

    def test_a_solver_started_by_hand_with_a_copy_of_its_keys_joins(self):
        """./sabo keys DIR, ./sabo run --keys DIR with the dem_solver by_hand, and the dem_solver started by hand
        with only coupler.key and its own .key_secret: the run completes with the bits of an undisturbed one."""
        reference = self.reference()
        keys = os.path.join(self.tmp, "keys")
        made = self.sabo(["keys", keys, "--no-setup"], env={"SABO_BUILD_DIR": BUILD_DIR})
        self.assertEqual(made.wait(30), 0, made.output())
        again = self.sabo(["keys", keys, "--no-setup"], env={"SABO_BUILD_DIR": BUILD_DIR})
        self.assertEqual(again.wait(30), 1)  # a key set is never replaced unasked
        self.assertIn("--force", again.stderr)
        copy = os.path.join(self.tmp, "remote_keys")
        os.mkdir(copy, 0o700)
        for name in ("coupler.key", "dem_solver.key_secret"):
            with open(os.path.join(keys, name), "rb") as source:
                data = source.read()
            descriptor = os.open(os.path.join(copy, name), os.O_WRONLY | os.O_CREAT, 0o600)
            with os.fdopen(descriptor, "wb") as target:
                target.write(data)
        scene = self.write_scene("by_hand", 'endpoint = "tcp"\nregistration_timeout = 60.0\n', dem_keys="by_hand = true\n")
        out = os.path.join(self.tmp, "run")
        sabo = self.run_sabo(scene, out, extra=["--keys", keys])
        endpoint = self.listening(sabo, out)
        remote_out = os.path.join(self.tmp, "remote_out")
        os.mkdir(remote_out)
        with open(os.path.join(self.tmp, "dem_by_hand.log"), "wb") as log:
            by_hand = subprocess.run([os.path.join(BUILD_DIR, "bin", "dem_solver"), "--scene", scene, "--coupler",
                                      endpoint, "--out", remote_out, "--keys", copy], stdin=subprocess.DEVNULL,
                                     stdout=log, stderr=subprocess.STDOUT, timeout=120)
        self.assertEqual(by_hand.returncode, 0)
        self.assertEqual(sabo.wait(60), 0, sabo.output())
        self.assertIn("waiting for dem_solver, started by hand", sabo.stdout + sabo.stderr)
        self.assertSameForces(reference, out)
        self.assertTrue(filecmp.cmp(os.path.join(reference, "dem.pvd"), os.path.join(remote_out, "dem.pvd"),
                                    shallow=False))
        # The run's own keys are the ones given.
        self.assertTrue(filecmp.cmp(os.path.join(keys, "coupler.key_secret"),
                                    os.path.join(out, "keys", "coupler.key_secret"), shallow=False))

    def test_a_run_without_curve_says_so(self):
        scene = self.write_scene("clear", 'endpoint = "tcp"\ntcp_security = "none"\n')
        out = os.path.join(self.tmp, "clear")
        sabo = self.run_sabo(scene, out)
        self.assertEqual(sabo.wait(180), 0, sabo.output())
        self.assertIn('tcp_security = "none"', sabo.stderr)
        security = read_json(os.path.join(out, "summary.json"))["security"]
        print("summary.json security: {}".format(security))
        self.assertEqual(security["mechanism"], "none")
        self.assertIn("any process that reaches", security["warning"])


class IpcSecurityTest(SecurityTestCase):
    def test_only_the_runs_processes_join_and_its_folder_is_private_whatever_the_umask(self):
        reference = self.reference()
        dem_register = recorded_registration(reference, "dem_solver")
        scene = self.write_scene("ipc", dem_keys=self.late("dem_solver", 4))
        out = os.path.join(self.tmp, "run")
        previous = os.umask(0)  # the run must not take it
        try:
            sabo = self.run_sabo(scene, out)
        finally:
            os.umask(previous)
        endpoint = self.listening(sabo, out)
        socket_path = endpoint[len("ipc://"):]
        no_token = send_registration(endpoint, dem_register)
        wrong_token = send_registration(endpoint, dem_register, plain_client("dem_solver", "0" * 64))
        other_user = None
        if os.geteuid() == 0:  # another user cannot even reach the socket
            probe = ("import socket\ns = socket.socket(socket.AF_UNIX)\ntry:\n    s.connect({!r})\n    print('connected')\n"
                     "except OSError as e:\n    print(type(e).__name__)\n").format(socket_path)
            other_user = subprocess.run([sys.executable, "-c", probe], stdout=subprocess.PIPE, universal_newlines=True,
                                        preexec_fn=lambda: (os.setgid(65534), os.setuid(65534))).stdout.strip()
        print("no token: reply {}; a wrong token: reply {}; user nobody connecting to {}: {}".format(
            no_token, wrong_token, socket_path, other_user or "(not root: not tried)"))
        self.assertIsNone(no_token)
        self.assertIsNone(wrong_token)
        if other_user is not None:
            self.assertEqual(other_user, "PermissionError")
        self.assertEqual(sabo.wait(180), 0, sabo.output())
        self.assertSameForces(reference, out)

        modes = {}
        for folder, folders, files in os.walk(out):
            for name in folders + files:
                path = os.path.join(folder, name)
                modes[os.path.relpath(path, out)] = stat.S_IMODE(os.lstat(path).st_mode)
        print("run folder {:o}; {} entries, modes {}".format(stat.S_IMODE(os.stat(out).st_mode), len(modes),
                                                             sorted({"{:o}".format(m) for m in modes.values()})))
        self.assertEqual(stat.S_IMODE(os.stat(out).st_mode), 0o700)
        for path, mode in modes.items():
            expected = 0o700 if os.path.isdir(os.path.join(out, path)) else 0o600
            self.assertEqual(mode, expected, "{} has mode {:o}".format(path, mode))
        self.assertEqual(read_json(os.path.join(out, "summary.json"))["security"]["mechanism"], "token")

    def test_a_process_the_supervisor_did_not_start_cannot_take_a_role(self):
        """A process of the same user that read the token registers as the dem_solver before it: the kernel
        names its pid, which the supervisor did not start, and the run stops saying so."""
        reference = self.reference()
        dem_register = recorded_registration(reference, "dem_solver")
        scene = self.write_scene("impostor", dem_keys=self.late("dem_solver", 4))
        out = os.path.join(self.tmp, "run")
        sabo = self.run_sabo(scene, out)
        endpoint = self.listening(sabo, out)
        with open(os.path.join(out, "keys", "ipc.token"), encoding="ascii") as handle:
            token = handle.read().strip()
        context = zmq.Context()
        impostor = context.socket(zmq.DEALER)
        impostor.setsockopt(zmq.LINGER, 0)
        plain_client("dem_solver", token)(impostor)
        impostor.connect(endpoint)
        impostor.send_multipart([HEADER.pack(b"SABO", 1, REGISTER), dem_register])
        try:
            code = sabo.wait(60)
        finally:
            impostor.close(0)
            context.term()
        print(sabo.output())
        self.assertEqual(code, 1)
        self.assertIn("registered from pid {}, which the supervisor did not start".format(os.getpid()),
                      sabo.output())
        self.assertNoProcessLeft(out)


class LostSolverTest(SecurityTestCase):
    """ZMTP heartbeats: a solver whose process stops (SIGSTOP: alive, but silent) is reported within 10 s
    naming it; with restart = "auto" it is killed and restarted from its checkpoint, and the run's outputs are
    those of an undisturbed run."""

    def stop_dem_at(self, out, sabo, step):
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline and sabo.popen.poll() is None:
            steps = [e.get("step", 0) for e in read_events(out) if e.get("event") == "progress"]
            if steps and steps[-1] >= step:
                os.kill(read_json(os.path.join(out, "pids.json"))["dem_solver"], signal.SIGSTOP)
                return time.monotonic()
            time.sleep(0.01)
        self.fail("the run ended before step {}".format(step))

    def test_a_stopped_solver_is_reported_within_10_s_and_the_run_stops_cleanly(self):
        scene = self.write_scene("stopped", 'restart = "off"\n')
        out = os.path.join(self.tmp, "run")
        sabo = self.run_sabo(scene, out)
        stopped_at = self.stop_dem_at(out, sabo, 2000)
        reported = None
        while sabo.popen.poll() is None and time.monotonic() - stopped_at < 30:
            if any(e.get("event") == "error" for e in read_events(out)):
                reported = time.monotonic()
                break
            time.sleep(0.05)
        code = sabo.wait(60)
        error = next(e for e in read_events(out) if e.get("event") == "error")
        print("the coupler reported {:.1f} s after SIGSTOP (limit 10 s): {}".format(reported - stopped_at,
                                                                                  error["message"]))
        self.assertEqual(code, 1)
        self.assertLess(reported - stopped_at, 10.0)
        self.assertEqual(error["process"], "dem_solver")
        self.assertIn("lost its connection", error["message"])
        self.assertEqual(read_json(os.path.join(out, "summary.json"))["status"], "failed")
        with h5py.File(os.path.join(out, "traffic.h5"), "r") as traffic:
            self.assertGreater(traffic["dem_solver/state/step"].shape[0], 2000)
        self.assertNoProcessLeft(out)

    def test_a_stopped_solver_is_restarted_and_the_run_is_unchanged(self):
        # Three times longer than chute_small: the stop comes well before the end (progress every 0.5 s).
        scene = self.write_scene("longer", end_time=12.0)
        reference = self.reference(scene)
        out = os.path.join(self.tmp, "run")
        sabo = self.run_sabo(scene, out)
        self.stop_dem_at(out, sabo, 5000)
        self.assertEqual(sabo.wait(180), 0, sabo.output())
        restarts = read_json(os.path.join(out, "summary.json"))["restarts"]
        print("restarts: {}".format(restarts))
        self.assertEqual([r["process"] for r in restarts], ["dem_solver"])
        self.assertIn("lost its connection", sabo.output())
        self.assertSameForces(reference, out)
        self.assertNoProcessLeft(out)
