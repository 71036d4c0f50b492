"""cslam_client: stream RGB-D frames from a Python robot program to cslam-server.

Pure Python on Debian's python3-zmq, python3-protobuf, python3-opencv, python3-numpy,
python3-zstandard and (for the lean stream's H.264 colour, video.py) python3-av; the protobuf
module is generated from proto/cslam.proto at build time.
See README.md ("Python client") for an example robot loop.
"""
from . import camera, dataset, video
from .camera import Camera
from .codecs import ByteBudget, Codecs, auto_rgb_codec
from .errors import (ConnectionFailed, CslamError, FrameRejected, HelloRejected, NotAuthorized, ProtocolVersionError,
                     ServerError, ServerShuttingDown, SessionBusy, TooManyClients)
from .progress import Progress
from .sender import AckInfo, CurveKeys, FrameSender, SenderStats
from .video import H264Encoder, H264Options

__all__ = ["AckInfo", "ByteBudget", "Camera", "Codecs", "ConnectionFailed", "CslamError", "CurveKeys", "FrameRejected", "FrameSender",
           "H264Encoder", "H264Options", "HelloRejected", "NotAuthorized", "Progress", "ProtocolVersionError",
           "SenderStats", "ServerError", "ServerShuttingDown", "SessionBusy", "TooManyClients", "camera", "dataset",
           "video", "auto_rgb_codec"]
