"""The sph_solver on several processes (docs/architecture.md, "The slurry on several processes"):
the same scene run with the sph_solver alone and through the launcher `mpirun -n 2` (rank 0 the
coupler's correspondent, rank 1 following it) gives the same forces on every structure, step by step,
and the same particles in every output, to the bit: a dam break against penalty walls and a collapsing
column in a tank of boundary particles. A checkpoint moves between rank counts: the sph_solver of a 2-rank run
replayed alone from its checkpoint, and that of a run alone replayed on 2 ranks, reproduce the recorded states.
A flood enters through an inflow, and a dam break runs in a channel periodic across its width, on ranks as
alone. Replay's --take feeds recorded fields to the ranks as to one process. Gauges and fronts read the same on
ranks. Boulders of boundary particles lagged one step (sph.lagged_boundary_particles) give the same bits on ranks."""
import filecmp
import glob
import json
import os
import re
import unittest

from e2e_support import BUILD_DIR, RealRunTestCase, read_json

# mpirun as root (CI's containers) needs these; --oversubscribe: more ranks than cores;
# mpi_yield_when_idle: a rank waiting in a collective gives its core away (this machine runs other tests beside).
MPI_ENV = {"OMPI_ALLOW_RUN_AS_ROOT": "1", "OMPI_ALLOW_RUN_AS_ROOT_CONFIRM": "1", "OMP_NUM_THREADS": "1",
           "OMPI_MCA_rmaps_base_oversubscribe": "1", "OMPI_MCA_mpi_yield_when_idle": "1"}
LAUNCHER = '\n[solvers.sph]\nlauncher = ["mpirun", "-n", "2", "--oversubscribe"]\n'
# A launcher needs a tcp endpoint (docs/cluster.md); both runs take the same one.
ENDPOINT = ("[run]\n", '[run]\nendpoint = "tcp://127.0.0.1:*"\n')


class SphRanksTestCase(RealRunTestCase):
    """Runs a scene alone and on 2 ranks; the tests are in the classes below (one ctest each)."""

    def write_scene(self, source, name, replacements, ranks):
        with open(self.scene_path(source), encoding="utf-8") as handle:
            text = handle.read()
        for old, new in [ENDPOINT] + list(replacements):
            self.assertIn(old, text)
            text = text.replace(old, new)
        if ranks:
            self.assertNotIn("[solvers.sph]", text)
            text += LAUNCHER
        scene = os.path.join(self.tmp, name + ".toml")
        with open(scene, "w", encoding="utf-8") as handle:
            handle.write(text)
        return scene

    def compare(self, source, name, replacements, extra=()):
        runs = {}
        for ranks in (False, True):
            label = name + ("_ranks" if ranks else "_alone")
            out = os.path.join(self.tmp, label)
            sabo = self.run_sabo(self.write_scene(source, label, replacements, ranks), out, env=MPI_ENV)
            self.assertEqual(sabo.wait(300), 0, sabo.output())
            runs[ranks] = out
        alone, shared = runs[False], runs[True]
        with open(os.path.join(shared, "sph_solver.log"), encoding="utf-8", errors="replace") as handle:
            self.assertIn("the SPH model runs on 2 ranks", handle.read())
        for output in ("forces.csv", "energy.csv") + tuple(extra):
            self.assertTrue(os.path.getsize(os.path.join(alone, output)) > 0, output)
            self.assertTrue(filecmp.cmp(os.path.join(alone, output), os.path.join(shared, output), shallow=False),
                            output + " differs between the sph_solver alone and on 2 ranks")
        frames = sorted(os.listdir(os.path.join(alone, "sph")))
        self.assertEqual(frames, sorted(os.listdir(os.path.join(shared, "sph"))))
        different = [f for f in frames if not filecmp.cmp(os.path.join(alone, "sph", f),
                                                          os.path.join(shared, "sph", f), shallow=False)]
        summary = read_json(os.path.join(shared, "summary.json"))
        print("{}: {} the same, {} of {} particle outputs the same bits on 2 ranks; Newton violations {}".format(
            name, ", ".join(("forces.csv", "energy.csv") + tuple(extra)), len(frames) - len(different), len(frames),
            summary["newton_third_law"]["violations"]))
        self.assertEqual(different, [])
        self.assertEqual(summary["newton_third_law"]["violations"], 0)


