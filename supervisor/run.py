"""`./sabo run`: supervise one coupled run.

The coupler starts first; its stdout is a stream of JSON event lines (see
docs/protocol.md, "What the supervisor expects from the coupler"). When it reports
`listening`, the solvers start. Every ~100 ms the supervisor reads events and
polls every process; whatever goes wrong (a process dies, a solver exits too
early, the coupler reports a failure, nothing progresses, the user presses
Ctrl-C) ends with every process stopped and a report naming the culprit.
"""
from __future__ import annotations

import json
import os
import selectors
import shutil
import signal
import socket
import stat
import subprocess
import tempfile
import time
from typing import TYPE_CHECKING, Iterable

from .display import format_duration, format_progress, list_run_folder, wrap_items
from .errors import EXIT_OK, EXIT_FAILED, EXIT_BAD_INPUT, EXIT_INTERRUPTED
from . import run_folder
from .processes import describe_exit, signal_name, start_process

if TYPE_CHECKING:
    from types import FrameType

    from .display import Display
    from .plan import LaunchPlan, ProcessSpec
    from .processes import ManagedProcess

POLL_INTERVAL_S = 0.1
# SIGTERM -> SIGKILL when stopping after a fault. The coupler needs some of it to give up waiting for
# the dead solver's goodbye and close traffic.h5 and the summary.
FAULT_GRACE_S = 5.0
EARLY_EXIT_GRACE_S = 3.0     # beyond hang_timeout, for a solver that left early with code 0
INTERRUPT_GRACE_S = 5.0      # Ctrl-C: time for the coupler to stop the solvers cleanly
SETTLE_S = 0.5              # after a solver died: time for the coupler to react before judging
FINISH_GRACE_S = 10.0        # solvers' time to exit once the coupler has completed
SOLVER_TERM_DELAY_S = 1.0    # Ctrl-C: solvers still alive this long after the coupler exited get SIGTERM
MAX_UNIX_SOCKET_PATH = 100   # bytes; sun_path holds 108 with the NUL, keep a margin
WATCHDOG_MIN_VARIABLE = "SABO_WATCHDOG_MIN_S"
DEFAULT_WATCHDOG_MIN_S = 30.0
LOG_TAIL_LINES = 10

COUPLER_EXIT_COMPLETED = 0
COUPLER_EXIT_BAD_INPUT = 2
COUPLER_EXIT_SOLVER_FAILED = 3
COUPLER_EXIT_STOPPED = 130

EVENTS_FILE = "coupler.events.jsonl"
PIDS_FILE = "pids.json"


class Outcome:
    def __init__(self, status: str, exit_code: int, reason: str | None = None) -> None:
        self.status = status        # "completed", "failed", "stopped", "bad input"
        self.exit_code = exit_code
        self.reason = reason


def resolve_endpoint(plan_endpoint: str, run_dir: str) -> tuple[str, str | None]:
    """(endpoint for the coupler and solvers, temporary folder to remove at the end or None). The ipc socket
    sits in the run folder (0700) or, when that path is too long for a socket, in a folder of /tmp that
    mkdtemp makes 0700: only the user can enter either."""
    if plan_endpoint == "tcp":
        return "tcp://127.0.0.1:*", None
    if plan_endpoint != "ipc":
        return plan_endpoint, None
    path = os.path.join(os.path.abspath(run_dir), "coupler.sock")
    if len(os.fsencode(path)) <= MAX_UNIX_SOCKET_PATH:
        return "ipc://" + path, None
    folder = tempfile.mkdtemp(prefix="sabo-", dir="/tmp")
    return "ipc://" + os.path.join(folder, "coupler.sock"), folder


def watchdog_seconds(hang_timeout: float) -> float:
    minimum = DEFAULT_WATCHDOG_MIN_S
    text = os.environ.get(WATCHDOG_MIN_VARIABLE)
    if text:
        try:
            minimum = max(0.1, float(text))
        except ValueError:
            pass
    return max(3.0 * hang_timeout, minimum)


def connect_endpoint(endpoint: str, launched: bool, connect_host: str | None) -> str:
    """Where a solver connects to the coupler listening on `endpoint` (as it reported it): a solver started
    through a launcher may be on another host, which reaches the coupler at `connect_host` (or this machine's
    name) when the coupler listens on every interface."""
    if not launched or not endpoint.startswith("tcp://"):
        return endpoint
    host, port = endpoint[len("tcp://"):].rsplit(":", 1)
    if connect_host:
        host = connect_host
    elif host in ("0.0.0.0", "*"):
        host = socket.getfqdn()
    return f"tcp://{host}:{port}"


def started_by(peer_pid: int, process: ManagedProcess) -> bool:
    """The process the kernel names at the other end of an ipc connection is `process` or one of the processes
    it started (its process group: the supervisor starts each in a session of its own)."""
    if peer_pid == process.pid:
        return True
    try:
        return os.getpgid(peer_pid) == process.pid
    except OSError:
        return False


