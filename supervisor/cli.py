"""The command line of `./sabo`: setup, run, resume, replay, plot, test, status."""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from typing import TYPE_CHECKING

from . import plot, run_folder
from .display import Display, format_progress, list_run_folder, wrap_items
from .errors import SaboError, EXIT_OK, EXIT_FAILED, EXIT_BAD_INPUT, EXIT_INTERRUPTED
from .plan import check_scene
from .replay import command_replay
from .study import command_study
from .run import PIDS_FILE, Supervisor
from .setup_env import setup

if TYPE_CHECKING:
    from .plan import LaunchPlan

BUILD_DIR_VARIABLE = "SABO_BUILD_DIR"

DESCRIPTION = """\
Sabo: co-simulation of debris flows striking protective structures.

  ./sabo setup             install the Debian packages, configure and build (idempotent)
  ./sabo run SCENE         run a scene (does setup first); output goes to a run folder
  ./sabo resume RUN_DIR    continue a run that was killed, from its newest checkpoint common to every process
  ./sabo replay RUN ROLE   replay a run's recorded traffic against one process (sph, dem, fem, coupler)
  ./sabo plot RUN_DIR      figures of a run (forces, energy, gauges, sensors, time steps) in RUN_DIR/plots/
  ./sabo test [ARGS...]    build, then run the test suite with ctest (ARGS go to ctest)
  ./sabo status RUN_DIR    what a run folder holds; repairs what a killed run left behind
  ./sabo keys DIR          a key set for a run whose solvers are started by hand on other hosts
  ./sabo study STUDY.toml  what accuracy costs: a scene swept over keys, errors against wall time, Pareto front
"""