class SphRanksSameBitsTest(SphRanksTestCase):
    def test_dam_break_against_penalty_walls(self):
        self.compare("configs/tests/sph_dam_break_soft_wall.toml", "penalty",
                     [("end_time = 0.7\n", "end_time = 0.45\n"), ("output_interval = 0.01\n",
                                                                   "output_interval = 0.05\n")])

    def test_column_collapsing_among_boundary_particles(self):
        self.compare("configs/tests/sph_tank_boundary.toml", "boundary",
                     [("end_time = 0.6\n", "end_time = 0.3\n"),
                      ("max = [0.4, 0.4, 0.3]", "max = [0.2, 0.4, 0.3]")])

    def test_a_flood_entering_through_an_inflow(self):
        """configs/tests/inflow_channel.toml's hydrograph entering the sloping flume, its first 0.4 s, with side
        walls instead of the periodic width: the buffer's particles move with their owners."""
        self.compare("configs/tests/inflow_channel.toml", "inflow",
                     [("end_time = 1.15\noutput_interval = 0.025\n", "end_time = 0.4\noutput_interval = 0.05\n"),
                      ("periodic_y = [0.0, 0.07]\n", ""),
                      ("start_wall_height = 0.2\n", "start_wall_height = 0.2\nwall_height = 0.1\n")],
                     extra=("inflows.csv", "gauges.csv"))

    def test_a_dam_break_periodic_across_its_channel(self):
        """configs/tests/sph_dam_break_gauges.toml (periodic across the width, gauges on the far wall), its first
        0.25 s: the slabs cut along the channel and each rank makes its window's periodic images."""
        self.compare("configs/tests/sph_dam_break_gauges.toml", "periodic",
                     [("end_time = 0.5\n", "end_time = 0.25\n"), ("output_interval = 0.01\n",
                                                                   "output_interval = 0.05\n")],
                     extra=("gauges.csv",))


class SphRanksLaggedBoundaryParticlesTest(SphRanksTestCase):
    def test_boulders_in_a_tank_with_lagged_boundary_particles(self):
        """configs/tests/sph_boulders_tank.toml, its first 0.1 s, with sph.lagged_boundary_particles: the ranks
        compute each step with the wall particles of the step before moved ahead, as the process alone does."""
        self.compare("configs/tests/sph_boulders_tank.toml", "lagged",
                     [('wall_model = "boundary_particles"\n',
                       'wall_model = "boundary_particles"\nlagged_boundary_particles = true\n'),
                      ("end_time = 0.3\n", "end_time = 0.1\n")])


