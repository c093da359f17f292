"""`./sabo plot` and the plots at the end of `./sabo run` (scripts/sabo_plot.py under /usr/bin/python3 with
matplotlib): the figures of a real run folder (a hydrostatic tank: forces.csv, energy.csv and the coupler's
events), two runs overlaid, gauges.csv and sensors.csv in the formats of docs/scene.md, bad input (exit 2
naming the file and what is wrong) and a python3 without matplotlib (how to get the plots; the run still
completes). Each check prints what it found."""
import math
import os
import re
import shutil
import struct

from e2e_support import BUILD_DIR, ROOT, RealRunTestCase, Sabo

TANK = "configs/tests/sph_tank_penalty.toml"
BOULDERS_TANK = "configs/tests/sph_boulders_tank.toml"  # fluid, two boulders and structures: a snapshot's all
RUN_FIGURES = ("forces.png", "energy.png", "steps.png")  # the figures a run of TANK has data for
MIN_PNG_BYTES = 20000
WIDTH_PX = 1200  # 10 in at 120 dpi
MIN_HEIGHT_PX = 700
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
PLOT_ENV = {"SABO_PLOT_PYTHON": ""}


def png_size(path):
    """(width, height) from the IHDR chunk, the first after the PNG signature."""
    with open(path, "rb") as handle:
        head = handle.read(24)
    if head[:8] != PNG_SIGNATURE or head[12:16] != b"IHDR":
        raise AssertionError("{} is not a PNG file".format(path))
    return struct.unpack(">II", head[16:24])


def write(path, text):
    with open(path, "w", encoding="utf-8") as handle:
        handle.write(text)


def gauges_csv(line=True):
    """Two point gauges (empty depth) and, with `line`, a line gauge of 5 points whose water falls from 0.3 m."""
    rows = ["time,gauge,point,x,y,z,kernel_sum,pressure,velocity_x,velocity_y,velocity_z,depth"]
    for k in range(41):
        t = 0.01 * k
        depth = 0.3 * math.exp(-t)
        for name, x in (("wall", 1.0), ("middle", 0.5)):
            rows.append("{:g},{},0,{},0,0.05,1,{:.6g},{:.6g},0,{:.6g},".format(
                t, name, x, 2000.0 * x * math.sin(math.pi * t / 0.4), 0.5 * math.cos(t), -0.1 * t))
        for point in range(5 if line else 0):
            z = 0.1 * point
            wet = z < depth
            rows.append("{:g},profile,{},0.2,0,{:g},{},{:.6g},0.1,0,0,{:.6g}".format(
                t, point, z, 1 if wet else 0, 9810.0 * (depth - z) if wet else 0.0, depth))
    return "\n".join(rows) + "\n"


def sensors_csv():
    """A 10 mm transducer and a whole part, each loaded by two sources."""
    rows = ["time,sensor,part,source,Fx,Fy,Fz,F,F_peak,area,pressure"]
    for k in range(41):
        t = 0.01 * k
        for sensor, area in (("transducer", 1e-4), ("dam", 2.0)):
            for source, share in (("fluid", 1.0), ("particles", 0.3)):
                force = share * area * 5e4 * math.sin(math.pi * t / 0.4) ** 2
                rows.append("{:g},{},dam,{},{:.6g},0,0,{:.6g},{:.6g},{},{:.6g}".format(
                    t, sensor, source, -force, force, 1.4 * force, area, force / area))
    return "\n".join(rows) + "\n"


