"""`./sabo replay RUN_DIR ROLE`: one process of a recorded run against its recorded traffic.

For a solver role, `sabo_replay solver` plays the coupler from RUN_DIR/traffic.h5 (the registration's answer,
then every recorded StepForces in order) and compares each StepState the solver sends with the recorded one;
for ROLE = coupler, `sabo_replay coupler` plays every solver (the recorded registrations and states) and
compares each StepForces the coupler sends. The process is the scene's own (the built executable or the
scene's `command`), or `--command ...`: the program a user wants to check in place of the original. The
scene is the recorded one, with `--set KEY=VALUE` overrides. `--resume CHECKPOINT` starts the solver from one of
its checkpoints (RUN_DIR/checkpoints/<role>_<step>.h5, with the run's own scene file) and replays from that step:
the check that a restart continues with the same bits. Everything runs in RUN_DIR/replay/<role>-<time>/.

Exit status: 0 every field matches, 1 a divergence (the first is printed, then a table per field), 2 bad input,
3 the process failed.
"""
from __future__ import annotations

import os
import shlex
import shutil
import subprocess
import sys
import time
from typing import TYPE_CHECKING

from . import run_folder
from .errors import SaboError, EXIT_BAD_INPUT, EXIT_FAILED
from .plan import check_scene
from .scene_text import absolute_file_keys, apply_overrides
from .processes import describe_exit, start_process

if TYPE_CHECKING:
    import argparse

    from .processes import ManagedProcess

ROLES = {"sph": "sph_solver", "dem": "dem_solver", "fem": "fem_solver", "coupler": "coupler"}
EXIT_PROCESS_FAILED = 3


def _wait(process: ManagedProcess, timeout_s: float) -> bool:
    deadline = time.monotonic() + timeout_s
    while process.running and time.monotonic() < deadline:
        time.sleep(0.05)
    return not process.running


def _stop(process: ManagedProcess) -> None:
    if process.running:
        process.send(15)
        if not _wait(process, 3):
            process.send(9)
            _wait(process, 3)
    process.sweep()


