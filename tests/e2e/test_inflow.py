"""An inflow hydrograph through the real processes (issue 23, [[inflows]]): water enters a sloping flume through a
section at the hydrograph's rate (configs/tests/inflow_channel.toml). The volume and mass released against the
integral of Q, the discharge through a section downstream while the flow there is steady against the plateau's
(continuity), the inflow's energy account in energy.csv, the buffer's states in the particle files, and a replay of
the sph_solver and the coupler against a recorded flood. Each check prints measured beside expected."""
import collections
import os

from e2e_support import RealRunTestCase, load_scene, read_csv, read_json, read_vtk, vtp_series

SCENE = "configs/tests/inflow_channel.toml"


def section_discharges(run_dir, gauge, width):
    """Per sample time of the line gauge `gauge`: the discharge through its vertical section, m^3/s: the width
    times the integral of velocity_x from the bed (its first point) up to the free surface (its depth), the
    trapezoid rule between the points below the surface and the last one's velocity from there to the surface
    (a sum that stops at the last whole point would move by up to a point's spacing as the depth crosses one)."""
    samples = collections.defaultdict(list)
    for row in read_csv(os.path.join(run_dir, "gauges.csv")):
        if row["gauge"] == gauge:
            samples[float(row["time"])].append(row)
    out = {}
    for time, rows in sorted(samples.items()):
        rows.sort(key=lambda row: int(row["point"]))
        depth = float(rows[0]["depth"])
        bottom = float(rows[0]["z"])
        wet = [(float(row["z"]) - bottom, float(row["velocity_x"])) for row in rows]
        wet = [(height, velocity) for height, velocity in wet if height < depth]
        total = sum(0.5 * (u0 + u1) * (z1 - z0) for (z0, u0), (z1, u1) in zip(wet, wet[1:]))
        if wet:
            total += wet[-1][1] * (depth - wet[-1][0])
        out[time] = width * total
    return out


