"""Issue 18, item 1, end to end: a client that connects to the coupler's tcp endpoint, sends one frame and
disconnects at once must not end the run. Before the fix the coupler exited 1 with "ZeroMQ: cannot send Error
(81 bytes): Host unreachable (errno 113)" (5 of 5 times while waiting for registrations, 3 of 13 in
supervised tcp runs).

The clients speak ZMTP 3.0 with the standard library's sockets (the e2e tests need no pyzmq): greetings and
READY commands exchanged, one message frame as a DEALER, then close (half of them with an RST, SO_LINGER 0).
A client that sends everything at once, before the coupler's greeting, is dropped by ZeroMQ unread.

These clients speak the NULL mechanism, so the scenes here say tcp_security = "none": what is tested is that a
coupler which lets such clients in survives them. With CURVE (the default) they are refused at the handshake
(test_security.py)."""
import json
import os
import signal
import socket
import struct
import subprocess
import time
import unittest

from e2e_support import BUILD_DIR, RealRunTestCase, read_events, read_json, wait_for_events

CHUTE_SMALL = "configs/tests/chute_small.toml"


def scene_without_security(test, port=None):
    """chute_small over tcp without CURVE (and at `port`), in the test's folder."""
    with open(test.scene_path(CHUTE_SMALL), encoding="utf-8") as handle:
        text = handle.read()
    endpoint = 'endpoint = "tcp://127.0.0.1:{}"\n'.format(port) if port else ""
    scene = os.path.join(test.tmp, "chute_tcp.toml")
    with open(scene, "w", encoding="utf-8") as handle:
        handle.write(text.replace("[run]\n", '[run]\n{}tcp_security = "none"\n'.format(endpoint), 1))
    return scene
STARTUP_TIMEOUT_S = 120


def zmtp_greeting():
    """The 64-byte ZMTP 3.0 greeting of a client with the NULL mechanism."""
    return b"\xff" + b"\x00" * 8 + b"\x7f" + b"\x03\x00" + b"NULL".ljust(20, b"\x00") + b"\x00" + b"\x00" * 31


def zmtp_ready_dealer():
    """The READY command of a DEALER socket (short command frame)."""
    name, value = b"Socket-Type", b"DEALER"
    body = b"\x05READY" + bytes([len(name)]) + name + struct.pack(">I", len(value)) + value
    return b"\x04" + bytes([len(body)]) + body


def hit_and_run(port, payload=b"x", reset=False):
    """Connect, exchange greetings and READY as a DEALER, send one frame of `payload` and close at once,
    before any answer. False when the connection or the handshake failed."""
    try:
        with socket.create_connection(("127.0.0.1", port), timeout=5.0) as client:
            if reset:
                client.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, struct.pack("ii", 1, 0))
            client.sendall(zmtp_greeting())
            received = b""  # the coupler's greeting (64 bytes), then its READY (a short command frame)
            while len(received) < 66 or len(received) < 66 + received[65]:
                chunk = client.recv(4096)
                if not chunk:
                    return False
                received += chunk
            client.sendall(zmtp_ready_dealer() + b"\x00" + bytes([len(payload)]) + payload)
        return True
    except OSError:
        return False


def tcp_port(endpoint):
    return int(endpoint.rsplit(":", 1)[1])


class DisconnectingClientTest(RealRunTestCase):
    def test_the_coupler_waiting_for_registrations_survives_clients_that_send_one_frame_and_leave(self):
        """The issue's reproduction: the coupler on its own, waiting for solvers that never come."""
        out = os.path.join(self.tmp, "coupler_alone")
        os.makedirs(out)
        events_path = os.path.join(self.tmp, "coupler.events")
        with open(events_path, "wb") as events, open(os.path.join(self.tmp, "coupler.log"), "wb") as log:
            coupler = subprocess.Popen(
                [os.path.join(BUILD_DIR, "bin", "coupler"), "--scene", scene_without_security(self), "--endpoint",
                 "tcp://127.0.0.1:*", "--out", out, "--registration-timeout", "60"],
                stdin=subprocess.DEVNULL, stdout=events, stderr=log)
        try:
            endpoint = None
            deadline = time.monotonic() + 30
            while endpoint is None and time.monotonic() < deadline and coupler.poll() is None:
                with open(events_path, encoding="utf-8") as handle:
                    for line in handle.read().split("\n")[:-1]:
                        event = json.loads(line)
                        if event.get("event") == "listening":
                            endpoint = event["endpoint"]
                time.sleep(0.05)
            self.assertIsNotNone(endpoint, "the coupler did not report where it listens")
            sent = sum(hit_and_run(tcp_port(endpoint), reset=k % 2 == 1) for k in range(50))
            time.sleep(1.0)
            alive = coupler.poll() is None
            with open(os.path.join(self.tmp, "coupler.log"), encoding="utf-8", errors="replace") as handle:
                log_text = handle.read()
            print("{} clients sent b'x' and left, {} of them before the coupler's answer (the answer that ended the "
                  "run before): the coupler is {} 1 s later (expected running)".format(
                      sent, log_text.count("could not answer a peer that is not registered"),
                      "running" if alive else "gone with exit code {}".format(coupler.returncode)))
            self.assertEqual(sent, 50)
            self.assertTrue(alive, log_text)
            self.assertNotIn("[coupler] error", log_text)
        finally:
            if coupler.poll() is None:
                coupler.send_signal(signal.SIGTERM)
            code = coupler.wait(30)
        print("after SIGTERM the coupler exited with {} (expected 130)".format(code))
        self.assertEqual(code, 130)

    def test_a_supervised_tcp_run_completes_with_clients_that_send_one_frame_and_leave(self):
        """./sabo run over tcp, with such clients before the solvers register and during the steps."""
        scene = scene_without_security(self, "*")
        out = os.path.join(self.tmp, "run")
        sabo = self.run_sabo(scene, out)
        events = wait_for_events(sabo, out, lambda e: any(x.get("event") == "listening" for x in e),
                                 STARTUP_TIMEOUT_S, "the listening event")
        port = tcp_port(next(x for x in events if x.get("event") == "listening")["endpoint"])
        frames = [b"x", b"\x00" * 12, b"not a registration"]
        # A burst while the solvers start and register, then one client every 20 ms until the run ends.
        before_registration = sum(hit_and_run(port, frames[k % 3], reset=k % 2 == 1) for k in range(20))
        during_steps = 0
        while sabo.popen.poll() is None:
            stepping = any(x.get("event") == "progress" for x in read_events(out))
            if hit_and_run(port, frames[(before_registration + during_steps) % 3],
                           reset=(before_registration + during_steps) % 2 == 1):
                if stepping:
                    during_steps += 1
                else:
                    before_registration += 1
            time.sleep(0.02)
        code = sabo.wait(60)
        print("{} clients before the first step and {} during the steps sent one frame and left: ./sabo exited "
              "with {} (expected 0)".format(before_registration, during_steps, code))
        self.assertEqual(code, 0, sabo.output())
        self.assertNotIn("[coupler] error", sabo.output())
        self.assertGreater(during_steps, 10)
        summary = read_json(os.path.join(out, "summary.json"))
        self.assertEqual(summary["status"], "completed")
        print("summary.json connections: {}".format(summary.get("connections")))
        self.assertNoProcessLeft(out)


if __name__ == "__main__":
    unittest.main()