def command_replay(root: str, build_dir: str, args: argparse.Namespace) -> int:
    run_dir = os.path.abspath(args.run_dir)
    traffic = os.path.join(run_dir, "traffic.h5")
    if args.role not in ROLES:
        raise SaboError(f'role {args.role!r}: choose one of {", ".join(ROLES)}', EXIT_BAD_INPUT)
    if not os.path.isfile(traffic):
        raise SaboError(f"{run_dir}: no traffic.h5 (was the run recorded? [recording] enabled = true)",
                        EXIT_BAD_INPUT)
    role = ROLES[args.role]
    bin_dir = os.path.join(build_dir, "bin")
    # A run killed with its supervisor (kill -9) left traffic.h5 flagged open for writing, coupler.sock and no
    # summary.json: repaired first, as `./sabo status` does (issue 18), when no process of the run lives.
    if os.path.exists(os.path.join(run_dir, run_folder.PIDS_FILE)):
        for line in run_folder.repair(run_dir, bin_dir, summary=None if os.path.exists(
                os.path.join(run_dir, run_folder.SUMMARY_FILE)) else run_folder.killed_summary(
                    run_dir, "the run was killed: no process of it is alive and the coupler wrote no summary",
                    written_by="./sabo replay")):
            print(f"sabo: {run_dir}: {line}", file=sys.stderr)
    tool = os.path.join(bin_dir, "sabo_replay")
    if not os.access(tool, os.X_OK):
        raise SaboError(f"{tool} is missing: build the project with `./sabo setup`", EXIT_FAILED)

    stamp = time.strftime("%Y%m%d-%H%M%S")
    folder = os.path.abspath(args.out) if args.out else os.path.join(run_dir, "replay", f"{args.role}-{stamp}")
    os.makedirs(folder, exist_ok=True)
    scene_text = subprocess.run([tool, "scene", "--traffic", traffic], stdin=subprocess.DEVNULL,
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE, universal_newlines=True)
    if scene_text.returncode != 0:
        raise SaboError(scene_text.stderr.strip() or f"sabo_replay could not read {traffic}", EXIT_BAD_INPUT)
    recorded_scene = run_folder.run_scene(run_dir)
    window = _parse_steps(args.steps) if args.steps else None
    taken = _taken_roles(args.take) if args.take and role == "coupler" else None
    if window is not None and args.resume:
        raise SaboError("--steps and --resume: --steps picks the newest checkpoint at or before its first step "
                        "itself; give one of them", EXIT_BAD_INPUT)
    if args.resume and args.set:
        raise SaboError("--resume with --set: a checkpoint continues the scene it was written with, unchanged; "
                        "replay from step 0 to try a changed scene", EXIT_BAD_INPUT)
    # The recorded scene (with --set overrides) says which processes run; a replay from checkpoints runs the
    # run's own scene file, which the checkpoints name (their digest).
    text = absolute_file_keys(scene_text.stdout, os.path.dirname(recorded_scene) if recorded_scene else run_dir)
    scene = os.path.join(folder, "scene.toml")
    with open(scene, "w", encoding="utf-8") as handle:
        handle.write(apply_overrides(text, args.set or []))
    plan = check_scene(scene, bin_dir)
    spec = next((p for p in plan.processes if p.role == role), None)
    if spec is None:
        raise SaboError(f"the recorded scene has no {role}", EXIT_BAD_INPUT)
    live_specs = [s for s in plan.solvers if s.role not in taken] if taken is not None else []
    resumes = {}  # process role: the checkpoint it starts from
    if window is not None:
        resumes = _window_checkpoints(run_dir, role, [s.role for s in live_specs], window[0], bool(args.set))
    elif args.resume:
        resumes = _given_checkpoints(run_dir, role, [s.role for s in live_specs], os.path.abspath(args.resume))
    if resumes:
        if not recorded_scene or not os.path.isfile(recorded_scene):
            raise SaboError(f'--resume: the run\'s scene file {recorded_scene or "(unknown: no summary.json)"} is gone; '
                            "a checkpoint needs the scene it was written with", EXIT_BAD_INPUT)
        scene = recorded_scene
    command = shlex.split(args.program) if args.program else list(spec.command)

    endpoint = "ipc://" + os.path.join(folder, "replay.sock")
    tolerances = []
    for option, values in (("rtol", args.rtol or []), ("atol", args.atol or [])):
        for value in values:
            field, equals, number = value.partition("=")
            if not equals:
                raise SaboError(f"--{option} {value}: expected FIELD=VALUE, e.g. --{option} position=1e-12",
                                EXIT_BAD_INPUT)
            tolerances.append((field, option, number))
    merged = {}
    for field, option, number in tolerances:
        merged.setdefault(field, {"rtol": "0", "atol": "0"})[option] = number
    tool_command = [tool, "solver" if role != "coupler" else "coupler", "--traffic", traffic, "--endpoint", endpoint,
                    "--json", os.path.join(folder, "replay.json")]
    for field, values in merged.items():
        tool_command += ["--tolerance", f'{field}={values["rtol"]}:{values["atol"]}']
    if window is not None and window[1] is not None:
        tool_command += ["--until", str(window[1])]
    live = []
    out = os.path.join(folder, "out")
    if taken is not None:
        tool_command += ["--play"] + taken
        live = [(live_spec, list(live_spec.command) + ["--scene", scene, "--coupler", endpoint, "--out", out] +
                 (["--resume", resumes[live_spec.role]] if resumes else [])) for live_spec in live_specs]
    if role != "coupler":
        tool_command += ["--role", role]
        if args.take:  # state fields fed to the solver from the recording (sabo_replay checks the names)
            tool_command += ["--take"] + args.take
        process_command = command + ["--scene", scene, "--coupler", endpoint, "--out", out]
    else:
        # The replayed coupler's own recording would only repeat what the replay compares, at the cost of
        # writing it (as much as the live run's recording cost).
        process_command = command + ["--scene", scene, "--endpoint", endpoint, "--out", out, "--no-recording"]
    os.makedirs(out, exist_ok=True)
    if resumes:
        tool_command += ["--resume", resumes[role]]
        process_command += ["--resume", resumes[role]]
        if role == "coupler":
            # A resumed coupler continues the run's histories from its checkpoint: copies of them.
            for name in ("forces.csv", "energy.csv", "sensors.csv"):
                if os.path.isfile(os.path.join(run_dir, name)):
                    shutil.copyfile(os.path.join(run_dir, name), os.path.join(out, name))

    print(f"sabo: replaying the {role} of {run_dir} ({folder})", file=sys.stderr)
    replay_log = os.path.join(folder, "replay.log")
    process_log = os.path.join(folder, f"{role}.log")
    started = []
    code = None
    failed = None
    try:
        # The side that binds the endpoint starts first: the replay for a solver, the coupler for ROLE coupler.
        if role != "coupler":
            tool_process = start_process("replay", tool_command, folder, replay_log, stdout_to_pipe=True)
            started.append(tool_process)
            time.sleep(0.3)
            started.append(start_process(role, process_command, folder, process_log, stdout_to_pipe=False))
        else:
            started.append(start_process(role, process_command, folder, process_log, stdout_to_pipe=False))
            time.sleep(0.3)
            tool_process = start_process("replay", tool_command, folder, replay_log, stdout_to_pipe=True)
            started.append(tool_process)
            for spec, live_command in live:  # --take: the solvers not taken from the recording run live
                started.append(start_process(spec.role, live_command, folder,
                                             os.path.join(folder, f"{spec.role}.log"), stdout_to_pipe=False))
        report, failed = _watch(tool_process, [p for p in started if p is not tool_process])
        code = EXIT_PROCESS_FAILED if failed else tool_process.returncode
    finally:
        # A replay that ended its comparison lets the process finish on its own (it got stop); one that could
        # not run leaves it waiting for a coupler that will not answer.
        grace = 10 if code in (0, 1) else 1
        for process in started:
            if not _wait(process, grace):
                _stop(process)
            process.sweep()
    sys.stdout.write(report.decode("utf-8", "replace") if isinstance(report, bytes) else (report or ""))
    if failed:
        print(f"sabo: the {failed.role} {describe_exit(failed.returncode)} before the replay ended; its log: "
              f"{failed.log_path}", file=sys.stderr)
        for line in failed.log_tail(5):
            print(f"  {line}", file=sys.stderr)
    elif code == EXIT_PROCESS_FAILED:
        print(f"sabo: the {role} failed; its log: {process_log}", file=sys.stderr)
    elif code == EXIT_BAD_INPUT:
        print(f"sabo: replay could not run; see {replay_log}", file=sys.stderr)
        try:
            with open(replay_log, encoding="utf-8", errors="replace") as handle:
                sys.stderr.write(handle.read()[-2000:])
        except OSError:
            pass
    return code


