"""The launch plan of a run: which processes to start, with which command lines.

`sabo_scene check SCENE --bin-dir DIR` validates the scene and prints the plan
as one JSON object:

    {"scene": "/abs/scene.toml", "end_time": 2.0, "output_interval": 0.01,
     "hang_timeout": 10.0, "endpoint": "ipc" | "tcp" | "tcp://HOST:PORT",
     "tcp_security": "curve" | "none", "connect_host": "head-node" (optional),
     "processes": [{"role": "coupler", "command": ["/abs/coupler"]},
                   {"role": "dem_solver", "command": ["/abs/dem_solver"],
                    "launcher": ["ssh", "node2"], "by_hand": false (both optional)}, ...]}

Exit status 2 with the errors on stderr means the scene is wrong.
For debugging, the environment variable SABO_PLAN_OVERRIDE may name a JSON
file holding a plan; it replaces the scene check (e.g. to run a solver under
gdb or valgrind by editing its command).
"""
from __future__ import annotations

import json
import os
import subprocess
import sys

from .errors import SaboError, EXIT_BAD_INPUT, EXIT_FAILED
from .processes import describe_exit

COUPLER_ROLE = "coupler"
PLAN_OVERRIDE_VARIABLE = "SABO_PLAN_OVERRIDE"


class ProcessSpec:
    def __init__(self, role: str, command: list[str], launcher: list[str] | None = None, by_hand: bool = False) -> None:
        self.role = role
        self.command = list(command)
        self.launcher = list(launcher or [])  # a prefix that places the process (["ssh", "node2"]); empty: here
        self.by_hand = by_hand                # the supervisor does not start it: a user does (docs/cluster.md)


class LaunchPlan:
    def __init__(self, scene: str | None, end_time: float, output_interval: float, hang_timeout: float,
                 endpoint: str, processes: list[ProcessSpec], restart: str = "off", max_restarts: int = 0,
                 tcp_security: str = "curve", connect_host: str | None = None,
                 registration_timeout: float = 30.0) -> None:
        self.scene = scene
        self.registration_timeout = registration_timeout  # s the coupler waits for the solvers to register
        self.tcp_security = tcp_security  # "curve" or "none" (docs/security.md)
        self.connect_host = connect_host  # where launched solvers connect to; None: the endpoint's address
        self.restart = restart            # "auto": restart a solver that dies from its newest checkpoint
        self.max_restarts = max_restarts  # per solver
        self.end_time = end_time
        self.output_interval = output_interval
        self.hang_timeout = hang_timeout
        self.endpoint = endpoint
        self.processes = processes  # the coupler first, then the solvers in plan order

    @property
    def coupler(self) -> ProcessSpec:
        return self.processes[0]

    @property
    def solvers(self) -> list[ProcessSpec]:
        return self.processes[1:]


def _number(plan: dict, key: str, source: str, positive: bool = True) -> float:
    value = plan.get(key)
    if isinstance(value, bool) or not isinstance(value, (int, float)) or (positive and not value > 0):
        raise SaboError(f"{source}: launch plan key \"{key}\" must be a positive number, got {value!r}",
                        EXIT_FAILED)
    return float(value)


