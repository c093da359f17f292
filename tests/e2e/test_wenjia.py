"""The Wenjia scenes (issue 23), reduced: configs/tests/wenjia_{original,treated}_reduced.toml, the scenes of
configs/wenjia_*.toml at 3.5 m spacing for the first second, through the real processes. Each loads and
completes, keeps every particle in the domain and every boulder in the channel, and closes the energy balance
within 3 % of the potential energy released; the front starts at the deposit's toe; scripts/wenjia_compare.py
makes its table and figures from the two folders. And the committed scenes are what scripts/make_wenjia.py
writes. Each check prints measured beside expected."""
import csv
import os
import subprocess
import sys

from e2e_support import ROOT, RealRunTestCase, interpolate, load_scene, read_csv, read_json, read_vtk, vtp_series

LAYOUTS = ("original", "treated")
BALANCE_TOLERANCE = 0.03  # of the potential energy released


def front_ahead(scene):
    return scene["fronts"][0].get("ahead", 0)


def read_profile(path):
    distance, elevation = [], []
    with open(path) as handle:
        for line in handle:
            if line.startswith("#") or line.startswith("distance"):
                continue
            s, z = line.split(",")
            distance.append(float(s))
            elevation.append(float(z))
    return distance, elevation


class WenjiaReducedTest(RealRunTestCase):
    def test_the_scenes_are_what_the_generator_writes(self):
        result = subprocess.run([sys.executable, os.path.join(ROOT, "scripts", "make_wenjia.py"), "--check"],
                                capture_output=True, text=True)
        print(result.stdout.strip())
        self.assertEqual(result.returncode, 0, result.stdout + result.stderr)

    def check_layout(self, layout):
        relative = "configs/tests/wenjia_{}_reduced.toml".format(layout)
        out = os.path.join(self.tmp, layout)
        sabo = self.run_sabo(self.scene_path(relative), out)
        self.assertEqual(sabo.wait(180), 0, sabo.output())
        scene = load_scene(self.scene_path(relative))
        summary = read_json(os.path.join(out, "summary.json"))
        self.assertEqual(summary["status"], "completed")
        print("{}: {} steps to t = {} s in {:.1f} s of wall time".format(layout, summary["steps"],
                                                                        summary["simulated_time"],
                                                                        summary["wall_seconds"]))

        # Every fluid particle still in the domain; every boulder between the walls and above the bed.
        sph = read_vtk(vtp_series(out, "sph")[-1][1])
        self.assertEqual(int(sph["active"].min()), 1, "fluid particles left the domain")
        distance, elevation = read_profile(os.path.join(ROOT, "configs", "wenjia", "profile_{}.csv".format(layout)))
        half_width = scene["structures"][0]["width"] / 2
        dem = read_vtk(vtp_series(out, "dem")[-1][1])
        worst_side, worst_bed = 0.0, float("inf")
        for (x, y, z), radius in zip(dem["Points"], dem["radius"]):
            worst_side = max(worst_side, abs(y) + radius - half_width)
            worst_bed = min(worst_bed, z - radius - interpolate(x, distance, elevation))
        print("{}: {} boulders, deepest into a side wall {:.3f} m, lowest above the bed {:.3f} m (tolerance 0.1 "
              "m each way: the penalty's overlap)".format(layout, len(dem["radius"]), worst_side, worst_bed))
        self.assertLessEqual(worst_side, 0.1)
        self.assertGreaterEqual(worst_bed, -0.1)

        # The energy balance against the potential energy the flow released.
        rows = read_csv(os.path.join(out, "energy.csv"))
        first, last = rows[0], rows[-1]
        released = float(first["potential"]) - float(last["potential"])
        residual = ((float(last["total"]) + float(last["dissipated"]))
                    - (float(first["total"]) + float(first["dissipated"])))
        print("{}: potential energy released {:.4g} J, kinetic {:.4g} J, dissipated {:.4g} J; balance residual "
              "{:.4g} J = {:.2%} of the release (tolerance {:.0%})".format(
                  layout, released, float(last["kinetic"]), float(last["dissipated"]), residual,
                  residual / released, BALANCE_TOLERANCE))
        self.assertGreater(released, 0.0)
        self.assertLess(abs(residual), BALANCE_TOLERANCE * released)

        # The front starts at the toe of the deposit and moves down the gully.
        front = summary["results"]["sph_solver"]["fronts"]["debris_front"]
        toe = front["stations"]["source_toe"]["at"]
        dx = scene["sph"]["particle_spacing"]
        positions = front["history"]["position"]
        # The particles fill the deposit's outline inset by half a spacing (the fluid's profile: its toe corner
        # stands back from the bed's toe); toward that corner the wedge is thinner than a lattice row, and the
        # front leaves out the `ahead` most advanced particles (two abreast): it starts within
        # ahead / 2 + 1 spacings behind the inset toe.
        inset_toe = scene["fluids"][0]["profile"][1][0]
        behind = (front_ahead(scene) / 2 + 1) * dx
        print("{}: front from {:.2f} m to {:.2f} m (the deposit's toe at {:.2f} m, the particles' outline's at "
              "{:.2f} m: the front starts within {} m behind it)".format(layout, positions[0], positions[-1], toe,
                                                                        inset_toe, behind))
        self.assertLessEqual(positions[0], inset_toe)
        self.assertGreaterEqual(positions[0], inset_toe - behind)
        self.assertGreater(positions[-1], positions[0])
        with open(os.path.join(out, "fronts.csv"), newline="") as handle:
            self.assertEqual(len(list(csv.DictReader(handle))), front["samples"])
        return out, summary

    def test_both_layouts_reduced_and_their_comparison(self):
        runs = {layout: self.check_layout(layout) for layout in LAYOUTS}
        # scripts/wenjia_compare.py on the two folders: every row of the paper's, its numbers from the runs.
        out = os.path.join(self.tmp, "comparison")
        result = subprocess.run(["/usr/bin/python3", os.path.join(ROOT, "scripts", "wenjia_compare.py"),
                                 "--original", runs["original"][0], "--treated", runs["treated"][0], "--out", out],
                                capture_output=True, text=True)
        print(result.stdout)
        self.assertEqual(result.returncode, 0, result.stderr)
        with open(os.path.join(out, "comparison.md")) as handle:
            table = handle.read()
        for quantity in ("check dam", "houses", "deposit at the gully mouth", "front passing the step pools: speed",
                         "slit dam 1 full", "peak fluid force on slit dam 1", "peak boulder force on slit dam 3"):
            self.assertIn("| {} |".format(quantity), table)
        peak = runs["treated"][1]["peak_force"]["slit_dam_1"]["fluid"] / 1e6
        self.assertIn("| peak fluid force on slit dam 1 | 65.7 MN | {:.1f} MN |".format(peak), table)
        # One second of flow reaches no structure: the check dam stands, and the final depths at the houses and
        # the mouth are not judged before the paper's 120 and 160 s.
        self.assertIn("| original | check dam | destroyed | standing (0% of its elements eroded) | no |", table)
        for layout, end in (("original", 120), ("treated", 160)):
            self.assertRegex(table, r"\| {} \| houses \| .* at t = 1 s, still flowing \(the paper's {} s not run\) "
                                    r"\| not judged \|".format(layout, end))
        for figure in ("front.png", "forces.png", "deposit.png", "final_original.png", "final_treated.png"):
            self.assertTrue(os.path.getsize(os.path.join(out, figure)) > 10000, figure)