def _watch(tool: ManagedProcess, others: list[ManagedProcess]) -> tuple[bytes, ManagedProcess | None]:
    """The replay tool's report, read while the processes it replays against are watched: one that ends while the
    tool still waits for it (a damaged checkpoint, a crash, a replacement program that does not speak the
    protocol) stops the tool within seconds instead of after its registration or hang timeout. Returns the report
    and the process that ended first (None when the tool ended on its own)."""
    ended = None  # (process, monotonic time its end was seen)
    while True:
        try:  # output read before a timeout is kept by Popen and returned by the call that completes
            return tool.popen.communicate(timeout=0.2)[0] or b"", None
        except subprocess.TimeoutExpired:
            pass
        if ended is None:
            gone = next((p for p in others if not p.running), None)
            if gone is not None:
                ended = (gone, time.monotonic())
        # A process that ends with a failure leaves nothing for the tool to wait for; one that exits 0 may have
        # sent its last state, which the tool is still comparing.
        elif time.monotonic() - ended[1] > (2.0 if ended[0].returncode != 0 else 10.0):
            _stop(tool)
            return tool.popen.communicate()[0] or b"", ended[0]


def _taken_roles(names: list[str]) -> list[str]:
    """The solver roles of `--take NAME...` with ROLE = coupler: played from the recording, the others live."""
    taken = []
    for name in names:
        solver = ROLES.get(name, name)
        if solver not in ("sph_solver", "dem_solver", "fem_solver"):
            raise SaboError(f"--take {name}: with ROLE = coupler, --take names the solvers to play from the "
                            "recording (sph, dem, fem); with a solver's role, the fields of its state to feed it",
                            EXIT_BAD_INPUT)
        taken.append(solver)
    return taken


