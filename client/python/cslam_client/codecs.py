"""Image codecs of the cslam wire protocol, bit-compatible with src/codec.

RGB: raw BGR8, JPEG and PNG through OpenCV (python3-opencv links the same libjpeg/libpng as the
C++ programs, so the same quality gives the same bytes), and "h264-intra": every image one
H.264 key picture that decodes on its own, from one encoder per stream (ImageEncoder below, as
the C++ codec/image_encoder.h: the same pictures in the same order give the same bytes).
Depth (16-bit, lossless): raw little-endian, 16-bit PNG, and zstd-delta, the default: the layout of
``depth_codec::zstd_delta_encode`` in src/codec/depth_codecs.cpp, vectorised with numpy:

  u32 T; T sorted distinct non-zero depth values (u16 LE, delta-coded); W*H bytes hole mask
  (1 valid, 0 hole); M low bytes then M high bytes of the zig-zag residuals of the valid pixels'
  value ranks against the LOCO-I median edge predictor (M valid pixels, raster order); all zstd.

zstd comes from python3-zstandard, which links Debian's libzstd: the compressed bytes equal the
C++ encoder's at the same level. RVL is not offered here (a per-nibble loop is slow in Python).

A lean stream's light frames (video.py) send colour as RGB_H264 packets and depth subsampled
(RgbdFrame.depth_subsample) with the depth codec above.
"""
from dataclasses import dataclass

import numpy as np

RGB_CODECS = ("raw", "jpeg", "png", "h264-intra")
DEPTH_CODECS = ("raw", "png", "zstd")
# Wire encoding of a light frame's colour: a packet of the robot's H.264 stream (video.py). Never
# a full frame's: a full frame's colour must decode on its own.
RGB_H264 = "RGB_H264"


def auto_rgb_codec(light_frames):
    """The full frames' colour codec unless one is chosen, as auto_rgb_codec() in
    src/codec/image_codec.h: standalone H.264 pictures in a stream with light frames, else JPEG."""
    return "h264-intra" if light_frames else "jpeg"


@dataclass
class Codecs:
    rgb: str = "jpeg"
    depth: str = "zstd"
    jpeg_quality: int = 75     # as CodecOptions in src/codec/image_codec.h
    png_compression: int = 1
    zstd_level: int = 1
    h264_intra_crf: int = 15   # 0..51, as CodecOptions::h264_intra_crf

    def validate(self):
        if self.rgb not in RGB_CODECS:
            raise ValueError(f"unknown RGB codec '{self.rgb}' ({', '.join(RGB_CODECS)})")
        if self.depth not in DEPTH_CODECS:
            raise ValueError(f"unknown depth codec '{self.depth}' ({', '.join(DEPTH_CODECS)}; rvl only in C++)")
        if not 1 <= self.jpeg_quality <= 100:
            raise ValueError("JPEG quality must be in 1..100")
        if not 0 <= self.png_compression <= 9:
            raise ValueError("PNG compression must be in 0..9")
        if not 1 <= self.zstd_level <= 19:
            raise ValueError("zstd level must be in 1..19")
        if not 0 <= self.h264_intra_crf <= 51:
            raise ValueError("H.264 intra crf must be in 0..51")


def _imencode(ext, image, params):
    import cv2
    ok, buf = cv2.imencode(ext, image, params)
    if not ok:
        raise RuntimeError(f"cannot encode {ext}")
    return buf.tobytes()


def encode_rgb(bgr, codecs):
    """bgr: HxWx3 uint8 (OpenCV order). Returns (wire encoding name, bytes)."""
    import cv2
    if not isinstance(bgr, np.ndarray) or bgr.dtype != np.uint8 or bgr.ndim != 3 or bgr.shape[2] != 3:
        raise TypeError("encode_rgb: expected an HxWx3 uint8 BGR image")
    if codecs.rgb == "raw":
        return "RGB_RAW_BGR8", np.ascontiguousarray(bgr).tobytes()
    if codecs.rgb == "jpeg":
        return "RGB_JPEG", _imencode(".jpg", bgr, [cv2.IMWRITE_JPEG_QUALITY, codecs.jpeg_quality])
    if codecs.rgb == "h264-intra":
        raise ValueError("encode_rgb: h264-intra pictures come from one ImageEncoder per stream")
    return "RGB_PNG", _imencode(".png", bgr, [cv2.IMWRITE_PNG_COMPRESSION, codecs.png_compression])


