"""C1, a 2 m water column on a clamped elastic aluminium plate (Fourey et al. 2017), through the real processes
(`./sabo run`: coupler, sph_solver, fem_solver), reduced: dx = 0.1 m, one-point shells of 0.1 m, the water's
settle_time 0.02 s, 0.06 s in all (4 500 steps of the shells' 1.33e-5 s), the plate's frames every 0.2 ms
(bench/plate_under_water.py's full case: 0.45 s, the mean of frames every 2.5 ms over 0.2-0.45 s). The plate's
surface is sampled as boundary particles. The plate, loaded at once, rings about its static deflection at about
230 Hz (4.3 ms) with an amplitude close to the deflection itself: the deflection is the mean of the midspan's
history over the whole periods of that ringing after the settling (from its first deepest swing to its last,
8 periods), against Euler-Bernoulli's -6.86e-5 m in plane strain (tolerance 3 %); the fluid's load on the plate
over the same periods against the water's weight (2 %); and no water below the plate's upper face: the walls
standing on the plate close the corners (before 6 December 2026 the shell's layers began behind its back face,
the corners under the walls were open, the water left through them and the plate bent 28 % short).
Frames every 2.5 ms, as the benchmark writes them, sample that ringing at 0.6 a period: their mean over a short
window wanders by several % with the window (the test's earlier form, 0.15 s with the mean over 0.05-0.15 s,
read +0.8 %; over 0.05-0.10 s it would have read +2.1 %). Measured: -0.9 % over 8 periods (0.024-0.059 s), the
load +0.05 %, the lowest water particle 0.0497 m. Shorter runs leave less margin: to 0.05 s (5 periods) -1.8 %,
to 0.045 s with a settle_time of 0.01 s -1.4 % with the load -0.7 % (the column's own start, 4 H / c = 0.18 s,
not yet averaged out)."""
import csv
import os
import sys
import unittest

from e2e_support import ROOT, RealRunTestCase, read_vtk, vtp_series

sys.path.insert(0, os.path.join(ROOT, "bench"))
from plate_under_water import (DEPTH, GRAVITY, OUTPUT_INTERVAL, REFERENCE, SPAN, TOLERANCE,  # noqa: E402
                               WATER_DENSITY, Plate, mean_between, midspan_history, whole_periods)

FRAME_INTERVAL = 0.0002  # s: the plate's frames, about 22 a period of its ringing


def plate_load(run_dir, first, last):
    """N: the mean vertical force of the fluid on the plate over (first, last] (forces.csv: each row the mean over
    the output interval that ends at its time)."""
    with open(os.path.join(run_dir, "forces.csv"), newline="") as handle:
        rows = [float(row["Fz"]) for row in csv.DictReader(handle)
                if row["part"] == "plate" and row["source"] == "fluid" and first < float(row["time"]) <= last + 1e-12]
    return sum(rows) / len(rows)


class PlateUnderWaterTest(RealRunTestCase):
    def test_a_water_column_bends_a_clamped_plate_as_beam_theory_says(self):
        plate = Plate(spacing=0.1, element_size=0.1, formulation="one_point", end_time=0.06, measure_from=0.02,
                      settle_time=0.02)
        text = plate.scene_text()
        frames = "output_interval = {!r}".format(OUTPUT_INTERVAL)
        self.assertIn(frames, text)
        out = self.run_scene_text(text.replace(frames, "output_interval = {!r}".format(FRAME_INTERVAL)), "plate",
                                  240)

        history = midspan_history(out)
        first, last, periods = whole_periods(history, plate.measure_from)
        self.assertGreaterEqual(periods, 6)
        deflection = mean_between(history, first, last)
        off = deflection / REFERENCE - 1
        print("C1, dx = 0.1 m, one-point shells: midspan deflection {:.4e} m (the mean over {} periods of the "
              "plate's ringing, {:.4f}-{:.4f} s), expected {:.3e} m ({:+.1%}; tolerance {:.0%})".format(
                  deflection, periods, first, last, REFERENCE, off, TOLERANCE))
        self.assertLess(abs(off), TOLERANCE)

        weight = WATER_DENSITY * GRAVITY * DEPTH * SPAN * plate.width
        load = -plate_load(out, first, last)
        print("C1: the fluid's load on the plate over the same periods {:.1f} N, the water's weight {:.1f} N "
              "({:+.2%}; tolerance 2 %)".format(load, weight, load / weight - 1))
        self.assertLess(abs(load / weight - 1), 0.02)

        lowest = min(float(read_vtk(path)["Points"][:, 2].min()) for _, path in vtp_series(out, "sph"))
        print("C1: the lowest water particle over the run at z = {:.4f} m (the plate's upper face at 0, the first "
              "layer dx / 2 above it)".format(lowest))
        self.assertGreater(lowest, 0.0)
        self.assertNoProcessLeft(out)


if __name__ == "__main__":
    unittest.main()
