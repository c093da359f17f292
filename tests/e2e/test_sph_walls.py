"""SPH against FEM walls through the real processes (`./sabo run`: coupler, sph_solver, fem_solver):
a hydrostatic tank whose walls are penalty contact or boundary particles. At rest the floor carries
the weight of the water and each wall the hydrostatic thrust; Newton's third law holds every step.
Each check prints measured beside expected."""
import csv
import math
import os
import unittest

from e2e_support import (S1_T, S1_Z, RealRunTestCase, interpolate, load_scene, read_json, read_text, read_vtk,
                          vtp_series)

PENALTY = "configs/tests/sph_tank_penalty.toml"
BOUNDARY = "configs/tests/sph_tank_boundary.toml"
GAUGED = "configs/tests/sph_tank_gauges_small.toml"
WALLS = ["wall_x0", "wall_x1", "wall_y0", "wall_y1"]


def mean_forces(run_dir, after):
    """The mean force of the fluid on each part over the run after time `after` (the mean of the
    forces.csv rows, each the mean over one output interval), N."""
    sums, counts = {}, {}
    with open(os.path.join(run_dir, "forces.csv"), newline="") as handle:
        for row in csv.DictReader(handle):
            if row["source"] != "fluid" or float(row["time"]) <= after:
                continue
            force = [float(row["Fx"]), float(row["Fy"]), float(row["Fz"])]
            total = sums.setdefault(row["part"], [0.0, 0.0, 0.0])
            for c in range(3):
                total[c] += force[c]
            counts[row["part"]] = counts.get(row["part"], 0) + 1
    return {part: [value / counts[part] for value in total] for part, total in sums.items()}