def parse_plan(text: str, source: str) -> LaunchPlan:
    """The LaunchPlan in JSON `text`; `source` names where it came from, for errors."""
    try:
        plan = json.loads(text)
    except ValueError as error:
        raise SaboError(f"{source}: the launch plan is not valid JSON: {error}", EXIT_FAILED)
    if not isinstance(plan, dict):
        raise SaboError(f"{source}: the launch plan must be a JSON object", EXIT_FAILED)

    endpoint = plan.get("endpoint", "ipc")
    if not isinstance(endpoint, str) or not (endpoint in ("ipc", "tcp") or endpoint.startswith("tcp://")):
        raise SaboError(f"{source}: launch plan key \"endpoint\" must be \"ipc\", \"tcp\" or \"tcp://HOST:PORT\", "
                        f"got {endpoint!r}", EXIT_FAILED)
    tcp_security = plan.get("tcp_security", "curve")
    if tcp_security not in ("curve", "none"):
        raise SaboError(f"{source}: launch plan key \"tcp_security\" must be \"curve\" or \"none\", got "
                        f"{tcp_security!r}", EXIT_FAILED)
    connect_host = plan.get("connect_host")
    if connect_host is not None and (not isinstance(connect_host, str) or not connect_host):
        raise SaboError(f"{source}: launch plan key \"connect_host\" must be a host name, got {connect_host!r}",
                        EXIT_FAILED)

    entries = plan.get("processes")
    if not isinstance(entries, list) or not entries:
        raise SaboError(f"{source}: launch plan key \"processes\" must be a non-empty list", EXIT_FAILED)
    processes = []
    for index, entry in enumerate(entries):
        where = f"{source}: processes[{index}]"
        if not isinstance(entry, dict):
            raise SaboError(f"{where} must be an object with \"role\" and \"command\"", EXIT_FAILED)
        role, command, launcher = entry.get("role"), entry.get("command"), entry.get("launcher", [])
        by_hand = entry.get("by_hand", False)
        if not isinstance(role, str) or not role or "/" in role:
            raise SaboError(f"{where}: \"role\" must be a name such as \"dem_solver\", got {role!r}",
                            EXIT_FAILED)
        if (not isinstance(command, list) or not command or
                not all(isinstance(part, str) and part for part in command)):
            raise SaboError(f"{where} ({role}): \"command\" must be a non-empty list of strings, got {command!r}",
                            EXIT_FAILED)
        if not isinstance(launcher, list) or not all(isinstance(part, str) and part for part in launcher):
            raise SaboError(f"{where} ({role}): \"launcher\" must be a list of strings, got {launcher!r}",
                            EXIT_FAILED)
        if any(spec.role == role for spec in processes):
            raise SaboError(f"{where}: role \"{role}\" appears twice", EXIT_FAILED)
        if not isinstance(by_hand, bool):
            raise SaboError(f"{where} ({role}): \"by_hand\" must be true or false, got {by_hand!r}", EXIT_FAILED)
        processes.append(ProcessSpec(role, command, launcher, by_hand))
    couplers = [spec for spec in processes if spec.role == COUPLER_ROLE]
    if len(couplers) != 1:
        raise SaboError(f"{source}: the launch plan must have exactly one process with role \"coupler\"",
                        EXIT_FAILED)
    processes = couplers + [spec for spec in processes if spec.role != COUPLER_ROLE]

    return LaunchPlan(scene=plan.get("scene"),
                      end_time=_number(plan, "end_time", source),
                      output_interval=_number(plan, "output_interval", source),
                      hang_timeout=_number(plan, "hang_timeout", source),
                      endpoint=endpoint,
                      processes=processes,
                      restart=plan.get("restart", "off"),
                      max_restarts=int(plan.get("max_restarts", 0)),
                      tcp_security=tcp_security,
                      connect_host=connect_host,
                      registration_timeout=float(plan.get("registration_timeout", 30.0)))


def check_scene(scene: str, bin_dir: str) -> LaunchPlan:
    """Validate `scene` with sabo_scene and return its LaunchPlan; SaboError(exit 2) on scene errors."""
    override = os.environ.get(PLAN_OVERRIDE_VARIABLE)
    if override:
        try:
            with open(override, encoding="utf-8") as handle:
                text = handle.read()
        except OSError as error:
            raise SaboError(f"{PLAN_OVERRIDE_VARIABLE}={override}: {error.strerror}", EXIT_BAD_INPUT)
        return parse_plan(text, f"{PLAN_OVERRIDE_VARIABLE}={override}")

    checker = os.path.join(bin_dir, "sabo_scene")
    if not os.access(checker, os.X_OK):
        raise SaboError(f"{checker} is missing: build the project with `./sabo setup`", EXIT_FAILED)
    result = subprocess.run([checker, "check", scene, "--bin-dir", bin_dir], stdin=subprocess.DEVNULL,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, universal_newlines=True,
                            errors="replace")
    errors = result.stderr.rstrip("\n")
    if result.returncode == 2:
        raise SaboError(errors or f"{scene}: the scene has errors (sabo_scene gave no details)",
                        EXIT_BAD_INPUT)
    if result.returncode != 0:
        raise SaboError(f"sabo_scene {describe_exit(result.returncode)} while checking {scene}"
                        + (":\n" + errors if errors else ""), EXIT_FAILED)
    if errors:  # warnings
        print(errors, file=sys.stderr)
    return parse_plan(result.stdout, f"sabo_scene check {scene}")
