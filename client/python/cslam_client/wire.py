"""The generated protobuf module (cslam_pb2, made from proto/cslam.proto at build time).

cslam.proto imports common.proto publicly (CameraIntrinsics, Pose: shared with the snapshot
schema), so ``pb.CameraIntrinsics`` and ``pb.Pose`` are there as before. protoc's Python output
imports it as the top-level module ``common_pb2``; the package's own copy is registered under
that name first.
"""
import sys

try:
    from . import common_pb2 as _common_pb2
    sys.modules.setdefault("common_pb2", _common_pb2)
    from . import cslam_pb2 as pb
except ImportError as e:  # pragma: no cover - a source checkout without a build
    raise ImportError("cslam_client: cslam_pb2 is missing; build the project (cmake generates it into "
                      "build/python/cslam_client) and put build/python on PYTHONPATH") from e
