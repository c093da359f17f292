"""A channel drawn from a longitudinal profile and a front tracked along it (issue 23), through the real
processes: the S1 dam break in a flat flume of one `channel` structure (configs/tests/channel_dam_break.toml).
The front's history against Martin & Moyce, its passage at each station against the floor gauge there (an
independent reading of the same event), each station's depth against the particles of the last frame, and
summary.json's results against the CSV files. Each check prints measured beside expected."""
import math
import os

from e2e_support import (S1_T, S1_Z, RealRunTestCase, interpolate, load_scene, read_csv, read_json, read_vtk,
                         vtp_series)

SCENE = "configs/tests/channel_dam_break.toml"


class ChannelFrontTest(RealRunTestCase):
    def test_the_front_along_a_channel_meets_martin_moyce_and_the_gauges(self):
        out = os.path.join(self.tmp, "flume")
        sabo = self.run_sabo(self.scene_path(SCENE), out)
        self.assertEqual(sabo.wait(240), 0, sabo.output())
        scene = load_scene(self.scene_path(SCENE))
        a = scene["fluids"][0]["max"][0]
        dx = scene["sph"]["particle_spacing"]
        g = 9.81
        time_unit = math.sqrt(a / (2 * g))  # t = T time_unit
        front = scene["fronts"][0]
        rows = [row for row in read_csv(os.path.join(out, "fronts.csv")) if row["front"] == front["name"]]
        times = [float(row["time"]) for row in rows]
        positions = [float(row["position"]) for row in rows]

        # Martin & Moyce: Z = s / a (the column stands against the flume's back wall, s = 0) at T.
        curve_t = [t / time_unit for t in times]
        curve_z = [s / a for s in positions]
        reference = [(t, z) for t, z in zip(S1_T, S1_Z) if t >= 0.84]

        def rms(shift):
            return math.sqrt(sum(((interpolate(t - shift, curve_t, curve_z) - z) / z) ** 2 for t, z in reference)
                             / len(reference))
        shift = min((k / 100.0 for k in range(-30, 31)), key=rms)
        for t, z in reference:
            print("T = {:.2f}: front at Z = {:.3f} (at T - shift {:.3f}), Martin & Moyce Z = {:.2f}".format(
                t, interpolate(t - shift, curve_t, curve_z), interpolate(t, curve_t, curve_z), z))
        print("front history: RMS relative error in Z {:.2%} with a shift of {:+.2f} T ({:.2%} without); tolerance "
              "8 %, shift at most 0.3 T (as the gauges' S1 check)".format(rms(shift), shift, rms(0.0)))
        self.assertLess(rms(shift), 0.08)
        self.assertTrue(all(b >= a_ - dx for a_, b in zip(positions, positions[1:]) if b < 0.55),
                        "the front went back by more than a spacing before the far wall")

        # summary.json carries what the CSV files hold.
        summary = read_json(os.path.join(out, "summary.json"))
        result = summary["results"]["sph_solver"]["fronts"][front["name"]]
        self.assertEqual(result["samples"], len(rows))
        # The CSV holds 9 significant digits.
        for full, written in zip(result["history"]["position"], positions):
            self.assertAlmostEqual(full, written, delta=1e-8 * abs(written))
        self.assertAlmostEqual(result["final_position"], positions[-1], delta=1e-8)
        self.assertEqual(result["path"], "channel flume")
        depth_rows = read_csv(os.path.join(out, "front_stations.csv"))

        # Each station's passage against the gauge on the floor at the same x: the gauge is wet once the kernel
        # sum of the particles around it reaches 0.1, which the nose of the surge (a wedge of particles) brings
        # up to about one smoothing length h ahead of its leading particle: the gauge may see the front up to
        # h / v earlier, and each reading is late by up to one sample interval.
        gauges = read_csv(os.path.join(out, "gauges.csv"))
        h = scene["sph"]["smoothing_ratio"] * dx
        for station in front["stations"]:
            gauge = "front_{:.0f}mm".format(station["at"] * 1000)
            wet = min(float(row["time"]) for row in gauges if row["gauge"] == gauge and float(row["kernel_sum"]) >= 0.1)
            arrival = result["stations"][station["name"]]["arrival_time"]
            speed = interpolate(arrival, times, [float(row["flow_speed"]) for row in rows])
            tolerance = h / speed + front["interval"]
            print("station {} at x = {} m: front passes at t = {:.4f} s, gauge {} wet at {:.4f} s: {:+.4f} s "
                  "(tolerance -{:.4f} .. +{:.4f} s)".format(station["name"], station["at"], arrival, gauge, wet,
                                                             wet - arrival, tolerance, front["interval"]))
            self.assertLessEqual(wet - arrival, front["interval"] + 1e-9)
            self.assertGreaterEqual(wet - arrival, -tolerance)
            self.assertAlmostEqual(arrival, interpolate(station["at"], positions, times), delta=front["interval"])

            # The final depth against the top of the particles within dx / 2 of the station in the last frame
            # (the free surface half a spacing above the top particles' centres).
            last_time, last_frame = vtp_series(out, "sph")[-1]
            points = read_vtk(last_frame)["Points"]
            column = points[abs(points[:, 0] - station["at"]) <= dx / 2]
            top = float(column[:, 2].max()) + dx / 2 if len(column) else 0.0
            final = [row for row in depth_rows if row["station"] == station["name"]][-1]
            self.assertAlmostEqual(float(final["time"]), last_time, delta=1e-9)
            depth = result["stations"][station["name"]]["final_depth"]
            print("station {}: depth at t = {:.3f} s measured {:.4f} m, top particle + dx/2 {:.4f} m (tolerance "
                  "dx = {} m)".format(station["name"], last_time, depth, top, dx))
            self.assertAlmostEqual(depth, float(final["depth"]), places=6)
            self.assertLessEqual(abs(depth - top), dx)

        # The flume holds every particle: boundary-particle walls let a particle into them by a fraction of a
        # spacing where the surge strikes (the floor and walls of configs/tests/sph_dam_break_gauges.toml, as
        # separate planes, do the same), never through them.
        last = read_vtk(vtp_series(out, "sph")[-1][1])
        points = last["Points"]
        print("last frame: {} particles, x in [{:.4f}, {:.4f}] m, z >= {:.4f} m (the flume: x in [0, 0.6] m, z >= "
              "0, each to a spacing {} m)".format(len(points), points[:, 0].min(), points[:, 0].max(),
                                                  points[:, 2].min(), dx))
        self.assertEqual(int(last["active"].min()), 1, "particles left the domain")
        self.assertGreaterEqual(points[:, 0].min(), -dx)
        self.assertLessEqual(points[:, 0].max(), 0.6 + dx)
        self.assertGreaterEqual(points[:, 2].min(), -dx)