class InflowTest(RealRunTestCase):
    def test_a_hydrograph_enters_at_its_rate_and_flows_on(self):
        out = os.path.join(self.tmp, "flume")
        sabo = self.run_sabo(self.scene_path(SCENE), out)
        self.assertEqual(sabo.wait(240), 0, sabo.output())
        scene = load_scene(self.scene_path(SCENE))
        inflow = scene["inflows"][0]
        hydrograph = inflow["hydrograph"]
        plateau = max(q for _, q in hydrograph)
        rest_density = scene["materials"]["water"]["density"]

        # The volume released against the integral of Q (the section's lattice cells).
        summary = read_json(os.path.join(out, "summary.json"))
        result = summary["results"]["sph_solver"]["inflows"][0]
        print("released {:.6g} m^3 against the hydrograph's {:.6g} m^3 to t = {:.4g} s ({:+.3%}; tolerance 1 %, "
              "half a layer is {:.3g} m^3); mass {:.6g} kg against rho0 V = {:.6g} kg".format(
                  result["released_volume"], result["hydrograph_volume"], result["time"], result["relative_error"],
                  0.5 * result["layer_volume"], result["released_mass"], rest_density * result["hydrograph_volume"]))
        self.assertEqual(result["name"], inflow["name"])
        self.assertLess(abs(result["relative_error"]), 0.01)
        self.assertLessEqual(abs(result["released_volume"] - result["hydrograph_volume"]),
                             0.5 * result["layer_volume"] + 1e-12)
        # Hydrostatic densities at the section: the mass a little above rho0 V.
        self.assertAlmostEqual(result["released_mass"] / (rest_density * result["hydrograph_volume"]), 1.0,
                               delta=0.01)
        self.assertTrue(result["buffer_ended"])
        effects = {e["effect"]: e for e in summary["active_effects"]}
        self.assertAlmostEqual(effects["sph_inflow_hydrograph"]["inflows"][inflow["name"]]["peak_discharge"], plateau)
        with open(os.path.join(out, "sph_solver.log")) as log:
            self.assertIn("inflow '{}': a section of 7 x 4 particles".format(inflow["name"]), log.read())

        # inflows.csv: at every output time the volume released within half a layer of the hydrograph's integral
        # so far; its last row what summary.json says.
        history = read_csv(os.path.join(out, "inflows.csv"))
        shortfall = max(abs(float(row["hydrograph_volume"]) - float(row["released_volume"])) for row in history)
        print("inflows.csv: {} rows, the released volume within {:.3g} m^3 of the hydrograph's integral at every "
              "output time (half a layer: {:.3g} m^3)".format(len(history), shortfall, 0.5 * result["layer_volume"]))
        self.assertGreater(len(history), 30)
        self.assertLessEqual(shortfall, 0.5 * result["layer_volume"] * 1.01)
        self.assertAlmostEqual(float(history[-1]["released_volume"]), result["released_volume"], delta=1e-9)

        # Continuity: where the flow is steady, what passes a section downstream is what the inflow brings.
        discharges = section_discharges(out, "section_0_3m", inflow["width"])
        steady = [q for t, q in discharges.items() if 0.7 <= t <= 0.95]
        mean = sum(steady) / len(steady)
        print("discharge 0.24 m downstream, t = 0.7 to 0.95 s ({} samples): mean {:.4g} m^3/s, {:.4g} to {:.4g}; "
              "the hydrograph's plateau {:.4g} m^3/s ({:+.2%}; tolerance 3 %, each sample 4 %)".format(
                  len(steady), mean, min(steady), max(steady), plateau, mean / plateau - 1))
        self.assertGreater(len(steady), 20)
        self.assertAlmostEqual(mean / plateau, 1.0, delta=0.03)
        self.assertAlmostEqual(min(steady) / plateau, 1.0, delta=0.04)
        self.assertAlmostEqual(max(steady) / plateau, 1.0, delta=0.04)

        # Energy: the inflow's account grows as the fluid enters, and the scene's own energy (the total less it)
        # never rises above its start: nothing but the inflow brings energy.
        energies = summary["energies"]
        rows = read_csv(os.path.join(out, "energy.csv"))
        inflow_energy = [float(row["inflow"]) for row in rows]
        print("inflow account {:.4g} J at the end; largest rise of total - inflow over its start {:.3g} J; "
              "dissipated {:.4g} J (the fluid that left the flume's end among it)".format(
                  inflow_energy[-1], energies["max_rise_over_initial"], energies["final"]["dissipated"]))
        self.assertGreater(inflow_energy[-1], 0.5 * float(rows[-1]["dissipated"]))
        self.assertLessEqual(energies["max_rise_over_initial"], 1e-6 * inflow_energy[-1])
        self.assertAlmostEqual(energies["final"]["inflow"], inflow_energy[-1], delta=1e-9 * inflow_energy[-1])

        # The particle files: buffer states while the hydrograph runs, none after it.
        frames = vtp_series(out, "sph")
        middle = read_vtk(frames[len(frames) // 2][1])["active"]
        last = read_vtk(frames[-1][1])["active"]
        print("mid-run frame: {} free, {} in the buffer, {} out; last frame: {} free, {} in the buffer".format(
            sum(1 for a in middle if a == 1), sum(1 for a in middle if a >= 2), sum(1 for a in middle if a == 0),
            sum(1 for a in last if a == 1), sum(1 for a in last if a >= 2)))
        self.assertGreater(sum(1 for a in middle if a >= 2), 0)
        self.assertEqual(sum(1 for a in last if a >= 2), 0)
        self.assertTrue(set(middle) <= {0, 1, 2, 3})


class InflowReplayTest(RealRunTestCase):
    def test_a_recorded_inflow_replays_to_the_bit(self):
        # A short flood (the hydrograph ends at 0.5 s, the buffer taken out within the 0.6 s), recorded whole:
        # the sph_solver replayed against it matches every field at every step (releases, entries and the
        # buffer's end are deterministic), and so does the coupler.
        scene = self.scene_variant(SCENE, "short_flood", replace=[
            ("end_time = 1.15", "end_time = 0.6"),
            ("hydrograph = [[0.0, 0.0], [0.2, 0.0028], [0.95, 0.0028], [1.05, 0.0]]",
             "hydrograph = [[0.0, 0.0], [0.2, 0.0028], [0.4, 0.0028], [0.5, 0.0]]"),
            ("[recording]\nenabled = false", "[recording]\nenabled = true")])
        out = os.path.join(self.tmp, "short_flood")
        sabo = self.run_sabo(scene, out)
        self.assertEqual(sabo.wait(120), 0, sabo.output())
        for role in ("sph", "coupler"):
            code, stdout, stderr = self.replay(out, role)
            print("replay {}: exit {}; {}".format(role, code, stdout.splitlines()[0] if stdout else stderr))
            self.assertEqual(code, 0, stdout + stderr)
            self.assertIn("every field matches", stdout)
