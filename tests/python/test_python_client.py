"""The Python client against a real cslam-server over loopback, compared with cslam-client.

The same synthetic robot is streamed once by cslam-client (C++) and once by cslam_client
(Python) to servers started with the same options. Protocol equivalence is checked on the
server side: the same frames accepted and processed, the same number of frame bytes received
(the codecs are byte-identical, see test_python_codecs), the same trajectory timestamps. The trajectories
are compared by ATE against the ground truth, with a tolerance for the SLAM worker's threads.
"""
import dataclasses
import json
import os
import subprocess
import time
import unittest
import urllib.request

import numpy as np
import zmq

import harness
from cslam_client import camera, codecs, dataset, errors, video
from cslam_client.sender import CurveKeys, FrameSender
from cslam_client.wire import pb


def stream_robot(sender, robot):
    """Connects, sends every frame of the robot's dataset, says goodbye (all acked); returns the pairs."""
    sender.connect()
    pairs = dataset.open_tum(robot)
    for pair in pairs:
        bgr, depth = dataset.load_pair(pair)
        sender.send(bgr, depth, pair.rgb_time, pair.depth_time - pair.rgb_time)
    if not sender.goodbye():
        raise AssertionError("goodbye: not every frame was acknowledged")
    return pairs


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
        pairs = stream_robot(sender, self.robot)
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


class BudgetedLeanStreamEqualsCpp(unittest.TestCase):
    """A lean stream with a byte budget (cslam-client --depth-every 5 --byte-budget) from both
    clients: the same full frames made finer, the same bytes. The servers run without SLAM, so no
    depth request makes the full frames depend on timing."""

    @classmethod
    def setUpClass(cls):
        cls.dir = harness.scratch("pybudget")
        cls.scene = harness.synth_scene(os.path.join(cls.dir, "scene"), frames=40)
        cls.robot = os.path.join(cls.scene, "robot_1")
        cls.ok = True

    @classmethod
    def tearDownClass(cls):
        harness.cleanup(cls.dir, cls.ok)

    BUDGET_MB_S = 0.4  # the synthetic lean stream sends ~0.3 MB/s: room for some finer full frames

    def test_budgeted_lean_stream_is_the_cpp_stream(self):
        try:
            cpp = harness.Server(os.path.join(self.dir, "cpp"), extra=["--no-slam"])
            self.addCleanup(cpp.stop)
            summary = os.path.join(self.dir, "cpp", "summary.json")
            with open(os.path.join(self.dir, "cpp", "client.log"), "w") as log:
                rc = subprocess.run([harness.program("cslam-client"), "--server", cpp.endpoint, "--id", "1", "--dataset",
                                     self.robot, "--rate", "max", "--depth-every", "5", "--byte-budget",
                                     str(self.BUDGET_MB_S), "--summary-out", summary],
                                    stdout=log, stderr=subprocess.STDOUT).returncode
            self.assertEqual(rc, 0, f"see {self.dir}/cpp/client.log")
            self.assertEqual(cpp.wait(), 0, f"see {cpp.log_path}")
            with open(summary) as f:
                cpp_finer = json.load(f)["frames_finer"]

            py = harness.Server(os.path.join(self.dir, "python"), extra=["--no-slam"])
            self.addCleanup(py.stop)
            cam = camera.load(os.path.join(self.robot, "camera.yaml"))
            budget = codecs.ByteBudget(self.BUDGET_MB_S * 1e6, frame_rate=30)
            sender = FrameSender(py.endpoint, 1, cam, depth_every=5, byte_budget=budget)
            stream_robot(sender, self.robot)
            self.assertEqual(py.wait(), 0, f"see {py.log_path}")

            # Full frames (8 of the 40) got finer colour, the same in both, within the budget.
            self.assertGreater(sender.stats.frames_finer, 0)
            self.assertEqual(sender.stats.frames_finer, cpp_finer)
            cpp_stats = harness.client_stats(cpp.network_stats(), 1)
            py_stats = harness.client_stats(py.network_stats(), 1)
            for key in ("frames_accepted", "frames_light", "dropped_total"):
                self.assertEqual(py_stats[key], cpp_stats[key], key)
            self.assertEqual(py_stats["frames_accepted"], 40)
            self.assertEqual(py_stats["bytes_received"], cpp_stats["bytes_received"])
        except Exception:
            type(self).ok = False
            raise

    def test_budget_options_are_checked(self):
        for bad in ({"bytes_per_s": -1}, {"bytes_per_s": float("nan")}, {"frame_rate": 0}, {"burst_s": 0},
                    {"jpeg_qualities": (90, 95)}, {"jpeg_qualities": (101,)}):
            with self.assertRaises(ValueError, msg=str(bad)):
                codecs.ByteBudget(**bad)
        self.assertFalse(codecs.ByteBudget().enabled)


