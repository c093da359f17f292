"""B1, a Newtonian surge stopped by a rigid wall, through the real processes (`./sabo run`: coupler,
sph_solver, fem_solver), reduced: Fr = 1 at h = 6 dx with a plateau of 4 T after the impact (T = h / sqrt(g h))
instead of 8 T.
The wall's force plateau per unit width against alpha rho v^2 h (Armanini & Scotton's bore, alpha = 2.35;
tolerance 10 %), the bore's height behind the wall, read by a line gauge, against r h, and the wall's force
against the pressure a line gauge reads one spacing in front of it. The full cases
(Fr = 1, 2, 4 with the longer plateau, the plot of alpha(Fr)) are bench/surge_wall.py's, figures in bench/RESULTS.md."""
import json
import os
import subprocess
import sys
import tempfile
import unittest

from e2e_support import ROOT, RealRunTestCase
from test_plot import png_size

sys.path.insert(0, os.path.join(ROOT, "bench"))
from surge_wall import Surge, measure, TOLERANCE  # noqa: E402


class SurgeWallTest(RealRunTestCase):
    def test_surge_at_froude_1_loads_the_wall_as_the_bore_theory_says(self):
        surge = Surge(1.0, spacings=6, window=4.0)
        out = self.run_scene_text(surge.scene_text(), "surge", 300)
        figures = measure(out, surge)
        off = figures["alpha"] / surge.alpha - 1
        print("B1 Fr = 1, h = 6 dx, block {:g} h: wall force plateau {:.2f} N/m over {:.2f}-{:.2f} s, expected "
              "alpha rho v^2 h = {:.2f} N/m: alpha {:.3f} against {:.3f} ({:+.1%}; tolerance {:.0%})".format(
                  surge.length / surge.depth, figures["plateau"], surge.settled, surge.plateau_end,
                  surge.expected_force(), figures["alpha"], surge.alpha, off, TOLERANCE))
        self.assertLess(abs(off), TOLERANCE)
        bore = figures["bore_depth"] / (surge.ratio * surge.depth) - 1
        print("B1 Fr = 1: bore height {:.4f} m 3 h upstream of the wall, expected r h = {:.4f} m ({:+.1%}; "
              "tolerance 10 %)".format(figures["bore_depth"], surge.ratio * surge.depth, bore))
        self.assertLess(abs(bore), 0.10)
        # The wall particles pass on what the fluid carries: the pressure one spacing in front of the wall,
        # integrated over the height, against the wall's force.
        profile = figures["profile_force"] / figures["plateau"] - 1
        print("B1 Fr = 1: the pressure 1 dx in front of the wall integrated over the height {:.2f} N/m, the wall's "
              "force {:.2f} N/m ({:+.1%}; tolerance 10 %)".format(figures["profile_force"], figures["plateau"],
                                                                  profile))
        self.assertLess(abs(profile), 0.10)
        print("B1 Fr = 1: impact peak {:.1f} N/m = {:.1f} x the plateau".format(
            figures["peak"], figures["peak"] / figures["plateau"]))


class SurgeWallReplotTest(unittest.TestCase):
    """`bench/surge_wall.py --replot`: the alpha(Fr) figure from the figures that runs of several invocations wrote
    (--json), and a clear error for a file that is not such a list."""

    def replot(self, paths, png):
        return subprocess.run(["/usr/bin/python3", os.path.join(ROOT, "bench", "surge_wall.py"), "--replot"] + paths
                              + ["--plot", png], capture_output=True, text=True, timeout=120)

    def test_replot_draws_the_runs_of_several_invocations(self):
        with tempfile.TemporaryDirectory() as tmp:
            paths = []
            for k, (froude, alpha, ratio) in enumerate([(1.0, 2.31, 0.5), (4.0, 1.17, 0.5), (2.0, 1.41, 1.0)]):
                paths.append(os.path.join(tmp, "run{}.json".format(k)))
                with open(paths[-1], "w", encoding="utf-8") as handle:
                    json.dump([{"froude": froude, "alpha": alpha, "spacings": 8, "free_slip": True,
                                "wall_spacing_ratio": ratio}], handle)
            png = os.path.join(tmp, "alpha.png")
            done = self.replot(paths, png)
            self.assertEqual(done.returncode, 0, done.stderr)
            self.assertEqual(png_size(png), (720, 540))
            bad = os.path.join(tmp, "bad.json")
            with open(bad, "w", encoding="utf-8") as handle:
                handle.write("{not json")
            done = self.replot([bad], png)
            self.assertEqual(done.returncode, 2)
            self.assertIn("--replot {}".format(bad), done.stderr)
            with open(bad, "w", encoding="utf-8") as handle:
                json.dump({"froude": 1.0}, handle)
            done = self.replot([bad], png)
            self.assertEqual(done.returncode, 2)
            self.assertIn("not a list of figures with froude, alpha and spacings", done.stderr)


if __name__ == "__main__":
    unittest.main()
