"""`./sabo replay RUN_DIR ROLE` (issue 19, part 1): a recorded three-solver run (water, two boulders as SPH
boundary particles, the tank's walls) replayed against each of its processes matches to the bit; a solver with
one changed parameter reports where it diverges first; a recording that cannot drive a replay is refused with
exit status 2; the folder of a run killed with its supervisor is repaired first (issue 18)."""
import json
import os
import shutil

from e2e_support import TANK_PENALTY_WALLS, RealRunTestCase, read_json

TANK = "configs/tests/sph_boulders_tank.toml"


class ReplayTestCase(RealRunTestCase):
    """A recorded run and its replays; the tests are in the classes below (one ctest each)."""

    def recorded_run(self, name="recorded", fields_line=None, replace=(), append=""):
        """A short run of the boulder tank recorded in full (or with `fields_line` in [recording]), with each
        (old, new) of `replace` done and `append` added."""
        scene = self.scene_variant(TANK, name, [("end_time = 0.3", "end_time = 0.04"),
                                                ('fields = ["position", "velocity", "force", "torque", "energies"]',
                                                 fields_line or "")] + list(replace), append)
        out = os.path.join(self.tmp, name)
        sabo = self.run_sabo(scene, out)
        self.assertEqual(sabo.wait(120), 0, sabo.output())
        return out

    @staticmethod
    def report_of(run_dir, role):
        """replay.json of the latest replay of `role` in `run_dir`."""
        folder = sorted(f for f in os.listdir(os.path.join(run_dir, "replay")) if f.startswith(role + "-"))[-1]
        return os.path.join(run_dir, "replay", folder, "replay.json")


