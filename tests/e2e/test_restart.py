"""Restart of one solver while the others wait (issue 19, part 3): in the boulder tank (water, two boulders as SPH
boundary particles, the tank's walls; 751 steps, a checkpoint every 0.03 s) each solver is killed with SIGKILL at
a seeded random step, three times per solver. The supervisor restarts it from its newest checkpoint, the coupler
feeds it the StepForces since then and checks its states against the ones it sent before; the run completes,
every output file (forces.csv, energy.csv, the .pvd series and each .vtp frame) is byte for byte that of an
uninterrupted run, and summary.json names the restart. A scene with restart = "off" stops instead."""
import os
import random

from e2e_support import TANK_PENALTY_WALLS, RealRunTestCase, read_json

TANK = "configs/tests/sph_boulders_tank.toml"
OUTPUTS = ["forces.csv", "energy.csv", "dem.pvd", "sph.pvd", "fem.pvd"]
ROLES = ("dem_solver", "sph_solver", "fem_solver")


class RestartTestCase(RealRunTestCase):
    def write_scene(self, name, extra_run_lines="", replace=(), append=""):
        # No traffic recording: the coupler's restart journal is what the catch-up uses.
        return self.scene_variant(TANK, name, [("end_time = 0.3", "end_time = 0.3\n" + extra_run_lines),
                                               ("[recording]", "[recording]\nenabled = false")] + list(replace),
                                  append)

    def assertSameOutputs(self, reference, run):
        self.assertSameRunOutputs(reference, run, OUTPUTS)

    def kill_three_times_and_compare(self, role, name="tank", replace=(), append="", trials=3):
        """Runs the tank (with write_scene's `replace` and `append`) uninterrupted, then kills `role` at three
        seeded random steps (the first `trials` of them), one run each: every run restarts it, completes and writes
        the uninterrupted run's outputs."""
        scene = self.write_scene(name, "checkpoint_interval = 0.03", replace, append)
        reference = os.path.join(self.tmp, "reference")
        sabo = self.run_sabo(scene, reference)
        self.assertEqual(sabo.wait(180), 0, sabo.output())
        steps = read_json(os.path.join(reference, "summary.json"))["steps"]
        # The kill follows the coupler's progress events, one every 0.5 s: on a quiet machine the last 150 steps
        # can pass between two of them, and a kill at the first event past at_step then lands after the run's
        # last step. 350 steps leave two or more events after any at_step. One seeded sequence for all the roles.
        randomness = random.Random(19)
        at_steps = {r: [randomness.randrange(100, steps - 350) for _ in range(3)] for r in ROLES}
        for trial, at_step in enumerate(at_steps[role][:trials]):
            out = os.path.join(self.tmp, "{}-{}".format(role, trial))
            code, sabo = self.run_and_kill(scene, out, role, at_step)
            summary = read_json(os.path.join(out, "summary.json"))
            restarts = summary["restarts"]
            print("{} killed at step {}: exit {}, {}".format(role, at_step, code, restarts))
            self.assertEqual(code, 0, sabo.output())
            self.assertEqual(summary["status"], "completed")
            self.assertEqual(len(restarts), 1)
            self.assertEqual(restarts[0]["process"], role)
            # From the newest checkpoint: at most one interval (0.03 s, under 100 steps) to catch up.
            self.assertEqual(restarts[0]["catch_up_steps"], restarts[0]["at_step"] - restarts[0]["from_step"])
            self.assertLess(restarts[0]["catch_up_steps"], 100)
            self.assertIn("restarting it from its checkpoint of step {}".format(restarts[0]["from_step"]),
                          sabo.output())
            self.assertSameOutputs(reference, out)
            self.assertNoProcessLeft(out)


# One class (one ctest) per solver killed, and one for the runs that must stop.
class RestartDemSolverTest(RestartTestCase):
    def test_the_dem_solver_killed_at_random_steps_is_restarted_and_the_run_is_unchanged(self):
        self.kill_three_times_and_compare("dem_solver")


class RestartSphSolverTest(RestartTestCase):
    def test_the_sph_solver_killed_at_random_steps_is_restarted_and_the_run_is_unchanged(self):
        self.kill_three_times_and_compare("sph_solver")


class RestartSphSolverWallsBeforeTheFluidTest(RestartTestCase):
    def test_the_sph_solver_killed_after_its_walls_went_is_restarted_and_the_run_is_unchanged(self):
        """The tank's walls as penalty contacts: the boulders' wall particles are then the only ones, and the coupler
        sends them before the fluid's state is in (docs/protocol.md, "Walls ahead"), often to a sph_solver that is
        killed before it reads them. Its replacement gets them again with the step's forces, and the run is the
        uninterrupted one (before that was mended, every such restart failed for want of the walls)."""
        self.kill_three_times_and_compare("sph_solver", "tank_penalty_walls", trials=2, **TANK_PENALTY_WALLS)
        summary = read_json(os.path.join(self.tmp, "reference", "summary.json"))
        ahead = summary["processes"]["coupler"]["walls_before_the_fluid_state"]
        print("the walls went before the fluid's state at {} of {} exchanges".format(ahead, summary["steps"]))
        self.assertGreater(ahead, 0)


class RestartFemSolverTest(RestartTestCase):
    def test_the_fem_solver_killed_at_random_steps_is_restarted_and_the_run_is_unchanged(self):
        self.kill_three_times_and_compare("fem_solver")


class RestartRefusedTest(RestartTestCase):
    def test_past_its_journal_limit_a_killed_solver_stops_the_run_and_says_why(self):
        """A restart journal held to 1 byte (run.restart_journal_limit) is dropped at the first step after each
        checkpoint: the coupler says so once a drop, and a solver killed then cannot rejoin; the run stops naming
        the limit, and the journal's file is empty rather than growing."""
        scene = self.write_scene("tank_limit", "checkpoint_interval = 0.03\nrestart_journal_limit = 1e-9")
        out = os.path.join(self.tmp, "limit")
        code, sabo = self.run_and_kill(scene, out, "dem_solver", 200)
        with open(os.path.join(out, "coupler.log"), encoding="utf-8", errors="replace") as handle:
            log = handle.read()
        print(sabo.output()[-600:])
        self.assertNotEqual(code, 0)
        self.assertIn("passed run.restart_journal_limit = 1e-09 GB", log)
        self.assertIn("restart_journal_limit", sabo.output())
        self.assertNoProcessLeft(out)

    def test_with_restart_off_a_killed_solver_stops_the_run(self):
        scene = self.write_scene("tank_off", 'checkpoint_interval = 0.03\nrestart = "off"')
        out = os.path.join(self.tmp, "off")
        code, sabo = self.run_and_kill(scene, out, "dem_solver", 200)
        print(sabo.output()[-400:])
        self.assertNotEqual(code, 0)
        self.assertIn("dem_solver", sabo.output())
        self.assertNotIn("restarting it", sabo.output())
        self.assertNoProcessLeft(out)