class TerrainFrontTest(RealRunTestCase):
    """The same dam break with its floor read from an elevation raster (a flat ESRI ASCII grid) and its front
    tracked along the terrain's strip (configs/tests/terrain_dam_break.toml): the front and the stations'
    arrivals follow the channel's run within half a spacing and one sample."""

    def test_a_terrain_front_follows_the_channel_front(self):
        runs = {}
        for name, scene in (("channel", SCENE), ("terrain", "configs/tests/terrain_dam_break.toml")):
            out = os.path.join(self.tmp, name)
            sabo = self.run_sabo(self.scene_path(scene), out)
            self.assertEqual(sabo.wait(240), 0, sabo.output())
            runs[name] = (read_csv(os.path.join(out, "fronts.csv")),
                          read_json(os.path.join(out, "summary.json"))["results"]["sph_solver"]["fronts"]["surge"])
        scene = load_scene(self.scene_path(SCENE))
        dx = scene["sph"]["particle_spacing"]
        interval = scene["fronts"][0]["interval"]
        self.assertEqual(runs["terrain"][1]["path"], "terrain flume")
        channel_rows, terrain_rows = runs["channel"][0], runs["terrain"][0]
        self.assertEqual(len(channel_rows), len(terrain_rows))
        worst = max(abs(float(a["position"]) - float(b["position"])) for a, b in zip(channel_rows, terrain_rows))
        print("terrain front against the channel front: largest difference {:.2e} m over {} samples (tolerance "
              "dx / 2 = {} m)".format(worst, len(channel_rows), dx / 2))
        self.assertLess(worst, dx / 2)
        for station in scene["fronts"][0]["stations"]:
            channel = runs["channel"][1]["stations"][station["name"]]["arrival_time"]
            terrain = runs["terrain"][1]["stations"][station["name"]]["arrival_time"]
            print("station {}: arrival along the terrain {:.4f} s, along the channel {:.4f} s".format(
                station["name"], terrain, channel))
            self.assertAlmostEqual(terrain, channel, delta=interval)
