"""What the server says back about a robot's frames: each Ack as an AckInfo (tracking state,
pose in the group's frame, latency), and the sender's counters (SenderStats)."""
from dataclasses import dataclass, field
from typing import Dict, Optional

from .wire import pb


@dataclass
class AckInfo:
    seq: int
    credits: int
    received_at: float          # time.monotonic() when the ack arrived
    fields: Dict[str, object]   # every field of the Ack message that is set
    # Pose feedback (protocol version 2; None from a server without it):
    state: Optional[str] = None           # "TRACK_OK", "TRACK_LOST", "TRACK_SKIPPED", ...
    T_world_cam: Optional[tuple] = None   # (tx, ty, tz, qx, qy, qz, qw), camera-to-world, TRACK_OK only
    group: Optional[int] = None           # fused group whose frame the pose is in
    map_epoch: Optional[int] = None       # increases when a fusion/loop may have moved earlier poses
    latency_s: Optional[float] = None     # this frame's send to its ack, seconds

    def pose_matrix(self):
        """T_world_cam as a 4x4 numpy array (None without a pose)."""
        if self.T_world_cam is None:
            return None
        import numpy as np
        tx, ty, tz, x, y, z, w = self.T_world_cam
        T = np.eye(4)
        T[:3, :3] = [[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]]
        T[:3, 3] = [tx, ty, tz]
        return T


def ack_info(a, received_at, sent_at):
    info = AckInfo(a.seq, a.credits, received_at, {f.name: v for f, v in a.ListFields()})
    names = a.DESCRIPTOR.fields_by_name
    if "state" in names:  # the schema has pose feedback
        info.state = pb.TrackState.Name(a.state) if a.state in pb.TrackState.values() else str(a.state)
        if info.state == "TRACK_OK" and a.HasField("T_world_cam"):
            p = a.T_world_cam
            info.T_world_cam = (p.tx, p.ty, p.tz, p.qx, p.qy, p.qz, p.qw)
        info.group = a.group
        info.map_epoch = a.map_epoch
    if sent_at is not None:
        info.latency_s = received_at - sent_at
    return info


@dataclass
class SenderStats:
    frames_sent: int = 0
    bytes_sent: int = 0
    acks: int = 0
    heartbeats: int = 0
    reconnects: int = 0
    dropped_no_credit: int = 0   # live mode: frames replaced by a newer one before a credit came
    frames_refused: int = 0      # errors about a sent frame (seq != 0): frames the server did not take
    frames_resent: int = 0       # sent again after a resumed session said the server lacked them
    frames_lost: int = 0         # the server lacked them and they were no longer kept (or live)
    errors: Dict[str, int] = field(default_factory=dict)  # server error code name -> count
    # Lean stream: light frames sent (and their wire bytes), key packets of the colour stream,
    # acks asking for full depth, and stream gaps the server reported (each healed by a key packet).
    frames_light: int = 0
    bytes_light: int = 0
    colour_key_packets: int = 0
    depth_requests: int = 0
    # Requests answered by a full frame, and frames from the asking frame to that answer (1: the
    # next frame), as the C++ sender counts them.
    depth_requests_met: int = 0
    depth_request_lag_sum: int = 0
    depth_request_lag_max: int = 0
    stream_gaps: int = 0
    frames_finer: int = 0  # full frames whose colour the byte budget made finer than the codecs' own