class Supervisor:
    def __init__(self, plan: LaunchPlan, scene: str, run_dir: str, display: Display, bin_dir: str | None = None,
                 resume: tuple[int, dict[str, str]] | None = None, keys: str | None = None) -> None:
        """`resume`: (step, {role: checkpoint path}) to continue the run in `run_dir` from (`./sabo resume`), with
        the coupler's checkpoint under "coupler"; None: a new run. `keys`: a key set (`./sabo keys DIR`) to copy
        into RUN_DIR/keys instead of making a new one."""
        self.plan = plan
        self._resume = resume
        self._resume_reason = "./sabo resume" if resume is not None else None
        self.bin_dir = bin_dir  # the built tools (sabo_traffic, sabo_keys)
        self._keys_source = keys
        self.keys_dir = None         # RUN_DIR/keys once made; None: the processes run without keys
        self.scene = os.path.abspath(scene)
        self.run_dir = os.path.abspath(run_dir)
        self.display = display
        self.endpoint, self._socket_folder = resolve_endpoint(plan.endpoint, self.run_dir)
        self.watchdog_s = watchdog_seconds(plan.hang_timeout)
        # A solver that exits cleanly before the coupler says the run is ending: the coupler
        # should notice within hang_timeout and explain; after that the supervisor does.
        self.early_exit_grace_s = plan.hang_timeout + EARLY_EXIT_GRACE_S

        self.processes = []          # ManagedProcess, coupler first, in start order
        self._interrupts = []        # signal numbers received
        self._previous_handlers = {}
        self._selector = None
        self._pipe = None            # the coupler's stdout
        self._buffer = b""
        self._events = None          # coupler.events.jsonl
        self._solvers_started = False
        self._solver_endpoint = None
        self._restarts = {}  # role -> restarts so far
        self._start_failure = None
        self._stopping = False       # the coupler said the run is ending
        self._done = None            # the done event
        self._errors = []            # error events
        self._registered = set()     # roles the coupler reported registered
        self._impostor = None        # why a registration came from a process the supervisor did not start
        self._last_progress = None   # last progress event
        self._last_activity = None   # monotonic time of the last progress (watchdog)
        self._started_at = None

    # ----------------------------------------------------------------------------- public

    def run(self) -> int:
        """Run to the end; returns the exit code of `./sabo run`."""
        self._started_at = time.monotonic()
        self._last_activity = self._started_at
        self._install_signal_handlers()
        outcome = Outcome("failed", EXIT_FAILED, "internal error")
        try:
            self._events = open(os.path.join(self.run_dir, EVENTS_FILE), "a", encoding="utf-8")
            self._write_pids()
            if self._resume is None:
                run_folder.write_run_file(self.run_dir, self.scene)
            problem = self._prepare_keys()
            outcome = self._outcome_failed(problem) if problem else self._start_and_supervise()
        finally:
            self._kill_leftovers()
            self._close_pipe()
            if self._events is not None:
                self._events.close()
            self._remove_socket()
            self._restore_signal_handlers()
        self._after_a_crash(outcome)
        self._report(outcome)
        return outcome.exit_code

    # ------------------------------------------------------------------------ signals

    def _install_signal_handlers(self) -> None:
        for number in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):
            self._previous_handlers[number] = signal.signal(number, self._on_signal)

    def _restore_signal_handlers(self) -> None:
        for number, handler in self._previous_handlers.items():
            signal.signal(number, handler if handler is not None else signal.SIG_DFL)

    def _on_signal(self, number: int, _frame: FrameType | None) -> None:
        self._interrupts.append(number)

    # --------------------------------------------------------------------------- keys

    def _prepare_keys(self) -> str | None:
        """RUN_DIR/keys: the key set every process of the run proves itself with (docs/security.md), made by
        sabo_keys, copied from --keys, or kept from the run being resumed. None, or why the run cannot start."""
        folder = os.path.join(self.run_dir, run_folder.KEYS_FOLDER)
        if self._keys_source is not None:
            try:
                run_folder.copy_key_set(self._keys_source, folder)
            except OSError as error:
                return f"--keys {self._keys_source}: cannot copy the key set: {error}"
        elif not os.path.isfile(os.path.join(folder, run_folder.TOKEN_FILE)):
            tool = os.path.join(self.bin_dir or "", "sabo_keys")
            if self.bin_dir is None or not os.access(tool, os.X_OK):
                return f"{tool} is missing: build the project with `./sabo setup`"
            result = subprocess.run([tool, folder, "--force"], stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                                    stderr=subprocess.PIPE, universal_newlines=True, errors="replace")
            if result.returncode != 0:
                return f"could not make the run's keys: {result.stderr.strip() or describe_exit(result.returncode)}"
        self.keys_dir = folder
        return None

    def _security_arguments(self) -> list[str]:
        """--keys for every process, but over tcp with tcp_security = "none" (nothing to prove there)."""
        in_clear = self.endpoint.startswith("tcp://") and self.plan.tcp_security == "none"
        return ["--keys", self.keys_dir] if self.keys_dir and not in_clear else []

    def _solver_command(self, spec: ProcessSpec, endpoint: str, extra: list[str]) -> list[str]:
        """The command line of a solver: its launcher, its program, and the arguments every solver takes."""
        target = connect_endpoint(endpoint, bool(spec.launcher), self.plan.connect_host)
        return (spec.launcher + spec.command + ["--scene", self.scene, "--coupler", target, "--out", self.run_dir] +
                self._security_arguments() + extra)

    def _ask_for(self, spec: ProcessSpec, endpoint: str) -> None:
        """A role started by hand: say how, once the coupler listens."""
        target = connect_endpoint(endpoint, True, self.plan.connect_host)
        keys = (f" --keys DIR (a copy of {os.path.join(self.keys_dir, 'coupler.key')} and of "
                f"{os.path.join(self.keys_dir, spec.role + '.key_secret')}, mode 0600)") if self.keys_dir else ""
        self.display.info(f"sabo: waiting for {spec.role}, started by hand within {self.plan.registration_timeout:g} s: "
                          f"{spec.role} --scene {self.scene} --coupler {target} --out DIR{keys}")

    # ---------------------------------------------------------------------- processes

    @property
    def coupler(self) -> ManagedProcess | None:
        return self.processes[0] if self.processes else None

    @property
    def solvers(self) -> list[ManagedProcess]:
        return self.processes[1:]

    def _running(self, processes: Iterable[ManagedProcess] | None = None) -> list[ManagedProcess]:
        return [p for p in (self.processes if processes is None else processes) if p.running]

    def _start(self, spec: ProcessSpec, command: list[str], pipe: bool) -> ManagedProcess:
        process = start_process(spec.role, command, self.run_dir, os.path.join(self.run_dir, spec.role + ".log"),
                                stdout_to_pipe=pipe)
        self.processes.append(process)
        self._write_pids()
        return process

    def _write_pids(self) -> None:
        pids = {"supervisor": os.getpid()}
        for process in self.processes:
            pids[process.role] = process.pid
        path = os.path.join(self.run_dir, PIDS_FILE)
        with open(path + ".tmp", "w", encoding="utf-8") as handle:
            json.dump(pids, handle, indent=2)
            handle.write("\n")
        os.replace(path + ".tmp", path)

    def _start_and_supervise(self) -> Outcome:
        problem = self._start_coupler()
        if problem is not None:
            return self._outcome_failed(problem)
        return self._supervise()

    def _start_coupler(self) -> str | None:
        """Starts the coupler (from its checkpoint when resuming); None, or why it could not be started."""
        spec = self.plan.coupler
        arguments = ["--scene", self.scene, "--endpoint", self.endpoint, "--out", self.run_dir]
        arguments += self._security_arguments()
        if self._resume is not None:
            arguments += ["--resume", self._resume[1]["coupler"], "--resume-reason", self._resume_reason]
        try:
            coupler = self._start(spec, spec.command + arguments, pipe=True)
        except OSError as error:
            return f"could not start the coupler: {spec.command[0]}: {error.strerror}"
        self._pipe = coupler.popen.stdout
        os.set_blocking(self._pipe.fileno(), False)
        self._selector = selectors.DefaultSelector()
        self._selector.register(self._pipe, selectors.EVENT_READ)
        return None

    def _start_solvers(self, endpoint: str) -> str | None:
        self._solvers_started = True
        self._solver_endpoint = endpoint
        for spec in self.plan.solvers:
            if self._interrupts:
                return
            if spec.by_hand:
                self._ask_for(spec, endpoint)
                continue
            extra = ["--resume", self._resume[1][spec.role]] if self._resume is not None else []
            try:
                self._start(spec, self._solver_command(spec, endpoint, extra), pipe=False)
            except OSError as error:
                self._start_failure = f"could not start {spec.role}: {spec.command[0]}: {error.strerror}"
                return

    # ------------------------------------------------------------------ the main loop

    def _supervise(self) -> Outcome:
        while True:
            self._pump(POLL_INTERVAL_S)
            now = time.monotonic()
            if self._interrupts:
                return self._stop_on_interrupt()
            if self._start_failure:
                return self._fail(self._start_failure)
            if self._impostor:
                return self._fail(self._impostor)
            if self.coupler.poll() is not None:
                if not self._coupler_may_restart():
                    return self._on_coupler_exit()
                dead = self.coupler
                problem = self._restart_coupler()
                if problem is None:
                    continue
                return self._fail(problem, culprits=[dead])
            failed = self._failed_solvers()
            if failed:
                # The coupler may be going down at the same moment, and the solver only because of it
                # (the coupler's exit code and error events then tell the story): let it settle.
                # A solver killed by a signal is restarted at once (the coupler waits hang_timeout for it).
                if not all(p.returncode < 0 for p in failed):
                    self._wait_for_exit(self.coupler, SETTLE_S)
                if self.coupler.poll() is not None:
                    return self._on_coupler_exit(failed)
                refused = [reason for reason in (self._restart(p) for p in failed) if reason]
                if not refused:
                    continue
                # What the solver told the coupler before it went (an instability, a model error) is the why.
                reported = ["the coupler reports: " + self._error_text()] if self._errors else []
                return self._fail("; ".join(refused + reported), culprits=failed)
            for solver in self.solvers:
                if solver.poll() is None or solver.handled:
                    continue
                if self._stopping:
                    solver.handled = True
                elif solver.role not in self._registered and now - solver.exited_at >= SETTLE_S:
                    # It never registered, so the coupler will only notice it at its registration timeout.
                    solver.handled = True
                    return self._fail(f"{solver.role} (pid {solver.pid}) exited with code 0 "
                                      f"{solver.exited_at - solver.started_at:.1f} s after it started, before registering "
                                      "with the coupler: the program ended without taking part in the run (its "
                                      f'command: {" ".join(solver.command)})',
                                      culprits=[solver])
                elif now - solver.exited_at > self.early_exit_grace_s:
                    solver.handled = True
                    return self._fail(f"{solver.role} (pid {solver.pid}) exited with code 0 before the coupler reported "
                                      "the end of the run", culprits=[solver])
            # Before the first step the coupler may wait registration_timeout for a solver started by hand.
            waits_for_hands = self._last_progress is None and any(spec.by_hand for spec in self.plan.solvers)
            watchdog_s = max(self.watchdog_s, self.plan.registration_timeout + EARLY_EXIT_GRACE_S) if (
                waits_for_hands) else self.watchdog_s
            if now - self._last_activity > watchdog_s:
                return self._fail(
                    f"no progress reported by the coupler for {now - self._last_activity:.0f} s while every process is "
                    "alive: the run looks "
                    f"hung (the scene's hang_timeout is {self.plan.hang_timeout:g} s){self._last_progress_text()}",
                    culprits=[self.coupler])

    def _restart(self, process: ManagedProcess) -> str | None:
        """Start `process`'s role again from its newest checkpoint (restart = "auto"); None when it was restarted,
        else the reason the run stops."""
        died = process.describe()
        # Only a death by a signal (a crash, kill -9, the out-of-memory killer) is restarted: a solver that exits
        # with an error code decided to stop (bad input, a failure it reported), and would do so again.
        if self.plan.restart != "auto" or self._stopping or self._interrupts or process.returncode >= 0:
            return died
        count = self._restarts.get(process.role, 0)
        if count >= self.plan.max_restarts:
            return f"{died}; it was restarted {count} times already (max_restarts = {self.plan.max_restarts})"
        found = run_folder.checkpoints(self.run_dir, process.role)
        checkpoint = max(found.items()) if found else None
        if checkpoint is None:
            return f"{died}; no checkpoint of it to restart from yet (the first comes at [run] checkpoint_interval)"
        step, path = checkpoint
        spec = next(p for p in self.plan.solvers if p.role == process.role)
        try:
            replacement = start_process(spec.role, self._solver_command(spec, self._solver_endpoint, ["--resume", path]),
                                        self.run_dir, os.path.join(self.run_dir, spec.role + ".log"),
                                        stdout_to_pipe=False)
        except OSError as error:
            return f"{died}; could not start it again: {error.strerror}"
        process.sweep()
        self.processes[self.processes.index(process)] = replacement
        self._write_pids()
        self._restarts[process.role] = count + 1
        self._last_activity = time.monotonic()
        self.display.error(f"sabo: {died}; restarting it from its checkpoint of step {step} (pid {replacement.pid}, "
                           f"restart {count + 1} of {self.plan.max_restarts})")
        return None

    def _coupler_may_restart(self) -> bool:
        """The coupler died by a signal (a crash, kill -9) in a run that restarts its processes."""
        coupler = self.coupler
        return (self.plan.restart == "auto" and coupler.returncode is not None and coupler.returncode < 0 and
                not self._stopping and not self._interrupts)

    def _restart_coupler(self) -> str | None:
        """Every process starts again from the newest checkpoint common to all of them (docs/restart.md, "Restart
        of the coupler"); None when the run goes on, else why it stops."""
        coupler = self.coupler
        self._drain_pipe(0.5)
        died = coupler.describe()
        if self._last_progress is not None:
            died += f' at step {self._last_progress.get("step")}'
        count = self._restarts.get("coupler", 0)
        if count >= self.plan.max_restarts:
            return f"{died}; it was restarted {count} times already (max_restarts = {self.plan.max_restarts})"
        # The solvers wait for the dead coupler's reply: they stop, their checkpoints stay.
        self._terminate(self._running(self.solvers), FAULT_GRACE_S)
        roles = ["coupler"] + [spec.role for spec in self.plan.solvers]
        common = run_folder.common_checkpoint(self.run_dir, roles)
        if common is None:
            return (f'{died}; no checkpoint common to {", ".join(roles)} to resume from yet (the first comes at [run] '
                    "checkpoint_interval)")
        self._close_pipe()
        for process in self.processes:
            process.handled = True
            process.sweep()
        self.processes = []
        self._remove_socket()
        self._resume = common
        self._resume_reason = died
        self._solvers_started = False
        self._registered = set()
        self._restarts["coupler"] = count + 1
        self._last_activity = time.monotonic()
        self.display.error(f"sabo: {died}; resuming every process from their checkpoints of step {common[0]} "
                           f"(restart {count + 1} of {self.plan.max_restarts})")
        return self._start_coupler()

    def _last_progress_text(self) -> str:
        if self._last_progress is None:
            return "; no progress event at all"
        return f'; last progress: step {self._last_progress.get("step")}, t = {self._last_progress.get("time")}'

    # ---------------------------------------------------------------------- endings

    def _outcome_failed(self, reason: str) -> Outcome:
        self.display.error("sabo: " + reason)
        return Outcome("failed", EXIT_FAILED, reason)

    def _show_log_tail(self, process: ManagedProcess) -> None:
        lines = process.log_tail(LOG_TAIL_LINES)
        if not lines:
            self.display.error(f"sabo: {self._relative(process.log_path)} is empty")
            return
        self.display.error(f"sabo: last lines of {self._relative(process.log_path)}:")
        for line in lines:
            self.display.error("    " + line)

    def _fail(self, reason: str, culprits: Iterable[ManagedProcess] = ()) -> Outcome:
        """Report `reason` (and the culprits' log tails), stop every process, return a failed outcome."""
        outcome = self._outcome_failed(reason)
        shown = set()
        for culprit in culprits:
            if culprit.role not in shown:
                shown.add(culprit.role)
                self._show_log_tail(culprit)
        self._terminate(self._running(), FAULT_GRACE_S)
        return outcome

    def _failed_solvers(self) -> list[ManagedProcess]:
        """Solvers that ended with a non-zero code or a signal, not yet reported; killed by a signal first."""
        failed = [p for p in self.solvers if not p.handled and p.poll() is not None and p.returncode != 0]
        for process in failed:
            process.handled = True
        return sorted(failed, key=lambda p: p.returncode > 0)

    def _terminate(self, processes: list[ManagedProcess], grace_s: float) -> None:
        """SIGTERM `processes`, SIGKILL those still alive after `grace_s` (at once on a new Ctrl-C)."""
        processes = [p for p in processes if p.running]
        if not processes:
            return
        interrupts_before = len(self._interrupts)
        for process in processes:
            process.send(signal.SIGTERM)
        deadline = time.monotonic() + grace_s
        why = f"{grace_s:g} s after SIGTERM"
        while self._running(processes) and time.monotonic() < deadline:
            if len(self._interrupts) > interrupts_before:
                why = "at the interrupt"
                break
            self._pump(POLL_INTERVAL_S)
        self._kill(self._running(processes), why)

    def _kill(self, processes: list[ManagedProcess], why: str) -> None:
        for process in processes:
            self.display.error(f"sabo: {process.role} (pid {process.pid}) still running {why}: killing it (SIGKILL)")
            process.send(signal.SIGKILL)
        for process in processes:
            try:
                process.popen.wait(timeout=5)
            except subprocess.TimeoutExpired:  # unkillable (e.g. stuck in the kernel): nothing more to do
                self.display.error(f"sabo: {process.role} (pid {process.pid}) does not die even with SIGKILL")

    def _error_text(self) -> str:
        return "; ".join(f'{event.get("process", "?")}: {event.get("message", "?")}'
                         for event in self._errors)

    def _process_by_role(self, role: str) -> ManagedProcess | None:
        for process in self.processes:
            if process.role == role:
                return process
        return None

    def _wait_for_exit(self, process: ManagedProcess, timeout_s: float) -> None:
        deadline = time.monotonic() + timeout_s
        while process.running and time.monotonic() < deadline:
            self._pump(0.05)

    def _on_coupler_exit(self, failed_before: Iterable[ManagedProcess] = ()) -> Outcome:
        coupler = self.coupler
        coupler.handled = True
        self._drain_pipe(1.0)
        code = coupler.returncode
        if code == COUPLER_EXIT_COMPLETED:
            return self._finish_completed()
        errors = self._error_text()
        reported = "the coupler reports: " + errors if errors else ""
        # A solver's death is usually why the coupler gave up; it may still be on its way out.
        deadline = time.monotonic() + SETTLE_S
        while self._running(self.solvers) and time.monotonic() < deadline:
            time.sleep(0.02)
        failed = list(failed_before) + self._failed_solvers()
        named = [self._process_by_role(event.get("process")) for event in self._errors]
        failed.sort(key=lambda p: (p not in named, p.returncode > 0))
        if code == COUPLER_EXIT_BAD_INPUT:
            reason = f'the coupler rejected the input (exit code 2){"; " + reported if errors else ""}'
            self.display.error("sabo: " + reason)
            if not errors:
                self._show_log_tail(coupler)
            self._terminate(self._running(), FAULT_GRACE_S)
            return Outcome("bad input", EXIT_BAD_INPUT, reason)
        if code == COUPLER_EXIT_SOLVER_FAILED:
            culprits = failed + [p for p in named if p is not None and p not in failed]
            first = next((p for p in named if p is not None), failed[0] if failed else None)
            return self._fail(self._failure_headline(first, failed, code),
                              culprits=([first] if first is not None else []) + culprits or [coupler])
        if code == COUPLER_EXIT_STOPPED and not failed:
            reason = "the coupler was stopped by a signal that did not come from the supervisor (exit code 130)"
            self.display.error("sabo: " + reason)
            self._terminate(self._running(), INTERRUPT_GRACE_S)
            return Outcome("stopped", EXIT_INTERRUPTED, reason)
        # Killed by a signal first (the likelier cause), then in the order their ends were seen.
        ended = sorted([coupler] + failed, key=lambda p: (p.returncode > 0, p.exited_at or 0.0))
        first = next((p for p in named if p is not None), ended[0])
        return self._fail(self._failure_headline(first, ended, code),
                          culprits=[first] + [p for p in ended if p is not first])

    def _failure_headline(self, first: ManagedProcess | None, failed: list[ManagedProcess], coupler_code: int | None) -> str:
        """The first process that failed and what is known of it, then the peers that ended because of it:
        'sph_solver (pid 12) ...; the coupler reports: sph_solver: ...; stopped because of it: fem_solver (pid
        13) exited with code 130'."""
        parts = []
        if first is not None and first.returncode not in (None, 0):
            parts.append(first.describe())
        first_errors = [e for e in self._errors if first is not None and e.get("process") == first.role]
        other_errors = [e for e in self._errors if e not in first_errors]
        for event in first_errors[:1] + other_errors:
            parts.append(f'the coupler reports: {event.get("process", "?")}: {event.get("message", "?")}')
        for event in first_errors[1:]:
            parts.append(f'the coupler also reports: {event.get("process", "?")}: {event.get("message", "?")}')
        if not parts:
            parts.append(f"the coupler exited with code {coupler_code} without an error event")
        stopped = [p for p in failed if p is not first and p is not None]
        if stopped:
            parts.append("stopped because of it: " + ", ".join(p.describe() for p in stopped))
        return "; ".join(parts)

    def _finish_completed(self) -> Outcome:
        """The coupler completed: the solvers have been told to stop and must now exit cleanly."""
        deadline = time.monotonic() + FINISH_GRACE_S
        while self._running(self.solvers) and time.monotonic() < deadline and not self._interrupts:
            self._pump(POLL_INTERVAL_S)
        late = self._running(self.solvers)
        if late and self._interrupts:
            what = "Ctrl-C" if self._interrupts[0] == signal.SIGINT else signal_name(self._interrupts[0])
            self.display.error(f"sabo: {what}: stopping the solvers that are still finishing")
            self._terminate(late, INTERRUPT_GRACE_S)
            return Outcome("stopped", EXIT_INTERRUPTED, f"stopped by {what} after the coupler completed")
        if late:
            reason = (f'{", ".join(f"{p.role} (pid {p.pid})" for p in late)} did not exit within {FINISH_GRACE_S:g} s '
                      "after the coupler completed the run")
            self.display.error("sabo: " + reason)
            self._terminate(late, FAULT_GRACE_S)
            return Outcome("failed", EXIT_FAILED, reason)
        failed = [p for p in self.solvers if p.returncode != 0]
        if failed:
            reason = "the coupler completed, but " + ", ".join(p.describe() for p in failed)
            self.display.error("sabo: " + reason)
            for process in failed:
                self._show_log_tail(process)
            return Outcome("failed", EXIT_FAILED, reason)
        return Outcome("completed", EXIT_OK)

    def _stop_on_interrupt(self) -> Outcome:
        first = self._interrupts[0]
        what = "Ctrl-C" if first == signal.SIGINT else signal_name(first)
        self.display.error(f"sabo: {what}: stopping the run (press Ctrl-C again to kill everything at once)")
        interrupts_seen = len(self._interrupts)
        coupler = self.coupler
        if coupler.running:
            coupler.send(signal.SIGTERM)
            solvers_signalled = False
        else:
            for solver in self._running(self.solvers):
                solver.send(signal.SIGTERM)
            solvers_signalled = True
        deadline = time.monotonic() + INTERRUPT_GRACE_S
        while self._running():
            now = time.monotonic()
            if len(self._interrupts) > interrupts_seen:
                self.display.error("sabo: killing every process now")
                self._kill(self._running(), "at the second interrupt")
                break
            if now >= deadline:
                self._kill(self._running(), f"{INTERRUPT_GRACE_S:g} s after the stop request")
                break
            if (not solvers_signalled and not coupler.running and
                    now - coupler.exited_at > SOLVER_TERM_DELAY_S):
                for solver in self._running(self.solvers):
                    solver.send(signal.SIGTERM)
                solvers_signalled = True
            self._pump(POLL_INTERVAL_S)
        self._drain_pipe(0.5)
        return Outcome("stopped", EXIT_INTERRUPTED, f"stopped by {what}")

    def _kill_leftovers(self) -> None:
        """Last line of defence (also on an internal error): nothing outlives the supervisor."""
        running = self._running()
        if running:
            self._kill(running, "at the end of the run")
        for process in self.processes:
            process.sweep()

    # ------------------------------------------------------------------------- events

    def _pump(self, timeout: float) -> None:
        """Wait up to `timeout` for coupler output and handle the complete lines."""
        if self._pipe is None:
            time.sleep(timeout)
            return
        if self._selector.select(timeout):
            self._read_pipe()

    def _read_pipe(self) -> None:
        for _ in range(64):  # bounded, so that a flood of output cannot starve the polling
            try:
                data = os.read(self._pipe.fileno(), 65536)
            except BlockingIOError:
                return
            if not data:
                if self._buffer:
                    self._handle_line(self._buffer)
                    self._buffer = b""
                self._close_pipe()
                return
            self._buffer += data
            *lines, self._buffer = self._buffer.split(b"\n")
            for line in lines:
                self._handle_line(line)

    def _drain_pipe(self, timeout_s: float) -> None:
        deadline = time.monotonic() + timeout_s
        while self._pipe is not None and time.monotonic() < deadline:
            self._pump(0.05)

    def _close_pipe(self) -> None:
        if self._pipe is None:
            return
        if self._selector is not None:
            self._selector.unregister(self._pipe)
            self._selector.close()
            self._selector = None
        self._pipe.close()
        self._pipe = None

    def _handle_line(self, raw: bytes) -> None:
        text = raw.decode("utf-8", "replace").rstrip("\r")
        if not text.strip():
            return
        try:
            event = json.loads(text)
        except ValueError:
            event = None
        if not isinstance(event, dict) or not isinstance(event.get("event"), str):
            self._append_to_coupler_log(text)
            return
        self._events.write(text + "\n")
        self._events.flush()
        handler = self._EVENT_HANDLERS.get(event["event"])
        if handler is not None:
            handler(self, event)

    # The coupler's events (docs/protocol.md, "Events"), one handler each; an unknown event is only logged.

    def _on_listening(self, event: dict) -> None:
        self._last_activity = time.monotonic()
        if not self._solvers_started:
            endpoint = event.get("endpoint")
            if not isinstance(endpoint, str) or "://" not in endpoint or "*" in endpoint:
                endpoint = self.endpoint
            self.display.info(f"sabo: coupler (pid {self.coupler.pid}) listening on {endpoint}")
            self._start_solvers(endpoint)

    def _on_registered(self, event: dict) -> None:
        self._last_activity = time.monotonic()
        role = event.get("role")
        self._registered.add(role)
        name = f", {event['name']}" if event.get("name") else ""
        where = f", from {event['address']}" if event.get("address") else ""
        self.display.info(f"sabo: {event.get('role', '?')} registered (pid {event.get('pid', '?')}{name}{where})")
        # Over ipc the kernel names the process at the other end: it must be the one started for the role (or
        # one it started). The run's token keeps others out already; this catches a process of the same user
        # that read it.
        process = self._process_by_role(role)
        spec = next((p for p in self.plan.solvers if p.role == role), None)
        peer_pid = event.get("peer_pid")
        if (isinstance(peer_pid, int) and process is not None and spec is not None and not spec.launcher and
                not spec.by_hand and process.running and not started_by(peer_pid, process)):
            self._impostor = (f"{role} registered from pid {peer_pid}, which the supervisor did not start (it started "
                              f"{role} as pid {process.pid}): another process of this user took the role; the run "
                              "stops")

    def _on_lost(self, event: dict) -> None:
        """The coupler lost a solver's connection (its host vanished, its process stopped): what is left of it
        is killed, so that it is restarted from its checkpoint like a solver that died."""
        self._last_activity = time.monotonic()
        role = event.get("process")
        self.display.error(f"sabo: the coupler reports: {event.get('message', role)}")
        process = self._process_by_role(role)
        if process is not None and process.running:
            process.send(signal.SIGKILL)

    def _on_progress(self, event: dict) -> None:
        self._last_activity = time.monotonic()
        self._last_progress = event
        self.display.progress(event, self.plan.end_time)

    def _on_error(self, event: dict) -> None:
        self._errors.append(event)
        self.display.error(f"sabo: the coupler reports: {event.get('process', '?')}: {event.get('message', '?')}")

    def _on_restarted(self, event: dict) -> None:
        self._last_activity = time.monotonic()
        self.display.info(f"sabo: {event.get('process', '?')} (pid {event.get('pid', '?')}) rejoined at step "
                          f"{event.get('from_step', '?')}, catching up {event.get('catch_up_steps', '?')} steps")

    def _on_resumed(self, event: dict) -> None:
        self._last_activity = time.monotonic()
        self.display.info(f"sabo: the run resumed at step {event.get('from_step', '?')}, "
                          f"t = {event.get('time', '?')} s")

    def _on_caught_up(self, event: dict) -> None:
        self._last_activity = time.monotonic()
        self.display.info(f"sabo: {event.get('process', '?')} caught up with the run at step "
                          f"{event.get('at_step', '?')} ({float(event.get('seconds', 0)):.2f} s)")

    def _on_stopping(self, _event: dict) -> None:
        self._last_activity = time.monotonic()
        self._stopping = True

    def _on_done(self, event: dict) -> None:
        self._last_activity = time.monotonic()
        self._stopping = True
        self._done = event

    _EVENT_HANDLERS = {
        "listening": _on_listening,
        "registered": _on_registered,
        "lost": _on_lost,
        "progress": _on_progress,
        "error": _on_error,
        "restarted": _on_restarted,
        "resumed": _on_resumed,
        "caught_up": _on_caught_up,
        "stopping": _on_stopping,
        "done": _on_done,
    }

    def _append_to_coupler_log(self, text: str) -> None:
        try:
            with open(os.path.join(self.run_dir, "coupler.log"), "a", encoding="utf-8") as log:
                log.write("[stdout] " + text + "\n")
        except OSError:
            pass

    # ------------------------------------------------------------------------ the end

    def _remove_socket(self) -> None:
        if self._socket_folder is not None:
            shutil.rmtree(self._socket_folder, ignore_errors=True)
            return
        if self.endpoint.startswith("ipc://"):
            path = self.endpoint[len("ipc://"):]
            try:
                if stat.S_ISSOCK(os.lstat(path).st_mode):
                    os.unlink(path)
            except OSError:
                pass

    def _after_a_crash(self, outcome: Outcome) -> None:
        """The coupler died without closing its files (a signal, a crash): traffic.h5 made readable by
        ordinary tools, and a summary.json that says so (the coupler wrote none)."""
        coupler = self.coupler
        if coupler is None or coupler.returncode is None or coupler.returncode in (
                COUPLER_EXIT_COMPLETED, COUPLER_EXIT_BAD_INPUT, COUPLER_EXIT_SOLVER_FAILED, COUPLER_EXIT_STOPPED):
            return
        traffic = os.path.join(self.run_dir, run_folder.TRAFFIC_FILE)
        if os.path.isfile(traffic) and self.bin_dir is not None:
            line = run_folder.repair_traffic(traffic, self.bin_dir)
            if line:
                self.display.error("sabo: " + line)
        if os.path.exists(os.path.join(self.run_dir, run_folder.SUMMARY_FILE)):
            return
        processes = {p.role: {"pid": p.pid, "exit": describe_exit(p.returncode) if p.returncode is not None
                              else "still running"} for p in self.processes}
        summary = run_folder.killed_summary(
            self.run_dir, outcome.reason or coupler.describe(),
            status="killed" if coupler.returncode < 0 else "failed", processes=processes,
            wall_seconds=time.monotonic() - self._started_at, scene=self.scene)
        try:
            run_folder.write_summary(self.run_dir, summary)
            self.display.error(f"sabo: the coupler wrote no summary: wrote {run_folder.SUMMARY_FILE} "
                               f'with status "{summary["status"]}"')
        except OSError as error:
            self.display.error(f"sabo: could not write {run_folder.SUMMARY_FILE}: {error.strerror}")

    def _relative(self, path: str) -> str:
        relative = os.path.relpath(path)
        return path if relative.startswith("..") else relative

    def _report(self, outcome: Outcome) -> None:
        wall = time.monotonic() - self._started_at
        headline = {"completed": "completed", "failed": "FAILED", "stopped": "stopped",
                    "bad input": "FAILED (bad input)"}[outcome.status]
        lines = [f'sabo: run {headline}{": " + outcome.reason if outcome.reason else ""}']
        if self._last_progress is not None:
            lines.append("  last step:   " + format_progress(self._last_progress, self.plan.end_time))
        lines.append(f"  wall time:   {format_duration(wall)}")
        lines.append(f"  run folder:  {self._relative(self.run_dir)}")
        files = list_run_folder(self.run_dir)
        if files:
            lines.extend(wrap_items(files, "  files:       ", " " * 15))
        self.display.summary(lines)
