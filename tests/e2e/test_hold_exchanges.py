"""Hold exchanges (issue 22; docs/protocol.md, "Hold exchanges"): with multirate the slurry steps at its own
step although the boulders and the dams set a shorter exchange. The reduced treated Wenjia scene
(configs/tests/wenjia_treated_reduced.toml, its first second): the sph_solver steps at every second exchange and
holds at the others. Against the same scene with `hold_exchanges = false` (every solver at every exchange, as
until 7 December 2026): the sph_solver takes at most 0.6 of the steps (0.50 measured), the front's advance over
the second stays within 3 % (-0.16 %), the fluid's mean load on the gully within 2 % (+0.02 %) and the boulders'
within 5 % (+3.8 %: the slurry's forces on them are held over two of their steps), the energy never rises above its
start and the contact forces keep Newton's third law to 1e-10. And a run with hold exchanges is a pure
function of its input: every process replays from traffic.h5 to the bit, and the sph_solver killed mid-run and
restarted from its checkpoint gives the same bits as the run left alone. Each check prints measured beside
expected."""
import csv
import os

from e2e_support import ROOT, RealRunTestCase, read_json

SCENE = "configs/tests/wenjia_treated_reduced.toml"
OUTPUTS = ["forces.csv", "energy.csv", "fronts.csv", "sph.pvd", "dem.pvd", "fem.pvd"]


def front_advance(run_dir):
    with open(os.path.join(run_dir, "fronts.csv"), newline="") as handle:
        rows = list(csv.DictReader(handle))
    return float(rows[-1]["position"]) - float(rows[0]["position"])


def mean_loads(run_dir, part):
    """Per source, the load's magnitude averaged over the output times after the first (N)."""
    loads = {}
    with open(os.path.join(run_dir, "forces.csv"), newline="") as handle:
        for row in csv.DictReader(handle):
            if row["part"] == part and float(row["time"]) > 0:
                loads.setdefault(row["source"], []).append(float(row["F"]))
    return {source: sum(values) / len(values) for source, values in loads.items()}


class HoldExchangesTest(RealRunTestCase):
    def write_scene(self, name, holds, end_time=1.0, record_all=False):
        with open(self.scene_path(SCENE), encoding="utf-8") as handle:
            text = handle.read()
        text = text.replace("end_time = 1.0\n", "end_time = {!r}\n".format(end_time), 1)
        text = text.replace("multirate = true", "multirate = true\nhold_exchanges = {}".format(
            "true" if holds else "false"), 1)
        # The profile file is named relative to the scene's folder.
        text = text.replace('"../wenjia/', '"{}/'.format(os.path.join(ROOT, "configs", "wenjia")))
        if record_all:
            start = text.index("[recording]")
            text = text[:start] + "[recording]\nevery = 1\n"
        scene = os.path.join(self.tmp, name + ".toml")
        with open(scene, "w", encoding="utf-8") as handle:
            handle.write(text)
        return scene

    def run_case(self, name, holds, **scene_options):
        out = os.path.join(self.tmp, name)
        sabo = self.run_sabo(self.write_scene(name, holds, **scene_options), out)
        self.assertEqual(sabo.wait(300), 0, sabo.output())
        return out, read_json(os.path.join(out, "summary.json"))

    def test_the_slurry_steps_at_its_own_step_and_the_loads_stay(self):
        held, held_summary = self.run_case("holds", True)
        every, every_summary = self.run_case("every_exchange", False)
        sph = held_summary["multirate"]["solvers"]["sph_solver"]
        sph_every = every_summary["multirate"]["solvers"]["sph_solver"]
        ratio = sph["steps"] / sph_every["steps"]
        print("sph_solver: {} steps and {} hold exchanges in {} exchanges, against {} steps at every exchange: "
              "{:.2f} of them (at most 0.60); wall time {:.1f} s against {:.1f} s".format(
                  sph["steps"], sph["hold_exchanges"], sph["exchanges"], sph_every["steps"], ratio,
                  held_summary["wall_seconds"], every_summary["wall_seconds"]))
        self.assertGreater(sph["hold_exchanges"], 0)
        self.assertLessEqual(ratio, 0.60)
        self.assertEqual(sph_every["hold_exchanges"], 0)
        for name in ("dem_solver", "fem_solver"):
            self.assertEqual(held_summary["multirate"]["solvers"][name]["hold_exchanges"], 0)

        advance, advance_every = front_advance(held), front_advance(every)
        print("front's advance over the run: {:.4f} m with hold exchanges, {:.4f} m without ({:+.2f} %, within "
              "3 %)".format(advance, advance_every, 100 * (advance / advance_every - 1)))
        self.assertGreater(advance_every, 0.5)
        self.assertLess(abs(advance / advance_every - 1), 0.03)
        # The boulders' load moves more: the slurry's penalty forces on them are held over two of their steps.
        loads, loads_every = mean_loads(held, "gully"), mean_loads(every, "gully")
        for source, limit in (("fluid", 0.02), ("particles", 0.05)):
            change = loads[source] / loads_every[source] - 1
            print("mean {} load on the gully: {:.5g} N with hold exchanges, {:.5g} N without ({:+.3f} %, within "
                  "{:.0f} %)".format(source, loads[source], loads_every[source], 100 * change, 100 * limit))
            self.assertGreater(loads_every[source], 0)
            self.assertLess(abs(change), limit)
        for summary, label in ((held_summary, "with hold exchanges"), (every_summary, "without")):
            rise = summary["energies"]["max_rise_over_initial"]
            newton = summary["newton_third_law"]["max_relative_residual"]
            print("{}: energy rise over its start {:.3g} (0 expected), Newton residual {:.2e} (at most 1e-10)"
                  .format(label, rise, newton))
            self.assertLessEqual(rise, 0.0)
            self.assertLessEqual(newton, 1e-10)

    def test_replays_and_restarts_to_the_bit(self):
        reference, summary = self.run_case("recorded", True, end_time=0.5, record_all=True)
        print("recorded: {} exchanges, the sph_solver holding at {}".format(
            summary["steps"], summary["multirate"]["solvers"]["sph_solver"]["hold_exchanges"]))
        for role in ("sph", "dem", "fem", "coupler"):
            code, out, err = self.replay(reference, role)
            print("replay {}: exit {}; {}".format(role, code, out.splitlines()[0] if out else err))
            self.assertEqual(code, 0, out + err)
            self.assertIn("every field matches", out)

        out = os.path.join(self.tmp, "restarted")
        code, sabo = self.run_and_kill(self.write_scene("restarted", True, end_time=0.5, record_all=True), out,
                                       "sph_solver", 300)
        self.assertEqual(code, 0, sabo.output())
        restarts = read_json(os.path.join(out, "summary.json"))["restarts"]
        print("restarts: {}".format(restarts))
        self.assertEqual(len(restarts), 1)
        self.assertSameRunOutputs(reference, out, OUTPUTS)
        print("restarted: {} and every frame of sph/, dem/ and fem/ are the bits of the run left alone".format(
            ", ".join(OUTPUTS)))