class ImageEncoder:
    """One stream's encoder for full frames' images, as ImageEncoder in src/codec/image_encoder.h:
    stateless codecs through encode_rgb / encode_depth; h264-intra through one H.264 encoder with
    video.intra_image() (key interval 1), made at the first picture, whose rate control carries
    over between pictures. Encode the frames in sending order."""
    SKIP_FACTOR = 1.25  # rgb_within skips a quality whose last picture was over this x the allowance

    def __init__(self, codecs):
        codecs.validate()
        self.codecs = codecs
        self._intra = None
        self._jpeg_sizes = {}  # rgb_within: JPEG quality -> its last picture's bytes

    def rgb(self, bgr):
        """Returns (wire encoding name, bytes)."""
        if self.codecs.rgb != "h264-intra":
            return encode_rgb(bgr, self.codecs)
        from . import video
        if self._intra is None:
            if not isinstance(bgr, np.ndarray) or bgr.ndim != 3:
                raise TypeError("ImageEncoder.rgb: expected an HxWx3 uint8 BGR image")
            self._intra = video.H264Encoder(bgr.shape[1], bgr.shape[0], video.intra_image(self.codecs.h264_intra_crf))
        return "RGB_H264_INTRA", self._intra.encode(bgr)

    def depth(self, depth):
        return encode_depth(depth, self.codecs)

    def rgb_within(self, bgr, allowance, jpeg_qualities):
        """A full frame's colour within a byte budget, as ImageEncoder::rgb_within: the first of
        `jpeg_qualities` (finest first) finer than the codecs' own JPEG quality whose picture takes
        at most `allowance` bytes, else rgb(). Raw and PNG are never replaced. Returns (wire
        encoding name, bytes, finer: whether a finer JPEG was chosen)."""
        import cv2
        if self.codecs.rgb not in ("raw", "png") and allowance > 0:
            if not isinstance(bgr, np.ndarray) or bgr.dtype != np.uint8 or bgr.ndim != 3 or bgr.shape[2] != 3:
                raise TypeError("rgb_within: expected an HxWx3 uint8 BGR image")
            for quality in jpeg_qualities:
                if self.codecs.rgb == "jpeg" and quality <= self.codecs.jpeg_quality:
                    break
                last = self._jpeg_sizes.get(quality)
                if last is not None and float(last) > self.SKIP_FACTOR * float(allowance):
                    continue  # far over the last time: not tried (as the C++ encoder)
                data = _imencode(".jpg", bgr, [cv2.IMWRITE_JPEG_QUALITY, quality])
                self._jpeg_sizes[quality] = len(data)
                if len(data) <= allowance:
                    return "RGB_JPEG", data, True
        enc, data = self.rgb(bgr)
        return enc, data, False


class ByteBudget:
    """A robot's byte budget, as ByteBudget in src/codec/byte_budget.h (the same choices from the
    same bytes): a token bucket counted in frames. Every frame earns ``bytes_per_s / frame_rate``
    bytes, the bucket holds at most ``burst_s`` seconds of budget and starts empty, every frame
    sent spends its bytes (a frame never waits: the bucket may owe), and a full frame's colour is
    the finest of ``jpeg_qualities`` that fits (ImageEncoder.rgb_within). 0 bytes/s: no budget."""
    HEADER_BYTES = 64  # a wire frame's bytes beside its images, as ByteBudget::kHeaderBytes

    def __init__(self, bytes_per_s=0.0, frame_rate=30.0, burst_s=2.0, jpeg_qualities=(95, 90, 85)):
        import math
        bytes_per_s, frame_rate, burst_s = float(bytes_per_s), float(frame_rate), float(burst_s)
        if not (bytes_per_s >= 0 and math.isfinite(bytes_per_s)):
            raise ValueError(f"byte budget {bytes_per_s} B/s must be >= 0 (0: none)")
        if not 0 < frame_rate <= 1000:
            raise ValueError(f"byte budget frame rate {frame_rate} must be in (0, 1000]")
        if not 0 < burst_s <= 1000:
            raise ValueError(f"byte budget burst {burst_s} s must be in (0, 1000]")
        qualities = tuple(int(q) for q in jpeg_qualities)
        if any(not 1 <= q <= 100 for q in qualities) or any(b >= a for a, b in zip(qualities, qualities[1:])):
            raise ValueError("byte budget JPEG qualities must be in 1..100, strictly decreasing (finest first)")
        self.bytes_per_s, self.frame_rate, self.burst_s, self.jpeg_qualities = bytes_per_s, frame_rate, burst_s, qualities
        self._share = bytes_per_s / frame_rate
        self._capacity = max(self._share, bytes_per_s * burst_s)
        self._bucket = 0.0

    @property
    def enabled(self):
        return self.bytes_per_s > 0

    def _filled(self):
        return min(self._capacity, self._bucket + self._share)

    def allowance(self):
        """Bytes the next frame may take: the bucket with the frame's own share (0 when it owes)."""
        room = self._filled()
        return int(room) if room > 0 else 0

    def image_allowance(self, other_image_bytes):
        """What one image may take beside the frame's other image bytes and HEADER_BYTES."""
        return max(0, self.allowance() - other_image_bytes - self.HEADER_BYTES)

    def add(self, nbytes):
        """Every frame sent, in order: its wire message's bytes."""
        self._bucket = self._filled() - float(nbytes)


