"""A solver in another language (issue 21): examples/python_dem/solver.py, a DEM solver in Python, runs in
place of the dem_solver through the scene's `command` on the sphere drop (reduced to the first bounce). It
bounces with the spring-dashpot restitution of the coupler's DEM-FEM contact; its run replays against its
own recording to the bit (the conformance check of docs/adding-a-solver.md); and replayed against a
recording of the C++ dem_solver it reproduces every field to the bit, energies included (one sphere,
frictionless: the two solvers compute the same sums in the same order)."""
import math
import os

from e2e_support import ROOT, RealRunTestCase, load_scene, read_json
from test_physics_runs import particle_states

SPHERE_DROP = "configs/tests/sphere_drop.toml"
RECORDING_LINE = 'fields = ["position", "velocity", "force"]'
# Reduced to the first bounce: thrown down at 7 m/s from 0.8 m (centre height), it strikes at 7.4 m/s, about
# the 7.0 m/s of the drop from 3 m, at t = 0.04 s; 0.1 s are 3300 steps instead of 83 000. The rest height of
# the whole drop is e2e_physics's, with the C++ dem_solver.
REDUCED = [("center = [0.0, 0.0, 3.0], radius = 0.5",
            "center = [0.0, 0.0, 0.8], radius = 0.5, velocity = [0.0, 0.0, -7.0]"),
           ("end_time = 2.5", "end_time = 0.1")]


class PythonSolverTest(RealRunTestCase):
    def solver_command(self):
        return ["/usr/bin/python3", os.path.join(ROOT, "examples", "python_dem", "solver.py")]

    def scene_copy(self, name, python):
        """The sphere drop, recorded in full (replay needs every field), with the Python solver or the
        built dem_solver in the dem role."""
        with open(self.scene_path(SPHERE_DROP), encoding="utf-8") as handle:
            text = handle.read()
        self.assertIn(RECORDING_LINE, text)
        text = text.replace(RECORDING_LINE, "")
        for old, new in REDUCED:
            self.assertIn(old, text)
            text = text.replace(old, new)
        if python:
            text += "\n[solvers.dem]\ncommand = [{}]\n".format(", ".join('"{}"'.format(a) for a in self.solver_command()))
        path = os.path.join(self.tmp, name + ".toml")
        with open(path, "w", encoding="utf-8") as handle:
            handle.write(text)
        return path

    def replay(self, run_dir, extra=()):
        env = {"SABO_BUILD_DIR": os.environ.get("SABO_BUILD_DIR", ""), "SABO_PLAN_OVERRIDE": ""}
        sabo = self.sabo(["replay", run_dir, "dem", "--no-setup"] + list(extra), env=env)
        code = sabo.wait(300)
        return code, sabo.stdout, sabo.stderr

    def test_bounces_and_replays_like_the_dem_solver(self):
        scene_file = self.scene_copy("python_drop", python=True)
        out = os.path.join(self.tmp, "python_drop")
        sabo = self.run_sabo(scene_file, out)
        self.assertEqual(sabo.wait(400), 0, sabo.output())
        summary = read_json(os.path.join(out, "summary.json"))
        with open(os.path.join(out, "dem_solver.log"), encoding="utf-8") as log:
            self.assertIn("python_dem", log.read())
        print("python dem_solver: {} steps, {:.1f} s wall".format(summary["steps"], summary["wall_seconds"]))

        scene = load_scene(scene_file)
        zeta = scene["contact"]["dem_fem"]["normal_damping_ratio"]
        radius = scene["particles"][0]["spheres"][0]["radius"]
        s = particle_states(out)
        vz = s["velocity"][:, 2]
        in_contact = abs(s["force"][:, 2]) > 0
        self.assertTrue(in_contact.any(), "the sphere never touched the plane")
        first = int(in_contact.argmax())
        after = first + int((~in_contact[first:]).argmax())
        e_measured = -vz[after] / vz[first]
        e_expected = math.exp(-math.pi * zeta / math.sqrt(1 - zeta * zeta))
        print("restitution of the first bounce: measured {:.4f}, expected {:.4f} (zeta = {}), error {:+.2%} "
              "(tolerance 2 %, as for the dem_solver)".format(e_measured, e_expected, zeta,
                                                              e_measured / e_expected - 1))
        self.assertLess(abs(e_measured / e_expected - 1), 0.02)
        self.assertGreater(s["position"][-1, 2], radius, "the sphere did not bounce off the plane")
        self.assertTrue(os.path.isfile(os.path.join(out, "dem.pvd")))

        code, stdout, stderr = self.replay(out)
        print("replay of its own recording: exit {}; {}".format(code, stdout.splitlines()[0] if stdout else stderr))
        self.assertEqual(code, 0, stdout + stderr)
        self.assertIn("every field matches", stdout)

        reference = os.path.join(self.tmp, "cpp_drop")
        sabo = self.run_sabo(self.scene_copy("cpp_drop", python=False), reference)
        self.assertEqual(sabo.wait(300), 0, sabo.output())
        code, stdout, stderr = self.replay(reference, ["--command", " ".join(self.solver_command())])
        print("the C++ dem_solver's recording replayed against the Python solver: exit {}; {}".format(
            code, stdout.splitlines()[0] if stdout else stderr))
        self.assertEqual(code, 0, stdout + stderr)
        # It registers takes_state = false: --take is refused with the reason and where to read the fix.
        code, stdout, stderr = self.replay(reference, ["--command", " ".join(self.solver_command()), "--take",
                                                       "position"])
        self.assertEqual(code, 2, stdout + stderr)
        self.assertIn("--take: the dem_solver cannot take recorded fields (its registration says takes_state = "
                      "false; docs/adding-a-solver.md", stderr)
        self.assertNoProcessLeft(out, pids_file=False)

    def test_a_scene_it_cannot_run_is_refused_with_the_fix(self):
        """A random `fill` set: the Python solver exits 2 before registering, and the run's final line names
        it, with the solver's own message (key and fix) in the log tail."""
        with open(self.scene_path(SPHERE_DROP), encoding="utf-8") as handle:
            text = handle.read()
        sphere = "spheres = [ { center = [0.0, 0.0, 3.0], radius = 0.5 } ]"
        self.assertIn(sphere, text)
        text = text.replace(sphere, "fill = { min = [-2.0, -2.0, 2.0], max = [2.0, 2.0, 4.0], count = 5, "
                                    "diameter = [0.2, 0.4] }")
        text += "\n[solvers.dem]\ncommand = [{}]\n".format(", ".join('"{}"'.format(a) for a in self.solver_command()))
        scene_file = os.path.join(self.tmp, "fill.toml")
        with open(scene_file, "w", encoding="utf-8") as handle:
            handle.write(text)
        out = os.path.join(self.tmp, "fill")
        sabo = self.run_sabo(scene_file, out)
        code = sabo.wait(120)
        print(sabo.output()[-600:])
        self.assertEqual(code, 1, sabo.output())
        self.assertIn("dem_solver", sabo.output())
        self.assertIn("exited with code 2", sabo.output())
        self.assertIn("this solver places only explicit `spheres` lists (no `fill`). Fix: list the spheres",
                      sabo.output())
        self.assertNoProcessLeft(out)
