"""Every scene in tests/scenes/bad/ is refused by `./sabo run` with an error naming the file, and
nothing is started (real sabo_scene from the build)."""
import glob
import os
import unittest

from e2e_support import ROOT, RealRunTestCase

BAD_SCENES = os.path.join(ROOT, "tests", "scenes", "bad")


class BadSceneTest(RealRunTestCase):
    def test_every_bad_scene_is_refused_before_anything_starts(self):
        scenes = sorted(glob.glob(os.path.join(BAD_SCENES, "*.toml")))
        self.assertTrue(scenes, "no bad scenes in " + BAD_SCENES)
        for scene in scenes:
            name = os.path.basename(scene)
            with self.subTest(scene=name):
                out = os.path.join(self.tmp, os.path.splitext(name)[0])
                sabo = self.run_sabo(scene, out)
                self.assertEqual(sabo.wait(60), 2, sabo.output())
                self.assertIn(name, sabo.stderr)
                self.assertIn("nothing was started", sabo.stderr)
                self.assertFalse(os.path.exists(out), "a run folder was created for " + name)
                self.assertNoProcessLeft(out, pids_file=False)


if __name__ == "__main__":
    unittest.main()
