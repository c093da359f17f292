"""Issue 24, `./sabo study`: a study file swept through the real supervisor, its measures against their
references, study.csv / study.md / pareto.png / convergence_<key>.png, runs taken as they are by a second
invocation, and every bad study file refused with its file, line, key and the fix. The units (the Pareto front,
the fitted order) are in test_supervisor_units.py."""
import csv
import os
import struct
import subprocess
import sys
import time

from e2e_support import BUILD_DIR, ROOT, RealRunTestCase

sys.path.insert(0, ROOT)
from supervisor.scene_text import apply_overrides  # noqa: E402

SCENE = "configs/tests/hertz_wall_impact.toml"


def png_size(path):
    with open(path, "rb") as handle:
        head = handle.read(24)
    assert head[:8] == b"\x89PNG\r\n\x1a\n", path
    return struct.unpack(">II", head[16:24])


class StudyTest(RealRunTestCase):
    def study_file(self, name, text):
        path = os.path.join(self.tmp, name + ".toml")
        with open(path, "w", encoding="utf-8") as handle:
            handle.write(text)
        return path

    def run_study(self, path, out, extra=()):
        sabo = self.sabo(["study", path, "--out", out, "--no-setup"] + list(extra),
                         env={"SABO_BUILD_DIR": BUILD_DIR, "SABO_PLAN_OVERRIDE": ""})
        return sabo.wait(300), sabo

    def test_a_time_step_sweep_measured_against_hertz(self):
        scene = self.scene_path(SCENE)
        path = self.study_file("d1", '''format_version = 1
[study]
scene = "{}"
runs_at_once = 2
[[parameters]]
key = "run.max_dt"
values = [1.0]
[[parameters]]
key = "solvers.dem.beta"
from = 1.0
to = 0.1
count = 3
spacing = "log"
[[measures]]
name = "peak_force"
unit = "N"
source = "csv"
file = "forces.csv"
column = "F_peak"
where = {{ part = "wall" }}
reduce = "max"
reference = 11470.0
[[measures]]
name = "rebound_speed"
source = "script"
command = ["/usr/bin/python3", "{}"]
reference = "finest"
[[measures]]
name = "exchanges"
source = "summary"
field = "multirate.solvers.dem_solver.exchanges"
'''.format(scene, self.scene_path("configs/studies/measures/rebound_speed.py")))
        out = os.path.join(self.tmp, "d1")
        code, sabo = self.run_study(path, out)
        print(sabo.stdout[-1500:])
        self.assertEqual(code, 0, sabo.output())
        with open(os.path.join(out, "study.csv"), newline="") as handle:
            rows = list(csv.DictReader(handle))
        self.assertEqual([float(r["solvers.dem.beta"]) for r in rows], [1.0, 0.316227766017, 0.1])  # log spacing
        for row in rows:
            self.assertEqual(row["status"], "completed")
            self.assertGreater(float(row["wall_s"]), 0)
            self.assertGreater(float(row["cpu_s"]), 0)
            self.assertLess(abs(float(row["peak_force"]) / 11470.0 - 1), 0.01)  # Hertz within 1 %
            self.assertAlmostEqual(float(row["peak_force_error"]), abs(float(row["peak_force"]) / 11470.0 - 1),
                                   places=9)
        # Smaller steps: more of them; the finest run is its own reference.
        steps = [int(r["steps"]) for r in rows]
        self.assertEqual(steps, sorted(steps))
        self.assertEqual(float(rows[-1]["rebound_speed_error"]), 0.0)
        with open(os.path.join(out, "study.md"), encoding="utf-8") as handle:
            report = handle.read()
        self.assertIn("observed order of convergence of rebound_speed in solvers.dem.beta", report)
        self.assertIn("★", report)
        for name in ("pareto.png", "convergence_solvers_dem_beta.png"):
            width, height = png_size(os.path.join(out, name))
            print("{}: {} x {}".format(name, width, height))
            self.assertGreater(width, 500)
            self.assertGreater(height, 400)

        # Again: every run is taken as it is.
        start = time.monotonic()
        code, sabo = self.run_study(path, out)
        self.assertEqual(code, 0, sabo.output())
        self.assertIn("3 of 3 runs completed earlier: taken as they are", sabo.stdout)
        print("the second invocation took {:.1f} s".format(time.monotonic() - start))

    def test_every_shipped_study_and_each_of_its_scenes_is_valid(self):
        folder = self.scene_path("configs/studies/d1_impact.toml").rsplit(os.sep, 1)[0]
        studies = sorted(name for name in os.listdir(folder) if name.endswith(".toml"))
        self.assertGreaterEqual(len(studies), 2)
        for name in studies:
            with self.subTest(study=name):
                code, sabo = self.run_study(os.path.join(folder, name), os.path.join(self.tmp, name), ["--dry-run"])
                self.assertEqual(code, 0, sabo.output())
                print(sabo.stdout.splitlines()[0])

    def test_the_cantilever_measure_reads_f1_from_the_tip(self):
        """configs/studies/f1_cantilever.toml's measure on the coarsest run of its sweep (one-point hexahedra, one
        element through the depth; 20 elements, about a second): the middle of the tip's swing against
        q L^4 / (8 E I) and its frequency against the first bending mode, within 1 % (measured 0.31 % and
        0.043 %)."""
        with open(self.scene_path("configs/tests/cantilever_self_weight.toml"), encoding="utf-8") as handle:
            text = apply_overrides(handle.read(), ['structures[0].element_formulation="one_point"',
                                                   "structures[0].element_size=0.05"])
        scene = self.study_file("cantilever", text)
        out = os.path.join(self.tmp, "cantilever")
        sabo = self.run_sabo(scene, out)
        self.assertEqual(sabo.wait(120), 0, sabo.output())
        script = self.scene_path("configs/studies/measures/cantilever_tip.py")
        for option, expected in (("--static", 2.2003e-4), ("--frequency", 41.78)):
            measured = float(subprocess.run(["/usr/bin/python3", script, option, out], check=True,
                                            capture_output=True, text=True).stdout)
            print("{}: measured {:.6g}, expected {:.6g} (tolerance 1 %)".format(option, measured, expected))
            self.assertLess(abs(measured / expected - 1), 0.01)

    def test_the_surge_measure_reads_b1_from_the_wall(self):
        """configs/studies/b1_surge.toml's measure on its base scene, the coarsest run of the sweep (h = 4 dx;
        about 10 s): alpha of the wall's force plateau against the bore theory's 2.355, within B1's 10 %
        (measured 2.257, -4.2 %)."""
        out = os.path.join(self.tmp, "b1")
        sabo = self.run_sabo(self.scene_path("configs/tests/b1_surge_fr1.toml"), out)
        self.assertEqual(sabo.wait(120), 0, sabo.output())
        script = self.scene_path("configs/studies/measures/b1_alpha.py")
        measured = float(subprocess.run(["/usr/bin/python3", script, out], check=True, capture_output=True,
                                        text=True).stdout)
        print("B1 alpha at h = 4 dx: measured {:.4f}, expected 2.355 ({:+.1%}; tolerance 10 %)".format(
            measured, measured / 2.355 - 1))
        self.assertLess(abs(measured / 2.355 - 1), 0.10)

    def test_bad_study_files_are_refused_with_the_line_key_and_fix(self):
        scene = self.scene_path(SCENE)
        head = 'format_version = 1\n[study]\nscene = "{}"\n'.format(scene)
        parameter = '[[parameters]]\nkey = "run.max_dt"\nvalues = [1e-5]\n'
        measure = '[[measures]]\nname = "f"\nsource = "summary"\nfield = "steps"\n'
        cases = [
            (head + parameter + measure.replace('source = "summary"', 'source = "sumary"'),
             ":9: key 'measures[0].source' = \"sumary\": must be one of summary, csv, script"),
            (head + parameter.replace("values", "valeus") + measure,
             ":6: key 'parameters[0].valeus' = [1e-05]: unknown key. Fix: use one of count, from, key, spacing, to, "
             "values"),
            (head + '[[parameters]]\nkey = "max_dt"\nvalues = [1]\n' + measure,
             ":5: key 'parameters[0].key' = \"max_dt\": must be a scene key TABLE.KEY"),
            (head + '[[parameters]]\nkey = "run.max_dt"\nfrom = 1.0\nto = 0.0\ncount = 3\nspacing = "log"\n' + measure,
             ":6: key 'parameters[0].from' = 1.0: a log range needs positive ends"),
            (head + parameter + measure.replace('field = "steps"\n', ""),
             "key 'measures[0].field': missing: source = \"summary\" needs field"),
            (head.replace(scene, "no/such/scene.toml") + parameter + measure,
             ":3: key 'study.scene' = \"no/such/scene.toml\": no such file"),
            (head + parameter + measure.replace('name = "f"', 'name = "steps"'),
             ":8: key 'measures[0].name' = \"steps\": a column of study.csv already"),
            (head + parameter + measure + 'reference = "best"\n',
             ":11: key 'measures[0].reference' = \"best\": must be a number or \"finest\""),
            (head + parameter,
             "key 'measures': a study takes at least one measure from each run"),
            (head + '[[parameters]]\nkey = "run.max_dt"\nvalues = [-1.0]\n' + measure,
             "the variant r00-max_dt_-1 (run.max_dt = -1) is not a valid scene"),
        ]
        for index, (text, expected) in enumerate(cases):
            with self.subTest(expected=expected):
                path = self.study_file("bad{}".format(index), text)
                code, sabo = self.run_study(path, os.path.join(self.tmp, "bad{}".format(index)), ["--dry-run"])
                print(sabo.stderr.strip().splitlines()[-1][:300])
                self.assertEqual(code, 2, sabo.output())
                self.assertIn(expected, sabo.stderr)
                if "variant" in expected:  # and above it, the scene check's own words on the variant
                    self.assertIn("r00-max_dt_-1.toml", sabo.stderr)
                    self.assertIn("key 'run.max_dt' = -1.0: must be > 0", sabo.stderr)
                else:
                    self.assertIn(path, sabo.stderr)
                    self.assertIn("Fix:", sabo.stderr)
