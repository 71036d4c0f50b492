"""The Python client against a real cslam-server over loopback, compared with cslam-client.

The same synthetic robot is streamed once by cslam-client (C++) and once by cslam_client
(Python) to servers started with the same options. Protocol equivalence is checked on the
server side: the same frames accepted and processed, the same number of frame bytes received
(the codecs are byte-identical, see test_python_codecs), the same trajectory timestamps. The trajectories
are compared by ATE against the ground truth, with a tolerance for the SLAM worker's threads.
"""
import dataclasses
import os
import subprocess
import unittest

import numpy as np
import zmq

import harness
from cslam_client import camera, dataset, errors
from cslam_client.sender import CurveKeys, FrameSender
from cslam_client.wire import pb


class PythonClientEndToEnd(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.dir = harness.scratch("pyclient")
        cls.scene = harness.synth_scene(os.path.join(cls.dir, "scene"))
        cls.robot = os.path.join(cls.scene, "robot_1")
        cls.ok = True

    @classmethod
    def tearDownClass(cls):
        harness.cleanup(cls.dir, cls.ok)

    def run_cpp(self, name):
        server = harness.Server(os.path.join(self.dir, name))
        self.addCleanup(server.stop)  # a failed check must not leave the server waiting for a goodbye
        with open(os.path.join(self.dir, name, "client.log"), "w") as log:
            rc = subprocess.run([harness.program("cslam-client"), "--server", server.endpoint, "--id", "1", "--dataset",
                                 self.robot, "--rate", "max"], stdout=log, stderr=subprocess.STDOUT).returncode
        self.assertEqual(rc, 0, f"see {self.dir}/{name}/client.log")
        self.assertEqual(server.wait(), 0, f"see {server.log_path}")
        return server

    def run_python(self, name):
        server = harness.Server(os.path.join(self.dir, name))
        self.addCleanup(server.stop)
        cam = camera.load(os.path.join(self.robot, "camera.yaml"))
        acks = []
        sender = FrameSender(server.endpoint, 1, cam, on_ack=acks.append)
        sender.connect()
        pairs = dataset.open_tum(self.robot)
        for pair in pairs:
            bgr, depth = dataset.load_pair(pair)
            sender.send(bgr, depth, pair.rgb_time, pair.depth_time - pair.rgb_time)
        self.assertTrue(sender.goodbye())
        self.assertEqual(sender.stats.frames_sent, len(pairs))
        self.assertEqual(sender.stats.acks, len(pairs))
        self.assertEqual(sorted(a.seq for a in acks), list(range(1, len(pairs) + 1)))
        self.assertEqual(sender.stats.errors, {})
        type(self).py_bytes_sent = sender.stats.bytes_sent
        self.assertEqual(server.wait(), 0, f"see {server.log_path}")
        return server

    def test_python_stream_equals_cpp_stream(self):
        try:
            cpp = self.run_cpp("cpp")
            py = self.run_python("python")
            cpp_stats = harness.client_stats(cpp.network_stats(), 1)
            py_stats = harness.client_stats(py.network_stats(), 1)
            for key in ("frames_accepted", "frames_processed", "dropped_total", "goodbyes"):
                self.assertEqual(py_stats[key], cpp_stats[key], key)
            self.assertEqual(py_stats["frames_accepted"], 60)
            # The server counts the bytes of frame messages: identical streams, byte for byte in size.
            self.assertEqual(py_stats["bytes_received"], cpp_stats["bytes_received"])
            self.assertEqual(py_stats["bytes_received"], self.py_bytes_sent)

            cpp_traj, py_traj = cpp.trajectory(1), py.trajectory(1)
            self.assertEqual(len(py_traj), len(cpp_traj))
            for a, b in zip(cpp_traj, py_traj):
                self.assertAlmostEqual(a[0], b[0], places=6)
            gt = os.path.join(self.robot, "groundtruth.txt")
            ate_cpp = harness.ate_rmse(gt, os.path.join(cpp.out, "client_1.txt"))
            ate_py = harness.ate_rmse(gt, os.path.join(py.out, "client_1.txt"))
            # Both track; the tolerance covers thread scheduling in the SLAM worker (harness.py).
            self.assertLess(ate_cpp, harness.ATE_MAX)
            self.assertLess(ate_py, harness.ATE_MAX)
            self.assertLess(abs(ate_py - ate_cpp), harness.ATE_TOLERANCE,
                            f"ATE C++ {ate_cpp:.4f} m, Python {ate_py:.4f} m")
        except Exception:
            type(self).ok = False
            raise


class PythonClientSession(unittest.TestCase):
    """Resume after a reconnect, and the server's errors as typed exceptions."""

    @classmethod
    def setUpClass(cls):
        cls.dir = harness.scratch("pysession")
        cls.scene = harness.synth_scene(os.path.join(cls.dir, "scene"), frames=20)
        cls.robot = os.path.join(cls.scene, "robot_1")
        cls.cam = camera.load(os.path.join(cls.robot, "camera.yaml"))
        cls.pairs = dataset.open_tum(cls.robot)
        cls.ok = True

    @classmethod
    def tearDownClass(cls):
        harness.cleanup(cls.dir, cls.ok)

    def setUp(self):
        self.server = harness.Server(os.path.join(self.dir, self.id().split(".")[-1]), extra=["--no-slam"])

    def tearDown(self):
        self.server.stop()
        result = self._outcome.result
        if result.failures or result.errors:
            type(self).ok = False

    def test_reconnect_resumes_the_session(self):
        sender = FrameSender(self.server.endpoint, 1, self.cam)
        sender.connect()
        for pair in self.pairs[:10]:
            sender.send(*dataset.load_pair(pair), pair.rgb_time, pair.depth_time - pair.rgb_time)
        sender.reconnect()  # a new connection, same client id
        self.assertTrue(sender.welcome.resumed)
        self.assertGreaterEqual(sender.welcome.last_seq, 1)
        for pair in self.pairs[10:]:
            sender.send(*dataset.load_pair(pair), pair.rgb_time, pair.depth_time - pair.rgb_time)
        self.assertTrue(sender.goodbye())
        self.assertEqual(self.server.wait(), 0)
        self.assertEqual(len(self.server.trajectory(1)), len(self.pairs))
        stats = harness.client_stats(self.server.network_stats(), 1)
        self.assertEqual(stats["frames_accepted"], len(self.pairs))
        self.assertEqual(stats["dropped_total"], 0)

    def test_bad_hello_raises_with_the_server_code(self):
        sender = FrameSender(self.server.endpoint, 2, self.cam)
        sender.camera = dataclasses.replace(self.cam, fx=-1.0)  # past the client's check: the server's
        with self.assertRaises(errors.HelloRejected) as ctx:
            sender.connect()
        self.assertEqual(ctx.exception.code, pb.ERROR_BAD_HELLO)
        self.assertEqual(ctx.exception.code_name, "ERROR_BAD_HELLO")
        self.assertIn("camera", ctx.exception.server_message)
        sender.close()

    def test_old_protocol_version_raises(self):
        sender = FrameSender(self.server.endpoint, 3, self.cam, protocol_version=99)
        with self.assertRaises(errors.ProtocolVersionError) as ctx:
            sender.connect()
        self.assertEqual(ctx.exception.code, pb.ERROR_BAD_VERSION)
        sender.close()

    def test_corrupt_frame_is_a_typed_frame_error_and_gives_the_credit_back(self):
        sender = FrameSender(self.server.endpoint, 4, self.cam, strict=True)
        sender.connect()
        window = sender.credits
        bgr, depth = dataset.load_pair(self.pairs[0])
        frame = sender.encode(bgr, depth, self.pairs[0].rgb_time)
        frame.depth.data = frame.depth.data[: len(frame.depth.data) // 2]  # truncated zstd stream
        sender.send_encoded(frame)
        with self.assertRaises(errors.FrameRejected) as ctx:
            sender.goodbye(timeout=30)
        self.assertEqual(ctx.exception.code_name, "ERROR_CORRUPT_IMAGE")
        self.assertEqual(ctx.exception.seq, 1)
        self.assertEqual(sender.stats.errors, {"ERROR_CORRUPT_IMAGE": 1})
        self.assertEqual(sender.credits, window)
        self.assertEqual(sender.in_flight, 0)
        sender.close()



class FakeServer:
    """A ROUTER socket that speaks the server's side by hand, for exact control of credits."""

    def __init__(self, curve_secret=None):
        self.ctx = zmq.Context.instance()
        self.sock = self.ctx.socket(zmq.ROUTER)
        self.sock.setsockopt(zmq.LINGER, 0)
        if curve_secret:
            self.sock.curve_server = True
            self.sock.curve_secretkey = curve_secret
        port = self.sock.bind_to_random_port("tcp://127.0.0.1")
        self.endpoint = f"tcp://127.0.0.1:{port}"
        self.peer = None

    def recv(self, timeout=10.0):
        if not self.sock.poll(int(timeout * 1000)):
            return None
        self.peer, body = self.sock.recv_multipart()
        m = pb.ClientMessage()
        m.ParseFromString(body)
        return m

    def recv_kind(self, kind, timeout=10.0):
        while True:
            m = self.recv(timeout)
            if m is None or m.WhichOneof("body") == kind:
                return m

    def reply(self, **body):
        m = pb.ServerMessage(**body)
        self.sock.send_multipart([self.peer, m.SerializeToString()])

    def close(self):
        self.sock.close()


class PythonClientProtocol(unittest.TestCase):
    """Live mode and CURVE against a hand-driven server (exact credits, no timing races)."""

    def setUp(self):
        self.cam = camera.Camera(width=32, height=24, name="tiny")
        self.bgr = np.zeros((24, 32, 3), np.uint8)
        self.depth = np.full((24, 32), 5000, np.uint16)

    def test_live_mode_never_blocks_and_keeps_the_newest_frame(self):
        server = FakeServer()
        sender = FrameSender(server.endpoint, 7, self.cam, live=True, reply_timeout=10)
        sender._open_socket()
        hello = pb.ClientMessage(hello=pb.Hello(client_id=7))
        sender._send_message(hello)
        self.assertIsNotNone(server.recv_kind("hello"))
        server.reply(welcome=pb.Welcome(client_id=7, credits=2, window=2))
        while not sender._welcomed:
            sender.poll(0.1)
        for k in range(5):  # no ack comes: two frames go out, the newest of the rest waits
            sender.send(self.bgr, self.depth, 100.0 + k)
        self.assertEqual(sender.stats.frames_sent, 2)
        self.assertEqual(sender.stats.dropped_no_credit, 2)
        got = [server.recv_kind("frame").frame for _ in range(2)]
        self.assertEqual([f.timestamp for f in got], [100.0, 101.0])
        self.assertEqual([f.seq for f in got], [1, 2])
        server.reply(ack=pb.Ack(client_id=7, seq=1, credits=1))
        sender.poll(2.0)
        third = server.recv_kind("frame").frame
        self.assertEqual((third.seq, third.timestamp), (3, 104.0))  # the newest frame, next seq
        self.assertEqual(sender.last_ack.seq, 1)
        self.assertEqual([(a.seq, a.fields) for a in sender.take_acks()], [(1, {"client_id": 7, "seq": 1, "credits": 1})])
        self.assertEqual(sender.take_acks(), [])
        sender.close()
        server.close()

    def test_curve_keys_encrypt_and_authenticate(self):
        server_public, server_secret = zmq.curve_keypair()
        client_public, client_secret = zmq.curve_keypair()
        server = FakeServer(curve_secret=server_secret)
        keys = CurveKeys(server_public.decode(), client_public.decode(), client_secret.decode())
        sender = FrameSender(server.endpoint, 8, self.cam, curve=keys, reply_timeout=10)
        sender._open_socket()
        sender._send_message(pb.ClientMessage(hello=pb.Hello(client_id=8)))
        m = server.recv_kind("hello")
        self.assertIsNotNone(m)
        self.assertEqual(m.hello.client_id, 8)
        sender.close()
        # A client with the wrong server key never gets through (the handshake fails).
        wrong_public, _ = zmq.curve_keypair()
        bad = FrameSender(server.endpoint, 9, self.cam, reply_timeout=1.5, max_reconnects=1,
                          curve=CurveKeys(wrong_public.decode(), client_public.decode(), client_secret.decode()))
        with self.assertRaises(errors.ConnectionFailed):
            bad.connect()
        self.assertIsNone(server.recv(timeout=0.5))
        bad.close()
        server.close()

    def test_curve_keys_load_from_files(self):
        """cslam-keygen's files (NAME.key: public-key + secret-key lines, NAME.pub) and bare keys."""
        server_public, server_secret = zmq.curve_keypair()
        public, secret = zmq.curve_keypair()
        d = harness.scratch("pykeys")
        path = lambda name: os.path.join(d, name)  # noqa: E731
        with open(path("server.pub"), "w") as f:
            f.write(f"# cslam CURVE public key\npublic-key = {server_public.decode()}\n")
        with open(path("robot1.key"), "w") as f:
            f.write(f"# cslam CURVE secret key: keep private (mode 0600)\npublic-key = {public.decode()}\n"
                    f"secret-key = {secret.decode()}\n")
        with open(path("bare_server"), "w") as f:
            f.write(server_public.decode() + "\n")
        with open(path("bare_secret"), "w") as f:
            f.write(secret.decode() + "\n")
        for server_file, own_file in (("server.pub", "robot1.key"), ("bare_server", "bare_secret")):
            keys = CurveKeys.load(path(server_file), path(own_file))
            self.assertEqual((keys.server_public, keys.client_public, keys.client_secret),
                             (server_public.decode(), public.decode(), secret.decode()))
        with self.assertRaises(ValueError):  # a .pub where the secret key belongs
            CurveKeys.load(path("server.pub"), path("server.pub"))
        harness.cleanup(d, True)


if __name__ == "__main__":
    unittest.main()
