"""A fake coupler for the supervisor tests: the real one's command line, event lines and exit codes,
with a trivial text protocol over a stream socket instead of ZeroMQ.

    coupler.py --scene SCENE --endpoint ipc://PATH|tcp://HOST:PORT --out DIR

Solvers connect and send `register ROLE PID`; each step the coupler sends `step N` to every solver
and waits for `ok N`; at the end (or on SIGTERM/SIGINT) it sends `stop` and waits for `bye`.
Behaviour from the scene (JSON), key "coupler":
  freeze_at_step: N     stop everything at step N, ignoring SIGTERM (only SIGKILL ends it)
  ignore_sigterm: true  SIGTERM and SIGINT are ignored
  exit_at_step: [N, C]  exit with code C at step N (after an error event when C != 0)
  never_detect: true    wait for missing replies forever (no hang or lost-connection detection)
and top-level "steps", "step_seconds", "end_time", "hang_timeout", "solvers".
Exit codes: 0 completed, 2 bad input, 3 a solver failed or hung, 130 stopped by a signal.
"""
import argparse
import json
import os
import select
import signal
import socket
import sys
import time

stop_requested = False


def emit(**event):
    sys.stdout.write(json.dumps(event) + "\n")
    sys.stdout.flush()


def on_stop_signal(_number, _frame):
    global stop_requested
    stop_requested = True


class Link:
    def __init__(self, connection):
        self.connection = connection
        self.buffer = b""
        self.role = None
        self.pid = None
        self.closed = False

    def send(self, text):
        try:
            self.connection.sendall((text + "\n").encode())
        except OSError:
            pass

    def read_line(self):
        """A complete line if one is buffered, '' on EOF, None when nothing yet."""
        if b"\n" in self.buffer:
            line, self.buffer = self.buffer.split(b"\n", 1)
            return line.decode()
        return None

    def receive(self):
        """Read what is available; returns False on EOF."""
        data = self.connection.recv(4096)
        if not data:
            return False
        self.buffer += data
        return True


def fail(role, message, code=3):
    emit(event="error", process=role, message=message)
    emit(event="done", summary="summary.json", status="failed")
    sys.exit(code)


def collect_goodbyes(links, timeout):
    """Wait up to `timeout` for `bye` from every link; a solver that is gone is not waited for."""
    waiting = list(links)
    deadline = time.monotonic() + timeout
    while waiting and time.monotonic() < deadline:
        for link in list(waiting):
            line = link.read_line()
            while line is not None and line != "bye":
                line = link.read_line()
            if line == "bye":
                waiting.remove(link)
        readable, _, _ = select.select([link.connection for link in waiting], [], [], 0.05)
        for link in list(waiting):
            if link.connection in readable:
                try:
                    alive = link.receive()
                except OSError:
                    alive = False
                if not alive:
                    waiting.remove(link)


def wait_for_lines(links, expected, timeout, detect):
    """Wait until every link has sent `expected`; fail on EOF or after `timeout` (when `detect`)."""
    waiting = {link: None for link in links}
    deadline = time.monotonic() + timeout
    while waiting:
        if stop_requested:
            return False
        for link in list(waiting):
            line = link.read_line()
            if line is not None:
                if line != expected:
                    fail(link.role, "protocol error: expected '{}', got '{}'".format(expected, line))
                del waiting[link]
        if not waiting:
            break
        if detect and time.monotonic() > deadline:
            link = next(iter(waiting))
            fail(link.role, "hung: no message for {:g} s (hang_timeout)".format(timeout))
        readable, _, _ = select.select([link.connection for link in waiting if not link.closed], [], [], 0.05)
        for link in list(waiting):
            if link.connection in readable and not link.receive():
                if detect:
                    fail(link.role, "connection lost (the process ended)")
                link.closed = True  # like ZeroMQ: a vanished peer just stays silent
        time.sleep(0.05 if all(link.closed for link in waiting) else 0)
    return True


