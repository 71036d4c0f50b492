"""The generated protobuf module (cslam_pb2, made from proto/cslam.proto at build time)."""
try:
    from . import cslam_pb2 as pb
except ImportError as e:  # pragma: no cover - a source checkout without a build
    raise ImportError("cslam_client: cslam_pb2 is missing; build the project (cmake generates it into "
                      "build/python/cslam_client) and put build/python on PYTHONPATH") from e