def _parse_steps(text: str) -> tuple[int, int | None]:
    """(first, last or None) of `--steps A:B` (A: and :B allowed); SaboError (exit 2) when malformed."""
    first, colon, last = text.partition(":")
    try:
        window = (int(first) if first.strip() else 0, int(last) if last.strip() else None)
    except ValueError:
        window = None
    if not colon or window is None or window[0] < 0 or (window[1] is not None and window[1] < window[0]):
        raise SaboError(f"--steps {text}: expected A:B with 0 <= A <= B (A: to the end, :B from the start), e.g. "
                        "--steps 1200:1300", EXIT_BAD_INPUT)
    return window


def _window_checkpoints(run_dir: str, role: str, live: list[str], first: int, changed_scene: bool) -> dict[str, str]:
    """{process role: checkpoint} a window starting at step `first` replays from: the newest step at or before it
    that `role` (and the solvers that run `live` beside a replayed coupler) have a checkpoint of, said on stderr;
    empty: from step 0."""
    roles = [role] + live
    found = {r: run_folder.checkpoints(run_dir, r) for r in roles}
    usable = [step for step in set.intersection(*(set(paths) for paths in found.values())) if step <= first]
    who = role + "".join(f" and the live {r}" for r in live)
    if not usable:
        kept = ", ".join(str(step) for step in sorted(found[role])) or "none"
        print(f"sabo: --steps: no checkpoint of the {who} at or before step {first} is kept (kept: {kept}): "
              "the replay starts at step 0", file=sys.stderr)
        return {}
    if changed_scene:
        print("sabo: --steps with --set: a checkpoint continues the scene it was written with: the replay starts "
              "at step 0", file=sys.stderr)
        return {}
    step = max(usable)
    print(f"sabo: --steps: the {who} resume{'s' if not live else ''} from {'its' if not live else 'their'} "
          f"checkpoint of step {step}", file=sys.stderr)
    return {r: found[r][step] for r in roles}


def _given_checkpoints(run_dir: str, role: str, live: list[str], checkpoint: str) -> dict[str, str]:
    """{process role: checkpoint} of `--resume CHECKPOINT`: the file for `role`, and for the solvers that run live
    beside a replayed coupler their checkpoints of its step."""
    if not os.path.isfile(checkpoint):
        raise SaboError(f"--resume {checkpoint}: no such file (checkpoints are in RUN_DIR/checkpoints)",
                        EXIT_BAD_INPUT)
    resumes = {role: checkpoint}
    if live:
        step = run_folder.checkpoint_step(checkpoint)
        if step is None:
            raise SaboError(f"--resume {checkpoint}: not named <role>_<step>.h5, so the step the live solvers resume "
                            "at is unknown: give a checkpoint of RUN_DIR/checkpoints", EXIT_BAD_INPUT)
        for solver in live:
            path = run_folder.checkpoints(run_dir, solver).get(step)
            if path is None:
                raise SaboError(f"--resume {checkpoint}: the {solver}, which runs live, has no checkpoint of step "
                                f"{step} in {os.path.join(run_dir, 'checkpoints')}: take it from the recording too, "
                                "or resume from a step every live solver has", EXIT_BAD_INPUT)
            resumes[solver] = path
    return resumes
