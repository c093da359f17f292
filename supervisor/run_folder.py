"""A run folder after the fact: which of its processes still live, and the repairs a killed run needs.

A run whose coupler was killed (kill -9, a crash), or whose supervisor was (every process then gets SIGKILL),
leaves behind:

* traffic.h5 with HDF5's "open for writing" flags set: h5ls, h5dump and a plain h5py.File(path) refuse it
  (docs/traffic.md quotes them). `sabo_traffic repair` clears the flags;
* coupler.sock, the coupler's ipc socket: removed;
* no summary.json: one is written with status "killed" (or "failed") and what is known.

The supervisor repairs its own run when the coupler dies; `./sabo status RUN_DIR` (any later command that
reads a run folder) repairs a folder whose supervisor was killed too. Nothing is touched while a process
of the run is alive.
"""
from __future__ import annotations

import json
import os
import re
import stat
import subprocess
import time

PIDS_FILE = "pids.json"
RUN_FILE = "run.json"
SUMMARY_FILE = "summary.json"
TRAFFIC_FILE = "traffic.h5"
SOCKET_FILE = "coupler.sock"
KEYS_FOLDER = "keys"
TOKEN_FILE = "ipc.token"  # of a key set (libsabo/protocol/security.hpp): its presence marks one
KEY_FILE_SUFFIXES = (".key", ".key_secret", ".token")
PRIVATE_FOLDER_MODE = 0o700
PRIVATE_FILE_MODE = 0o600


def make_private(run_dir: str) -> None:
    """The run folder, only the user's (0700): the results, the logs, the keys and the ipc socket inside it.
    Files made in it are 0600 by the umask `./sabo run` sets (077)."""
    os.chmod(run_dir, PRIVATE_FOLDER_MODE)


def copy_key_set(source: str, folder: str) -> None:
    """Copy the key set in `source` (`./sabo keys DIR`) into `folder` (0700, files 0600). OSError when `source`
    is not a key set."""
    if not os.path.isfile(os.path.join(source, TOKEN_FILE)) or not os.path.isfile(
            os.path.join(source, "coupler.key_secret")):
        raise OSError(f"{source} holds no key set (coupler.key_secret and ipc.token are missing): write one with "
                      f"./sabo keys {source}")
    os.makedirs(folder, mode=PRIVATE_FOLDER_MODE, exist_ok=True)
    os.chmod(folder, PRIVATE_FOLDER_MODE)
    for name in sorted(os.listdir(source)):
        if not name.endswith(KEY_FILE_SUFFIXES):
            continue
        with open(os.path.join(source, name), "rb") as handle:
            data = handle.read()
        target = os.path.join(folder, name)
        descriptor = os.open(target + ".tmp", os.O_WRONLY | os.O_CREAT | os.O_TRUNC, PRIVATE_FILE_MODE)
        with os.fdopen(descriptor, "wb") as handle:
            os.fchmod(handle.fileno(), PRIVATE_FILE_MODE)
            handle.write(data)
        os.replace(target + ".tmp", target)


def _command_line(pid: int) -> str | None:
    try:
        with open(f"/proc/{pid}/cmdline", "rb") as handle:
            return handle.read().replace(b"\0", b" ").decode("utf-8", "replace")
    except OSError:
        return None


def _state(pid: int) -> str | None:
    try:
        with open(f"/proc/{pid}/stat", encoding="utf-8", errors="replace") as handle:
            return handle.read().rsplit(")", 1)[1].split()[0]
    except (OSError, IndexError):
        return None


def read_pids(run_dir: str) -> dict[str, int]:
    """{role: pid} of pids.json ({} when absent or unreadable)."""
    try:
        with open(os.path.join(run_dir, PIDS_FILE), encoding="utf-8") as handle:
            pids = json.load(handle)
    except (OSError, ValueError):
        return {}
    if not isinstance(pids, dict):
        return {}
    return {role: pid for role, pid in pids.items() if isinstance(pid, int) and not isinstance(pid, bool)}


def live_processes(run_dir: str) -> list[tuple[str, int]]:
    """[(role, pid)] of the run's processes (pids.json) that are alive and are still the run's: the
    supervisor is `sabo` or python, the others name the run folder on their command line (a reused pid
    is not the run's)."""
    run_dir = os.path.abspath(run_dir)
    alive = []
    for role, pid in read_pids(run_dir).items():
        if pid == os.getpid() or _state(pid) in (None, "Z", "X"):
            continue
        command = _command_line(pid)
        if command is None:
            continue
        if role == "supervisor" and ("sabo" in command or "python" in command):
            alive.append((role, pid))
        elif role != "supervisor" and run_dir in command:
            alive.append((role, pid))
    return alive


def repair_traffic(path: str, bin_dir: str) -> str | None:
    """Clear the flags a killed writer left in traffic.h5 with sabo_traffic; the line it printed, or why not."""
    tool = os.path.join(bin_dir, "sabo_traffic")
    if not os.access(tool, os.X_OK):
        return f"{TRAFFIC_FILE} was not checked: {tool} is missing (./sabo setup builds it)"
    result = subprocess.run([tool, "repair", path], stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, universal_newlines=True, errors="replace")
    text = (result.stdout.strip() or result.stderr.strip()).replace(path, TRAFFIC_FILE)
    if result.returncode != 0:
        return f"{TRAFFIC_FILE} could not be repaired: {text}"
    return text if "repaired" in text else None


