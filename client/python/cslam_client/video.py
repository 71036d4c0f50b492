"""The lean stream's codecs, byte-identical to src/codec: the H.264 colour stream
(video_codec.{h,cpp}) and subsampled depth (depth_subsample.{h,cpp}).

A robot's light frames carry their colour as packets of one H.264 stream: our 16-byte header
("H4", version 1, key flag, frame index, bitstream length, CRC-32 of header bytes 0..11 and the
bitstream; little-endian) followed by one annex-B access unit. The encoder is the C++ one's
settings, one for one: BGR -> I420 by cv2.cvtColor(COLOR_BGR2YUV_I420), libx264 through PyAV
(python3-av links Debian's libavcodec 59 and x264 core 164, the build the C++ programs use) with
preset/tune/crf, bframes 0, rc-lookahead 0, one thread, keyint, forced-idr, smpte170m / tv range
in the VUI, time base 1/frame_rate and pts = frame index. Same settings, same library, same
input: the same bytes (test_python_codecs.py compares them with the C++ encoder's).

Light frames' depth keeps every S-th pixel of every S-th row (no averaging: no depth is invented
across an edge) and goes out losslessly with the depth codec.
"""
import struct
import zlib
from dataclasses import dataclass
from fractions import Fraction

import numpy as np

HEADER_BYTES = 16
MAX_IMAGE_SIDE = 8192       # kMaxImageSide, src/codec/image_codec.h
MAX_DEPTH_SUBSAMPLE = 16    # kMaxDepthSubsample, src/codec/depth_subsample.h

_MAGIC, _VERSION, _FLAG_KEY = b"H4", 1, 1
_PRESETS = ("ultrafast", "superfast", "veryfast", "faster", "fast", "medium", "slow", "slower", "veryslow",
            "placebo")
_TUNES = ("zerolatency", "film", "animation", "grain", "stillimage", "psnr", "ssim", "fastdecode")


@dataclass
class H264Options:
    """As video::H264Options (src/codec/video_codec.h); the defaults are the C++ defaults."""
    crf: int = 17                   # 0..51, lower = better and larger
    preset: str = "veryfast"        # x264 preset, ultrafast .. placebo
    tune: str = "zerolatency,psnr"  # must include zerolatency: one packet out per frame in, at once
    key_interval: int = 300         # frames between automatic IDR frames, 1..100000
    frame_rate: int = 30            # 1..1000; x264's rate control weighs frames by duration

    def validate(self):
        if not 0 <= self.crf <= 51:
            raise ValueError(f"h264 crf {self.crf} out of range 0..51")
        if self.preset not in _PRESETS:
            raise ValueError(f"unknown h264 preset '{self.preset}' (ultrafast .. placebo)")
        items = self.tune.split(",")
        for item in items:
            if item not in _TUNES:
                raise ValueError(f"unknown h264 tune '{item}' in '{self.tune}'")
        if "zerolatency" not in items:
            raise ValueError(f"h264 tune '{self.tune}' must include zerolatency (one packet per frame)")
        if not 1 <= self.key_interval <= 100000:
            raise ValueError(f"h264 key interval {self.key_interval} out of range 1..100000")
        if not 1 <= self.frame_rate <= 1000:
            raise ValueError(f"h264 frame rate {self.frame_rate} out of range 1..1000")


def light_colour_stream() -> H264Options:
    """The lean stream's default colour stream, as video::light_colour_stream()
    (src/codec/video_codec.h, client::SenderConfig's default): CRF 26, preset superfast."""
    return H264Options(crf=26, preset="superfast")


def intra_image(crf) -> H264Options:
    """Full frames' colour as standalone key pictures, as video::intra_image() (src/codec/video_codec.h):
    one encoder per stream (codecs.ImageEncoder), preset superfast, key interval 1."""
    o = H264Options(crf=crf, preset="superfast", key_interval=1)
    o.validate()
    return o


@dataclass
class PacketHeader:
    key: bool
    index: int
    length: int   # bitstream bytes after the header
    crc: int


def parse_header(packet):
    """The header of a packet (no CRC check). ValueError if it is not our header."""
    if len(packet) < HEADER_BYTES or packet[:2] != _MAGIC or packet[2] != _VERSION:
        raise ValueError("not an H.264 packet of the cslam colour stream (magic 'H4', version 1)")
    index, length, crc = struct.unpack_from("<III", packet, 4)
    return PacketHeader(bool(packet[3] & _FLAG_KEY), index, length, crc)


def is_key_packet(packet):
    """True if the packet has our header with the key flag set (reads only the header)."""
    return len(packet) >= HEADER_BYTES and packet[:2] == _MAGIC and packet[2] == _VERSION and bool(
        packet[3] & _FLAG_KEY)


def _check_size(width, height):
    if not (2 <= width <= MAX_IMAGE_SIDE and 2 <= height <= MAX_IMAGE_SIDE) or width % 2 or height % 2:
        raise ValueError(f"H.264 image size {width}x{height}: sides must be even, 2..{MAX_IMAGE_SIDE}")


