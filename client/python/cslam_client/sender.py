"""FrameSender: the cslam wire protocol from Python, as client/frame_sender.cpp does it.

  sender = FrameSender("tcp://127.0.0.1:5555", client_id=1, camera=camera.preset("tum1"))
  sender.connect()                      # hello -> welcome (credits)
  sender.send(bgr, depth, timestamp)    # encodes, waits for a credit, sends
  sender.goodbye()                      # waits for the last acks, says goodbye

Flow control: at most `window` frames are unacknowledged. In the default (lossless) mode send()
blocks, sending heartbeats, until the server hands a credit back. With ``live=True`` send()
never blocks: without a credit it keeps only the newest frame (older ones are dropped and
counted in stats.dropped_no_credit) and sends it as soon as a credit comes; call poll() from an
idle loop. A silent server triggers a reconnect that resumes the session (same client id,
sequence numbers continue). Lossless frames already sent are kept (``resend_buffer_bytes``,
default 128 MB): when a resumed welcome's last_seq is behind (the server restarted from an older
snapshot, or frames were in flight), the kept frames it lacks are sent again first, with their
own sequence numbers; those no longer kept are counted in stats.frames_lost.

Every Ack is passed to ``on_ack(AckInfo)`` (callback style), kept as ``last_ack`` and queued for
``take_acks()`` (poll style, the newest 1024). With pose feedback (protocol version 2) an AckInfo
carries the frame's tracking ``state``, ``T_world_cam`` (only when tracked: never a stale pose),
``group``, ``map_epoch`` and the send-to-ack ``latency_s``; every set field is in ``fields``.
Live frames are marked ``live`` so the server may skip a stale one.
``curve=CurveKeys(...)`` turns on ZeroMQ CURVE encryption and authentication.

Lean stream (``depth_every=N``, as cslam-client --depth-every N): the N-th frame after the last
full one is full (colour with ``codecs``, full depth), and so is the next one after an ack asks
for depth; the frames between are light: colour as packets of one H.264 stream (video.py, the
C++ encoder's bytes), depth every ``light_depth_subsample``-th pixel of every such row. A light
frame is encoded only when it leaves (in live mode too). ERROR_STREAM_GAP and a reconnect make the
next colour packet a key packet.
"""
import collections
import logging
import time
from typing import Callable, Optional

import zmq

from . import errors, video
from .codecs import RGB_H264, ByteBudget, Codecs, ImageEncoder, auto_rgb_codec, encode_depth
from .feedback import AckInfo, SenderStats, ack_info
from .keys import CurveKeys
from .wire import pb

# A depth image further than this from its colour image (s) is not one frame's pair (as the server).
MAX_DEPTH_TIME_OFFSET = 0.1

log = logging.getLogger("cslam_client")


