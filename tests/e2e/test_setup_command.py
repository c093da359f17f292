"""`./sabo setup` and `./sabo test` with fake system tools (dpkg-query, apt-get, sudo, cmake, ctest) first
on PATH: which packages get installed, how, and what is configured, built and tested."""
import io
import os
import sys
import unittest
from unittest import mock

from e2e_support import ROOT, E2eTestCase, read_text

sys.path.insert(0, ROOT)
from supervisor import setup_env  # noqa: E402
from supervisor.errors import SaboError  # noqa: E402

# Each fake tool appends "NAME ARG..." to $FAKE_LOG, then acts as described.
FAKE_TOOL = r'''#!{python}
import os, sys
name = os.path.basename(sys.argv[0])
args = sys.argv[1:]
with open(os.environ["FAKE_LOG"], "a") as log:
    extra = " DEBIAN_FRONTEND=" + os.environ.get("DEBIAN_FRONTEND", "") if name == "apt-get" else ""
    extra = " CTEST_PARALLEL_LEVEL=" + os.environ.get("CTEST_PARALLEL_LEVEL", "") if name == "ctest" else extra
    log.write(" ".join([name] + [a.replace("\n", "\\n").replace("\t", "\\t") for a in args]) + extra + "\n")
installed_path = os.environ["FAKE_INSTALLED"]
installed = open(installed_path).read().split()
if name == "dpkg-query":
    missing = False
    for package in args[2:]:
        if package in installed:
            print(package + "\tii ")
        else:
            print("dpkg-query: no packages found matching " + package, file=sys.stderr)
            missing = True
    sys.exit(1 if missing else 0)
if name == "apt-get":
    if os.environ.get("FAKE_APT_FAIL"):
        sys.exit(100)
    if args[0] == "install":
        with open(installed_path, "a") as handle:
            handle.write("\n" + "\n".join(a for a in args[1:] if not a.startswith("-")) + "\n")
if name == "sudo":
    os.execvp(args[0], args)
if name == "cmake":
    if "-B" in args:
        build = args[args.index("-B") + 1]
        os.makedirs(build, exist_ok=True)
        open(os.path.join(build, "CMakeCache.txt"), "w").close()
        print("-- Configuring done")
    if args[:1] == ["--build"]:
        if os.environ.get("FAKE_BUILD_FAIL"):
            print("main.cpp:1: error: expected ';'")
            sys.exit(1)
        print("ninja: no work to do." if os.environ.get("FAKE_UP_TO_DATE") else "[1/1] Linking CXX executable x")
if name == "ctest":
    sys.exit(int(os.environ.get("FAKE_CTEST_RC", "0")))
'''