def _x264_context(width, height, o):
    """A libx264 context set up exactly as H264Encoder's constructor does."""
    import av
    try:
        ctx = av.CodecContext.create("libx264", "w")
    except Exception as e:  # noqa: BLE001 - PyAV raises its own error types
        raise RuntimeError(f"libavcodec has no libx264 encoder ({e})") from None
    ctx.width, ctx.height, ctx.pix_fmt = width, height, "yuv420p"
    ctx.time_base = Fraction(1, o.frame_rate)
    ctx.framerate = Fraction(o.frame_rate, 1)
    ctx.gop_size = o.key_interval
    # PyAV defaults to automatic slice threading; libavcodec's own default (what C++ gets) is
    # frame+slice, with one thread: deterministic output.
    ctx.thread_type = "AUTO"
    ctx.thread_count = 1
    # Generic AVCodecContext options PyAV does not expose, by their libavcodec option names, and
    # libx264's private ones; avcodec_open2 applies them all.
    ctx.options = {
        "bf": "0",                    # max_b_frames
        "color_range": "tv",          # cv2's I420 is BT.601 limited range
        "colorspace": "smpte170m",
        "preset": o.preset,
        "tune": o.tune,
        "crf": str(o.crf),
        "rc-lookahead": "0",
        "forced-idr": "1",
    }
    try:
        ctx.open()
    except Exception as e:  # noqa: BLE001
        raise RuntimeError(f"libx264: cannot open the encoder: {e}") from None
    if ctx.options:  # PyAV leaves the options avcodec_open2 did not take
        raise RuntimeError(f"libx264 ignored option '{next(iter(ctx.options))}'")
    return ctx


class H264Encoder:
    """One robot's colour stream. Every frame gives exactly one packet, at once; the first packet
    and every ``force_key`` packet are key (IDR) frames. A new encoder starts again at index 0."""

    def __init__(self, width, height, options=None):
        _check_size(width, height)
        self.options = options or H264Options()
        self.options.validate()
        self.width, self.height = width, height
        self._ctx = _x264_context(width, height, self.options)
        self._time_base = Fraction(1, self.options.frame_rate)
        self.next_index = 0   # index the next packet will carry

    def encode(self, bgr, force_key=False):
        """bgr: HxWx3 uint8 (OpenCV order) of exactly the encoder's size. Returns the packet."""
        import av
        import cv2
        self._check_image(bgr)
        i420 = cv2.cvtColor(np.ascontiguousarray(bgr), cv2.COLOR_BGR2YUV_I420)  # Y, then U, V (w/2 x h/2)
        frame = av.VideoFrame.from_ndarray(i420, format="yuv420p")
        frame.pts = self.next_index
        frame.time_base = self._time_base
        frame.pict_type = "I" if force_key else "NONE"   # with forced-idr: an IDR frame
        packets = self._ctx.encode(frame)
        if len(packets) != 1:  # zerolatency: never none, never more
            raise RuntimeError(f"libx264 returned {len(packets)} packets for frame {self.next_index}, expected 1")
        packet = self._packet(bytes(packets[0]), packets[0].is_keyframe)
        self.next_index += 1
        return packet

    def _check_image(self, bgr):
        if not isinstance(bgr, np.ndarray) or bgr.dtype != np.uint8 or bgr.ndim != 3 or bgr.shape[2] != 3:
            got = f"{bgr.dtype} array of shape {bgr.shape}" if isinstance(bgr, np.ndarray) else type(bgr).__name__
            raise TypeError(f"H264Encoder.encode: expected an HxWx3 uint8 BGR image, got {got}")
        if bgr.shape[:2] != (self.height, self.width):
            raise ValueError(f"H264Encoder.encode: image is {bgr.shape[1]}x{bgr.shape[0]}, "
                             f"the stream is {self.width}x{self.height}")

    def _packet(self, bitstream, key):
        flags = _FLAG_KEY if key else 0
        header = _MAGIC + bytes([_VERSION, flags]) + struct.pack("<II", self.next_index, len(bitstream))
        crc = zlib.crc32(bitstream, zlib.crc32(header))
        return header + struct.pack("<I", crc) + bitstream


# -- subsampled depth ---------------------------------------------------------------------------
def _check_subsample(subsample):
    if not isinstance(subsample, (int, np.integer)) or not 1 <= subsample <= MAX_DEPTH_SUBSAMPLE:
        raise ValueError(f"depth subsample {subsample} is not 1..{MAX_DEPTH_SUBSAMPLE}")


def subsampled_depth_size(width, height, subsample):
    """(width, height) of the subsampled image: ceil(width/S) x ceil(height/S)."""
    _check_subsample(subsample)
    return (width + subsample - 1) // subsample, (height + subsample - 1) // subsample


