"""`./sabo setup`: install the Debian packages the project needs, then configure and build.

Idempotent and fast when there is nothing to do: dpkg-query decides whether
apt-get runs at all, ninja decides what to rebuild.
"""
import os
import shutil
import subprocess
import sys

from .errors import SaboError, EXIT_FAILED

PACKAGE_LIST = "packages.txt"
NINJA_NOTHING_TO_DO = "ninja: no work to do."


def read_package_list(path):
    """The package names in `path`: one per line, `#` starts a comment."""
    try:
        with open(path, encoding="utf-8") as handle:
            lines = handle.read().splitlines()
    except OSError as error:
        raise SaboError("cannot read the package list {}: {}".format(path, error.strerror))
    packages = []
    for line in lines:
        name = line.split("#", 1)[0].strip()
        if name:
            packages.append(name)
    return packages


def missing_packages(packages):
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


def _privileged(command):
    """`command` run as root: directly when we are root, else through sudo."""
    if os.geteuid() == 0:
        return command
    if shutil.which("sudo") is None:
        raise SaboError("installing packages needs root: run `./sabo setup` as root, or install sudo")
    return ["sudo"] + command


def install_packages(packages, out=sys.stdout):
    """apt-get update, then install `packages` without recommends, non-interactively."""
    if shutil.which("apt-get") is None:
        raise SaboError("apt-get is not available to install: {}".format(" ".join(packages)))
    apt = ["env", "DEBIAN_FRONTEND=noninteractive", "apt-get"]
    steps = [apt + ["update"], apt + ["install", "-y", "--no-install-recommends"] + list(packages)]
    print("sabo: installing {}".format(" ".join(packages)), file=out, flush=True)
    for command in steps:
        command = _privileged(command)
        result = subprocess.run(command, stdin=subprocess.DEVNULL)
        if result.returncode != 0:
            raise SaboError("`{}` failed with exit code {}".format(" ".join(command), result.returncode))


def ensure_packages(root, out=sys.stdout):
    """Install what is missing from the package list; does nothing when all is installed."""
    packages = read_package_list(os.path.join(root, PACKAGE_LIST))
    missing = missing_packages(packages)
    if missing is None:
        print("sabo: dpkg-query not found (not a Debian system): not checking packages; "
              "install the equivalents of {} yourself".format(PACKAGE_LIST), file=out, flush=True)
        return
    if not missing:
        return
    install_packages(missing, out)
    still_missing = missing_packages(packages)
    if still_missing:
        raise SaboError("still not installed after apt-get: {}".format(" ".join(still_missing)))


def _run_streamed(command, quiet, out):
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


def ensure_build(root, build_dir, quiet=False, out=sys.stdout):
    """Configure (Release, Ninja) when `build_dir` has no CMake cache yet, then build."""
    for tool in ("cmake", "ninja"):
        if shutil.which(tool) is None:
            raise SaboError("{} is not installed: run `./sabo setup`".format(tool))
    if not os.path.exists(os.path.join(build_dir, "CMakeCache.txt")):
        command = ["cmake", "-S", root, "-B", build_dir, "-G", "Ninja", "-DCMAKE_BUILD_TYPE=Release"]
        if _run_streamed(command, quiet, out) != 0:
            raise SaboError("configuring with CMake failed (see above): {}".format(" ".join(command)), EXIT_FAILED)
    command = ["cmake", "--build", build_dir]
    if _run_streamed(command, quiet, out) != 0:
        raise SaboError("the build failed (see above): {}".format(" ".join(command)), EXIT_FAILED)


def setup(root, build_dir, quiet=False, out=sys.stdout):
    ensure_packages(root, out)
    ensure_build(root, build_dir, quiet, out)