EPILOG = """\
environment:
  SABO_BUILD_DIR       build folder (default: build/ in the repository)
  SABO_PLAN_OVERRIDE   JSON launch plan to use instead of the scene check (debugging)
  SABO_WATCHDOG_MIN_S  lower bound of the no-progress watchdog, seconds (default 30)
  SABO_PLOT_PYTHON     the python3 with numpy and matplotlib that draws the plots (default /usr/bin/python3)
  OMP_NUM_THREADS      threads per process (OpenMP); OMP_WAIT_POLICY defaults to passive
"""


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="sabo", description=DESCRIPTION, epilog=EPILOG,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    commands = parser.add_subparsers(dest="command", metavar="COMMAND")

    setup_parser = commands.add_parser(
        "setup", help="install missing packages, configure and build",
        description="Install the missing Debian packages listed in packages.txt (apt-get, through sudo when "
                    "not root), configure CMake (Release, Ninja) and build. Does nothing when all is done.")
    setup_parser.add_argument("--quiet", action="store_true", help="show build output only when it fails")

    run_parser = commands.add_parser(
        "run", help="run a scene",
        description="Check the scene, start the coupler and the solvers it needs, show progress and stop "
                    "everything cleanly at the end, on a failure or on Ctrl-C. Exit status: 0 when the run "
                    "completed, 1 when it failed, 2 for bad input (scene errors, run folder refused), "
                    "130 when stopped by Ctrl-C or SIGTERM.")
    run_parser.add_argument("scene", metavar="SCENE", help="scene file (TOML), e.g. configs/sphere_drop.toml")
    run_parser.add_argument("--out", metavar="DIR",
                            help="run folder; must not exist or be empty (default: runs/<scene>-<date>-<time>)")
    run_parser.add_argument("--quiet", action="store_true", help="no progress line, only errors and the summary")
    run_parser.add_argument("--no-setup", action="store_true", help="skip the package check and the build")
    run_parser.add_argument("--no-plots", action="store_true", help="no figures in RUN_DIR/plots/ at the end")
    run_parser.add_argument("--keys", metavar="DIR",
                            help="use the key set in DIR (from ./sabo keys DIR) instead of a new one: for solvers "
                                 "started by hand on other hosts with a copy of it (docs/security.md)")

    resume_parser = commands.add_parser(
        "resume", help="continue a killed run from its checkpoints",
        description="Continue a run whose supervisor, coupler or machine died, from the newest step every process "
                    "of it has a checkpoint of, in the same run folder: forces.csv, energy.csv, the .pvd series and "
                    "traffic.h5 continue without duplicate or missing rows (docs/restart.md).")
    resume_parser.add_argument("run_dir", metavar="RUN_DIR", help="the run folder, e.g. runs/boulders_chute-20260101-120000")
    resume_parser.add_argument("--quiet", action="store_true", help="no progress line, only errors and the summary")
    resume_parser.add_argument("--no-setup", action="store_true", help="skip the package check and the build")
    resume_parser.add_argument("--no-plots", action="store_true", help="no figures in RUN_DIR/plots/ at the end")

    plot_parser = commands.add_parser(
        "plot", help="figures of a run folder, or of two overlaid",
        description="Draw the figures of a run folder into RUN_DIR/plots/ (PNG): forces.png (forces.csv), "
                    "energy.png (energy.csv, with the balance's residual), fem_energy.png (fem_energy.csv), "
                    "gauges.png (gauges.csv), fronts.png (fronts.csv), front_stations.png (front_stations.csv), "
                    "sensors.png (sensors.csv), steps.png (the time step and the step "
                    "rate, from coupler.events.jsonl), each when its data are there. With RUN_DIR_B the same "
                    "figures with both runs overlaid (RUN_DIR solid, RUN_DIR_B dashed) into "
                    "RUN_DIR/plots/compare_<name of RUN_DIR_B>/. `./sabo run` and `./sabo resume` make them at "
                    "the end (unless --no-plots). Needs Debian's python3 with matplotlib (python3-matplotlib). "
                    "Exit status: 0, 1 when they cannot be drawn (no matplotlib), 2 for bad input (not a run "
                    "folder, none of the files, a malformed file).")
    plot_parser.add_argument("run_dir", metavar="RUN_DIR", help="a run folder, e.g. runs/sphere_drop-20260101-120000")
    plot_parser.add_argument("compare_dir", metavar="RUN_DIR_B", nargs="?",
                             help="a second run folder, overlaid on the first (dashed)")
    plot_parser.add_argument("--out", metavar="DIR",
                             help="folder of the figures (default: RUN_DIR/plots, or RUN_DIR/plots/compare_<B>)")

    status_parser = commands.add_parser(
        "status", help="show a run folder; repair what a killed run left behind",
        description="Show the status of a run folder (summary.json, or the processes still running) and, when "
                    "no process of the run is alive, repair what a killed run left: traffic.h5's 'open for "
                    "writing' flags (so that h5ls and h5py open it), a leftover coupler.sock, a missing "
                    "summary.json (written with status \"killed\"). Exit status: 0, or 2 when RUN_DIR is not a "
                    "run folder.")
    status_parser.add_argument("run_dir", metavar="RUN_DIR", help="a run folder, e.g. runs/sphere_drop-20260101-120000")

    replay_parser = commands.add_parser(
        "replay", help="replay a run's recorded traffic against one process and compare, field by field",
        description="Replay RUN_DIR/traffic.h5 against one process: for a solver role the recording plays the "
                    "coupler (every recorded StepForces in order) and each StepState the solver sends is compared "
                    "with the recorded one; for the coupler the recording plays every solver and each StepForces is "
                    "compared. Prints the first divergence (step, time, field, entity, recorded and replayed values, "
                    "their difference, the tolerance) and a table per field. Exit status: 0 everything matches, "
                    "1 a divergence, 2 bad input, 3 the process failed. docs/traffic.md, 'Replay'.")
    replay_parser.add_argument("run_dir", metavar="RUN_DIR", help="the run folder (with traffic.h5)")
    replay_parser.add_argument("role", metavar="ROLE", help="sph, dem, fem or coupler")
    replay_parser.add_argument("--command", dest="program", metavar="CMD",
                               help="the program to check instead of the scene's "
                                                                 "(a shell-quoted command line)")
    replay_parser.add_argument("--set", metavar="TABLE.KEY=VALUE", action="append",
                               help="override a key of the recorded scene, e.g. materials.granite.density=3100 "
                                    "(repeatable)")
    replay_parser.add_argument("--rtol", metavar="FIELD=VALUE", action="append",
                               help="relative tolerance of a field, e.g. position=1e-12 (default: exact)")
    replay_parser.add_argument("--atol", metavar="FIELD=VALUE", action="append",
                               help="absolute tolerance of a field (default: exact)")
    replay_parser.add_argument("--resume", metavar="CHECKPOINT",
                               help="start the solver from this checkpoint (RUN_DIR/checkpoints/<role>_<step>.h5) "
                                    "and replay from its step")
    replay_parser.add_argument("--take", metavar="NAME", nargs="+",
                               help="ROLE sph, dem or fem: feed these fields of the solver's state from the "
                                    "recording at every step in place of its own (position, velocity, "
                                    "angular_velocity; node_position, node_velocity), to isolate the field that "
                                    "drifts. ROLE coupler: play only these solvers (sph, dem, fem) from the "
                                    "recording; the others run live against the replayed coupler")
    replay_parser.add_argument("--steps", metavar="A:B",
                               help="replay the window of steps A to B: a solver starts from its newest checkpoint "
                                    "at or before A (from step 0 when none is kept), and the replay ends at B")
    replay_parser.add_argument("--out", metavar="DIR", help="the replay's folder (default: RUN_DIR/replay/ROLE-<time>)")
    replay_parser.add_argument("--no-setup", action="store_true", help="skip the package check and the build")

    study_parser = commands.add_parser(
        "study", help="sweep scene keys, measure each run's error and cost, draw the Pareto front",
        description="Run every combination of the study file's swept scene keys through the supervisor (as many "
                    "at once as the cores allow; runs completed by an earlier invocation are taken as they are), "
                    "read each measure from the run folders, compare it with its reference and write study.csv, "
                    "study.md (sorted by cost, the Pareto-optimal runs marked, the observed orders of "
                    "convergence), pareto.png and convergence_<key>.png into the study folder "
                    "(docs/accuracy-cost.md). Exit status: 0 every run completed, 1 some failed, 2 bad input.")
    study_parser.add_argument("study", metavar="STUDY", help="study file (TOML), e.g. configs/studies/s1_front.toml")
    study_parser.add_argument("--out", metavar="DIR", help="the study folder (default: studies/<name>); reused: "
                                                           "completed runs are kept")
    study_parser.add_argument("--runs-at-once", type=int, default=0, metavar="N",
                              help="runs at the same time (default: the study's runs_at_once, else the cores / "
                                   "threads_per_run)")
    study_parser.add_argument("--dry-run", action="store_true", help="check the study and its scenes, list the runs")
    study_parser.add_argument("--no-setup", action="store_true", help="skip the package check and the build")

    keys_parser = commands.add_parser(
        "keys", help="write a key set for runs whose solvers start by hand on other hosts",
        description="Write a key set into DIR (created 0700, files 0600): a ZeroMQ CURVE key pair for the coupler "
                    "and for each solver role, and a token for ipc runs. Start the run with ./sabo run SCENE --keys "
                    "DIR, and a solver on another host with --keys pointing at a copy of DIR/coupler.key and its "
                    "role's .key_secret (docs/security.md). Exit status: 0 written, 1 not written, 2 bad input.")
    keys_parser.add_argument("folder", metavar="DIR", help="the folder to write, e.g. ~/sabo-keys/wenjia")
    keys_parser.add_argument("--force", action="store_true", help="replace a key set already in DIR")
    keys_parser.add_argument("--no-setup", action="store_true", help="skip the package check and the build")

    test_parser = commands.add_parser(
        "test", help="build, then run the tests with ctest",
        description="Build (as `./sabo setup`), then run `ctest --test-dir BUILD --output-on-failure ARGS...`, "
                    "one test per core (CTEST_PARALLEL_LEVEL, unless set or ARGS give -j N).")
    test_parser.add_argument("--no-setup", action="store_true", help="skip the package check and the build "
                                                                     "(must come first)")
    test_parser.add_argument("ctest_args", nargs="*", metavar="ARGS", help="passed to ctest, e.g. -R e2e -j2")
    return parser