class SphRanksCheckpointsReplayAndGaugesTest(SphRanksTestCase):
    def test_checkpoints_move_between_rank_counts(self):
        """A run on 2 ranks writes the sph role's checkpoints; its sph_solver replayed alone from one of them
        reproduces the recorded states (2 ranks -> 1). A run alone; its sph_solver replayed on 2 ranks from one
        of its checkpoints (1 -> 2). Every recorded field to the bit, the energies among them."""
        replacements = [("end_time = 0.6\n", "end_time = 0.2\ncheckpoint_interval = 0.05\n"),
                        ("max = [0.4, 0.4, 0.3]", "max = [0.2, 0.4, 0.3]"), ('fields = ["energies"]', "fields = []")]
        solver = os.path.join(BUILD_DIR, "bin", "sph_solver")
        for ranks, program in ((True, None), (False, "mpirun -n 2 --oversubscribe " + solver)):
            label = "checkpoints_" + ("ranks" if ranks else "alone")
            out = os.path.join(self.tmp, label)
            sabo = self.run_sabo(self.write_scene("configs/tests/sph_tank_boundary.toml", label, replacements, ranks),
                                 out, env=MPI_ENV)
            self.assertEqual(sabo.wait(300), 0, sabo.output())
            checkpoints = sorted(glob.glob(os.path.join(out, "checkpoints", "sph_solver_*.h5")))
            self.assertTrue(checkpoints, "no checkpoint of the sph_solver")
            args = ["replay", out, "sph", "--no-setup", "--resume", checkpoints[0]]
            if program:
                args += ["--command", program]
            env = dict(MPI_ENV, SABO_BUILD_DIR=BUILD_DIR, SABO_PLAN_OVERRIDE="")
            replay = self.sabo(args, env=env)
            code = replay.wait(300)
            self.assertEqual(code, 0, replay.stdout + replay.stderr)
            steps = int(re.search(r"every field matches over (\d+) steps", replay.stdout).group(1))
            print("{}: the sph_solver {} from {} matches the recording over {} steps".format(
                label, "on 2 ranks" if program else "alone", os.path.basename(checkpoints[0]), steps))
            self.assertGreater(steps, 10)
            logs = glob.glob(os.path.join(out, "replay", "sph-*", "sph_solver.log"))
            self.assertEqual(len(logs), 1, logs)
            with open(logs[0], encoding="utf-8", errors="replace") as handle:
                on_ranks = "the SPH model runs on 2 ranks" in handle.read()
            self.assertEqual(on_ranks, bool(program), "the replayed sph_solver on 2 ranks exactly when asked")

    def test_replay_takes_recorded_fields_on_ranks(self):
        """`./sabo replay RUN sph --take position` with the sph_solver on 2 ranks: every rank takes the recorded
        positions into its arrays. A changed fluid (twice the artificial viscosity) fed the recorded positions
        diverges in the same fields, from the same steps, by the same largest differences as the sph_solver alone
        does: the two replays' reports are equal."""
        replacements = [("end_time = 0.6\n", "end_time = 0.15\n"), ("max = [0.4, 0.4, 0.3]", "max = [0.2, 0.4, 0.3]"),
                        ('fields = ["energies"]', "fields = []")]
        out = os.path.join(self.tmp, "take")
        sabo = self.run_sabo(self.write_scene("configs/tests/sph_tank_boundary.toml", "take", replacements, False),
                             out, env=MPI_ENV)
        self.assertEqual(sabo.wait(300), 0, sabo.output())
        solver = os.path.join(BUILD_DIR, "bin", "sph_solver")
        env = dict(MPI_ENV, SABO_BUILD_DIR=BUILD_DIR, SABO_PLAN_OVERRIDE="")
        reports = {}
        for program in (None, "mpirun -n 2 --oversubscribe " + solver):
            args = ["replay", out, "sph", "--no-setup", "--set", "sph.artificial_viscosity=0.1", "--take", "position"]
            if program:
                args += ["--command", program]
            replay = self.sabo(args, env=env)
            code = replay.wait(300)
            self.assertEqual(code, 1, replay.stdout + replay.stderr)  # the changed fluid diverges
            folder = sorted(f for f in os.listdir(os.path.join(out, "replay")) if f.startswith("sph-"))[-1]
            with open(os.path.join(out, "replay", folder, "replay.json"), encoding="utf-8") as handle:
                report = json.load(handle)
            with open(os.path.join(out, "replay", folder, "sph_solver.log"), encoding="utf-8",
                      errors="replace") as handle:
                self.assertEqual("the SPH model runs on 2 ranks" in handle.read(), bool(program))
            reports[bool(program)] = report
        alone, shared = reports[False]["fields"], reports[True]["fields"]
        print("replay sph --take position of a changed fluid: alone {}; on 2 ranks {}".format(
            {f: v["first_step"] for f, v in alone.items()}, {f: v["first_step"] for f, v in shared.items()}))
        self.assertEqual(reports[True]["taken"], ["position"])
        self.assertIsNone(shared["position"]["first_step"])
        self.assertIsNotNone(shared["velocity"]["first_step"])
        self.assertEqual(alone, shared)

    def test_gauges_and_fronts_read_the_same_on_ranks(self):
        """A gauge line and a front along the tank: rank 0 asks the rank whose slab holds each point."""
        instruments = (
            '\n[[fronts]]\nname = "front"\nkind = "axis"\nstart = [0.0, 0.2, 0.0]\ndirection = [1.0, 0.0, 0.0]\n'
            'interval = 0.02\nstations = [{ name = "middle", at = 0.3 }]\n'
            '\n[[gauges]]\nname = "depth"\nkind = "line"\nstart = [0.3, 0.2, 0.0]\nend = [0.3, 0.2, 0.3]\n'
            'points = 4\ninterval = 0.01\n\n[recording]\n')
        self.compare("configs/tests/sph_tank_boundary.toml", "instruments",
                     [("end_time = 0.6\n", "end_time = 0.3\n"), ("max = [0.4, 0.4, 0.3]", "max = [0.2, 0.4, 0.3]"),
                      ("\n[recording]\n", instruments)],
                     extra=("gauges.csv", "fronts.csv", "front_stations.csv"))


if __name__ == "__main__":
    unittest.main()