class TankTest(RealRunTestCase):
    def check_tank(self, scene_file, name, floor_tolerance, wall_tolerance):
        out = os.path.join(self.tmp, name)
        sabo = self.run_sabo(self.scene_path(scene_file), out)
        self.assertEqual(sabo.wait(300), 0, sabo.output())
        scene = load_scene(self.scene_path(scene_file))
        fluid = scene["fluids"][0]
        size = [hi - lo for lo, hi in zip(fluid["min"], fluid["max"])]
        rho = scene["materials"]["water"]["density"]
        g = -scene["run"]["gravity"][2]
        weight = rho * g * size[0] * size[1] * size[2]
        thrust = 0.5 * rho * g * size[2] ** 2 * size[1]

        # The first output interval holds the start-up transient (the water settles onto its walls).
        forces = mean_forces(out, 1.5 * scene["run"]["output_interval"])
        floor_z = -forces["floor"][2]
        print("{}: floor force measured {:.1f} N, expected the weight {:.1f} N ({:+.2%})".format(
            name, floor_z, weight, floor_z / weight - 1))
        self.assertLess(abs(floor_z / weight - 1), floor_tolerance)
        total = [sum(forces[part][c] for part in forces) for c in range(3)]
        print("{}: total force on the tank ({:.2f}, {:.2f}, {:.2f}) N, expected (0, 0, {:.1f})".format(
            name, total[0], total[1], total[2], -weight))
        self.assertLess(abs(total[0]) + abs(total[1]), 0.01 * weight)
        self.assertLess(abs(-total[2] / weight - 1), 0.01)
        for wall in WALLS:
            magnitude = max(abs(forces[wall][0]), abs(forces[wall][1]))
            print("{}: {} thrust measured {:.1f} N, expected {:.1f} N ({:+.2%})".format(
                name, wall, magnitude, thrust, magnitude / thrust - 1))
            self.assertLess(abs(magnitude / thrust - 1), wall_tolerance)

        summary = read_json(os.path.join(out, "summary.json"))
        print("{}: Newton residual {:.2e}".format(name, summary["newton_third_law"]["max_relative_residual"]))
        self.assertEqual(summary["newton_third_law"]["violations"], 0)
        return summary

    def test_penalty_walls_carry_the_weight(self):
        # Measured (dx = 0.05 m, 0.1-0.6 s): floor +0.6 %, walls -3.1 to -3.5 %. The penalty wall truncates the
        # kernel next to it and the water rattles on its springs: the wall thrust gets a looser bound.
        self.check_tank(PENALTY, "penalty", 0.02, 0.08)

    def test_boundary_particle_walls_carry_the_weight_and_the_thrust(self):
        # Measured (dx = 0.05 m, 0.1-0.6 s): floor +0.5 %, walls +0.6 to +1.0 %, total vertical force +0.4 %.
        summary = self.check_tank(BOUNDARY, "boundary", 0.02, 0.04)
        # The default sph.wall_work = "bounded": the total energy never rises above its initial value, and
        # the SPH process's dissipated energy (its audit: the energy lost beyond the work done on it, the walls'
        # work held back among it) is >= 0 (measured 0.022 J of 71 J at the end).
        with open(os.path.join(self.tmp, "boundary", "energy.csv"), newline="") as handle:
            rows = list(csv.DictReader(handle))
        initial = float(rows[0]["total"])
        rise = max(float(row["total"]) for row in rows) - initial
        held = [float(row["dissipated"]) for row in rows]
        print("boundary: energy.csv over {} rows: largest total - initial {:.3g} J (expected <= 0), dissipated "
              "(the fluid's audit) {:.3g}..{:.3g} J (expected >= 0, and above 0 after the start-up)".format(
                  len(rows), rise, min(held), max(held)))
        self.assertLessEqual(rise, 0.0)
        self.assertGreaterEqual(min(held), 0.0)
        self.assertGreater(held[-1], 0.0)
        effects = [e for e in summary["active_effects"] if e["effect"] == "sph_fem_boundary_particles"]
        self.assertEqual(len(effects), 1)
        print("boundary particles sampled: {} in {} layers".format(effects[0]["boundary_particles"],
                                                                   effects[0]["layers"]))

    def test_gauges_and_sensors_read_the_hydrostatic_tank(self):
        """gauges.csv and sensors.csv of a tank at rest against rho g (H - z) and rho g H^2 w / 2, averaged
        over 0.1-0.2 s (the start-up transient before). The tank (sph_tank_gauges_small.toml) is
        sph_tank_gauges.toml's at a quarter of its footprint, run to 0.2 s instead of 0.3 s (a quarter of the
        particles, two thirds of the steps). Measured: gauges +0.30 / +0.12 / +0.08 % of rho g H (deep, middle,
        shallow), the wall's force +0.43 %, the transducer +0.25 % of rho g H; the full tank over 0.1-0.3 s:
        +0.29 / +0.11 / +0.07 %, +0.49 %, +0.23 %."""
        out = os.path.join(self.tmp, "gauged")
        sabo = self.run_sabo(self.scene_path(GAUGED), out)
        self.assertEqual(sabo.wait(300), 0, sabo.output())
        scene = load_scene(self.scene_path(GAUGED))
        fluid = scene["fluids"][0]
        depth, width = fluid["max"][2], fluid["max"][1] - fluid["min"][1]
        rho = scene["materials"]["water"]["density"]
        g = -scene["run"]["gravity"][2]
        dx = scene["sph"]["particle_spacing"]
        after = 0.1 - 1e-9
        with open(os.path.join(out, "gauges.csv"), newline="") as handle:
            gauges = [row for row in csv.DictReader(handle) if float(row["time"]) >= after]
        for name in ("deep", "middle", "shallow"):
            rows = [row for row in gauges if row["gauge"] == name]
            z = float(rows[0]["z"])
            measured = sum(float(row["pressure"]) for row in rows) / len(rows)
            expected = rho * g * (depth - z)
            print("gauge {} at z = {} m: pressure measured {:.1f} Pa, expected {:.1f} Pa ({:+.2%} of rho g H; "
                  "tolerance 2 %)".format(name, z, measured, expected, (measured - expected) / (rho * g * depth)))
            self.assertLess(abs(measured - expected), 0.02 * rho * g * depth)
        air = [float(row["pressure"]) for row in gauges if row["gauge"] == "air"]
        print("gauge air: largest |pressure| {} Pa over {} samples (expected 0)".format(max(map(abs, air)), len(air)))
        self.assertEqual(max(map(abs, air)), 0.0)
        column = [float(row["depth"]) for row in gauges if row["gauge"] == "column" and row["point"] == "0"]
        mean_depth = sum(column) / len(column)
        print("gauge column: depth measured {:.5f} m, expected {} m (tolerance dx/4 = {} m)".format(
            mean_depth, depth, dx / 4))
        self.assertLess(abs(mean_depth - depth), dx / 4)

        with open(os.path.join(out, "sensors.csv"), newline="") as handle:
            sensor_rows = list(csv.DictReader(handle))
        with open(os.path.join(out, "forces.csv"), newline="") as handle:
            force_rows = {(row["time"], row["part"], row["source"]): row for row in csv.DictReader(handle)}
        by_sensor = {}
        for row in sensor_rows:
            by_sensor.setdefault(row["sensor"], []).append(row)
        # A sensor of a whole part is that part's row of forces.csv, digit for digit.
        for row in by_sensor["wall_x0"]:
            part_row = force_rows[(row["time"], "wall_x0", row["source"])]
            self.assertEqual([row[k] for k in ("Fx", "Fy", "Fz", "F_peak")],
                             [part_row[k] for k in ("Fx", "Fy", "Fz", "F_peak")])
        # Two box sensors that split the wall sum to it (to the 9 digits written).
        worst = 0.0
        for whole, lower, upper in zip(by_sensor["wall_x0"], by_sensor["wall_x0_lower"], by_sensor["wall_x0_upper"]):
            for k in ("Fx", "Fy", "Fz"):
                gap = abs(float(lower[k]) + float(upper[k]) - float(whole[k]))
                worst = max(worst, gap)
                self.assertLessEqual(gap, 1e-8 * max(1.0, abs(float(whole[k]))))
        print("wall_x0: lower + upper box sensors - whole wall: largest difference {:.2e} N (expected 0 to "
              "rounding)".format(worst))
        thrust = 0.5 * rho * g * depth ** 2 * width
        rows = [row for row in by_sensor["wall_x0"] if float(row["time"]) >= after]
        wall = sum(float(row["F"]) for row in rows) / len(rows)
        print("sensor wall_x0: force measured {:.4f} N, expected rho g H^2 w / 2 = {:.4f} N ({:+.2%}; tolerance "
              "2 %)".format(wall, thrust, wall / thrust - 1))
        self.assertLess(abs(wall / thrust - 1), 0.02)
        rows = [row for row in by_sensor["transducer"] if float(row["time"]) >= after]
        pressure = sum(float(row["pressure"]) for row in rows) / len(rows)
        box = [sensor for sensor in scene["sensors"] if sensor["name"] == "transducer"][0]
        centre = 0.5 * (box["min"][2] + box["max"][2])
        self.assertAlmostEqual(centre, 0.02, places=12)
        expected = rho * g * (depth - centre)
        print("sensor transducer (10 mm, area {} m^2): mean pressure measured {:.1f} Pa, expected {:.1f} Pa "
              "({:+.2%} of rho g H; tolerance 2 %)".format(rows[0]["area"], pressure, expected,
                                                           (pressure - expected) / (rho * g * depth)))
        self.assertAlmostEqual(float(rows[0]["area"]), 1e-4, places=12)
        self.assertLess(abs(pressure - expected), 0.02 * rho * g * depth)

    def test_boundary_particle_walls_are_recorded(self):
        """traffic.h5 holds the walls sent to the sph_solver and its forces on them (docs/traffic.md): every
        step, 3 values per wall particle in each 3-vector field and 1 volume, and the forces of step n match
        the walls of the step they answer (boundary_step, n - 1 when absent)."""
        import h5py
        import numpy as np
        with open(self.scene_path(BOUNDARY), encoding="utf-8") as handle:
            text = handle.read()
        self.assertIn('fields = ["energies"]', text)
        self.assertIn("end_time = 0.6", text)
        text = text.replace('fields = ["energies"]', 'fields = ["boundary_particles", "boundary_force"]')
        text = text.replace("end_time = 0.6", "end_time = 0.03")
        scene = os.path.join(self.tmp, "tank_recorded.toml")
        with open(scene, "w", encoding="utf-8") as handle:
            handle.write(text)
        out = os.path.join(self.tmp, "recorded")
        sabo = self.run_sabo(scene, out)
        self.assertEqual(sabo.wait(120), 0, sabo.output())
        with h5py.File(os.path.join(out, "traffic.h5"), "r", swmr=True) as traffic:
            forces, state = traffic["sph_solver/forces"], traffic["sph_solver/state"]
            force_steps, state_steps = forces["step"][()], state["step"][()]
            self.assertGreater(len(state_steps), 2)
            self.assertTrue(np.array_equal(force_steps, np.arange(len(force_steps))))
            volumes = forces["boundary_volume_count"][:len(force_steps)]
            for name in ["boundary_position", "boundary_velocity", "boundary_normal", "boundary_acceleration"]:
                counts = forces[name + "_count"][:len(force_steps)]
                if name in ("boundary_velocity", "boundary_acceleration"):
                    # Empty where every wall particle sent is at rest (docs/protocol.md).
                    self.assertTrue(np.all((counts == 0) | (counts == 3 * volumes)), name)
                else:
                    self.assertTrue(np.array_equal(counts, 3 * volumes), name)
                self.assertEqual(forces[name].shape[0], counts.sum(), name)
            self.assertTrue((volumes > 0).all(), "walls sent every step")
            normals = forces["boundary_normal"][:].reshape(-1, 3)
            self.assertLess(np.abs(np.linalg.norm(normals, axis=1) - 1).max(), 1e-12)
            force_counts = state["boundary_force_count"][:len(state_steps)]
            step_counts = state["boundary_step_count"][:len(state_steps)]
            step_values = state["boundary_step"][()]
            step_offsets = state["boundary_step_offset"][:len(state_steps)]
            answered = 0
            for i, n in enumerate(int(value) for value in state_steps):
                if force_counts[i] == 0:
                    self.assertLess(n, 2, "forces missing at step {}".format(n))
                    continue
                k = int(step_values[step_offsets[i]]) if step_counts[i] == 1 else n - 1
                self.assertEqual(force_counts[i], 3 * volumes[k], "step {} answering step {}".format(n, k))
                answered += 1
            print("traffic.h5: {} steps, {} to {} wall particles sent per step, {} answers with consistent "
                  "sizes".format(len(force_steps), volumes.min(), volumes.max(), answered))
            self.assertGreater(answered, 0)
            fem = traffic["fem_solver/forces"]
            self.assertEqual(fem["boundary_volume_count"][:len(fem["step"][()])].sum(), 0)