class ReplayProcessesTest(ReplayTestCase):
    def test_every_process_of_an_unchanged_build_matches_its_recording(self):
        run = self.recorded_run()
        for role in ("sph", "dem", "fem", "coupler"):
            code, out, err = self.replay(run, role)
            print("replay {}: exit {}; {}".format(role, code, out.splitlines()[0] if out else err))
            self.assertEqual(code, 0, out + err)
            self.assertIn("every field matches", out)
        self.assertNoProcessLeft(run, pids_file=False)

    def test_walls_sent_before_the_fluids_state_replay_to_the_bit(self):
        """The tank's walls as penalty contacts: the boulders' wall particles go before the fluid's state is in
        (docs/protocol.md, "Walls ahead") at most exchanges of the run, and in whatever order the replay feeds the
        states; the coupler and the sph_solver replay to the bit."""
        run = self.recorded_run("penalty_walls", **TANK_PENALTY_WALLS)
        summary = read_json(os.path.join(run, "summary.json"))
        ahead = summary["processes"]["coupler"]["walls_before_the_fluid_state"]
        print("the walls went before the fluid's state at {} of {} exchanges".format(ahead, summary["steps"]))
        self.assertGreater(ahead, 0)
        for role in ("coupler", "sph"):
            code, out, err = self.replay(run, role)
            print("replay {}: exit {}; {}".format(role, code, out.splitlines()[0] if out else err))
            self.assertEqual(code, 0, out + err)
            self.assertIn("every field matches", out)
        self.assertNoProcessLeft(run, pids_file=False)

    def test_a_window_of_steps_starts_from_the_newest_checkpoint_before_it(self):
        run = self.recorded_run()
        kept = sorted(int(name.split("_")[-1][:-3]) for name in os.listdir(os.path.join(run, "checkpoints"))
                      if name.startswith("dem_solver_"))
        self.assertEqual(len(kept), 2)
        first, last = kept[-1] + 2, kept[-1] + 6
        for role in ("dem", "sph", "fem"):
            code, out, err = self.replay(run, role, ["--steps", "{}:{}".format(first, last)])
            print("replay {} --steps {}:{}: exit {}; {}".format(role, first, last, code, out.splitlines()[0]))
            self.assertEqual(code, 0, out + err)
            self.assertIn("resumes from its checkpoint of step {}".format(kept[-1]), err)
            self.assertIn("every field matches over {} steps".format(last - kept[-1] + 1), out)
        # The coupler from its own checkpoint, the solvers played from the recording; with one solver played and
        # the others live, those resume from their checkpoints of the same step.
        code, out, err = self.replay(run, "coupler", ["--steps", "{}:{}".format(first, last)])
        print("replay coupler --steps {}:{}: exit {}; {}".format(first, last, code, out.splitlines()[0]))
        self.assertEqual(code, 0, out + err)
        self.assertIn("the coupler resumes from its checkpoint of step {}".format(kept[-1]), err)
        self.assertIn("every field matches over {} steps".format(last - kept[-1] + 1), out)
        code, out, err = self.replay(run, "coupler", ["--steps", "{}:".format(first), "--take", "dem"])
        self.assertEqual(code, 0, out + err)
        self.assertIn("the coupler and the live sph_solver and the live fem_solver resume from their checkpoint of "
                      "step {}".format(kept[-1]), err)
        self.assertIn("every field matches over {} steps".format(85 - kept[-1]), out)
        # Before every kept checkpoint: from step 0.
        code, out, err = self.replay(run, "dem", ["--steps", "3:7"])
        self.assertEqual(code, 0, out + err)
        self.assertIn("no checkpoint of the dem_solver at or before step 3 is kept", err)
        self.assertIn("every field matches over 8 steps", out)
        code, out, err = self.replay(run, "coupler", ["--steps", ":20"])
        self.assertEqual(code, 0, out + err)
        self.assertIn("every field matches over 21 steps", out)
        code, out, err = self.replay(run, "dem", ["--steps", "9:4"])
        self.assertEqual(code, 2)
        self.assertIn("--steps 9:4: expected A:B with 0 <= A <= B", err)
        self.assertNoProcessLeft(run, pids_file=False)

    def test_the_coupler_with_one_solver_taken_from_the_recording_and_the_others_live(self):
        run = self.recorded_run()
        code, out, err = self.replay(run, "coupler", ["--take", "dem"])
        print("replay coupler --take dem: exit {}; {}".format(code, out.splitlines()[0] if out else err))
        self.assertEqual(code, 0, out + err)
        self.assertIn("every field matches over 85 steps", out)
        folder = os.path.dirname(self.report_of(run, "coupler"))
        self.assertTrue(os.path.isfile(os.path.join(folder, "sph_solver.log")), "the sph_solver ran live")
        self.assertTrue(os.path.isfile(os.path.join(folder, "fem_solver.log")), "the fem_solver ran live")
        self.assertFalse(os.path.exists(os.path.join(folder, "dem_solver.log")), "the dem_solver was played")
        # The live solvers with a heavier boulder (the DEM's material): the coupler's answer to the played sph
        # and fem diverges.
        code, out, err = self.replay(run, "coupler", ["--take", "sph", "fem", "--set",
                                                       "materials.granite.density=2700.0"])
        print(out.splitlines()[0] if out else err)
        self.assertEqual(code, 1, out + err)
        self.assertIn("first divergence", out)
        code, out, err = self.replay(run, "coupler", ["--take", "position"])
        self.assertEqual(code, 2)
        self.assertIn("--take position: with ROLE = coupler, --take names the solvers to play", err)
        self.assertNoProcessLeft(run, pids_file=False)

    def test_a_solver_fed_recorded_fields_shows_which_field_drifts(self):
        """--take FIELD with a solver's role: the recorded values of those fields replace the solver's own at every
        step, so what still diverges is what the change does beyond them."""
        run = self.recorded_run()
        code, out, err = self.replay(run, "dem", ["--take", "position", "velocity", "angular_velocity"])
        print("replay dem --take position velocity angular_velocity: exit {}; {}".format(code, out.splitlines()[0]))
        self.assertEqual(code, 0, out + err)
        self.assertIn("every field matches over 85 steps", out)
        self.assertIn("taken from the recording at every step (the solver's own values replaced): angular_velocity, "
                      "position, velocity", out)
        # A heavier stone: its velocity diverges from step 2 (test_a_changed_parameter_...). With its positions
        # fed from the recording they match at every step while its own velocities still drift; with the whole
        # motion fed, only the energies (which the mass enters) diverge.
        heavier = ["--set", "materials.granite.density=2700.0"]
        code, out, err = self.replay(run, "dem", heavier + ["--take", "position"])
        self.assertEqual(code, 1, out + err)
        with open(self.report_of(run, "dem"), encoding="utf-8") as handle:
            report = json.load(handle)
        print("--take position: position diverges from {}, velocity from {} (expected: never, 2)".format(
            report["fields"]["position"]["first_step"], report["fields"]["velocity"]["first_step"]))
        self.assertEqual(report["taken"], ["position"])
        self.assertIsNone(report["fields"]["position"]["first_step"])
        self.assertGreater(report["fields"]["position"]["compared"], 0)
        self.assertEqual(report["fields"]["velocity"]["first_step"], 2)
        code, out, err = self.replay(run, "dem", heavier + ["--take", "position", "velocity", "angular_velocity"])
        self.assertEqual(code, 1, out + err)
        with open(self.report_of(run, "dem"), encoding="utf-8") as handle:
            report = json.load(handle)
        diverged = sorted(field for field, summary in report["fields"].items() if summary["first_step"] is not None)
        print("--take the whole motion: diverged {} (expected ['energies'])".format(diverged))
        self.assertEqual(diverged, ["energies"])
        # The sph_solver takes its particles' motion; fields a solver does not move are refused with the list.
        code, out, err = self.replay(run, "sph", ["--take", "position", "velocity"])
        self.assertEqual(code, 0, out + err)
        self.assertIn("every field matches over 85 steps", out)
        for role, field, takes in (("dem", "energies", "position, velocity, angular_velocity"),
                                   ("fem", "position", "node_position, node_velocity"),
                                   ("sph", "angular_velocity", "position, velocity")):
            code, out, err = self.replay(run, role, ["--take", field])
            self.assertEqual(code, 2, out + err)
            self.assertIn("--take {}: the {}_solver takes {}".format(field, role, takes), err)
        self.assertNoProcessLeft(run, pids_file=False)