class PlotTest(RealRunTestCase):
    def plot(self, *args, env=None):
        """`./sabo plot ARGS`: (exit status, stdout, stderr)."""
        sabo = self.sabo(["plot"] + list(args), env=dict(PLOT_ENV, **(env or {})))
        code = sabo.wait(120)
        print("./sabo plot {} -> {}\n{}{}".format(" ".join(args), code, sabo.stdout, sabo.stderr))
        return code, sabo.stdout, sabo.stderr

    def assertFigures(self, folder, names):
        for name in names:
            path = os.path.join(folder, name)
            self.assertTrue(os.path.isfile(path), "no {}".format(path))
            width, height = png_size(path)
            size = os.path.getsize(path)
            print("{}: {} x {} px, {} bytes".format(path, width, height, size))
            self.assertGreater(size, MIN_PNG_BYTES, path)
            self.assertEqual(width, WIDTH_PX, path)
            self.assertGreaterEqual(height, MIN_HEIGHT_PX, path)

    def assertNoTraceback(self, text):
        self.assertNotIn("Traceback", text)

    def test_a_snapshot_of_a_run_folder_shows_the_fluid_the_boulders_and_the_structures(self):
        """scripts/render_snapshot.py (the README's picture) on a short run of the boulders tank: every fluid
        particle of the last output, both boulders, the structures' section; bad input exits 2 naming it."""
        with open(self.scene_path(BOULDERS_TANK), encoding="utf-8") as handle:
            text = handle.read()
        self.assertIn("end_time = 0.3", text)
        scene = os.path.join(self.tmp, "boulders.toml")
        write(scene, text.replace("end_time = 0.3", "end_time = 0.04"))
        run = os.path.join(self.tmp, "boulders")
        sabo = self.run_sabo(scene, run)
        self.assertEqual(sabo.wait(120), 0, sabo.output())
        script = os.path.join(ROOT, "scripts", "render_snapshot.py")
        out = os.path.join(self.tmp, "snapshot.png")
        sabo = self.sabo_python([script, run, "--out", out])
        self.assertEqual(sabo.wait(120), 0, sabo.output())
        print(sabo.stdout.strip())
        with open(os.path.join(run, "sph_solver.log"), encoding="utf-8") as log:
            fluid = int(re.search(r"(\d+) SPH particles", log.read()).group(1))
        self.assertRegex(sabo.stdout, r"t = 0\.04\d* s, {} fluid particles, 2 boulders, ".format(fluid))
        segments = int(re.search(r"(\d+) structure segments", sabo.stdout).group(1))
        self.assertGreater(segments, 0)
        width, height = png_size(out)
        print("{}: {} x {} px".format(out, width, height))
        self.assertGreater(os.path.getsize(out), 10000)

        empty = os.path.join(self.tmp, "empty")
        os.makedirs(empty)
        sabo = self.sabo_python([script, empty])
        self.assertEqual(sabo.wait(60), 2)
        self.assertIn("no ParaView series (*.pvd) here", sabo.stderr)
        last = sorted(os.listdir(os.path.join(run, "sph")))[-1]
        with open(os.path.join(run, "sph", last), "r+b") as handle:
            handle.truncate(200)
        sabo = self.sabo_python([script, run])
        self.assertEqual(sabo.wait(60), 2)
        print(sabo.stderr.strip())
        self.assertIn(last, sabo.stderr)

    def sabo_python(self, args):
        """A script under Debian's python3 (matplotlib), tracked like `./sabo`."""
        process = Sabo(["/usr/bin/python3"] + args, raw=True)
        self.started.append(process)
        return process

    def test_a_run_plots_itself_and_sabo_plot_redraws_and_overlays(self):
        first = os.path.join(self.tmp, "tank")
        sabo = self.run_sabo(self.scene_path(TANK), first, plots=True)
        self.assertEqual(sabo.wait(120), 0, sabo.output())
        plots = os.path.join(first, "plots")
        self.assertIn("  plots:       {}/: {}".format(plots, ", ".join(RUN_FIGURES)), sabo.stdout)
        self.assertFigures(plots, RUN_FIGURES)
        self.assertEqual(sorted(os.listdir(plots)), sorted(RUN_FIGURES))

        shutil.rmtree(plots)
        code, stdout, stderr = self.plot(first)
        self.assertEqual(code, 0, stderr)
        self.assertFigures(plots, RUN_FIGURES)
        self.assertIn("skipped: fem_energy.png (no fem_energy.csv), gauges.png (no gauges.csv), "
                      "fronts.png (no fronts.csv), front_stations.png (no front_stations.csv), "
                      "sensors.png (no sensors.csv)", stdout)

        second = os.path.join(self.tmp, "tank_again")
        sabo = self.run_sabo(self.scene_path(TANK), second)
        self.assertEqual(sabo.wait(120), 0, sabo.output())
        self.assertFalse(os.path.exists(os.path.join(second, "plots")), "--no-plots drew plots")
        code, stdout, stderr = self.plot(first, second)
        self.assertEqual(code, 0, stderr)
        self.assertFigures(os.path.join(plots, "compare_tank_again"), RUN_FIGURES)
        elsewhere = os.path.join(self.tmp, "comparison")
        code, stdout, stderr = self.plot(first, second, "--out", elsewhere)
        self.assertEqual(code, 0, stderr)
        self.assertFigures(elsewhere, RUN_FIGURES)

    def test_without_matplotlib_the_run_completes_and_says_how_to_get_the_plots(self):
        blocker = os.path.join(self.tmp, "no_matplotlib")
        os.makedirs(blocker)
        write(os.path.join(blocker, "matplotlib.py"), 'raise ImportError("No module named \'matplotlib\'")\n')
        python = os.path.join(self.tmp, "python3")
        write(python, '#!/bin/sh\nPYTHONPATH="{}" exec /usr/bin/python3 "$@"\n'.format(blocker))
        os.chmod(python, 0o755)
        out = os.path.join(self.tmp, "tank")
        sabo = self.sabo(["run", self.scene_path(TANK), "--out", out, "--no-setup"],
                         env={"SABO_BUILD_DIR": BUILD_DIR, "SABO_PLAN_OVERRIDE": "", "SABO_WATCHDOG_MIN_S": "",
                              "SABO_PLOT_PYTHON": python})
        self.assertEqual(sabo.wait(120), 0, sabo.output())
        print("./sabo run with {}: {}".format(python, sabo.stderr.strip()))
        hint = "sudo apt-get install python3-matplotlib, then ./sabo plot {}".format(out)
        self.assertIn("sabo: warning: plots: {} cannot import matplotlib: {}".format(python, hint), sabo.stderr)
        self.assertNoTraceback(sabo.stderr)
        code, _, stderr = self.plot(out, env={"SABO_PLOT_PYTHON": python})
        self.assertEqual(code, 1)
        self.assertIn(hint, stderr)
        self.assertNoTraceback(stderr)

    def test_gauges_and_sensors_files_are_drawn(self):
        run = os.path.join(self.tmp, "synthetic")
        os.makedirs(run)
        write(os.path.join(run, "gauges.csv"), gauges_csv())
        write(os.path.join(run, "sensors.csv"), sensors_csv())
        code, stdout, stderr = self.plot(run)
        self.assertEqual(code, 0, stderr)
        self.assertIn("wrote {}/: gauges.png, sensors.png".format(os.path.join(run, "plots")), stdout)
        self.assertFigures(os.path.join(run, "plots"), ("gauges.png", "sensors.png"))
        points_only = os.path.join(self.tmp, "points_only")  # every depth field empty
        os.makedirs(points_only)
        write(os.path.join(points_only, "gauges.csv"), gauges_csv(line=False))
        code, _, stderr = self.plot(points_only)
        self.assertEqual(code, 0, stderr)
        self.assertFigures(os.path.join(points_only, "plots"), ("gauges.png",))

    def test_bad_input_exits_2_naming_the_file_and_what_is_wrong(self):
        older = os.path.join(self.tmp, "older")
        os.makedirs(older)
        write(os.path.join(older, "forces.csv"), "time,part,source,Fx,Fy,Fz,F\n0,dam,fluid,0,0,0,0\n")
        code, _, stderr = self.plot(older)
        self.assertEqual(code, 2)
        self.assertIn("{}: no column F_peak".format(os.path.join(older, "forces.csv")), stderr)
        self.assertIn("older format", stderr)
        self.assertNoTraceback(stderr)

        broken = os.path.join(self.tmp, "broken")
        os.makedirs(broken)
        write(os.path.join(broken, "energy.csv"), "time,kinetic,potential,solver_elastic,contact_elastic,total,"
                                                  "dissipated\n0,0,1,0,0,1,0\n0.1,0.5,0.5,0,0,one,0\n")
        code, _, stderr = self.plot(broken)
        self.assertEqual(code, 2)
        self.assertIn("{} line 3: column total holds 'one', not a number".format(
            os.path.join(broken, "energy.csv")), stderr)
        self.assertNoTraceback(stderr)

        empty = os.path.join(self.tmp, "empty")
        os.makedirs(empty)
        code, _, stderr = self.plot(empty)
        self.assertEqual(code, 2)
        self.assertIn("{}: nothing to plot: none of forces.csv, energy.csv".format(empty), stderr)
        self.assertFalse(os.path.exists(os.path.join(empty, "plots")))
        self.assertNoTraceback(stderr)

        code, _, stderr = self.plot(os.path.join(self.tmp, "absent"))
        self.assertEqual(code, 2)
        self.assertIn("absent: not a folder", stderr)
        self.assertNoTraceback(stderr)
