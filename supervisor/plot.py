"""`./sabo plot RUN_DIR [RUN_DIR_B]`, and the plots made at the end of `./sabo run` and `./sabo resume`.

The figures need numpy and matplotlib, which the supervisor (any python3, standard library only) does not
use: scripts/sabo_plot.py draws them in a process of Debian's /usr/bin/python3 (or $SABO_PLOT_PYTHON). That
process is also the check that matplotlib imports: the script exits with EXIT_NO_MATPLOTLIB when it cannot,
so a run pays for one interpreter start (about a second with matplotlib), not two.
"""
from __future__ import annotations

import os
import subprocess
from typing import TYPE_CHECKING, Iterable

from .processes import _child_setup_function  # the plotting process dies with the supervisor, as the others

if TYPE_CHECKING:
    from .display import Display

PYTHON_VARIABLE = "SABO_PLOT_PYTHON"
DEFAULT_PYTHON = "/usr/bin/python3"
SCRIPT = os.path.join("scripts", "sabo_plot.py")
EXIT_NO_MATPLOTLIB = 3  # scripts/sabo_plot.py: numpy or matplotlib cannot be imported
TIMEOUT_S = 300.0
SCRIPT_PREFIXES = ("sabo_plot: error: ", "sabo_plot: ")


class PlotResult:
    """What became of the plots: `code` sabo_plot.py's exit status (None: it did not run to its end),
    `output` its stdout lines, `problems` one line per thing that went wrong (none when code is 0)."""

    def __init__(self, code: int | None, output: Iterable[str] = (), problems: Iterable[str] = ()) -> None:
        self.code = code
        self.output = list(output)
        self.problems = list(problems)

    def written(self) -> str | None:
        """'DIR/: forces.png, energy.png' from the script's 'wrote' line, or None."""
        for line in self.output:
            if line.startswith("sabo_plot: wrote "):
                return line[len("sabo_plot: wrote "):]
        return None


def plot_python() -> str:
    return os.environ.get(PYTHON_VARIABLE) or DEFAULT_PYTHON


def how_to_get_them(run_dirs: list[str]) -> str:
    return f'sudo apt-get install python3-matplotlib, then ./sabo plot {" ".join(run_dirs)}'


def without_prefix(line: str) -> str:
    for prefix in SCRIPT_PREFIXES:
        if line.startswith(prefix):
            return line[len(prefix):]
    return line


def draw(root: str, run_dirs: list[str], out: str | None = None) -> PlotResult:
    """Runs scripts/sabo_plot.py on `run_dirs` (one run folder, or two to overlay) into `out` (default: the
    script's) and returns a PlotResult. Never raises: a missing interpreter or matplotlib, a timeout or a
    Ctrl-C become its problems."""
    python = plot_python()
    if not os.access(python, os.X_OK):
        return PlotResult(None, problems=[f"no {python} to draw them with: {how_to_get_them(run_dirs)}"])
    command = [python, os.path.join(root, SCRIPT)] + list(run_dirs) + (["--out", out] if out else [])
    try:
        done = subprocess.run(command, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                              timeout=TIMEOUT_S, preexec_fn=_child_setup_function())
    except subprocess.TimeoutExpired:
        return PlotResult(None, problems=[f"scripts/sabo_plot.py ran for more than {TIMEOUT_S:.0f} s and was stopped"])
    except KeyboardInterrupt:
        return PlotResult(None, problems=[f'interrupted; make them with ./sabo plot {" ".join(run_dirs)}'])
    except OSError as error:
        return PlotResult(None, problems=[f"cannot run {python}: {error.strerror}"])
    output = done.stdout.decode("utf-8", "replace").splitlines()
    errors = [without_prefix(line) for line in done.stderr.decode("utf-8", "replace").splitlines() if line.strip()]
    if done.returncode == EXIT_NO_MATPLOTLIB:
        return PlotResult(done.returncode, output, [f"{python} cannot import matplotlib: {how_to_get_them(run_dirs)}"])
    if done.returncode != 0 and not errors:
        errors = [f"scripts/sabo_plot.py exited with code {done.returncode}"]
    return PlotResult(done.returncode, output, errors if done.returncode != 0 else [])


def after_run(root: str, run_dir: str, display: Display) -> None:
    """The plots at the end of a run: a line naming them, a warning line per problem; never fails the run."""
    result = draw(root, [run_dir])
    if result.written():
        display.summary(["  plots:       " + result.written()])
    for problem in result.problems:
        display.error(f"sabo: warning: plots: {problem}")