class DamBreakGaugesTest(RealRunTestCase):
    SCENE = "configs/tests/sph_dam_break_gauges.toml"

    def test_gauges_time_the_front_and_read_the_far_wall(self):
        """S1 through the coupler read by gauges (issue 20): the front's arrival at floor gauges Z = 1.5 ... 4
        against Martin & Moyce (RMS relative error in Z at most 8 % with a fitted shift |s| <= 0.3 in T, the
        S1 criterion), then the surge on the far wall (Z = 6): its arrival, and the pressure at its foot read
        two independent ways, by the gauge in the fluid one spacing in front of it and by the pressure pad of
        the wall's force over its area, over the 0.1 s after the impact. The scene runs to 0.43 s instead of its
        0.5 s: the surge strikes the far wall at 0.318 s, and nothing after 0.418 s is read."""
        out = os.path.join(self.tmp, "dam_break")
        scene_file = self.scene_variant(self.SCENE, "dam_break", [("end_time = 0.5\n", "end_time = 0.43\n")])
        sabo = self.run_sabo(scene_file, out)
        self.assertEqual(sabo.wait(300), 0, sabo.output())
        scene = load_scene(scene_file)
        a = scene["fluids"][0]["max"][0]
        g = -scene["run"].get("gravity", [0.0, 0.0, -9.81])[2]
        time_unit = math.sqrt(a / (2 * g))  # t = T time_unit
        with open(os.path.join(out, "gauges.csv"), newline="") as handle:
            rows = list(csv.DictReader(handle))

        def arrival(name):
            # The first sample at which the gauge is wet (kernel sum >= 0.1: a particle within about 0.3 h).
            for row in rows:
                if row["gauge"] == name and float(row["kernel_sum"]) >= 0.1:
                    return float(row["time"]) / time_unit
            self.fail("gauge {} never wet".format(name))

        stations = [(gauge["position"][0] / a, arrival(gauge["name"])) for gauge in scene["gauges"]
                    if gauge["name"].startswith("front_")]
        self.assertEqual(len(stations), 6)

        def rms(shift):
            return math.sqrt(sum(((interpolate(t + shift, S1_T, S1_Z) - z) / z) ** 2 for z, t in stations)
                             / len(stations))
        shift = min((k / 100.0 for k in range(-30, 31)), key=rms)
        for z, t in stations:
            print("front at Z = {:.2f}: arrives at T = {:.3f}; Martin & Moyce at T = {:.3f} (at T + shift: Z = {:.3f})".format(
                z, t, interpolate(z, S1_Z, S1_T), interpolate(t + shift, S1_T, S1_Z)))
        print("front arrivals: RMS relative error in Z {:.2%} with the simulated front {:.2f} T ahead ({:.2%} without); "
              "tolerance 8 %, shift at most 0.3 T".format(rms(shift), shift, rms(0.0)))
        self.assertLess(rms(shift), 0.08)

        wall_arrival = arrival("wall_foot")
        speed = (6.0 - 4.0) / (wall_arrival - stations[-1][1])
        print("far wall (Z = 6): the front arrives at T = {:.3f} (t = {:.3f} s), after Z = 4 at T = {:.3f}: mean "
              "front speed {:.2f} a per T (Martin & Moyce over their last 0.5 T: {:.2f})".format(
                  wall_arrival, wall_arrival * time_unit, stations[-1][1], speed,
                  (S1_Z[-1] - S1_Z[-4]) / (S1_T[-1] - S1_T[-4])))
        self.assertGreater(wall_arrival, stations[-1][1])

        impact = wall_arrival * time_unit
        # The window read below must lie inside the run (the gauges sample every 2 ms).
        last = max(float(row["time"]) for row in rows)
        self.assertGreaterEqual(last, impact + 0.1 - 0.002, "the run ends {:.3f} s after the impact".format(
            last - impact))
        foot = [float(row["pressure"]) for row in rows
                if row["gauge"] == "wall_foot" and impact <= float(row["time"]) <= impact + 0.1]
        with open(os.path.join(out, "sensors.csv"), newline="") as handle:
            sensors = list(csv.DictReader(handle))
        pad = [row for row in sensors if row["sensor"] == "pad_0_20mm" and row["source"] == "fluid"
               and impact < float(row["time"]) <= impact + 0.1 + 1e-9]
        pad_mean = sum(float(row["pressure"]) for row in pad) / len(pad)
        foot_mean = sum(foot) / len(foot)
        peak = max(float(row["F_peak"]) / float(row["area"]) for row in pad)
        rho = scene["materials"]["water"]["density"]
        print("far wall foot over {:.3f}-{:.3f} s: gauge 1 dx in front {:.0f} Pa, pressure pad (0-20 mm) {:.0f} "
              "Pa ({:+.1%}); pad's peak {:.0f} Pa = {:.2f} rho g 2a; tolerance 15 %".format(
                  impact, impact + 0.1, foot_mean, pad_mean, pad_mean / foot_mean - 1, peak,
                  peak / (rho * g * 2 * a)))
        self.assertLess(abs(pad_mean / foot_mean - 1), 0.15)
        self.assertGreater(pad_mean, 0.0)