class FrameSender:
    def __init__(self, server, client_id, camera, name="", codecs=None, reply_timeout=10.0, heartbeat_interval=1.0,
                 max_reconnects=3, live=False, strict=False, curve: Optional[CurveKeys] = None,
                 on_ack: Optional[Callable[[AckInfo], None]] = None, context=None, protocol_version=None,
                 resend_buffer_bytes=128 << 20, depth_every=1, light_depth_subsample=4,
                 colour_stream: Optional[video.H264Options] = None, byte_budget: Optional[ByteBudget] = None):
        if not 0 <= int(client_id) <= 65535:
            raise ValueError("client id must be in 0..65535")
        self.server = server
        self.client_id = int(client_id)
        self.camera = camera
        self.name = name or f"client{client_id}"
        if not isinstance(depth_every, int) or depth_every < 1:
            raise ValueError(f"depth_every {depth_every} must be >= 1 (1: every frame full)")
        self.codecs = codecs or Codecs(rgb=auto_rgb_codec(depth_every > 1))
        self._images = ImageEncoder(self.codecs)  # full frames' images (validates the codecs)
        # Byte budget (cslam-client --byte-budget): the full frames' colour is the finest JPEG
        # that keeps the stream within it, else the codecs' own; in a lean stream only on the full
        # frames the acks expect to become keyframes (LeanStream.expects_keyframe). None: no budget.
        self.budget = byte_budget or ByteBudget()
        camera.validate()
        # Lean stream: light frames between full ones. The default colour stream is coarser than
        # H264Options' (light frames are only tracked): video.light_colour_stream().
        self.lean = None
        if depth_every > 1:
            self.lean = video.LeanStream(camera.width, camera.height, depth_every, light_depth_subsample,
                                         colour_stream or video.light_colour_stream())
        self.reply_timeout = float(reply_timeout)
        self.heartbeat_interval = float(heartbeat_interval)
        self.max_reconnects = int(max_reconnects)
        self.live = live
        self.strict = strict
        self.curve = curve
        self.on_ack = on_ack
        # The newest version the generated schema knows, unless a test asks for another.
        self.protocol_version = protocol_version or max(pb.ProtocolVersion.values())
        # Lossless frames already sent, kept (newest, up to this many bytes) for a server that
        # resumes behind them (restarted from an older snapshot, or frames lost in flight).
        self.resend_buffer_bytes = int(resend_buffer_bytes)
        self._kept = collections.deque()    # (seq, wire message)
        self._kept_bytes = 0
        self._resend = collections.deque()  # queued after a resumed welcome, oldest first
        self.last_ack: Optional[AckInfo] = None
        self._acks = collections.deque(maxlen=1024)
        self._sent_at = collections.OrderedDict()  # seq -> send time, for the pose latency
        self._live_field = "live" in pb.RgbdFrame.DESCRIPTOR.fields_by_name  # protocol version 2
        self.stats = SenderStats()
        self.credits = 0
        self.in_flight = 0
        self.window = 0
        self.last_seq = 0
        self.welcome = None
        self._context = context or zmq.Context.instance()
        self._socket = None
        self._welcomed = False
        self._pending = None          # live mode: builds the newest frame once a credit comes (encoded then)
        self._hello_busy = False      # the server asked to repeat the hello a little later
        self._rejected = []           # strict mode: frame errors to raise at the next call
        now = time.monotonic()
        self._last_reply = now
        self._last_heartbeat = now

    # -- connection ------------------------------------------------------------------------
    def __enter__(self):
        self.connect()
        return self

    def __exit__(self, exc_type, exc, tb):
        if exc_type is None:
            self.goodbye()
        else:
            self.close()

    def _open_socket(self):
        self.close()
        s = self._context.socket(zmq.DEALER)
        s.setsockopt(zmq.LINGER, 2000)  # let a goodbye leave before close
        s.setsockopt(zmq.SNDTIMEO, int(self.reply_timeout * 1000))
        if self.curve:
            self.curve.apply(s)
        s.connect(self.server)
        self._socket = s

    def close(self):
        if self._socket is not None:
            self._socket.close()
            self._socket = None

    def connect(self):
        """Hello -> welcome. Raises ConnectionFailed on timeout, a ServerError on refusal."""
        self._open_socket()
        self._welcomed = False
        if self.lean:
            self.lean.on_connect()
        hello = pb.ClientMessage()
        hello.hello.version = self.protocol_version
        hello.hello.client_id = self.client_id
        hello.hello.name = self.name
        hello.hello.camera.CopyFrom(self.camera.to_wire(pb))
        self._send_message(hello)
        deadline = time.monotonic() + self.reply_timeout
        while not self._welcomed:
            left = deadline - time.monotonic()
            if left <= 0:
                raise errors.ConnectionFailed(
                    f"client {self.client_id}: no welcome from {self.server} within {self.reply_timeout} s")
            self._handle_reply(left)
            if self._hello_busy and not self._welcomed:
                self._hello_busy = False
                self._handle_reply(min(left, 0.5))
                self._send_message(hello)

    def reconnect(self):
        attempt = 0
        while True:
            attempt += 1
            self.stats.reconnects += 1
            log.warning("client %d: reconnecting to %s (attempt %d)", self.client_id, self.server, attempt)
            try:
                self.connect()
                return
            except errors.ConnectionFailed:
                if attempt >= self.max_reconnects:
                    raise

    # -- frames ----------------------------------------------------------------------------
    def encode(self, bgr, depth, timestamp, depth_time_offset=0.0):
        """An encoded cslam.wire.RgbdFrame (id and seq are stamped when it is sent). `timestamp` is
        the colour image's capture time; `depth_time_offset` the depth image's, relative to it (s).
        Always a full frame (with depth), also in a lean stream. With h264-intra colour the pictures
        come from one encoder: encode the frames in sending order."""
        return self._encode_full(bgr, depth, timestamp, depth_time_offset, True)

    def _encode_full(self, bgr, depth, timestamp, depth_time_offset, spend):
        """encode(), with the byte budget (if any) only when `spend`."""
        self._check_images(bgr, depth, depth_time_offset)
        h, w = depth.shape[:2]
        frame = pb.RgbdFrame(timestamp=float(timestamp), depth_time_offset=float(depth_time_offset))
        depth_enc, depth_data = self._images.depth(depth)
        if self.budget.enabled and spend:
            enc, data, finer = self._images.rgb_within(bgr, self.budget.image_allowance(len(depth_data)),
                                                       self.budget.jpeg_qualities)
            self.stats.frames_finer += int(finer)
        else:
            enc, data = self._images.rgb(bgr)
        frame.rgb.width, frame.rgb.height, frame.rgb.encoding, frame.rgb.data = w, h, pb.Encoding.Value(enc), data
        enc, data = depth_enc, depth_data
        frame.depth.width, frame.depth.height, frame.depth.encoding, frame.depth.data = w, h, pb.Encoding.Value(enc), data
        return frame

    def _check_images(self, bgr, depth, depth_time_offset):
        h, w = depth.shape[:2]
        if bgr.shape[:2] != (h, w) or (w, h) != (self.camera.width, self.camera.height):
            raise ValueError(f"images are {bgr.shape[1]}x{bgr.shape[0]} / {w}x{h}, "
                             f"camera is {self.camera.width}x{self.camera.height}")
        if not abs(depth_time_offset) <= MAX_DEPTH_TIME_OFFSET:
            raise ValueError(f"depth image {depth_time_offset} s from the colour image "
                             f"(at most {MAX_DEPTH_TIME_OFFSET} s)")

    def encode_next(self, bgr, depth, timestamp, depth_time_offset=0.0):
        """The next frame of the stream: encode()'s full frame or, in a lean stream, a light one.
        Only for a frame sent right away (stamped with the next seq): its colour packet is part of
        the stream."""
        seq = self.last_seq + 1
        if self.lean is None or self.lean.next_is_full():
            spend = self.lean is None or self.lean.expects_keyframe(seq)
            frame = self._encode_full(bgr, depth, timestamp, depth_time_offset, spend)
            lag = self.lean.full_sent(seq) if self.lean else None
            if lag is not None:
                self.stats.depth_requests_met += 1
                self.stats.depth_request_lag_sum += lag
                self.stats.depth_request_lag_max = max(self.stats.depth_request_lag_max, lag)
            return frame
        self._check_images(bgr, depth, depth_time_offset)
        packet, key, coarse = self.lean.encode_light(bgr, depth, seq)
        h, w = bgr.shape[:2]
        frame = pb.RgbdFrame(timestamp=float(timestamp))
        r = frame.rgb
        r.width, r.height, r.encoding, r.data = w, h, pb.Encoding.Value(RGB_H264), packet
        if coarse is not None:
            enc, data = encode_depth(coarse, self.codecs)
            d = frame.depth
            d.width, d.height, d.encoding, d.data = coarse.shape[1], coarse.shape[0], pb.Encoding.Value(enc), data
            frame.depth_subsample = self.lean.light_depth_subsample
            frame.depth_time_offset = float(depth_time_offset)
        self.stats.frames_light += 1
        self.stats.colour_key_packets += int(key)
        return frame

    def send(self, bgr, depth, timestamp, depth_time_offset=0.0):
        """Encodes and sends one frame; returns the message size (0 when live mode kept it pending).
        A lean stream encodes the frame only when it can leave."""
        if self.lean is None:
            return self.send_encoded(self.encode(bgr, depth, timestamp, depth_time_offset))
        self._check_images(bgr, depth, depth_time_offset)
        if self.live:  # kept until a credit comes: the caller may reuse its buffers meanwhile
            bgr, depth = bgr.copy(), depth.copy()
        return self._submit(lambda: self.encode_next(bgr, depth, timestamp, depth_time_offset))

    def send_encoded(self, frame):
        return self._submit(lambda: frame)

    def _submit(self, make_frame):
        """Sends make_frame() when a credit is free (lossless: waits; live: keeps only the newest)."""
        if self._socket is None:
            raise RuntimeError("FrameSender: send before connect()")
        self._raise_rejected()
        if self.live:
            self.poll(0)
            if self.credits == 0:
                if self._pending is not None:
                    self.stats.dropped_no_credit += 1
                self._pending = make_frame
                return 0
            self._pending = None
        else:
            # Frames the server lacks go first (a reconnect while waiting may queue some).
            while True:
                self._send_resends(wait=True)
                self._wait_for_credit()
                if not self._resend:
                    break
        return self._send_frame(make_frame())

    def poll(self, timeout=0.0):
        """Handles replies for up to `timeout` s (heartbeats if due); live mode: sends the pending
        frame when a credit has come. Returns True if a reply arrived."""
        got = False
        deadline = time.monotonic() + timeout
        while True:
            self._heartbeat_if_due()
            got |= self._handle_reply(max(0.0, deadline - time.monotonic()))
            if self._pending is not None and self.credits > 0:
                make_frame, self._pending = self._pending, None
                self._send_frame(make_frame())
            if time.monotonic() >= deadline:
                break
        if time.monotonic() - self._last_reply > self.reply_timeout and (self.in_flight or self._pending):
            self.reconnect()
        self._raise_rejected()
        return got

    def take_acks(self):
        """The acks received since the last call (oldest first; at most the newest 1024)."""
        out = list(self._acks)
        self._acks.clear()
        return out

    def _send_frame(self, frame):
        self.last_seq += 1
        frame.client_id = self.client_id
        frame.seq = self.last_seq
        if self.live and self._live_field:
            frame.live = True  # the server may skip it for a newer one
        message = pb.ClientMessage()
        message.frame.CopyFrom(frame)
        body = message.SerializeToString()
        self._send_bytes(body)
        if not (self.live and self._live_field) and self.resend_buffer_bytes > 0:
            self._kept.append((frame.seq, body))
            self._kept_bytes += len(body)
            while self._kept_bytes > self.resend_buffer_bytes and self._kept:
                self._kept_bytes -= len(self._kept.popleft()[1])
        self._sent_at[frame.seq] = time.monotonic()
        while len(self._sent_at) > 4096:
            self._sent_at.popitem(last=False)
        self.credits -= 1
        self.in_flight += 1
        self.stats.frames_sent += 1
        self.stats.bytes_sent += len(body)
        self.budget.add(len(body))
        if frame.rgb.encoding == pb.Encoding.Value(RGB_H264):
            self.stats.bytes_light += len(body)
        return len(body)

    def _plan_resend(self, server_last_seq):
        self._resend.clear()
        if server_last_seq >= self.last_seq:
            return
        self._resend.extend((seq, body) for seq, body in self._kept if seq > server_last_seq)
        lost = self.last_seq - server_last_seq - len(self._resend)
        if lost > 0:
            self.stats.frames_lost += lost
            log.warning("client %d: the server lacks frames %d..%d; %d of them are no longer kept and are lost",
                        self.client_id, server_last_seq + 1, self.last_seq, lost)
        if self._resend:
            log.warning("client %d: the server lacks frames %d..%d: sending %d kept frame(s) again", self.client_id,
                        server_last_seq + 1, self.last_seq, len(self._resend))

    def _send_resends(self, wait):
        while self._resend:
            if self.credits == 0:
                if not wait:
                    return
                self._wait_for_credit()  # may reconnect, which plans the re-sends again
                continue
            seq, body = self._resend.popleft()
            self._send_bytes(body)
            self._sent_at[seq] = time.monotonic()
            self.credits -= 1
            self.in_flight += 1
            self.stats.frames_resent += 1

    def _wait_for_credit(self):
        while self.credits == 0:
            if time.monotonic() - self._last_reply > self.reply_timeout:
                self.reconnect()
                continue
            self._heartbeat_if_due()
            self._handle_reply(self.heartbeat_interval)

    def keep_alive(self, timeout):
        """Handles replies for `timeout` s, heartbeating, for a robot that is idle a while."""
        self.poll(timeout)

    def goodbye(self, timeout=30.0):
        """Waits (up to timeout s) for every sent frame's ack, then says goodbye. False if some
        acks did not come (goodbye is sent anyway)."""
        if self._socket is None:
            return False
        deadline = time.monotonic() + timeout
        while (self.in_flight > 0 or self._pending is not None or self._resend) and time.monotonic() < deadline:
            self._send_resends(wait=False)
            self.poll(min(self.heartbeat_interval, max(0.0, deadline - time.monotonic())))
        all_acked = self.in_flight == 0 and self._pending is None and not self._resend
        if not all_acked:
            log.warning("client %d: %d frame(s) not acknowledged before goodbye", self.client_id, self.in_flight)
        bye = pb.ClientMessage()
        bye.goodbye.client_id = self.client_id
        bye.goodbye.frames_sent = self.stats.frames_sent
        self._send_message(bye)
        self.close()  # linger delivers the goodbye
        return all_acked

    # -- wire ------------------------------------------------------------------------------
    def _send_message(self, message):
        self._send_bytes(message.SerializeToString())

    def _send_bytes(self, body):
        try:
            self._socket.send(body)
        except zmq.Again:
            raise errors.ConnectionFailed(f"client {self.client_id}: send timed out") from None

    def _heartbeat_if_due(self):
        now = time.monotonic()
        if self._socket is not None and now - self._last_heartbeat >= self.heartbeat_interval:
            hb = pb.ClientMessage()
            hb.heartbeat.client_id = self.client_id
            self._send_message(hb)
            self.stats.heartbeats += 1
            self._last_heartbeat = now

    def _handle_reply(self, timeout):
        """Receives and handles one reply if one arrives within `timeout` s."""
        if not self._socket.poll(int(timeout * 1000), zmq.POLLIN):
            return False
        try:
            body = self._socket.recv(zmq.NOBLOCK)
        except zmq.Again:
            return False
        self._last_reply = time.monotonic()
        m = pb.ServerMessage()
        try:
            m.ParseFromString(body)
        except Exception:  # noqa: BLE001 - protobuf's DecodeError
            raise errors.CslamError(f"not a cslam ServerMessage from {self.server} ({len(body)} bytes)") from None
        kind = m.WhichOneof("body")
        if kind == "welcome":
            w = m.welcome
            self.welcome = w
            self.window = w.window
            self.credits = w.credits
            self.in_flight = w.window - w.credits if w.window >= w.credits else 0
            if w.resumed:
                self._plan_resend(w.last_seq)
            self.last_seq = max(self.last_seq, w.last_seq)
            self._welcomed = True
            log.info("client %d: %s session at %s, window %d, %d credits, last seq %d", self.client_id,
                     "resumed" if w.resumed else "new", self.server, w.window, w.credits, w.last_seq)
        elif kind == "ack":
            a = m.ack
            self.credits += a.credits
            if self.in_flight > 0:
                self.in_flight -= 1
            self.stats.acks += 1
            info = ack_info(a, self._last_reply, self._sent_at.pop(a.seq, None))
            # The acks of the frames in flight may all ask; a full frame sent since meets them.
            if self.lean and info.fields.get("want_depth") and self.lean.on_want_depth(a.seq):
                self.stats.depth_requests += 1
            if self.lean:
                self.lean.on_keyframe_hint(a.seq, info.fields.get("keyframe_due_in", 0))
            self.last_ack = info
            self._acks.append(info)
            if self.on_ack:
                self.on_ack(info)
        elif kind == "error":
            e = m.error
            err = errors.from_wire(e, pb)
            self.stats.errors[err.code_name] = self.stats.errors.get(err.code_name, 0) + 1
            self.credits += e.credits
            # A frame that reached a server which no longer knows this session is not refused: the
            # reconnect below resumes, and the frame goes again if the server lacks it.
            unregistered = err.code_name == "ERROR_NOT_REGISTERED" and self._welcomed
            if e.seq != 0:
                if not unregistered:
                    self.stats.frames_refused += 1
                if self.in_flight > 0:
                    self.in_flight -= 1
            log.warning("client %d: server error %s for seq %d: %s", self.client_id, err.code_name, e.seq, e.message)
            if err.code_name == "ERROR_STREAM_GAP":  # the server's colour stream lost its reference
                self.stats.stream_gaps += 1
                if self.lean:
                    self.lean.on_stream_gap(e.seq)
            fatal = (errors.ProtocolVersionError, errors.HelloRejected, errors.ServerShuttingDown, errors.TooManyClients)
            if isinstance(err, fatal) or (isinstance(err, errors.NotAuthorized) and e.seq == 0):
                raise err  # the session cannot go on (as client/frame_sender.cpp)
            if isinstance(err, errors.SessionBusy) and not self._welcomed:
                self._hello_busy = True  # our previous connection has not timed out: connect() asks again
            elif err.code_name == "ERROR_NOT_REGISTERED" and self._welcomed:
                self.reconnect()
            elif self.strict and e.seq != 0:
                self._rejected.append(err)
        return True

    def _raise_rejected(self):
        if self._rejected:
            err = self._rejected.pop(0)
            raise err
