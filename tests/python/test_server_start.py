"""cslam-server refuses an --out-dir it cannot write at start, with one line, instead of failing
after the session (where the results would be lost)."""
import os
import subprocess
import unittest

import harness


class ServerStart(unittest.TestCase):
    def test_unwritable_out_dir_is_refused_at_start(self):
        d = harness.scratch("outdir")
        blocker = os.path.join(d, "a_file")
        open(blocker, "w").close()
        for out_dir in (os.path.join(blocker, "out"), "/proc/cslam-out"):  # under a file; in /proc (even root)
            with self.subTest(out_dir=out_dir):
                r = subprocess.run([harness.program("cslam-server"), "--out-dir", out_dir, "--http", "off", "--bind",
                                    "tcp://127.0.0.1:*"], capture_output=True, text=True, timeout=60)
                self.assertEqual(r.returncode, 2, r.stderr)
                lines = r.stderr.strip().splitlines()
                self.assertEqual(len(lines), 1, r.stderr)
                self.assertIn(f"--out-dir '{out_dir}' is not writable", lines[0])
        harness.cleanup(d, True)

    def test_writable_out_dir_is_created_and_left_clean(self):
        d = harness.scratch("outdir")
        out = os.path.join(d, "new", "out")
        server = harness.Server(d, extra=["--out-dir", out])  # the last --out-dir wins
        server.stop()
        self.assertTrue(os.path.isdir(out))
        self.assertFalse(os.path.exists(os.path.join(out, ".cslam-write-probe")))
        harness.cleanup(d, True)


if __name__ == "__main__":
    unittest.main()