class SetupTest(E2eTestCase):
    def setUp(self):
        super().setUp()
        self.bin = os.path.join(self.tmp, "fakebin")
        os.makedirs(self.bin)
        for name in ("dpkg-query", "apt-get", "sudo", "cmake", "ninja", "ctest"):
            path = os.path.join(self.bin, name)
            with open(path, "w") as handle:
                handle.write(FAKE_TOOL.format(python=sys.executable))
            os.chmod(path, 0o755)
        self.log = os.path.join(self.tmp, "log")
        self.installed = os.path.join(self.tmp, "installed")
        self.packages = setup_env.read_package_list(os.path.join(ROOT, setup_env.PACKAGE_LIST))
        self.build_dir = os.path.join(self.tmp, "build")
        self.env = {"PATH": self.bin + os.pathsep + os.environ["PATH"], "FAKE_LOG": self.log,
                    "FAKE_INSTALLED": self.installed, "SABO_BUILD_DIR": self.build_dir}

    def set_installed(self, packages):
        with open(self.installed, "w") as handle:
            handle.write("\n".join(packages) + "\n")

    def calls(self):
        calls = read_text(self.log).splitlines() if os.path.exists(self.log) else []
        os.remove(self.log) if os.path.exists(self.log) else None
        return calls

    def test_package_list(self):
        self.assertEqual(len(self.packages), len(set(self.packages)), "no duplicates")
        for needed in ("build-essential", "cmake", "ninja-build", "libzmq3-dev", "libhdf5-dev", "libgtest-dev",
                       "python3-numpy", "python3-h5py"):
            self.assertIn(needed, self.packages)

    def test_nothing_installed_when_all_is_there_and_configure_only_once(self):
        self.set_installed(self.packages)
        sabo = self.sabo(["setup"], env=self.env)
        self.assertEqual(sabo.wait(60), 0, sabo.output())
        self.assertEqual(self.calls(), [
            r"dpkg-query -W -f=${Package}\t${db:Status-Abbrev}\n " + " ".join(self.packages),
            "cmake -S {} -B {} -G Ninja -DCMAKE_BUILD_TYPE=Release".format(ROOT, self.build_dir),
            "cmake --build " + self.build_dir])
        self.assertIn("[1/1] Linking CXX executable x", sabo.stdout)

        again = self.sabo(["setup"], env=dict(self.env, FAKE_UP_TO_DATE="1"))
        self.assertEqual(again.wait(60), 0, again.output())
        calls = self.calls()
        self.assertEqual(len(calls), 2, calls)
        self.assertEqual(calls[1], "cmake --build " + self.build_dir)
        self.assertNotIn("no work to do", again.stdout)

    def test_missing_packages_are_installed_with_apt_get(self):
        missing = [self.packages[1], self.packages[-1]]
        self.set_installed([p for p in self.packages if p not in missing])
        sabo = self.sabo(["setup"], env=self.env)
        self.assertEqual(sabo.wait(60), 0, sabo.output())
        calls = self.calls()
        self.assertEqual(calls[1:3], [
            "apt-get update DEBIAN_FRONTEND=noninteractive",
            "apt-get install -y --no-install-recommends {} DEBIAN_FRONTEND=noninteractive".format(" ".join(missing))])
        self.assertTrue(calls[3].startswith("dpkg-query"), "checked again after installing")
        self.assertIn("installing " + " ".join(missing), sabo.stdout)

    def test_failing_apt_get_is_reported(self):
        self.set_installed(self.packages[1:])
        sabo = self.sabo(["setup"], env=dict(self.env, FAKE_APT_FAIL="1"))
        self.assertEqual(sabo.wait(60), 1, sabo.output())
        self.assertIn("apt-get update` failed with exit code 100", sabo.stderr)

    def test_sudo_is_used_when_not_root(self):
        self.set_installed([])
        with mock.patch.dict(os.environ, self.env), mock.patch("os.geteuid", return_value=1000):
            setup_env.install_packages(["libfoo-dev"], out=io.StringIO())
        self.assertEqual(self.calls(), [
            "sudo env DEBIAN_FRONTEND=noninteractive apt-get update",
            "apt-get update DEBIAN_FRONTEND=noninteractive",
            "sudo env DEBIAN_FRONTEND=noninteractive apt-get install -y --no-install-recommends libfoo-dev",
            "apt-get install -y --no-install-recommends libfoo-dev DEBIAN_FRONTEND=noninteractive"])

    def test_build_failure_is_reported_with_the_compiler_output(self):
        self.set_installed(self.packages)
        sabo = self.sabo(["setup", "--quiet"], env=dict(self.env, FAKE_BUILD_FAIL="1"))
        self.assertEqual(sabo.wait(60), 1, sabo.output())
        self.assertIn("main.cpp:1: error: expected ';'", sabo.stdout)
        self.assertIn("the build failed", sabo.stderr)

    def test_sabo_test_passes_its_arguments_and_exit_code_through(self):
        self.set_installed(self.packages)
        sabo = self.sabo(["test", "-R", "e2e_", "-j2", "--no-tests=error"],
                         env=dict(self.env, FAKE_CTEST_RC="8", CTEST_PARALLEL_LEVEL=""))
        self.assertEqual(sabo.wait(60), 8, sabo.output())
        # One test per core by default (ctest's -j2 here wins over the variable).
        self.assertEqual(self.calls()[-1],
                         f"ctest --test-dir {self.build_dir} --output-on-failure -R e2e_ -j2 --no-tests=error "
                         f"CTEST_PARALLEL_LEVEL={os.cpu_count()}")

        sabo = self.sabo(["test", "--no-setup", "--", "-L", "fast"], env=dict(self.env, CTEST_PARALLEL_LEVEL="7"))
        self.assertEqual(sabo.wait(60), 0, sabo.output())
        self.assertEqual(self.calls(),
                         [f"ctest --test-dir {self.build_dir} --output-on-failure -L fast CTEST_PARALLEL_LEVEL=7"])

    def test_missing_dpkg_is_tolerated(self):
        with mock.patch("shutil.which", return_value=None):
            self.assertIsNone(setup_env.missing_packages(["cmake"]))
            with self.assertRaises(SaboError):
                setup_env.install_packages(["cmake"])


if __name__ == "__main__":
    unittest.main()
