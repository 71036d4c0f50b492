"""The Python client's codecs against the C++ ones (src/codec), byte for byte.

Run by ctest with PYTHONPATH=build/python and CSLAM_CODEC_TOOL=the C++ codec tool.
"""
import os
import subprocess
import tempfile
import unittest

import cv2
import numpy as np
import zstandard

from cslam_client import camera, codecs

TOOL = os.environ.get("CSLAM_CODEC_TOOL", "")


def depth_cases():
    rng = np.random.default_rng(7)
    h, w = 120, 160
    y, x = np.mgrid[0:h, 0:w]
    # A Kinect-like surface: quantised smooth depth, noise, holes, a depth edge.
    surface = 5000 * (1.2 + 0.004 * x + 0.002 * y) + rng.normal(0, 8, (h, w))
    surface[40:80, 60:100] -= 2500
    kinect = np.rint(surface / 5) * 5
    kinect[rng.random((h, w)) < 0.08] = 0
    kinect[:, :7] = 0
    cases = {
        "kinect": kinect.astype(np.uint16),
        "all_holes": np.zeros((h, w), np.uint16),
        "one_pixel": np.zeros((h, w), np.uint16),
        "no_holes_full_range": rng.integers(1, 65536, (h, w)).astype(np.uint16),  # residuals wrap in int16
        "sparse_extremes": np.where(rng.random((h, w)) < 0.3, rng.choice([1, 65535], (h, w)), 0).astype(np.uint16),
        "odd_size": rng.integers(0, 3000, (37, 53)).astype(np.uint16),
    }
    cases["one_pixel"][h // 2, w // 3] = 1234
    return cases


class CodecsMatchCpp(unittest.TestCase):
    def setUp(self):
        self.assertTrue(os.path.isfile(TOOL), f"CSLAM_CODEC_TOOL '{TOOL}' missing: run through ctest after a build")
        self.tmp = tempfile.TemporaryDirectory(prefix="cslam-pycodec-")
        self.dir = self.tmp.name

    def tearDown(self):
        self.tmp.cleanup()

    def tool(self, *args):
        subprocess.run([TOOL, *map(str, args)], check=True)

    def read(self, name):
        with open(os.path.join(self.dir, name), "rb") as f:
            return f.read()

    def test_zstd_delta_depth_is_the_cpp_encoding(self):
        for name, depth in depth_cases().items():
            with self.subTest(image=name):
                png = os.path.join(self.dir, name + ".png")
                self.assertTrue(cv2.imwrite(png, depth))
                ours = codecs.encode_depth(depth, codecs.Codecs())[1]
                self.tool("encode-depth", "zstd", 1, png, os.path.join(self.dir, name + ".cpp"))
                theirs = self.read(name + ".cpp")
                # The uncompressed layouts are identical, and so are the zstd frames (same libzstd).
                dctx = zstandard.ZstdDecompressor()
                self.assertEqual(dctx.decompress(ours), dctx.decompress(theirs))
                self.assertEqual(ours, theirs)
                # The C++ decoder gives back the exact image.
                with open(os.path.join(self.dir, name + ".py"), "wb") as f:
                    f.write(ours)
                out = os.path.join(self.dir, name + ".decoded.png")
                self.tool("decode-depth", "zstd", depth.shape[1], depth.shape[0], os.path.join(self.dir, name + ".py"),
                          out)
                np.testing.assert_array_equal(cv2.imread(out, cv2.IMREAD_ANYDEPTH), depth)

    def test_other_depth_codecs_decode_in_cpp(self):
        depth = depth_cases()["kinect"]
        for codec in ("raw", "png"):
            with self.subTest(codec=codec):
                data = codecs.encode_depth(depth, codecs.Codecs(depth=codec))[1]
                path = os.path.join(self.dir, codec + ".bin")
                with open(path, "wb") as f:
                    f.write(data)
                out = os.path.join(self.dir, codec + ".png")
                self.tool("decode-depth", codec, depth.shape[1], depth.shape[0], path, out)
                np.testing.assert_array_equal(cv2.imread(out, cv2.IMREAD_ANYDEPTH), depth)

    def test_jpeg_and_png_rgb_are_the_cpp_bytes(self):
        rng = np.random.default_rng(3)
        y, x = np.mgrid[0:96, 0:128]
        bgr = np.dstack([x * 2, y * 2, (x + y)]).astype(np.uint8) + rng.integers(0, 20, (96, 128, 3)).astype(np.uint8)
        png = os.path.join(self.dir, "rgb.png")
        cv2.imwrite(png, bgr)
        for codec, quality in (("jpeg", 75), ("jpeg", 90), ("png", 75), ("raw", 75)):
            with self.subTest(codec=codec, quality=quality):
                ours = codecs.encode_rgb(bgr, codecs.Codecs(rgb=codec, jpeg_quality=quality))[1]
                self.tool("encode-rgb", codec, quality, png, os.path.join(self.dir, "rgb.cpp"))
                self.assertEqual(ours, self.read("rgb.cpp"))


class CodecOptions(unittest.TestCase):
    def test_rejects_bad_options_and_images(self):
        with self.assertRaises(ValueError):
            codecs.Codecs(depth="rvl").validate()
        with self.assertRaises(ValueError):
            codecs.Codecs(jpeg_quality=0).validate()
        with self.assertRaises(TypeError):
            codecs.encode_depth(np.zeros((4, 4), np.float32), codecs.Codecs())
        with self.assertRaises(TypeError):
            codecs.encode_rgb(np.zeros((4, 4), np.uint8), codecs.Codecs())


class CameraFromName(unittest.TestCase):
    def test_tum_camera_in_a_bag_or_folder_name_as_the_cpp_rule(self):
        # The same cases as tests/io/test_dataset_camera.cpp.
        cases = {"/data/rgbd_dataset_freiburg2_xyz": "tum2", "/data/rgbd_dataset_freiburg3_long_office_household/": "tum3",
                 "../shared/data/tum_fr1_desk": "tum1", "FR3-office.bag": "tum3", "/data/freiburg2/xyz": "tum2",
                 "/data/robot_1": "", "/data/frame_dump": "", "/data/run_fr12": "", "/data/afr1": "",
                 "/data/freiburg4_x": "", "": ""}
        for path, preset in cases.items():
            with self.subTest(path=path):
                self.assertEqual(camera.preset_from_name(path), preset)

    def test_rolling_shutter_readout_as_the_cpp_presets(self):
        # src/geometry/camera.cpp: the TUM colour cameras read out in 20 ms; synthetic and files
        # without the key are global shutter.
        for name in ("tum1", "tum2", "tum2-corrected", "tum3"):
            self.assertEqual(camera.preset(name).readout_time, 0.020)
        self.assertEqual(camera.preset("synthetic").readout_time, 0.0)
        self.assertEqual(camera.Camera().readout_time, 0.0)
        with self.assertRaises(ValueError):
            camera.Camera(readout_time=-0.01).validate()


if __name__ == "__main__":
    unittest.main()
