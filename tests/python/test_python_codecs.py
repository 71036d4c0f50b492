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

from cslam_client import camera, codecs, video

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


def moving_frames(w, h, n):
    """n BGR frames of a camera panning over a smooth random texture, with a square crossing it."""
    rng = np.random.default_rng(11)
    texture = cv2.GaussianBlur(rng.integers(0, 256, (h + n, w + 2 * n, 3), dtype=np.uint8), (0, 0), 1.5)
    frames = []
    for i in range(n):
        f = texture[i:i + h, 2 * i:2 * i + w].copy()
        x = (5 * i) % max(1, w - 12)
        f[h // 3:h // 3 + 12, x:x + 12] = (40, 200, 250)
        frames.append(f)
    return frames


def split_packets(data):
    """Packets written back to back (each header gives its bitstream length)."""
    packets = []
    while data:
        size = video.HEADER_BYTES + video.parse_header(data).length
        packets.append(data[:size])
        data = data[size:]
    return packets


def psnr(a, b):
    mse = np.mean((a.astype(np.float64) - b.astype(np.float64)) ** 2)
    return 99.0 if mse == 0 else 10 * np.log10(255.0 ** 2 / mse)


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

    def test_rgb_codecs_are_the_cpp_bytes(self):
        rng = np.random.default_rng(3)
        y, x = np.mgrid[0:96, 0:128]
        bgr = np.dstack([x * 2, y * 2, (x + y)]).astype(np.uint8) + rng.integers(0, 20, (96, 128, 3)).astype(np.uint8)
        png = os.path.join(self.dir, "rgb.png")
        cv2.imwrite(png, bgr)
        for codec, quality in (("jpeg", 75), ("jpeg", 90), ("png", 75), ("raw", 75), ("h264-intra", 15),
                               ("h264-intra", 30)):
            with self.subTest(codec=codec, quality=quality):
                options = codecs.Codecs(rgb=codec, jpeg_quality=quality if codec == "jpeg" else 75,
                                        h264_intra_crf=quality if codec == "h264-intra" else 15)
                ours = codecs.ImageEncoder(options).rgb(bgr)[1]
                self.tool("encode-rgb", codec, quality, png, os.path.join(self.dir, "rgb.cpp"))
                self.assertEqual(ours, self.read("rgb.cpp"))


class LeanStreamCodecsMatchCpp(unittest.TestCase):
    """video.py against video_codec.cpp and depth_subsample.cpp."""
    setUp = CodecsMatchCpp.setUp
    tearDown = CodecsMatchCpp.tearDown
    tool = CodecsMatchCpp.tool
    read = CodecsMatchCpp.read

    def write_frames(self, frames):
        path = os.path.join(self.dir, "frames.raw")
        with open(path, "wb") as f:
            f.write(b"".join(np.ascontiguousarray(fr).tobytes() for fr in frames))
        return path

    def cpp_packets(self, frames, options, forced):
        h, w = frames[0].shape[:2]
        out = os.path.join(self.dir, "cpp.h264")
        self.tool("encode-h264", w, h, options.crf, options.preset, options.tune, options.key_interval,
                  options.frame_rate, ",".join(map(str, sorted(forced))) or "-", self.write_frames(frames), out)
        return split_packets(self.read("cpp.h264"))

    def cpp_decode(self, packets, w, h):
        path = os.path.join(self.dir, "py.h264")
        with open(path, "wb") as f:
            f.write(b"".join(packets))
        out = os.path.join(self.dir, "decoded.raw")
        self.tool("decode-h264", w, h, path, out)
        return list(np.frombuffer(self.read("decoded.raw"), np.uint8).reshape(-1, h, w, 3))

    def test_h264_packets_are_the_cpp_bytes(self):
        cases = {
            "defaults": (160, 120, video.H264Options(), {9, 23}),
            "light frames' default": (160, 120, video.light_colour_stream(), {9}),
            # Full frames' h264-intra pictures (codecs.ImageEncoder): every packet a key packet.
            "intra pictures": (160, 120, video.intra_image(15), set()),
            # Odd settings: another size (not a multiple of 16), CRF, preset, tune, frame rate, and
            # a key interval short enough for automatic IDR frames between the forced ones.
            "odd": (98, 62, video.H264Options(crf=30, preset="ultrafast", tune="zerolatency", key_interval=10,
                                              frame_rate=15), {4, 5, 17}),
        }
        for name, (w, h, options, forced) in cases.items():
            with self.subTest(case=name):
                frames = moving_frames(w, h, 36)
                encoder = video.H264Encoder(w, h, options)
                ours = [encoder.encode(f, force_key=i in forced) for i, f in enumerate(frames)]
                theirs = self.cpp_packets(frames, options, forced)
                self.assertEqual(len(theirs), len(frames))
                for i, (a, b) in enumerate(zip(ours, theirs)):
                    if a != b:
                        at = next((k for k, (x, y) in enumerate(zip(a, b)) if x != y), min(len(a), len(b)))
                        self.fail(f"packet {i} differs from the C++ encoder's: {len(a)} vs {len(b)} bytes, "
                                  f"first difference at byte {at} (header {a[:16].hex()} vs {b[:16].hex()})")
                headers = [video.parse_header(p) for p in ours]
                self.assertEqual([hd.index for hd in headers], list(range(len(frames))))
                keys = {hd.index for hd in headers if hd.key}
                self.assertTrue({0} | forced <= keys, f"key packets {sorted(keys)}")
                self.assertEqual(keys, {i for i, p in enumerate(ours) if video.is_key_packet(p)})
                gaps = np.diff(sorted(keys))
                self.assertLessEqual(max(gaps), options.key_interval)
                self.assertEqual(encoder.next_index, len(frames))

    def test_cpp_decoder_decodes_python_packets(self):
        w, h = 160, 120
        frames = moving_frames(w, h, 30)
        first = video.H264Encoder(w, h)
        packets = [first.encode(f) for f in frames[:15]]
        # A restarted encoder (a robot program restarted) begins again at index 0 with a key packet.
        second = video.H264Encoder(w, h)
        packets += [second.encode(f) for f in frames[15:]]
        self.assertTrue(video.is_key_packet(packets[15]))
        self.assertEqual(video.parse_header(packets[15]).index, 0)
        decoded = self.cpp_decode(packets, w, h)
        self.assertEqual(len(decoded), len(frames))
        for i, (src, out) in enumerate(zip(frames, decoded)):
            self.assertGreater(psnr(src, out), 30.0, f"frame {i}")

    def test_depth_subsample_is_the_cpp_one(self):
        rng = np.random.default_rng(5)
        for h, w in ((120, 160), (37, 53), (5, 17), (1, 1)):
            depth = rng.integers(0, 65536, (h, w)).astype(np.uint16)
            png = os.path.join(self.dir, "depth.png")
            self.assertTrue(cv2.imwrite(png, depth))
            for s in (1, 2, 3, 4, 7, 16):
                with self.subTest(size=f"{w}x{h}", subsample=s):
                    ours = video.subsample_depth(depth, s)
                    out = os.path.join(self.dir, "coarse.png")
                    self.tool("subsample-depth", s, png, out)
                    theirs = cv2.imread(out, cv2.IMREAD_ANYDEPTH)
                    self.assertEqual(theirs.dtype, np.uint16)
                    np.testing.assert_array_equal(ours, theirs)
                    self.assertEqual(video.subsampled_depth_size(w, h, s), (ours.shape[1], ours.shape[0]))
                    self.assertEqual(codecs.encode_depth(ours, codecs.Codecs())[1],
                                     codecs.encode_depth(np.ascontiguousarray(theirs), codecs.Codecs())[1])


class KeyframeHintMatchesCpp(unittest.TestCase):
    """LeanStream's keyframe hints (which full frames a byte budget is for) make the choices of
    KeyframeHint in src/codec/keyframe_hint.h: the scripts of tests/codec/test_keyframe_hint.cpp.
    ("full", seq, requested) sends a full frame, ("ack", seq, due_in) an ack's hint, ("want", seq)
    an ack asking for depth, ("expect", seq, requested, answer) checks a full frame's choice."""

    SCRIPTS = {
        "no hint yet": [("expect", 1, True, True), ("full", 1, True), ("ack", 1, 0), ("ack", 2, 0),
                        ("expect", 6, False, True), ("full", 6, False), ("expect", 11, False, True)],
        "first full frame at or after": [
            ("full", 1, True), ("ack", 1, 10), ("ack", 2, 9), ("ack", 5, 6), ("expect", 6, False, False),
            ("full", 6, False), ("ack", 6, 5), ("ack", 9, 2), ("expect", 10, False, False),
            ("expect", 11, False, True), ("expect", 12, False, True), ("full", 12, False),
            ("expect", 16, False, False)],
        "stale": [("full", 1, True), ("ack", 1, 10), ("full", 11, False), ("ack", 10, 1),
                  ("expect", 16, False, False), ("ack", 11, 10), ("expect", 16, False, False),
                  ("expect", 21, False, True)],
        "depth request": [("full", 1, True), ("ack", 1, 10), ("ack", 3, 0), ("expect", 6, False, False),
                          ("want", 3), ("expect", 4, True, True), ("full", 4, True), ("ack", 3, 0),
                          ("expect", 9, False, False), ("ack", 4, 10), ("expect", 14, False, True)],
        "an ack without a hint": [
            ("full", 1, True), ("ack", 1, 10), ("ack", 5, 0), ("expect", 6, False, False), ("expect", 11, False, True),
            ("full", 11, False), ("ack", 12, 0), ("expect", 16, False, False), ("expect", 100, False, False),
            ("ack", 20, 3), ("expect", 23, False, True)],
    }

    def test_scripts(self):
        for name, script in self.SCRIPTS.items():
            lean = video.LeanStream(64, 48, 5)
            for step in script:
                kind, seq = step[0], step[1]
                if kind == "ack":
                    lean.on_keyframe_hint(seq, step[2])
                elif kind == "want":
                    self.assertTrue(lean.on_want_depth(seq), name)
                elif kind == "full":
                    self.assertEqual(lean._depth_wanted, step[2], f"{name}: {step}")
                    lean.full_sent(seq)
                else:
                    self.assertEqual(lean._depth_wanted, step[2], f"{name}: {step}")
                    self.assertEqual(lean.expects_keyframe(seq), step[3], f"{name}: {step}")


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

    def test_h264_encoder_rejects_bad_sizes_images_and_options(self):
        with self.assertRaisesRegex(ValueError, "161x120: sides must be even"):
            video.H264Encoder(161, 120)
        with self.assertRaisesRegex(ValueError, "sides must be even"):
            video.H264Encoder(0, 120)
        encoder = video.H264Encoder(64, 48)
        with self.assertRaisesRegex(TypeError, "HxWx3 uint8 BGR image, got float32"):
            encoder.encode(np.zeros((48, 64, 3), np.float32))
        with self.assertRaisesRegex(TypeError, r"shape \(48, 64\)"):
            encoder.encode(np.zeros((48, 64), np.uint8))
        with self.assertRaisesRegex(TypeError, "got list"):
            encoder.encode([[0, 0, 0]])
        with self.assertRaisesRegex(ValueError, "image is 62x48, the stream is 64x48"):
            encoder.encode(np.zeros((48, 62, 3), np.uint8))
        self.assertEqual(encoder.next_index, 0)  # nothing refused was counted
        self.assertTrue(video.is_key_packet(encoder.encode(np.zeros((48, 64, 3), np.uint8))))
        bad = {"crf": 52, "preset": "turbo", "tune": "psnr", "key_interval": 0, "frame_rate": 1001}
        messages = {"crf": "crf 52", "preset": "preset 'turbo'", "tune": "must include zerolatency",
                    "key_interval": "key interval 0", "frame_rate": "frame rate 1001"}
        for field, value in bad.items():
            with self.subTest(option=field):
                with self.assertRaisesRegex(ValueError, messages[field]):
                    video.H264Encoder(64, 48, video.H264Options(**{field: value}))
        with self.assertRaisesRegex(ValueError, "unknown h264 tune 'fast'"):
            video.H264Options(tune="zerolatency,fast").validate()

    def test_depth_subsample_rejects_bad_input(self):
        for s in (0, 17):
            with self.assertRaisesRegex(ValueError, f"depth subsample {s} is not 1..16"):
                video.subsample_depth(np.zeros((4, 4), np.uint16), s)
        with self.assertRaisesRegex(TypeError, "HxW uint16"):
            video.subsample_depth(np.zeros((4, 4), np.float32), 2)
        with self.assertRaisesRegex(TypeError, "HxW uint16"):
            video.subsample_depth(np.zeros((4, 4, 1), np.uint16), 2)


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