class ReplayFieldsTest(ReplayTestCase):
    def test_a_structure_fed_its_recorded_surface_motion(self):
        """The fem_solver takes its surface nodes' motion: a stiffer block fed the recorded one diverges in its
        stable step and energies only."""
        with open(self.scene_path("configs/tests/sphere_on_block.toml"), encoding="utf-8") as handle:
            text = handle.read()
        recorded_fields = 'fields = ["position", "velocity", "force", "node_position", "node_force", "energies"]'
        self.assertIn(recorded_fields, text)
        scene = os.path.join(self.tmp, "block.toml")
        with open(scene, "w", encoding="utf-8") as handle:
            handle.write(text.replace(recorded_fields, ""))
        run = os.path.join(self.tmp, "block")
        sabo = self.run_sabo(scene, run)
        self.assertEqual(sabo.wait(120), 0, sabo.output())
        code, out, err = self.replay(run, "fem", ["--take", "node_position", "node_velocity"])
        self.assertEqual(code, 0, out + err)
        stiffer = ["--set", "materials.soft_concrete.youngs_modulus=2e9"]
        code, out, err = self.replay(run, "fem", stiffer)
        self.assertEqual(code, 1, out + err)
        with open(self.report_of(run, "fem"), encoding="utf-8") as handle:
            alone = json.load(handle)
        code, out, err = self.replay(run, "fem", stiffer + ["--take", "node_position", "node_velocity"])
        self.assertEqual(code, 1, out + err)
        with open(self.report_of(run, "fem"), encoding="utf-8") as handle:
            fed = json.load(handle)
        print("stiffer block: node_position diverges from step {} on its own, from {} when fed (expected: "
              "never); stable_dt from {}".format(alone["fields"]["node_position"]["first_step"],
                                                 fed["fields"]["node_position"]["first_step"],
                                                 fed["fields"]["stable_dt"]["first_step"]))
        self.assertIsNotNone(alone["fields"]["node_position"]["first_step"])
        for field in ("node_position", "node_velocity"):
            self.assertIsNone(fed["fields"][field]["first_step"])
            self.assertGreater(fed["fields"][field]["compared"], 0)
        self.assertEqual(fed["fields"]["stable_dt"]["first_step"], 0)
        self.assertNoProcessLeft(run, pids_file=False)

    def test_a_changed_parameter_is_reported_where_it_first_diverges(self):
        run = self.recorded_run()
        code, out, err = self.replay(run, "dem", ["--set", "materials.granite.density=2700.0"])
        print(out)
        self.assertEqual(code, 1, out + err)
        # The heavier stone starts with more kinetic energy (it is launched at 0.5 m/s): step 0, energies.
        self.assertIn("first divergence: step 0, t = 0 s, field energies, kinetic", out)
        with open(self.report_of(run, "dem"), encoding="utf-8") as handle:
            report = json.load(handle)
        self.assertFalse(report["matches"])
        self.assertEqual(report["first_divergence"]["field"], "energies")
        # Its motion diverges once the same forces act on more mass (the first forces reach it at step 1).
        velocity = report["fields"]["velocity"]
        print("velocity diverges from step {} in {} values".format(velocity["first_step"], velocity["values"]))
        self.assertEqual(velocity["first_step"], 2)
        # With the energies allowed to differ, the first divergence is that motion.
        code, out, err = self.replay(run, "dem", ["--set", "materials.granite.density=2700.0",
                                                  "--rtol", "energies=1"])
        self.assertEqual(code, 1, out + err)
        self.assertRegex(out, r"first divergence: step 2, .* field (velocity|angular_velocity|position)")

    def test_a_recording_of_some_fields_compares_those(self):
        run = self.recorded_run("scene_fields", 'fields = ["position", "velocity", "force", "torque", "energies"]')
        code, out, err = self.replay(run, "dem")
        print(out)
        self.assertEqual(code, 0, out + err)
        self.assertIn("not compared (not recorded): angular_velocity", out)
        with open(self.report_of(run, "dem"), encoding="utf-8") as handle:
            report = json.load(handle)
        self.assertTrue(report["matches"])
        self.assertGreater(report["fields"]["velocity"]["compared"], 0)

    def test_recordings_that_cannot_drive_a_replay_are_refused(self):
        partial = self.recorded_run("partial", 'fields = ["position", "velocity"]')
        code, out, err = self.replay(partial, "dem")
        print("partial recording: exit {}: {}".format(code, err.strip().splitlines()[-1] if err.strip() else out))
        self.assertEqual(code, 2)
        self.assertIn("lacks the field(s) force, torque", err + out)
        empty = os.path.join(self.tmp, "empty")
        os.makedirs(empty)
        code, out, err = self.replay(empty, "dem")
        self.assertEqual(code, 2)
        self.assertIn("no traffic.h5", err)
        foreign = os.path.join(self.tmp, "foreign")
        os.makedirs(foreign)
        with open(os.path.join(foreign, "traffic.h5"), "w", encoding="utf-8") as handle:
            handle.write("not HDF5\n")
        code, out, err = self.replay(foreign, "dem")
        print("foreign traffic.h5: exit {}: {}".format(code, err.strip().splitlines()[-1]))
        self.assertEqual(code, 2)
        code, out, err = self.replay(partial, "boulders")
        self.assertEqual(code, 2)
        self.assertIn("choose one of sph, dem, fem, coupler", err)
        shutil.rmtree(foreign)


