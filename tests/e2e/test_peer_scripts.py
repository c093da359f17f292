"""Issue 26, the side-by-side scripts of bench/peers/ against fakes of both sides. dualsphysics.py: a
DualSPHysics that writes a Run.out as DualSPHysics 5.4 does (its format copied from a real run: thousands
separators, dotted labels) and a bench_sph_throughput that prints its JSON line. liggghts.py: an mpirun that
runs its program, a LIGGGHTS that prints its thermo rows and "Loop time" line as LIGGGHTS 3.8 does, and a
bench_dem_box. The rates, medians and ratios are checked against the arithmetic of the fakes' figures, and a
peer that fails or writes no runtime is refused with what to mend."""
import json
import os
import shutil
import stat
import subprocess
import tempfile
import textwrap
import unittest

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.realpath(__file__))))
SCRIPT = os.path.join(ROOT, "bench", "peers", "dualsphysics.py")

RUN_OUT = """\
Total particles: 171,496 (bound=43186 (fx=43186 mv=0 ft=0) fluid=128310)
[Simulation finished  05-12-2026 14:08:12]
Particles of simulation (initial): 171,496
Total Runtime....................: {total} sec.
Simulation Runtime...............: {runtime} sec.
Steps per second.................: 3.431660
Steps of simulation..............: {steps}
"""


def executable(path, text):
    with open(path, "w", encoding="utf-8") as handle:
        handle.write(text)
    os.chmod(path, os.stat(path).st_mode | stat.S_IXUSR)


class DualSphysicsPeerTest(unittest.TestCase):
    def setUp(self):
        self.tmp = tempfile.mkdtemp(prefix="sabo-peer-test-")
        self.addCleanup(shutil.rmtree, self.tmp, ignore_errors=True)
        self.case = os.path.join(self.tmp, "CaseDambreak")
        for ext in (".xml", ".bi4"):
            open(self.case + ext, "w", encoding="utf-8").close()
        # A fake DualSPHysics: runtimes 20, 25, 30 s for 100 steps, one per call (a counter file).
        self.peer = os.path.join(self.tmp, "DualSPHysics5.4CPU_linux64")
        executable(self.peer, textwrap.dedent("""\
            #!/usr/bin/env python3
            import os, sys
            out = sys.argv[2]
            os.makedirs(out, exist_ok=True)
            counter = os.path.join(os.path.dirname(os.path.abspath(__file__)), "calls")
            calls = int(open(counter).read()) if os.path.exists(counter) else 0
            open(counter, "w").write(str(calls + 1))
            if os.environ.get("FAKE_NO_RUNTIME"):
                open(os.path.join(out, "Run.out"), "w").write("Total particles: 10 (bound=4 fluid=6)\\n")
                sys.exit(0)
            assert "-ompthreads:2" in sys.argv and "-nsteps:100" in sys.argv, sys.argv
            runtime = [20.0, 25.0, 30.0][calls % 3]
            open(os.path.join(out, "Run.out"), "w").write({run_out!r}.format(
                total=runtime + 0.1, runtime=runtime, steps=100))
            """).format(run_out=RUN_OUT))
        # A fake Sabo build: bench_sph_throughput printing 1.0, 1.5, 2.0e6 fluid particle-steps/s.
        bin_dir = os.path.join(self.tmp, "build", "bin")
        os.makedirs(bin_dir)
        executable(os.path.join(bin_dir, "bench_sph_throughput"), textwrap.dedent("""\
            #!/usr/bin/env python3
            import json, os, sys
            assert sys.argv[1:7] == ["--kernel", "cubic_spline", "--ratio", "1.732", "--spacing", "0.009"], sys.argv
            counter = os.path.join(os.path.dirname(os.path.abspath(__file__)), "calls")
            calls = int(open(counter).read()) if os.path.exists(counter) else 0
            open(counter, "w").write(str(calls + 1))
            print(json.dumps({"particles": 170368, "walls": 276284, "particle_steps_per_second":
                              [1.0e6, 1.5e6, 2.0e6][calls % 3], "neighbours_per_particle": 167.0,
                              "bytes_per_particle": 170.0, "seconds": 1.0}))
            """))
        self.env = dict(os.environ, SABO_BUILD_DIR=os.path.join(self.tmp, "build"))

    def run_script(self, extra_env=None):
        env = dict(self.env, **(extra_env or {}))
        return subprocess.run([SCRIPT, "--dualsphysics", self.peer, "--case", self.case, "--runs", "3"],
                              env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                              universal_newlines=True, timeout=60)

    def test_medians_and_both_ratios(self):
        result = self.run_script()
        self.assertEqual(result.returncode, 0, result.stdout)
        summary = json.loads(result.stdout.strip().splitlines()[-1])
        fluid_rate = 128310 * 100 / 25.0  # the median runtime
        all_rate = (128310 + 43186) * 100 / 25.0
        peer = summary["peers"][0]
        print("fluid rate {:.6g} (expected {:.6g}), with the boundary {:.6g} ({:.6g}); ratios {:.4f} and {:.4f} "
              "(expected {:.4f}, {:.4f})".format(peer["fluid_rate"], fluid_rate, peer["all_rate"], all_rate,
                                                 peer["ratio_fluid"], peer["ratio_all"], 1.5e6 / fluid_rate,
                                                 1.5e6 / all_rate))
        self.assertAlmostEqual(summary["sabo_fluid_rate"], 1.5e6)
        self.assertAlmostEqual(peer["fluid_rate"], fluid_rate, delta=1e-9 * fluid_rate)
        self.assertAlmostEqual(peer["all_rate"], all_rate, delta=1e-9 * all_rate)
        self.assertAlmostEqual(peer["ratio_fluid"], 1.5e6 / fluid_rate, places=9)
        self.assertAlmostEqual(peer["ratio_all"], 1.5e6 / all_rate, places=9)
        self.assertEqual(result.stdout.count("round "), 6, result.stdout)
        self.assertIn("128310 fluid + 43186 boundary particles, 100 steps in 20.000 s", result.stdout)

    def test_a_run_without_a_runtime_is_refused(self):
        result = self.run_script({"FAKE_NO_RUNTIME": "1"})
        self.assertNotEqual(result.returncode, 0)
        self.assertIn("Run.out: no 'Simulation Runtime' and 'Steps of simulation' lines", result.stdout)

    def test_a_case_without_its_files_is_refused(self):
        os.remove(self.case + ".bi4")
        result = self.run_script()
        self.assertNotEqual(result.returncode, 0)
        self.assertIn("CaseDambreak.bi4 are needed. Fix: run GenCase", result.stdout)