def default_run_dir_base(scene: str) -> str:
    stem = os.path.splitext(os.path.basename(scene))[0] or "run"
    return os.path.join("runs", f'{stem}-{time.strftime("%Y%m%d-%H%M%S")}')


def refuse_used_run_dir(path: str) -> None:
    """SaboError unless `path` is absent or an empty folder: a run never overwrites another."""
    if not os.path.exists(path):
        return
    if not os.path.isdir(path):
        raise SaboError(f"--out {path}: exists and is not a folder; choose another --out", EXIT_BAD_INPUT)
    if os.listdir(path):
        raise SaboError(f"--out {path}: the folder already exists and is not empty; nothing was overwritten. "
                        f"Choose another --out, or delete it first (rm -r {path})", EXIT_BAD_INPUT)


def claim_run_dir(path: str) -> bool:
    """Create `path` (or take it if empty) and mark it as taken, atomically: False if another run has it."""
    try:
        os.makedirs(path, exist_ok=True)
        if os.listdir(path):
            return False
        os.close(os.open(os.path.join(path, PIDS_FILE), os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o644))
    except FileExistsError:
        return False
    except OSError as error:
        raise SaboError(f"cannot create the run folder {path}: {error.strerror}", EXIT_BAD_INPUT)
    return True


def create_run_dir(out: str | None, scene: str) -> str:
    """The run folder, created and claimed: `out`, or runs/<scene stem>-<date>-<time>[-N]."""
    if out is not None:
        refuse_used_run_dir(out)
        if not claim_run_dir(out):
            refuse_used_run_dir(out)
            raise SaboError(f"--out {out}: taken by another run; choose another --out", EXIT_BAD_INPUT)
        return out
    base = default_run_dir_base(scene)
    candidate, suffix = base, 2
    while not claim_run_dir(candidate):
        candidate = f"{base}-{suffix}"
        suffix += 1
    return candidate