class PeriodicChannelTest(RealRunTestCase):
    def test_periodic_channel_ending_in_a_wall_runs(self):
        """Issue 17, item 2: the floor/end-wall corner of a channel periodic across its width used to put wall
        particles past the seams (the sph_solver stopped at step 0); the coupler now keeps them inside."""
        out = os.path.join(self.tmp, "periodic")
        sabo = self.run_sabo(self.scene_path("configs/tests/sph_periodic_channel.toml"), out)
        self.assertEqual(sabo.wait(120), 0, sabo.output())
        summary = read_json(os.path.join(out, "summary.json"))
        walls = [e for e in summary["active_effects"] if e["effect"] == "sph_fem_boundary_particles"][0]
        print("periodic channel: {} steps, {} wall particles sampled, at most {} sent".format(
            summary["steps"], walls["boundary_particles"], walls["max_sent_per_step"]))
        self.assertEqual(summary["status"], "completed")


SLIDING = "configs/tests/sph_sliding_layer.toml"
FAST_LAYER = "configs/tests/sph_fast_layer.toml"


class SlidingLayerTest(RealRunTestCase):
    """A viscous layer sliding at U over a floor of boundary particles (configs/tests/sph_sliding_layer.toml,
    periodic along x and y, 4 Pa s for 0.075 s): Stokes' first problem. A no-slip floor drags it into
    u(z, t) = U erf(z / (2 sqrt(nu t))); a free-slip one ([sph] free_slip_walls) leaves it at U, the artificial
    viscosity included (it acts on the approach normal to a free-slip wall only)."""

    def profile(self, name, free_slip):
        slip = 'periodic_y = [0.0, 0.04]\n'
        scene_file = self.scene_variant(SLIDING, name,
                                        [(slip, slip + 'free_slip_walls = ["floor"]\n')] if free_slip else [])
        out = os.path.join(self.tmp, name)
        sabo = self.run_sabo(scene_file, out)
        self.assertEqual(sabo.wait(300), 0, sabo.output())
        with open(os.path.join(out, "gauges.csv"), newline="") as handle:
            rows = [row for row in csv.DictReader(handle) if row["gauge"] == "profile"]
        last = max(float(row["time"]) for row in rows)
        return last, [(float(row["z"]), float(row["velocity_x"])) for row in rows if float(row["time"]) == last]

    def test_no_slip_floor_against_stokes_and_free_slip_floor_keeps_the_speed(self):
        scene = load_scene(self.scene_path(SLIDING))
        speed = scene["fluids"][0]["velocity"][0]
        nu = scene["materials"]["oil"]["viscosity"] / scene["materials"]["oil"]["density"]
        # Measured (dx = 5 mm, 4 Pa s, t = 0.075 s): within 0.40 % of U at every height (1.06 % with 1 Pa s at
        # 0.3 s, the same nu t, in four times the steps).
        t, no_slip = self.profile("no_slip", False)
        worst = 0.0
        for z, u in no_slip:
            expected = speed * math.erf(z / (2.0 * math.sqrt(nu * t)))
            worst = max(worst, abs(u - expected) / speed)
            print("no-slip floor, t = {:.3f} s, z = {:.4f} m: u measured {:.4f} m/s, Stokes {:.4f} m/s ({:+.2%} of "
                  "U)".format(t, z, u, expected, (u - expected) / speed))
        print("no-slip floor: largest difference {:.2%} of U, tolerance 2 %".format(worst))
        self.assertLess(worst, 0.02)
        # Measured: within 1.1e-4 of U (8.9e-5 with 1 Pa s at 0.3 s).
        t, free_slip = self.profile("free_slip", True)
        drift = max(abs(u - speed) for _, u in free_slip) / speed
        print("free-slip floor, t = {:.3f} s: u measured {:.5f}..{:.5f} m/s over z = {:.3f}..{:.3f} m, expected U = {} "
              "m/s everywhere; largest difference {:.2e} of U, tolerance 1e-3".format(
                  t, min(u for _, u in free_slip), max(u for _, u in free_slip), free_slip[0][0], free_slip[-1][0],
                  speed, drift))
        self.assertLess(drift, 1e-3)