def subsample_depth(depth, subsample):
    """Every S-th pixel of every S-th row of an HxW uint16 depth image (a new, contiguous array)."""
    if not isinstance(depth, np.ndarray) or depth.dtype != np.uint16 or depth.ndim != 2:
        raise TypeError("subsample_depth: depth must be an HxW uint16 image")
    _check_subsample(subsample)
    return np.ascontiguousarray(depth[::subsample, ::subsample])


# -- the lean stream's schedule -----------------------------------------------------------------
class LeanStream:
    """Which frames of a lean stream are full and which light, and the robot's colour stream, as
    client/frame_sender.cpp decides them (frame/full_frame_clock.h). The first frame is full
    (full depth with standalone colour), and so is the next one after an ack asks for depth
    (want_depth: a keyframe is due); otherwise the depth_every-th frame after the last full one.
    The frames between are light: colour as the next packet of one H.264 stream, depth
    subsampled by light_depth_subsample (0: none). The first colour packet is a key packet, and
    so is the first after a (re)connect or a gap the server reported.

    Call next_is_full() and then encode_light() or full_sent() for a frame that leaves right
    away with sequence number `seq`: a colour packet that never left would break the stream."""

    def __init__(self, width, height, depth_every, light_depth_subsample=4, colour=None):
        if not isinstance(depth_every, (int, np.integer)) or depth_every < 2:
            raise ValueError(f"lean stream: depth_every {depth_every} must be >= 2 (1: every frame full)")
        if light_depth_subsample != 0 and not 2 <= light_depth_subsample <= MAX_DEPTH_SUBSAMPLE:
            raise ValueError(f"lean stream: light_depth_subsample {light_depth_subsample} must be 0 (no depth) "
                             f"or 2..{MAX_DEPTH_SUBSAMPLE}")
        self.depth_every = int(depth_every)
        self.light_depth_subsample = int(light_depth_subsample)
        self.encoder = H264Encoder(width, height, colour or H264Options())
        self._since_full = 0
        self._depth_wanted = True   # the first frame carries depth
        self._key_wanted = True     # the first colour packet is a key packet
        self._last_key_seq = 0      # a gap reported before it is healed by it
        self._last_full_seq = 0     # a depth request before it is met by it
        self._request_seq = 0       # the frame whose ack asked for the pending full depth (0: none)
        # Which full frames a byte budget is for, as KeyframeHint (src/codec/keyframe_hint.h).
        self._hint_heard = False    # an ack carried a keyframe hint
        self._hint_due_seq = 0      # the frame the latest hint names; 0: used up
        self._hint_met_at = 0       # the last full frame that met a hint

    def next_is_full(self):
        if not self._depth_wanted:
            self._since_full += 1
        return self._depth_wanted or self._since_full >= self.depth_every

    def expects_keyframe(self, seq):
        """Whether the full frame about to be sent as `seq` may spend a byte budget: it answers a
        depth request, or the latest ack's keyframe hint names it or an earlier frame, or no ack
        has carried a hint yet. Call it before full_sent(seq)."""
        return self._depth_wanted or not self._hint_heard or 0 < self._hint_due_seq <= seq

    def on_keyframe_hint(self, acked_seq, due_in):
        """An ack said tracking expects its next keyframe `due_in` frames after `acked_seq` (0: no hint)."""
        if due_in <= 0 or acked_seq < self._hint_met_at:  # no hint, or sent before the full frame that met one
            return
        self._hint_heard = True
        self._hint_due_seq = acked_seq + due_in

    def full_sent(self, seq):
        """Frames from the asking frame to this one if it answers a depth request (1: the next
        frame), else None."""
        lag = seq - self._request_seq if self._request_seq > 0 else None
        if self.expects_keyframe(seq):  # the hint is used up
            self._hint_met_at = seq
            if self._hint_heard:
                self._hint_due_seq = 0
        self._request_seq = 0
        self._since_full = 0
        self._depth_wanted = False
        self._last_full_seq = seq
        return lag

    def encode_light(self, bgr, depth, seq):
        """(colour packet, key?, subsampled depth or None) of the light frame sent as `seq`."""
        coarse = None
        if self.light_depth_subsample >= 2 and depth is not None:
            coarse = subsample_depth(depth, self.light_depth_subsample)
        key = self._key_wanted
        packet = self.encoder.encode(bgr, force_key=key)
        self._key_wanted = False
        if key:
            self._last_key_seq = seq
        return packet, key, coarse

    def on_connect(self):
        """A restarted server has no colour stream of ours, and frames in flight may be lost."""
        self._key_wanted = True

    def on_want_depth(self, acked_seq):
        """An ack asked for depth; True if that is a new request (not met by a full frame since)."""
        if acked_seq <= self._last_full_seq:
            return False
        if not self._depth_wanted:
            self._request_seq = acked_seq
        self._depth_wanted = True
        return True

    def on_stream_gap(self, refused_seq):
        """The server's colour stream lacks a packet's reference; key packet next unless one went since."""
        if refused_seq > self._last_key_seq:
            self._key_wanted = True