class SmallSceneCase(unittest.TestCase):
    """A 20-frame synthetic robot in a scratch folder of its own (SCRATCH names it), kept when a
    test failed."""
    SCRATCH = ""

    @classmethod
    def setUpClass(cls):
        cls.dir = harness.scratch(cls.SCRATCH)
        cls.scene = harness.synth_scene(os.path.join(cls.dir, "scene"), frames=20)
        cls.robot = os.path.join(cls.scene, "robot_1")
        cls.cam = camera.load(os.path.join(cls.robot, "camera.yaml"))
        cls.pairs = dataset.open_tum(cls.robot)
        cls.ok = True

    @classmethod
    def tearDownClass(cls):
        harness.cleanup(cls.dir, cls.ok)


class PythonClientSession(SmallSceneCase):
    """Resume after a reconnect, and the server's errors as typed exceptions."""
    SCRATCH = "pysession"

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


class PythonClientLeanStream(SmallSceneCase):
    """depth_every > 1 against a real cslam-server: light frames decoded and counted by the server
    (/api/status), a reconnect and a lost packet healed by key packets (as test_lean_stream.cpp)."""
    SCRATCH = "pylean"

    @classmethod
    def setUpClass(cls):
        super().setUpClass()
        cls.frames = [(*dataset.load_pair(p), p.rgb_time, p.depth_time - p.rgb_time) for p in cls.pairs]

    def setUp(self):
        run = os.path.join(self.dir, self.id().split(".")[-1])
        self.port_file = os.path.join(run, "http_port")
        # --no-slam: tracking never asks for depth (want_depth), so the schedule is exactly depth_every's.
        self.server = harness.Server(run, extra=["--no-slam", "--http", "0", "--http-port-file", self.port_file])

    def tearDown(self):
        self.server.stop()
        result = self._outcome.result
        if result.failures or result.errors:
            type(self).ok = False

    def network_client(self, client_id):
        """This client's receiver counters from /api/status ({} until the server lists it)."""
        with open(self.port_file) as f:
            port = int(f.read().strip())
        with urllib.request.urlopen(f"http://127.0.0.1:{port}/api/status", timeout=10) as r:
            status = json.load(r)
        return next((c for c in status.get("network", {}).get("clients", []) if c["id"] == client_id), {})

    def wait_for_counter(self, client_id, key, value, timeout=60):
        """The status is a cached snapshot, refreshed in the background: wait for it to show `value`."""
        deadline = time.monotonic() + timeout
        while True:
            got = self.network_client(client_id).get(key)
            if got == value or time.monotonic() > deadline:
                return got
            time.sleep(0.1)

    def drain(self, sender):
        while sender.in_flight > 0:
            sender.poll(0.5)

    def test_light_frames_between_full_frames_are_taken(self):
        sender = FrameSender(self.server.endpoint, 1, self.cam, depth_every=4)
        sender.connect()
        for i, frame in enumerate(self.frames):
            if i == 10:
                sender.reconnect()  # a restarted server would lack the stream: the next packet is a key
                self.assertTrue(sender.welcome.resumed)
            sender.send(*frame)
        self.drain(sender)
        s = sender.stats
        # Full frames 1, 5, 9, 13, 17 (the count goes on across the reconnect); light frames
        # 2-4, 6-8, 10-12, 14-16, 18-20; key packets: frame 2 and frame 11, the first after the reconnect.
        self.assertEqual((s.frames_sent, s.frames_light, s.colour_key_packets), (20, 15, 2))
        self.assertEqual((s.depth_requests, s.stream_gaps, s.frames_refused), (0, 0, 0))
        # The hello may be asked again while the server still holds the old connection.
        self.assertEqual(set(s.errors) - {"ERROR_SESSION_BUSY"}, set(), s.errors)
        self.assertLess(s.bytes_light / 15, (s.bytes_sent - s.bytes_light) / 5)  # a light frame is smaller
        self.assertEqual(self.wait_for_counter(1, "frames_light", 15), 15)
        self.assertEqual(self.network_client(1)["frames_accepted"], 20)
        self.assertTrue(sender.goodbye())
        self.assertEqual(self.server.wait(), 0, f"see {self.server.log_path}")
        stats = harness.client_stats(self.server.network_stats(), 1)
        self.assertEqual((stats["frames_accepted"], stats["dropped_total"]), (20, 0))

    def test_a_lost_packet_is_healed_by_the_next_key_packet(self):
        sender = FrameSender(self.server.endpoint, 1, self.cam, depth_every=100)  # full depth only first
        sender.connect()
        for frame in self.frames[:6]:
            sender.send(*frame)
        # A colour packet that never reaches the server (as one lost on the way): the next one
        # lacks its reference, the server answers ERROR_STREAM_GAP.
        sender.lean.encoder.encode(self.frames[6][0])
        for frame in self.frames[6:]:
            sender.send(*frame)
        self.assertTrue(sender.goodbye())  # every frame answered: acked or refused
        s = sender.stats
        self.assertGreaterEqual(s.stream_gaps, 1)
        self.assertEqual(s.errors, {"ERROR_STREAM_GAP": s.stream_gaps})
        self.assertEqual(s.colour_key_packets, 2)  # the first packet, and one after the gap
        # Up to `window` frames are in flight when the gap is reported: each is refused, then the
        # key packet restarts the stream and every frame after it is taken.
        self.assertEqual(s.frames_refused, s.stream_gaps)
        self.assertEqual(s.acks, len(self.frames) - s.frames_refused)
        self.assertLessEqual(s.stream_gaps, sender.window)
        self.assertEqual(self.server.wait(), 0, f"see {self.server.log_path}")
        stats = harness.client_stats(self.server.network_stats(), 1)
        self.assertEqual(stats["dropped"], {"stream_gap": s.stream_gaps})


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

    def test_lean_stream_follows_depth_requests_and_stream_gaps(self):
        """Full frames every depth_every-th frame and after an ack asks for depth; a reported gap
        makes the next colour packet a key packet; light frames carry the colour stream's packets
        (the bytes of an H264Encoder fed the same images) and subsampled depth."""
        cam = camera.Camera(width=64, height=48, name="small")
        server = FakeServer()
        sender = FrameSender(server.endpoint, 7, cam, depth_every=5, reply_timeout=10)
        sender._open_socket()
        sender._send_message(pb.ClientMessage(hello=pb.Hello(client_id=7)))
        self.assertIsNotNone(server.recv_kind("hello"))
        server.reply(welcome=pb.Welcome(client_id=7, credits=20, window=20))
        while not sender._welcomed:
            sender.poll(0.1)
        rng = np.random.default_rng(1)
        texture = rng.integers(0, 256, (48, 64 + 20, 3), dtype=np.uint8)
        images = [np.ascontiguousarray(texture[:, i:i + 64]) for i in range(9)]
        depth = (np.arange(48 * 64).reshape(48, 64) % 5000 + 500).astype(np.uint16)

        def send(i):
            sender.send(images[i], depth, 1.0 + i / 30, 0.01)
            return server.recv_kind("frame").frame

        def reply_and_wait(counter, **body):
            before = getattr(sender.stats, counter)
            server.reply(**body)
            while getattr(sender.stats, counter) == before:
                sender.poll(0.1)

        got = [send(i) for i in range(3)]                  # seq 1 full, 2 light (key), 3 light
        reply_and_wait("acks", ack=pb.Ack(client_id=7, seq=2, credits=1, want_depth=True))
        got.append(send(3))                                # seq 4: full, asked for
        reply_and_wait("acks", ack=pb.Ack(client_id=7, seq=3, credits=1, want_depth=True))  # met by seq 4
        got.append(send(4))                                # seq 5 light
        reply_and_wait("stream_gaps", error=pb.Error(client_id=7, seq=5, code=pb.ERROR_STREAM_GAP, credits=1))
        got += [send(i) for i in range(5, 9)]              # seq 6 light (key), 7, 8 light, 9 full
        h264 = pb.Encoding.Value(codecs.RGB_H264)
        kinds = ["full" if f.rgb.encoding != h264 else "key" if video.is_key_packet(f.rgb.data) else "light"
                 for f in got]
        self.assertEqual(kinds, ["full", "key", "light", "full", "light", "key", "light", "light", "full"])
        s = sender.stats
        self.assertEqual((s.frames_light, s.colour_key_packets, s.depth_requests, s.stream_gaps), (6, 2, 1, 1))
        # The request of seq 2's ack was answered by seq 4: two frames after the asking one.
        self.assertEqual((s.depth_requests_met, s.depth_request_lag_sum, s.depth_request_lag_max), (1, 2, 2))
        stream = video.H264Encoder(64, 48, video.light_colour_stream())  # the sender's default colour stream
        coarse = codecs.encode_depth(video.subsample_depth(depth, 4), codecs.Codecs())[1]
        for i, f in enumerate(got):
            with self.subTest(seq=f.seq):
                if kinds[i] == "full":
                    self.assertEqual((f.depth.width, f.depth.height, f.depth_subsample), (64, 48, 0))
                    continue
                self.assertEqual(f.rgb.data, stream.encode(images[i], force_key=kinds[i] == "key"))
                self.assertEqual((f.depth.width, f.depth.height, f.depth_subsample), (16, 12, 4))
                self.assertEqual(f.depth.data, coarse)
                self.assertAlmostEqual(f.depth_time_offset, 0.01)
        sender.close()
        server.close()

    def test_live_lean_stream_encodes_a_light_frame_only_when_it_leaves(self):
        server = FakeServer()
        sender = FrameSender(server.endpoint, 7, self.cam, live=True, depth_every=3, reply_timeout=10)
        sender._open_socket()
        sender._send_message(pb.ClientMessage(hello=pb.Hello(client_id=7)))
        self.assertIsNotNone(server.recv_kind("hello"))
        server.reply(welcome=pb.Welcome(client_id=7, credits=1, window=1))
        while not sender._welcomed:
            sender.poll(0.1)
        for k in range(4):  # one credit: the first frame goes, the newest of the rest waits
            sender.send(self.bgr + k, self.depth, 100.0 + k)
        self.assertEqual((sender.stats.frames_sent, sender.stats.dropped_no_credit), (1, 2))
        first = server.recv_kind("frame").frame
        # Full: the first frame, its colour a standalone H.264 picture (a lean stream's default).
        self.assertEqual((first.rgb.encoding, first.depth.width), (pb.RGB_H264_INTRA, 32))
        self.assertEqual(sender.lean.encoder.next_index, 0)  # the dropped frames never entered the stream
        server.reply(ack=pb.Ack(client_id=7, seq=1, credits=1))
        while sender.stats.frames_sent < 2:
            sender.poll(0.1)
        light = server.recv_kind("frame").frame
        self.assertEqual((light.seq, light.timestamp, light.live), (2, 103.0, True))
        self.assertEqual(video.parse_header(light.rgb.data).index, 0)
        self.assertTrue(video.is_key_packet(light.rgb.data))
        self.assertEqual(sender.stats.frames_light, 1)
        sender.close()
        server.close()

    def test_lean_stream_options_are_checked(self):
        for kwargs, message in (({"depth_every": 0}, "depth_every 0"),
                                ({"depth_every": 2, "light_depth_subsample": 1}, "light_depth_subsample 1"),
                                ({"depth_every": 2, "colour_stream": video.H264Options(crf=60)}, "crf 60")):
            with self.subTest(**{k: str(v) for k, v in kwargs.items()}):
                with self.assertRaisesRegex(ValueError, message):
                    FrameSender("tcp://127.0.0.1:1", 1, self.cam, **kwargs)
        with self.assertRaisesRegex(ValueError, "31x24: sides must be even"):
            FrameSender("tcp://127.0.0.1:1", 1, camera.Camera(width=31, height=24, name="odd"), depth_every=2)

    def test_light_colour_stream_is_the_cpp_clients_default(self):
        # One default for both client libraries: the C++ client prints SenderConfig's in --help.
        text = subprocess.run([harness.program("cslam-client"), "--help"], check=True, capture_output=True,
                              text=True).stdout
        def default(option):
            block = text.split(f"--{option} V", 1)[1]
            return block.split("(default: ", 1)[1].split(")", 1)[0]
        light = video.light_colour_stream()
        self.assertEqual((default("colour-crf"), default("colour-preset")), (str(light.crf), light.preset))

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