class LiggghtsPeerTest(unittest.TestCase):
    def setUp(self):
        self.tmp = tempfile.mkdtemp(prefix="sabo-peer-test-")
        self.addCleanup(shutil.rmtree, self.tmp, ignore_errors=True)
        self.mpirun = os.path.join(self.tmp, "mpirun")
        executable(self.mpirun, textwrap.dedent("""\
            #!/usr/bin/env python3
            import os, sys
            args = sys.argv[1:]
            assert args[0] == "-np" and args[2] == "--oversubscribe", args
            program = [a for a in args[3:] if a != "--allow-run-as-root"]
            os.environ["FAKE_RANKS"] = args[1]
            os.execv(program[0], program)
            """))
        # A fake LIGGGHTS: the timed run takes 6, 5, 4 s on one rank (half on two), 1000 steps of 30000 spheres.
        self.lmp = os.path.join(self.tmp, "lmp_auto")
        executable(self.lmp, textwrap.dedent("""\
            #!/usr/bin/env python3
            import os, sys
            deck = sys.argv[sys.argv.index("-in") + 1]
            text = open(deck).read()
            assert "pair_style gran model hertz tangential history" in text and "processors * * 1" in text
            if deck == "settle.in":
                assert "particles_in_region 30000" in text and "run 6000" in text, text
                open("settled.restart", "w").write("fake")
                sys.exit(0)
            assert os.path.exists("settled.restart") and "timestep 1e-05" in text and "run 1000" in text, text
            if os.environ.get("FAKE_CRASH"):
                print("ERROR: Lost atoms")
                sys.exit(1)
            counter = "calls"
            calls = int(open(counter).read()) if os.path.exists(counter) else 0
            open(counter, "w").write(str(calls + 1))
            ranks = int(os.environ["FAKE_RANKS"])
            seconds = [6.0, 5.0, 4.0][calls % 3] / ranks
            print("Step Atoms c_total")
            print("       0    30000    144000 ")
            print("    1000    30000    144000 ")
            print("Loop time of {} on {} procs for 1000 steps with 30000 atoms".format(seconds, ranks))
            """))
        bin_dir = os.path.join(self.tmp, "build", "bin")
        os.makedirs(bin_dir)
        executable(os.path.join(bin_dir, "bench_dem_box"), textwrap.dedent("""\
            #!/usr/bin/env python3
            import json, os, sys
            assert sys.argv[1:3] == ["--spheres", "30000"], sys.argv
            threads = int(os.environ["OMP_NUM_THREADS"])
            print(json.dumps({"sphere_steps_per_second": 9.0e6 * threads, "contacts_per_sphere": 4.8}))
            """))
        self.env = dict(os.environ, SABO_BUILD_DIR=os.path.join(self.tmp, "build"))

    def run_script(self, extra_env=None):
        env = dict(self.env, **(extra_env or {}))
        return subprocess.run([os.path.join(ROOT, "bench", "peers", "liggghts.py"), "--liggghts", self.lmp,
                               "--mpirun", self.mpirun, "--ranks", "1", "2", "--runs", "3"], env=env,
                              stdout=subprocess.PIPE, stderr=subprocess.STDOUT, universal_newlines=True, timeout=60)

    def test_medians_and_ratios_per_rank_count(self):
        result = self.run_script()
        self.assertEqual(result.returncode, 0, result.stdout)
        summary = json.loads(result.stdout.strip().splitlines()[-1])
        for entry, ranks in zip(summary["ranks"], (1, 2)):
            expected = 30000 * 1000 / (5.0 / ranks)  # the median loop time
            print("{} rank(s): LIGGGHTS {:.6g} (expected {:.6g}), ratio {:.4f} (expected {:.4f})".format(
                ranks, entry["liggghts_rate"], expected, entry["ratio"], 9.0e6 * ranks / expected))
            self.assertEqual(entry["ranks"], ranks)
            self.assertAlmostEqual(entry["liggghts_rate"], expected, delta=1e-9 * expected)
            self.assertAlmostEqual(entry["ratio"], 9.0e6 * ranks / expected, places=9)
        self.assertIn("4.80 contacts per sphere", result.stdout)

    def test_a_failed_run_is_refused(self):
        result = self.run_script({"FAKE_CRASH": "1"})
        self.assertNotEqual(result.returncode, 0)
        self.assertIn("failed (exit 1)", result.stdout)
        self.assertIn("ERROR: Lost atoms", result.stdout)


if __name__ == "__main__":
    unittest.main()
