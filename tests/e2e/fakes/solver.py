"""A fake solver for the supervisor tests (see coupler.py for the protocol).

    solver.py --role ROLE --scene SCENE --coupler ENDPOINT --out DIR

Behaviour from the scene (JSON), key ROLE:
  exit_at_step: [N, C]   print a few log lines, then exit with code C on step N
  hang_at_step: N        stop answering at step N (keeps running)
  signal_at_step: [N, S] kill itself with signal number S on step N
On SIGTERM it logs and exits with 130, like a real solver.
"""
import argparse
import json
import os
import signal
import socket
import sys
import time


def log(text):
    print("[{}] {}".format(os.getpid(), text), file=sys.stderr, flush=True)


def on_sigterm(_number, _frame):
    log("stopping on SIGTERM")
    sys.exit(130)


def connect(endpoint, timeout=10.0):
    deadline = time.monotonic() + timeout
    while True:
        try:
            if endpoint.startswith("ipc://"):
                connection = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
                connection.connect(endpoint[len("ipc://"):])
            else:
                host, port = endpoint[len("tcp://"):].rsplit(":", 1)
                connection = socket.create_connection((host, int(port)))
            return connection
        except OSError:
            if time.monotonic() > deadline:
                raise
            time.sleep(0.05)


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--role", required=True)
    parser.add_argument("--scene", required=True)
    parser.add_argument("--coupler", required=True)
    parser.add_argument("--out", required=True)
    parser.add_argument("--keys")  # the run's key set: the fakes speak no ZeroMQ, and need none
    args = parser.parse_args()
    signal.signal(signal.SIGTERM, on_sigterm)
    with open(args.scene, encoding="utf-8") as handle:
        behaviour = json.load(handle).get(args.role, {})
    log("{} connecting to {}".format(args.role, args.coupler))
    connection = connect(args.coupler)
    connection.sendall("register {} {}\n".format(args.role, os.getpid()).encode())
    try:
        return serve(connection, args, behaviour)
    except OSError as error:
        log("lost the coupler: {}".format(error))
        return 1


def serve(connection, args, behaviour):
    stream = connection.makefile("r")
    for line in stream:
        words = line.split()
        if words == ["stop"]:
            with open(os.path.join(args.out, args.role + ".out"), "w", encoding="utf-8") as handle:
                handle.write("final state\n")
            connection.sendall(b"bye\n")
            log("stopped by the coupler")
            return 0
        step = int(words[1])
        exit_at = behaviour.get("exit_at_step")
        if exit_at and exit_at[0] == step:
            for index in range(15):
                log("diagnostic line {}".format(index))
            log("failing on purpose at step {} with code {}".format(step, exit_at[1]))
            return exit_at[1]
        signal_at = behaviour.get("signal_at_step")
        if signal_at and signal_at[0] == step:
            log("killing myself with signal {}".format(signal_at[1]))
            os.kill(os.getpid(), signal_at[1])
            time.sleep(5)
        if behaviour.get("hang_at_step") == step:
            log("hanging at step {}".format(step))
            while True:
                time.sleep(1)
        connection.sendall("ok {}\n".format(step).encode())
    log("the coupler closed the connection")
    return 1


if __name__ == "__main__":
    sys.exit(main())
