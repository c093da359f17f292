"""`./sabo setup`: install the Debian packages the project needs, then configure and build.

Idempotent and fast when there is nothing to do: dpkg-query decides whether
apt-get runs at all, ninja decides what to rebuild.
"""
from __future__ import annotations

import os
import shutil
import subprocess
import sys
from typing import TextIO

from .errors import SaboError, EXIT_FAILED

PACKAGE_LIST = "packages.txt"
NINJA_NOTHING_TO_DO = "ninja: no work to do."


def read_package_list(path: str) -> list[str]:
    """The package names in `path`: one per line, `#` starts a comment."""
    try:
        with open(path, encoding="utf-8") as handle:
            lines = handle.read().splitlines()
    except OSError as error:
        raise SaboError(f"cannot read the package list {path}: {error.strerror}")
    packages = []
    for line in lines:
        name = line.split("#", 1)[0].strip()
        if name:
            packages.append(name)
    return packages


def missing_packages(packages: list[str]) -> list[str] | None:
    """The packages of `packages` that dpkg does not report as installed, in list order.

    Returns None when dpkg-query is not available (not a Debian system).
    """
    if shutil.which("dpkg-query") is None:
        return None
    result = subprocess.run(
        ["dpkg-query", "-W", "-f=${Package}\t${db:Status-Abbrev}\n"] + list(packages),
        stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, universal_newlines=True)
    # Exit status 1 only means that some package is unknown; those lines are missing.
    installed = set()
    for line in result.stdout.splitlines():
        name, _, status = line.partition("\t")
        if status.startswith("ii"):
            installed.add(name.split(":", 1)[0])
    return [name for name in packages if name not in installed]


def _privileged(command: list[str]) -> list[str]:
    """`command` run as root: directly when we are root, else through sudo."""
    if os.geteuid() == 0:
        return command
    if shutil.which("sudo") is None:
        raise SaboError("installing packages needs root: run `./sabo setup` as root, or install sudo")
    return ["sudo"] + command


def install_packages(packages: list[str], out: TextIO = sys.stdout) -> None:
    """apt-get update, then install `packages` without recommends, non-interactively."""
    if shutil.which("apt-get") is None:
        raise SaboError(f'apt-get is not available to install: {" ".join(packages)}')
    apt = ["env", "DEBIAN_FRONTEND=noninteractive", "apt-get"]
    steps = [apt + ["update"], apt + ["install", "-y", "--no-install-recommends"] + list(packages)]
    print(f'sabo: installing {" ".join(packages)}', file=out, flush=True)
    for command in steps:
        command = _privileged(command)
        result = subprocess.run(command, stdin=subprocess.DEVNULL)
        if result.returncode != 0:
            raise SaboError(f'`{" ".join(command)}` failed with exit code {result.returncode}')


def ensure_packages(root: str, out: TextIO = sys.stdout) -> None:
    """Install what is missing from the package list; does nothing when all is installed."""
    packages = read_package_list(os.path.join(root, PACKAGE_LIST))
    missing = missing_packages(packages)
    if missing is None:
        print("sabo: dpkg-query not found (not a Debian system): not checking packages; "
              f"install the equivalents of {PACKAGE_LIST} yourself", file=out, flush=True)
        return
    if not missing:
        return
    install_packages(missing, out)
    still_missing = missing_packages(packages)
    if still_missing:
        raise SaboError(f'still not installed after apt-get: {" ".join(still_missing)}')


def _run_streamed(command: list[str], quiet: bool, out: TextIO) -> int:
    """Run `command`; stream its output (quiet: only when it fails). Returns the exit code."""
    process = subprocess.Popen(command, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                               stderr=subprocess.STDOUT, universal_newlines=True, errors="replace")
    captured = []
    for line in process.stdout:
        if line.strip() == NINJA_NOTHING_TO_DO:
            continue
        if quiet:
            captured.append(line)
        else:
            out.write(line)
            out.flush()
    code = process.wait()
    if code != 0 and quiet:
        out.write("".join(captured))
        out.flush()
    return code


def ensure_build(root: str, build_dir: str, quiet: bool = False, out: TextIO = sys.stdout) -> None:
    """Configure (Release, Ninja) when `build_dir` has no CMake cache yet, then build."""
    for tool in ("cmake", "ninja"):
        if shutil.which(tool) is None:
            raise SaboError(f"{tool} is not installed: run `./sabo setup`")
    if not os.path.exists(os.path.join(build_dir, "CMakeCache.txt")):
        command = ["cmake", "-S", root, "-B", build_dir, "-G", "Ninja", "-DCMAKE_BUILD_TYPE=Release"]
        if _run_streamed(command, quiet, out) != 0:
            raise SaboError(f'configuring with CMake failed (see above): {" ".join(command)}', EXIT_FAILED)
    command = ["cmake", "--build", build_dir]
    if _run_streamed(command, quiet, out) != 0:
        raise SaboError(f'the build failed (see above): {" ".join(command)}', EXIT_FAILED)


def setup(root: str, build_dir: str, quiet: bool = False, out: TextIO = sys.stdout) -> None:
    ensure_packages(root, out)
    ensure_build(root, build_dir, quiet, out)