def write_summary(out_dir, status, steps):
    with open(os.path.join(out_dir, "summary.json"), "w", encoding="utf-8") as handle:
        json.dump({"status": status, "steps": steps}, handle)


def listen(endpoint):
    if endpoint.startswith("ipc://"):
        server = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        server.bind(endpoint[len("ipc://"):])
        server.listen(8)
        return server, endpoint
    host, port = endpoint[len("tcp://"):].rsplit(":", 1)
    server = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    server.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    server.bind((host, int(port)))
    server.listen(8)
    return server, "tcp://{}:{}".format(host, server.getsockname()[1])


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--scene", required=True)
    parser.add_argument("--endpoint", required=True)
    parser.add_argument("--out", required=True)
    parser.add_argument("--keys")  # the run's key set: the fakes speak no ZeroMQ, and need none
    args = parser.parse_args()
    with open(args.scene, encoding="utf-8") as handle:
        scene = json.load(handle)
    behaviour = scene.get("coupler", {})
    steps = scene.get("steps", 20)
    step_seconds = scene.get("step_seconds", 0.05)
    end_time = scene.get("end_time", 1.0)
    hang_timeout = scene.get("hang_timeout", 1.0)
    roles = scene.get("solvers", ["dem_solver", "fem_solver"])
    detect = not behaviour.get("never_detect", False)
    handler = signal.SIG_IGN if behaviour.get("ignore_sigterm") else on_stop_signal
    signal.signal(signal.SIGTERM, handler)
    signal.signal(signal.SIGINT, handler)
    print("fake coupler starting, pid {}".format(os.getpid()), file=sys.stderr, flush=True)

    server, endpoint = listen(args.endpoint)
    emit(event="listening", endpoint=endpoint)
    links = []
    server.settimeout(0.1)
    deadline = time.monotonic() + max(5.0, hang_timeout)
    while len(links) < len(roles):
        if stop_requested:
            write_summary(args.out, "stopped", 0)
            emit(event="done", summary="summary.json", status="stopped")
            return 130
        if time.monotonic() > deadline:
            fail("coupler", "only {} of {} solvers connected".format(len(links), len(roles)))
        try:
            connection, _ = server.accept()
        except socket.timeout:
            continue
        connection.setblocking(True)
        link = Link(connection)
        line = link.read_line()
        while line is None:
            if not link.receive():
                fail("coupler", "a solver disconnected before registering")
            line = link.read_line()
        _, link.role, link.pid = line.split()
        links.append(link)
        emit(event="registered", role=link.role, pid=int(link.pid), name="fake " + link.role)

    dt = end_time / steps
    started = time.monotonic()
    steps_done = 0
    for step in range(steps):
        if behaviour.get("freeze_at_step") == step:
            signal.signal(signal.SIGTERM, signal.SIG_IGN)
            signal.signal(signal.SIGINT, signal.SIG_IGN)
            while True:
                time.sleep(1)
        exit_at = behaviour.get("exit_at_step")
        if exit_at and exit_at[0] == step:
            if exit_at[1] != 0:
                emit(event="error", process="coupler", message="fake failure with code {}".format(exit_at[1]))
            return exit_at[1]
        if stop_requested:
            break
        for link in links:
            link.send("step {}".format(step))
        if not wait_for_lines(links, "ok {}".format(step), hang_timeout, detect):
            break
        time.sleep(step_seconds)
        elapsed = time.monotonic() - started
        rate = (step + 1) / elapsed if elapsed > 0 else 0.0
        steps_done = step + 1
        emit(event="progress", step=step + 1, time=(step + 1) * dt, end_time=end_time, dt=dt,
             steps_per_second=rate, eta_seconds=(steps - step - 1) / rate if rate > 0 else None)

    status = "stopped" if stop_requested else "completed"
    emit(event="stopping", reason=status)
    for link in links:
        link.send("stop")
    collect_goodbyes(links, 2.0)
    write_summary(args.out, status, steps_done)
    emit(event="done", summary="summary.json", status=status)
    return 130 if status == "stopped" else 0


if __name__ == "__main__":
    sys.exit(main())
