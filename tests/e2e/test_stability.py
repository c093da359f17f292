"""Issue 24, instability detection: every solver checks its state after each step (libsabo/solver/stability.hpp).
The first bad step stops the run with the process, the step, the entities and their values, and
RUN_DIR/instability.vtp holds those entities and their neighbours.

  * A sphere in free fall with max_speed = 1 m/s: found at the step its speed passes 1 m/s, computed from the
    leapfrog (v_{n+1/2} = g dt (n + 1/2)), not a step later.
  * The boulder chute with the dem_solver's beta = 8 (steps eight times its stable step): it blows up, and the
    last state the dem_solver sent (traffic.h5) is the step before, every sphere finite and below the bound.
  * A tank with density_ratio_limits tighter than its hydrostatic compression: the sph_solver stops at once,
    naming the particles and their densities."""
import math
import os
import re

import h5py
import numpy

from e2e_support import RealRunTestCase, read_events, read_json

SPHERE_DROP = "configs/tests/sphere_drop.toml"
CHUTE_SMALL = "configs/tests/chute_small.toml"
TANK = "configs/tests/sph_tank_gauges.toml"


def vtp_points(path):
    with open(path, "rb") as handle:
        text = handle.read(4096).decode("latin-1")
    return int(re.search(r'NumberOfPoints="(\d+)"', text).group(1)), text


class InstabilityTest(RealRunTestCase):
    def failed_run(self, scene, name):
        out = os.path.join(self.tmp, name)
        sabo = self.run_sabo(scene, out)
        code = sabo.wait(300)
        self.assertEqual(code, 1, sabo.output())
        errors = [e for e in read_events(out) if e.get("event") == "error"]
        self.assertTrue(errors, sabo.output())
        self.assertEqual(read_json(os.path.join(out, "summary.json"))["status"], "failed")
        self.assertNoProcessLeft(out)
        return out, errors[0], sabo

    def test_a_speed_bound_is_caught_at_the_step_it_is_passed(self):
        scene = self.scene_variant(SPHERE_DROP, "drop", [("max_dt = 3e-5\n", "max_dt = 3e-5\nmax_speed = 1.0\n")])
        out, error, _ = self.failed_run(scene, "drop")
        message = error["message"]
        print(message)
        step = int(re.search(r"unstable after step (\d+)", message).group(1))
        speed = float(re.search(r"speed ([0-9.e+-]+) m/s", message).group(1))
        g, dt = 9.81, 3e-5
        expected = math.ceil(1.0 / (g * dt) - 0.5)  # the first n with g dt (n + 1/2) > 1
        print("found after step {} at {:.6g} m/s; expected step {} (v = g dt (n + 1/2) = {:.6g} m/s)".format(
            step, speed, expected, g * dt * (expected + 0.5)))
        self.assertEqual(error["process"], "dem_solver")
        self.assertEqual(step, expected)
        self.assertGreater(speed, 1.0)
        self.assertLess(speed, 1.0 + g * dt)
        points, text = vtp_points(os.path.join(out, "instability.vtp"))
        self.assertEqual(points, 1)  # the sphere; nothing else within reach
        for name in ("culprit", "velocity", "radius"):
            self.assertIn('Name="{}"'.format(name), text)
        self.assertIn(os.path.join(out, "instability.vtp"), message)

    def test_steps_eight_times_the_stable_step_are_stopped_before_a_bad_state_is_sent(self):
        scene = self.scene_variant(CHUTE_SMALL, "chute", [("beta = 0.8\n", "beta = 8.0\n")])
        out, error, sabo = self.failed_run(scene, "chute")
        message = error["message"]
        print(message)
        self.assertIn("beta = 8 takes steps 8 times the dem_solver's stable step", sabo.stderr)
        self.assertEqual(error["process"], "dem_solver")
        step = int(re.search(r"unstable after step (\d+)", message).group(1))
        with h5py.File(os.path.join(out, "traffic.h5"), "r") as traffic:
            steps = traffic["dem_solver/state/step"][()]
            velocity = traffic["dem_solver/state/velocity"][()]
            position = traffic["dem_solver/state/position"][()]
            counts = traffic["dem_solver/state/velocity_count"][()]
        # The spheres the dem_solver sent (those near a structure: the interest regions) in its last state.
        last = velocity[len(velocity) - int(counts[-1]):].reshape(-1, 3)
        speeds = numpy.linalg.norm(last, axis=1) if len(last) else numpy.zeros(1)
        print("the last state the dem_solver sent: step {} (the instability after step {}), {} spheres in it, the "
              "fastest {:.4g} m/s (bound 1000 m/s)".format(steps[-1], step, len(last), speeds.max()))
        self.assertEqual(int(steps[-1]), step)
        self.assertTrue(numpy.all(numpy.isfinite(velocity)) and numpy.all(numpy.isfinite(position)))
        self.assertLessEqual(speeds.max(), 1000.0)
        points, text = vtp_points(os.path.join(out, "instability.vtp"))
        self.assertGreaterEqual(points, 1)
        self.assertIn('Name="culprit"', text)

    def test_a_density_out_of_its_limits_stops_the_sph_solver(self):
        scene = self.scene_variant(TANK, "tank", [("[sph]\n", "[sph]\ndensity_ratio_limits = [0.999, 1.001]\n")])
        out, error, _ = self.failed_run(scene, "tank")
        message = error["message"]
        print(message[:400])
        self.assertEqual(error["process"], "sph_solver")
        self.assertIn("with a density outside sph.density_ratio_limits = [0.999, 1.001] of the rest density", message)
        self.assertIn("times its rest density", message)
        points, text = vtp_points(os.path.join(out, "instability.vtp"))
        self.assertGreater(points, 10)  # the culprits and the particles within a kernel support of them
        for name in ("density", "pressure", "culprit"):
            self.assertIn('Name="{}"'.format(name), text)