def command_setup(root: str, build_dir: str, args: argparse.Namespace) -> int:
    setup(root, build_dir, quiet=args.quiet)
    print(f"sabo: packages installed, build up to date in {build_dir}")
    return 0


def set_up_and_check(root: str, build_dir: str, args: argparse.Namespace, scene: str) -> LaunchPlan:
    """The setup (unless --no-setup), then the scene check: the launch plan, or SaboError (bad input)."""
    if not args.no_setup:
        setup(root, build_dir, quiet=args.quiet)
    try:
        return check_scene(scene, os.path.join(build_dir, "bin"))
    except SaboError as error:
        if error.exit_code == EXIT_BAD_INPUT:
            print(error, file=sys.stderr)
            raise SaboError(f"{scene}: the scene has errors (above); nothing was started", EXIT_BAD_INPUT)
        raise


def command_keys(root: str, build_dir: str, args: argparse.Namespace) -> int:
    if not args.no_setup:
        setup(root, build_dir, quiet=True)
    tool = os.path.join(build_dir, "bin", "sabo_keys")
    command = [tool, args.folder] + (["--force"] if args.force else [])
    try:
        return subprocess.run(command, stdin=subprocess.DEVNULL).returncode
    except OSError as error:
        raise SaboError(f"cannot run {tool}: {error.strerror}; build the project with ./sabo setup")


def command_run(root: str, build_dir: str, args: argparse.Namespace) -> int:
    scene = args.scene
    if not os.path.isfile(scene):
        raise SaboError(f"scene file not found: {scene}", EXIT_BAD_INPUT)
    if args.out is not None:
        refuse_used_run_dir(args.out)
    if args.keys is not None and not os.path.isfile(os.path.join(args.keys, run_folder.TOKEN_FILE)):
        raise SaboError(f"--keys {args.keys}: not a key set (no ipc.token in it). Fix: write one with "
                        f"./sabo keys {args.keys}", EXIT_BAD_INPUT)
    plan = set_up_and_check(root, build_dir, args, scene)
    run_dir = create_run_dir(args.out, scene)
    run_folder.make_private(run_dir)
    display = Display(quiet=args.quiet)
    code = Supervisor(plan, scene, run_dir, display, bin_dir=os.path.join(build_dir, "bin"), keys=args.keys).run()
    return plot_after_run(root, run_dir, args, display, code)


