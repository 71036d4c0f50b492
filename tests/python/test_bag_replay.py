"""tools/cslam-bag-replay against a real cslam-server, matched with the folder replay.

A synthetic sequence is written to ROS 1 bags by python3-rosbag: one TUM-style (default topics,
rgb8 + 32FC1 depth in metres), one with other topics and 16UC1 depth. Each bag's replay must
send the same frames as cslam-client replaying the folder: same frames and frame bytes at the
server, same trajectory timestamps, ATE within the SLAM worker's run-to-run tolerance.
"""
import os
import subprocess
import unittest

import cv2
import numpy as np
import rosbag
import rospy
from sensor_msgs.msg import Image

import harness
from cslam_client import dataset


def image_msg(stamp, encoding, array, step_bytes):
    msg = Image()
    msg.header.stamp = stamp
    msg.header.frame_id = "camera"
    msg.height, msg.width = array.shape[:2]
    msg.encoding = encoding
    msg.is_bigendian = 0
    msg.step = step_bytes
    msg.data = array.tobytes()
    return msg


def write_bag(path, robot, rgb_topic, depth_topic, depth_encoding, extra_topic=None):
    with rosbag.Bag(path, "w") as bag:
        for pair in dataset.open_tum(robot):
            bgr, depth = dataset.load_pair(pair)
            rgb = cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB)
            t_rgb, t_depth = rospy.Time.from_sec(pair.rgb_time), rospy.Time.from_sec(pair.depth_time)
            bag.write(rgb_topic, image_msg(t_rgb, "rgb8", rgb, rgb.shape[1] * 3), t_rgb)
            if depth_encoding == "32FC1":
                metres = np.where(depth > 0, depth.astype(np.float32) / np.float32(5000), np.float32("nan"))
                bag.write(depth_topic, image_msg(t_depth, "32FC1", metres.astype("<f4"), depth.shape[1] * 4), t_depth)
            else:
                bag.write(depth_topic, image_msg(t_depth, depth_encoding, depth.astype("<u2"), depth.shape[1] * 2), t_depth)
            if extra_topic:
                bag.write(extra_topic, image_msg(t_rgb, "mono8", bgr[:, :, 0].copy(), bgr.shape[1]), t_rgb)