def remove_socket(run_dir: str) -> bool:
    """Remove a leftover coupler.sock; True when there was one."""
    path = os.path.join(run_dir, SOCKET_FILE)
    try:
        if stat.S_ISSOCK(os.lstat(path).st_mode):
            os.unlink(path)
            return True
    except OSError:
        pass
    return False


def write_summary(run_dir: str, summary: dict) -> None:
    """summary.json, written whole then renamed (as the coupler writes its own)."""
    path = os.path.join(run_dir, SUMMARY_FILE)
    with open(path + ".tmp", "w", encoding="utf-8") as handle:
        json.dump(summary, handle, indent=2)
        handle.write("\n")
    os.replace(path + ".tmp", path)


def repair(run_dir: str, bin_dir: str, summary: dict | None = None) -> list[str]:
    """Repair a run folder none of whose processes lives; returns what was done, one line each.

    `summary`: the summary.json to write when there is none (default: status "killed", written by
    `./sabo status`, from the last progress event in coupler.events.jsonl).
    """
    done = []
    if live_processes(run_dir):
        return done
    traffic = os.path.join(run_dir, TRAFFIC_FILE)
    if os.path.isfile(traffic):
        line = repair_traffic(traffic, bin_dir)
        if line:
            done.append(line)
    if remove_socket(run_dir):
        done.append(f"removed the leftover {SOCKET_FILE}")
    try:
        os.unlink(os.path.join(run_dir, SUMMARY_FILE + ".tmp"))
        done.append(f"removed the coupler's unfinished {SUMMARY_FILE}.tmp")
    except OSError:
        pass
    if not os.path.exists(os.path.join(run_dir, SUMMARY_FILE)) and os.path.exists(os.path.join(run_dir, PIDS_FILE)):
        if summary is None:
            summary = killed_summary(run_dir, "the run was killed: no process of it is alive and the coupler "
                                              "wrote no summary", written_by="./sabo status")
        write_summary(run_dir, summary)
        done.append(f'wrote {SUMMARY_FILE} with status "{summary["status"]}"')
    return done


def last_progress(run_dir: str) -> dict | None:
    """The last progress event of coupler.events.jsonl, or None."""
    last = None
    try:
        with open(os.path.join(run_dir, "coupler.events.jsonl"), encoding="utf-8", errors="replace") as handle:
            for line in handle:
                try:
                    event = json.loads(line)
                except ValueError:
                    continue
                if isinstance(event, dict) and event.get("event") == "progress":
                    last = event
    except OSError:
        pass
    return last


def killed_summary(run_dir: str, failure: str, status: str = "killed", processes: dict | None = None,
                   wall_seconds: float | None = None, scene: str | None = None,
                   written_by: str = "supervisor") -> dict:
    """A summary.json for a run whose coupler could not write its own: what the supervisor (or `./sabo status`)
    knows."""
    progress = last_progress(run_dir) or {}
    summary = {
        "status": status,
        "failure": failure,
        "written_by": f"{written_by} (the coupler wrote no summary)",
        "written_at": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
        "steps": progress.get("step", 0),
        "simulated_time": progress.get("time", 0.0),
        "end_time": progress.get("end_time"),
        "processes": processes if processes is not None else {
            role: {"pid": pid} for role, pid in read_pids(run_dir).items()},
    }
    if wall_seconds is not None:
        summary["wall_seconds"] = wall_seconds
    if scene is not None:
        summary["scene"] = scene
    return summary


def write_run_file(run_dir: str, scene: str) -> None:
    """run.json: what `./sabo resume` needs to start the run's processes again (the scene file)."""
    path = os.path.join(run_dir, RUN_FILE)
    with open(path + ".tmp", "w", encoding="utf-8") as handle:
        json.dump({"scene": os.path.abspath(scene), "started_at": time.strftime("%Y-%m-%dT%H:%M:%S%z")}, handle,
                  indent=2)
        handle.write("\n")
    os.replace(path + ".tmp", path)


def run_scene(run_dir: str) -> str | None:
    """The scene file the run was started with (run.json, else summary.json), or None."""
    for name in (RUN_FILE, SUMMARY_FILE):
        try:
            with open(os.path.join(run_dir, name), encoding="utf-8") as handle:
                scene = json.load(handle).get("scene")
        except (OSError, ValueError, AttributeError):
            continue
        if isinstance(scene, str) and scene:
            return scene
    return None


def checkpoint_step(path: str, role: str = r"[a-z_]+") -> int | None:
    """The step of a checkpoint file named <role>_<step>.h5 (as the processes name them), or None."""
    match = re.fullmatch(rf"{role}_([0-9]{{10}})\.h5", os.path.basename(path))
    return int(match.group(1)) if match else None


def checkpoints(run_dir: str, role: str) -> dict[int, str]:
    """{step: path} of the complete checkpoints of `role` ("coupler", "dem_solver", ...) in RUN_DIR/checkpoints."""
    folder = os.path.join(run_dir, "checkpoints")
    try:
        names = os.listdir(folder)
    except OSError:
        return {}
    return {step: os.path.join(folder, name) for name in names
            for step in [checkpoint_step(name, re.escape(role))] if step is not None}


def common_checkpoint(run_dir: str, roles: list[str]) -> tuple[int, dict[str, str]] | None:
    """(step, {role: path}) of the newest step every role in `roles` has a checkpoint of, or None."""
    found = {role: checkpoints(run_dir, role) for role in roles}
    steps = set.intersection(*(set(paths) for paths in found.values())) if found else set()
    if not steps:
        return None
    step = max(steps)
    return step, {role: paths[step] for role, paths in found.items()}