def command_resume(root: str, build_dir: str, args: argparse.Namespace) -> int:
    run_dir = args.run_dir
    if not os.path.isdir(run_dir) or not os.path.exists(os.path.join(run_dir, PIDS_FILE)):
        raise SaboError(f"{run_dir}: not a run folder (it has no {PIDS_FILE})", EXIT_BAD_INPUT)
    alive = run_folder.live_processes(run_dir)
    if alive:
        raise SaboError(f'{run_dir}: the run is still running ({", ".join(f"{r} pid {p}" for r, p in alive)}): '
                        "nothing to resume. Stop it first (Ctrl-C in its "
                        f'terminal, or kill {" ".join(str(p) for _, p in alive)})', EXIT_BAD_INPUT)
    try:
        with open(os.path.join(run_dir, run_folder.SUMMARY_FILE), encoding="utf-8") as handle:
            status = json.load(handle).get("status")
    except (OSError, ValueError, AttributeError):
        status = None
    if status == "completed":
        raise SaboError(f"{run_dir}: the run completed: nothing to resume", EXIT_BAD_INPUT)
    scene = run_folder.run_scene(run_dir)
    if scene is None:
        raise SaboError(f"{run_dir}: names no scene ({run_folder.RUN_FILE} is missing): the run cannot be resumed. "
                        "Fix: start it again with ./sabo run SCENE", EXIT_BAD_INPUT)
    if not os.path.isfile(scene):
        raise SaboError(f"{run_dir}: the run's scene {scene} is not there any more. Fix: put the scene back, "
                        "unchanged, and resume again", EXIT_BAD_INPUT)
    plan = set_up_and_check(root, build_dir, args, scene)
    roles = ["coupler"] + [spec.role for spec in plan.solvers]
    common = run_folder.common_checkpoint(run_dir, roles)
    if common is None:
        raise SaboError(f'{run_dir}: no step that every process ({", ".join(roles)}) has a checkpoint of in '
                        f'{os.path.join(run_dir, "checkpoints")}: the run died before its '
                        "first checkpoint ([run] checkpoint_interval), or it never wrote any. Fix: start it again "
                        f"with ./sabo run {scene}", EXIT_BAD_INPUT)
    # What the killed run left behind (its socket, an unfinished summary) goes; the rest continues.
    run_folder.make_private(run_dir)
    run_folder.remove_socket(run_dir)
    try:
        os.unlink(os.path.join(run_dir, run_folder.SUMMARY_FILE + ".tmp"))
    except OSError:
        pass
    display = Display(quiet=args.quiet)
    display.info(f'sabo: resuming {run_dir} at step {common[0]} (checkpoints of {", ".join(roles)})')
    code = Supervisor(plan, scene, run_dir, display, bin_dir=os.path.join(build_dir, "bin"), resume=common).run()
    return plot_after_run(root, run_dir, args, display, code)


def plot_after_run(root: str, run_dir: str, args: argparse.Namespace, display: Display, code: int) -> int:
    """The figures of a run that completed or failed (not of one stopped by Ctrl-C or refused), unless
    --no-plots; whatever becomes of them, the run's exit status stays `code`."""
    if not args.no_plots and code in (EXIT_OK, EXIT_FAILED):
        plot.after_run(root, run_dir, display)
    return code


def command_plot(root: str, args: argparse.Namespace) -> int:
    run_dirs = [args.run_dir] + ([args.compare_dir] if args.compare_dir else [])
    for run_dir in run_dirs:
        if not os.path.isdir(run_dir):
            raise SaboError(f"{run_dir}: not a folder (give a run folder, e.g. runs/<scene>-<date>-<time>)",
                            EXIT_BAD_INPUT)
    result = plot.draw(root, run_dirs, args.out)
    for line in result.output:
        print(line)
    for problem in result.problems:
        print(f'sabo: {"error" if result.code == EXIT_BAD_INPUT else "cannot plot"}: {problem}',
              file=sys.stderr)
    if result.code in (EXIT_OK, EXIT_BAD_INPUT):
        return result.code
    return EXIT_FAILED


