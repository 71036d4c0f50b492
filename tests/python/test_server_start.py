"""cslam-server refuses at start, with one line (code 2), what would otherwise fail later or leave
it running without what it was asked for: an --out-dir or --state-dir it cannot write (results or
snapshots lost after the session), a full disk there, a --bind or HTTP port in use, no folder for
the keyframe store. Its temporary keyframe store goes away with it."""
import os
import resource
import signal
import subprocess
import unittest
from unittest import mock

import harness


class ServerStart(unittest.TestCase):
    def assert_refused(self, run_dir, args, expected, **kwargs):
        """Starts cslam-server with `args` (and an --out-dir in run_dir unless given): exit code 2 and
        one line on stderr that contains `expected`."""
        if "--out-dir" not in args:
            args = [*args, "--out-dir", os.path.join(run_dir, "out")]
        r = subprocess.run([harness.program("cslam-server"), *args, "--log-level", "warn"], capture_output=True,
                           text=True, timeout=60, **kwargs)
        self.assertEqual(r.returncode, 2, r.stderr)
        lines = r.stderr.strip().splitlines()
        self.assertEqual(len(lines), 1, r.stderr)
        self.assertIn(expected, lines[0])
        return lines[0]

    def test_unwritable_out_dir_and_state_dir_are_refused_at_start(self):
        """--state-dir as --out-dir: a server that could never write a snapshot there would lose
        the maps it was asked to keep."""
        d = harness.scratch("outdir")
        blocker = os.path.join(d, "a_file")
        open(blocker, "w").close()
        for option in ("--out-dir", "--state-dir"):
            for folder in (os.path.join(blocker, "out"), "/proc/cslam-out"):  # under a file; in /proc (even root)
                with self.subTest(option=option, folder=folder):
                    self.assert_refused(d, [option, folder, "--http", "off", "--bind", "tcp://127.0.0.1:*"],
                                        f"{option} '{folder}' is not writable")
        harness.cleanup(d, True)

    def test_a_folder_without_write_permission_is_refused_with_the_reason(self):
        """The folder exists but no file can be made in it (sysfs refuses even root): the line says
        why, in the words the system gives this test for the same attempt (permission denied on a
        host, a read-only file system in some containers)."""
        d = harness.scratch("outdir")
        with self.assertRaises(OSError) as attempt:
            open("/sys/.cslam-test-probe", "w").close()
        reason = os.strerror(attempt.exception.errno)
        self.assert_refused(d, ["--out-dir", "/sys", "--http", "off", "--bind", "tcp://127.0.0.1:*", "--no-dense"],
                            f"--out-dir '/sys' is not writable: cannot write a file in it: {reason}")
        harness.cleanup(d, True)

    def test_a_full_disk_is_refused_at_start(self):
        """The probe file is closed before it counts as written: a full disk fails at the flush, not
        at the write into the buffer. A file size limit below the probe's 3 bytes stands in for the
        full disk (as tests/persistence does), so this runs without root."""
        d = harness.scratch("fulldisk")

        def limit_file_size():
            signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # writes beyond it fail with EFBIG instead
            resource.setrlimit(resource.RLIMIT_FSIZE, (2, 2))

        out_dir = os.path.join(d, "out")
        self.assert_refused(d, ["--out-dir", out_dir, "--http", "off", "--bind", "tcp://127.0.0.1:*", "--no-dense"],
                            f"--out-dir '{out_dir}' is not writable: cannot write a file in it",
                            preexec_fn=limit_file_size)
        self.assertEqual(os.listdir(out_dir), [], "the probe file stayed")
        harness.cleanup(d, True)

    def test_ports_in_use_are_refused(self):
        """A --bind endpoint in use is named; asked for HTTP, the server does not run without its API
        and viewer."""
        d = harness.scratch("ports")
        port_file = os.path.join(d, "http_port")
        first = harness.Server(os.path.join(d, "first"),
                               extra=["--no-dense", "--http", "0", "--http-port-file", port_file])
        try:
            # Written (atomically) before the endpoint file the harness waited for.
            with open(port_file) as f:
                port = f.read().strip()
            self.assert_refused(d, ["--bind", first.endpoint, "--http", "off", "--no-dense"],
                                f"cannot bind --bind {first.endpoint}: Address already in use")
            self.assert_refused(d, ["--bind", "tcp://127.0.0.1:*", "--http", port, "--no-dense"],
                                f"cannot serve HTTP on 127.0.0.1:{port} (in use?)")
        finally:
            first.stop()
        harness.cleanup(d, True)

    def test_writable_out_dir_is_created_and_left_clean(self):
        d = harness.scratch("outdir")
        out = os.path.join(d, "new", "out")
        server = harness.Server(d, extra=["--out-dir", out])  # the last --out-dir wins
        server.stop()
        self.assertTrue(os.path.isdir(out))
        self.assertFalse(os.path.exists(os.path.join(out, ".cslam-write-probe")))
        harness.cleanup(d, True)

    def test_the_keyframe_stores_temporary_folder(self):
        """Without --state-dir the keyframe store lives in a private folder under TMPDIR, removed at
        exit; --no-dense makes none; a TMPDIR where none can be made is refused at start, with one
        line saying what to do (a read-only container without a tmpfs at /tmp)."""
        d = harness.scratch("tmpdir")
        tmp = os.path.join(d, "tmp")
        os.makedirs(tmp)
        for extra in ((), ("--no-dense",)):
            with self.subTest(extra=extra), mock.patch.dict(os.environ, {"TMPDIR": tmp}):
                server = harness.Server(os.path.join(d, "run" + "".join(extra)), extra=list(extra))
                made = os.listdir(tmp)
                server.stop()
                self.assertEqual(len(made), 0 if extra else 1, made)
                self.assertEqual(os.listdir(tmp), [], "the folder outlived the server")
        local = ["--http", "off", "--bind", "tcp://127.0.0.1:*"]
        with mock.patch.dict(os.environ, {"TMPDIR": tmp}):  # a dense option refused after the folder was made
            self.assert_refused(d, [*local, "--dense-submap-keyframes", "0"], "keyframes_per_submap")
        self.assertEqual(os.listdir(tmp), [], "a refused start left its folder")
        for tmpdir in (os.path.join(d, "missing"), "/proc"):  # no folder; one not even root can write
            with self.subTest(tmpdir=tmpdir), mock.patch.dict(os.environ, {"TMPDIR": tmpdir}):
                line = self.assert_refused(d, local,
                                           f"cannot create the keyframe store's temporary folder in '{tmpdir}'")
                self.assertIn("--state-dir", line)
        harness.cleanup(d, True)


if __name__ == "__main__":
    unittest.main()