def encode_depth(depth, codecs):
    """depth: HxW uint16 raw units (camera.depth_factor per metre). Returns (encoding name, bytes)."""
    import cv2
    if not isinstance(depth, np.ndarray) or depth.dtype != np.uint16 or depth.ndim != 2:
        raise TypeError("encode_depth: expected an HxW uint16 depth image")
    if codecs.depth == "raw":
        return "DEPTH_RAW_U16LE", np.ascontiguousarray(depth, dtype="<u2").tobytes()
    if codecs.depth == "png":
        return "DEPTH_PNG16", _imencode(".png", depth, [cv2.IMWRITE_PNG_COMPRESSION, codecs.png_compression])
    return "DEPTH_ZSTD_DELTA", zstd_delta_encode(depth, codecs.zstd_level)


def _predict(ranks, valid):
    """The predictor of depth_codecs.cpp for every pixel at once (it only reads encoder-side ranks)."""
    h, w = ranks.shape
    a = np.zeros_like(ranks)
    b = np.zeros_like(ranks)
    c = np.zeros_like(ranks)
    va = np.zeros_like(valid)
    vb = np.zeros_like(valid)
    vc = np.zeros_like(valid)
    a[:, 1:] = ranks[:, :-1]
    va[:, 1:] = valid[:, :-1]
    b[1:, :] = ranks[:-1, :]
    vb[1:, :] = valid[:-1, :]
    c[1:, 1:] = ranks[:-1, :-1]
    vc[1:, 1:] = valid[:-1, :-1]
    # `last`: the rank of the previous valid pixel in raster order (0 before the first).
    flat_valid = valid.ravel()
    idx = np.where(flat_valid, np.arange(flat_valid.size), -1)
    prev = np.empty_like(idx)
    prev[0] = -1
    prev[1:] = np.maximum.accumulate(idx)[:-1]
    last = np.where(prev >= 0, ranks.ravel()[np.maximum(prev, 0)], 0).reshape(h, w)

    hi = np.maximum(a, b)
    lo = np.minimum(a, b)
    med = np.where(c <= lo, hi, np.where(c >= hi, lo, a + b - c))
    both = va & vb
    pred = np.where(both & vc, med, np.where(both, (a + b) // 2, np.where(va, a, np.where(vb, b, last))))
    return pred


def zstd_delta_encode(depth, level=1):
    import zstandard
    d = np.ascontiguousarray(depth, dtype=np.uint16)
    h, w = d.shape
    valid = d != 0
    table = np.unique(d[valid]).astype(np.uint16)
    lut = np.zeros(65536, dtype=np.int32)
    lut[table] = np.arange(table.size, dtype=np.int32)
    ranks = lut[d]
    residual = (ranks - _predict(ranks, valid))[valid]          # raster order of the valid pixels
    r16 = residual.astype(np.int16)                              # wraps like the C++ int16 cast
    z = (r16.astype(np.uint16) << 1) ^ (r16 >> 15).astype(np.uint16)
    deltas = np.diff(table.astype(np.int32), prepend=0).astype("<u2")
    payload = b"".join([
        np.uint32(table.size).astype("<u4").tobytes(),
        deltas.tobytes(),
        valid.astype(np.uint8).tobytes(),
        (z & 0xFF).astype(np.uint8).tobytes(),
        (z >> 8).astype(np.uint8).tobytes(),
    ])
    return zstandard.ZstdCompressor(level=level, write_content_size=True).compress(payload)