class BagReplay(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.dir = harness.scratch("bagreplay")
        cls.scene = harness.synth_scene(os.path.join(cls.dir, "scene"))
        cls.robot = os.path.join(cls.scene, "robot_1")
        cls.camera = os.path.join(cls.robot, "camera.yaml")
        cls.tum_bag = os.path.join(cls.dir, "tum_style.bag")
        write_bag(cls.tum_bag, cls.robot, "/camera/rgb/image_color", "/camera/depth/image", "32FC1")
        cls.u16_bag = os.path.join(cls.dir, "u16.bag")
        write_bag(cls.u16_bag, cls.robot, "/cam/color", "/cam/depth", "16UC1")
        cls.bad_bag = os.path.join(cls.dir, "mono_depth.bag")
        write_bag(cls.bad_bag, cls.robot, "/camera/rgb/image_color", "/camera/depth/image", "8UC1",
                  extra_topic="/camera/ir/image")
        cls.ok = True
        cls.folder = cls.replay("folder", [harness.program("cslam-client"), "--dataset", cls.robot, "--rate", "max"])

    @classmethod
    def tearDownClass(cls):
        harness.cleanup(cls.dir, cls.ok)

    @classmethod
    def replay(cls, name, command):
        server = harness.Server(os.path.join(cls.dir, name))
        log_path = os.path.join(cls.dir, name, "client.log")
        with open(log_path, "w") as log:
            rc = subprocess.run([*command, "--server", server.endpoint, "--id", "1"], stdout=log,
                                stderr=subprocess.STDOUT).returncode
        if rc != 0:
            server.stop()
            cls.ok = False
            raise AssertionError(f"{name}: replay exited {rc}, see {log_path}")
        if server.wait() != 0:
            cls.ok = False
            raise AssertionError(f"{name}: server failed, see {server.log_path}")
        return server

    def bag_tool(self, bag, *args):
        return [harness.program("cslam-bag-replay"), bag, "--camera", self.camera, "--progress-interval", "1", *args]

    def check_same_as_folder(self, server):
        try:
            ref = harness.client_stats(self.folder.network_stats(), 1)
            got = harness.client_stats(server.network_stats(), 1)
            self.assertEqual(got["frames_accepted"], 60)
            for key in ("frames_accepted", "frames_processed", "dropped_total", "bytes_received"):
                self.assertEqual(got[key], ref[key], key)
            ref_traj, traj = self.folder.trajectory(1), server.trajectory(1)
            self.assertEqual(len(traj), len(ref_traj))
            for a, b in zip(ref_traj, traj):
                self.assertAlmostEqual(a[0], b[0], places=6)
            gt = os.path.join(self.robot, "groundtruth.txt")
            ate_ref = harness.ate_rmse(gt, os.path.join(self.folder.out, "client_1.txt"))
            ate = harness.ate_rmse(gt, os.path.join(server.out, "client_1.txt"))
            self.assertLess(ate, harness.ATE_MAX)
            self.assertLess(abs(ate - ate_ref), harness.ATE_TOLERANCE, f"ATE folder {ate_ref:.4f} m, bag {ate:.4f} m")
        except Exception:
            type(self).ok = False
            raise

    def test_tum_bag_with_metric_float_depth(self):
        self.check_same_as_folder(self.replay("tum32f", self.bag_tool(self.tum_bag)))

    def test_bag_with_16bit_depth_and_other_topics(self):
        server = self.replay("u16", self.bag_tool(self.u16_bag, "--rgb-topic", "/cam/color", "--depth-topic",
                                                  "/cam/depth", "--depth-units", "5000", "--rate", "200"))
        self.check_same_as_folder(server)

    def test_lean_stream_from_a_bag(self):
        server = self.replay("lean", self.bag_tool(self.tum_bag, "--depth-every", "4"))
        got = harness.client_stats(server.network_stats(), 1)
        self.assertEqual(got["frames_accepted"], 60)
        self.assertGreaterEqual(got["frames_light"], 30)  # 3 of 4 frames light, but for the server's depth requests
        self.assertEqual(got["dropped_total"], 0)
        ate = harness.ate_rmse(os.path.join(self.robot, "groundtruth.txt"), os.path.join(server.out, "client_1.txt"))
        self.assertLess(ate, harness.ATE_MAX)

    def test_bad_depth_every_is_refused(self):
        r = subprocess.run([*self.bag_tool(self.tum_bag, "--depth-every", "0"), "--id", "1"], capture_output=True, text=True)
        self.assertEqual(r.returncode, 2, r.stderr)
        self.assertIn("depth_every 0 must be >= 1", r.stderr)

    def test_missing_topic_lists_the_bag_topics(self):
        r = subprocess.run(self.bag_tool(self.u16_bag, "--id", "1"), capture_output=True, text=True)
        self.assertEqual(r.returncode, 2, r.stderr)
        self.assertIn("no colour topic /camera/rgb/image_color", r.stderr)
        self.assertIn("/cam/color (sensor_msgs/Image, 60 msgs)", r.stderr)
        self.assertIn("/cam/depth (sensor_msgs/Image, 60 msgs)", r.stderr)

    def test_unknown_depth_encoding_is_named(self):
        server = harness.Server(os.path.join(self.dir, "bad_encoding"), extra=["--no-slam"])
        try:
            r = subprocess.run([*self.bag_tool(self.bad_bag), "--server", server.endpoint, "--id", "1"],
                               capture_output=True, text=True)
        finally:
            server.stop()
        self.assertEqual(r.returncode, 2, r.stderr)
        self.assertIn("depth encoding '8UC1' is not handled", r.stderr)


if __name__ == "__main__":
    unittest.main()