def command_status(build_dir: str, args: argparse.Namespace) -> int:
    run_dir = args.run_dir
    if not os.path.isdir(run_dir) or not os.path.exists(os.path.join(run_dir, PIDS_FILE)):
        raise SaboError(f"{run_dir}: not a run folder (it has no {PIDS_FILE})", EXIT_BAD_INPUT)
    alive = run_folder.live_processes(run_dir)
    if alive:
        progress = run_folder.last_progress(run_dir)
        print(f'sabo: {run_dir}: running: {", ".join(f"{r} (pid {p})" for r, p in alive)}')
        if progress is not None:
            print("  last step:   " + format_progress(progress, progress.get("end_time") or 0.0))
        return 0
    for line in run_folder.repair(run_dir, os.path.join(build_dir, "bin"),
                                  summary=run_folder.killed_summary(
                                      run_dir, "the run was killed: no process of it is alive and the coupler wrote "
                                               "no summary", written_by="./sabo status")):
        print(f"sabo: {run_dir}: {line}")
    try:
        with open(os.path.join(run_dir, run_folder.SUMMARY_FILE), encoding="utf-8") as handle:
            summary = json.load(handle)
    except (OSError, ValueError) as error:
        print(f"sabo: {run_dir}: no readable {run_folder.SUMMARY_FILE} ({error})")
        return 0
    print(f'sabo: {run_dir}: {summary.get("status", "?")}'
          f'{": " + summary["failure"] if summary.get("failure") else ""}')
    print(f'  steps:       {summary.get("steps", "?")}, t = {summary.get("simulated_time", "?")} '
          f'of {summary.get("end_time", "?")} s')
    files = list_run_folder(run_dir)
    if files:
        for line in wrap_items(files, "  files:       ", " " * 15):
            print(line)
    return 0


def command_test(root: str, build_dir: str, no_setup: bool, ctest_args: list[str]) -> None:
    if not no_setup:
        setup(root, build_dir)
    command = ["ctest", "--test-dir", build_dir, "--output-on-failure"] + list(ctest_args)
    # One test per core unless ARGS say otherwise (-j N wins over the variable); each test runs on
    # one thread (tests/CMakeLists.txt), so the cores are used without oversubscribing them.
    if not os.environ.get("CTEST_PARALLEL_LEVEL"):
        os.environ["CTEST_PARALLEL_LEVEL"] = str(os.cpu_count() or 1)
    sys.stdout.flush()
    sys.stderr.flush()
    try:
        os.execvp(command[0], command)
    except OSError as error:
        raise SaboError(f"cannot run ctest: {error.strerror}")


def main(root: str, argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    build_dir = os.path.abspath(os.environ.get(BUILD_DIR_VARIABLE) or os.path.join(root, "build"))
    parser = build_parser()
    try:
        if argv and argv[0] == "test" and argv[1:2] not in (["-h"], ["--help"]):
            # Everything after `test` belongs to ctest (argparse would take -j, -R... for itself).
            rest = argv[1:]
            no_setup = rest[:1] == ["--no-setup"]
            rest = rest[1:] if no_setup else rest
            rest = rest[1:] if rest[:1] == ["--"] else rest
            return command_test(root, build_dir, no_setup, rest)
        args = parser.parse_args(argv)
        if args.command is None:
            parser.print_help(sys.stderr)
            return EXIT_BAD_INPUT
        if args.command == "setup":
            return command_setup(root, build_dir, args)
        if args.command == "keys":
            return command_keys(root, build_dir, args)
        if args.command in ("run", "resume", "study"):
            # What a run writes is the user's alone: files 0600, folders 0700, whatever the umask was
            # (the processes inherit it).
            os.umask(0o077)
        if args.command == "study":
            if not args.no_setup:
                setup(root, build_dir, quiet=True)
            return command_study(root, build_dir, args)
        if args.command == "resume":
            return command_resume(root, build_dir, args)
        if args.command == "status":
            return command_status(build_dir, args)
        if args.command == "plot":
            return command_plot(root, args)
        if args.command == "replay":
            if not args.no_setup:
                setup(root, build_dir, quiet=True)
            return command_replay(root, build_dir, args)
        return command_run(root, build_dir, args)
    except SaboError as error:
        print(f"sabo: error: {error}", file=sys.stderr)
        return error.exit_code
    except KeyboardInterrupt:
        print("\nsabo: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