class ReplayAfterAKillTest(RealRunTestCase):
    """Issue 18, item 5: after a kill -9 of the supervisor (every process of the run dies with it) the run
    folder holds traffic.h5 flagged open for writing, coupler.sock and no summary.json; `./sabo replay`, the
    next command that reads the folder, repairs it first and replays what was recorded."""

    def test_replay_repairs_the_folder_a_killed_supervisor_left(self):
        import signal
        import h5py
        from e2e_support import progress_count, wait_for_events
        with open(self.scene_path(TANK), encoding="utf-8") as handle:
            text = handle.read()
        self.assertIn("end_time = 0.3", text)
        scene = os.path.join(self.tmp, "killed.toml")
        with open(scene, "w", encoding="utf-8") as handle:
            handle.write(text.replace("end_time = 0.3", "end_time = 30.0"))
        out = os.path.join(self.tmp, "killed")
        sabo = self.run_sabo(scene, out)
        wait_for_events(sabo, out, lambda events: progress_count(events) >= 3, 120, "3 progress events")
        sabo.signal(signal.SIGKILL)
        sabo.wait(30)
        self.assertNoProcessLeft(out, wait_s=5.0)
        left = sorted(os.listdir(out))
        print("left by kill -9 of the supervisor: {}".format(left))
        self.assertIn("coupler.sock", left)
        self.assertNotIn("summary.json", left)
        with self.assertRaises(OSError):
            h5py.File(os.path.join(out, "traffic.h5"), "r").close()
        code, stdout, stderr = self.replay(out, "dem")
        print("./sabo replay exited with {}; stderr: {}".format(code, stderr.strip()))
        self.assertIn("repaired", stderr)
        self.assertIn("removed the leftover coupler.sock", stderr)
        self.assertIn('wrote summary.json with status "killed"', stderr)
        self.assertFalse(os.path.exists(os.path.join(out, "coupler.sock")))
        with h5py.File(os.path.join(out, "traffic.h5"), "r") as traffic:
            print("traffic.h5 opens with a plain h5py.File: groups {}".format(sorted(traffic)))
        self.assertEqual(code, 0, stdout + stderr)
        self.assertIn("every field matches", stdout)
        self.assertNoProcessLeft(out, pids_file=False)