class FastLayerTest(RealRunTestCase):
    """A water layer sliding at a tenth of the sound speed over a free-slip floor (configs/tests/sph_fast_layer.toml):
    a uniform flow, which must stay uniform. With the floor's particles at dx / 2 (the scene's
    sph.wall_spacing_ratio) the row beside the floor stays on it; at dx the floor's lattice pumps that row
    and it falls through (the defect the key mends; the second run shows the scene does test it: within the
    first run's time it breaks the first run's bounds). Reduced: half the scene's periodic length (0.04 m along
    x, 8 dx, as across it: 512 particles), frames every 0.025 s, the run at dx / 2 to 0.2 s and the run at dx to
    0.3 s instead of 0.4 s each; at dx the row is through the floor by 0.275 s in both sizes."""

    # The scene at half its length along x, a frame every 0.025 s.
    REDUCED = [("output_interval = 0.05\n", "output_interval = 0.025\n"),
               ("periodic_x = [0.0, 0.08]", "periodic_x = [0.0, 0.04]"),
               ("domain_max = [0.09, 0.05, 0.2]", "domain_max = [0.05, 0.05, 0.2]"),
               ("max = [0.08, 0.04, 0.04]", "max = [0.04, 0.04, 0.04]"),
               ("origin = [0.04, 0.02, 0.0]", "origin = [0.02, 0.02, 0.0]"),
               ("length = 0.08\n", "length = 0.04\n")]

    def lowest_and_fastest(self, name, ratio, end_time, replace=()):
        """Runs the reduced scene to `end_time` with the wall particles at `ratio` dx; the lowest particle (m) and
        the largest vertical speed (m/s) of each frame: [(time, lowest, fastest)]."""
        replace = self.REDUCED + [("end_time = 0.4\n", "end_time = {!r}\n".format(end_time))] + list(replace)
        if ratio != 0.5:
            replace.append(("wall_spacing_ratio = 0.5", "wall_spacing_ratio = {}".format(ratio)))
        out = os.path.join(self.tmp, name)
        sabo = self.run_sabo(self.scene_variant(FAST_LAYER, name, replace), out)
        self.assertEqual(sabo.wait(300), 0, sabo.output())
        frames = []
        for time, path in vtp_series(out, "sph"):
            frame = read_vtk(path)
            inside = frame["active"] == 1
            frames.append((time, float(frame["Points"][inside, 2].min()),
                           float(abs(frame["velocity"][inside, 2]).max())))
        self.assertGreaterEqual(frames[-1][0], end_time - 1e-9)
        return frames

    def test_a_fast_layer_stays_on_a_free_slip_floor_of_half_spaced_wall_particles(self):
        scene = load_scene(self.scene_path(FAST_LAYER))
        dx = scene["sph"]["particle_spacing"]
        speed = scene["fluids"][0]["velocity"][0]
        # Measured (to 0.2 s): lowest particle 0.00238 m (it starts at dx / 2 = 0.0025 m), |w| 1.4e-3 m/s at most
        # (the whole scene to 0.4 s, frames every 0.05 s: 0.00237 m, 5e-4 m/s).
        half_end = 0.2
        frames = self.lowest_and_fastest("half", 0.5, half_end)
        lowest, fastest = min(f[1] for f in frames), max(f[2] for f in frames)
        print("wall particles at dx / 2, to {} s: lowest particle {:.5f} m, expected above 0.3 dx = {:.5f} m; largest "
              "vertical speed {:.2e} m/s, expected below 1e-2 U = {:.3f} m/s".format(
                  half_end, lowest, 0.3 * dx, fastest, 0.01 * speed))
        self.assertGreater(lowest, 0.3 * dx)
        self.assertLess(fastest, 0.01 * speed)
        # The domain's floor 0.4 dx below the floor's face: what goes into the floor is taken out, and the
        # sph_solver's warning names the remedy. Measured (to 0.3 s): by 0.2 s lowest 0.0012 m, |w| 0.052 m/s;
        # by 0.3 s lowest -0.0019 m, |w| 0.15 m/s (6 U / 100), the first particle out at 0.27 s (the whole scene:
        # -0.0017 m and 0.13 m/s by 0.3 s).
        domain = ("domain_min = [-0.01, -0.01, -0.04]", "domain_min = [-0.01, -0.01, -0.002]")
        frames = self.lowest_and_fastest("whole", 1.0, 0.3, [domain])
        # (A frame is written at the first step at or after its time.)
        early = [f for f in frames if f[0] < half_end + 0.01]
        early_lowest, early_fastest = min(f[1] for f in early), max(f[2] for f in early)
        print("wall particles at dx, to {} s: lowest particle {:.5f} m, largest vertical speed {:.3f} m/s, expected "
              "above the bound at dx / 2 ({:.3f} m/s)".format(half_end, early_lowest, early_fastest, 0.01 * speed))
        self.assertGreater(early_fastest, 0.01 * speed)
        lowest, fastest = min(f[1] for f in frames), max(f[2] for f in frames)
        print("wall particles at dx, to {:.2f} s: lowest particle {:.5f} m, expected below the floor's face (0 m); "
              "largest vertical speed {:.3f} m/s, expected above 0.04 U = {:.3f} m/s".format(
                  frames[-1][0], lowest, fastest, 0.04 * speed))
        self.assertLess(lowest, 0.0)
        self.assertGreater(fastest, 0.04 * speed)
        log = read_text(os.path.join(self.tmp, "whole", "sph_solver.log"))
        self.assertIn("left the domain", log)
        self.assertIn("sph.wall_spacing_ratio = 0.5", log)


if __name__ == "__main__":
    unittest.main()
