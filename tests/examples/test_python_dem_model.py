"""examples/python_dem/dem_model.py on its own (no coupler): the reference solver's physics against the
closed forms of the linear spring-dashpot, and its scene errors."""
import math
import os
import sys
import unittest

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "examples", "python_dem"))
import dem_model  # noqa: E402

GRANITE = {"density": 3000.0, "youngs_modulus": 30e9, "poisson_ratio": 0.3}


def scene(spheres, zeta=0.3, gravity=(0.0, 0.0, 0.0), fixed_first=False, **contact):
    sets = [{"name": "a", "material": "granite", "spheres": spheres[:1], "fixed": fixed_first},
            {"name": "b", "material": "granite", "spheres": spheres[1:]}]
    return {"run": {"gravity": list(gravity)}, "materials": {"granite": GRANITE},
            "particles": [s for s in sets if s["spheres"]],
            "contact": {"dem_dem": dict(normal_damping_ratio=zeta, **contact)}}


def advance(model, steps, dt):
    dt_previous = 0.0
    for _ in range(steps):
        model.compute_internal_forces()
        model.integrate(dt_previous, dt)
        dt_previous = dt


class HeadOnCollisionTest(unittest.TestCase):
    """Two equal spheres meet head on at 2 m/s: the linear spring-dashpot's restitution
    exp(-pi zeta / sqrt(1 - zeta^2)) and contact time pi / sqrt(k / m_eff - (zeta w)^2), momentum kept, and
    kinetic + elastic + dissipated energy constant to first order in dt (the dashpot acts on v_{n-1/2})."""

    @staticmethod
    def collide(zeta, steps_per_stable_dt):
        model = dem_model.DemModel(scene([{"center": [-0.51, 0, 0], "radius": 0.5, "velocity": [1.0, 0, 0]},
                                          {"center": [0.51, 0, 0], "radius": 0.5, "velocity": [-1.0, 0, 0]}], zeta))
        dt = model.stable_dt() / steps_per_stable_dt
        initial = model.kinetic
        touched, contact_steps, energy_error = False, 0, 0.0
        for step in range(100 * steps_per_stable_dt):
            model.compute_internal_forces()
            model.integrate(0.0 if step == 0 else dt, dt)
            in_contact = model.elastic > 0
            touched |= in_contact
            contact_steps += in_contact
            energy_error = max(energy_error, abs(model.kinetic + model.elastic + model.dissipated - initial) / initial)
            if touched and not in_contact:
                break
        return model, contact_steps * dt, energy_error

    def test_restitution_contact_time_and_energy(self):
        zeta = 0.3
        e_expected = math.exp(-math.pi * zeta / math.sqrt(1 - zeta * zeta))
        errors = []
        for steps, tolerance in ((20, 0.02), (80, 0.01)):
            model, contact_time, energy_error = self.collide(zeta, steps)
            k = model.pair_stiffness(np.array([0]), np.array([1]))[0]
            omega = math.sqrt(k / (model.mass[0] / 2))
            t_expected = math.pi / (omega * math.sqrt(1 - zeta * zeta))
            e_measured = model.velocity[1, 0] / 1.0
            print("dt = stable dt / {}: restitution {:.5f}, expected {:.5f} ({:+.2%}); contact time {:.4e} s, "
                  "expected {:.4e} s; largest energy-balance error {:.2e} of the initial".format(
                      steps, e_measured, e_expected, e_measured / e_expected - 1, contact_time, t_expected,
                      energy_error))
            self.assertAlmostEqual(e_measured / e_expected, 1.0, delta=tolerance)
            self.assertAlmostEqual(contact_time / t_expected, 1.0, delta=0.01)
            self.assertLess(abs(model.velocity[:, 0].sum()), 1e-12)  # equal masses: momentum stays zero
            errors.append(energy_error)
        order = math.log(errors[0] / errors[1]) / math.log(4)
        print("order of the energy-balance error: {:.3f}, expected 1 (+-0.2)".format(order))
        self.assertAlmostEqual(order, 1.0, delta=0.2)

    def test_stable_step_is_a_fifth_of_the_spring_period(self):
        model = dem_model.DemModel(scene([{"center": [0, 0, 0], "radius": 0.5}]))
        bulk = 30e9 / (3 * (1 - 0.6))
        k = 0.01 * (bulk * 0.5) / 2
        expected = 0.2 * math.pi * math.sqrt(model.mass[0] / k)
        print("stable dt: {:.6e} s, expected {:.6e} s".format(model.stable_dt(), expected))
        self.assertAlmostEqual(model.stable_dt() / expected, 1.0, places=12)


class RestOnAFixedSphereTest(unittest.TestCase):
    """A sphere settles on a fixed one with the overlap m g / k (dashpot ratio 0.7)."""

    def test_rest_overlap(self):
        model = dem_model.DemModel(scene([{"center": [0, 0, 0], "radius": 0.5},
                                          {"center": [0, 0, 1.0], "radius": 0.5}], zeta=0.7,
                                         gravity=(0, 0, -9.81), fixed_first=True))
        advance(model, 4000, model.stable_dt())
        k = model.pair_stiffness(np.array([0]), np.array([1]))[0]
        overlap = 1.0 - (model.position[1, 2] - model.position[0, 2])
        expected = model.mass[1] * 9.81 / k
        print("rest overlap: measured {:.6e} m, expected m g / k = {:.6e} m".format(overlap, expected))
        self.assertAlmostEqual(overlap / expected, 1.0, delta=1e-6)
        self.assertEqual(model.position[0].tolist(), [0.0, 0.0, 0.0])


class SceneErrorTest(unittest.TestCase):
    def test_a_fill_set_is_refused_with_the_fix(self):
        bad = scene([{"center": [0, 0, 0], "radius": 0.5}])
        bad["particles"][0] = {"name": "heap", "material": "granite", "fill": {"count": 3}}
        with self.assertRaises(dem_model.SceneError) as caught:
            dem_model.DemModel(bad, "heap.toml")
        self.assertIn("heap.toml: [[particles]] 'heap'", str(caught.exception))
        self.assertIn("Fix: list the spheres", str(caught.exception))

    def test_overlapping_spheres_and_an_unknown_law_are_refused(self):
        with self.assertRaisesRegex(dem_model.SceneError, "overlaps sphere 1 .* by 0.1 m"):
            dem_model.DemModel(scene([{"center": [0, 0, 0], "radius": 0.5}, {"center": [0.9, 0, 0], "radius": 0.5}]))
        with self.assertRaisesRegex(dem_model.SceneError, "linear law only"):
            dem_model.DemModel(scene([{"center": [0, 0, 0], "radius": 0.5}], model="hertz_mindlin"))


if __name__ == "__main__":
    unittest.main()
