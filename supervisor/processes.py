"""Starting, watching and stopping the processes of a run.

Every process runs in its own session (so a Ctrl-C in the terminal reaches only
the supervisor, which then stops the run in order) and, on Linux, gets SIGKILL
when the supervisor dies (PR_SET_PDEATHSIG), so that nothing outlives it.
"""
from __future__ import annotations

import ctypes
import os
import signal
import subprocess
import sys
import time
from typing import Callable

PR_SET_PDEATHSIG = 1  # <linux/prctl.h>
_SIGNALS_RESET_IN_CHILD = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP, signal.SIGQUIT)


def signal_name(number: int) -> str:
    try:
        return signal.Signals(number).name
    except ValueError:
        return f"signal {number}"


def describe_exit(returncode: int) -> str:
    """'exited with code 3' or 'was killed by SIGKILL', from a Popen return code."""
    if returncode < 0:
        return f"was killed by {signal_name(-returncode)}"
    return f"exited with code {returncode}"


def _child_setup_function() -> Callable[[], None] | None:
    """The preexec_fn of every process: die with the supervisor; default signal dispositions."""
    parent_pid = os.getpid()
    prctl = None
    if sys.platform.startswith("linux"):
        try:
            prctl = ctypes.CDLL(None, use_errno=True).prctl
        except (OSError, AttributeError):
            prctl = None

    def child_setup() -> None:
        # Ignored dispositions survive exec (e.g. SIGINT under `cmd &`); the processes expect defaults.
        for number in _SIGNALS_RESET_IN_CHILD:
            signal.signal(number, signal.SIG_DFL)
        if prctl is not None:
            prctl(PR_SET_PDEATHSIG, int(signal.SIGKILL), 0, 0, 0)
            if os.getppid() != parent_pid:  # the supervisor died before prctl took effect
                os.kill(os.getpid(), signal.SIGKILL)

    return child_setup


def child_environment() -> dict[str, str]:
    """The environment of every started process: the supervisor's own, plus
    OMP_WAIT_POLICY=passive unless the user set it. The processes of a run take
    turns in lock step; OpenMP threads that spin while their process waits take
    the cores from the process whose turn it is (measured: twice the wall time
    for configs/boulders_chute.toml on 2 cores)."""
    environment = dict(os.environ)
    environment.setdefault("OMP_WAIT_POLICY", "passive")
    return environment


class ManagedProcess:
    """One started process: its role, Popen and log file."""

    def __init__(self, role: str, command: list[str], popen: subprocess.Popen, log_path: str) -> None:
        self.role = role
        self.command = command
        self.popen = popen
        self.pid = popen.pid
        self.log_path = log_path
        self.started_at = time.monotonic()
        self.exited_at = None   # monotonic time at which the exit was seen
        self.handled = False    # the supervisor has acted on the exit
        self.signalled = set()  # signals the supervisor sent (numbers)

    @property
    def returncode(self) -> int | None:
        return self.popen.returncode

    def poll(self) -> int | None:
        code = self.popen.poll()
        if code is not None and self.exited_at is None:
            self.exited_at = time.monotonic()
        return code

    @property
    def running(self) -> bool:
        return self.poll() is None

    def send(self, number: int) -> None:
        """Send signal `number` to the process group (the process and anything it started)."""
        if not self.running:
            return
        self.signalled.add(number)
        try:
            os.killpg(self.pid, number)
        except ProcessLookupError:
            pass
        except PermissionError:
            self.popen.send_signal(number)

    def sweep(self) -> None:
        """SIGKILL whatever is left in the process's group after it has been reaped."""
        try:
            os.killpg(self.pid, signal.SIGKILL)
        except (ProcessLookupError, PermissionError):
            pass

    def describe(self) -> str:
        return f"{self.role} (pid {self.pid}) {describe_exit(self.returncode)}"

    def log_tail(self, count: int = 10) -> list[str]:
        """The last `count` lines of the log file."""
        try:
            with open(self.log_path, "rb") as handle:
                handle.seek(0, os.SEEK_END)
                size = handle.tell()
                handle.seek(max(0, size - 64 * 1024))
                text = handle.read().decode("utf-8", "replace")
        except OSError:
            return []
        return text.splitlines()[-count:]


def start_process(role: str, command: list[str], cwd: str, log_path: str, stdout_to_pipe: bool) -> ManagedProcess:
    """Start `command` in `cwd`, stderr (and stdout unless `stdout_to_pipe`) appended to `log_path`.

    Raises OSError when the program cannot be started.
    """
    log = open(log_path, "ab")
    try:
        popen = subprocess.Popen(command, cwd=cwd, stdin=subprocess.DEVNULL, env=child_environment(),
                                 stdout=subprocess.PIPE if stdout_to_pipe else log, stderr=log,
                                 start_new_session=True, preexec_fn=_child_setup_function(), close_fds=True)
    finally:
        log.close()
    return ManagedProcess(role, command, popen, log_path)
